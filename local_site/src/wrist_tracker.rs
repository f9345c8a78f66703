//! The wrist tracker node (thesis ch. 7.2-7.4): reads the tracker and the pedals
//! through the operator-site hardware traits, registers the tracked marker into the
//! operator's hand frame in the UR5 base frame, drops jumps, and publishes
//! [`topics::WRIST_POSE`] and [`topics::OPERATOR_INPUT`], on the node runner.
//!
//! # Pipeline, per new tracker sample
//!
//! 1. **Source** (`[source]`): the motion capture over the bus (`mocap`, default:
//!    [`BusWristTracker`] on [`topics::HW_MOCAP_MARKER`], each sample with its capture
//!    stamp), or an in-process source (`simulated`, `replay`, `bvh`) read once per tick
//!    and stamped with the read time.
//! 2. **Registration** ([`Registration`], `[registration]`): the published pose is
//!    `base_from_tracker * tracker_from_marker * hand_from_marker^-1`, the hand frame
//!    of Fig. 3.6 (origin at the wrist, z along the fingers, y the palm normal) in the
//!    UR5 base frame. The thesis's chain `rT_p = rT_c cT_a aT_b bT_p` (eq. 7.1) is
//!    folded into the two configured transforms: `base_from_tracker` = `rT_c` (the
//!    tracker in the UR5 base, from the calibration), `hand_from_marker^-1` =
//!    `aT_b bT_p` (the marker's rigid body to the hand), the tracked `cT_a` in
//!    between. Each transform not given takes its **source's default**
//!    ([`RegistrationConfig::resolve`]): the operator-site simulator's installation
//!    for `mocap`, the identity for the other sources (which keep publishing their
//!    poses unchanged, in frame `tracker`).
//! 3. **Jump filter and re-acquisition** ([`PoseGate`], `[jump]`, `[reacquire]`): a
//!    pose that jumps more than 50 cm along an axis or turns more than 60 deg from the
//!    last accepted one (thesis ch. 7.4; [`JumpFilter`]) is not published and is
//!    counted by reason. Since the tracker has no clutch to re-centre with, poses that
//!    keep agreeing with each other (within 5 cm / 10 deg of the first of them, no gap
//!    over `max_gap_s`) for `reacquire.after_s` (0.3 s) after a rejection are taken as
//!    the hand's new place: the filter is reset and the pose published, counted as
//!    `wrist_pose.reacquired`. The robot site's PR2 controller still has its own jump
//!    filter and clutch: a re-acquired jump never moves the PR2 without a fresh clutch
//!    press.
//! 4. **Stamp and rate**: `header.stamp` is the sample's capture stamp (mocap), so
//!    every later stage measures its latency from the capture. Each accepted sample is
//!    published at the next tick, unless `pose_rate_hz` is below the source's rate;
//!    then the newest accepted sample per `1 / pose_rate_hz` period.
//!
//! The pedals come from `[panel]`: the pedal box over the bus (`bus`, default:
//! [`BusPanel`] on [`topics::HW_PEDALS`]), the in-process simulated operator
//! (`simulated`) or the keys of the node's terminal (`keyboard`:
//! [`KeyboardReader`] on stdin). Stale or lost pedals publish nothing (the robot site
//! stops on stale input). The node is in [`Lifecycle::Fault`] while the tracker or the
//! pedals are lost or stale.

use std::time::Duration;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher};
use teleop_control::{ConfigError, JumpFilter, JumpFilterConfig, Rejection, RejectionKind};
use teleop_control::{RejectionCounts, TransformConfig};
use teleop_hardware::{HardwareError, OperatorPanel, WristTracker};
use teleop_hardware_bus::{BusPanel, BusWristTracker};
use teleop_interfaces::calibration;
use teleop_interfaces::topics;
use teleop_msgs::{Header, Lifecycle, OperatorInput, PoseStamped, Time};
use teleop_node::{FinalReport, Node, NodeConfig, NodeErrors, Periodic, SchedulingConfig};

use crate::keyboard_panel::{KeyboardPanelConfig, KeyboardReader};
use crate::tracking::bvh::{BvhStreamConfig, BvhStreamTracker};
use crate::tracking::replay::{ReplayConfig, ReplayTracker};

/// Frame id of registered poses (the UR5 base).
pub const BASE_FRAME: &str = "ur5_base_link";
/// Frame id of unregistered poses (the tracker's own frame).
pub const TRACKER_FRAME: &str = "tracker";

/// Configuration of the wrist tracker node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WristTrackerConfig {
    /// Node name (unique across both sites).
    pub node_name: String,
    /// Frame id of published poses. Unset: the PR2 torso
    /// ([`crate::tracking::imu_arm::TORSO_FRAME`]) for a BVH source with the arm
    /// registration (`[source.arm]`, the chapter-6 absolute mode), [`BASE_FRAME`] when
    /// the poses are registered into the UR5 base (the `mocap` source, or
    /// `registration.base_from_tracker` given), [`TRACKER_FRAME`] otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_id: Option<String>,
    /// Node tick rate, Hz: how often the tracker is read. At least the source's rate
    /// (320 Hz for the motion capture) so that no sample waits more than one tick.
    pub tick_rate_hz: f64,
    /// Most wrist poses published per second, Hz. At or above the source's rate every
    /// accepted sample is published; below it, the newest accepted sample per period.
    pub pose_rate_hz: f64,
    /// Pedal state publishing rate, Hz (also the operator-side heartbeat).
    pub input_rate_hz: f64,
    /// A gap between consecutive samples (their capture times) longer than this is
    /// counted as a dropout (`wrist_pose.dropouts`), s.
    pub dropout_after_s: f64,
    /// Where wrist poses come from.
    pub source: TrackerSource,
    /// Where the pedals come from.
    pub panel: PanelSource,
    /// The registration of the tracked marker into the hand frame in the UR5 base;
    /// unset transforms take the source's default.
    pub registration: RegistrationConfig,
    /// The jump filter (thesis ch. 7.4).
    pub jump: JumpFilterConfig,
    /// Re-acquisition after a rejected jump.
    pub reacquire: ReacquireConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    /// The bus.
    pub bus: BusConfig,
}

