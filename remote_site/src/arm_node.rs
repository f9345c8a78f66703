//! The PR2 arm controller node: operator inputs from the bus, the arm through an
//! [`ArmHardware`], the [`ArmController`] core in between, at the configured rate, on
//! the node runner (`teleop-node`).

use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeWatch};
use teleop_hardware::ArmHardware;
use teleop_hardware_bus::BusArm;
use teleop_interfaces::hardware::{PR2_ARM, SHADOW_HAND};
use teleop_interfaces::{nodes, topics};
use teleop_msgs::{Lifecycle, OperatorInput, PoseStamped};
use teleop_node::source::{self, CommanderConfig};
use teleop_node::{
    FinalReport, Node, NodeConfig, NodeErrors, SchedulingConfig, SourceLock, check_controller_links,
};

use crate::arm_controller::{
    ArmController, ArmControllerConfig, ArmInputs, ArmMode, OperatorSample, Pr2ArmCommand,
    WristSample,
};
use crate::command_age::CommandAges;

/// Configuration of the `pr2_arm_controller` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmNodeConfig {
    pub node_name: String,
    /// Nodes of the operator site; the arm stops when none of them is alive. Default:
    /// the operator-site node it takes commands from, the wrist tracker (poses and
    /// pedals).
    pub operator_site_nodes: Vec<String>,
    /// Nodes that command the hand on the arm, on either site (liveliness): its
    /// controller and the source of its targets. The arm moves only while every one
    /// of them is alive; losing one is a safety stop (a fresh clutch press after it is
    /// back), so the operator cannot carry a hand nobody commands into the scene.
    /// Default: the Shadow hand's controller and hand inference; empty for an arm
    /// without a hand.
    pub hand_nodes: Vec<String>,
    /// The arm hardware's state counts as lost after this long, s.
    pub hardware_timeout_s: f64,
    /// One commanding operator site at a time.
    pub commander: CommanderConfig,
    pub arm: ArmControllerConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    pub bus: BusConfig,
}

impl Default for ArmNodeConfig {
    fn default() -> Self {
        Self {
            node_name: PR2_ARM.controller_node.into(),
            operator_site_nodes: vec![nodes::WRIST_TRACKER.into()],
            hand_nodes: vec![
                SHADOW_HAND.controller_node.into(),
                nodes::HAND_INFERENCE.into(),
            ],
            hardware_timeout_s: 0.1,
            commander: CommanderConfig::default(),
            arm: ArmControllerConfig::default(),
            scheduling: SchedulingConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for ArmNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        check_controller_links(&self.operator_site_nodes, self.hardware_timeout_s)?;
        if self.hand_nodes.iter().any(|n| n.trim().is_empty()) {
            return Err("hand_nodes: a node name is empty".into());
        }
        self.commander.validate()?;
        self.arm.validate()
    }
}

pub use teleop_hardware::wire::isometry;

/// Whether every number of `pose` is finite.
fn pose_is_finite(pose: &teleop_msgs::Pose) -> bool {
    let (p, q) = (&pose.position, &pose.orientation);
    [p.x, p.y, p.z, q.x, q.y, q.z, q.w]
        .iter()
        .all(|v| v.is_finite())
}

/// The node: its subscriptions, the arm, the controller core.
#[derive(Debug)]
pub struct ArmNode {
    operator_site_nodes: Vec<String>,
    hand_nodes: Vec<String>,
    commander: CommanderConfig,
    wrist_sub: SourceLock<PoseStamped>,
    input_sub: SourceLock<OperatorInput>,
    watch: NodeWatch,
    hw: BusArm<7>,
    ctrl: ArmController,
    wrist: Option<WristSample>,
    /// The capture stamp of `wrist` (its header), ns.
    wrist_stamp_ns: u64,
    /// The capture stamp of the wrist pose the newest engagement took as the operator's
    /// reference, ns (0 before the first): in the status (`arm.engaged_from_stamp_ns`)
    /// so that an observer can measure the arm against the reference it really took.
    engaged_from_stamp_ns: u64,
    operator: Option<OperatorSample>,
    hardware_errors: u64,
    rejected_frame_ids: u64,
    /// Wrist poses refused at receipt for a NaN or infinite value.
    rejected_non_finite: u64,
    /// The wrist poses' ages when taken (none older than the deadline).
    wrist_ages: CommandAges,
    hardware_ok: bool,
    errors: NodeErrors,
}

impl ArmNode {
    /// Declares the node's subscriptions and the arm client on `bus`.
    ///
    /// # Errors
    /// Bus declarations or the controller's configuration.
    pub async fn new(cfg: &ArmNodeConfig, bus: &Bus) -> anyhow::Result<Self> {
        let ctrl =
            ArmController::new(teleop_kinematics::robots::pr2_arm_chain()?, cfg.arm.clone())?;
        let wrist_ages = CommandAges::new(
            "wrist_pose",
            "wrist_pose.sent_to_taken",
            &bus.guard_settings(&topics::WRIST_POSE.spec),
        );
        Ok(Self {
            operator_site_nodes: cfg.operator_site_nodes.clone(),
            hand_nodes: cfg.hand_nodes.clone(),
            commander: cfg.commander,
            wrist_ages,
            wrist_sub: SourceLock::new(
                bus.subscriber(&topics::WRIST_POSE).await?,
                cfg.commander.release_after_s,
            ),
            input_sub: SourceLock::new(
                bus.subscriber(&topics::OPERATOR_INPUT).await?,
                cfg.commander.release_after_s,
            ),
            watch: bus.watch_nodes().await?,
            hw: BusArm::new(bus, &PR2_ARM, cfg.hardware_timeout_s).await?,
            ctrl,
            wrist: None,
            wrist_stamp_ns: 0,
            engaged_from_stamp_ns: 0,
            operator: None,
            hardware_errors: 0,
            rejected_frame_ids: 0,
            rejected_non_finite: 0,
            hardware_ok: false,
            errors: NodeErrors::new(),
        })
    }

