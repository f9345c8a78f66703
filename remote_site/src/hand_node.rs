//! The Shadow hand controller node: finger targets from the operator site's hand
//! inference and the enable switch from the bus, the hand through a [`HandHardware`],
//! the [`HandSupervisor`] core in between, at the configured rate, on the node runner.

use std::time::Duration;

use nalgebra::SVector;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeWatch};
use teleop_control::OperatorSample;
use teleop_hardware::{ArmHardware, HandCommand, HandHardware};
use teleop_hardware_bus::{BusArm, BusHand};
use teleop_interfaces::hardware::{PR2_ARM, SHADOW_HAND};
use teleop_interfaces::{nodes, topics};
use teleop_msgs::{JointState, Lifecycle, OperatorInput};
use teleop_node::source::{self, CommanderConfig};
use teleop_node::{
    FinalReport, LatencyHistogram, Node, NodeConfig, NodeErrors, SchedulingConfig, SourceLock,
    check_controller_links,
};

use crate::command_age::CommandAges;
use crate::hand_controller::{HandSupervisor, HandSupervisorConfig};

/// Configuration of the `shadow_hand_controller` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandNodeConfig {
    pub node_name: String,
    /// Nodes of the operator site; the hand holds when none of them is alive. Default:
    /// the operator-site nodes it takes commands from: the wrist tracker (pedals) and
    /// hand inference (finger targets).
    pub operator_site_nodes: Vec<String>,
    /// The hand hardware's state counts as lost after this long, s.
    pub hardware_timeout_s: f64,
    /// One commanding operator site at a time (finger targets and pedals).
    pub commander: CommanderConfig,
    pub hand: HandSupervisorConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    pub bus: BusConfig,
}

impl Default for HandNodeConfig {
    fn default() -> Self {
        Self {
            node_name: SHADOW_HAND.controller_node.into(),
            operator_site_nodes: vec![nodes::WRIST_TRACKER.into(), nodes::HAND_INFERENCE.into()],
            hardware_timeout_s: 0.05,
            commander: CommanderConfig::default(),
            hand: HandSupervisorConfig::default(),
            // On the depth frame's path to the hand (docs/local-site.md).
            scheduling: SchedulingConfig::realtime(teleop_node::sched::LATENCY_PATH_PRIORITY),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for HandNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        check_controller_links(&self.operator_site_nodes, self.hardware_timeout_s)?;
        self.commander.validate()?;
        self.hand.validate().map_err(|e| format!("hand.{e}"))
    }
}

/// The node: subscriptions, the hand, the arm (read-only, for gravity), the supervisor.
#[derive(Debug)]
pub struct HandNode {
    operator_site_nodes: Vec<String>,
    gravity_compensation: bool,
    rate_hz: f64,
    commander: CommanderConfig,
    target_sub: SourceLock<JointState>,
    input_sub: SourceLock<OperatorInput>,
    watch: NodeWatch,
    hw: BusHand,
    arm: BusArm<7>,
    arm_position: Option<SVector<f64, 7>>,
    /// The hand's last measured posture (what it holds when the node stops).
    hand_position: Option<SVector<f64, 17>>,
    hand: HandSupervisor,
    operator: Option<OperatorSample>,
    hardware_errors: u64,
    hardware_ok: bool,
    /// Finger targets: the depth frame's capture (their stamp) -> received here, the
    /// operator site's whole chain as this site sees it.
    capture_to_received: LatencyHistogram,
    /// The targets' ages when taken (none older than the deadline).
    target_ages: CommandAges,
    errors: NodeErrors,
}

impl HandNode {
    /// Declares the node's subscriptions and hardware clients on `bus`.
    ///
    /// # Errors
    /// Bus declarations or the supervisor's configuration.
    pub async fn new(cfg: &HandNodeConfig, bus: &Bus) -> anyhow::Result<Self> {
        let (lower, upper) = HandSupervisor::shadow_hand_limits()?;
        let hand = HandSupervisor::new(cfg.hand, lower, upper)?;
        tracing::info!(rate_hz = cfg.hand.rate_hz, mode = ?hand.mode(),
            "Shadow hand controller: holding until targets arrive with the enable switch held");
        Ok(Self {
            operator_site_nodes: cfg.operator_site_nodes.clone(),
            gravity_compensation: cfg.hand.gravity_compensation,
            rate_hz: cfg.hand.rate_hz,
            commander: cfg.commander,
            target_sub: SourceLock::new(
                bus.subscriber(&topics::HAND_JOINT_TARGETS).await?,
                cfg.commander.release_after_s,
            ),
            input_sub: SourceLock::new(
                bus.subscriber(&topics::OPERATOR_INPUT).await?,
                cfg.commander.release_after_s,
            ),
            watch: bus.watch_nodes().await?,
            hw: BusHand::new(bus, &SHADOW_HAND, cfg.hardware_timeout_s).await?,
            // The arm's posture orients the hand for gravity compensation (read-only).
            arm: BusArm::monitor(bus, &PR2_ARM, cfg.hardware_timeout_s).await?,
            arm_position: None,
            hand_position: None,
            hand,
            operator: None,
            hardware_errors: 0,
            hardware_ok: false,
            capture_to_received: LatencyHistogram::new("targets.capture_to_received"),
            target_ages: CommandAges::new(
                "joint_targets",
                "targets.sent_to_taken",
                &bus.guard_settings(&topics::HAND_JOINT_TARGETS.spec),
            ),
            errors: NodeErrors::new(),
        })
    }

