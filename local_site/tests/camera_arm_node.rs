//! The camera arm node on scripted time, over in-process Zenoh sessions on loopback: a
//! fake UR5 owner (a perfect velocity integrator behind an `ArmEndpoint`), a fake
//! wrist tracker (hand poses and pedals) and an intruding second station, all on one
//! `ManualClock` the test moves; the node's `tick` is called by the test, as the runner
//! would call it.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::{Isometry3, Matrix3, Rotation3, SVector, UnitQuaternion, Vector3};
use teleop_bus::{Bus, Clock, ManualClock, Publisher, Subscriber};
use teleop_hardware::{ArmState, wire};
use teleop_hardware_bus::ArmEndpoint;
use teleop_interfaces::hardware::UR5_ARM;
use teleop_interfaces::joints::UR5_JOINTS;
use teleop_interfaces::topics;
use teleop_kinematics::{FixedChain, robots};
use teleop_local_site::camera_arm::{CameraStopReason, UR5_DOF};
use teleop_local_site::camera_arm_node::{
    CAMERA_POSE_FRAME, CameraArmNode, CameraArmNodeConfig, isometry, pose_msg,
};
use teleop_msgs::{Header, JointState, Lifecycle, OperatorInput, PoseStamped, Time};
use teleop_node::Node;

type Q = SVector<f64, UR5_DOF>;
const DT: f64 = 1.0 / 30.0;
/// Real time for a sample to cross the loopback.
const DELIVERY: Duration = Duration::from_millis(12);

fn free_port() -> u16 {
    teleop_bus::testing::free_port().unwrap()
}

use teleop_bus::testing::isolated_pair;

fn q0() -> Q {
    Q::from([0.0, -1.57, 1.0, 0.57, 1.57, 0.0])
}

/// The hand pose whose palm-side goal is the camera pose `camera` (inverse of
/// `camera_goal` with the default settings).
fn hand_for_camera(camera: &Isometry3<f64>) -> Isometry3<f64> {
    let r = camera.rotation;
    let (xc, yc, zc) = (r * Vector3::x(), r * Vector3::y(), r * Vector3::z());
    let (hx, hy, hz) = (-xc, -zc, -yc);
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::from_columns(&[hx, hy, hz]),
    ));
    let centre = camera.translation.vector + zc * 0.40;
    let wrist = centre - rot * Vector3::new(0.0, 0.0, 0.08);
    Isometry3::from_parts(wrist.into(), rot)
}

/// Poses equal to float precision.
fn close(a: Option<Isometry3<f64>>, b: &Isometry3<f64>) -> bool {
    a.is_some_and(|a| {
        (a.translation.vector - b.translation.vector).norm() < 1e-9
            && a.rotation.angle_to(&b.rotation) < 1e-6
    })
}

fn ns(t: f64) -> i64 {
    (t * 1e9).round() as i64
}

/// What the fake stations send in one period.
#[derive(Debug, Clone, Copy)]
struct Send {
    hand: Option<Isometry3<f64>>,
    /// (enable, camera_stop)
    pedals: Option<(bool, bool)>,
    intruder_hand: Option<Isometry3<f64>>,
    /// The UR5 owner publishes its state.
    hardware: bool,
}

impl Send {
    fn follow(hand: Isometry3<f64>) -> Self {
        Self {
            hand: Some(hand),
            pedals: Some((true, false)),
            intruder_hand: None,
            hardware: true,
        }
    }
}

struct Rig {
    clock: Arc<ManualClock>,
    chain: FixedChain<UR5_DOF>,
    node: CameraArmNode,
    owner: ArmEndpoint<UR5_DOF>,
    /// The owner's joints and the velocity it applies (the last command taken).
    q: Q,
    v: Q,
    /// Whether the owner took a command in the last period, and which.
    taken: Option<Q>,
    /// Every state the owner published, by stamp (ns).
    states: BTreeMap<i64, Q>,
    pose_pub: Publisher<PoseStamped>,
    input_pub: Publisher<OperatorInput>,
    intruder_pub: Publisher<PoseStamped>,
    camera_poses: Subscriber<PoseStamped>,
    joint_states: Subscriber<JointState>,
    /// What the node published, as received.
    camera_pose_msgs: Vec<PoseStamped>,
    joint_state_msgs: Vec<JointState>,
    _buses: Vec<Bus>,
}

