//! The wrist tracker node: polls the tracker and the pedals, publishes
//! [`topics::WRIST_POSE`] and [`topics::OPERATOR_INPUT`], and its status.
//!
//! A non-finite pose from the tracker is never published: it is counted as
//! `wrist_pose.rejected_non_finite` and reported in the node status.

use std::time::Duration;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeConfig, StatusReporter, topics};
use teleop_msgs::{Header, Lifecycle, OperatorInput, Point, Pose, PoseStamped, Quaternion, Time};
use tokio::time::MissedTickBehavior;

use crate::devices::{OperatorDevice, SimulatedOperator, SimulatedOperatorConfig, WristTracker};

/// Configuration of the wrist tracker node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WristTrackerConfig {
    /// Node name (unique across both sites).
    pub node_name: String,
    /// Frame id of published poses.
    pub frame_id: String,
    /// Wrist pose publishing rate, Hz.
    pub pose_rate_hz: f64,
    /// Pedal state publishing rate, Hz (also the operator-side heartbeat).
    pub input_rate_hz: f64,
    /// Status report rate, Hz.
    pub status_rate_hz: f64,
    /// The simulated operator (the only backend today).
    pub operator: SimulatedOperatorConfig,
    pub bus: BusConfig,
}

impl Default for WristTrackerConfig {
    fn default() -> Self {
        Self {
            node_name: "wrist_tracker".into(),
            frame_id: "tracker".into(),
            pose_rate_hz: topics::WRIST_POSE.spec.rate_hz,
            input_rate_hz: topics::OPERATOR_INPUT.spec.rate_hz,
            status_rate_hz: 1.0,
            operator: SimulatedOperatorConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for WristTrackerConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("pose_rate_hz", self.pose_rate_hz),
            ("input_rate_hz", self.input_rate_hz),
            ("status_rate_hz", self.status_rate_hz),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 10_000.0) {
                return Err(format!("{name} must be in (0, 10000] Hz, got {v}"));
            }
        }
        self.operator.validate()
    }
}

/// Converts a pose to the message type; `None` if any component is not finite.
pub fn pose_msg(pose: &Isometry3<f64>) -> Option<Pose> {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    let msg = Pose {
        position: Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    };
    msg.is_finite().then_some(msg)
}

/// Counters of the node.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct TrackerCounters {
    pub poses_published: u64,
    pub poses_missing: u64,
    pub poses_non_finite: u64,
    pub inputs_published: u64,
}

impl TrackerCounters {
    fn named(&self) -> Vec<(String, u64)> {
        vec![
            ("wrist_pose.published".into(), self.poses_published),
            ("wrist_pose.missing".into(), self.poses_missing),
            (
                "wrist_pose.rejected_non_finite".into(),
                self.poses_non_finite,
            ),
            ("operator_input.published".into(), self.inputs_published),
        ]
    }
}

/// Runs the node until `duration` elapses (forever if `None`) or Ctrl-C.
///
/// # Errors
/// Bus errors (session, declarations).
pub async fn run(
    cfg: WristTrackerConfig,
    duration: Option<Duration>,
) -> anyhow::Result<TrackerCounters> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let pose_pub = bus.publisher(&topics::WRIST_POSE).await?;
    let input_pub = bus.publisher(&topics::OPERATOR_INPUT).await?;
    let status = StatusReporter::new(&bus).await?;
    tracing::info!(node = %cfg.node_name, zid = bus.zid(), "wrist tracker running (simulated operator)");

    let mut operator = SimulatedOperator::new(cfg.operator.clone());
    let mut pose_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.pose_rate_hz));
    let mut input_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.input_rate_hz));
    let mut status_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.status_rate_hz));
    for t in [&mut pose_tick, &mut input_tick, &mut status_tick] {
        t.set_missed_tick_behavior(MissedTickBehavior::Skip);
    }
    let start = tokio::time::Instant::now();
    let stop = teleop_bus::node::stop_signal(duration);
    tokio::pin!(stop);
    let mut counters = TrackerCounters::default();
    let mut last_error = String::new();
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = pose_tick.tick() => {
                let t = start.elapsed().as_secs_f64();
                match WristTracker::read(&mut operator, t) {
                    None => counters.poses_missing += 1,
                    Some(p) => match pose_msg(&p) {
                        Some(pose) => {
                            let msg = PoseStamped { header: Header::new(Time::now(), cfg.frame_id.clone()), pose };
                            if let Err(e) = pose_pub.put(&msg) {
                                last_error = e.to_string();
                                tracing::warn!("publishing wrist pose: {e}");
                            } else {
                                counters.poses_published += 1;
                            }
                        }
                        None => {
                            counters.poses_non_finite += 1;
                            last_error = "tracker returned a non-finite pose".into();
                        }
                    },
                }
            }
            _ = input_tick.tick() => {
                let t = start.elapsed().as_secs_f64();
                let s = OperatorDevice::read(&mut operator, t);
                let msg = OperatorInput {
                    header: Header::new(Time::now(), ""),
                    clutch: s.clutch,
                    enable: s.enable,
                    camera_stop: s.camera_stop,
                    motion_scale: s.motion_scale,
                };
                match input_pub.put(&msg) {
                    Ok(()) => counters.inputs_published += 1,
                    Err(e) => last_error = e.to_string(),
                }
            }
            _ = status_tick.tick() => {
                if let Err(e) = status.report(Lifecycle::Active, &counters.named(), &last_error) {
                    tracing::warn!("publishing status: {e}");
                }
            }
        }
    }
    let _ = status.report(Lifecycle::Finalized, &counters.named(), &last_error);
    drop((pose_pub, input_pub, status));
    bus.close().await?;
    Ok(counters)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_poses_are_refused() {
        let mut p = Isometry3::<f64>::identity();
        assert!(pose_msg(&p).is_some());
        p.translation.vector.x = f64::NAN;
        assert!(pose_msg(&p).is_none());
    }

    #[test]
    fn default_config_is_valid_and_rates_are_checked() {
        let cfg = WristTrackerConfig::default();
        cfg.validate().expect("default valid");
        let bad = WristTrackerConfig {
            pose_rate_hz: 0.0,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().contains("pose_rate_hz"));
    }
}
