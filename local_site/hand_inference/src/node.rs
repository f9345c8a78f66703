//! The `hand_inference` node (operator site): depth frames of the operator's hand in,
//! the Shadow hand's 17 finger joint targets out.
//!
//! Per depth frame ([`topics::HW_HAND_DEPTH`], newest only):
//!
//! 1. **Hand centre at the frame's capture time.** The camera arm publishes where the
//!    camera's optical frame is ([`topics::CAMERA_POSE`], UR5 base frame, stamped with
//!    the joint measurement's time) and the wrist tracker where the operator's hand
//!    frame is ([`topics::WRIST_POSE`], same base frame, stamped with the motion-capture
//!    time). Both are kept in short buffers ([`PoseBuffer`]) and interpolated to the
//!    frame's stamp ([`interpolate_pose`]: lerp + slerp, a small extrapolation
//!    allowed); the centre is `camera^-1 * wrist * HAND_CENTRE_IN_HAND_FRAME`
//!    ([`tracked_centre`]). Without usable poses, and if configured, the centre comes
//!    from the image instead ([`image_centre`]: closest-object segmentation).
//! 2. **Estimate** with [`HandEstimator::estimate`] (the one preprocessing, the model,
//!    the output checks).
//! 3. **Publish** [`topics::HAND_JOINT_TARGETS`] only for a hand: names
//!    [`SHADOW_FINGER_JOINTS`], positions in rad, `header.stamp` = the depth frame's
//!    capture stamp (so the robot site measures frame-to-command latency). No hand in
//!    view, or any error, publishes nothing: the robot's hand holds.
//!
//! The node is [`Lifecycle::Active`] while hands are being estimated and
//! [`Lifecycle::Inactive`] once none has been for
//! [`HandInferenceConfig::no_hand_after_s`]; its counters say why (no hand, no centre,
//! refused images, model errors) and how long each stage took (p50/p99 in µs).
//!
//! The node is generic over the [`JointModel`], so tests run it with
//! [`DeterministicTestModel`](crate::DeterministicTestModel); [`run`] loads the ONNX
//! model.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Point3, Translation3};
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, BusError, Clock, Publisher};
use teleop_hand_model::scene::HAND_CENTRE_IN_HAND_FRAME;
use teleop_hardware::{Camera, CameraKind};
use teleop_hardware_bus::BusCamera;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_interfaces::{nodes, topics};
use teleop_msgs::{Header, Image, JointState, Lifecycle, Pose, PoseStamped, encodings};
use teleop_node::{
    FinalReport, LatencyHistogram, Node, NodeConfig, NodeErrors, SchedulingConfig, SourceLock,
};
use teleop_render::Intrinsics;

use crate::{HandEstimate, HandEstimator, InferenceError, JointModel, OnnxModel, OnnxOptions};

/// The committed model, relative to the repository root.
pub const DEFAULT_MODEL: &str = "local_site/models/hand/model.onnx";

/// Counter-name prefix of the node.
const PREFIX: &str = "hand_inference";

/// The depth camera's intrinsics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntrinsicsChoice {
    /// RealSense SR300 depth stream, 640 x 480 ([`Intrinsics::sr300`]).
    #[default]
    Sr300,
}

impl IntrinsicsChoice {
    /// The intrinsics.
    #[must_use]
    pub fn intrinsics(self) -> Intrinsics {
        match self {
            Self::Sr300 => Intrinsics::sr300(),
        }
    }
}

/// The image fallback's closest-object segmentation ([`image_centre`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImageCentreConfig {
    /// Depths below this are ignored (m).
    pub min_depth_m: f64,
    /// Depths beyond this are ignored (m).
    pub max_depth_m: f64,
    /// The nearest object's depth is this percentile of the valid depths (%), not
    /// their minimum, so isolated specks do not count.
    pub near_percentile: f64,
    /// The object is the pixels from its nearest depth to this much farther (m).
    pub band_m: f64,
    /// The back-projected centre is pushed this far along its viewing ray (m): the
    /// hand's centre lies inside the hand, behind the surface the camera sees.
    pub push_back_m: f64,
    /// Fewer valid pixels (or object pixels) than this: no object.
    pub min_pixels: u32,
}

impl Default for ImageCentreConfig {
    fn default() -> Self {
        Self {
            min_depth_m: 0.2,
            max_depth_m: 2.0,
            near_percentile: 0.5,
            band_m: 0.15,
            push_back_m: 0.02,
            min_pixels: 100,
        }
    }
}

impl ImageCentreConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// A text naming the offending field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.min_depth_m.is_finite() && self.min_depth_m > 0.0) {
            return Err(format!("min_depth_m must be > 0, got {}", self.min_depth_m));
        }
        if !(self.max_depth_m.is_finite()
            && self.max_depth_m > self.min_depth_m
            && self.max_depth_m <= 65.0)
        {
            return Err(format!(
                "max_depth_m must be in (min_depth_m, 65], got {}",
                self.max_depth_m
            ));
        }
        if !(self.near_percentile.is_finite() && (0.0..=50.0).contains(&self.near_percentile)) {
            return Err(format!(
                "near_percentile must be in [0, 50], got {}",
                self.near_percentile
            ));
        }
        if !(self.band_m.is_finite() && self.band_m > 0.0 && self.band_m <= 1.0) {
            return Err(format!("band_m must be in (0, 1], got {}", self.band_m));
        }
        if !(self.push_back_m.is_finite() && (0.0..=0.2).contains(&self.push_back_m)) {
            return Err(format!(
                "push_back_m must be in [0, 0.2], got {}",
                self.push_back_m
            ));
        }
        if self.min_pixels == 0 {
            return Err("min_pixels must be at least 1".into());
        }
        Ok(())
    }
}

/// Configuration of the `hand_inference` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandInferenceConfig {
    /// The node's name on the bus.
    pub node_name: String,
    /// Tick rate (Hz) of the checks for missing frames. Frames do not wait for a tick:
    /// each arriving frame wakes the node, which processes it at once (polling at
    /// 200 Hz, a frame waited up to 5 ms for its turn). Default 50.
    pub rate_hz: f64,
    /// The ONNX model. A relative path is looked for in the current directory, then
    /// in the repository root.
    pub model: PathBuf,
    /// `libonnxruntime.so` to use; unset: searched for (see [`crate::runtime`]).
    pub onnxruntime_library: Option<PathBuf>,
    /// ONNX Runtime intra-op threads.
    pub threads: usize,
    /// The depth camera's intrinsics; frames of another size are refused.
    pub intrinsics: IntrinsicsChoice,
    /// How far past the newest (or before the oldest) pose sample a pose may be
    /// extrapolated to a frame's stamp (s); beyond it there is no tracked centre.
    pub max_pose_extrapolation_s: f64,
    /// Two samples farther apart than this are not interpolated between (s).
    pub max_pose_gap_s: f64,
    /// How much pose history is kept (s).
    pub pose_buffer_s: f64,
    /// The camera and wrist poses are each taken from one publisher (the operator
    /// site's camera arm and wrist tracker, as the robot site's controllers take
    /// theirs): another publisher's poses are refused, counted
    /// (`<topic>.rejected_foreign`) and reported as a conflict, never mixed into the
    /// crop centre. A source silent this long may be replaced by the next one heard
    /// (s).
    pub pose_source_release_after_s: f64,
    /// The node turns inactive when no hand has been estimated for this long (s).
    pub no_hand_after_s: f64,
    /// When the poses stop for a moment (the motion capture loses the markers for a
    /// few hundred ms), the newest tracked centre, in the camera's frame, is used for
    /// frames up to this long after it (s; 0: never). The camera arm keeps the hand
    /// where it was in the camera's view, so this stays within millimetres where
    /// the image fallback's centroid is centimetres off, and the network's estimate
    /// with it (an open hand read from a closed one flung a held can away).
    pub hold_tracked_centre_s: f64,
    /// Without a tracked centre, find the hand as the closest object in the image.
    pub image_fallback: bool,
    /// The image fallback's segmentation.
    pub image_centre: ImageCentreConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    /// The node's bus settings.
    pub bus: BusConfig,
}

