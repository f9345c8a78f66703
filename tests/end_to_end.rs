//! The wrist tracker node runs against the simulated operator; a second session checks
//! what arrives against the simulator's ground truth.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use teleop_bus::Bus;
use teleop_interfaces::topics;
use teleop_local_site::wrist_tracker::{self, WristTrackerConfig};
use teleop_msgs::Lifecycle;
use teleop_sim::operator::SimulatedOperatorConfig;
use teleop_system_tests::simulated_operator;
use teleop_system_tests::{free_port, isolated_pair};

/// One system of nodes at a time: each test runs a simulator, controllers and 320 Hz
/// trackers; several at once starve a 2-core machine into stale-sample drops, which
/// the counters below would then count instead of the foreign samples they look for.
static ONE_SYSTEM: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

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
    let _one = ONE_SYSTEM.lock().await;
    let (node_bus, probe_bus) = isolated_pair(21, free_port().unwrap());
    let operator = SimulatedOperatorConfig {
        clutch_delay_s: 1.5,
        ..Default::default()
    };
    let cfg = WristTrackerConfig {
        source: wrist_tracker::TrackerSource::InProcess,
        panel: wrist_tracker::PanelSource::InProcess,
        bus: node_bus,
        ..Default::default()
    };
    let probe = Bus::open("probe", &probe_bus).await.unwrap();
    let poses = probe.subscriber(&topics::WRIST_POSE).await.unwrap();
    let inputs = probe.subscriber(&topics::OPERATOR_INPUT).await.unwrap();
    let status = probe.subscriber(&topics::NODE_STATUS).await.unwrap();
    let node = tokio::spawn(wrist_tracker::run_with_devices(
        cfg,
        simulated_operator(&operator, true),
        Some(Duration::from_secs(3)),
    ));

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

/// Palm positions (FK of the arm hardware's states) and operator wrist positions (as
/// the tracker published them), with their receive times.
#[derive(Default)]
struct Trace {
    palm: Vec<(f64, nalgebra::Vector3<f64>)>,
    operator: Vec<(f64, nalgebra::Vector3<f64>)>,
}

impl Trace {
    fn at(series: &[(f64, nalgebra::Vector3<f64>)], t: f64) -> nalgebra::Vector3<f64> {
        series
            .iter()
            .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
            .unwrap()
            .1
    }

    /// The palm's displacement over `[t0, t1]` against the operator's over the same
    /// window shifted by the arm's lag (the best of 0..0.3 s): the mean and largest
    /// difference (m), and how far the operator moved (m).
    fn follow_error(&self, t0: f64, t1: f64) -> (f64, f64, f64) {
        let samples: Vec<f64> = self
            .palm
            .iter()
            .map(|(t, _)| *t)
            .filter(|t| *t >= t0 && *t <= t1)
            .collect();
        let mut best = (f64::INFINITY, f64::INFINITY);
        for k in 0..=6 {
            let lag = f64::from(k) * 0.05;
            let p0 = Self::at(&self.palm, t0);
            let o0 = Self::at(&self.operator, t0 - lag);
            let errors: Vec<f64> = samples
                .iter()
                .map(|&t| {
                    let dp = Self::at(&self.palm, t) - p0;
                    let dop = Self::at(&self.operator, t - lag) - o0;
                    (dp - dop).norm()
                })
                .collect();
            let mean = errors.iter().sum::<f64>() / errors.len() as f64;
            let max = errors.iter().copied().fold(0.0, f64::max);
            if mean < best.0 {
                best = (mean, max);
            }
        }
        let moved = samples
            .iter()
            .map(|&t| (Self::at(&self.operator, t) - Self::at(&self.operator, t0)).norm())
            .fold(0.0, f64::max);
        (best.0, best.1, moved)
    }
}

/// Records palm and operator positions for `duration` from `probe`'s subscriptions.
async fn record(
    trace: &mut Trace,
    states: &teleop_bus::Subscriber<teleop_msgs::JointState>,
    poses: &teleop_bus::Subscriber<teleop_msgs::PoseStamped>,
    duration: Duration,
) {
    use teleop_hardware::wire;
    let chain = teleop_kinematics::robots::pr2_arm_chain().unwrap();
    let until = tokio::time::Instant::now() + duration;
    while tokio::time::Instant::now() < until {
        tokio::time::sleep(Duration::from_millis(10)).await;
        while let Some(r) = states.try_recv() {
            let q = wire::arm_state(&teleop_interfaces::joints::PR2_ARM_JOINTS, &r.msg)
                .unwrap()
                .position_rad;
            trace
                .palm
                .push((r.receive_time_s(), chain.end_pose(&q).translation.vector));
        }
        while let Some(r) = poses.try_recv() {
            let p = r.msg.pose.position;
            trace
                .operator
                .push((r.receive_time_s(), nalgebra::Vector3::new(p.x, p.y, p.z)));
        }
    }
}

