//! The Shadow hand controller node over the bus: the simulator (as the hand's driver),
//! the `shadow_hand_controller` node and a stand-in for the operator site's hand
//! inference, each on its own Zenoh session. The hand holds while the enable switch is
//! released, follows the targets while it is held, and holds its posture when the
//! targets stop or a target is NaN.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use teleop_bus::Bus;
use teleop_hardware::wire;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{Header, JointState, OperatorInput, Time, unix_nanos_now};
use teleop_remote_site::hand_node::{self, HandNodeConfig};
use teleop_sim_nodes::remote_sim::{self, SceneKind, SimNodeConfig};
use teleop_system_tests::{free_port, isolated_pair};

fn stamp() -> Header {
    Header::new(Time::from_nanos(unix_nanos_now()), "")
}

fn targets(ffj3: f64) -> JointState {
    let mut position = vec![0.0; 17];
    position[1] = ffj3; // rh_FFJ3
    position[4] = ffj3 * 0.75; // rh_MFJ3
    JointState {
        header: stamp(),
        name: SHADOW_FINGER_JOINTS
            .iter()
            .map(|s| (*s).to_owned())
            .collect(),
        position,
        ..Default::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_hand_node_follows_with_enable_and_holds_when_targets_stop() {
    assert_eq!(SHADOW_FINGER_JOINTS[1], "rh_FFJ3");
    let port = free_port().unwrap();
    let (hub, spoke) = isolated_pair(23, port);
    let sim = SimNodeConfig {
        bus: hub,
        scene: SceneKind::Free,
        ..Default::default()
    };
    let hand = HandNodeConfig {
        bus: spoke.clone(),
        ..Default::default()
    };
    let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(9))));
    tokio::time::sleep(Duration::from_millis(300)).await;
    let hand_task = tokio::spawn(hand_node::run(hand, Some(Duration::from_secs(8))));

    // The operator site's hand inference (its liveliness makes the site "alive").
    let op = Bus::open("hand_inference", &spoke).await.unwrap();
    let target_pub = op.publisher(&topics::HAND_JOINT_TARGETS).await.unwrap();
    let input_pub = op.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let states = op.subscriber(&topics::HW_HAND_STATE).await.unwrap();
    let status = op.subscriber(&topics::NODE_STATUS).await.unwrap();
    // The thesis's gating (the default): the right pedal and the switch open the hand.
    let send = |ffj3: Option<f64>, enable: bool| {
        if let Some(q) = ffj3 {
            target_pub.put(&targets(q)).unwrap();
        }
        input_pub
            .put(&OperatorInput {
                header: stamp(),
                clutch: enable,
                enable,
                camera_stop: false,
                motion_scale: 1.0,
            })
            .unwrap();
    };
    let ffj3 = || async {
        // Newest state.
        let mut last = states.recv_timeout(Duration::from_secs(2)).await.unwrap();
        while let Some(r) = states.try_recv() {
            last = r;
        }
        wire::hand_state(&last.msg, None).unwrap().position_rad[1]
    };
    let period = Duration::from_millis(20);

    // 1.5 s of targets with the enable switch released: the hand does not follow.
    let start = ffj3().await;
    for _ in 0..75 {
        send(Some(0.9), false);
        tokio::time::sleep(period).await;
    }
    let released = ffj3().await;
    assert!(
        (released - start).abs() < 0.1,
        "moved without enable: {start} -> {released}"
    );
    // Enable held but the clutch pedal up: still no motion.
    for _ in 0..25 {
        target_pub.put(&targets(0.9)).unwrap();
        input_pub
            .put(&OperatorInput {
                header: stamp(),
                clutch: false,
                enable: true,
                camera_stop: false,
                motion_scale: 1.0,
            })
            .unwrap();
        tokio::time::sleep(period).await;
    }
    let no_clutch = ffj3().await;
    assert!(
        (no_clutch - start).abs() < 0.1,
        "moved without the clutch: {start} -> {no_clutch}"
    );

    // 2 s with enable: the finger reaches the target, and the fingers are still there
    // (the last 0.5 s): the stiff part of the loop runs in the hand's own loop (joint
    // impedance), not across the bus, where it made the fingers chatter at 16 rad/s
    // against the effort cap.
    let mut settled = Vec::new();
    for i in 0..100 {
        send(Some(0.9), true);
        tokio::time::sleep(period).await;
        while let Some(r) = states.try_recv() {
            if i >= 75 {
                settled.push(wire::hand_state(&r.msg, None).unwrap());
            }
        }
    }
    let followed = ffj3().await;
    assert!((followed - 0.9).abs() < 0.08, "FFJ3 at {followed}");
    // The state subscription keeps the newest: about one per 20 ms period.
    assert!(settled.len() >= 20, "{} states in 0.5 s", settled.len());
    let median = |f: &dyn Fn(&teleop_hardware::HandState) -> f64| {
        let mut v: Vec<f64> = settled.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let speed = median(&|s| s.velocity_rad_s.amax());
    let effort = median(&|s| s.effort_nm.amax());
    println!(
        "settled: fastest joint median {speed:.3} rad/s, largest effort median {effort:.3} N m"
    );
    assert!(
        speed < 0.5,
        "fingers not still at the target: {speed} rad/s"
    );
    assert!(
        effort < 1.0,
        "efforts near the 2 N m cap at rest: {effort} N m"
    );

    // A NaN target is refused (named, counted) and changes nothing.
    let mut bad = targets(0.9);
    bad.position[5] = f64::NAN;
    target_pub.put(&bad).unwrap();
    // Targets stop, enable stays held: after the timeout the hand holds its posture.
    for _ in 0..75 {
        send(None, true);
        tokio::time::sleep(period).await;
    }
    let held = ffj3().await;
    assert!((held - 0.9).abs() < 0.1, "hold drifted to {held}");

    // The node's status names what happened.
    let mut seen = None;
    while let Some(r) = status.recv_timeout(Duration::from_secs(2)).await {
        if r.msg.node_name == "shadow_hand_controller" {
            seen = Some(r.msg);
            if seen
                .as_ref()
                .unwrap()
                .counter("hand.hold.stale_target")
                .unwrap_or(0)
                > 0
            {
                break;
            }
        }
    }
    let s = seen.expect("a status from the hand node");
    assert!(
        s.counter("hand.hold.enable_released").unwrap_or(0) > 0,
        "{s:?}"
    );
    assert!(
        s.counter("hand.hold.clutch_released").unwrap_or(0) > 0,
        "{s:?}"
    );
    assert!(
        s.counter("hand.hold.stale_target").unwrap_or(0) > 0,
        "{s:?}"
    );
    assert!(
        s.counter("hand.target_rejected.non_finite").unwrap_or(0) == 1,
        "{s:?}"
    );
    assert!(
        s.counter("hand.targets_accepted").unwrap_or(0) > 100,
        "{s:?}"
    );
    drop((target_pub, input_pub, states, status));
    op.close().await.unwrap();
    hand_task.await.unwrap().unwrap();
    sim_task.await.unwrap().unwrap();
}