impl Default for HandInferenceConfig {
    fn default() -> Self {
        Self {
            node_name: nodes::HAND_INFERENCE.into(),
            rate_hz: 50.0,
            model: PathBuf::from(DEFAULT_MODEL),
            onnxruntime_library: None,
            threads: 1,
            intrinsics: IntrinsicsChoice::Sr300,
            max_pose_extrapolation_s: 0.05,
            max_pose_gap_s: 0.2,
            pose_source_release_after_s: 1.0,
            pose_buffer_s: 1.0,
            no_hand_after_s: 0.5,
            hold_tracked_centre_s: 0.5,
            image_fallback: true,
            image_centre: ImageCentreConfig::default(),
            // On the depth frame's path to the hand (docs/local-site.md).
            scheduling: SchedulingConfig::realtime(teleop_node::sched::LATENCY_PATH_PRIORITY),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for HandInferenceConfig {
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
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= 1000.0) {
            return Err(format!(
                "rate_hz must be in (0, 1000], got {}",
                self.rate_hz
            ));
        }
        if self.model.as_os_str().is_empty() {
            return Err("model must name the .onnx file".into());
        }
        if self
            .onnxruntime_library
            .as_ref()
            .is_some_and(|p| p.as_os_str().is_empty())
        {
            return Err("onnxruntime_library must not be empty (leave it out to search)".into());
        }
        if !(1..=64).contains(&self.threads) {
            return Err(format!("threads must be in [1, 64], got {}", self.threads));
        }
        if !(self.max_pose_extrapolation_s.is_finite()
            && (0.0..=0.5).contains(&self.max_pose_extrapolation_s))
        {
            return Err(format!(
                "max_pose_extrapolation_s must be in [0, 0.5], got {}",
                self.max_pose_extrapolation_s
            ));
        }
        if !(self.hold_tracked_centre_s.is_finite()
            && (0.0..=2.0).contains(&self.hold_tracked_centre_s))
        {
            return Err(format!(
                "hold_tracked_centre_s must be in [0, 2], got {}",
                self.hold_tracked_centre_s
            ));
        }
        if !(self.max_pose_gap_s.is_finite()
            && self.max_pose_gap_s > 0.0
            && self.max_pose_gap_s <= 2.0)
        {
            return Err(format!(
                "max_pose_gap_s must be in (0, 2], got {}",
                self.max_pose_gap_s
            ));
        }
        if !(self.pose_buffer_s.is_finite()
            && self.pose_buffer_s >= self.max_pose_gap_s
            && self.pose_buffer_s <= 10.0)
        {
            return Err(format!(
                "pose_buffer_s must be in [max_pose_gap_s, 10], got {}",
                self.pose_buffer_s
            ));
        }
        if !(self.pose_source_release_after_s.is_finite()
            && self.pose_source_release_after_s >= 0.05
            && self.pose_source_release_after_s <= 60.0)
        {
            return Err(format!(
                "pose_source_release_after_s must be in [0.05, 60], got {}",
                self.pose_source_release_after_s
            ));
        }
        if !(self.no_hand_after_s.is_finite()
            && self.no_hand_after_s > 0.0
            && self.no_hand_after_s <= 60.0)
        {
            return Err(format!(
                "no_hand_after_s must be in (0, 60], got {}",
                self.no_hand_after_s
            ));
        }
        self.image_centre
            .validate()
            .map_err(|e| format!("image_centre.{e}"))
    }
}

/// Errors of building the node.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NodeError {
    #[error("invalid configuration: {0}")]
    Config(String),
    #[error(
        "hand model {path} not found (looked at: {}); set `model` in the node's config to the .onnx file (the committed one is local_site/models/hand/model.onnx in the repository)",
        looked.join("; ")
    )]
    ModelNotFound { path: String, looked: Vec<String> },
    #[error(transparent)]
    Inference(#[from] InferenceError),
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// The repository root, as this crate was built from it.
fn repo_root() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    std::fs::canonicalize(&root).unwrap_or(root)
}

/// The model file `path` names: an absolute path as is; a relative one in the
/// current directory, else in the repository root.
///
/// # Errors
/// [`NodeError::ModelNotFound`] naming the path and every place looked at.
pub fn resolve_model_path(path: &Path) -> Result<PathBuf, NodeError> {
    let candidates = if path.is_absolute() {
        vec![path.to_path_buf()]
    } else {
        let mut c = Vec::new();
        if let Ok(cwd) = std::env::current_dir() {
            c.push(cwd.join(path));
        }
        c.push(repo_root().join(path));
        c
    };
    if let Some(found) = candidates.iter().find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    Err(NodeError::ModelNotFound {
        path: path.display().to_string(),
        looked: candidates.iter().map(|p| p.display().to_string()).collect(),
    })
}

/// The offline evaluation `hand_eval` writes beside a model (`report.json`): which
/// model each row is of (`--model NAME=PATH` in its command) and its mean error.
#[derive(Debug, Deserialize)]
struct OfflineEvaluation {
    command: String,
    rows: Vec<OfflineRow>,
}

#[derive(Debug, Deserialize)]
struct OfflineRow {
    model: String,
    dataset: String,
    mean_error_rad: f64,
}

/// The model's mean joint error on its offline test set, from the `report.json`
/// `hand_eval` wrote beside it (the row of dataset `test` for the `--model NAME=PATH`
/// whose file is this model's): what the closed loop's hand joint error is judged
/// against. `Ok(None)` when there is no such file or row (a model evaluated nowhere).
///
/// # Errors
/// The file exists but cannot be read or parsed (named), or its error is not a
/// positive finite number.
pub fn offline_test_error(model: &Path) -> Result<Option<f64>, String> {
    let path = model.with_file_name("report.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{}: {e}", path.display())),
    };
    let eval: OfflineEvaluation =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let file = model.file_name();
    let mut words = eval.command.split_whitespace();
    let mut name = None;
    while let Some(w) = words.next() {
        if w == "--model"
            && let Some((n, p)) = words.next().and_then(|v| v.split_once('='))
            && Path::new(p).file_name() == file
        {
            name = Some(n.to_owned());
            break;
        }
    }
    let Some(name) = name else {
        return Ok(None);
    };
    match eval
        .rows
        .iter()
        .find(|r| r.model == name && r.dataset == "test")
    {
        Some(r) if r.mean_error_rad.is_finite() && r.mean_error_rad > 0.0 => {
            Ok(Some(r.mean_error_rad))
        }
        Some(r) => Err(format!(
            "{}: test error of {name} is {} (not a positive number)",
            path.display(),
            r.mean_error_rad
        )),
        None => Ok(None),
    }
}

