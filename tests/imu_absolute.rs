//! The chapter-6 absolute arm mode end to end: an Axis-Neuron-style BVH broadcast
//! (written by the test) -> the wrist tracker (BVH source with the spine-to-torso
//! registration and the arm-length scaling) -> the PR2 arm controller in absolute mode
//! -> the robot-site simulator, each on its own Zenoh session. The simulated arm's
//! palm (forward kinematics of its true joint states) is checked against the targets.
#![allow(clippy::unwrap_used)]

use std::io::Write;
use std::net::TcpListener;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, SVector, Vector3};
use teleop_bus::Bus;
use teleop_hardware::wire;
use teleop_ik::{Goal, IkSettings, Solver};
use teleop_interfaces::{joints, topics};
use teleop_local_site::tracking::bvh::{BvhStreamConfig, Skeleton};
use teleop_local_site::tracking::imu_arm::{ImuArmConfig, ImuArmMapping};
use teleop_local_site::wrist_tracker::{self, WristTrackerConfig};
use teleop_remote_site::arm_controller::{AbsoluteConfig, ArmControllerConfig, ArmMode};
use teleop_remote_site::arm_node::{self, ArmNodeConfig};
use teleop_sim::operator::SimulatedOperatorConfig;
use teleop_sim_nodes::remote_sim::{self, SceneKind, SimNodeConfig};
use teleop_system_tests::simulated_operator;
use teleop_system_tests::{free_port, isolated_pair, repo_root};

/// One system of nodes at a time (2-core machines).
static ONE_SYSTEM: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// Script times, s (from the broadcast's start).
const MOVE_FROM_S: f64 = 2.5;
const MOVE_UNTIL_S: f64 = 7.5;
const STREAM_UNTIL_S: f64 = 9.5;

/// The operator's arm at script time `t`: upper arm lowered 40 deg and swung 30 deg
/// forward, elbow bent 60 deg, then both swinging by 8 deg (periods 5 s and 4 s)
/// between `MOVE_FROM_S` and `MOVE_UNTIL_S`. Channels follow `tests/fixtures/upper_body.bvh`.
fn frame(t: f64) -> Vec<f64> {
    let phase = (t.clamp(MOVE_FROM_S, MOVE_UNTIL_S) - MOVE_FROM_S) * std::f64::consts::TAU;
    let swing = 8.0 * (phase / 5.0).sin();
    let bend = 8.0 * (phase / 4.0).sin();
    let mut v = vec![0.0, 100.0, 0.0, 0.0, 0.0, 0.0]; // hips
    v.extend([0.0; 3]); // spine
    v.extend([0.0; 3]); // shoulder
    v.extend([30.0 + swing, 0.0, 40.0]); // upper arm
    v.extend([60.0 + bend, 0.0, 0.0]); // forearm
    v.extend([0.0, 10.0, 0.0]); // hand
    v
}

fn skeleton_path() -> std::path::PathBuf {
    repo_root().join("tests/fixtures/upper_body.bvh")
}

/// The palm target in the torso frame for script time `t`, through the library's
/// skeleton and mapping (each tested on its own in `local_site/tests`).
fn target(skeleton: &Skeleton, mapping: &ImuArmMapping, t: f64) -> Isometry3<f64> {
    let j = |n: &str| skeleton.joint(n).unwrap();
    let arm = skeleton
        .arm_in(
            &frame(t),
            j("Spine3"),
            [j("RightArm"), j("RightForeArm"), j("RightHand")],
            0.01,
        )
        .unwrap();
    mapping.palm_target(&arm).unwrap()
}