/// The operator site's wrist tracker, the robot site's simulator and the PR2 arm
/// controller, each on its own Zenoh session: the arm holds still until the clutch is
/// pressed, then follows the operator's motion, displacement for displacement in the
/// base-aligned frame (within millimetres, after the arm's lag).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wrist_tracker_drives_the_simulated_pr2_arm_through_the_clutch() {
    let _one = ONE_SYSTEM.lock().await;
    use teleop_hardware::wire;
    use teleop_remote_site::arm_node::{self, ArmNodeConfig};
    use teleop_remote_site::feedback_node::{self, FeedbackConfig};
    use teleop_sim_nodes::remote_sim::{self, SimNodeConfig};

    let port = free_port().unwrap();
    let (hub, spoke) = isolated_pair(22, port);
    let sim = SimNodeConfig {
        bus: hub,
        ..Default::default()
    };
    let arm = ArmNodeConfig {
        // The arm alone: no hand whose commanders it would wait for.
        hand_nodes: Vec::new(),
        bus: spoke.clone(),
        ..Default::default()
    };
    let tracker_operator = SimulatedOperatorConfig {
        clutch_delay_s: 2.5,
        speed_m_s: 0.05,
        ..Default::default()
    };
    let tracker = WristTrackerConfig {
        source: wrist_tracker::TrackerSource::InProcess,
        panel: wrist_tracker::PanelSource::InProcess,
        bus: spoke.clone(),
        ..Default::default()
    };
    let feedback = FeedbackConfig {
        bus: spoke.clone(),
        ..Default::default()
    };
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(10))));
    let feedback_task = tokio::spawn(feedback_node::run(feedback, Some(Duration::from_secs(9))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let states = probe.subscriber(&topics::HW_PR2_ARM_STATE).await.unwrap();
    let poses = probe.subscriber(&topics::WRIST_POSE).await.unwrap();
    let to_operator = probe.subscriber(&topics::PR2_JOINT_STATES).await.unwrap();
    let pressures = probe
        .subscriber(&topics::FINGERTIP_PRESSURES)
        .await
        .unwrap();
    let arm_task = tokio::spawn(arm_node::run(arm, Some(Duration::from_secs(9))));
    let tracker_task = tokio::spawn(wrist_tracker::run_with_devices(
        tracker,
        simulated_operator(&tracker_operator, true),
        Some(Duration::from_secs(9)),
    ));
    let t_start = probe.now_s();

    // Before the clutch (t < 2.5 s): the arm does not move.
    let mut before = Trace::default();
    record(&mut before, &states, &poses, Duration::from_millis(2200)).await;
    let first = before
        .palm
        .iter()
        .find(|(t, _)| *t > t_start + 0.5)
        .unwrap()
        .1;
    let last = before.palm.last().unwrap().1;
    assert!(
        (last - first).norm() < 1e-3,
        "arm moved without the clutch: {} m",
        (last - first).norm()
    );
    // Clutch pressed from 2.5 s: the palm's displacement follows the operator's.
    let mut trace = Trace::default();
    record(&mut trace, &states, &poses, Duration::from_millis(5500)).await;
    let t0 = t_start + 3.5;
    let (mean, max, moved) = trace.follow_error(t0, t0 + 4.0);
    println!(
        "arm follows: operator moved {:.1} mm, palm displacement error mean {:.2} mm, max {:.2} mm",
        moved * 1e3,
        mean * 1e3,
        max * 1e3
    );
    assert!(moved > 0.1, "the operator moved only {moved} m");
    // The velocity law's steady lag (0.1 s at the thesis gains) and the 30 Hz hold
    // leave a few millimetres; a motion copied wrongly (direction, scale, the other
    // operator) would be off by centimetres.
    assert!(mean < 0.010, "mean displacement error {mean} m");
    assert!(max < 0.025, "largest displacement error {max} m");
    // The feedback publisher forwards the arm's state and the fingertip pressures.
    let fed = to_operator
        .recv_timeout(Duration::from_secs(2))
        .await
        .unwrap();
    let fed = wire::arm_state(&teleop_interfaces::joints::PR2_ARM_JOINTS, &fed.msg)
        .unwrap()
        .position_rad;
    let hw = states.recv_timeout(Duration::from_secs(2)).await.unwrap();
    let hw = wire::arm_state(&teleop_interfaces::joints::PR2_ARM_JOINTS, &hw.msg)
        .unwrap()
        .position_rad;
    assert!(
        (fed - hw).amax() < 0.05,
        "forwarded state far from the hardware's"
    );
    let p = pressures
        .recv_timeout(Duration::from_secs(2))
        .await
        .unwrap();
    assert!(p.msg.values().iter().all(|v| v.is_finite() && *v >= 0.0));
    let arm_report = arm_task.await.unwrap().unwrap();
    assert_eq!(arm_report.counter("arm.engagements"), Some(1));
    feedback_task.await.unwrap().unwrap();
    tracker_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();
}

/// One commander at a time: a second wrist tracker joins while the arm follows the
/// first; the arm keeps following the first (displacement for displacement), refuses
/// the second's samples, and reports the conflict in its status.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_operator_site_is_refused_and_reported_never_blended() {
    let _one = ONE_SYSTEM.lock().await;
    use teleop_remote_site::arm_node::{self, ArmNodeConfig};
    use teleop_sim_nodes::remote_sim::{self, SimNodeConfig};

    let (hub, spoke) = isolated_pair(24, free_port().unwrap());
    let sim = SimNodeConfig {
        bus: hub,
        ..Default::default()
    };
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(11))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let states = probe.subscriber(&topics::HW_PR2_ARM_STATE).await.unwrap();
    let poses = probe.subscriber(&topics::WRIST_POSE).await.unwrap();
    let status = probe.subscriber(&topics::NODE_STATUS).await.unwrap();
    let arm = ArmNodeConfig {
        // The arm alone: no hand whose commanders it would wait for.
        hand_nodes: Vec::new(),
        bus: spoke.clone(),
        ..Default::default()
    };
    let arm_task = tokio::spawn(arm_node::run(arm, Some(Duration::from_secs(10))));
    let first_operator = SimulatedOperatorConfig {
        clutch_delay_s: 1.0,
        ..Default::default()
    };
    let first = WristTrackerConfig {
        source: wrist_tracker::TrackerSource::InProcess,
        panel: wrist_tracker::PanelSource::InProcess,
        bus: spoke.clone(),
        ..Default::default()
    };
    let first_task = tokio::spawn(wrist_tracker::run_with_devices(
        first,
        simulated_operator(&first_operator, true),
        Some(Duration::from_secs(10)),
    ));
    let t_start = probe.now_s();
    let mut trace = Trace::default();
    record(&mut trace, &states, &poses, Duration::from_millis(3500)).await;
    // The second station: another square elsewhere, its clutch pressed at once.
    let second_operator = SimulatedOperatorConfig {
        seed: 99,
        center_m: [0.3, 0.2, 0.5],
        speed_m_s: 0.08,
        clutch_delay_s: 0.0,
        ..Default::default()
    };
    let second = WristTrackerConfig {
        source: wrist_tracker::TrackerSource::InProcess,
        panel: wrist_tracker::PanelSource::InProcess,
        node_name: "wrist_tracker_b".into(),
        bus: spoke.clone(),
        ..Default::default()
    };
    let second_task = tokio::spawn(wrist_tracker::run_with_devices(
        second,
        simulated_operator(&second_operator, true),
        Some(Duration::from_secs(5)),
    ));
    let t_join = probe.now_s();
    // Only the first tracker's poses describe the operator the arm should follow.
    let mut during = Trace::default();
    record(&mut during, &states, &poses, Duration::from_millis(4000)).await;
    trace.palm.extend(during.palm);
    // Both stations publish on the same topic: keep the first's samples (its square).
    let centre = nalgebra::Vector3::new(0.5, 0.0, 0.3);
    trace.operator.extend(
        during
            .operator
            .into_iter()
            .filter(|(_, p)| (p - centre).norm() < 0.16),
    );
    let (mean, max, moved) = trace.follow_error(t_join - 0.5, t_join + 3.5);
    println!(
        "second station present: first operator moved {:.1} mm, palm displacement error mean {:.2} mm, max {:.2} mm",
        moved * 1e3,
        mean * 1e3,
        max * 1e3
    );
    assert!(moved > 0.05);
    assert!(
        mean < 0.010 && max < 0.025,
        "the arm did not keep following the first station"
    );
    // The arm controller reports the conflict: a report made at least 3 s after the
    // second station joined (the subscriber also holds older ones, made when few of
    // its samples had come yet).
    let mut report = None;
    let until = tokio::time::Instant::now() + Duration::from_secs(3);
    while report.is_none() && tokio::time::Instant::now() < until {
        if let Some(s) = status.recv_timeout(Duration::from_millis(200)).await
            && s.msg.node_name == "pr2_arm_controller"
            && s.msg.counter("wrist_pose.conflict_active") == Some(1)
            && s.msg.header.stamp.as_secs_f64() >= t_join + 3.0
        {
            report = Some(s.msg);
        }
    }
    let s = report.expect("a status reporting the conflict");
    println!("pr2_arm_controller: {}", s.last_error);
    assert!(
        s.last_error.contains("conflicting commander"),
        "{}",
        s.last_error
    );
    assert!(s.last_error.contains("wrist_tracker_b"), "{}", s.last_error);
    assert!(s.counter("wrist_pose.rejected_foreign").unwrap() > 50);
    assert!(s.counter("operator_input.rejected_foreign").unwrap() > 20);
    assert_eq!(s.counter("arm.engagements"), Some(1));
    second_task.await.unwrap().unwrap();
    first_task.await.unwrap().unwrap();
    arm_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();
    assert!(t_join - t_start > 3.0);
}