/// Loads the configured ONNX model into an estimator.
///
/// # Errors
/// [`NodeError::ModelNotFound`], or the [`InferenceError`] of loading ONNX Runtime
/// or the model (each says what to do).
pub fn load_estimator(cfg: &HandInferenceConfig) -> Result<HandEstimator<OnnxModel>, NodeError> {
    let path = resolve_model_path(&cfg.model)?;
    let model = OnnxModel::load(
        &path,
        &OnnxOptions {
            library: cfg.onnxruntime_library.clone(),
            threads: Some(cfg.threads),
        },
    )?;
    tracing::info!(model = %model.path().display(), kind = model.kind(),
        library = %model.library().display(), "hand model loaded");
    Ok(HandEstimator::new(model)?)
}

// ------------------------------------------------------------------ poses

/// A pose and the time it was measured at (s since the Unix epoch).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    /// Measurement time (s since the Unix epoch).
    pub time_s: f64,
    /// The pose.
    pub pose: Isometry3<f64>,
}

/// A pose message as an isometry; `None` if a component is not finite or the
/// quaternion's norm is more than 1 % off unit (it is normalised otherwise):
/// [`teleop_hardware::wire::checked_isometry`] at
/// [`teleop_hardware::wire::POSE_QUATERNION_TOLERANCE`].
#[must_use]
pub fn pose_from_msg(pose: &Pose) -> Option<Isometry3<f64>> {
    teleop_hardware::wire::checked_isometry(pose, teleop_hardware::wire::POSE_QUATERNION_TOLERANCE)
        .ok()
}

/// `a` moved towards `b` by the fraction `s` (extrapolating for `s` outside [0, 1]):
/// translation linearly, rotation along the shortest arc.
fn blend(a: &Isometry3<f64>, b: &Isometry3<f64>, s: f64) -> Isometry3<f64> {
    let ta = a.translation.vector;
    let tb = b.translation.vector;
    let delta = a.rotation.inverse() * b.rotation;
    Isometry3::from_parts(
        Translation3::from(ta + (tb - ta) * s),
        a.rotation * delta.powf(s),
    )
}

/// The pose at time `t` from samples sorted by time:
///
/// * between two samples at most `max_gap_s` apart: interpolated (lerp of the
///   translation, slerp of the rotation);
/// * between two samples farther apart: the nearer one if within
///   `max_extrapolation_s` of `t`, else `None`;
/// * before the first or after the last sample by at most `max_extrapolation_s`:
///   extrapolated along the two end samples (held, if there is only one);
/// * otherwise (no samples, `t` too far outside, `t` not finite): `None`.
#[must_use]
pub fn interpolate_pose(
    samples: &[StampedPose],
    t: f64,
    max_extrapolation_s: f64,
    max_gap_s: f64,
) -> Option<Isometry3<f64>> {
    if !t.is_finite() {
        return None;
    }
    let (first, last) = (samples.first()?, samples.last()?);
    let n = samples.len();
    let extrapolate = |a: &StampedPose, b: &StampedPose| {
        let dt = b.time_s - a.time_s;
        if dt > 0.0 {
            blend(&a.pose, &b.pose, (t - a.time_s) / dt)
        } else {
            b.pose
        }
    };
    if t < first.time_s {
        if first.time_s - t > max_extrapolation_s {
            return None;
        }
        return Some(if n >= 2 {
            extrapolate(first, &samples[1])
        } else {
            first.pose
        });
    }
    if t >= last.time_s {
        if t - last.time_s > max_extrapolation_s {
            return None;
        }
        return Some(if n >= 2 && t > last.time_s {
            extrapolate(&samples[n - 2], last)
        } else {
            last.pose
        });
    }
    // first <= t < last: samples[i - 1] <= t < samples[i].
    let i = samples.partition_point(|s| s.time_s <= t);
    let (a, b) = (&samples[i - 1], &samples[i]);
    let dt = b.time_s - a.time_s;
    if dt > max_gap_s {
        return if t - a.time_s <= max_extrapolation_s.min(b.time_s - t) {
            Some(a.pose)
        } else if b.time_s - t <= max_extrapolation_s {
            Some(b.pose)
        } else {
            None
        };
    }
    Some(blend(&a.pose, &b.pose, (t - a.time_s) / dt))
}

/// A short, time-ordered history of a pose stream.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseBuffer {
    samples: Vec<StampedPose>,
    span_s: f64,
}

impl PoseBuffer {
    /// Keeps the samples of the last `span_s` seconds (before the newest one).
    #[must_use]
    pub fn new(span_s: f64) -> Self {
        Self {
            samples: Vec::new(),
            span_s,
        }
    }

    /// Adds a sample in time order (a late one is inserted where it belongs, one with
    /// the same stamp as a kept sample replaces it); `false` if its time is not finite
    /// or older than the history kept.
    pub fn push(&mut self, sample: StampedPose) -> bool {
        let t = sample.time_s;
        if !t.is_finite() {
            return false;
        }
        if let Some(newest) = self.samples.last()
            && t < newest.time_s - self.span_s
        {
            return false;
        }
        let i = self.samples.partition_point(|s| s.time_s < t);
        match self.samples.get_mut(i) {
            Some(s) if s.time_s == t => *s = sample,
            _ => self.samples.insert(i, sample),
        }
        let newest = self.samples.last().map_or(t, |s| s.time_s);
        let keep_from = self
            .samples
            .partition_point(|s| s.time_s < newest - self.span_s);
        self.samples.drain(..keep_from);
        true
    }

    /// The samples, oldest first.
    #[must_use]
    pub fn samples(&self) -> &[StampedPose] {
        &self.samples
    }

    /// The pose at `t` ([`interpolate_pose`]).
    #[must_use]
    pub fn at(&self, t: f64, max_extrapolation_s: f64, max_gap_s: f64) -> Option<Isometry3<f64>> {
        interpolate_pose(&self.samples, t, max_extrapolation_s, max_gap_s)
    }
}

/// The hand centre in the camera's optical frame from the camera's and the hand
/// frame's poses in one base frame: `camera^-1 * hand * HAND_CENTRE_IN_HAND_FRAME`.
#[must_use]
pub fn tracked_centre(
    camera_in_base: &Isometry3<f64>,
    hand_in_base: &Isometry3<f64>,
) -> Point3<f64> {
    let centre_in_base = hand_in_base * Point3::from(HAND_CENTRE_IN_HAND_FRAME);
    camera_in_base.inverse_transform_point(&centre_in_base)
}

// ------------------------------------------------------------ image centre