/// Serves the broadcast at 50 Hz until `STREAM_UNTIL_S`, then closes; sends the
/// moment its clock started (the tracker connected) on `started`.
fn serve(listener: TcpListener, started: std::sync::mpsc::Sender<Instant>) {
    let (mut conn, _) = listener.accept().unwrap();
    let start = Instant::now();
    let _ = started.send(start);
    loop {
        let t = start.elapsed().as_secs_f64();
        if t > STREAM_UNTIL_S {
            return;
        }
        let values: Vec<String> = frame(t).iter().map(|v| format!("{v:.4}")).collect();
        if conn
            .write_all(format!("0 Avatar00 {} ||", values.join(" ")).as_bytes())
            .is_err()
        {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The robot's start: the arm already in the operator's initial posture (the clutch
/// engages only near the target), from the IK of the first target.
fn start_posture(base_from_torso: &Isometry3<f64>, first: &Isometry3<f64>) -> [f64; 7] {
    let chain = teleop_kinematics::robots::pr2_arm_chain().unwrap();
    let solver = Solver::new(chain.clone(), IkSettings::default());
    let goal = Goal::Pose {
        target: base_from_torso * first,
        weight: 1.0,
        rotation_scale: 0.25,
    };
    let seed = SVector::<f64, 7>::from_column_slice(&[-0.3, 0.5, -0.5, -1.2, 0.0, 0.0, 0.0]);
    let q = match solver.solve_cold(&[goal], Some(&seed), 1, teleop_ik::ColdBudget::default()) {
        Ok(s) => s.q,
        Err(f) => f.best.q,
    };
    let palm = chain.end_pose(&q);
    let miss = (palm.translation.vector - (base_from_torso * first).translation.vector).norm();
    assert!(
        miss < 0.01,
        "the first target is out of the PR2's reach ({miss} m)"
    );
    let mut out = [0.0; 7];
    out.copy_from_slice(q.as_slice());
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_pr2_follows_the_imu_suit_absolutely_and_stops_when_the_stream_ends() {
    let _one = ONE_SYSTEM.lock().await;
    let skeleton = Skeleton::load(&skeleton_path()).unwrap().0;
    let mapping = ImuArmMapping::new(&ImuArmConfig::default()).unwrap();
    let absolute = AbsoluteConfig::default();
    let base_from_torso = absolute.base_from_frame.isometry();
    let q0 = start_posture(&base_from_torso, &target(&skeleton, &mapping, 0.0));

    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let (hub, spoke) = isolated_pair(31, free_port().unwrap());
    let mut sim = SimNodeConfig {
        bus: hub,
        scene: SceneKind::Free,
        ..Default::default()
    };
    sim.world.arm.initial_position_rad = q0;
    let arm = ArmNodeConfig {
        // The arm alone: no hand whose commanders it would wait for.
        hand_nodes: Vec::new(),
        bus: spoke.clone(),
        arm: ArmControllerConfig {
            mode: ArmMode::Absolute,
            absolute,
            ..Default::default()
        },
        ..Default::default()
    };
    let tracker_operator = SimulatedOperatorConfig {
        clutch_delay_s: 1.5,
        clutch_on_s: 100.0,
        clutch_cycle_s: 200.0,
        ..Default::default()
    };
    let tracker = WristTrackerConfig {
        source: wrist_tracker::TrackerSource::Bvh(BvhStreamConfig {
            address,
            skeleton: skeleton_path(),
            avatar_index: 0,
            reference_joint: "Spine3".into(),
            hand_joint: "RightHand".into(),
            to_metres: 0.01,
            stale_after_s: 0.1,
            reconnect_s: 0.2,
            arm: Some(ImuArmConfig::default()),
        }),
        panel: wrist_tracker::PanelSource::InProcess,
        bus: spoke.clone(),
        ..Default::default()
    };
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(13))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let states = probe.subscriber(&topics::HW_PR2_ARM_STATE).await.unwrap();
    let poses = probe.subscriber(&topics::WRIST_POSE).await.unwrap();
    let arm_task = tokio::spawn(arm_node::run(arm, Some(Duration::from_secs(12))));
    let tracker_task = tokio::spawn(wrist_tracker::run_with_devices(
        tracker,
        simulated_operator(&tracker_operator, false),
        Some(Duration::from_secs(12)),
    ));
    let (started_tx, started_rx) = std::sync::mpsc::channel();
    let server = std::thread::spawn(move || serve(listener, started_tx));

    let chain = teleop_kinematics::robots::pr2_arm_chain().unwrap();
    let mut palm: Vec<(f64, Vector3<f64>)> = Vec::new();
    let mut targets: Vec<(f64, Isometry3<f64>)> = Vec::new();
    let mut frames_ok = true;
    let until = tokio::time::Instant::now() + Duration::from_millis(11_500);
    while tokio::time::Instant::now() < until {
        tokio::time::sleep(Duration::from_millis(10)).await;
        while let Some(r) = states.try_recv() {
            let q = wire::arm_state(&joints::PR2_ARM_JOINTS, &r.msg)
                .unwrap()
                .position_rad;
            palm.push((r.receive_time_s(), chain.end_pose(&q).translation.vector));
        }
        while let Some(r) = poses.try_recv() {
            frames_ok &= r.msg.header.frame_id == "torso_lift_link";
            targets.push((r.receive_time_s(), wire::isometry(&r.msg.pose)));
        }
    }
    server.join().unwrap();
    // Times from the broadcast's start, on the probe's clock: the server's clock starts
    // when the tracker connects, which under load is a while after the nodes start.
    let started = started_rx.recv().expect("the tracker connected");
    let t0 = probe.now_s() - started.elapsed().as_secs_f64();
    for (t, _) in palm.iter_mut() {
        *t -= t0;
    }
    for (t, _) in targets.iter_mut() {
        *t -= t0;
    }
    let arm_report = arm_task.await.unwrap().unwrap();
    tracker_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();

    assert!(frames_ok, "a wrist pose not in the torso frame");
    assert!(targets.len() > 300, "{} targets", targets.len());
    // The pipeline publishes the mapping of the broadcast frames: while the operator
    // holds still, the target is the mapped posture.
    let still = target(&skeleton, &mapping, STREAM_UNTIL_S);
    let held: Vec<_> = targets
        .iter()
        .filter(|(t, _)| (MOVE_UNTIL_S + 0.5..STREAM_UNTIL_S - 0.3).contains(t))
        .collect();
    assert!(held.len() > 50);
    for (_, p) in &held {
        assert!((p.translation.vector - still.translation.vector).norm() < 1e-3);
    }
    // Before the clutch (1.5 s) the arm holds its start.
    let start = palm.iter().find(|(t, _)| *t > 0.3).unwrap().1;
    let before = palm
        .iter()
        .filter(|(t, _)| *t < 1.3)
        .map(|(_, p)| (p - start).norm());
    assert!(before.fold(0.0, f64::max) < 1e-3, "moved before the clutch");
    // While the operator moves, the palm follows the target (the nearest target
    // received 50 ms earlier: the arm's lag), in the base frame.
    let target_at = |t: f64| {
        targets
            .iter()
            .rev()
            .find(|(tt, _)| *tt <= t)
            .map(|(_, p)| (base_from_torso * p).translation.vector)
    };
    let errors: Vec<f64> = palm
        .iter()
        .filter(|(t, _)| (MOVE_FROM_S + 0.5..MOVE_UNTIL_S).contains(t))
        .filter_map(|(t, p)| target_at(t - 0.05).map(|q| (p - q).norm()))
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let max = errors.iter().copied().fold(0.0, f64::max);
    let moved = palm
        .iter()
        .filter(|(t, _)| (MOVE_FROM_S..MOVE_UNTIL_S).contains(t))
        .map(|(_, p)| (p - start).norm())
        .fold(0.0, f64::max);
    println!(
        "absolute mode: palm moved up to {:.1} cm; error against the target {:.2} mm mean, {:.2} mm max ({} states)",
        moved * 100.0,
        mean * 1e3,
        max * 1e3,
        errors.len()
    );
    assert!(moved > 0.04, "the palm moved {moved} m only");
    assert!(mean < 0.006, "mean error {mean} m");
    assert!(max < 0.015, "largest error {max} m");
    // Held still, it settles on the target.
    let settled = palm
        .iter()
        .filter(|(t, _)| (STREAM_UNTIL_S - 0.6..STREAM_UNTIL_S - 0.1).contains(t))
        .map(|(_, p)| (p - (base_from_torso * still).translation.vector).norm())
        .fold(0.0, f64::max);
    println!("held still: {:.2} mm from the target", settled * 1e3);
    assert!(settled < 0.004, "settled {settled} m from the target");
    // The broadcast ends: the wrist pose goes stale, the arm stops and stays.
    let after: Vec<_> = palm
        .iter()
        .filter(|(t, _)| *t > STREAM_UNTIL_S + 0.8)
        .collect();
    assert!(after.len() > 10);
    let drift = after
        .iter()
        .map(|(_, p)| (p - after[0].1).norm())
        .fold(0.0, f64::max);
    assert!(
        drift < 1e-3,
        "the arm moved {drift} m after the stream ended"
    );
    assert_eq!(arm_report.counter("arm.engagements"), Some(1));
    assert_eq!(arm_report.counter("arm.stop.stale_wrist_pose"), Some(1));
    assert_eq!(arm_report.counter("wrist_pose.rejected_frame_id"), Some(0));
}

/// A controller in absolute mode facing an operator site that publishes UR5-base poses
/// (relative-mode registration): every pose is refused by frame, the arm never engages.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn absolute_mode_refuses_poses_in_another_frame() {
    let _one = ONE_SYSTEM.lock().await;
    let (hub, spoke) = isolated_pair(32, free_port().unwrap());
    let sim = SimNodeConfig {
        bus: hub,
        scene: SceneKind::Free,
        ..Default::default()
    };
    let arm = ArmNodeConfig {
        // The arm alone: no hand whose commanders it would wait for.
        hand_nodes: Vec::new(),
        bus: spoke.clone(),
        arm: ArmControllerConfig {
            mode: ArmMode::Absolute,
            ..Default::default()
        },
        ..Default::default()
    };
    let tracker_operator = SimulatedOperatorConfig {
        clutch_delay_s: 0.5,
        ..Default::default()
    };
    let tracker = WristTrackerConfig {
        source: wrist_tracker::TrackerSource::InProcess,
        panel: wrist_tracker::PanelSource::InProcess,
        registration: wrist_tracker::RegistrationConfig {
            base_from_tracker: Some(teleop_control::TransformConfig::default()),
            ..Default::default()
        },
        bus: spoke.clone(),
        ..Default::default()
    };
    assert_eq!(tracker.frame_id_in_effect(), "ur5_base_link");
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(5))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let arm_task = tokio::spawn(arm_node::run(arm, Some(Duration::from_secs(4))));
    let tracker_task = tokio::spawn(wrist_tracker::run_with_devices(
        tracker,
        simulated_operator(&tracker_operator, true),
        Some(Duration::from_secs(4)),
    ));
    let report = arm_task.await.unwrap().unwrap();
    tracker_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();
    assert!(report.counter("wrist_pose.rejected_frame_id").unwrap() > 100);
    assert_eq!(report.counter("arm.engagements"), Some(0));
    assert!(
        report.last_error.contains("torso_lift_link"),
        "{}",
        report.last_error
    );
}