impl Rig {
    async fn new(domain_id: u32) -> Self {
        let clock = ManualClock::starting_at(1_700_000_000.0);
        let shared: Arc<dyn Clock> = clock.clone();
        let (hub, spoke) = isolated_pair(domain_id, free_port());
        let cfg = CameraArmNodeConfig::default();
        let node_bus = Bus::open_with_clock(&cfg.node_name, &hub, shared.clone())
            .await
            .unwrap();
        let node = CameraArmNode::new(&cfg, &node_bus).await.unwrap();
        let owner_bus = Bus::open_with_clock("local_sim", &spoke, shared.clone())
            .await
            .unwrap();
        let owner = ArmEndpoint::<UR5_DOF>::new(&owner_bus, &UR5_ARM, UR5_ARM.controller_node)
            .await
            .unwrap();
        let camera_poses = owner_bus.subscriber(&topics::CAMERA_POSE).await.unwrap();
        let joint_states = owner_bus
            .subscriber(&topics::UR5_JOINT_STATES)
            .await
            .unwrap();
        let tracker_bus = Bus::open_with_clock("wrist_tracker", &spoke, shared.clone())
            .await
            .unwrap();
        let pose_pub = tracker_bus.publisher(&topics::WRIST_POSE).await.unwrap();
        let input_pub = tracker_bus
            .publisher(&topics::OPERATOR_INPUT)
            .await
            .unwrap();
        let intruder_bus = Bus::open_with_clock("second_station", &spoke, shared)
            .await
            .unwrap();
        let intruder_pub = intruder_bus.publisher(&topics::WRIST_POSE).await.unwrap();
        Self {
            clock,
            chain: robots::ur5_camera_chain().unwrap(),
            node,
            owner,
            q: q0(),
            v: Q::zeros(),
            taken: None,
            states: BTreeMap::new(),
            pose_pub,
            input_pub,
            intruder_pub,
            camera_poses,
            joint_states,
            camera_pose_msgs: Vec::new(),
            joint_state_msgs: Vec::new(),
            _buses: vec![node_bus, owner_bus, tracker_bus, intruder_bus],
        }
    }

    fn pose_stamped(&self, pose: &Isometry3<f64>) -> PoseStamped {
        PoseStamped {
            header: Header::new(Time::from_nanos(ns(self.clock.now_s())), "ur5_base_link"),
            pose: pose_msg(pose).unwrap(),
        }
    }

    /// One scripted period: the clock moves on, the owner applies the command it took
    /// over the period and publishes its state, the stations publish, the samples
    /// arrive (real time), the node ticks, its command arrives.
    async fn period(&mut self, send: Send) {
        self.clock.advance_s(DT);
        let t = self.clock.now_s();
        self.taken = self.owner.take_command().map(|c| c.velocity_rad_s);
        if let Some(v) = self.taken {
            self.v = v;
        }
        self.q += self.v * DT;
        if send.hardware {
            let state = ArmState {
                time_s: t,
                position_rad: self.q,
                velocity_rad_s: self.v,
            };
            self.owner.publish_state(&state).unwrap();
            // Keyed by the stamp the state goes out with.
            let stamp = wire::arm_state_msg(&UR5_JOINTS, &state).header.stamp;
            self.states.insert(stamp.as_nanos(), self.q);
        }
        if let Some(hand) = send.hand {
            self.pose_pub.put(&self.pose_stamped(&hand)).unwrap();
        }
        if let Some(hand) = send.intruder_hand {
            self.intruder_pub.put(&self.pose_stamped(&hand)).unwrap();
        }
        if let Some((enable, camera_stop)) = send.pedals {
            self.input_pub
                .put(&OperatorInput {
                    header: Header::new(Time::from_nanos(ns(t)), ""),
                    clutch: false,
                    enable,
                    camera_stop,
                    motion_scale: 1.0,
                })
                .unwrap();
        }
        tokio::time::sleep(DELIVERY).await;
        self.node.tick(t);
        tokio::time::sleep(DELIVERY).await;
        // State topics keep only the newest sample: collect them every period.
        while let Some(r) = self.camera_poses.try_recv() {
            self.camera_pose_msgs.push(r.msg);
        }
        while let Some(r) = self.joint_states.try_recv() {
            self.joint_state_msgs.push(r.msg);
        }
    }

    fn camera(&self) -> Isometry3<f64> {
        self.chain.end_pose(&self.q)
    }