/// The `rank`-th smallest value (0-based) of a histogram of integer depths starting
/// at `offset`.
fn rank_in(hist: &[u32], offset: usize, rank: u64) -> usize {
    let mut seen = 0u64;
    for (i, c) in hist.iter().enumerate() {
        seen += u64::from(*c);
        if seen > rank {
            return offset + i;
        }
    }
    offset + hist.len().saturating_sub(1)
}

/// The hand centre estimated from the depth image alone (camera optical frame, m),
/// as the closest object: `d0` = the `near_percentile` of the depths within
/// `min_depth_m..=max_depth_m` (zeros are no return), the object = the pixels within
/// `d0..=d0 + band_m`; its pixel centroid back-projected at its median depth, pushed
/// `push_back_m` farther along the viewing ray. `None` when the image does not match
/// the intrinsics or holds fewer than `min_pixels` valid or object pixels.
#[must_use]
pub fn image_centre(
    depth_mm: &[u16],
    intrinsics: &Intrinsics,
    cfg: &ImageCentreConfig,
) -> Option<Point3<f64>> {
    let (w, h) = (intrinsics.width() as usize, intrinsics.height() as usize);
    if depth_mm.len() != w * h || w == 0 {
        return None;
    }
    // Depth bounds in whole mm (config values are validated, well inside u16).
    let lo = (cfg.min_depth_m * 1000.0).ceil().max(1.0) as usize;
    let hi = ((cfg.max_depth_m * 1000.0).floor() as usize).min(usize::from(u16::MAX));
    if hi < lo {
        return None;
    }
    let mut hist = vec![0u32; hi - lo + 1];
    let mut valid = 0u64;
    for &d in depth_mm {
        let d = usize::from(d);
        if (lo..=hi).contains(&d) {
            hist[d - lo] += 1;
            valid += 1;
        }
    }
    if valid < u64::from(cfg.min_pixels) {
        return None;
    }
    let rank = ((cfg.near_percentile / 100.0) * (valid - 1) as f64).floor() as u64;
    let d0 = rank_in(&hist, lo, rank);
    let d1 = (d0 + (cfg.band_m * 1000.0).round() as usize).min(hi);
    let mut band = vec![0u32; d1 - d0 + 1];
    let (mut su, mut sv, mut count) = (0.0f64, 0.0f64, 0u64);
    for (v, row) in depth_mm.chunks_exact(w).enumerate() {
        for (u, &d) in row.iter().enumerate() {
            let d = usize::from(d);
            if (d0..=d1).contains(&d) {
                band[d - d0] += 1;
                su += u as f64;
                sv += v as f64;
                count += 1;
            }
        }
    }
    if count < u64::from(cfg.min_pixels) {
        return None;
    }
    let median_mm = rank_in(&band, d0, (count - 1) / 2);
    let (u, v) = (su / count as f64, sv / count as f64);
    let surface = intrinsics.ray_through(u, v) * (median_mm as f64 / 1000.0);
    let pushed = surface + surface.normalize() * cfg.push_back_m;
    Some(Point3::from(pushed))
}

// ------------------------------------------------------------------ frames

/// Why a depth image was refused before estimation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FrameError {
    #[error("depth image encoding `{0}`, expected 16UC1 (mm)")]
    Encoding(String),
    #[error(
        "depth image is {width} x {height}, the camera's intrinsics are {expected_width} x {expected_height}"
    )]
    Size {
        width: u32,
        height: u32,
        expected_width: u32,
        expected_height: u32,
    },
    #[error("depth image layout: {0}")]
    Layout(String),
}

/// Decodes a `16UC1` image of the intrinsics' size into `out` (row-major mm).
///
/// # Errors
/// [`FrameError`] for another encoding, another size, or an inconsistent layout.
pub fn depth_from_image(
    image: &Image,
    intrinsics: &Intrinsics,
    out: &mut Vec<u16>,
) -> Result<(), FrameError> {
    if image.encoding != encodings::DEPTH_16UC1 {
        return Err(FrameError::Encoding(image.encoding.clone()));
    }
    if image.width != intrinsics.width() || image.height != intrinsics.height() {
        return Err(FrameError::Size {
            width: image.width,
            height: image.height,
            expected_width: intrinsics.width(),
            expected_height: intrinsics.height(),
        });
    }
    image.check_layout().map_err(FrameError::Layout)?;
    let (w, step) = (image.width as usize, image.step as usize);
    out.clear();
    out.reserve(w * image.height as usize);
    for row in image.data.chunks_exact(step) {
        out.extend(row[..2 * w].chunks_exact(2).map(|b| {
            if image.is_bigendian == 0 {
                u16::from_le_bytes([b[0], b[1]])
            } else {
                u16::from_be_bytes([b[0], b[1]])
            }
        }));
    }
    Ok(())
}

/// Where a frame's hand centre came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CentreSource {
    /// The camera and wrist poses at the frame's stamp.
    Tracked,
    /// The newest tracked centre, held through a short gap in the poses
    /// (`hold_tracked_centre_s`).
    Held,
    /// The closest object in the image.
    Image,
}

/// What became of one depth frame.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameOutcome {
    /// Targets published.
    Published {
        /// The joints (rad, [`SHADOW_FINGER_JOINTS`] order).
        joints: [f64; SHADOW_FINGER_JOINTS.len()],
        /// The hand centre used (camera frame, m).
        centre_m: Point3<f64>,
        /// Where it came from.
        source: CentreSource,
    },
    /// No hand in the crop: nothing published.
    NoHand {
        /// Fraction of the crop that held anything.
        foreground: f64,
        /// Where the centre came from.
        source: CentreSource,
    },
    /// No hand centre (no usable poses, no image fallback or no object).
    NoCentre,
    /// The image was refused (encoding, size, layout).
    Refused(String),
    /// Estimation failed (input, model, non-finite output) or publishing did.
    Failed(String),
}

/// The node's counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InferenceCounters {
    /// Depth frames taken (accepted by the camera handle).
    pub frames: u64,
    /// Targets published.
    pub published: u64,
    /// Frames without a hand in the crop.
    pub no_hand: u64,
    /// Frames whose centre came from the camera and wrist poses.
    pub centre_tracked: u64,
    /// Frames whose centre was the newest tracked one, held through a gap in the
    /// poses.
    pub centre_held: u64,
    /// Frames whose centre came from the image.
    pub centre_image: u64,
    /// Frames without a hand centre.
    pub no_centre: u64,
    /// Depth images not `16UC1`.
    pub rejected_encoding: u64,
    /// Depth images of another size than the intrinsics'.
    pub rejected_image_size: u64,
    /// Depth images whose layout is inconsistent.
    pub rejected_image_layout: u64,
    /// Pose messages with non-finite values or a non-unit quaternion.
    pub rejected_pose: u64,
    /// Estimator input errors (centre not in front of the camera, bad sizes).
    pub errors_input: u64,
    /// Model failures.
    pub errors_model: u64,
    /// Model outputs refused as not finite.
    pub errors_non_finite: u64,
    /// Joints clamped into the Shadow's limits.
    pub clamped_joints: u64,
    /// Targets that could not be published.
    pub publish_errors: u64,
}