    /// The supervisor core.
    pub fn supervisor(&self) -> &HandSupervisor {
        &self.hand
    }
}

impl Node for HandNode {
    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.rate_hz)
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        // Holding, a silent commander's lock may go (and, if configured, any lock).
        if self.hand.hold_reason_now().is_some() {
            self.commander
                .disengaged(now_s, &mut [&mut self.target_sub, &mut self.input_sub]);
        }
        if let Some(r) = self.target_sub.poll() {
            let sent_s = r.source_timestamp_ns as f64 * 1e-9;
            if !self
                .target_ages
                .admit(now_s, sent_s, r.publisher_gid, r.sequence)
            {
                // Expired between receipt and this step: never executed.
                let text = format!(
                    "finger targets refused: older than {:.0} ms when taken",
                    self.target_ages.limit_s() * 1e3
                );
                self.errors.event("finger targets", text, now_s);
            } else {
                match self.hand.accept_target(&r.msg, r.receive_time_s()) {
                    Ok(()) => self
                        .capture_to_received
                        .record_s(r.receive_time_s() - r.msg.header.stamp.as_secs_f64()),
                    Err(e) => self.errors.event("finger targets", e.to_string(), now_s),
                }
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
        if let Some(conflict) =
            source::conflict(now_s, &mut [&mut self.target_sub, &mut self.input_sub])
        {
            self.errors.event("commander", conflict, now_s);
        }
        let alive = self
            .operator_site_nodes
            .iter()
            .any(|n| self.watch.is_alive(n));
        if self.gravity_compensation {
            // A stale arm state keeps the last posture: the hand's orientation changes
            // only with the arm, and the arm stops on its own.
            if let Ok(a) = self.arm.read(now_s) {
                self.arm_position = Some(a.position_rad);
            }
        }
        match self.hw.read(now_s) {
            Ok(state) => {
                self.hardware_ok = true;
                self.errors.resolved("hardware", now_s);
                self.hand_position = Some(state.position_rad);
                let out = self.hand.step(
                    now_s,
                    self.operator,
                    alive,
                    &state,
                    self.arm_position.as_ref(),
                );
                if let Err(e) = self.hw.write(now_s, &out.command) {
                    self.hardware_errors += 1;
                    self.errors.event("hardware write", e.to_string(), now_s);
                }
            }
            Err(e) => {
                self.hardware_ok = false;
                self.hardware_errors += 1;
                self.errors.condition("hardware", e.to_string(), now_s);
                if let Some(cmd) = self.hand.hardware_lost()
                    && let Err(e) = self.hw.write(now_s, &cmd)
                {
                    self.errors.event("hardware write", e.to_string(), now_s);
                }
            }
        }
    }

    fn state(&self) -> Lifecycle {
        if !self.hardware_ok {
            Lifecycle::Fault
        } else if self.hand.hold_reason_now().is_none() {
            Lifecycle::Active
        } else {
            Lifecycle::Inactive
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let mut counters = self.hand.named_counters();
        counters.push(("hand.hardware_errors".into(), self.hardware_errors));
        counters.push(("hand.bad_hardware_states".into(), self.hw.bad_states()));
        counters.extend(self.target_sub.named_counters());
        counters.extend(self.input_sub.named_counters());
        self.capture_to_received.named(&mut counters);
        self.target_ages.named(&mut counters);
        counters
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    /// The hand holds the posture it is in through its own position servo: it stops
    /// moving, and a grasped object is neither dropped nor squeezed harder.
    fn shutdown(&mut self, now_s: f64) {
        if let Some(q) = self.hand_position
            && let Err(e) = self.hw.write(now_s, &HandCommand::Position(q))
        {
            tracing::warn!("holding the hand at shutdown: {e}");
        }
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: HandNodeConfig, duration: Option<Duration>) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = HandNode::new(&cfg, &bus).await?;
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}
