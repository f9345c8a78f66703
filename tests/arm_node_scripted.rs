//! The arm node on scripted time: its clock (and its bus's) is a `ManualClock` the test
//! moves, so the watchdog's deadlines are exercised exactly, not by sleeping. The node's
//! `tick` is called by the test, as the runner would call it.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::Duration;

use nalgebra::SVector;
use teleop_bus::{Bus, Clock, ManualClock, Publisher, Subscriber};
use teleop_hardware::{ArmState, wire};
use teleop_interfaces::joints::PR2_ARM_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{
    Header, JointState, Lifecycle, OperatorInput, Point, Pose, PoseStamped, Quaternion, Time,
};
use teleop_node::Node;
use teleop_remote_site::arm_node::{ArmNode, ArmNodeConfig};
use teleop_sim::WORKING_POSTURE_RAD;
use teleop_system_tests::{free_port, isolated_pair};

const DT: f64 = 1.0 / 30.0;

/// The operator site and the arm's hardware as one scripted peer, on the node's clock.
struct Script {
    clock: Arc<ManualClock>,
    /// The node's bus and the peer's, open as long as the script.
    _buses: (Bus, Bus),
    state_pub: Publisher<JointState>,
    pose_pub: Publisher<PoseStamped>,
    input_pub: Publisher<OperatorInput>,
    commands: Subscriber<JointState>,
}

impl Script {
    /// The arm node (with `cfg`) on a scripted clock, and its peer.
    async fn start(cfg: &ArmNodeConfig, domain: u32) -> (ArmNode, Self, teleop_bus::BusConfig) {
        let clock = ManualClock::starting_at(1_000_000.0);
        let shared: Arc<dyn Clock> = clock.clone();
        let (hub, spoke) = isolated_pair(domain, free_port().unwrap());
        let bus = Bus::open_with_clock("pr2_arm_controller", &hub, shared.clone())
            .await
            .unwrap();
        let node = ArmNode::new(cfg, &bus).await.unwrap();
        let peer = Bus::open_with_clock("wrist_tracker", &spoke, shared)
            .await
            .unwrap();
        let script = Self {
            clock,
            state_pub: peer.publisher(&topics::HW_PR2_ARM_STATE).await.unwrap(),
            pose_pub: peer.publisher(&topics::WRIST_POSE).await.unwrap(),
            input_pub: peer.publisher(&topics::OPERATOR_INPUT).await.unwrap(),
            commands: peer.subscriber(&topics::HW_PR2_ARM_COMMAND).await.unwrap(),
            _buses: (bus, peer),
        };
        (node, script, spoke)
    }

