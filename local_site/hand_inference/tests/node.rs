//! The `hand_inference` node over the bus, with the deterministic test model: two
//! Zenoh sessions in one process (the node's, and a rig that plays the depth camera,
//! the camera arm, the wrist tracker and the robot site), on TCP loopback without
//! scouting. The node is ticked by the test.

use std::collections::BTreeSet;
use std::time::Duration;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use teleop_bus::{Bus, BusConfig, Publisher, Subscriber};
use teleop_hand_inference::node::{
    self, CentreSource, FrameOutcome, HandInferenceConfig, HandInferenceNode, tracked_centre,
};
use teleop_hand_inference::{DeterministicTestModel, HandEstimator};
use teleop_hand_model::scene::HAND_CENTRE_IN_HAND_FRAME;
use teleop_hardware::safety::HandLimits;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{Header, Image, JointState, Lifecycle, PoseStamped, Time};
use teleop_node::{Node, NodeConfig};
use teleop_render::Intrinsics;

fn configs(domain_id: u32) -> (BusConfig, BusConfig) {
    teleop_bus::testing::loopback_pair(domain_id)
}

/// Where the hand is: the camera in the UR5 base frame, the hand centre in the camera
/// frame, and the hand frame (wrist) in the base frame consistent with both.
struct Scene {
    camera: Isometry3<f64>,
    centre_in_camera: Point3<f64>,
    wrist: Isometry3<f64>,
}

impl Scene {
    fn new() -> Self {
        // Camera 0.9 m above the base, looking down and a little forward.
        let camera = Isometry3::from_parts(
            Translation3::new(0.4, 0.1, 0.9),
            UnitQuaternion::from_euler_angles(std::f64::consts::PI - 0.3, 0.1, 0.4),
        );
        let centre_in_camera = Point3::new(0.03, -0.02, 0.45);
        // The hand's orientation relative to the camera: palm towards it, turned a bit.
        let hand_in_camera_rot = UnitQuaternion::from_euler_angles(1.2, -0.3, 0.5);
        let wrist_in_camera = Isometry3::from_parts(
            Translation3::from(
                centre_in_camera.coords
                    - hand_in_camera_rot * Vector3::from(HAND_CENTRE_IN_HAND_FRAME),
            ),
            hand_in_camera_rot,
        );
        Self {
            camera,
            centre_in_camera,
            wrist: camera * wrist_in_camera,
        }
    }
}

/// A depth frame (16UC1 mm) of a 5 cm-radius ball centred at `centre` (camera frame):
/// the hand-sized blob the test model sees.
fn blob_frame(centre: &Point3<f64>) -> Vec<u16> {
    let k = Intrinsics::sr300();
    let (w, h) = (k.width() as usize, k.height() as usize);
    let radius = 0.05;
    let c = centre.coords;
    let mut img = vec![0u16; w * h];
    for v in 0..h {
        for u in 0..w {
            let r = k.ray_through(u as f64, v as f64);
            // |s r - c| = radius, nearest s: depth (r.z = 1).
            let (a, b, cc) = (r.dot(&r), r.dot(&c), c.dot(&c) - radius * radius);
            let disc = b * b - a * cc;
            if disc >= 0.0 {
                let s = (b - disc.sqrt()) / a;
                img[v * w + u] = (s * 1000.0).round() as u16;
            }
        }
    }
    img
}

fn pose_msg(pose: &Isometry3<f64>, stamp: Time) -> PoseStamped {
    PoseStamped {
        header: Header::new(stamp, "ur5_base"),
        pose: teleop_hardware::wire::pose_msg(pose).expect("a finite test pose"),
    }
}

/// The node, the rig's publishers and the robot site's subscriber.
struct Rig {
    node: HandInferenceNode<DeterministicTestModel>,
    node_bus: Bus,
    rig_bus: Bus,
    depth: Publisher<Image>,
    camera_pose: Publisher<PoseStamped>,
    wrist_pose: Publisher<PoseStamped>,
    targets: Subscriber<JointState>,
    scene: Scene,
}

