//! The wrist tracker node: reads the tracker and the pedals through the operator-site
//! hardware traits, publishes [`topics::WRIST_POSE`] and [`topics::OPERATOR_INPUT`],
//! on the node runner.
//!
//! A non-finite pose from the tracker is never published: it is counted as
//! `wrist_pose.rejected_non_finite` and reported in the node status.

use std::time::Duration;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher};
use teleop_hardware::{OperatorPanel, WristTracker};
use teleop_interfaces::topics;
use teleop_msgs::{Header, Lifecycle, OperatorInput, Point, Pose, PoseStamped, Quaternion, Time};
use teleop_node::{FinalReport, Node, NodeConfig, Periodic};
use teleop_sim::operator::{SimulatedDevices, SimulatedOperator, SimulatedOperatorConfig};

use crate::tracking::bvh::{BvhStreamConfig, BvhStreamTracker};
use crate::tracking::replay::{ReplayConfig, ReplayTracker};

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
    /// Where wrist poses come from.
    pub source: TrackerSource,
    /// The simulated operator: the pedals and switch (the only panel backend today),
    /// and the wrist poses when `source` is `simulated`.
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
            source: TrackerSource::Simulated,
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
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 10_000.0) {
                return Err(format!("{name} must be in (0, 10000] Hz, got {v}"));
            }
        }
        match &self.source {
            TrackerSource::Simulated => {}
            TrackerSource::Replay(r) => r.validate()?,
            TrackerSource::Bvh(b) => b.validate()?,
        }
        self.operator.validate()
    }
}

/// The wrist pose source, `[source] kind = "..."` in the config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TrackerSource {
    /// The simulated operator's motion capture.
    Simulated,
    /// A recorded trajectory (CSV, [`crate::tracking::replay`]).
    Replay(ReplayConfig),
    /// The Perception Neuron suit through Axis Neuron's BVH broadcast
    /// ([`crate::tracking::bvh`]): the palm pose relative to the spine.
    Bvh(BvhStreamConfig),
}

impl TrackerSource {
    /// Opens the source.
    ///
    /// # Errors
    /// A missing or malformed replay or skeleton file, an unknown joint name.
    pub fn open(
        &self,
        operator: &SimulatedOperatorConfig,
    ) -> anyhow::Result<Box<dyn WristTracker>> {
        Ok(match self {
            Self::Simulated => Box::new(SimulatedDevices::new(SimulatedOperator::new(
                operator.clone(),
            ))),
            Self::Replay(r) => Box::new(ReplayTracker::open(r)?),
            Self::Bvh(b) => Box::new(BvhStreamTracker::start(b)?),
        })
    }

    /// A short name for logs.
    pub fn describe(&self) -> String {
        match self {
            Self::Simulated => "simulated operator".into(),
            Self::Replay(r) => format!("replay of {}", r.path.display()),
            Self::Bvh(b) => format!("BVH stream from {}", b.address),
        }
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
    /// The counters by name, as in the node status.
    pub fn named(&self) -> Vec<(String, u64)> {
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

/// The node: the devices, the publishers.
pub struct WristTrackerNode {
    frame_id: String,
    pose_period: Duration,
    tracker: Box<dyn WristTracker>,
    panel: Box<dyn OperatorPanel>,
    pose_pub: Publisher<PoseStamped>,
    input_pub: Publisher<OperatorInput>,
    input_due: Periodic,
    counters: TrackerCounters,
    devices_ok: bool,
    last_error: String,
}

impl std::fmt::Debug for WristTrackerNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WristTrackerNode")
            .field("counters", &self.counters)
            .finish()
    }
}

impl WristTrackerNode {
    /// The node with the configured pose source and the simulated operator's pedals.
    ///
    /// # Errors
    /// The source cannot be opened; bus declarations.
    pub async fn new(cfg: &WristTrackerConfig, bus: &Bus) -> anyhow::Result<Self> {
        let tracker = cfg.source.open(&cfg.operator)?;
        let panel = SimulatedDevices::new(SimulatedOperator::new(cfg.operator.clone()));
        Self::with_devices(cfg, bus, tracker, Box::new(panel)).await
    }

    /// The node with given devices.
    ///
    /// # Errors
    /// Bus declarations.
    pub async fn with_devices(
        cfg: &WristTrackerConfig,
        bus: &Bus,
        tracker: Box<dyn WristTracker>,
        panel: Box<dyn OperatorPanel>,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            frame_id: cfg.frame_id.clone(),
            pose_period: Duration::from_secs_f64(1.0 / cfg.pose_rate_hz),
            tracker,
            panel,
            pose_pub: bus.publisher(&topics::WRIST_POSE).await?,
            input_pub: bus.publisher(&topics::OPERATOR_INPUT).await?,
            input_due: Periodic::at_rate(cfg.input_rate_hz),
            counters: TrackerCounters::default(),
            devices_ok: true,
            last_error: String::new(),
        })
    }

    /// Counters so far.
    pub fn tracker_counters(&self) -> TrackerCounters {
        self.counters
    }
}