/// A robot simulator with 160 x 120 camera views on `hub`, and a feedback publisher
/// with its defaults on `spoke`.
fn small_views_sim_and_feedback(
    hub: teleop_bus::BusConfig,
    spoke: &teleop_bus::BusConfig,
) -> (
    teleop_sim_nodes::remote_sim::SimNodeConfig,
    teleop_remote_site::feedback_node::FeedbackConfig,
) {
    let sim = teleop_sim_nodes::remote_sim::SimNodeConfig {
        bus: hub,
        cameras: teleop_sim::CameraViewsConfig {
            width_px: 160,
            height_px: 120,
            ..Default::default()
        },
        ..Default::default()
    };
    let feedback = teleop_remote_site::feedback_node::FeedbackConfig {
        bus: spoke.clone(),
        ..Default::default()
    };
    (sim, feedback)
}

/// The simulator renders the top and side camera views of its world (as a camera driver
/// would publish them); the feedback publisher forwards them, rate-limited and as JPEG,
/// to the operator site.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn remote_camera_views_reach_the_operator_site() {
    let _one = ONE_SYSTEM.lock().await;
    use teleop_remote_site::feedback_node;
    use teleop_sim_nodes::remote_sim;

    let (hub, spoke) = isolated_pair(23, free_port().unwrap());
    let (sim, feedback) = small_views_sim_and_feedback(hub, &spoke);
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let top = probe.subscriber(&topics::REMOTE_CAMERA_TOP).await.unwrap();
    let side = probe.subscriber(&topics::REMOTE_CAMERA_SIDE).await.unwrap();
    let status = probe.subscriber(&topics::NODE_STATUS).await.unwrap();
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(4))));
    let feedback_task = tokio::spawn(feedback_node::run(
        feedback,
        Some(Duration::from_millis(3500)),
    ));

    for (view, sub, frame_id) in [
        ("top", &top, "remote_camera_top_optical_frame"),
        ("side", &side, "remote_camera_side_optical_frame"),
    ] {
        for _ in 0..3 {
            let jpeg = sub
                .recv_timeout(Duration::from_secs(4))
                .await
                .unwrap_or_else(|| panic!("no {view} image reached the operator site"))
                .msg;
            assert_eq!(jpeg.format, "jpeg", "{view}");
            // JPEG: a fraction of the raw view's 57.6 kB.
            assert!(
                jpeg.data.len() < 160 * 120 * 3 / 4,
                "{view}: {} B",
                jpeg.data.len()
            );
            let image = teleop_msgs::image_codec::decode_rgb8(&jpeg).unwrap();
            assert_eq!(image.header, jpeg.header);
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

/// The operator display answers each camera view with a receipt, and the feedback
/// publisher paces the views by them: every view it sent is acknowledged, none taken as
/// lost, and the round trip it measured is a loopback's. A receipt that names no camera
/// is counted, nothing else.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_operator_display_acknowledges_the_views_and_the_publisher_paces_by_them() {
    let _one = ONE_SYSTEM.lock().await;
    use teleop_local_site::operator_display::{self, OperatorDisplayConfig};
    use teleop_remote_site::feedback_node;
    use teleop_sim_nodes::remote_sim;

    let (hub, spoke) = isolated_pair(25, free_port().unwrap());
    let (sim, feedback) = small_views_sim_and_feedback(hub, &spoke);
    let display = OperatorDisplayConfig {
        bus: spoke.clone(),
        http_listen: "127.0.0.1:0".into(),
        ..Default::default()
    };
    let probe = Bus::open("probe", &spoke).await.unwrap();
    let forged = probe
        .publisher(&topics::REMOTE_CAMERA_RECEIPTS)
        .await
        .unwrap();
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(6))));
    let (feedback_done, feedback_ended) = tokio::sync::oneshot::channel::<()>();
    let feedback_task = tokio::spawn(async move {
        let sent = feedback_node::run(feedback, Some(Duration::from_millis(5500))).await;
        let _ = feedback_done.send(());
        sent
    });
    // The display outlives the publisher, so every view sent can be acknowledged: it
    // stops 0.3 s after the publisher has (timers of their own would not do: each
    // node's time counts from the end of its own start-up, which on a loaded machine
    // may take a few hundred milliseconds longer for one than the other), within its
    // feedback timeout (1 s), so it is still Active at its stop.
    let display_task = tokio::spawn(operator_display::run_until(display, async move {
        let _ = feedback_ended.await;
        tokio::time::sleep(Duration::from_millis(300)).await;
    }));
    tokio::time::sleep(Duration::from_secs(3)).await;
    for i in 0..3 {
        forged
            .put(&teleop_msgs::Header::new(
                teleop_msgs::Time::from_nanos(i),
                "no_such_camera",
            ))
            .unwrap();
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let shown = display_task.await.unwrap().unwrap();
    let sent = feedback_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();

    let d = |name: &str| shown.counter(name).unwrap_or_else(|| panic!("{name}"));
    let f = |name: &str| sent.counter(name).unwrap_or_else(|| panic!("{name}"));
    assert_eq!(shown.state_at_stop, Lifecycle::Active, "{shown:?}");
    for view in ["top", "side"] {
        let received = d(&format!("display.view_{view}.received"));
        assert!(received > 20, "{view}: {received} views shown");
        assert_eq!(d(&format!("display.view_{view}.refused")), 0);
        let age_us = d(&format!("display.view_{view}.age_us"));
        // Measured from the views' stamps (how long they take is the benchmarks' and the
        // end-of-run report's to say: tests assert behaviour, never timing).
        assert!(age_us > 0, "{view}: {age_us} us");
    }
    assert_eq!(
        d("display.receipts_sent"),
        d("display.view_top.received") + d("display.view_side.received")
    );
    assert!(d("display.pr2_states.received") > 100, "{shown:?}");
    assert!(d("display.pressures.received") > 100, "{shown:?}");

    let forwarded = f("feedback.camera_top.forwarded") + f("feedback.camera_side.forwarded");
    let acknowledged = f("feedback.camera_pacing.acknowledged");
    // At most the last view of each camera may still be on its way at the stop.
    assert!(
        acknowledged + 2 >= forwarded && acknowledged > 40,
        "{acknowledged} of {forwarded} views acknowledged: {sent:?}"
    );
    assert_eq!(f("feedback.camera_pacing.lost"), 0, "{sent:?}");
    assert!(f("feedback.camera_pacing.unmatched") >= 3, "{sent:?}");
    let rtt_us = f("feedback.camera_pacing.base_rtt_us");
    assert!(rtt_us > 0, "the pacing measured a round trip: {rtt_us} us");
}

/// A page address already taken leaves the display running without its page: the
/// views would still be received and acknowledged; its status says why there is no
/// page and `display.web.serving` is 0.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_operator_display_runs_on_without_its_page_when_the_address_is_taken() {
    use teleop_local_site::operator_display::{self, OperatorDisplayConfig};
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap();
    let (hub, _spoke) = isolated_pair(26, free_port().unwrap());
    let report = operator_display::run(
        OperatorDisplayConfig {
            bus: hub,
            http_listen: addr.to_string(),
            ..Default::default()
        },
        Some(Duration::from_millis(1500)),
    )
    .await
    .expect("the display runs without its page");
    assert_eq!(report.counter("display.web.serving"), Some(0), "{report:?}");
    assert!(
        report.last_error.contains("no browser page")
            && report.last_error.contains(&addr.to_string()),
        "{}",
        report.last_error
    );
}