impl InferenceCounters {
    /// The counters by name, as in the node status (`hand_inference.<name>`).
    #[must_use]
    pub fn named(&self) -> Vec<(String, u64)> {
        [
            ("frames", self.frames),
            ("published", self.published),
            ("no_hand", self.no_hand),
            ("centre_tracked", self.centre_tracked),
            ("centre_held", self.centre_held),
            ("centre_image", self.centre_image),
            ("no_centre", self.no_centre),
            ("rejected_encoding", self.rejected_encoding),
            ("rejected_image_size", self.rejected_image_size),
            ("rejected_image_layout", self.rejected_image_layout),
            ("rejected_pose", self.rejected_pose),
            ("errors.input", self.errors_input),
            ("errors.model", self.errors_model),
            ("errors.non_finite", self.errors_non_finite),
            ("clamped_joints", self.clamped_joints),
            ("publish_errors", self.publish_errors),
        ]
        .into_iter()
        .map(|(n, v)| (format!("{PREFIX}.{n}"), v))
        .collect()
    }
}

/// The `hand_inference` node over a [`JointModel`].
#[derive(Debug)]
pub struct HandInferenceNode<M: JointModel> {
    period: Duration,
    intrinsics: Intrinsics,
    max_pose_extrapolation_s: f64,
    max_pose_gap_s: f64,
    no_hand_after_s: f64,
    hold_tracked_centre_s: f64,
    /// The newest tracked centre (camera frame) and its frame's stamp.
    last_tracked: Option<(f64, Point3<f64>)>,
    image_fallback: bool,
    image_centre: ImageCentreConfig,
    estimator: HandEstimator<M>,
    camera: BusCamera,
    camera_pose_sub: SourceLock<PoseStamped>,
    wrist_pose_sub: SourceLock<PoseStamped>,
    targets: Publisher<JointState>,
    clock: Arc<dyn Clock>,
    camera_poses: PoseBuffer,
    wrist_poses: PoseBuffer,
    depth: Vec<u16>,
    counters: InferenceCounters,
    capture_to_received: LatencyHistogram,
    processing: LatencyHistogram,
    capture_to_published: LatencyHistogram,
    sent_to_published: LatencyHistogram,
    /// Woken by each arriving depth frame: the frame is processed at once.
    wake: Arc<tokio::sync::Notify>,
    started_s: Option<f64>,
    /// The model's offline test error (rad), from its evaluation, if known.
    offline_test_error_rad: Option<f64>,
    last_tick_s: Option<f64>,
    last_frame_s: Option<f64>,
    last_hand_s: Option<f64>,
    last_outcome: Option<FrameOutcome>,
    errors: NodeErrors,
}

impl<M: JointModel> HandInferenceNode<M> {
    /// Declares the node's subscriptions and publisher on `bus`, around `estimator`.
    ///
    /// # Errors
    /// [`NodeError::Config`] for a configuration that does not validate,
    /// [`NodeError::Bus`] for the declarations.
    pub async fn with_model(
        cfg: &HandInferenceConfig,
        bus: &Bus,
        estimator: HandEstimator<M>,
    ) -> Result<Self, NodeError> {
        cfg.validate().map_err(NodeError::Config)?;
        let intrinsics = cfg.intrinsics.intrinsics();
        tracing::info!(
            rate_hz = cfg.rate_hz,
            image_fallback = cfg.image_fallback,
            width = intrinsics.width(),
            height = intrinsics.height(),
            "hand inference: waiting for depth frames"
        );
        let camera = BusCamera::monitor(bus, &topics::HW_HAND_DEPTH, CameraKind::Depth).await?;
        let wake = Arc::new(tokio::sync::Notify::new());
        camera.wake_on_frame(Some(Arc::clone(&wake)));
        Ok(Self {
            period: Duration::from_secs_f64(1.0 / cfg.rate_hz),
            intrinsics,
            max_pose_extrapolation_s: cfg.max_pose_extrapolation_s,
            max_pose_gap_s: cfg.max_pose_gap_s,
            no_hand_after_s: cfg.no_hand_after_s,
            hold_tracked_centre_s: cfg.hold_tracked_centre_s,
            last_tracked: None,
            image_fallback: cfg.image_fallback,
            image_centre: cfg.image_centre,
            estimator,
            camera,
            camera_pose_sub: SourceLock::new(
                bus.subscriber(&topics::CAMERA_POSE).await?,
                cfg.pose_source_release_after_s,
            ),
            wrist_pose_sub: SourceLock::new(
                bus.subscriber(&topics::WRIST_POSE).await?,
                cfg.pose_source_release_after_s,
            ),
            targets: bus.publisher(&topics::HAND_JOINT_TARGETS).await?,
            clock: Arc::clone(bus.clock()),
            camera_poses: PoseBuffer::new(cfg.pose_buffer_s),
            wrist_poses: PoseBuffer::new(cfg.pose_buffer_s),
            depth: Vec::new(),
            counters: InferenceCounters::default(),
            capture_to_received: LatencyHistogram::new("capture_to_received"),
            processing: LatencyHistogram::new("processing"),
            capture_to_published: LatencyHistogram::new("capture_to_published"),
            sent_to_published: LatencyHistogram::new("sent_to_published"),
            wake,
            started_s: None,
            offline_test_error_rad: None,
            last_tick_s: None,
            last_frame_s: None,
            last_hand_s: None,
            last_outcome: None,
            errors: NodeErrors::new(),
        })
    }

    /// Says the model's offline test error (rad) in the status, as
    /// `hand_inference.model.offline_test_error_urad`, for the end-of-run report's hand
    /// joint goal.
    #[must_use]
    pub fn with_offline_test_error(mut self, error_rad: Option<f64>) -> Self {
        self.offline_test_error_rad = error_rad;
        self
    }

    /// What became of the last depth frame.
    #[must_use]
    pub fn last_outcome(&self) -> Option<&FrameOutcome> {
        self.last_outcome.as_ref()
    }

    /// The camera-pose history.
    #[must_use]
    pub fn camera_poses(&self) -> &PoseBuffer {
        &self.camera_poses
    }

    /// The wrist-pose history.
    #[must_use]
    pub fn wrist_poses(&self) -> &PoseBuffer {
        &self.wrist_poses
    }

    fn take_poses(&mut self, now_s: f64) {
        for (lock, buffer) in [
            (&mut self.camera_pose_sub, &mut self.camera_poses),
            (&mut self.wrist_pose_sub, &mut self.wrist_poses),
        ] {
            lock.release_if_silent(now_s);
            for r in lock.drain() {
                match pose_from_msg(&r.msg.pose) {
                    Some(pose) => {
                        buffer.push(StampedPose {
                            time_s: r.msg.header.stamp.as_secs_f64(),
                            pose,
                        });
                    }
                    None => self.counters.rejected_pose += 1,
                }
            }
        }
    }