fn stamp(now_s: f64) -> Time {
    // Seconds since the epoch: far inside the i64 ns range.
    #[allow(clippy::cast_possible_truncation)]
    Time::from_nanos((now_s * 1e9) as i64)
}

impl Node for WristTrackerNode {
    fn period(&self) -> Duration {
        self.pose_period
    }

    fn tick(&mut self, now_s: f64) {
        let mut ok = true;
        match self.tracker.read(now_s) {
            Ok(None) => self.counters.poses_missing += 1,
            Ok(Some(p)) => match pose_msg(&p) {
                Some(pose) => {
                    let msg = PoseStamped {
                        header: Header::new(stamp(now_s), self.frame_id.clone()),
                        pose,
                    };
                    match self.pose_pub.put(&msg) {
                        Ok(()) => self.counters.poses_published += 1,
                        Err(e) => {
                            self.last_error = e.to_string();
                            tracing::warn!("publishing wrist pose: {e}");
                        }
                    }
                }
                None => {
                    self.counters.poses_non_finite += 1;
                    self.last_error = "tracker returned a non-finite pose".into();
                }
            },
            Err(e) => {
                ok = false;
                self.counters.poses_missing += 1;
                self.last_error = format!("tracker: {e}");
            }
        }
        if self.input_due.due(now_s) {
            match self.panel.read(now_s) {
                Ok(s) => {
                    let msg = OperatorInput {
                        header: Header::new(stamp(now_s), ""),
                        clutch: s.clutch,
                        enable: s.enable,
                        camera_stop: s.camera_stop,
                        motion_scale: s.motion_scale,
                    };
                    match self.input_pub.put(&msg) {
                        Ok(()) => self.counters.inputs_published += 1,
                        Err(e) => self.last_error = e.to_string(),
                    }
                }
                Err(e) => {
                    // Nothing is published: the robot site stops on stale input.
                    ok = false;
                    self.last_error = format!("pedals: {e}");
                }
            }
        }
        self.devices_ok = ok;
    }

    fn state(&self) -> Lifecycle {
        if self.devices_ok {
            Lifecycle::Active
        } else {
            Lifecycle::Fault
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        self.counters.named()
    }

    fn last_error(&self) -> String {
        self.last_error.clone()
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus errors (session, declarations).
pub async fn run(
    cfg: WristTrackerConfig,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = WristTrackerNode::new(&cfg, &bus).await?;
    tracing::info!(
        zid = bus.zid(),
        source = cfg.source.describe(),
        "wrist tracker running"
    );
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
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

    #[test]
    fn sources_parse_from_toml_and_unknown_fields_are_refused() {
        let cfg: WristTrackerConfig =
            toml::from_str("[source]\nkind = \"replay\"\npath = \"poses.csv\"\nend = \"loop\"\n")
                .expect("replay source");
        assert_eq!(
            cfg.source,
            TrackerSource::Replay(ReplayConfig {
                path: "poses.csv".into(),
                end: crate::tracking::replay::ReplayEnd::Loop,
                max_gap_s: 0.1,
            })
        );
        cfg.validate().expect("valid");
        let bvh: WristTrackerConfig = toml::from_str(
            "[source]\nkind = \"bvh\"\naddress = \"10.0.0.5:7001\"\nskeleton = \"neuron.bvh\"\n",
        )
        .expect("bvh source");
        let TrackerSource::Bvh(b) = &bvh.source else {
            panic!("not a BVH source: {:?}", bvh.source);
        };
        assert_eq!(b.reference_joint, "Spine3");
        assert_eq!(b.hand_joint, "RightHand");
        let typo = toml::from_str::<WristTrackerConfig>(
            "[source]\nkind = \"replay\"\npath = \"p.csv\"\nmax_gap = 1.0\n",
        )
        .expect_err("unknown field");
        assert!(typo.to_string().contains("max_gap"), "{typo}");
        let bad_gap: WristTrackerConfig =
            toml::from_str("[source]\nkind = \"replay\"\npath = \"p.csv\"\nmax_gap_s = -1.0\n")
                .expect("parses");
        assert!(bad_gap.validate().unwrap_err().contains("max_gap_s"));
        let missing = TrackerSource::Replay(ReplayConfig {
            path: "/nonexistent/poses.csv".into(),
            end: crate::tracking::replay::ReplayEnd::Stop,
            max_gap_s: 0.1,
        })
        .open(&SimulatedOperatorConfig::default())
        .err()
        .expect("missing file");
        assert!(missing.to_string().contains("/nonexistent/poses.csv"));
    }
}