    /// The controller core.
    pub fn controller(&self) -> &ArmController {
        &self.ctrl
    }
}

impl Node for ArmNode {
    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.ctrl.config().rate_hz)
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        // Disengaged, a silent commander's lock may go (and, if configured, any lock:
        // the next clutch press may come from another site).
        if !self.ctrl.is_engaged() {
            self.commander
                .disengaged(now_s, &mut [&mut self.wrist_sub, &mut self.input_sub]);
        }
        if let Some(r) = self.wrist_sub.poll() {
            let cfg = self.ctrl.config();
            if !pose_is_finite(&r.msg.pose) {
                // Refused at receipt, engaged or not: it never becomes the newest pose.
                self.rejected_non_finite += 1;
                self.errors.event(
                    "wrist pose",
                    "wrist pose with a NaN or infinite value refused",
                    now_s,
                );
            } else if cfg.mode == ArmMode::Absolute
                && r.msg.header.frame_id != cfg.absolute.frame_id
            {
                // An absolute target in another frame would put the arm somewhere else.
                self.rejected_frame_ids += 1;
                let text = format!(
                    "wrist pose in frame `{}` refused: the absolute mode takes `{}` only",
                    r.msg.header.frame_id, cfg.absolute.frame_id
                );
                self.errors.event("wrist pose", text, now_s);
            } else if !self.wrist_ages.admit(
                now_s,
                r.source_timestamp_ns as f64 * 1e-9,
                r.publisher_gid,
                r.sequence,
            ) {
                // Expired between receipt and this step: never executed.
                let text = format!(
                    "wrist pose refused: older than {:.0} ms when taken",
                    self.wrist_ages.limit_s() * 1e3
                );
                self.errors.event("wrist pose", text, now_s);
            } else {
                self.wrist = Some(WristSample {
                    received_s: r.receive_time_s(),
                    pose: isometry(&r.msg.pose),
                });
                self.wrist_stamp_ns = u64::try_from(r.msg.header.stamp.as_nanos()).unwrap_or(0);
            }
        }
        if let Some(r) = self.input_sub.poll() {
            self.operator = Some(OperatorSample {
                received_s: r.receive_time_s(),
                clutch: r.msg.clutch,
                enable: r.msg.enable,
                motion_scale: r.msg.motion_scale,
            });
        }
        let alive = self
            .operator_site_nodes
            .iter()
            .any(|n| self.watch.is_alive(n));
        // Poses and pedals must come from one operator site (one Zenoh session).
        let commander_conflict = match (self.wrist_sub.locked_info(), self.input_sub.locked_info())
        {
            (Some(w), Some(i)) => w.zid != i.zid,
            _ => false,
        };
        if let Some(conflict) =
            source::conflict(now_s, &mut [&mut self.wrist_sub, &mut self.input_sub])
        {
            self.errors.event("commander", conflict, now_s);
        }
        let inputs = ArmInputs {
            operator: self.operator,
            wrist: self.wrist,
            operator_site_alive: alive,
            hand_alive: self.hand_nodes.iter().all(|n| self.watch.is_alive(n)),
            commander_conflict,
        };
        let command = match self.hw.read(now_s) {
            Ok(state) => {
                self.hardware_ok = true;
                self.errors.resolved("hardware", now_s);
                let latched = self.ctrl.latched();
                let engagements = self.ctrl.counters().engagements;
                let command = self.ctrl.step(now_s, &inputs, &state).command;
                if self.ctrl.counters().engagements > engagements {
                    self.engaged_from_stamp_ns = self.wrist_stamp_ns;
                }
                // What the operator's display shows next to the Fault state.
                if let Some(r) = self.ctrl.latched()
                    && latched != Some(r)
                {
                    let text = format!(
                        "safety stop ({}): release the clutch and press it again to go on",
                        r.name()
                    );
                    self.errors.condition("safety stop", text, now_s);
                }
                if self.ctrl.latched().is_none() {
                    self.errors.resolved("safety stop", now_s);
                }
                command
            }
            Err(e) => {
                self.hardware_ok = false;
                self.hardware_errors += 1;
                self.errors.condition("hardware", e.to_string(), now_s);
                // Without a state, command a stop (the hardware stops on its own too).
                Pr2ArmCommand::stop()
            }
        };
        if let Err(e) = self.hw.write(now_s, &command) {
            self.hardware_errors += 1;
            self.errors.event("hardware write", e.to_string(), now_s);
        }
    }

    fn state(&self) -> Lifecycle {
        // A latch by the operator's own hand (enable released) is not a fault.
        let faulted = self
            .ctrl
            .latched()
            .is_some_and(|r| r != crate::arm_controller::StopReason::EnableReleased);
        if !self.hardware_ok || faulted {
            Lifecycle::Fault
        } else if self.ctrl.is_engaged() {
            Lifecycle::Active
        } else {
            Lifecycle::Inactive
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let mut counters = self.ctrl.named_counters();
        // One counter of non-finite poses: refused at receipt here, or by the
        // controller's filter (which no longer sees them from the network).
        match counters
            .iter_mut()
            .find(|(n, _)| n == "wrist_pose.rejected_non_finite")
        {
            Some((_, v)) => *v += self.rejected_non_finite,
            None => counters.push((
                "wrist_pose.rejected_non_finite".into(),
                self.rejected_non_finite,
            )),
        }
        counters.push(("arm.hardware_errors".into(), self.hardware_errors));
        counters.push((
            "wrist_pose.rejected_frame_id".into(),
            self.rejected_frame_ids,
        ));
        counters.push(("arm.bad_hardware_states".into(), self.hw.bad_states()));
        counters.push((
            teleop_interfaces::status::arm::ENGAGED_FROM_STAMP_NS.into(),
            self.engaged_from_stamp_ns,
        ));
        counters.extend(self.wrist_sub.named_counters());
        counters.extend(self.input_sub.named_counters());
        self.wrist_ages.named(&mut counters);
        counters
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    fn shutdown(&mut self, now_s: f64) {
        if let Err(e) = self.hw.write(now_s, &Pr2ArmCommand::stop()) {
            tracing::warn!("stopping the arm at shutdown: {e}");
        }
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: ArmNodeConfig, duration: Option<Duration>) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = ArmNode::new(&cfg, &bus).await?;
    tracing::info!(
        rate_hz = cfg.arm.rate_hz,
        mode = ?cfg.arm.mode,
        "PR2 arm controller: arm disabled until clutch + enable"
    );
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}