impl Default for WristTrackerConfig {
    fn default() -> Self {
        Self {
            node_name: "wrist_tracker".into(),
            frame_id: None,
            tick_rate_hz: topics::HW_MOCAP_MARKER.spec.rate_hz,
            pose_rate_hz: topics::HW_MOCAP_MARKER.spec.rate_hz,
            input_rate_hz: topics::OPERATOR_INPUT.spec.rate_hz,
            dropout_after_s: 0.01,
            source: TrackerSource::default(),
            panel: PanelSource::default(),
            registration: RegistrationConfig::default(),
            jump: JumpFilterConfig::default(),
            reacquire: ReacquireConfig::default(),
            scheduling: SchedulingConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl WristTrackerConfig {
    /// The frame id published: `frame_id`, or the default described there.
    pub fn frame_id_in_effect(&self) -> String {
        match &self.frame_id {
            Some(f) => f.clone(),
            None if matches!(&self.source, TrackerSource::Bvh(b) if b.arm.is_some()) => {
                crate::tracking::imu_arm::TORSO_FRAME.into()
            }
            None if matches!(self.source, TrackerSource::Mocap(_))
                || self.registration.base_from_tracker.is_some() =>
            {
                BASE_FRAME.into()
            }
            None => TRACKER_FRAME.into(),
        }
    }

    /// The registration in effect: the configured transforms, the source's defaults
    /// for those not given.
    pub fn registration_in_effect(&self) -> Registration {
        let (base_from_tracker, hand_from_marker) = self.registration.resolve(&self.source);
        Registration::new(&base_from_tracker.isometry(), &hand_from_marker.isometry())
    }
}

fn check_range(name: &str, v: f64, min: f64, max: f64) -> Result<(), String> {
    if v.is_finite() && v > min && v <= max {
        Ok(())
    } else {
        Err(format!("{name} must be in ({min}, {max}], got {v}"))
    }
}

impl NodeConfig for WristTrackerConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("tick_rate_hz", self.tick_rate_hz),
            ("pose_rate_hz", self.pose_rate_hz),
            ("input_rate_hz", self.input_rate_hz),
        ] {
            check_range(name, v, 0.0, 10_000.0)?;
        }
        for (name, v) in [
            ("pose_rate_hz", self.pose_rate_hz),
            ("input_rate_hz", self.input_rate_hz),
        ] {
            if v > self.tick_rate_hz {
                return Err(format!(
                    "{name} ({v} Hz) must not exceed tick_rate_hz ({} Hz)",
                    self.tick_rate_hz
                ));
            }
        }
        check_range("dropout_after_s", self.dropout_after_s, 0.0, 10.0)?;
        match &self.source {
            TrackerSource::Mocap(m) => m.validate()?,
            TrackerSource::InProcess => {}
            TrackerSource::Replay(r) => r.validate()?,
            TrackerSource::Bvh(b) => b.validate()?,
        }
        match &self.panel {
            PanelSource::Bus(p) => check_range("panel.stale_after_s", p.stale_after_s, 0.0, 10.0)?,
            PanelSource::InProcess => {}
            PanelSource::Keyboard(k) => k.validate().map_err(|e| format!("panel.{e}"))?,
        }
        self.registration.validate()?;
        self.jump.validate().map_err(|e| format!("jump: {e}"))?;
        self.reacquire
            .validate()
            .map_err(|e| format!("reacquire: {e}"))
    }
}

/// The motion capture over the bus, `[source] kind = "mocap"`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MocapConfig {
    /// No valid sample for this long: the tracker is lost (node in Fault), s.
    pub stale_after_s: f64,
}

impl Default for MocapConfig {
    fn default() -> Self {
        Self { stale_after_s: 0.2 }
    }
}

impl MocapConfig {
    /// # Errors
    /// `stale_after_s` not in (0, 10] s.
    pub fn validate(&self) -> Result<(), String> {
        check_range("source.stale_after_s", self.stale_after_s, 0.0, 10.0)
    }
}

/// The wrist pose source, `[source] kind = "..."` in the config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TrackerSource {
    /// The motion-capture driver (or the operator-site simulator standing in for it)
    /// over the bus: [`topics::HW_MOCAP_MARKER`], the marker on the back of the hand in
    /// the tracker's own frame, stamped with the capture time. The default.
    Mocap(MocapConfig),
    /// A tracker handed to the node by the program that embeds it
    /// ([`run_with_devices`], [`InProcessDevices`]): a simulated operator in a test, a
    /// driver linked in. Not for config files (it has no name there).
    #[serde(skip)]
    InProcess,
    /// A recorded trajectory (CSV, [`crate::tracking::replay`]).
    Replay(ReplayConfig),
    /// The Perception Neuron suit through Axis Neuron's BVH broadcast
    /// ([`crate::tracking::bvh`]): the palm pose relative to the spine.
    Bvh(BvhStreamConfig),
}

impl Default for TrackerSource {
    fn default() -> Self {
        Self::Mocap(MocapConfig::default())
    }
}

impl TrackerSource {
    /// Opens the source.
    ///
    /// # Errors
    /// A missing or malformed replay or skeleton file, an unknown joint name, a bus
    /// declaration.
    pub async fn open(&self, bus: &Bus) -> anyhow::Result<PoseDevice> {
        Ok(match self {
            Self::Mocap(m) => {
                PoseDevice::Mocap(BusWristTracker::mocap(bus, m.stale_after_s).await?)
            }
            Self::InProcess => anyhow::bail!("{IN_PROCESS_ONLY}"),
            Self::Replay(r) => PoseDevice::Other(Box::new(ReplayTracker::open(r)?)),
            Self::Bvh(b) => PoseDevice::Other(Box::new(BvhStreamTracker::start(b)?)),
        })
    }

    /// A short name for logs.
    pub fn describe(&self) -> String {
        match self {
            Self::Mocap(_) => format!("motion capture on {}", topics::HW_MOCAP_MARKER.spec.name),
            Self::InProcess => "an in-process tracker".into(),
            Self::Replay(r) => format!("replay of {}", r.path.display()),
            Self::Bvh(b) => format!("BVH stream from {}", b.address),
        }
    }
}

/// The pedal box over the bus, `[panel] kind = "bus"`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BusPanelConfig {
    /// No pedal state for this long: the pedals are stale, nothing is published and
    /// the node is in Fault, s.
    pub stale_after_s: f64,
}

impl Default for BusPanelConfig {
    fn default() -> Self {
        Self { stale_after_s: 0.1 }
    }
}

/// Where the pedals come from, `[panel] kind = "..."`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PanelSource {
    /// The pedal box driver (or the operator-site simulator) over the bus:
    /// [`topics::HW_PEDALS`]. The default.
    Bus(BusPanelConfig),
    /// Pedals handed to the node by the program that embeds it ([`run_with_devices`]).
    /// Not for config files.
    #[serde(skip)]
    InProcess,
    /// The keys of the node's terminal (stdin): a person at the keyboard
    /// ([`crate::keyboard_panel`]). For running the wrist tracker by hand.
    Keyboard(KeyboardPanelConfig),
}

impl Default for PanelSource {
    fn default() -> Self {
        Self::Bus(BusPanelConfig::default())
    }
}

impl PanelSource {
    /// Opens the panel.
    ///
    /// # Errors
    /// A bus declaration; for `keyboard`, an invalid config or a terminal whose mode
    /// cannot be set.
    pub async fn open(&self, bus: &Bus) -> anyhow::Result<Box<dyn OperatorPanel>> {
        Ok(match self {
            Self::Bus(p) => Box::new(BusPanel::pedals(bus, p.stale_after_s).await?),
            Self::InProcess => anyhow::bail!("{IN_PROCESS_ONLY}"),
            Self::Keyboard(k) => Box::new(KeyboardReader::stdin(k, bus.clock().clone())?),
        })
    }
}

