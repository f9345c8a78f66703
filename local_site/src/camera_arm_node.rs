//! The `camera_arm` node (thesis ch. 7.4): the operator's hand pose and pedals from the
//! bus, the UR5 through a [`BusArm`], the [`CameraArmController`] core in between, at
//! the core's rate, on the node runner (`teleop-node`).
//!
//! # Inputs and outputs
//!
//! * [`topics::WRIST_POSE`]: the operator's hand frame (Fig. 3.6) in the UR5 base frame,
//!   from the wrist tracker; locked onto one publisher ([`SourceLock`]), as are the
//!   pedals ([`topics::OPERATOR_INPUT`]: enable, `camera_stop` = the left pedal).
//! * The UR5 through [`UR5_ARM`] (`teleop/hw/ur5/{state,command}`): its owner accepts
//!   commands from the node named `camera_arm` only.
//! * [`topics::CAMERA_POSE`]: the camera's optical frame in the UR5 base frame
//!   ([`CAMERA_POSE_FRAME`]), the nominal FK of the **measured** joints, stamped with
//!   the measurement's time (`ArmState::time_s`), so hand inference knows where the
//!   camera was when a depth frame was taken. [`topics::UR5_JOINT_STATES`]: the
//!   measured joints. Both are published every tick that has a fresh, new hardware state
//!   (a state already published is not published again).
//!
//! # Safety
//!
//! No fresh hardware state: zero velocity, lifecycle `Fault`, `last_error` naming it.
//! None of the watched operator-site nodes alive, or the hand poses and pedals locked to
//! different sessions while the camera is not following: the pedals are withheld from
//! the core, which stops (`camera_arm.stop.stale_operator_input`). Shutdown commands
//! zero velocity.

use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeWatch, Publisher};
use teleop_collision::{ChainBodies, robots as collision_robots};
use teleop_hardware::{ArmCommand, ArmHardware, ArmState, wire};
use teleop_hardware_bus::BusArm;
use teleop_interfaces::hardware::UR5_ARM;
use teleop_interfaces::{nodes, topics};
use teleop_msgs::{Header, JointState, Lifecycle, OperatorInput, PoseStamped, Time};
use teleop_node::source::{self, CommanderConfig};
use teleop_node::{
    FinalReport, Node, NodeConfig, NodeErrors, SchedulingConfig, SourceLock, check_controller_links,
};

use crate::camera_arm::{
    CameraArmConfig, CameraArmController, CameraInputs, CameraStep, CameraStopReason, HandSample,
    PedalSample, UR5_DOF,
};

/// Frame id of the published camera poses: the UR5's base frame.
pub const CAMERA_POSE_FRAME: &str = "ur5_base_link";

/// Configuration of the `camera_arm` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraArmNodeConfig {
    /// Node name; the UR5's owner takes commands only from `camera_arm`.
    pub node_name: String,
    /// Operator-site nodes the hand poses and pedals come from; the arm stops when none
    /// of them is alive. Default: the wrist tracker.
    pub operator_site_nodes: Vec<String>,
    /// The UR5's state counts as lost after this long, s.
    pub hardware_timeout_s: f64,
    /// One source of hand poses and pedals at a time.
    pub commander: CommanderConfig,
    /// The control core (its `rate_hz` is the node's rate).
    pub camera_arm: CameraArmConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    /// The Zenoh session.
    pub bus: BusConfig,
}