    /// The hand centre for a frame stamped `t`, and where it came from.
    fn centre(&mut self, t: f64) -> Option<(Point3<f64>, CentreSource)> {
        let (ext, gap) = (self.max_pose_extrapolation_s, self.max_pose_gap_s);
        if let (Some(camera), Some(wrist)) = (
            self.camera_poses.at(t, ext, gap),
            self.wrist_poses.at(t, ext, gap),
        ) {
            let centre = tracked_centre(&camera, &wrist);
            self.last_tracked = Some((t, centre));
            return Some((centre, CentreSource::Tracked));
        }
        if let Some((at, centre)) = self.last_tracked
            && (t - at).abs() <= self.hold_tracked_centre_s
        {
            return Some((centre, CentreSource::Held));
        }
        if !self.image_fallback {
            return None;
        }
        image_centre(&self.depth, &self.intrinsics, &self.image_centre)
            .map(|c| (c, CentreSource::Image))
    }

    /// One depth frame taken at node time `now_s`.
    fn process(&mut self, image: &Image, now_s: f64) -> FrameOutcome {
        let stamp_s = image.header.stamp.as_secs_f64();
        self.counters.frames += 1;
        self.capture_to_received
            .record_s(self.clock.now_s() - stamp_s);
        if let Err(e) = depth_from_image(image, &self.intrinsics, &mut self.depth) {
            match e {
                FrameError::Encoding(_) => self.counters.rejected_encoding += 1,
                FrameError::Size { .. } => self.counters.rejected_image_size += 1,
                FrameError::Layout(_) => self.counters.rejected_image_layout += 1,
            }
            return FrameOutcome::Refused(e.to_string());
        }
        let Some((centre, source)) = self.centre(stamp_s) else {
            self.counters.no_centre += 1;
            return FrameOutcome::NoCentre;
        };
        match source {
            CentreSource::Tracked => self.counters.centre_tracked += 1,
            CentreSource::Held => self.counters.centre_held += 1,
            CentreSource::Image => self.counters.centre_image += 1,
        }
        let started = Instant::now();
        let estimate = self
            .estimator
            .estimate(&self.depth, &self.intrinsics, &centre);
        self.processing.record_s(started.elapsed().as_secs_f64());
        match estimate {
            Ok(HandEstimate::Hand {
                joints, clamped, ..
            }) => {
                self.counters.clamped_joints += u64::from(clamped);
                let msg = JointState::positions(
                    Header {
                        stamp: image.header.stamp,
                        frame_id: String::new(),
                    },
                    &SHADOW_FINGER_JOINTS,
                    &joints,
                );
                if let Err(e) = self.targets.put(&msg) {
                    self.counters.publish_errors += 1;
                    return FrameOutcome::Failed(format!("publishing the targets: {e}"));
                }
                let now = self.clock.now_s();
                self.capture_to_published.record_s(now - stamp_s);
                if let Some(sent_ns) = self.camera.last_sent_ns() {
                    self.sent_to_published.record_s(now - sent_ns as f64 * 1e-9);
                }
                self.counters.published += 1;
                self.last_hand_s = Some(now_s);
                FrameOutcome::Published {
                    joints,
                    centre_m: centre,
                    source,
                }
            }
            Ok(HandEstimate::NoHand { foreground }) => {
                self.counters.no_hand += 1;
                FrameOutcome::NoHand { foreground, source }
            }
            Err(e) => {
                match e {
                    InferenceError::Input(_) => self.counters.errors_input += 1,
                    InferenceError::NonFinite { .. } => self.counters.errors_non_finite += 1,
                    _ => self.counters.errors_model += 1,
                }
                FrameOutcome::Failed(e.to_string())
            }
        }
    }
}

impl<M: JointModel> Node for HandInferenceNode<M> {
    fn period(&self) -> Duration {
        self.period
    }

    fn tick(&mut self, now_s: f64) {
        self.last_tick_s = Some(now_s);
        self.errors.step(now_s);
        let started = *self.started_s.get_or_insert(now_s);
        self.take_poses(now_s);
        if let Some(conflict) = teleop_node::source::conflict(
            now_s,
            &mut [&mut self.camera_pose_sub, &mut self.wrist_pose_sub],
        ) {
            self.errors.event("pose source", conflict, now_s);
        }
        let outcome = match self.camera.read(now_s) {
            Ok(Some(image)) => Some(self.process(&image, now_s)),
            Ok(None) => None,
            Err(e) => Some(FrameOutcome::Refused(e.to_string())),
        };
        if let Some(outcome) = outcome {
            self.last_frame_s = Some(now_s);
            self.errors.resolved("depth camera", now_s);
            match &outcome {
                FrameOutcome::Published { .. } => self.errors.resolved("hand", now_s),
                FrameOutcome::NoHand { foreground, .. } => {
                    let text = format!("no hand in view (foreground {foreground:.2})");
                    self.errors.condition("hand", text, now_s);
                }
                FrameOutcome::NoCentre => {
                    let text = if self.image_fallback {
                        "no hand centre: no camera and wrist poses at the frame's time, and no object in the image"
                    } else {
                        "no hand centre: no camera and wrist poses at the frame's time (image_fallback is off)"
                    };
                    self.errors.condition("hand", text, now_s);
                }
                FrameOutcome::Refused(e) | FrameOutcome::Failed(e) => {
                    tracing::debug!("depth frame: {e}");
                    self.errors.event("depth frame", e.clone(), now_s);
                }
            }
            self.last_outcome = Some(outcome);
        } else if now_s - self.last_frame_s.unwrap_or(started) > self.no_hand_after_s {
            let text = format!(
                "no depth frame on {} for {:.1} s",
                topics::HW_HAND_DEPTH.spec.name,
                now_s - self.last_frame_s.unwrap_or(started)
            );
            self.errors.condition("depth camera", text, now_s);
        }
    }

    fn state(&self) -> Lifecycle {
        match (self.last_hand_s, self.last_tick_s) {
            (Some(hand), Some(now)) if now - hand <= self.no_hand_after_s => Lifecycle::Active,
            _ => Lifecycle::Inactive,
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let mut out = self.counters.named();
        out.push((format!("{PREFIX}.rejected_image"), self.camera.bad_images()));
        out.push((format!("{PREFIX}.frames_skipped"), self.camera.dropped()));
        let s = self.estimator.stats();
        out.push((format!("{PREFIX}.estimator.frames"), s.frames));
        out.push((format!("{PREFIX}.estimator.hands"), s.hands));
        if let Some(e) = self.offline_test_error_rad {
            // µrad: a few hundred thousand at most.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            out.push((
                format!("{PREFIX}.model.offline_test_error_urad"),
                (e * 1e6).round() as u64,
            ));
        }
        self.capture_to_received.named(&mut out);
        self.processing.named(&mut out);
        self.capture_to_published.named(&mut out);
        self.sent_to_published.named(&mut out);
        out.extend(self.camera_pose_sub.named_counters());
        out.extend(self.wrist_pose_sub.named_counters());
        out
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    fn wake(&self) -> Option<Arc<tokio::sync::Notify>> {
        Some(Arc::clone(&self.wake))
    }
}