/// The registration, `[registration]`: both transforms optional; one not given takes
/// its source's default ([`RegistrationConfig::resolve`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RegistrationConfig {
    /// The tracker's frame in the UR5 base frame (`rT_c` of eq. 7.1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub base_from_tracker: Option<TransformConfig>,
    /// The marker's pose in the hand frame of Fig. 3.6 (the inverse of `aT_b bT_p`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hand_from_marker: Option<TransformConfig>,
}

impl RegistrationConfig {
    /// `(base_from_tracker, hand_from_marker)` for `source`: the configured transforms,
    /// else the source's defaults: for `mocap` the operator site's default installation
    /// ([`calibration::default_base_from_mocap`],
    /// [`calibration::default_hand_from_marker`]), for an in-process source, `replay`
    /// and `bvh` the identity (their poses are published as they come).
    pub fn resolve(&self, source: &TrackerSource) -> (TransformConfig, TransformConfig) {
        let (base, hand) = match source {
            TrackerSource::Mocap(_) => (
                calibration::default_base_from_mocap(),
                calibration::default_hand_from_marker(),
            ),
            TrackerSource::InProcess | TrackerSource::Replay(_) | TrackerSource::Bvh(_) => {
                (TransformConfig::default(), TransformConfig::default())
            }
        };
        (
            self.base_from_tracker.unwrap_or(base),
            self.hand_from_marker.unwrap_or(hand),
        )
    }

    /// # Errors
    /// A transform with a non-finite (or absurd) value.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(t) = &self.base_from_tracker {
            t.validate("registration.base_from_tracker")?;
        }
        if let Some(t) = &self.hand_from_marker {
            t.validate("registration.hand_from_marker")?;
        }
        Ok(())
    }
}

/// The registration chain (eq. 7.1) folded into two transforms: the tracked marker
/// pose in, the hand frame in the UR5 base frame out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    base_from_tracker: Isometry3<f64>,
    marker_from_hand: Isometry3<f64>,
}

impl Registration {
    /// From the tracker's pose in the base and the marker's pose in the hand frame.
    pub fn new(base_from_tracker: &Isometry3<f64>, hand_from_marker: &Isometry3<f64>) -> Self {
        Self {
            base_from_tracker: *base_from_tracker,
            marker_from_hand: hand_from_marker.inverse(),
        }
    }

    /// No registration: poses pass unchanged.
    pub fn identity() -> Self {
        Self::new(&Isometry3::identity(), &Isometry3::identity())
    }

    /// The hand frame in the base: `base_from_tracker * tracker_from_marker *
    /// hand_from_marker^-1`.
    pub fn hand_in_base(&self, tracker_from_marker: &Isometry3<f64>) -> Isometry3<f64> {
        self.base_from_tracker * tracker_from_marker * self.marker_from_hand
    }

    /// The inverse: the marker pose the tracker sees when the hand is at
    /// `base_from_hand` (what a simulated tracker publishes).
    pub fn marker_in_tracker(&self, base_from_hand: &Isometry3<f64>) -> Isometry3<f64> {
        self.base_from_tracker.inverse() * base_from_hand * self.marker_from_hand.inverse()
    }
}

/// Re-acquisition after a rejected jump, `[reacquire]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReacquireConfig {
    /// How long the rejected poses must agree before they are taken as the hand's new
    /// place, s. Default 0.3.
    pub after_s: f64,
    /// Largest distance of a pose from the first of the agreeing run, m. Default 0.05.
    pub position_tolerance_m: f64,
    /// Largest rotation of a pose from the first of the run, deg. Default 10.
    pub orientation_tolerance_deg: f64,
    /// A longer gap between two rejected samples restarts the run, s. Default 0.05.
    pub max_gap_s: f64,
}

impl Default for ReacquireConfig {
    fn default() -> Self {
        Self {
            after_s: 0.3,
            position_tolerance_m: 0.05,
            orientation_tolerance_deg: 10.0,
            max_gap_s: 0.05,
        }
    }
}

impl ReacquireConfig {
    /// # Errors
    /// [`ConfigError::OutOfRange`] naming the first field out of its range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (name, value, min, max) in [
            ("after_s", self.after_s, 0.0, 60.0),
            ("position_tolerance_m", self.position_tolerance_m, 1e-4, 1.0),
            (
                "orientation_tolerance_deg",
                self.orientation_tolerance_deg,
                0.01,
                90.0,
            ),
            ("max_gap_s", self.max_gap_s, 1e-4, 10.0),
        ] {
            if !(value.is_finite() && value >= min && value <= max) {
                return Err(ConfigError::OutOfRange {
                    name,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }
}

/// What the [`PoseGate`] decided about one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Within the limits of the last accepted pose: publish it.
    Accepted(Isometry3<f64>),
    /// A jump that persisted and agreed with itself for `reacquire.after_s`: the
    /// filter was reset on it; publish it.
    Reacquired(Isometry3<f64>),
    /// Not published.
    Rejected(Rejection),
}

/// A run of rejected poses that agree with each other.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    anchor: Isometry3<f64>,
    since_s: f64,
    last_s: f64,
}

/// The jump filter with the tracker's re-acquisition rule (module docs, step 3).
///
/// Every pose is counted once: accepted, re-acquired or rejected by reason. A pose
/// rejected as invalid (non-finite, quaternion not normalized) neither starts nor
/// breaks an agreeing run.
#[derive(Debug, Clone)]
pub struct PoseGate {
    jump: JumpFilter,
    cfg: ReacquireConfig,
    max_orientation_rad: f64,
    candidate: Option<Candidate>,
    reacquired: u64,
}

impl PoseGate {
    /// A gate with no reference: its first valid pose is accepted.
    ///
    /// # Errors
    /// Either config's validation error.
    pub fn new(jump: JumpFilterConfig, reacquire: ReacquireConfig) -> Result<Self, ConfigError> {
        reacquire.validate()?;
        Ok(Self {
            jump: JumpFilter::new(jump)?,
            cfg: reacquire,
            max_orientation_rad: reacquire.orientation_tolerance_deg.to_radians(),
            candidate: None,
            reacquired: 0,
        })
    }