impl Default for CameraArmNodeConfig {
    fn default() -> Self {
        Self {
            node_name: UR5_ARM.controller_node.into(),
            operator_site_nodes: vec![nodes::WRIST_TRACKER.into()],
            hardware_timeout_s: 0.1,
            commander: CommanderConfig::default(),
            camera_arm: CameraArmConfig::default(),
            scheduling: SchedulingConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for CameraArmNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        if self.node_name.is_empty() {
            return Err("node_name must not be empty".into());
        }
        check_controller_links(&self.operator_site_nodes, self.hardware_timeout_s)?;
        self.commander.validate()?;
        self.camera_arm.validate()
    }
}

pub use teleop_hardware::wire::{isometry, pose_msg};

/// The camera arm controller core for the UR5 camera chain (nominal model) and its
/// collision bodies.
///
/// # Errors
/// The embedded models failing to build, or an invalid `cfg`.
pub fn build_controller(cfg: CameraArmConfig) -> anyhow::Result<CameraArmController> {
    let robot = teleop_kinematics::robots::ur5()?;
    let model = collision_robots::ur5(&robot)?;
    let chain = teleop_kinematics::robots::ur5_camera_chain()?;
    let bodies = Arc::new(ChainBodies::new(&model, &robot, &chain)?);
    Ok(CameraArmController::new(chain, bodies, cfg)?)
}

/// The node: its subscriptions and publishers, the UR5, the controller core.
#[derive(Debug)]
pub struct CameraArmNode {
    operator_site_nodes: Vec<String>,
    commander: CommanderConfig,
    wrist_sub: SourceLock<PoseStamped>,
    input_sub: SourceLock<OperatorInput>,
    watch: NodeWatch,
    hw: BusArm<UR5_DOF>,
    camera_pose_pub: Publisher<PoseStamped>,
    joint_states_pub: Publisher<JointState>,
    ctrl: CameraArmController,
    hand: Option<HandSample>,
    pedals: Option<PedalSample>,
    last_step: Option<CameraStep>,
    /// Time of the newest hardware state published.
    published_state_s: f64,
    site_alive: bool,
    hardware_ok: bool,
    hardware_errors: u64,
    publish_errors: u64,
    camera_poses_published: u64,
    joint_states_published: u64,
    operator_site_lost: u64,
    commander_conflicts: u64,
    errors: NodeErrors,
}

impl CameraArmNode {
    /// Declares the node's subscriptions, publishers and the UR5 client on `bus`.
    ///
    /// # Errors
    /// Bus declarations, the embedded models or the controller's configuration.
    pub async fn new(cfg: &CameraArmNodeConfig, bus: &Bus) -> anyhow::Result<Self> {
        let ctrl = build_controller(cfg.camera_arm.clone())?;
        Ok(Self {
            operator_site_nodes: cfg.operator_site_nodes.clone(),
            commander: cfg.commander,
            wrist_sub: SourceLock::new(
                bus.subscriber(&topics::WRIST_POSE).await?,
                cfg.commander.release_after_s,
            ),
            input_sub: SourceLock::new(
                bus.subscriber(&topics::OPERATOR_INPUT).await?,
                cfg.commander.release_after_s,
            ),
            watch: bus.watch_nodes().await?,
            hw: BusArm::new(bus, &UR5_ARM, cfg.hardware_timeout_s).await?,
            camera_pose_pub: bus.publisher(&topics::CAMERA_POSE).await?,
            joint_states_pub: bus.publisher(&topics::UR5_JOINT_STATES).await?,
            ctrl,
            hand: None,
            pedals: None,
            last_step: None,
            published_state_s: f64::NEG_INFINITY,
            site_alive: false,
            hardware_ok: false,
            hardware_errors: 0,
            publish_errors: 0,
            camera_poses_published: 0,
            joint_states_published: 0,
            operator_site_lost: 0,
            commander_conflicts: 0,
            errors: NodeErrors::new(),
        })
    }

    /// The controller core.
    pub fn controller(&self) -> &CameraArmController {
        &self.ctrl
    }

    /// The core's result at the last tick that had a hardware state.
    pub fn last_step(&self) -> Option<&CameraStep> {
        self.last_step.as_ref()
    }

    /// Publishes the camera pose (FK of the measured joints) and the joint states, once
    /// per new hardware state.
    fn publish_state(&mut self, now_s: f64, state: &ArmState<UR5_DOF>) {
        if state.time_s.is_nan() || state.time_s <= self.published_state_s {
            return;
        }
        self.published_state_s = state.time_s;
        let mut joints = wire::arm_state_msg(&UR5_ARM.joints, state);
        // The same stamp as the camera pose's, to the nanosecond.
        joints.header.stamp = Time::from_secs_f64(state.time_s);
        match self.joint_states_pub.put(&joints) {
            Ok(()) => self.joint_states_published += 1,
            Err(e) => {
                self.publish_errors += 1;
                let text = format!("publishing the UR5 joint states: {e}");
                self.errors.event("publish", text, now_s);
            }
        }
        // A non-finite state gives no pose (the core stops on it).
        if !state.position_rad.iter().all(|v| v.is_finite()) {
            return;
        }
        let Some(pose) = pose_msg(&self.ctrl.chain().end_pose(&state.position_rad)) else {
            return;
        };
        let msg = PoseStamped {
            header: Header::new(Time::from_secs_f64(state.time_s), CAMERA_POSE_FRAME),
            pose,
        };
        match self.camera_pose_pub.put(&msg) {
            Ok(()) => self.camera_poses_published += 1,
            Err(e) => {
                self.publish_errors += 1;
                let text = format!("publishing the camera pose: {e}");
                self.errors.event("publish", text, now_s);
            }
        }
    }

