//! The Shadow hand controller node: finger targets from the operator site's hand
//! inference and the enable switch from the bus, the hand through a [`HandHardware`],
//! the [`HandSupervisor`] core in between, at the configured rate.

use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeConfig, StatusReporter, topics};
use teleop_msgs::{Lifecycle, unix_seconds_now as now_s};
use tokio::time::MissedTickBehavior;

use crate::bus_hardware::{BusArm, BusHand};
use crate::hand_controller::{EnableSample, HandSupervisor, HandSupervisorConfig};
use crate::hardware::{ArmHardware, HandHardware};

/// Configuration of the `shadow_hand_controller` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandNodeConfig {
    pub node_name: String,
    /// Nodes of the operator site; the hand holds when none of them is alive.
    pub operator_site_nodes: Vec<String>,
    /// The hand hardware's state counts as lost after this long, s.
    pub hardware_timeout_s: f64,
    pub hand: HandSupervisorConfig,
    pub bus: BusConfig,
}

impl Default for HandNodeConfig {
    fn default() -> Self {
        Self {
            node_name: "shadow_hand_controller".into(),
            operator_site_nodes: vec!["wrist_tracker".into(), "hand_inference".into()],
            hardware_timeout_s: 0.05,
            hand: HandSupervisorConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for HandNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn validate(&self) -> Result<(), String> {
        crate::bus_hardware::check_controller_links(
            &self.operator_site_nodes,
            self.hardware_timeout_s,
        )?;
        self.hand.validate().map_err(|e| format!("hand.{e}"))
    }
}

/// Runs the node until `duration` elapses (forever if `None`) or Ctrl-C.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: HandNodeConfig, duration: Option<Duration>) -> anyhow::Result<()> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let target_sub = bus.subscriber(&topics::HAND_JOINT_TARGETS).await?;
    let input_sub = bus.subscriber(&topics::OPERATOR_INPUT).await?;
    let watch = bus.watch_nodes().await?;
    let status = StatusReporter::new(&bus).await?;
    let mut hw = BusHand::new(&bus, cfg.hardware_timeout_s).await?;
    // The arm's posture orients the hand for gravity compensation (read-only).
    let mut arm = BusArm::monitor(&bus, cfg.hardware_timeout_s).await?;
    let mut arm_position: Option<nalgebra::SVector<f64, 7>> = None;
    let (lower, upper) = HandSupervisor::shadow_hand_limits()?;
    let mut hand = HandSupervisor::new(cfg.hand, lower, upper)?;
    tracing::info!(node = %cfg.node_name, rate_hz = cfg.hand.rate_hz, mode = ?hand.mode(),
        "Shadow hand controller running; holding until targets arrive with the enable switch held");

    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.hand.rate_hz));
    tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut status_tick = tokio::time::interval(Duration::from_secs(1));
    let stop = teleop_bus::node::stop_signal(duration);
    tokio::pin!(stop);
    let mut enable: Option<EnableSample> = None;
    let mut hardware_errors = 0u64;
    let mut last_error = String::new();
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = status_tick.tick() => {
                let mut counters = hand.named_counters();
                counters.push(("hand.hardware_errors".into(), hardware_errors));
                counters.push(("hand.bad_hardware_states".into(), hw.bad_states()));
                counters.extend(target_sub.named_counters());
                counters.extend(input_sub.named_counters());
                let state = if hand.hold_reason_now().is_none() { Lifecycle::Active } else { Lifecycle::Inactive };
                if let Err(e) = status.report(state, &counters, &last_error) {
                    tracing::warn!("status: {e}");
                }
            }
            _ = tick.tick() => {
                while let Some(r) = target_sub.try_recv() {
                    if let Err(e) = hand.accept_target(&r.msg, r.receive_time_s()) {
                        last_error = e.to_string();
                    }
                }
                while let Some(r) = input_sub.try_recv() {
                    enable = Some(EnableSample { received_s: r.receive_time_s(), enable: r.msg.enable });
                }
                let alive = cfg.operator_site_nodes.iter().any(|n| watch.is_alive(n));
                if cfg.hand.gravity_compensation {
                    // A stale arm state keeps the last posture: the hand's orientation
                    // changes only with the arm, and the arm stops on its own.
                    if let Ok(a) = arm.read() {
                        arm_position = Some(a.position_rad);
                    }
                }
                match hw.read() {
                    Ok(state) => {
                        let out = hand.step(now_s(), enable, alive, &state, arm_position.as_ref());
                        if let Err(e) = hw.write(&out.command) {
                            hardware_errors += 1;
                            last_error = e.to_string();
                        }
                    }
                    Err(e) => {
                        hardware_errors += 1;
                        last_error = e.to_string();
                        if let Some(cmd) = hand.hardware_lost() {
                            let _ = hw.write(&cmd);
                        }
                    }
                }
            }
        }
    }
    let _ = status.report(Lifecycle::Finalized, &hand.named_counters(), &last_error);
    drop((target_sub, input_sub, watch, status, hw, arm));
    bus.close().await?;
    Ok(())
}