impl Rig {
    async fn new(domain_id: u32, cfg: HandInferenceConfig, model: DeterministicTestModel) -> Self {
        let (a, b) = configs(domain_id);
        let cfg = HandInferenceConfig { bus: a, ..cfg };
        let node_bus = Bus::open(&cfg.node_name, &cfg.bus).await.expect("node bus");
        let estimator = HandEstimator::new(model).expect("estimator");
        let node = HandInferenceNode::with_model(&cfg, &node_bus, estimator)
            .await
            .expect("node");
        let rig_bus = Bus::open("rig", &b).await.expect("rig bus");
        let rig = Self {
            node,
            depth: rig_bus
                .publisher(&topics::HW_HAND_DEPTH)
                .await
                .expect("depth"),
            camera_pose: rig_bus
                .publisher(&topics::CAMERA_POSE)
                .await
                .expect("camera pose"),
            wrist_pose: rig_bus
                .publisher(&topics::WRIST_POSE)
                .await
                .expect("wrist pose"),
            targets: rig_bus
                .subscriber(&topics::HAND_JOINT_TARGETS)
                .await
                .expect("targets"),
            node_bus,
            rig_bus,
            scene: Scene::new(),
        };
        // Let the sessions connect and the declarations propagate.
        tokio::time::sleep(Duration::from_millis(300)).await;
        rig
    }

    fn now(&self) -> Time {
        Time::from_nanos(self.rig_bus.clock().now_ns())
    }

    fn publish_poses(&self, stamp: Time) {
        self.camera_pose
            .put(&pose_msg(&self.scene.camera, stamp))
            .expect("camera pose");
        self.wrist_pose
            .put(&pose_msg(&self.scene.wrist, stamp))
            .expect("wrist pose");
    }

    fn publish_depth(&self, stamp: Time, depth_mm: &[u16]) {
        let img = Image::depth_mm(
            Header::new(stamp, "camera_optical_frame"),
            640,
            480,
            depth_mm,
        );
        self.depth.put(&img).expect("depth");
    }

    /// Waits a little, ticks the node, and collects the targets that arrived.
    async fn step(&mut self, got: &mut Vec<JointState>) {
        tokio::time::sleep(Duration::from_millis(25)).await;
        self.node.tick(self.node_bus.now_s());
        while let Some(r) = self.targets.try_recv() {
            got.push(r.msg);
        }
    }

    /// Publishes `frames` depth frames (with the poses around each if `poses`),
    /// ticking between them; returns the frames' stamps and the targets received.
    async fn run_frames(
        &mut self,
        depth_mm: &[u16],
        frames: usize,
        poses: bool,
    ) -> (BTreeSet<i64>, Vec<JointState>) {
        let mut stamps = BTreeSet::new();
        let mut got = Vec::new();
        for _ in 0..frames {
            // A pose sample, 20 ms later the frame is captured, 20 ms later the next
            // pose sample: the frame's stamp lies between two samples.
            let before = self.now();
            if poses {
                self.publish_poses(before);
            }
            self.step(&mut got).await;
            let capture = Time::from_nanos(before.as_nanos() + 20_000_000);
            if poses {
                self.publish_poses(Time::from_nanos(before.as_nanos() + 40_000_000));
            }
            self.step(&mut got).await;
            self.publish_depth(capture, depth_mm);
            stamps.insert(capture.as_nanos());
            self.step(&mut got).await;
        }
        for _ in 0..10 {
            self.step(&mut got).await;
        }
        (stamps, got)
    }

    fn counter(&self, name: &str) -> u64 {
        self.node
            .counters()
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no counter {name}"))
            .1
    }
}