    /// Judges `pose`, sampled at `t_s` (s, any clock whose differences are seconds:
    /// the capture time).
    pub fn step(&mut self, t_s: f64, pose: &Isometry3<f64>) -> Verdict {
        let rejection = match self.jump.check(pose) {
            Ok(()) => return self.accept(pose),
            Err(r) => r,
        };
        if matches!(
            rejection.kind(),
            RejectionKind::PositionJump | RejectionKind::OrientationJump
        ) {
            let run = self
                .candidate
                .filter(|c| t_s - c.last_s <= self.cfg.max_gap_s && self.agrees(&c.anchor, pose));
            match run {
                Some(c) if t_s - c.since_s >= self.cfg.after_s => {
                    self.jump.reset();
                    if let Verdict::Accepted(p) = self.accept(pose) {
                        self.reacquired += 1;
                        return Verdict::Reacquired(p);
                    }
                }
                Some(c) => {
                    self.candidate = Some(Candidate { last_s: t_s, ..c });
                }
                None => {
                    self.candidate = Some(Candidate {
                        anchor: *pose,
                        since_s: t_s,
                        last_s: t_s,
                    });
                }
            }
        }
        match self.jump.filter(pose) {
            // Unreachable after a failed check; treat as accepted all the same.
            Ok(p) => {
                self.candidate = None;
                Verdict::Accepted(p)
            }
            Err(r) => Verdict::Rejected(r),
        }
    }

    fn accept(&mut self, pose: &Isometry3<f64>) -> Verdict {
        match self.jump.filter(pose) {
            Ok(p) => {
                self.candidate = None;
                Verdict::Accepted(p)
            }
            Err(r) => Verdict::Rejected(r),
        }
    }

    fn agrees(&self, anchor: &Isometry3<f64>, pose: &Isometry3<f64>) -> bool {
        (pose.translation.vector - anchor.translation.vector).norm()
            <= self.cfg.position_tolerance_m
            && anchor.rotation.angle_to(&pose.rotation) <= self.max_orientation_rad
    }

    /// Rejections per reason.
    pub fn rejections(&self) -> &RejectionCounts {
        self.jump.rejections()
    }

    /// Times a jump was re-acquired.
    pub fn reacquired(&self) -> u64 {
        self.reacquired
    }

    /// Poses accepted (re-acquired ones included).
    pub fn accepted(&self) -> u64 {
        self.jump.accepted()
    }

    /// The last accepted pose.
    pub fn reference(&self) -> Option<&Isometry3<f64>> {
        self.jump.reference()
    }

    /// True while poses are being rejected since the last accepted one.
    pub fn holding(&self) -> bool {
        self.jump.consecutive_rejections() > 0
    }
}

pub use teleop_hardware::wire::pose_msg;

/// A wrist pose device as the node reads it.
pub enum PoseDevice {
    /// The motion capture over the bus: samples carry their capture stamp and arrive
    /// at the tracker's rate.
    Mocap(BusWristTracker),
    /// Any other tracker, read once per tick: a sample is stamped with the read time.
    Other(Box<dyn WristTracker>),
}

impl std::fmt::Debug for PoseDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Mocap(t) => f.debug_tuple("Mocap").field(t).finish(),
            Self::Other(_) => f.write_str("Other(..)"),
        }
    }
}

/// One sample of a [`PoseDevice`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    tracker_from_marker: Isometry3<f64>,
    stamp: Time,
    t_s: f64,
}

impl PoseDevice {
    fn read(&mut self, now_s: f64) -> Result<Option<Sample>, HardwareError> {
        Ok(match self {
            Self::Mocap(t) => t.read_sample(now_s)?.map(|s| Sample {
                tracker_from_marker: s.pose,
                stamp: s.capture,
                t_s: s.capture.as_secs_f64(),
            }),
            Self::Other(t) => t.read(now_s)?.map(|p| Sample {
                tracker_from_marker: p,
                stamp: Time::from_secs_f64(now_s),
                t_s: now_s,
            }),
        })
    }

    /// `(non-finite, not normalized)` samples the device itself refused.
    fn refused(&self) -> (u64, u64) {
        match self {
            Self::Mocap(t) => (t.non_finite(), t.not_normalized()),
            Self::Other(_) => (0, 0),
        }
    }

    fn skipped(&self) -> u64 {
        match self {
            Self::Mocap(t) => t.skipped(),
            Self::Other(_) => 0,
        }
    }

    /// Samples per second the device delivers, or `None` when it is read once per
    /// tick.
    fn rate_hz(&self) -> Option<f64> {
        match self {
            Self::Mocap(_) => Some(topics::HW_MOCAP_MARKER.spec.rate_hz),
            Self::Other(_) => None,
        }
    }
}

/// Counters of the node.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct TrackerCounters {
    /// Wrist poses published.
    pub poses_published: u64,
    /// Ticks without a new sample (occlusion, tracker slower than the tick, lost).
    pub poses_missing: u64,
    /// Gaps between consecutive samples longer than `dropout_after_s`.
    pub dropouts: u64,
    /// Samples rejected for a position jump.
    pub rejected_position_jump: u64,
    /// Samples rejected for an orientation jump.
    pub rejected_orientation_jump: u64,
    /// Samples with a NaN or infinite value (refused by the device or the filter).
    pub rejected_non_finite: u64,
    /// Samples whose quaternion is not of unit norm.
    pub rejected_not_normalized: u64,
    /// Jumps re-acquired (filter reset on a persistent new place).
    pub reacquired: u64,
    /// Samples replaced by a newer one before a tick read them.
    pub skipped: u64,
    /// Times the tracker went stale (samples stopped for `source.stale_after_s`).
    pub stale: u64,
    /// Pedal states published.
    pub inputs_published: u64,
    /// Times the pedals went stale (no state for `panel.stale_after_s`; nothing is
    /// published meanwhile).
    pub inputs_stale: u64,
}

impl TrackerCounters {
    /// The counters by name, as in the node status.
    pub fn named(&self) -> Vec<(String, u64)> {
        [
            ("wrist_pose.published", self.poses_published),
            ("wrist_pose.missing", self.poses_missing),
            ("wrist_pose.dropouts", self.dropouts),
            (
                "wrist_pose.rejected_position_jump",
                self.rejected_position_jump,
            ),
            (
                "wrist_pose.rejected_orientation_jump",
                self.rejected_orientation_jump,
            ),
            ("wrist_pose.rejected_non_finite", self.rejected_non_finite),
            (
                "wrist_pose.rejected_not_normalized",
                self.rejected_not_normalized,
            ),
            ("wrist_pose.reacquired", self.reacquired),
            ("wrist_pose.skipped", self.skipped),
            ("wrist_pose.stale", self.stale),
            ("operator_input.published", self.inputs_published),
            ("operator_input.stale", self.inputs_stale),
        ]
        .into_iter()
        .map(|(n, v)| (n.to_owned(), v))
        .collect()
    }
}

/// The node: the devices, the pose pipeline, the publishers.
pub struct WristTrackerNode {
    frame_id: String,
    tick_period: Duration,
    dropout_after_s: f64,
    device: PoseDevice,
    panel: Box<dyn OperatorPanel>,
    registration: Registration,
    gate: PoseGate,
    /// `None`: publish every accepted sample.
    pose_due: Option<Periodic>,
    pending: Option<(Isometry3<f64>, Time)>,
    last_sample_s: Option<f64>,
    pose_pub: Publisher<PoseStamped>,
    input_pub: Publisher<OperatorInput>,
    input_due: Periodic,
    counters: TrackerCounters,
    /// What is wrong with the tracker now (`None`: delivering).
    tracker_error: Option<HardwareError>,
    /// What is wrong with the pedals now.
    panel_error: Option<HardwareError>,
    errors: NodeErrors,
}

