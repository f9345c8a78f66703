//! The arm node on scripted time: its clock (and its bus's) is a `ManualClock` the test
//! moves, so the watchdog's deadlines are exercised exactly, not by sleeping. The node's
//! `tick` is called by the test, as the runner would call it.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::Duration;

use nalgebra::SVector;
use teleop_bus::{Bus, Clock, ManualClock};
use teleop_hardware::{ArmState, wire};
use teleop_interfaces::joints::PR2_ARM_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{Header, Lifecycle, OperatorInput, Point, Pose, PoseStamped, Quaternion, Time};
use teleop_node::Node;
use teleop_remote_site::arm_node::{ArmNode, ArmNodeConfig};
use teleop_sim::WORKING_POSTURE_RAD;
use teleop_system_tests::{free_port, isolated_pair};

const DT: f64 = 1.0 / 30.0;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_arm_node_stops_on_scripted_time() {
    let clock = ManualClock::starting_at(1_000_000.0);
    let shared: Arc<dyn Clock> = clock.clone();
    let (hub, spoke) = isolated_pair(26, free_port().unwrap());
    let bus = Bus::open_with_clock("pr2_arm_controller", &hub, shared.clone())
        .await
        .unwrap();
    let cfg = ArmNodeConfig::default();
    let mut node = ArmNode::new(&cfg, &bus).await.unwrap();
    // The operator site and the arm's hardware, on the same scripted clock.
    let peer = Bus::open_with_clock("wrist_tracker", &spoke, shared)
        .await
        .unwrap();
    let state_pub = peer.publisher(&topics::HW_PR2_ARM_STATE).await.unwrap();
    let pose_pub = peer.publisher(&topics::WRIST_POSE).await.unwrap();
    let input_pub = peer.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let commands = peer.subscriber(&topics::HW_PR2_ARM_COMMAND).await.unwrap();
    let q = SVector::<f64, 7>::from(WORKING_POSTURE_RAD);
    let stamp = |t: f64| Time::from_nanos((t * 1e9) as i64);
    // One scripted period: the peer publishes what it is told, the messages arrive
    // (real time), the clock moves by one period, the node ticks.
    let period = |t: f64, pose_x: Option<f64>, input: bool, clutch: bool| {
        state_pub
            .put(&wire::arm_state_msg(
                &PR2_ARM_JOINTS,
                &ArmState {
                    time_s: t,
                    position_rad: q,
                    velocity_rad_s: SVector::zeros(),
                },
            ))
            .unwrap();
        if let Some(x) = pose_x {
            pose_pub
                .put(&PoseStamped {
                    header: Header::new(stamp(t), "tracker"),
                    pose: Pose {
                        position: Point { x, y: 0.0, z: 1.0 },
                        orientation: Quaternion {
                            x: 0.0,
                            y: 0.0,
                            z: 0.0,
                            w: 1.0,
                        },
                    },
                })
                .unwrap();
        }
        if input {
            input_pub
                .put(&OperatorInput {
                    header: Header::new(stamp(t), ""),
                    clutch,
                    enable: true,
                    camera_stop: false,
                    motion_scale: 1.0,
                })
                .unwrap();
        }
    };
    // Discovery (real time), with the scripted clock standing still; the operator
    // presses the clutch once the node has heard it released (a node does not take a
    // clutch held since before it heard it for a press).
    for _ in 0..100 {
        let clutch = node.controller().armed();
        period(clock.now_s(), Some(0.4), true, clutch);
        tokio::time::sleep(Duration::from_millis(20)).await;
        node.tick(clock.now_s());
        if node.state() == Lifecycle::Active {
            break;
        }
    }
    assert_eq!(node.state(), Lifecycle::Active, "the arm engaged");
    // Engaged: the operator moves 1 cm per period along x; the node commands motion.
    let mut x = 0.4;
    let mut moving = false;
    for _ in 0..10 {
        clock.advance_s(DT);
        x += 0.01;
        period(clock.now_s(), Some(x), true, true);
        tokio::time::sleep(Duration::from_millis(15)).await;
        node.tick(clock.now_s());
        while let Some(c) = commands.try_recv() {
            let v = wire::arm_command(&PR2_ARM_JOINTS, &c.msg).unwrap();
            moving |= v.velocity_rad_s.amax() > 1e-3;
        }
    }
    assert!(moving, "the node commands motion while engaged");
    // The wrist poses stop; pedals and state keep coming. The 0.1 s pose deadline, in
    // scripted time: still engaged up to 0.1 s, stopped in the period after.
    let t_last_pose = clock.now_s();
    let mut stopped_at = None;
    for _ in 0..6 {
        clock.advance_s(DT);
        period(clock.now_s(), None, true, true);
        tokio::time::sleep(Duration::from_millis(15)).await;
        node.tick(clock.now_s());
        // The command reaches the hardware (real time).
        tokio::time::sleep(Duration::from_millis(15)).await;
        let mut last = None;
        while let Some(c) = commands.try_recv() {
            last = Some(wire::arm_command(&PR2_ARM_JOINTS, &c.msg).unwrap());
        }
        if stopped_at.is_none() && last.is_some_and(|c| c.velocity_rad_s.amax() == 0.0) {
            stopped_at = Some(clock.now_s() - t_last_pose);
        }
    }
    let stopped_after = stopped_at.expect("the arm stopped");
    assert!(
        stopped_after > 0.1 - 1e-9 && stopped_after <= 0.1 + DT + 1e-9,
        "stopped {stopped_after} s after the last pose"
    );
    assert_eq!(
        node.state(),
        Lifecycle::Fault,
        "a latched safety stop is a fault"
    );
    let counters = node.counters();
    let stops = counters
        .iter()
        .find(|(n, _)| n == "arm.stop.stale_wrist_pose")
        .unwrap()
        .1;
    assert_eq!(stops, 1);
    // Ten scripted seconds pass with nothing from the hardware: the state counts as
    // lost (a fault) and the node commands a stop.
    clock.advance_s(10.0);
    node.tick(clock.now_s());
    assert_eq!(node.state(), Lifecycle::Fault);
    assert!(
        node.last_error().contains("no state received"),
        "{}",
        node.last_error()
    );
}
