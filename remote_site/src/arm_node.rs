//! The PR2 arm controller node: operator inputs from the bus, the arm through an
//! [`ArmHardware`], the [`ArmController`] core in between, at the configured rate.

use std::time::Duration;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeConfig, StatusReporter, topics};
use teleop_msgs::{Lifecycle, Pose, unix_seconds_now as now_s};
use tokio::time::MissedTickBehavior;

use crate::arm_controller::{
    ArmController, ArmControllerConfig, ArmInputs, OperatorSample, WristSample,
};
use crate::bus_hardware::BusArm;
use crate::hardware::{ArmCommand, ArmHardware};

/// Configuration of the `pr2_arm_controller` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmNodeConfig {
    pub node_name: String,
    /// Nodes of the operator site; the arm stops when none of them is alive.
    pub operator_site_nodes: Vec<String>,
    /// The arm hardware's state counts as lost after this long, s.
    pub hardware_timeout_s: f64,
    pub arm: ArmControllerConfig,
    pub bus: BusConfig,
}

impl Default for ArmNodeConfig {
    fn default() -> Self {
        Self {
            node_name: "pr2_arm_controller".into(),
            operator_site_nodes: vec!["wrist_tracker".into()],
            hardware_timeout_s: 0.1,
            arm: ArmControllerConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for ArmNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn validate(&self) -> Result<(), String> {
        crate::bus_hardware::check_controller_links(
            &self.operator_site_nodes,
            self.hardware_timeout_s,
        )?;
        self.arm.validate()
    }
}

/// A wrist pose message as an isometry; the quaternion is taken as sent (the jump
/// filter refuses non-unit or non-finite ones, by name).
pub fn isometry(p: &Pose) -> Isometry3<f64> {
    let q = p.orientation;
    Isometry3::from_parts(
        Translation3::new(p.position.x, p.position.y, p.position.z),
        UnitQuaternion::new_unchecked(Quaternion::new(q.w, q.x, q.y, q.z)),
    )
}

/// Runs the node until `duration` elapses (forever if `None`) or Ctrl-C.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: ArmNodeConfig, duration: Option<Duration>) -> anyhow::Result<()> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let wrist_sub = bus.subscriber(&topics::WRIST_POSE).await?;
    let input_sub = bus.subscriber(&topics::OPERATOR_INPUT).await?;
    let watch = bus.watch_nodes().await?;
    let status = StatusReporter::new(&bus).await?;
    let mut hw = BusArm::new(&bus, cfg.hardware_timeout_s).await?;
    let mut ctrl =
        ArmController::new(teleop_kinematics::robots::pr2_arm_chain()?, cfg.arm.clone())?;
    tracing::info!(node = %cfg.node_name, rate_hz = cfg.arm.rate_hz, "PR2 arm controller running; arm disabled until clutch + enable");

    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.arm.rate_hz));
    tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut status_tick = tokio::time::interval(Duration::from_secs(1));
    let stop = teleop_bus::node::stop_signal(duration);
    tokio::pin!(stop);
    let mut wrist: Option<WristSample> = None;
    let mut operator: Option<OperatorSample> = None;
    let mut hardware_errors = 0u64;
    let mut last_error = String::new();
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = status_tick.tick() => {
                let mut counters = ctrl.named_counters();
                counters.push(("arm.hardware_errors".into(), hardware_errors));
                counters.extend(wrist_sub.named_counters());
                counters.extend(input_sub.named_counters());
                let state = if ctrl.is_engaged() { Lifecycle::Active } else { Lifecycle::Inactive };
                if let Err(e) = status.report(state, &counters, &last_error) {
                    tracing::warn!("status: {e}");
                }
            }
            _ = tick.tick() => {
                while let Some(r) = wrist_sub.try_recv() {
                    wrist = Some(WristSample { received_s: r.receive_time_s(), pose: isometry(&r.msg.pose) });
                }
                while let Some(r) = input_sub.try_recv() {
                    operator = Some(OperatorSample {
                        received_s: r.receive_time_s(),
                        clutch: r.msg.clutch,
                        enable: r.msg.enable,
                        motion_scale: r.msg.motion_scale,
                    });
                }
                let alive = cfg.operator_site_nodes.iter().any(|n| watch.is_alive(n));
                let inputs = ArmInputs { operator, wrist, operator_site_alive: alive };
                match hw.read() {
                    Ok(state) => {
                        let out = ctrl.step(now_s(), &inputs, &state);
                        if let Err(e) = hw.write(&out.command) {
                            hardware_errors += 1;
                            last_error = e.to_string();
                        }
                    }
                    Err(e) => {
                        hardware_errors += 1;
                        last_error = e.to_string();
                        // Without a state, command a stop (the driver stops on its own too).
                        let _ = hw.write(&ArmCommand::stop());
                    }
                }
            }
        }
    }
    let _ = hw.write(&ArmCommand::stop());
    let _ = status.report(Lifecycle::Finalized, &ctrl.named_counters(), &last_error);
    drop((wrist_sub, input_sub, watch, status, hw));
    bus.close().await?;
    Ok(())
}