impl std::fmt::Debug for WristTrackerNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WristTrackerNode")
            .field("device", &self.device)
            .field("counters", &self.tracker_counters())
            .finish()
    }
}

impl WristTrackerNode {
    /// The node with the configured pose source and panel.
    ///
    /// # Errors
    /// The source cannot be opened; bus declarations; an invalid filter config.
    pub async fn new(cfg: &WristTrackerConfig, bus: &Bus) -> anyhow::Result<Self> {
        Self::with_in_process(cfg, bus, InProcessDevices::default()).await
    }

    /// The node with the devices handed in (a tracker is read once per tick, stamped
    /// with the read time), the configured source or panel for those not handed in
    /// (`None`); registration and filters from `cfg`.
    ///
    /// # Errors
    /// A configured source cannot be opened (an [`TrackerSource::InProcess`] one not
    /// handed in); bus declarations; an invalid filter config.
    pub async fn with_in_process(
        cfg: &WristTrackerConfig,
        bus: &Bus,
        devices: InProcessDevices,
    ) -> anyhow::Result<Self> {
        let device = match devices.tracker {
            Some(t) => PoseDevice::Other(t),
            None => cfg.source.open(bus).await?,
        };
        let panel = match devices.panel {
            Some(p) => p,
            None => cfg.panel.open(bus).await?,
        };
        Self::with_pose_device(cfg, bus, device, panel).await
    }

    /// The node with a given pose device and panel; registration and filters from
    /// `cfg`.
    ///
    /// # Errors
    /// Bus declarations; an invalid filter config.
    pub async fn with_pose_device(
        cfg: &WristTrackerConfig,
        bus: &Bus,
        device: PoseDevice,
        panel: Box<dyn OperatorPanel>,
    ) -> anyhow::Result<Self> {
        let source_rate_hz = device.rate_hz().unwrap_or(cfg.tick_rate_hz);
        if cfg.tick_rate_hz < source_rate_hz {
            tracing::warn!(
                tick_rate_hz = cfg.tick_rate_hz,
                source_rate_hz,
                "the node ticks slower than its source: samples will be skipped"
            );
        }
        let pose_due =
            (cfg.pose_rate_hz < source_rate_hz).then(|| Periodic::at_rate(cfg.pose_rate_hz));
        Ok(Self {
            frame_id: cfg.frame_id_in_effect(),
            tick_period: Duration::from_secs_f64(1.0 / cfg.tick_rate_hz),
            dropout_after_s: cfg.dropout_after_s,
            device,
            panel,
            registration: cfg.registration_in_effect(),
            gate: PoseGate::new(cfg.jump, cfg.reacquire)?,
            pose_due,
            pending: None,
            last_sample_s: None,
            pose_pub: bus.publisher(&topics::WRIST_POSE).await?,
            input_pub: bus.publisher(&topics::OPERATOR_INPUT).await?,
            input_due: Periodic::at_rate(cfg.input_rate_hz),
            counters: TrackerCounters::default(),
            tracker_error: Some(HardwareError::NotConnected("tracker not read yet".into())),
            panel_error: Some(HardwareError::NotConnected("pedals not read yet".into())),
            errors: NodeErrors::new(),
        })
    }

    /// Counters so far.
    pub fn tracker_counters(&self) -> TrackerCounters {
        let r = self.gate.rejections();
        let (non_finite, not_normalized) = self.device.refused();
        TrackerCounters {
            rejected_position_jump: r.get(RejectionKind::PositionJump),
            rejected_orientation_jump: r.get(RejectionKind::OrientationJump),
            rejected_non_finite: r.get(RejectionKind::NonFinite) + non_finite,
            rejected_not_normalized: r.get(RejectionKind::NotNormalized) + not_normalized,
            reacquired: self.gate.reacquired(),
            skipped: self.device.skipped(),
            ..self.counters
        }
    }

    /// The frame id of published poses.
    pub fn frame_id(&self) -> &str {
        &self.frame_id
    }

    fn read_tracker(&mut self, now_s: f64) {
        let refused_before = self.device.refused();
        let read = self.device.read(now_s);
        let refused_after = self.device.refused();
        if refused_after.0 > refused_before.0 {
            let text = "tracker sample refused: non-finite value";
            self.errors.event("tracker sample", text, now_s);
        } else if refused_after.1 > refused_before.1 {
            let text = "tracker sample refused: quaternion not normalized";
            self.errors.event("tracker sample", text, now_s);
        }
        match read {
            Ok(sample) => {
                self.tracker_error = None;
                self.errors.resolved("tracker", now_s);
                match sample {
                    Some(s) => self.take_sample(now_s, &s),
                    None => self.counters.poses_missing += 1,
                }
            }
            Err(e) => {
                self.counters.poses_missing += 1;
                if matches!(e, HardwareError::StaleState { .. })
                    && !matches!(self.tracker_error, Some(HardwareError::StaleState { .. }))
                {
                    self.counters.stale += 1;
                }
                self.errors
                    .condition("tracker", format!("tracker: {e}"), now_s);
                self.tracker_error = Some(e);
            }
        }
    }

    fn take_sample(&mut self, now_s: f64, s: &Sample) {
        if let Some(prev) = self.last_sample_s
            && s.t_s - prev > self.dropout_after_s
        {
            self.counters.dropouts += 1;
        }
        self.last_sample_s = Some(s.t_s);
        let hand = self.registration.hand_in_base(&s.tracker_from_marker);
        match self.gate.step(s.t_s, &hand) {
            Verdict::Accepted(p) => self.pending = Some((p, s.stamp)),
            Verdict::Reacquired(p) => {
                tracing::info!("wrist pose re-acquired at a new place after a jump");
                self.pending = Some((p, s.stamp));
            }
            Verdict::Rejected(e) => {
                tracing::debug!("wrist pose rejected: {e}");
                let text = format!("wrist pose rejected: {e}");
                self.errors.event("wrist pose", text, now_s);
            }
        }
    }

    fn publish_pose(&mut self, now_s: f64) {
        if self.pending.is_none() {
            return;
        }
        if let Some(due) = &mut self.pose_due
            && !due.due(now_s)
        {
            return;
        }
        let Some((pose, stamp)) = self.pending.take() else {
            return;
        };
        let Some(pose) = pose_msg(&pose) else {
            // The gate refuses non-finite poses; kept as a last check.
            self.counters.rejected_non_finite += 1;
            return;
        };
        let msg = PoseStamped {
            header: Header::new(stamp, self.frame_id.clone()),
            pose,
        };
        match self.pose_pub.put(&msg) {
            Ok(()) => self.counters.poses_published += 1,
            Err(e) => {
                let text = format!("publishing wrist pose: {e}");
                self.errors.event("publish", text, now_s);
            }
        }
    }