fn check_targets(got: &[JointState], stamps: &BTreeSet<i64>) {
    let limits = HandLimits::shadow().expect("limits");
    assert!(!got.is_empty(), "no targets published");
    for msg in got {
        let names: Vec<&str> = msg.name.iter().map(String::as_str).collect();
        assert_eq!(names, SHADOW_FINGER_JOINTS);
        assert_eq!(msg.position.len(), 17);
        assert!(msg.velocity.is_empty() && msg.effort.is_empty());
        assert!(msg.header.frame_id.is_empty());
        for (i, q) in msg.position.iter().enumerate() {
            assert!(
                q.is_finite() && *q >= limits.lower_rad[i] && *q <= limits.upper_rad[i],
                "{}: {q}",
                SHADOW_FINGER_JOINTS[i]
            );
        }
        assert!(
            stamps.contains(&msg.header.stamp.as_nanos()),
            "stamp {:?} is not a frame's capture stamp",
            msg.header.stamp
        );
        // The robot site's parser takes them.
        teleop_hardware::wire::finger_targets(msg).expect("accepted by the robot site");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tracked_hand_gives_named_targets_stamped_with_the_frame() {
    let mut rig = Rig::new(
        71,
        HandInferenceConfig::default(),
        DeterministicTestModel::new(96),
    )
    .await;
    assert_eq!(rig.node.state(), Lifecycle::Inactive, "no hand seen yet");
    // The tracked centre is where the blob is.
    let centre = tracked_centre(&rig.scene.camera, &rig.scene.wrist);
    assert!((centre - rig.scene.centre_in_camera).norm() < 1e-9);
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let (stamps, got) = rig.run_frames(&frame, 5, true).await;
    check_targets(&got, &stamps);
    // The robot site's subscription keeps the newest only: it may miss some.
    assert!(rig.counter("hand_inference.published") >= got.len() as u64);
    assert!(rig.counter("hand_inference.centre_tracked") >= 1);
    assert_eq!(rig.counter("hand_inference.centre_image"), 0);
    assert_eq!(rig.counter("hand_inference.no_hand"), 0);
    match rig.node.last_outcome() {
        Some(FrameOutcome::Published { centre_m, .. }) => {
            assert!(
                (centre_m - rig.scene.centre_in_camera).norm() < 1e-6,
                "{centre_m:?}"
            );
        }
        other => panic!("expected a published frame, got {other:?}"),
    }
    // Every stage was timed.
    for stage in ["capture_to_received", "processing", "capture_to_published"] {
        let p50 = rig.counter(&format!("latency.{stage}_us.p50"));
        let p99 = rig.counter(&format!("latency.{stage}_us.p99"));
        assert!(p50 > 0 && p99 >= p50, "{stage}: p50 {p50} p99 {p99}");
    }
    assert!(
        rig.counter("latency.capture_to_published_us.p50")
            >= rig.counter("latency.capture_to_received_us.p50")
    );
    // Hands were estimated within the last 0.5 s.
    rig.node.tick(rig.node_bus.now_s());
    assert_eq!(rig.node.state(), Lifecycle::Active);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_hand_in_the_crop_publishes_nothing_and_the_node_goes_inactive() {
    let mut rig = Rig::new(
        72,
        HandInferenceConfig::default(),
        DeterministicTestModel::new(96),
    )
    .await;
    // First a hand, so the node is active.
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let (_, got) = rig.run_frames(&frame, 2, true).await;
    assert!(!got.is_empty());
    assert_eq!(rig.node.state(), Lifecycle::Active);
    let published = rig.counter("hand_inference.published");

    // An empty frame.
    let empty = vec![0u16; 640 * 480];
    let (_, got) = rig.run_frames(&empty, 3, true).await;
    assert!(got.is_empty(), "{got:?}");
    let no_hand = rig.counter("hand_inference.no_hand");
    assert!(no_hand >= 1);
    // The hand lies outside the crop: the poses say it is where it is not.
    let elsewhere = rig.scene.centre_in_camera + Vector3::new(0.25, 0.0, 0.0);
    let (_, got) = rig.run_frames(&blob_frame(&elsewhere), 3, true).await;
    assert!(got.is_empty(), "{got:?}");
    assert!(rig.counter("hand_inference.no_hand") > no_hand);
    assert_eq!(rig.counter("hand_inference.published"), published);
    assert!(matches!(
        rig.node.last_outcome(),
        Some(FrameOutcome::NoHand { .. })
    ));
    // More than 0.5 s without a hand: inactive, and the status says why.
    rig.node.tick(rig.node_bus.now_s());
    assert_eq!(rig.node.state(), Lifecycle::Inactive);
    let err = rig.node.last_error();
    assert!(err.starts_with("no hand in view (foreground"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_images_are_counted_and_nothing_is_published() {
    let mut rig = Rig::new(
        73,
        HandInferenceConfig::default(),
        DeterministicTestModel::new(96),
    )
    .await;
    let mut got = Vec::new();
    let stamp = rig.now();
    rig.publish_poses(stamp);
    let header = || Header::new(stamp, "camera_optical_frame");
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let rgb = Image {
        header: header(),
        height: 480,
        width: 640,
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: 640 * 3,
        data: vec![0; 640 * 480 * 3],
    };
    let mut float = Image::depth_mm(header(), 640, 480, &frame);
    float.encoding = "32FC1".into();
    float.step = 640 * 4;
    float.data = vec![0; 640 * 480 * 4];
    let mut truncated = Image::depth_mm(header(), 640, 480, &frame);
    truncated.data.truncate(1000);
    let small = Image::depth_mm(header(), 320, 240, &frame[..320 * 240]);
    for image in [rgb, float, truncated, small] {
        rig.depth.put(&image).expect("put");
        for _ in 0..4 {
            rig.step(&mut got).await;
        }
    }
    assert!(got.is_empty(), "{got:?}");
    assert_eq!(
        rig.counter("hand_inference.rejected_image"),
        2,
        "rgb8 and the truncated one"
    );
    assert_eq!(rig.counter("hand_inference.rejected_encoding"), 1);
    assert_eq!(rig.counter("hand_inference.rejected_image_size"), 1);
    assert_eq!(rig.counter("hand_inference.published"), 0);
    let err = rig.node.last_error();
    assert!(err.contains("320 x 240"), "{err}");
    assert_eq!(rig.node.state(), Lifecycle::Inactive);
    // A good frame still goes through afterwards.
    let (stamps, got) = rig.run_frames(&frame, 2, true).await;
    check_targets(&got, &stamps);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_poses_the_image_gives_the_centre() {
    let mut rig = Rig::new(
        74,
        HandInferenceConfig::default(),
        DeterministicTestModel::new(96),
    )
    .await;
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let (stamps, got) = rig.run_frames(&frame, 3, false).await;
    check_targets(&got, &stamps);
    assert!(rig.counter("hand_inference.centre_image") >= 1);
    assert_eq!(rig.counter("hand_inference.centre_tracked"), 0);
    match rig.node.last_outcome() {
        Some(FrameOutcome::Published { centre_m, .. }) => {
            // Near the ball's centre: its visible surface's median, pushed back 2 cm.
            assert!(
                (centre_m - rig.scene.centre_in_camera).norm() < 0.03,
                "{centre_m:?}"
            );
        }
        other => panic!("expected a published frame, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_poses_and_fallback_there_is_no_centre() {
    let cfg = HandInferenceConfig {
        image_fallback: false,
        ..HandInferenceConfig::default()
    };
    let mut rig = Rig::new(75, cfg, DeterministicTestModel::new(96)).await;
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let (_, got) = rig.run_frames(&frame, 3, false).await;
    assert!(got.is_empty());
    assert!(rig.counter("hand_inference.no_centre") >= 1);
    assert_eq!(rig.counter("hand_inference.centre_image"), 0);
    assert!(
        rig.node.last_error().contains("no hand centre"),
        "{}",
        rig.node.last_error()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stale_poses_fall_back_to_the_image() {
    let mut rig = Rig::new(
        76,
        HandInferenceConfig::default(),
        DeterministicTestModel::new(96),
    )
    .await;
    // Poses from 2 s ago only: nothing at the frames' stamps.
    let old = Time::from_nanos(rig.now().as_nanos() - 2_000_000_000);
    rig.publish_poses(old);
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let (stamps, got) = rig.run_frames(&frame, 2, false).await;
    check_targets(&got, &stamps);
    assert_eq!(rig.counter("hand_inference.centre_tracked"), 0);
    assert!(rig.counter("hand_inference.centre_image") >= 1);
}

/// The motion capture loses the markers for a moment: the frames in the gap keep the
/// newest tracked centre (the camera arm holds the hand where it was in the view)
/// instead of the image's centroid, which is centimetres off and moves the network's
/// estimate; with the hold off they take the image's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_short_gap_in_the_poses_holds_the_tracked_centre() {
    for (domain, hold_s) in [(77, 2.0), (78, 0.0)] {
        let cfg = HandInferenceConfig {
            hold_tracked_centre_s: hold_s,
            ..HandInferenceConfig::default()
        };
        let mut rig = Rig::new(domain, cfg, DeterministicTestModel::new(96)).await;
        let frame = blob_frame(&rig.scene.centre_in_camera);
        let (stamps, got) = rig.run_frames(&frame, 2, true).await;
        check_targets(&got, &stamps);
        let tracked = match rig.node.last_outcome() {
            Some(FrameOutcome::Published {
                centre_m,
                source: CentreSource::Tracked,
                ..
            }) => *centre_m,
            other => panic!("expected a tracked frame, got {other:?}"),
        };
        // The poses stop; the frames go on.
        let (stamps, got) = rig.run_frames(&frame, 2, false).await;
        check_targets(&got, &stamps);
        match (hold_s > 0.0, rig.node.last_outcome()) {
            (
                true,
                Some(FrameOutcome::Published {
                    centre_m,
                    source: CentreSource::Held,
                    ..
                }),
            ) => assert_eq!(*centre_m, tracked),
            (
                false,
                Some(FrameOutcome::Published {
                    source: CentreSource::Image,
                    ..
                }),
            ) => {}
            other => panic!("hold {hold_s} s: {other:?}"),
        }
        let held = rig.counter("hand_inference.centre_held");
        let image = rig.counter("hand_inference.centre_image");
        if hold_s > 0.0 {
            assert!(held >= 1 && image == 0, "held {held}, image {image}");
        } else {
            assert!(held == 0 && image >= 1, "held {held}, image {image}");
        }
    }
    let bad = HandInferenceConfig {
        hold_tracked_centre_s: f64::NAN,
        ..HandInferenceConfig::default()
    };
    let err = bad.validate().expect_err("NaN refused");
    assert!(err.contains("hold_tracked_centre_s"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_model_returning_nan_publishes_nothing() {
    let mut model = DeterministicTestModel::new(96);
    let mut nan = [0.1f32; 17];
    nan[3] = f32::NAN;
    model.fixed = Some(nan);
    let mut rig = Rig::new(77, HandInferenceConfig::default(), model).await;
    let frame = blob_frame(&rig.scene.centre_in_camera);
    let (_, got) = rig.run_frames(&frame, 2, true).await;
    assert!(got.is_empty());
    assert!(rig.counter("hand_inference.errors.non_finite") >= 1);
    let err = rig.node.last_error();
    assert!(err.contains(SHADOW_FINGER_JOINTS[3]), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missing_model_file_is_named() {
    let cfg = HandInferenceConfig {
        model: "/nonexistent/hand/model.onnx".into(),
        ..HandInferenceConfig::default()
    };
    let err = node::run(cfg, Some(Duration::from_millis(100)))
        .await
        .expect_err("no model");
    let msg = format!("{err:#}");
    assert!(msg.contains("/nonexistent/hand/model.onnx"), "{msg}");
    assert!(msg.contains("set `model`"), "{msg}");
}

#[test]
fn the_shipped_configs_parse_validate_and_the_defaults_file_is_the_defaults() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let shipped: HandInferenceConfig =
        teleop_node::config::load_checked(&root.join("deploy/config/hand_inference.toml"))
            .expect("shipped config");
    shipped.validate().expect("valid");
    let defaults: HandInferenceConfig =
        teleop_node::config::load_checked(&root.join("deploy/defaults/hand_inference.toml"))
            .expect("defaults file");
    assert_eq!(defaults, HandInferenceConfig::default());
}

/// A second publisher of wrist poses (another operator station, a stray tool) is
/// refused as the robot site's controllers refuse it: the crop centre keeps coming from
/// the poses the node locked onto, the foreign ones are counted and the conflict is
/// reported. Its poses are stamped at the frames' capture times, 0.3 m away, so a
/// single one taken in would move the centre.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_wrist_pose_publisher_is_refused_and_never_moves_the_crop() {
    let mut rig = Rig::new(
        79,
        HandInferenceConfig::default(),
        DeterministicTestModel::new(96),
    )
    .await;
    let frame = blob_frame(&rig.scene.centre_in_camera);
    // The node locks onto the rig's publishers.
    let (stamps, got) = rig.run_frames(&frame, 2, true).await;
    check_targets(&got, &stamps);
    let intruder = rig
        .rig_bus
        .publisher(&topics::WRIST_POSE)
        .await
        .expect("second wrist pose publisher");
    tokio::time::sleep(Duration::from_millis(300)).await;
    let elsewhere = Isometry3::translation(0.0, 0.3, 0.0) * rig.scene.wrist;
    let mut got = Vec::new();
    let mut published = 0;
    for _ in 0..5 {
        let before = rig.now();
        rig.publish_poses(before);
        rig.step(&mut got).await;
        let capture = Time::from_nanos(before.as_nanos() + 20_000_000);
        rig.publish_poses(Time::from_nanos(before.as_nanos() + 40_000_000));
        // Last before the tick: the newest sample in the queue.
        tokio::time::sleep(Duration::from_millis(5)).await;
        intruder
            .put(&pose_msg(&elsewhere, capture))
            .expect("intruder pose");
        rig.step(&mut got).await;
        rig.publish_depth(capture, &frame);
        rig.step(&mut got).await;
        match rig.node.last_outcome() {
            Some(FrameOutcome::Published { centre_m, .. }) => {
                assert!(
                    (centre_m - rig.scene.centre_in_camera).norm() < 1e-6,
                    "the crop moved to {centre_m:?}"
                );
                published += 1;
            }
            other => panic!("expected a published frame, got {other:?}"),
        }
    }
    assert_eq!(published, 5);
    for s in rig.node.wrist_poses().samples() {
        assert!(
            (s.pose.translation.vector - rig.scene.wrist.translation.vector).norm() < 1e-9,
            "a foreign pose in the history: {:?}",
            s.pose.translation
        );
    }
    assert!(rig.counter("wrist_pose.rejected_foreign") >= 1);
    assert_eq!(rig.counter("wrist_pose.source_locks"), 1);
    // The camera pose's counters take its topic's last name, `teleop/local_camera/pose`.
    assert_eq!(rig.counter("pose.source_locks"), 1);
    assert!(rig.counter("wrist_pose.conflicts") >= 1);
    assert!(
        rig.node
            .last_error()
            .contains("conflicting commander on /teleop/wrist_pose"),
        "{}",
        rig.node.last_error()
    );
}