    /// One scripted period: the peer publishes what it is told (the arm at rest in the
    /// working posture, a wrist pose at `pose_x`, the pedals).
    fn period(&self, pose_x: Option<f64>, input: bool, clutch: bool) {
        let t = self.clock.now_s();
        let stamp = Time::from_secs_f64(t);
        self.state_pub
            .put(&wire::arm_state_msg(
                &PR2_ARM_JOINTS,
                &ArmState {
                    time_s: t,
                    position_rad: SVector::<f64, 7>::from(WORKING_POSTURE_RAD),
                    velocity_rad_s: SVector::zeros(),
                },
            ))
            .unwrap();
        if let Some(x) = pose_x {
            self.pose_pub
                .put(&PoseStamped {
                    header: Header::new(stamp, "tracker"),
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
            self.input_pub
                .put(&OperatorInput {
                    header: Header::new(stamp, ""),
                    clutch,
                    enable: true,
                    camera_stop: false,
                    motion_scale: 1.0,
                })
                .unwrap();
        }
    }

    /// Discovery (real time), with the scripted clock standing still; the operator
    /// lets go of the clutch and presses it once the node has heard it released (a node
    /// does not take a clutch held since before it heard it for a press). Whether the
    /// arm engaged.
    async fn engage(&self, node: &mut ArmNode) -> bool {
        for i in 0..100 {
            let clutch = i >= 3 && node.controller().armed();
            self.period(Some(0.4), true, clutch);
            tokio::time::sleep(Duration::from_millis(20)).await;
            node.tick(self.clock.now_s());
            if node.state() == Lifecycle::Active {
                return true;
            }
        }
        false
    }

    /// Moves the operator's hand 1 cm along x per period for `n` periods (clutch held);
    /// whether the node commanded motion.
    async fn follow(&self, node: &mut ArmNode, x: &mut f64, n: usize) -> bool {
        let mut moving = false;
        for _ in 0..n {
            self.clock.advance_s(DT);
            *x += 0.01;
            self.period(Some(*x), true, true);
            tokio::time::sleep(Duration::from_millis(15)).await;
            node.tick(self.clock.now_s());
            while let Some(c) = self.commands.try_recv() {
                let v = wire::arm_command(&PR2_ARM_JOINTS, &c.msg).unwrap();
                moving |= v.velocity_rad_s.amax() > 1e-3;
            }
        }
        moving
    }
}

fn counter(node: &ArmNode, name: &str) -> u64 {
    node.counters()
        .iter()
        .find(|(n, _)| n == name)
        .map_or(0, |(_, v)| *v)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_arm_node_stops_on_scripted_time() {
    // The arm alone: no hand whose commanders it would wait for.
    let cfg = ArmNodeConfig {
        hand_nodes: Vec::new(),
        ..ArmNodeConfig::default()
    };
    let (mut node, script, _) = Script::start(&cfg, 26).await;
    let clock = &script.clock;
    assert!(script.engage(&mut node).await, "the arm engaged");
    // Engaged: the operator moves 1 cm per period along x; the node commands motion.
    let mut x = 0.4;
    assert!(
        script.follow(&mut node, &mut x, 10).await,
        "the node commands motion while engaged"
    );
    // The wrist poses stop; pedals and state keep coming. The 0.1 s pose deadline, in
    // scripted time: still engaged up to 0.1 s, stopped in the period after.
    let t_last_pose = clock.now_s();
    let mut stopped_at = None;
    for _ in 0..6 {
        clock.advance_s(DT);
        script.period(None, true, true);
        tokio::time::sleep(Duration::from_millis(15)).await;
        node.tick(clock.now_s());
        // The command reaches the hardware (real time).
        tokio::time::sleep(Duration::from_millis(15)).await;
        let mut last = None;
        while let Some(c) = script.commands.try_recv() {
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
    assert_eq!(counter(&node, "arm.stop.stale_wrist_pose"), 1);
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_arm_moves_only_while_the_hand_has_a_controller() {
    // The arm waits for the Shadow hand's controller only here (by default for hand
    // inference too).
    let cfg = ArmNodeConfig {
        hand_nodes: vec!["shadow_hand_controller".into()],
        ..ArmNodeConfig::default()
    };
    let (mut node, script, spoke) = Script::start(&cfg, 27).await;
    // No hand controller on the bus: the operator presses, the arm does not engage.
    assert!(
        !script.engage(&mut node).await,
        "engaged without a hand controller"
    );
    assert!(counter(&node, "arm.stop.hand_node_lost") >= 1);
    // The hand's controller appears (its liveliness token, with the node's name).
    let hand = Bus::open_with_clock("shadow_hand_controller", &spoke, script.clock.clone())
        .await
        .unwrap();
    assert!(
        script.engage(&mut node).await,
        "the arm engaged with the hand controlled"
    );
    let mut x = 0.4;
    assert!(script.follow(&mut node, &mut x, 5).await, "the arm follows");
    // The hand's controller goes (a crash: its session closes): the arm stops and
    // latches while the operator goes on moving.
    drop(hand);
    let mut stopped = false;
    for _ in 0..100 {
        if !script.follow(&mut node, &mut x, 1).await && node.state() != Lifecycle::Active {
            stopped = true;
            break;
        }
    }
    assert!(stopped, "the arm stopped without the hand's controller");
    assert_eq!(node.state(), Lifecycle::Fault, "a latched safety stop");
    assert_eq!(counter(&node, "arm.stop.hand_node_lost"), 2);
    // It comes back; the clutch is still held: no motion until a fresh press.
    let _hand = Bus::open_with_clock("shadow_hand_controller", &spoke, script.clock.clone())
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(
        !script.follow(&mut node, &mut x, 10).await,
        "moved on the held clutch"
    );
    assert_eq!(node.state(), Lifecycle::Fault);
    assert!(
        script.engage(&mut node).await,
        "a fresh press engages again"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_start_up_error_is_marked_recovered_once_its_cause_is_gone() {
    let cfg = ArmNodeConfig {
        hand_nodes: Vec::new(),
        ..ArmNodeConfig::default()
    };
    let (mut node, script, _) = Script::start(&cfg, 28).await;
    // Nothing from the hardware yet: a fault, named.
    node.tick(script.clock.now_s());
    assert_eq!(node.state(), Lifecycle::Fault);
    let before = node.last_error();
    assert!(
        before == "hardware not connected: no pr2_arm state received yet",
        "{before}"
    );
    // The hardware answers and the operator engages: the error is no longer current,
    // shown as recovered with the time, the original text kept.
    assert!(script.engage(&mut node).await, "the arm engaged");
    let after = node.last_error();
    assert!(
        after.starts_with(teleop_node::errors::RECOVERED_PREFIX) && after.ends_with(&before),
        "{after}"
    );
    // The scripted clock starts at 1e6 s after the epoch: 13:46:40 UTC.
    assert!(after.contains("13:46:40"), "{after}");
}