    fn publish_input(&mut self, now_s: f64) {
        if !self.input_due.due(now_s) {
            return;
        }
        match self.panel.read(now_s) {
            Ok(s) => {
                self.panel_error = None;
                self.errors.resolved("pedals", now_s);
                let msg = OperatorInput {
                    header: Header::new(Time::from_secs_f64(now_s), ""),
                    clutch: s.clutch,
                    enable: s.enable,
                    camera_stop: s.camera_stop,
                    motion_scale: s.motion_scale,
                };
                match self.input_pub.put(&msg) {
                    Ok(()) => self.counters.inputs_published += 1,
                    Err(e) => {
                        let text = format!("publishing operator input: {e}");
                        self.errors.event("publish", text, now_s);
                    }
                }
            }
            Err(e) => {
                // Nothing is published: the robot site stops on stale input.
                if matches!(e, HardwareError::StaleState { .. })
                    && !matches!(self.panel_error, Some(HardwareError::StaleState { .. }))
                {
                    self.counters.inputs_stale += 1;
                }
                self.errors
                    .condition("pedals", format!("pedals: {e}"), now_s);
                self.panel_error = Some(e);
            }
        }
    }
}

impl Node for WristTrackerNode {
    fn period(&self) -> Duration {
        self.tick_period
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        self.read_tracker(now_s);
        self.publish_pose(now_s);
        self.publish_input(now_s);
    }

    fn state(&self) -> Lifecycle {
        if self.tracker_error.is_none() && self.panel_error.is_none() {
            Lifecycle::Active
        } else {
            Lifecycle::Fault
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        self.tracker_counters().named()
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus errors (session, declarations), the source cannot be opened.
pub async fn run(
    cfg: WristTrackerConfig,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    run_with_devices(cfg, InProcessDevices::default(), duration).await
}

/// What a config file cannot open: an in-process source or panel.
const IN_PROCESS_ONLY: &str = "an in-process source or panel is handed to the node by the program that embeds it (wrist_tracker::run_with_devices); a config file names mocap, replay or bvh ([source]) and bus or keyboard ([panel])";

/// Devices handed to the node by the program that embeds it (a simulated operator in
/// a test, a driver linked in); `None` takes the configured one.
#[derive(Default)]
pub struct InProcessDevices {
    /// The wrist pose source, read once per tick (set `[source]` to
    /// [`TrackerSource::InProcess`] for its registration and frame).
    pub tracker: Option<Box<dyn WristTracker>>,
    /// The pedals.
    pub panel: Option<Box<dyn OperatorPanel>>,
}

impl std::fmt::Debug for InProcessDevices {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InProcessDevices")
            .field("tracker", &self.tracker.is_some())
            .field("panel", &self.panel.is_some())
            .finish()
    }
}

/// Runs the node like [`run`], with the devices handed in by the embedding program in
/// place of the configured ones.
///
/// # Errors
/// Bus errors (session, declarations), a configured source that cannot be opened.
pub async fn run_with_devices(
    cfg: WristTrackerConfig,
    devices: InProcessDevices,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let source = match devices.tracker {
        Some(_) => "an in-process tracker".to_owned(),
        None => cfg.source.describe(),
    };
    let node = WristTrackerNode::with_in_process(&cfg, &bus, devices).await?;
    tracing::info!(
        zid = bus.zid(),
        source,
        frame_id = node.frame_id(),
        "wrist tracker running"
    );
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};
    use teleop_control::Axis;

    fn pose(x: f64, y: f64, z: f64, r: f64, p: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(r, p, yaw),
        )
    }

    #[test]
    fn non_finite_poses_are_refused() {
        let mut p = Isometry3::<f64>::identity();
        assert!(pose_msg(&p).is_some());
        p.translation.vector.x = f64::NAN;
        assert!(pose_msg(&p).is_none());
    }

    #[test]
    fn registration_gives_the_known_hand_pose_exactly() {
        let cfg = WristTrackerConfig::default();
        let reg = cfg.registration_in_effect();
        let base_from_tracker = calibration::default_base_from_mocap().isometry();
        let hand_from_marker = calibration::default_hand_from_marker().isometry();
        // A known hand pose in the base, its marker as the tracker sees it (computed
        // independently of `Registration`), back through the registration.
        let hand = pose(0.55, -0.12, 0.31, 0.4, -0.7, 2.1);
        let marker = base_from_tracker.inverse() * hand * hand_from_marker;
        let got = reg.hand_in_base(&marker);
        assert!(
            (got.translation.vector - hand.translation.vector).amax() < 1e-12,
            "{got} vs {hand}"
        );
        assert!(got.rotation.angle_to(&hand.rotation) < 1e-12);
        // And the inverse map.
        let m = reg.marker_in_tracker(&hand);
        assert!((m.translation.vector - marker.translation.vector).amax() < 1e-12);
        assert!(m.rotation.angle_to(&marker.rotation) < 1e-12);
        // A hand at the base origin, axes aligned: the marker sits where the sim's
        // calibration puts it: tracker_from_marker = base_from_tracker^-1 * hand_from_marker.
        let at_origin = reg.marker_in_tracker(&Isometry3::identity());
        let expected = base_from_tracker.inverse() * hand_from_marker;
        assert!((at_origin.translation.vector - expected.translation.vector).amax() < 1e-12);
        // The marker 3 cm behind the back of the hand: the wrist is 3 cm in front of it
        // along the hand's +y (palm normal) and 5 cm back toward the wrist.
        let hand_at = reg.hand_in_base(&marker);
        let marker_in_base = base_from_tracker * marker;
        let offset_in_hand = hand_at
            .inverse_transform_point(&nalgebra::Point3::from(marker_in_base.translation.vector))
            .coords;
        assert!((offset_in_hand - Vector3::new(0.0, -0.03, 0.05)).amax() < 1e-12);
    }

    #[test]
    fn registration_defaults_depend_on_the_source() {
        let mocap = WristTrackerConfig::default();
        assert_eq!(mocap.frame_id_in_effect(), BASE_FRAME);
        let (b, h) = mocap.registration.resolve(&mocap.source);
        assert_eq!(b, calibration::default_base_from_mocap());
        assert_eq!(h, calibration::default_hand_from_marker());
        let sim = WristTrackerConfig {
            source: TrackerSource::InProcess,
            ..Default::default()
        };
        assert_eq!(sim.frame_id_in_effect(), TRACKER_FRAME);
        let p = pose(0.3, 0.2, 0.1, 0.1, 0.2, 0.3);
        assert_eq!(sim.registration_in_effect().hand_in_base(&p), p);
        // An explicit transform wins over the source default, and a registered pose is
        // in the base frame.
        let moved = TransformConfig {
            translation_m: [1.0, 0.0, 0.0],
            rpy_deg: [0.0; 3],
        };
        let registered_sim = WristTrackerConfig {
            source: TrackerSource::InProcess,
            registration: RegistrationConfig {
                base_from_tracker: Some(moved),
                hand_from_marker: None,
            },
            ..Default::default()
        };
        assert_eq!(registered_sim.frame_id_in_effect(), BASE_FRAME);
        let got = registered_sim.registration_in_effect().hand_in_base(&p);
        assert!((got.translation.vector - Vector3::new(1.3, 0.2, 0.1)).amax() < 1e-15);
        let toml: WristTrackerConfig =
            toml::from_str("[registration.hand_from_marker]\ntranslation_m = [0.0, 0.0, 0.1]\n")
                .expect("parses");
        let (b, h) = toml.registration.resolve(&toml.source);
        assert_eq!(b, calibration::default_base_from_mocap());
        assert_eq!(h.translation_m, [0.0, 0.0, 0.1]);
    }

