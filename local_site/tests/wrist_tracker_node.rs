//! The wrist tracker node on the operator-site hardware topics, with in-process buses:
//! a fake motion-capture driver publishes marker poses made from known hand poses
//! through the default registration, a fake pedal box publishes the pedals. The node
//! (default config: `mocap` source, `bus` panel) must publish the true hand pose in the
//! UR5 base, stamped with the capture time, drop a glitch, count a dropout, republish
//! the pedals, and fall into Fault (publishing no pedal state) when the pedals or the
//! tracker go quiet.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use teleop_bus::{Bus, BusConfig};
use teleop_interfaces::calibration;
use teleop_interfaces::topics;
use teleop_local_site::wrist_tracker::{BASE_FRAME, WristTrackerConfig, WristTrackerNode};
use teleop_msgs::{Header, Lifecycle, OperatorInput, Pose, PoseStamped, Time};
use teleop_node::Node;

fn configs(domain_id: u32) -> (BusConfig, BusConfig) {
    teleop_bus::testing::loopback_pair(domain_id)
}

/// The operator's true hand frame in the UR5 base at sample `k`.
fn true_hand(k: i64) -> Isometry3<f64> {
    let s = k as f64 * 0.02;
    Isometry3::from_parts(
        Translation3::new(0.5 + 0.05 * s.cos(), 0.1 * s.sin(), 0.3 + 0.02 * s),
        UnitQuaternion::from_euler_angles(0.2 * s.sin(), -0.4, 1.0 + 0.1 * s),
    )
}

/// What the motion capture sees for a hand pose: the marker in its own frame, through
/// the simulator's installation (computed here, independently of the node's code).
fn marker_for(hand: &Isometry3<f64>) -> Isometry3<f64> {
    let base_from_mocap = calibration::default_base_from_mocap().isometry();
    let hand_from_marker = calibration::default_hand_from_marker().isometry();
    base_from_mocap.inverse() * hand * hand_from_marker
}

fn pose_stamped(pose: &Isometry3<f64>, stamp: Time, frame: &str) -> PoseStamped {
    PoseStamped {
        header: Header::new(stamp, frame),
        pose: teleop_hardware::wire::pose_msg(pose).expect("a finite test pose"),
    }
}

fn to_isometry(p: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.position.x, p.position.y, p.position.z),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            p.orientation.w,
            p.orientation.x,
            p.orientation.y,
            p.orientation.z,
        )),
    )
}

const PERIOD_NS: i64 = 3_125_000; // 320 Hz