    fn counter(&self, name: &str) -> u64 {
        self.node
            .counters()
            .into_iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no counter {name}"))
            .1
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_camera_arm_node_follows_the_hand_obeys_the_pedals_and_stops() {
    let mut rig = Rig::new(61).await;
    let q_goal = q0() + Q::from([0.2, 0.1, -0.15, 0.1, 0.1, 0.2]);
    let hand = hand_for_camera(&rig.chain.end_pose(&q_goal));

    // Discovery (real time) with the enable switch held but no hand pose: the node
    // hears the hardware and the pedals, and holds the arm still.
    let mut ready = false;
    for _ in 0..150 {
        rig.period(Send {
            hand: None,
            ..Send::follow(hand)
        })
        .await;
        assert_eq!(rig.q, q0(), "no hand pose, no motion");
        if rig.node.state() == Lifecycle::Inactive
            && rig
                .node
                .last_step()
                .is_some_and(|s| s.stopped == Some(CameraStopReason::NoHandPose))
            && rig.taken.is_some()
        {
            ready = true;
            break;
        }
    }
    assert!(
        ready,
        "the node never saw the hardware and the pedals: {:?}, {}",
        rig.node.last_step(),
        rig.node.last_error()
    );
    for _ in 0..5 {
        rig.period(Send {
            hand: None,
            ..Send::follow(hand)
        })
        .await;
        assert_eq!(rig.taken, Some(Q::zeros()), "zero velocity without a pose");
    }
    assert_eq!(rig.q, q0());

    // Hand poses arrive: the camera converges onto the core's goal.
    let mut err = f64::INFINITY;
    let mut active = false;
    for _ in 0..(8.0 / DT) as usize {
        rig.period(Send::follow(hand)).await;
        active |= rig.node.state() == Lifecycle::Active;
        let goal = rig.node.controller().goal_for(&hand);
        err = (rig.camera().translation.vector - goal.translation.vector).norm();
        if err < 0.01 {
            break;
        }
    }
    assert!(active, "the node reported Active while following");
    assert!(err < 0.03, "camera {err} m from its goal");
    // It stays there (and the camera poses below have a second of them to check).
    for _ in 0..30 {
        rig.period(Send::follow(hand)).await;
        let goal = rig.node.controller().goal_for(&hand);
        err = (rig.camera().translation.vector - goal.translation.vector).norm();
        assert!(err < 0.03, "camera {err} m from its goal while holding");
    }
    let step = *rig.node.last_step().unwrap();
    let goal = rig.node.controller().goal_for(&hand);
    assert_eq!(step.stopped, None);
    assert!(close(step.goal, &goal), "{:?} != {goal:?}", step.goal);
    let view = (rig.camera().rotation * Vector3::z()).angle(&(goal.rotation * Vector3::z()));
    assert!(
        view.to_degrees() < 5.0,
        "view off by {} deg",
        view.to_degrees()
    );

    // The camera poses: stamped with the measured state's time, in the UR5 base frame,
    // the FK of the published joints (and of the owner's state at that stamp).
    let mut joints_by_stamp = BTreeMap::new();
    for msg in &rig.joint_state_msgs {
        let s = wire::arm_state(&UR5_JOINTS, msg).unwrap();
        joints_by_stamp.insert(msg.header.stamp.as_nanos(), s.position_rad);
    }
    let mut checked = 0;
    for msg in &rig.camera_pose_msgs {
        assert_eq!(msg.header.frame_id, CAMERA_POSE_FRAME);
        let stamp = msg.header.stamp.as_nanos();
        // Times are f64 seconds since the epoch: a quarter of a microsecond apart.
        let (_, owner_q) = rig
            .states
            .range(stamp - 1000..=stamp + 1000)
            .next()
            .unwrap_or_else(|| panic!("a camera pose stamped {stamp} ns, no state then"));
        let Some(q) = joints_by_stamp.get(&stamp) else {
            continue;
        };
        assert!((q - owner_q).amax() < 1e-12);
        let fk = rig.chain.end_pose(q);
        let pose = isometry(&msg.pose);
        assert!((pose.translation.vector - fk.translation.vector).norm() < 1e-9);
        assert!(pose.rotation.angle_to(&fk.rotation) < 1e-6);
        checked += 1;
    }
    assert!(checked > 20, "only {checked} camera poses checked");
    assert!(rig.counter("camera_arm.camera_poses_published") > 20);
    assert!(rig.counter("camera_arm.joint_states_published") > 20);

    // A second station's hand poses are refused, counted, reported, never followed.
    let elsewhere = Isometry3::translation(0.0, 0.3, 0.0) * hand;
    for _ in 0..20 {
        rig.period(Send {
            intruder_hand: Some(elsewhere),
            ..Send::follow(hand)
        })
        .await;
    }
    assert!(rig.counter("wrist_pose.rejected_foreign") > 0);
    assert_eq!(rig.counter("wrist_pose.source_locks"), 1);
    assert!(rig.counter("wrist_pose.conflicts") >= 1);
    assert!(
        rig.node.last_error().contains("conflicting commander"),
        "{}",
        rig.node.last_error()
    );
    assert!(
        close(rig.node.last_step().unwrap().goal, &goal),
        "following the intruder"
    );
    assert_eq!(rig.node.state(), Lifecycle::Active);

    // The left pedal stops it at once, while the hand moves on.
    let moved = Isometry3::translation(0.1, 0.0, 0.0) * hand;
    let press = Send {
        pedals: Some((true, true)),
        ..Send::follow(moved)
    };
    rig.period(press).await;
    assert_eq!(
        rig.node.last_step().unwrap().stopped,
        Some(CameraStopReason::CameraStopPedal)
    );
    rig.period(press).await;
    let held = rig.q;
    for _ in 0..10 {
        assert_eq!(
            rig.taken,
            Some(Q::zeros()),
            "zero velocity with the left pedal"
        );
        rig.period(press).await;
        assert_eq!(rig.node.state(), Lifecycle::Inactive);
    }
    assert_eq!(
        rig.q, held,
        "the arm stood still with the left pedal pressed"
    );
    assert_eq!(rig.counter("camera_arm.stop.camera_stop_pedal"), 1);

    // The hand poses stop (the tracker lost the hand) while the pedal is still
    // pressed, longer than the pose deadline; then the pedal is released: no motion.
    for _ in 0..10 {
        rig.period(Send {
            hand: None,
            ..press
        })
        .await;
    }
    let no_pose = Send {
        hand: None,
        ..Send::follow(moved)
    };
    for _ in 0..10 {
        rig.period(no_pose).await;
        assert_eq!(rig.node.state(), Lifecycle::Inactive);
    }
    assert_eq!(rig.q, held, "no hand pose, no motion");
    assert_eq!(
        rig.node.last_step().unwrap().stopped,
        Some(CameraStopReason::NoHandPose)
    );

    // Following again: the arm moves toward the moved hand.
    for _ in 0..10 {
        rig.period(Send::follow(moved)).await;
    }
    assert_eq!(rig.node.state(), Lifecycle::Active);
    assert!(rig.v.amax() > 1e-3, "moving again");

    // The hardware falls silent: a fault naming it, and a stop command.
    for _ in 0..6 {
        rig.period(Send {
            hardware: false,
            ..Send::follow(moved)
        })
        .await;
    }
    assert_eq!(rig.node.state(), Lifecycle::Fault);
    assert!(
        rig.node.last_error().contains("no state received"),
        "{}",
        rig.node.last_error()
    );
    assert!(rig.counter("camera_arm.hardware_errors") > 0);
    assert_eq!(rig.taken, Some(Q::zeros()));

    // Back, following, then shut down: the last command is zero velocity.
    for _ in 0..10 {
        rig.period(Send::follow(moved)).await;
    }
    assert_eq!(rig.node.state(), Lifecycle::Active);
    assert!(rig.v.amax() > 1e-3, "moving before the shutdown");
    rig.node.shutdown(rig.clock.now_s());
    tokio::time::sleep(DELIVERY * 2).await;
    let last = rig.owner.take_command().expect("a command at shutdown");
    assert_eq!(last.velocity_rad_s, Q::zeros(), "shutdown stops the arm");
}

#[test]
fn the_node_config_validates_and_names_bad_fields() {
    use teleop_node::NodeConfig;
    use teleop_node::config::parse_toml;
    assert!(CameraArmNodeConfig::default().validate().is_ok());
    let err = parse_toml::<CameraArmNodeConfig>("[camera_arm]\nstandof_m = 0.4\n").unwrap_err();
    assert!(err.contains("standof_m"), "{err}");
    let cfg: CameraArmNodeConfig = parse_toml("operator_site_nodes = []\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("operator_site_nodes"));
    let cfg: CameraArmNodeConfig = parse_toml("hardware_timeout_s = 0.0\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("hardware_timeout_s"));
    let cfg: CameraArmNodeConfig = parse_toml("[camera_arm]\nrate_hz = 0.0\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("rate_hz"));
}
