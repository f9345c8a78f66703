//! The wrist tracker node runs against the simulated operator; a second session checks
//! what arrives against the simulator's ground truth.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use teleop_bus::Bus;
use teleop_interfaces::topics;
use teleop_local_site::wrist_tracker::{self, WristTrackerConfig};
use teleop_msgs::Lifecycle;
use teleop_sim::operator::SimulatedOperatorConfig;
use teleop_system_tests::{free_port, isolated_pair};

/// Distance from `p` to the boundary of the axis-aligned square of side `side` centred
/// at `c` in the plane z = c.z.
fn distance_to_square(p: [f64; 3], c: [f64; 3], side: f64) -> f64 {
    let h = side / 2.0;
    let (dx, dy, dz) = (p[0] - c[0], p[1] - c[1], p[2] - c[2]);
    // Distance to each edge segment.
    let seg = |x: f64, y: f64, horizontal: bool, fixed: f64| -> f64 {
        if horizontal {
            let cx = x.clamp(-h, h);
            ((x - cx).powi(2) + (y - fixed).powi(2)).sqrt()
        } else {
            let cy = y.clamp(-h, h);
            ((x - fixed).powi(2) + (y - cy).powi(2)).sqrt()
        }
    };
    let d = seg(dx, dy, true, -h)
        .min(seg(dx, dy, true, h))
        .min(seg(dx, dy, false, -h))
        .min(seg(dx, dy, false, h));
    (d * d + dz * dz).sqrt()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wrist_tracker_publishes_ground_truth_poses_inputs_and_status() {
    let (node_bus, probe_bus) = isolated_pair(21, free_port().unwrap());
    let operator = SimulatedOperatorConfig {
        clutch_delay_s: 1.5,
        ..Default::default()
    };
    let cfg = WristTrackerConfig {
        bus: node_bus,
        operator: operator.clone(),
        ..Default::default()
    };
    let probe = Bus::open("probe", &probe_bus).await.unwrap();
    let poses = probe.subscriber(&topics::WRIST_POSE).await.unwrap();
    let inputs = probe.subscriber(&topics::OPERATOR_INPUT).await.unwrap();
    let status = probe.subscriber(&topics::NODE_STATUS).await.unwrap();
    let node = tokio::spawn(wrist_tracker::run(cfg, Some(Duration::from_secs(3))));

    let mut n_poses = 0;
    let mut max_dev: f64 = 0.0;
    let mut clutch_seen = [false, false];
    let mut active_status = None;
    let until = tokio::time::Instant::now() + Duration::from_secs(4);
    while tokio::time::Instant::now() < until {
        if let Some(p) = poses.recv_timeout(Duration::from_millis(20)).await {
            let pos = p.msg.pose.position;
            let q = p.msg.pose.orientation;
            let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
            assert!((norm - 1.0).abs() < 1e-9);
            max_dev = max_dev.max(distance_to_square(
                [pos.x, pos.y, pos.z],
                operator.center_m,
                operator.side_m,
            ));
            n_poses += 1;
        }
        while let Some(i) = inputs.try_recv() {
            assert!(i.msg.enable);
            clutch_seen[usize::from(i.msg.clutch)] = true;
        }
        while let Some(s) = status.try_recv() {
            if s.msg.lifecycle() == Some(Lifecycle::Active) {
                active_status = Some(s.msg);
            }
        }
    }
    let counters = node.await.unwrap().unwrap();
    assert!(n_poses > 100, "only {n_poses} poses arrived");
    // The tracker's noise is 0.2 mm (sigma): every pose lies on the true square.
    assert!(
        max_dev < 0.002,
        "pose {max_dev} m off the operator's true path"
    );
    assert_eq!(clutch_seen, [true, true], "clutch released then pressed");
    let s = active_status.expect("an active status report");
    assert_eq!(s.node_name, "wrist_tracker");
    assert!(s.counter("wrist_pose.published").unwrap() > 0);
    assert_eq!(s.counter("wrist_pose.rejected_non_finite"), Some(0));
    assert!(counters.counter("wrist_pose.published").unwrap() >= n_poses);
    assert_eq!(poses.stats().rejected(), 0);
}

/// The operator site's wrist tracker, the robot site's simulator and the PR2 arm
/// controller, each on its own Zenoh session: the arm holds still until the clutch is
/// pressed, then follows the operator.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wrist_tracker_drives_the_simulated_pr2_arm_through_the_clutch() {
    use teleop_hardware::wire;
    use teleop_remote_site::arm_node::{self, ArmNodeConfig};
    use teleop_remote_site::feedback_node::{self, FeedbackConfig};
    use teleop_remote_site::sim_node::{self, SimNodeConfig};

    let port = free_port().unwrap();
    let (hub, spoke) = isolated_pair(22, port);
    let sim = SimNodeConfig {
        bus: hub,
        ..Default::default()
    };
    let arm = ArmNodeConfig {
        bus: spoke.clone(),
        ..Default::default()
    };
    let tracker = WristTrackerConfig {
        bus: spoke.clone(),
        operator: SimulatedOperatorConfig {
            clutch_delay_s: 2.5,
            speed_m_s: 0.05,
            ..Default::default()
        },
        ..Default::default()
    };
    let feedback = FeedbackConfig {
        bus: spoke.clone(),
        ..Default::default()
    };
    let sim_task = tokio::spawn(sim_node::run(sim, Some(Duration::from_secs(8))));
    let feedback_task = tokio::spawn(feedback_node::run(feedback, Some(Duration::from_secs(7))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let states = probe.subscriber(&topics::HW_PR2_ARM_STATE).await.unwrap();
    let to_operator = probe.subscriber(&topics::PR2_JOINT_STATES).await.unwrap();
    let pressures = probe
        .subscriber(&topics::FINGERTIP_PRESSURES)
        .await
        .unwrap();
    let arm_task = tokio::spawn(arm_node::run(arm, Some(Duration::from_secs(7))));
    let tracker_task = tokio::spawn(wrist_tracker::run(tracker, Some(Duration::from_secs(7))));

    let read = |r: teleop_bus::Received<teleop_msgs::JointState>| {
        wire::arm_state(&teleop_interfaces::joints::PR2_ARM_JOINTS, &r.msg)
            .unwrap()
            .position_rad
    };
    // Before the clutch (t < 2.5 s): the arm does not move.
    tokio::time::sleep(Duration::from_millis(1000)).await;
    let a = read(states.recv_timeout(Duration::from_secs(2)).await.unwrap());
    tokio::time::sleep(Duration::from_millis(1000)).await;
    let b = read(states.recv_timeout(Duration::from_secs(2)).await.unwrap());
    assert!(
        (b - a).amax() < 1e-6,
        "arm moved without the clutch: {}",
        (b - a).amax()
    );
    // Clutch pressed from 2.5 s: the arm follows the operator's square.
    tokio::time::sleep(Duration::from_millis(3000)).await;
    let c = read(states.recv_timeout(Duration::from_secs(2)).await.unwrap());
    assert!(
        (c - b).amax() > 1e-3,
        "arm did not follow: {}",
        (c - b).amax()
    );
    // The feedback publisher forwards the arm's state and the fingertip pressures.
    let fed = to_operator
        .recv_timeout(Duration::from_secs(2))
        .await
        .unwrap();
    let fed = wire::arm_state(&teleop_interfaces::joints::PR2_ARM_JOINTS, &fed.msg)
        .unwrap()
        .position_rad;
    assert!(
        (fed - c).amax() < 0.05,
        "forwarded state far from the hardware's"
    );
    let p = pressures
        .recv_timeout(Duration::from_secs(2))
        .await
        .unwrap();
    assert!(p.msg.values().iter().all(|v| v.is_finite() && *v >= 0.0));
    arm_task.await.unwrap().unwrap();
    feedback_task.await.unwrap().unwrap();
    tracker_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();
}

/// The simulator renders the top and side camera views of its world (as a camera driver
/// would publish them); the feedback publisher forwards them, rate-limited, to the
/// operator site.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn remote_camera_views_reach_the_operator_site() {
    use teleop_remote_site::feedback_node::{self, FeedbackConfig};
    use teleop_remote_site::sim_node::{self, SimNodeConfig};
    use teleop_sim::CameraViewsConfig;

    let (hub, spoke) = isolated_pair(23, free_port().unwrap());
    let sim = SimNodeConfig {
        bus: hub,
        cameras: CameraViewsConfig {
            width_px: 160,
            height_px: 120,
            ..Default::default()
        },
        ..Default::default()
    };
    let feedback = FeedbackConfig {
        bus: spoke.clone(),
        ..Default::default()
    };
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let top = probe.subscriber(&topics::REMOTE_CAMERA_TOP).await.unwrap();
    let side = probe.subscriber(&topics::REMOTE_CAMERA_SIDE).await.unwrap();
    let status = probe.subscriber(&topics::NODE_STATUS).await.unwrap();
    let sim_task = tokio::spawn(sim_node::run(sim, Some(Duration::from_secs(4))));
    let feedback_task = tokio::spawn(feedback_node::run(
        feedback,
        Some(Duration::from_millis(3500)),
    ));

    for (view, sub, frame_id) in [
        ("top", &top, "remote_camera_top_optical_frame"),
        ("side", &side, "remote_camera_side_optical_frame"),
    ] {
        for _ in 0..3 {
            let image = sub
                .recv_timeout(Duration::from_secs(4))
                .await
                .unwrap_or_else(|| panic!("no {view} image reached the operator site"))
                .msg;
            assert_eq!(image.encoding, "rgb8", "{view}");
            assert_eq!((image.width, image.height), (160, 120), "{view}");
            assert_eq!(image.header.frame_id, frame_id);
            assert!(image.header.stamp.sec > 0, "{view}: stamped");
            image.check_layout().unwrap();
            // Not a blank frame: the robot is in view.
            assert!(image.data.iter().filter(|&&v| v > 0).count() > image.data.len() / 20);
        }
    }
    // The feedback publisher counts what it forwarded.
    let mut forwarded = None;
    let until = tokio::time::Instant::now() + Duration::from_secs(4);
    while forwarded.is_none() && tokio::time::Instant::now() < until {
        if let Some(s) = status.recv_timeout(Duration::from_millis(200)).await
            && s.msg.node_name == "feedback_publisher"
            && s.msg.counter("feedback.camera_top.forwarded").unwrap_or(0) > 0
        {
            forwarded = Some(s.msg);
        }
    }
    let s = forwarded.expect("a feedback_publisher status counting forwarded top images");
    assert!(s.counter("feedback.camera_side.forwarded").unwrap() > 0);
    assert!(s.counter("feedback.camera_top.dropped").is_some());
    assert_eq!(top.stats().rejected(), 0);
    feedback_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();
}