    const DT: f64 = 1.0 / 320.0;

    #[test]
    fn the_gate_drops_a_glitch_and_reacquires_a_relocation() {
        let mut gate =
            PoseGate::new(JumpFilterConfig::default(), ReacquireConfig::default()).expect("valid");
        let home = pose(0.5, 0.0, 0.3, 0.0, 0.0, 0.0);
        let mut t = 100.0;
        fn feed(gate: &mut PoseGate, t: &mut f64, p: &Isometry3<f64>) -> Verdict {
            let v = gate.step(*t, p);
            *t += DT;
            v
        }
        for _ in 0..10 {
            assert!(matches!(
                feed(&mut gate, &mut t, &home),
                Verdict::Accepted(_)
            ));
        }
        // A one-sample glitch 0.8 m along y: rejected, not published; the next normal
        // sample is accepted.
        let glitch = pose(0.5, 0.8, 0.3, 0.0, 0.0, 0.0);
        match feed(&mut gate, &mut t, &glitch) {
            Verdict::Rejected(Rejection::PositionJump { axis, .. }) => assert_eq!(axis, Axis::Y),
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            feed(&mut gate, &mut t, &home),
            Verdict::Accepted(_)
        ));
        // An orientation glitch (90 deg) of three samples: rejected, counted apart.
        let turned = pose(0.5, 0.0, 0.3, 90f64.to_radians(), 0.0, 0.0);
        for _ in 0..3 {
            assert!(matches!(
                feed(&mut gate, &mut t, &turned),
                Verdict::Rejected(Rejection::OrientationJump { .. })
            ));
        }
        assert!(matches!(
            feed(&mut gate, &mut t, &home),
            Verdict::Accepted(_)
        ));
        // NaN: rejected, counted, changes nothing.
        let mut nan = home;
        nan.translation.vector.z = f64::NAN;
        assert!(matches!(
            feed(&mut gate, &mut t, &nan),
            Verdict::Rejected(Rejection::NonFinite { .. })
        ));
        assert_eq!(gate.reference(), Some(&home));
        // A real relocation (the tracker re-mounted, the hand 0.7 m away), with 1 mm of
        // noise: rejected until it has agreed for 0.3 s, then re-acquired.
        let start = t;
        let moved = |k: usize| {
            let e = 1e-3 * ((k as f64) * 1.7).sin();
            pose(1.2 + e, 0.0, 0.3 - e, 0.0, 0.0, 0.01 * e)
        };
        let mut k = 0;
        let reacquired_at = loop {
            match feed(&mut gate, &mut t, &moved(k)) {
                Verdict::Rejected(Rejection::PositionJump { .. }) => {}
                Verdict::Reacquired(p) => break (t - DT, p),
                other => panic!("sample {k}: {other:?}"),
            }
            k += 1;
            assert!(k < 1000, "never re-acquired");
        };
        let waited = reacquired_at.0 - start;
        assert!((0.3..0.3 + 1.5 * DT).contains(&waited), "{waited}");
        assert_eq!(reacquired_at.1, moved(k));
        // From there on, the new place is the reference.
        assert!(matches!(
            feed(&mut gate, &mut t, &moved(k + 1)),
            Verdict::Accepted(_)
        ));
        let r = gate.rejections();
        assert_eq!(r.get(RejectionKind::PositionJump), 1 + k as u64);
        assert_eq!(r.get(RejectionKind::OrientationJump), 3);
        assert_eq!(r.get(RejectionKind::NonFinite), 1);
        assert_eq!(gate.reacquired(), 1);
    }

    #[test]
    fn a_jumping_stream_that_does_not_settle_is_never_reacquired() {
        let mut gate =
            PoseGate::new(JumpFilterConfig::default(), ReacquireConfig::default()).expect("valid");
        let mut t = 0.0;
        assert!(matches!(
            gate.step(t, &Isometry3::identity()),
            Verdict::Accepted(_)
        ));
        // Far away, but wandering 10 cm per sample: never agrees, never re-acquired.
        for k in 0..400 {
            t += DT;
            let x = 1.0 + 0.1 * f64::from(k % 2);
            assert!(matches!(
                gate.step(t, &pose(x, 0.0, 0.0, 0.0, 0.0, 0.0)),
                Verdict::Rejected(_)
            ));
        }
        // Far away and steady, but with a gap longer than max_gap_s in the middle:
        // the run restarts after the gap.
        let far = pose(0.0, 0.0, 0.9, 0.0, 0.0, 0.0);
        let mut k = 0;
        for _ in 0..64 {
            t += DT;
            assert!(matches!(gate.step(t, &far), Verdict::Rejected(_)));
        }
        t += 0.1;
        let restart = t;
        loop {
            t += DT;
            k += 1;
            if let Verdict::Reacquired(_) = gate.step(t, &far) {
                break;
            }
            assert!(k < 1000);
        }
        assert!(t - restart >= 0.3, "{}", t - restart);
        assert!(!gate.holding());
    }

    #[test]
    fn default_config_is_valid_and_rates_are_checked() {
        let cfg = WristTrackerConfig::default();
        cfg.validate().expect("default valid");
        assert_eq!(cfg.source, TrackerSource::Mocap(MocapConfig::default()));
        assert_eq!(cfg.panel, PanelSource::Bus(BusPanelConfig::default()));
        let bad = WristTrackerConfig {
            pose_rate_hz: 0.0,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().contains("pose_rate_hz"));
        let faster = WristTrackerConfig {
            pose_rate_hz: 500.0,
            ..Default::default()
        };
        assert!(faster.validate().unwrap_err().contains("tick_rate_hz"));
        let bad_reacquire = WristTrackerConfig {
            reacquire: ReacquireConfig {
                after_s: -1.0,
                ..Default::default()
            },
            ..Default::default()
        };
        assert!(bad_reacquire.validate().unwrap_err().contains("after_s"));
        let bad_registration: WristTrackerConfig =
            toml::from_str("[registration.base_from_tracker]\ntranslation_m = [1e9, 0.0, 0.0]\n")
                .expect("parses");
        assert!(
            bad_registration
                .validate()
                .unwrap_err()
                .contains("base_from_tracker")
        );
    }

    #[test]
    fn sources_parse_from_toml_and_unknown_fields_are_refused() {
        let mocap: WristTrackerConfig =
            toml::from_str("[source]\nkind = \"mocap\"\nstale_after_s = 0.5\n").expect("mocap");
        assert_eq!(
            mocap.source,
            TrackerSource::Mocap(MocapConfig { stale_after_s: 0.5 })
        );
        let panel: WristTrackerConfig =
            toml::from_str("[panel]\nkind = \"bus\"\nstale_after_s = 0.3\n").expect("panel");
        assert_eq!(
            panel.panel,
            PanelSource::Bus(BusPanelConfig { stale_after_s: 0.3 })
        );
        // In-process devices have no name in a config file; the simulated operator
        // that once ran inside the node is the operator-site simulator's now.
        for text in [
            "[panel]\nkind = \"simulated\"\n",
            "[source]\nkind = \"simulated\"\n",
            "[source]\nkind = \"in_process\"\n",
            "[operator]\nclutch_delay_s = 1.0\n",
        ] {
            assert!(
                toml::from_str::<WristTrackerConfig>(text).is_err(),
                "{text} must be refused"
            );
        }
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
        assert_eq!(bvh.frame_id_in_effect(), TRACKER_FRAME);
        // With the chapter-6 arm registration the poses are PR2 targets in the torso.
        let absolute: WristTrackerConfig = toml::from_str(
            "[source]\nkind = \"bvh\"\naddress = \"10.0.0.5:7001\"\nskeleton = \"neuron.bvh\"\n\
             [source.arm]\nelbow_joint = \"RightForeArm\"\n",
        )
        .expect("bvh source with the arm registration");
        assert_eq!(absolute.frame_id_in_effect(), "torso_lift_link");
        absolute.validate().expect("valid");
        let typo = toml::from_str::<WristTrackerConfig>(
            "[source]\nkind = \"bvh\"\naddress = \"h:1\"\nskeleton = \"n.bvh\"\n\
             [source.arm]\nratio = 1.3\n",
        )
        .expect_err("unknown field");
        assert!(typo.to_string().contains("ratio"), "{typo}");
        let typo = toml::from_str::<WristTrackerConfig>(
            "[source]\nkind = \"replay\"\npath = \"p.csv\"\nmax_gap = 1.0\n",
        )
        .expect_err("unknown field");
        assert!(typo.to_string().contains("max_gap"), "{typo}");
        let typo = toml::from_str::<WristTrackerConfig>("[reacquire]\nafter = 1.0\n")
            .expect_err("unknown field");
        assert!(typo.to_string().contains("after"), "{typo}");
        let bad_gap: WristTrackerConfig =
            toml::from_str("[source]\nkind = \"replay\"\npath = \"p.csv\"\nmax_gap_s = -1.0\n")
                .expect("parses");
        assert!(bad_gap.validate().unwrap_err().contains("max_gap_s"));
        // The default config round-trips through its TOML form.
        let text = teleop_node::config::to_toml(&WristTrackerConfig::default()).expect("toml");
        let back: WristTrackerConfig = toml::from_str(&text).expect("parses back");
        assert_eq!(back, WristTrackerConfig::default());
    }

    #[test]
    fn the_keyboard_panel_parses_and_its_fields_are_checked() {
        let cfg: WristTrackerConfig =
            toml::from_str("[panel]\nkind = \"keyboard\"\n").expect("keyboard panel");
        assert_eq!(
            cfg.panel,
            PanelSource::Keyboard(KeyboardPanelConfig::default())
        );
        cfg.validate().expect("default keyboard panel valid");
        let cfg: WristTrackerConfig = toml::from_str(
            "[panel]\nkind = \"keyboard\"\nhold_timeout_s = 0.9\nmotion_scale = 0.5\n",
        )
        .expect("keyboard panel");
        assert_eq!(
            cfg.panel,
            PanelSource::Keyboard(KeyboardPanelConfig {
                hold_timeout_s: 0.9,
                motion_scale: 0.5,
            })
        );
        cfg.validate().expect("valid");
        let typo = toml::from_str::<WristTrackerConfig>(
            "[panel]\nkind = \"keyboard\"\nhold_timeout = 0.9\n",
        )
        .expect_err("unknown field");
        assert!(typo.to_string().contains("hold_timeout"), "{typo}");
        // A field of the bus panel is not one of the keyboard's.
        let other = toml::from_str::<WristTrackerConfig>(
            "[panel]\nkind = \"keyboard\"\nstale_after_s = 0.1\n",
        )
        .expect_err("unknown field");
        assert!(other.to_string().contains("stale_after_s"), "{other}");
        for (text, name) in [
            ("hold_timeout_s = 5.0", "panel.hold_timeout_s"),
            ("hold_timeout_s = 0.0", "panel.hold_timeout_s"),
            ("motion_scale = 1.5", "panel.motion_scale"),
            ("motion_scale = -0.5", "panel.motion_scale"),
        ] {
            let cfg: WristTrackerConfig =
                toml::from_str(&format!("[panel]\nkind = \"keyboard\"\n{text}\n")).expect("parses");
            let e = cfg.validate().expect_err(text);
            assert!(e.starts_with(name), "{text}: {e}");
        }
        // Round trip through the TOML form.
        let text = teleop_node::config::to_toml(&cfg_with_keyboard()).expect("toml");
        let back: WristTrackerConfig = toml::from_str(&text).expect("parses back");
        assert_eq!(back, cfg_with_keyboard());
    }

    fn cfg_with_keyboard() -> WristTrackerConfig {
        WristTrackerConfig {
            panel: PanelSource::Keyboard(KeyboardPanelConfig {
                hold_timeout_s: 0.8,
                motion_scale: 0.25,
            }),
            ..Default::default()
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 1)]
    async fn a_missing_replay_file_is_named() {
        let bus = Bus::open(
            "wrist_tracker_test",
            &BusConfig {
                zenoh: teleop_bus::ZenohSettings {
                    multicast_scouting: false,
                    ..Default::default()
                },
                ..Default::default()
            },
        )
        .await
        .expect("bus");
        let missing = TrackerSource::Replay(ReplayConfig {
            path: "/nonexistent/poses.csv".into(),
            end: crate::tracking::replay::ReplayEnd::Stop,
            max_gap_s: 0.1,
        })
        .open(&bus)
        .await
        .expect_err("missing file");
        assert!(missing.to_string().contains("/nonexistent/poses.csv"));
        let in_process = TrackerSource::InProcess
            .open(&bus)
            .await
            .expect_err("no device handed in");
        assert!(
            in_process.to_string().contains("run_with_devices"),
            "{in_process}"
        );
        let panel = PanelSource::InProcess
            .open(&bus)
            .await
            .err()
            .expect("no panel handed in");
        assert!(panel.to_string().contains("run_with_devices"), "{panel}");
    }
}