/// Loads the model, then runs the node on the system clock until `duration` elapses
/// (forever if `None`) or SIGINT/SIGTERM.
///
/// # Errors
/// The model or ONNX Runtime cannot be loaded (the message says what to do), bus or
/// configuration errors.
pub async fn run(
    cfg: HandInferenceConfig,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    cfg.validate()
        .map_err(|e| anyhow::anyhow!("invalid configuration: {e}"))?;
    let estimator =
        load_estimator(&cfg).map_err(|e| anyhow::anyhow!("hand_inference cannot start: {e}"))?;
    let offline = match resolve_model_path(&cfg.model) {
        Ok(path) => offline_test_error(&path).unwrap_or_else(|e| {
            tracing::warn!("the model's offline evaluation cannot be read: {e}");
            None
        }),
        Err(_) => None,
    };
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = HandInferenceNode::with_model(&cfg, &bus, estimator)
        .await?
        .with_offline_test_error(offline);
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};
    use std::f64::consts::FRAC_PI_2;

    fn at(t: f64, pose: Isometry3<f64>) -> StampedPose {
        StampedPose { time_s: t, pose }
    }

    fn close(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
        (a.translation.vector - b.translation.vector).norm() < 1e-12
            && a.rotation.angle_to(&b.rotation) < 1e-9
    }

    #[test]
    fn poses_are_interpolated_extrapolated_a_little_and_refused_beyond() {
        let a = Isometry3::identity();
        let b = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2),
        );
        let s = [at(10.0, a), at(11.0, b)];
        let rot = |angle: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle);
        let mid = interpolate_pose(&s, 10.5, 0.05, 2.0).expect("inside");
        let want = Isometry3::from_parts(Translation3::new(0.5, 1.0, 1.5), rot(FRAC_PI_2 / 2.0));
        assert!(close(&mid, &want), "{mid:?}");
        assert!(close(
            &interpolate_pose(&s, 10.0, 0.05, 2.0).expect("a"),
            &a
        ));
        assert!(close(
            &interpolate_pose(&s, 11.0, 0.05, 2.0).expect("b"),
            &b
        ));
        // 20 ms past the newest: extrapolated along the last two samples.
        let ext = interpolate_pose(&s, 11.02, 0.05, 2.0).expect("extrapolated");
        let want =
            Isometry3::from_parts(Translation3::new(1.02, 2.04, 3.06), rot(FRAC_PI_2 * 1.02));
        assert!(close(&ext, &want), "{ext:?}");
        let before = interpolate_pose(&s, 9.99, 0.05, 2.0).expect("before");
        let want = Isometry3::from_parts(
            Translation3::new(-0.01, -0.02, -0.03),
            rot(-FRAC_PI_2 * 0.01),
        );
        assert!(close(&before, &want), "{before:?}");
        assert!(interpolate_pose(&s, 11.06, 0.05, 2.0).is_none());
        assert!(interpolate_pose(&s, 9.9, 0.05, 2.0).is_none());
        assert!(interpolate_pose(&s, f64::NAN, 0.05, 2.0).is_none());
        assert!(interpolate_pose(&[], 10.0, 0.05, 2.0).is_none());
        // One sample is held within the extrapolation window.
        assert!(close(
            &interpolate_pose(&s[..1], 10.03, 0.05, 2.0).expect("held"),
            &a
        ));
        // A gap too long to interpolate over: the nearer sample within the window.
        assert!(interpolate_pose(&s, 10.5, 0.05, 0.5).is_none());
        assert!(close(
            &interpolate_pose(&s, 10.01, 0.05, 0.5).expect("near a"),
            &a
        ));
        assert!(close(
            &interpolate_pose(&s, 10.98, 0.05, 0.5).expect("near b"),
            &b
        ));
    }

    #[test]
    fn slerp_takes_the_short_way_and_survives_sign_flips() {
        let a = Isometry3::from_parts(Translation3::identity(), UnitQuaternion::identity());
        // The same 90 deg rotation with its quaternion negated.
        let q = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), FRAC_PI_2);
        let neg = UnitQuaternion::new_unchecked(-q.into_inner());
        let b = Isometry3::from_parts(Translation3::identity(), neg);
        let mid = interpolate_pose(&[at(0.0, a), at(1.0, b)], 0.5, 0.0, 2.0).expect("mid");
        let want = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), FRAC_PI_2 / 2.0);
        assert!(mid.rotation.angle_to(&want) < 1e-9);
        // Identical rotations stay put.
        let same = interpolate_pose(&[at(0.0, a), at(1.0, a)], 0.3, 0.0, 2.0).expect("same");
        assert!(close(&same, &a));
    }

    #[test]
    fn the_buffer_keeps_order_and_its_span() {
        let mut buf = PoseBuffer::new(1.0);
        let p = |x: f64| Isometry3::translation(x, 0.0, 0.0);
        assert!(buf.push(at(5.0, p(5.0))));
        assert!(
            buf.push(at(4.5, p(4.5))),
            "a late sample is inserted in order"
        );
        assert!(buf.push(at(5.0, p(50.0))), "same stamp replaces");
        assert!(!buf.push(at(3.0, p(3.0))), "older than the span");
        assert!(!buf.push(at(f64::NAN, p(0.0))));
        assert!(buf.push(at(5.8, p(5.8))));
        assert!(buf.push(at(6.0, p(6.0))));
        let times: Vec<f64> = buf.samples().iter().map(|s| s.time_s).collect();
        assert_eq!(times, [5.0, 5.8, 6.0]);
        assert_eq!(buf.samples()[0].pose.translation.x, 50.0);
        let x = buf.at(5.9, 0.05, 0.5).expect("inside").translation.x;
        assert!((x - 5.9).abs() < 1e-12);
    }

    #[test]
    fn the_tracked_centre_is_the_palm_point_in_the_camera_frame() {
        // Camera 1 m above the base origin looking down (optical z = -base z).
        let camera = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 1.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        );
        // Hand frame at (0.1, 0.2, 0.3), fingers (z) along base x.
        let hand = Isometry3::from_parts(
            Translation3::new(0.1, 0.2, 0.3),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), FRAC_PI_2),
        );
        let c = tracked_centre(&camera, &hand);
        // Centre in base: (0.18, 0.2, 0.3); in the camera: x = 0.18, y = -0.2, z = 0.7.
        assert!((c - Point3::new(0.18, -0.2, 0.7)).norm() < 1e-12, "{c:?}");
    }

    #[test]
    fn pose_messages_are_checked() {
        let mut msg = Pose::default();
        msg.orientation.w = 1.0;
        msg.position.x = 0.5;
        let iso = pose_from_msg(&msg).expect("valid");
        assert_eq!(iso.translation.x, 0.5);
        msg.orientation.w = 1.005;
        assert!(
            pose_from_msg(&msg).is_some(),
            "slightly off unit is normalised"
        );
        msg.orientation.w = 0.5;
        assert!(pose_from_msg(&msg).is_none());
        msg.orientation.w = f64::NAN;
        assert!(pose_from_msg(&msg).is_none());
    }

    fn image_with(k: &Intrinsics, fill: impl Fn(usize, usize) -> u16) -> Vec<u16> {
        let (w, h) = (k.width() as usize, k.height() as usize);
        (0..w * h).map(|i| fill(i % w, i / w)).collect()
    }

    #[test]
    fn the_image_centre_is_the_nearest_object_pushed_back() {
        let k = Intrinsics::sr300();
        let cfg = ImageCentreConfig::default();
        // A 40 x 40 square at 500 mm around the principal point, three specks at
        // 300 mm, a wall at 1200 mm, a few pixels closer than the range.
        let img = image_with(&k, |u, v| {
            if (300..340).contains(&u) && (220..260).contains(&v) {
                500
            } else if v == 10 && u < 3 {
                300
            } else if v == 400 && u < 5 {
                100
            } else {
                1200
            }
        });
        let c = image_centre(&img, &k, &cfg).expect("centre");
        assert!((c - Point3::new(0.0, 0.0, 0.52)).norm() < 1e-12, "{c:?}");

        // Off-centre, on an empty background, with a depth gradient across it: the
        // median depth is used, and the push is along the viewing ray.
        let img = image_with(&k, |u, v| {
            if (400..420).contains(&u) && (100..120).contains(&v) {
                790 + (u - 400) as u16
            } else {
                0
            }
        });
        let c = image_centre(&img, &k, &cfg).expect("centre");
        let (u, v) = (409.5, 109.5);
        // 400 values, 790..=809 twenty each: the 200th (0-based 199) is 799.
        let surface = k.ray_through(u, v) * 0.799;
        let want = surface + surface.normalize() * 0.02;
        assert!((c.coords - want).norm() < 1e-12, "{c:?} vs {want:?}");

        // Nothing in range, too few pixels, or the wrong size: no centre.
        assert!(image_centre(&image_with(&k, |_, _| 0), &k, &cfg).is_none());
        let tiny = image_with(&k, |u, v| if u < 5 && v < 5 { 600 } else { 0 });
        assert!(image_centre(&tiny, &k, &cfg).is_none());
        assert!(image_centre(&img[..100], &k, &cfg).is_none());
    }

    #[test]
    fn images_are_decoded_and_refused_by_kind() {
        let k = Intrinsics::sr300();
        let depth: Vec<u16> = (0..640 * 480).map(|i| (i % 3000) as u16).collect();
        let img = Image::depth_mm(Header::default(), 640, 480, &depth);
        let mut out = Vec::new();
        depth_from_image(&img, &k, &mut out).expect("decoded");
        assert_eq!(out, depth);
        // Big-endian with padded rows.
        let mut be = img.clone();
        be.is_bigendian = 1;
        be.step = 640 * 2 + 4;
        be.data = depth
            .chunks(640)
            .flat_map(|row| {
                row.iter()
                    .flat_map(|d| d.to_be_bytes())
                    .chain([0u8; 4])
                    .collect::<Vec<u8>>()
            })
            .collect();
        depth_from_image(&be, &k, &mut out).expect("decoded");
        assert_eq!(out, depth);
        let small = Image::depth_mm(Header::default(), 320, 240, &depth[..320 * 240]);
        assert!(matches!(
            depth_from_image(&small, &k, &mut out),
            Err(FrameError::Size { width: 320, .. })
        ));
        let mut float = img.clone();
        float.encoding = encodings::DEPTH_32FC1.into();
        assert!(matches!(
            depth_from_image(&float, &k, &mut out),
            Err(FrameError::Encoding(_))
        ));
        let mut short = img;
        short.data.truncate(100);
        assert!(matches!(
            depth_from_image(&short, &k, &mut out),
            Err(FrameError::Layout(_))
        ));
    }

    #[test]
    fn config_errors_name_the_field_and_defaults_round_trip() {
        let d = HandInferenceConfig::default();
        d.validate().expect("defaults are valid");
        let text = teleop_node::config::to_toml(&d).expect("toml");
        let back: HandInferenceConfig = teleop_node::config::parse_toml(&text).expect("parses");
        assert_eq!(back, d);
        for (toml, field) in [
            ("rate_hz = 0.0", "rate_hz"),
            ("threads = 0", "threads"),
            ("max_pose_extrapolation_s = 1.0", "max_pose_extrapolation_s"),
            ("no_hand_after_s = -1.0", "no_hand_after_s"),
            ("[image_centre]\nband_m = 0.0", "image_centre.band_m"),
            (
                "[image_centre]\nmax_depth_m = 0.1",
                "image_centre.max_depth_m",
            ),
        ] {
            let cfg: HandInferenceConfig = teleop_node::config::parse_toml(toml).expect(toml);
            let err = cfg.validate().expect_err(toml);
            assert!(err.starts_with(field), "{toml}: {err}");
        }
        let err = teleop_node::config::parse_toml::<HandInferenceConfig>("modle = \"x\"")
            .expect_err("unknown field");
        assert!(err.contains("modle"), "{err}");
        let cfg: HandInferenceConfig = teleop_node::config::parse_toml(
            "intrinsics = \"sr300\"\nonnxruntime_library = \"/x/libonnxruntime.so\"",
        )
        .expect("parses");
        assert_eq!(
            cfg.onnxruntime_library,
            Some(PathBuf::from("/x/libonnxruntime.so"))
        );
    }

    #[test]
    fn a_missing_model_is_named_with_where_it_was_looked_for() {
        let err = resolve_model_path(Path::new("no/such/model.onnx")).expect_err("missing");
        let msg = err.to_string();
        assert!(msg.contains("no/such/model.onnx"), "{msg}");
        assert!(msg.contains("set `model`"), "{msg}");
        // The committed model is found from the repository root.
        let found = resolve_model_path(Path::new(DEFAULT_MODEL)).expect("committed model");
        assert!(found.is_file());
    }

    #[test]
    fn the_committed_models_offline_error_is_read_and_bad_evaluations_are_named() {
        let model = resolve_model_path(Path::new(DEFAULT_MODEL)).expect("committed model");
        let e = offline_test_error(&model)
            .expect("readable")
            .expect("the committed model is evaluated");
        assert!((0.05..0.2).contains(&e), "{e}");
        let dir = std::env::temp_dir().join(format!("hand-offline-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let m = dir.join("net.onnx");
        // No evaluation beside it: unknown, not an error.
        assert_eq!(offline_test_error(&m), Ok(None));
        let report = dir.join("report.json");
        std::fs::write(&report, "{ not json").expect("write");
        let err = offline_test_error(&m).expect_err("malformed");
        assert!(err.contains("report.json"), "{err}");
        let eval = |command: &str, error: &str| {
            format!(
                r#"{{"command": "{command}", "rows": [{{"model": "a", "dataset": "ood", "mean_error_rad": 0.3}}, {{"model": "a", "dataset": "test", "mean_error_rad": {error}}}]}}"#
            )
        };
        let with = |command: &str, error: &str| {
            std::fs::write(&report, eval(command, error)).expect("write");
            offline_test_error(&m)
        };
        assert_eq!(
            with("hand_eval --model a=x/net.onnx --data test=d", "0.09"),
            Ok(Some(0.09))
        );
        // Another model's evaluation: unknown.
        assert_eq!(with("hand_eval --model a=x/other.onnx", "0.09"), Ok(None));
        assert!(with("hand_eval --model a=net.onnx", "-1").is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