/// Ticks the node for `ms` while the motion capture keeps publishing (the pedals not).
async fn run_for(
    node: &mut WristTrackerNode,
    bus: &Bus,
    mocap: &teleop_bus::Publisher<PoseStamped>,
    t0_ns: i64,
    ms: u64,
    k: &mut i64,
) {
    let until = tokio::time::Instant::now() + Duration::from_millis(ms);
    while tokio::time::Instant::now() < until {
        let stamp = Time::from_nanos(t0_ns + *k * PERIOD_NS);
        mocap
            .put(&pose_stamped(&marker_for(&true_hand(*k)), stamp, "mocap"))
            .unwrap();
        *k += 1;
        tokio::time::sleep(Duration::from_millis(3)).await;
        node.tick(bus.now_s());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_node_publishes_the_registered_hand_pose_with_the_capture_stamp() {
    let (node_cfg, driver_cfg) = configs(51);
    let cfg = WristTrackerConfig {
        bus: node_cfg.clone(),
        ..Default::default()
    };
    let node_bus = Bus::open("wrist_tracker", &node_cfg).await.unwrap();
    let mut node = WristTrackerNode::new(&cfg, &node_bus).await.unwrap();
    assert_eq!(node.frame_id(), BASE_FRAME);
    let drivers = Bus::open("local_sim", &driver_cfg).await.unwrap();
    let mocap = drivers.publisher(&topics::HW_MOCAP_MARKER).await.unwrap();
    let pedals = drivers.publisher(&topics::HW_PEDALS).await.unwrap();
    let poses = drivers.subscriber(&topics::WRIST_POSE).await.unwrap();
    let inputs = drivers.subscriber(&topics::OPERATOR_INPUT).await.unwrap();

    let t0_ns = Time::now().as_nanos();
    let stamp_of = |k: i64| Time::from_nanos(t0_ns + k * PERIOD_NS);
    let pedal_msg = OperatorInput {
        header: Header::new(Time::now(), ""),
        clutch: true,
        enable: true,
        camera_stop: false,
        motion_scale: 0.7,
    };
    let mut received: Vec<PoseStamped> = Vec::new();
    let mut got_inputs: Vec<OperatorInput> = Vec::new();
    let drain = |received: &mut Vec<PoseStamped>, got: &mut Vec<OperatorInput>| {
        while let Some(r) = poses.try_recv() {
            received.push(r.msg);
        }
        while let Some(r) = inputs.try_recv() {
            got.push(r.msg);
        }
    };

    // Warm-up: sample 0 until the node has taken and published one (discovery).
    let mut warm = false;
    for _ in 0..300 {
        mocap
            .put(&pose_stamped(
                &marker_for(&true_hand(0)),
                stamp_of(0),
                "mocap",
            ))
            .unwrap();
        pedals.put(&pedal_msg).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        node.tick(node_bus.now_s());
        if node.tracker_counters().poses_published > 0 {
            warm = true;
            break;
        }
    }
    assert!(warm, "no sample reached the node: {:?}", node.counters());

    // 120 samples, one at a time (each taken by the node before the next is sent):
    // a glitch at 40 (the hand "jumps" 0.8 m), a dropout of 6 samples at 70..76.
    let glitch = 40;
    let taken = |n: &WristTrackerNode| {
        let c = n.tracker_counters();
        c.poses_published + c.rejected_position_jump
    };
    for k in 1..120 {
        if (70..76).contains(&k) {
            continue;
        }
        let hand = if k == glitch {
            Translation3::new(0.8, 0.0, 0.0) * true_hand(k)
        } else {
            true_hand(k)
        };
        mocap
            .put(&pose_stamped(&marker_for(&hand), stamp_of(k), "mocap"))
            .unwrap();
        if k % 6 == 0 {
            pedals.put(&pedal_msg).unwrap();
        }
        let before = taken(&node);
        for _ in 0..200 {
            tokio::time::sleep(Duration::from_millis(1)).await;
            node.tick(node_bus.now_s());
            if taken(&node) > before {
                break;
            }
        }
        drain(&mut received, &mut got_inputs);
    }
    tokio::time::sleep(Duration::from_millis(100)).await;
    drain(&mut received, &mut got_inputs);
    assert_eq!(node.state(), Lifecycle::Active, "{}", node.last_error());

    let c = node.tracker_counters();
    assert_eq!(c.rejected_position_jump, 1, "{c:?}");
    assert_eq!(c.dropouts, 1, "{c:?}");
    assert_eq!(c.reacquired, 0);
    assert!(c.poses_published >= 110, "{c:?}");
    assert!(
        received.len() >= 60,
        "only {} poses received",
        received.len()
    );
    for msg in &received {
        let k = (msg.header.stamp.as_nanos() - t0_ns) / PERIOD_NS;
        assert_eq!(
            msg.header.stamp,
            stamp_of(k),
            "the capture stamp, not the publish time"
        );
        assert_ne!(k, glitch, "the glitch was published");
        assert_eq!(msg.header.frame_id, BASE_FRAME);
        let got = to_isometry(&msg.pose);
        let truth = true_hand(k);
        assert!(
            (got.translation.vector - truth.translation.vector).amax() < 1e-6,
            "sample {k}: {got} vs {truth}"
        );
        assert!(got.rotation.angle_to(&truth.rotation) < 1e-6, "sample {k}");
    }
    // The pedals are republished.
    assert!(!got_inputs.is_empty());
    for i in &got_inputs {
        assert!(i.clutch && i.enable && !i.camera_stop);
        assert_eq!(i.motion_scale, 0.7);
    }

    // The pedals go quiet (the tracker keeps going): once stale, no operator input is
    // published and the node is in Fault.
    let mut k = 120;
    run_for(&mut node, &node_bus, &mocap, t0_ns, 250, &mut k).await;
    drain(&mut received, &mut got_inputs);
    let inputs_before = got_inputs.len();
    run_for(&mut node, &node_bus, &mocap, t0_ns, 250, &mut k).await;
    tokio::time::sleep(Duration::from_millis(50)).await;
    drain(&mut received, &mut got_inputs);
    assert_eq!(
        got_inputs.len(),
        inputs_before,
        "stale pedals were republished"
    );
    assert_eq!(node.state(), Lifecycle::Fault);
    assert!(
        node.last_error().contains("pedals"),
        "{}",
        node.last_error()
    );
    assert_eq!(node.tracker_counters().inputs_stale, 1);

    // The tracker goes quiet too: stale, counted, named.
    let until = tokio::time::Instant::now() + Duration::from_millis(300);
    while tokio::time::Instant::now() < until {
        tokio::time::sleep(Duration::from_millis(3)).await;
        node.tick(node_bus.now_s());
    }
    assert_eq!(node.state(), Lifecycle::Fault);
    let c = node.tracker_counters();
    assert_eq!(c.stale, 1, "{c:?}");
    let status: Vec<_> = node.counters();
    for name in [
        "wrist_pose.published",
        "wrist_pose.missing",
        "wrist_pose.dropouts",
        "wrist_pose.rejected_position_jump",
        "wrist_pose.rejected_orientation_jump",
        "wrist_pose.rejected_non_finite",
        "wrist_pose.reacquired",
        "wrist_pose.stale",
        "operator_input.published",
    ] {
        assert!(status.iter().any(|(n, _)| n == name), "{name} missing");
    }
}