    /// The pedals as the core may see them: withheld while no watched operator-site
    /// node is alive, or while poses and pedals come from different sessions and the
    /// camera is not following yet.
    fn gated_pedals(&mut self, now_s: f64) -> Option<PedalSample> {
        let alive = self
            .operator_site_nodes
            .iter()
            .any(|n| self.watch.is_alive(n));
        if self.site_alive && !alive {
            self.operator_site_lost += 1;
            let text = format!(
                "operator site lost: none of {} alive",
                self.operator_site_nodes.join(", ")
            );
            self.errors.condition("operator site", text, now_s);
        }
        if alive {
            self.errors.resolved("operator site", now_s);
        }
        self.site_alive = alive;
        if !alive {
            return None;
        }
        let conflict = match (self.wrist_sub.locked_info(), self.input_sub.locked_info()) {
            (Some(w), Some(i)) => w.zid != i.zid,
            _ => false,
        };
        if conflict && !self.ctrl.is_following() {
            self.commander_conflicts += 1;
            self.errors.event(
                "commander",
                "hand poses and pedals come from different sessions: camera arm held",
                now_s,
            );
            return None;
        }
        self.pedals
    }
}

impl Node for CameraArmNode {
    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.ctrl.config().rate_hz)
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        // Not following, a silent source's lock may go (and, if configured, any lock).
        if !self.ctrl.is_following() {
            self.commander
                .disengaged(now_s, &mut [&mut self.wrist_sub, &mut self.input_sub]);
        }
        if let Some(r) = self.wrist_sub.poll() {
            self.hand = Some(HandSample {
                received_s: r.receive_time_s(),
                pose: isometry(&r.msg.pose),
            });
        }
        if let Some(r) = self.input_sub.poll() {
            self.pedals = Some(PedalSample {
                received_s: r.receive_time_s(),
                enable: r.msg.enable,
                camera_stop: r.msg.camera_stop,
            });
        }
        if let Some(conflict) =
            source::conflict(now_s, &mut [&mut self.wrist_sub, &mut self.input_sub])
        {
            self.errors.event("commander", conflict, now_s);
        }
        let inputs = CameraInputs {
            hand: self.hand,
            pedals: self.gated_pedals(now_s),
        };
        let command = match self.hw.read(now_s) {
            Ok(state) => {
                self.hardware_ok = true;
                self.errors.resolved("hardware", now_s);
                self.publish_state(now_s, &state);
                let step = self.ctrl.step(now_s, &inputs, &state);
                if let Some(
                    r @ (CameraStopReason::InvalidArmState
                    | CameraStopReason::IkFailed
                    | CameraStopReason::TooCloseToHand),
                ) = step.stopped
                {
                    let text = format!("camera arm holds: {}", r.name());
                    self.errors.event("camera arm holds", text, now_s);
                }
                self.last_step = Some(step);
                step.command
            }
            Err(e) => {
                self.hardware_ok = false;
                self.hardware_errors += 1;
                self.errors
                    .condition("hardware", format!("UR5: {e}"), now_s);
                // Without a state, command a stop (the hardware stops on its own too).
                ArmCommand::stop()
            }
        };
        if let Err(e) = self.hw.write(now_s, &command) {
            self.hardware_errors += 1;
            self.errors
                .event("hardware write", format!("UR5: {e}"), now_s);
        }
    }

    fn state(&self) -> Lifecycle {
        let bad_state = self
            .last_step
            .is_some_and(|s| s.stopped == Some(CameraStopReason::InvalidArmState));
        if !self.hardware_ok || bad_state {
            Lifecycle::Fault
        } else if self.ctrl.is_following() {
            Lifecycle::Active
        } else {
            Lifecycle::Inactive
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let mut counters = self.ctrl.named_counters();
        counters.extend([
            (
                "camera_arm.hardware_errors".to_owned(),
                self.hardware_errors,
            ),
            (
                "camera_arm.bad_hardware_states".to_owned(),
                self.hw.bad_states(),
            ),
            (
                "camera_arm.camera_poses_published".to_owned(),
                self.camera_poses_published,
            ),
            (
                "camera_arm.joint_states_published".to_owned(),
                self.joint_states_published,
            ),
            ("camera_arm.publish_errors".to_owned(), self.publish_errors),
            (
                "camera_arm.operator_site_lost".to_owned(),
                self.operator_site_lost,
            ),
            (
                "camera_arm.commander_conflict_holds".to_owned(),
                self.commander_conflicts,
            ),
        ]);
        counters.extend(self.wrist_sub.named_counters());
        counters.extend(self.input_sub.named_counters());
        counters
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    fn shutdown(&mut self, now_s: f64) {
        if let Err(e) = self.hw.write(now_s, &ArmCommand::stop()) {
            tracing::warn!("stopping the UR5 at shutdown: {e}");
        }
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(
    cfg: CameraArmNodeConfig,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    if cfg.node_name != UR5_ARM.controller_node {
        tracing::warn!(
            node_name = cfg.node_name,
            expected = UR5_ARM.controller_node,
            "the UR5's owner takes commands from its controller node only: this node's will be refused"
        );
    }
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = CameraArmNode::new(&cfg, &bus).await?;
    tracing::info!(
        rate_hz = cfg.camera_arm.rate_hz,
        side = ?cfg.camera_arm.side,
        "camera arm: the UR5 follows the hand while enable is held and the left pedal released"
    );
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}
