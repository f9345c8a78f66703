//! BVH motion data: the skeleton of a `.bvh` file and the frame stream Axis Neuron
//! broadcasts for the Perception Neuron suit (thesis ch. 6), turned into the pose of one
//! joint (the palm) relative to another (the spine).
//!
//! # What is read
//!
//! * A BVH file's `HIERARCHY` (`ROOT`/`JOINT`/`End Site`, `OFFSET`, `CHANNELS`) and, if
//!   present, its `MOTION` section (`Frames:`, `Frame Time:`, one line of channel
//!   values per frame).
//! * Axis Neuron's "BVH data" broadcast in string format: frames of the form
//!   `<avatar index> <avatar name> v1 v2 ... vN ||`, where the values follow the
//!   skeleton's channel order. The broadcast carries no hierarchy; it is read from a BVH
//!   file exported by Axis Neuron with the same output settings (with or without
//!   displacement, rotation order), named in the config.
//!
//! # Conventions
//!
//! Rotation channels are in degrees and compose in the order listed (`Zrotation
//! Xrotation Yrotation` is `Rz * Rx * Ry`). A joint's translation from its parent is its
//! `OFFSET`, or, when it has position channels (the root; every joint "with
//! displacement"), the channel values. Lengths are in the file's units (Axis Neuron:
//! cm), scaled to metres by the caller's factor.

use std::io::{BufRead, BufReader, Read};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_hardware::{HardwareError, WristTracker};

use crate::tracking::imu_arm::{HumanArm, ImuArmConfig, ImuArmMapping};

/// Errors of BVH parsing and streaming.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BvhError {
    #[error("cannot read BVH file {path}: {reason}")]
    Io { path: PathBuf, reason: String },
    #[error("BVH line {line}: {reason}")]
    Syntax { line: usize, reason: String },
    #[error("BVH skeleton names joint `{0}` twice")]
    DuplicateJoint(String),
    #[error("BVH skeleton has no joint named `{0}`")]
    UnknownJoint(String),
    #[error("BVH frame has {found} values, the skeleton has {expected} channels")]
    FrameLength { found: usize, expected: usize },
    #[error("BVH frame value {index} is not a finite number (`{token}`)")]
    BadValue { index: usize, token: String },
    #[error("BVH stream frame has no `<avatar index> <avatar name>` prefix")]
    BadPrefix,
    #[error("BVH frame gives a zero-length arm (shoulder, elbow and hand coincide)")]
    DegenerateArm,
    #[error("BVH source's arm registration: {0}")]
    Arm(String),
}

/// One channel of a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    Xposition,
    Yposition,
    Zposition,
    Xrotation,
    Yrotation,
    Zrotation,
}

impl Channel {
    fn parse(token: &str) -> Option<Self> {
        Some(match token {
            "Xposition" => Self::Xposition,
            "Yposition" => Self::Yposition,
            "Zposition" => Self::Zposition,
            "Xrotation" => Self::Xrotation,
            "Yrotation" => Self::Yrotation,
            "Zrotation" => Self::Zrotation,
            _ => return None,
        })
    }
}

/// A joint of the skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct BvhJoint {
    pub name: String,
    /// Index of the parent joint (`None` for the root).
    pub parent: Option<usize>,
    /// Translation from the parent at rest, file units.
    pub offset: Vector3<f64>,
    pub channels: Vec<Channel>,
    /// Index of this joint's first value in a frame.
    pub first_channel: usize,
}

/// A skeleton (the `HIERARCHY` of a BVH file). End sites are not joints here.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    joints: Vec<BvhJoint>,
    channel_count: usize,
}

/// The `MOTION` section of a file.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    pub frame_time_s: f64,
    pub frames: Vec<Vec<f64>>,
}

struct Tokens<'a> {
    items: Vec<(usize, &'a str)>,
    pos: usize,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str) -> Self {
        let items = text
            .lines()
            .enumerate()
            .flat_map(|(i, l)| l.split_whitespace().map(move |t| (i + 1, t)))
            .collect();
        Self { items, pos: 0 }
    }
    fn line(&self) -> usize {
        self.items
            .get(self.pos)
            .or(self.items.last())
            .map_or(0, |(l, _)| *l)
    }
    fn next(&mut self) -> Result<&'a str, BvhError> {
        let t = self.items.get(self.pos).ok_or_else(|| BvhError::Syntax {
            line: self.line(),
            reason: "unexpected end of file".into(),
        })?;
        self.pos += 1;
        Ok(t.1)
    }
    fn peek(&self) -> Option<&'a str> {
        self.items.get(self.pos).map(|t| t.1)
    }
    fn expect(&mut self, want: &str) -> Result<(), BvhError> {
        let line = self.line();
        let got = self.next()?;
        if got == want {
            Ok(())
        } else {
            Err(BvhError::Syntax {
                line,
                reason: format!("expected `{want}`, found `{got}`"),
            })
        }
    }
    fn number(&mut self) -> Result<f64, BvhError> {
        let line = self.line();
        let t = self.next()?;
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(BvhError::Syntax {
                line,
                reason: format!("`{t}` is not a finite number"),
            }),
        }
    }
    fn vector(&mut self) -> Result<Vector3<f64>, BvhError> {
        Ok(Vector3::new(self.number()?, self.number()?, self.number()?))
    }
}

impl Skeleton {
    /// Reads a BVH file.
    ///
    /// # Errors
    /// [`BvhError`] naming the file or the line.
    pub fn load(path: &Path) -> Result<(Self, Option<Motion>), BvhError> {
        let text = std::fs::read_to_string(path).map_err(|e| BvhError::Io {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Self::parse(&text)
    }

    /// Parses BVH text: the hierarchy, and the motion section if there is one.
    ///
    /// # Errors
    /// [`BvhError::Syntax`] naming the line.
    pub fn parse(text: &str) -> Result<(Self, Option<Motion>), BvhError> {
        let mut tok = Tokens::new(text);
        tok.expect("HIERARCHY")?;
        tok.expect("ROOT")?;
        let mut skeleton = Skeleton {
            joints: Vec::new(),
            channel_count: 0,
        };
        skeleton.parse_joint(&mut tok, None)?;
        skeleton.check_unique()?;
        let motion = if tok.peek().is_some() {
            tok.expect("MOTION")?;
            tok.expect("Frames:")?;
            let line = tok.line();
            let count = tok.number()?;
            if count < 0.0 || count.fract() != 0.0 {
                return Err(BvhError::Syntax {
                    line,
                    reason: format!("frame count {count} is not a whole number"),
                });
            }
            tok.expect("Frame")?;
            tok.expect("Time:")?;
            let line = tok.line();
            let frame_time_s = tok.number()?;
            if frame_time_s <= 0.0 {
                return Err(BvhError::Syntax {
                    line,
                    reason: format!("frame time {frame_time_s} s is not positive"),
                });
            }
            let mut frames = Vec::new();
            for _ in 0..count as usize {
                let mut f = Vec::with_capacity(skeleton.channel_count);
                for _ in 0..skeleton.channel_count {
                    f.push(tok.number()?);
                }
                frames.push(f);
            }
            if tok.peek().is_some() {
                return Err(BvhError::Syntax {
                    line: tok.line(),
                    reason: format!("values after the {count} frames the header announced"),
                });
            }
            Some(Motion {
                frame_time_s,
                frames,
            })
        } else {
            None
        };
        Ok((skeleton, motion))
    }

    fn check_unique(&self) -> Result<(), BvhError> {
        for (i, j) in self.joints.iter().enumerate() {
            if self.joints[..i].iter().any(|k| k.name == j.name) {
                return Err(BvhError::DuplicateJoint(j.name.clone()));
            }
        }
        Ok(())
    }

    fn parse_joint(&mut self, tok: &mut Tokens<'_>, parent: Option<usize>) -> Result<(), BvhError> {
        let name = tok.next()?.to_string();
        tok.expect("{")?;
        tok.expect("OFFSET")?;
        let offset = tok.vector()?;
        tok.expect("CHANNELS")?;
        let line = tok.line();
        let n = tok.number()?;
        if !(0.0..=6.0).contains(&n) || n.fract() != 0.0 {
            return Err(BvhError::Syntax {
                line,
                reason: format!("{n} channels (0 to 6 allowed)"),
            });
        }
        let mut channels = Vec::new();
        for _ in 0..n as usize {
            let line = tok.line();
            let t = tok.next()?;
            channels.push(Channel::parse(t).ok_or_else(|| BvhError::Syntax {
                line,
                reason: format!("unknown channel `{t}`"),
            })?);
        }
        let index = self.joints.len();
        let first_channel = self.channel_count;
        self.channel_count += channels.len();
        self.joints.push(BvhJoint {
            name,
            parent,
            offset,
            channels,
            first_channel,
        });
        loop {
            let line = tok.line();
            match tok.next()? {
                "JOINT" => self.parse_joint(tok, Some(index))?,
                "End" => {
                    tok.expect("Site")?;
                    tok.expect("{")?;
                    tok.expect("OFFSET")?;
                    tok.vector()?;
                    tok.expect("}")?;
                }
                "}" => return Ok(()),
                other => {
                    return Err(BvhError::Syntax {
                        line,
                        reason: format!("expected `JOINT`, `End Site` or `}}`, found `{other}`"),
                    });
                }
            }
        }
    }

    /// The joints, parents before children.
    pub fn joints(&self) -> &[BvhJoint] {
        &self.joints
    }

    /// Number of values in a frame.
    pub fn channel_count(&self) -> usize {
        self.channel_count
    }

    /// Index of the joint named `name`.
    ///
    /// # Errors
    /// [`BvhError::UnknownJoint`].
    pub fn joint(&self, name: &str) -> Result<usize, BvhError> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| BvhError::UnknownJoint(name.to_string()))
    }

    /// Every joint's pose in the BVH world frame for one frame of values; lengths
    /// multiplied by `to_metres`.
    ///
    /// # Errors
    /// [`BvhError::FrameLength`] if `frame` does not match the skeleton,
    /// [`BvhError::BadValue`] for a non-finite value.
    pub fn world_poses(
        &self,
        frame: &[f64],
        to_metres: f64,
    ) -> Result<Vec<Isometry3<f64>>, BvhError> {
        if frame.len() != self.channel_count {
            return Err(BvhError::FrameLength {
                found: frame.len(),
                expected: self.channel_count,
            });
        }
        if let Some(index) = frame.iter().position(|v| !v.is_finite()) {
            return Err(BvhError::BadValue {
                index,
                token: frame[index].to_string(),
            });
        }
        let mut out: Vec<Isometry3<f64>> = Vec::with_capacity(self.joints.len());
        for j in &self.joints {
            let values = &frame[j.first_channel..j.first_channel + j.channels.len()];
            let mut translation = j.offset;
            let has_position = j.channels.iter().any(|c| {
                matches!(
                    c,
                    Channel::Xposition | Channel::Yposition | Channel::Zposition
                )
            });
            if has_position {
                translation = Vector3::zeros();
            }
            let mut rotation = UnitQuaternion::identity();
            for (c, v) in j.channels.iter().zip(values) {
                let angle = v.to_radians();
                match c {
                    Channel::Xposition => translation.x = *v,
                    Channel::Yposition => translation.y = *v,
                    Channel::Zposition => translation.z = *v,
                    Channel::Xrotation => {
                        rotation *= UnitQuaternion::from_axis_angle(&Vector3::x_axis(), angle)
                    }
                    Channel::Yrotation => {
                        rotation *= UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle)
                    }
                    Channel::Zrotation => {
                        rotation *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle)
                    }
                }
            }
            let local =
                Isometry3::from_parts(Translation3::from(translation * to_metres), rotation);
            let world = match j.parent {
                Some(p) => out[p] * local,
                None => local,
            };
            out.push(world);
        }
        Ok(out)
    }

    /// The arm joints `shoulder`, `elbow` and `hand` in the frame of joint `reference`
    /// for one frame of values (what the chapter-6 registration maps).
    ///
    /// # Errors
    /// As [`Skeleton::world_poses`]; [`BvhError::UnknownJoint`] for an index out of range.
    pub fn arm_in(
        &self,
        frame: &[f64],
        reference: usize,
        [shoulder, elbow, hand]: [usize; 3],
        to_metres: f64,
    ) -> Result<HumanArm, BvhError> {
        let world = self.world_poses(frame, to_metres)?;
        let at = |j: usize| -> Result<Isometry3<f64>, BvhError> {
            match (world.get(reference), world.get(j)) {
                (Some(r), Some(t)) => Ok(r.inverse() * t),
                _ => Err(BvhError::UnknownJoint(format!(
                    "joint index {reference} or {j} of {}",
                    self.joints.len()
                ))),
            }
        };
        Ok(HumanArm {
            shoulder: at(shoulder)?.translation.vector.into(),
            elbow: at(elbow)?.translation.vector.into(),
            hand: at(hand)?,
        })
    }

    /// Pose of joint `target` in the frame of joint `reference` for one frame of values.
    ///
    /// # Errors
    /// As [`Skeleton::world_poses`].
    pub fn relative_pose(
        &self,
        frame: &[f64],
        reference: usize,
        target: usize,
        to_metres: f64,
    ) -> Result<Isometry3<f64>, BvhError> {
        let world = self.world_poses(frame, to_metres)?;
        match (world.get(reference), world.get(target)) {
            (Some(r), Some(t)) => Ok(r.inverse() * t),
            _ => Err(BvhError::UnknownJoint(format!(
                "joint index {reference} or {target} of {}",
                self.joints.len()
            ))),
        }
    }
}

/// One frame of Axis Neuron's string broadcast: `<index> <name> v1 ... vN` (the `||`
/// separator already removed).
#[derive(Debug, Clone, PartialEq)]
pub struct StreamFrame {
    pub avatar_index: u32,
    pub avatar_name: String,
    pub values: Vec<f64>,
}

/// Parses one broadcast frame.
///
/// # Errors
/// [`BvhError::BadPrefix`] or [`BvhError::BadValue`].
pub fn parse_stream_frame(text: &str) -> Result<StreamFrame, BvhError> {
    let mut tokens = text.split_whitespace();
    let avatar_index = tokens
        .next()
        .and_then(|t| t.parse::<u32>().ok())
        .ok_or(BvhError::BadPrefix)?;
    let avatar_name = tokens.next().ok_or(BvhError::BadPrefix)?.to_string();
    if avatar_name.parse::<f64>().is_ok() {
        return Err(BvhError::BadPrefix);
    }
    let values = tokens
        .enumerate()
        .map(|(index, t)| match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(BvhError::BadValue {
                index,
                token: t.to_string(),
            }),
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(StreamFrame {
        avatar_index,
        avatar_name,
        values,
    })
}

/// Configuration of the BVH stream source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BvhStreamConfig {
    /// Axis Neuron's BVH broadcast server, `host:port` (TCP).
    pub address: String,
    /// A BVH file with the broadcast's skeleton (exported with the same settings).
    pub skeleton: PathBuf,
    /// Only this avatar's frames are used.
    #[serde(default)]
    pub avatar_index: u32,
    /// The reference joint (the spine, registered to the robot's torso).
    #[serde(default = "default_reference")]
    pub reference_joint: String,
    /// The tracked joint (the palm).
    #[serde(default = "default_hand")]
    pub hand_joint: String,
    /// File units to metres (Axis Neuron: cm, 0.01).
    #[serde(default = "default_to_metres")]
    pub to_metres: f64,
    /// A frame older than this (s) is no measurement.
    #[serde(default = "default_stale_after_s")]
    pub stale_after_s: f64,
    /// Wait between reconnection attempts, s.
    #[serde(default = "default_reconnect_s")]
    pub reconnect_s: f64,
    /// The chapter-6 registration (`[source.arm]`): when set, the source yields the
    /// PR2 palm's target in the torso frame ([`crate::tracking::imu_arm`]), scaled by
    /// the arm-length ratio, instead of the palm relative to the spine.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arm: Option<ImuArmConfig>,
}

fn default_reference() -> String {
    "Spine3".into()
}
fn default_hand() -> String {
    "RightHand".into()
}
fn default_to_metres() -> f64 {
    0.01
}
fn default_stale_after_s() -> f64 {
    0.2
}
fn default_reconnect_s() -> f64 {
    1.0
}

impl BvhStreamConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// A message naming the bad field.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("bvh.to_metres", self.to_metres),
            ("bvh.stale_after_s", self.stale_after_s),
            ("bvh.reconnect_s", self.reconnect_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be a positive number, got {v}"));
            }
        }
        if self.address.trim().is_empty() {
            return Err("bvh.address is empty (expected host:port)".into());
        }
        if let Some(arm) = &self.arm {
            arm.validate()?;
        }
        Ok(())
    }
}

/// Counters of the stream reader.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct BvhStreamCounters {
    pub frames: u64,
    pub rejected: u64,
    pub other_avatars: u64,
    pub connections: u64,
}

#[derive(Debug, Default)]
struct Shared {
    latest: Option<(Instant, Isometry3<f64>)>,
    connected: bool,
    last_error: Option<String>,
    counters: BvhStreamCounters,
    stop: bool,
}

/// A [`WristTracker`] reading Axis Neuron's BVH broadcast over TCP on a thread of its
/// own; `read` returns the palm pose relative to the spine from the newest frame.
pub struct BvhStreamTracker {
    shared: Arc<Mutex<Shared>>,
    stale_after: Duration,
}

impl BvhStreamTracker {
    /// Loads the skeleton and starts the reader thread (which connects, and reconnects
    /// after a loss).
    ///
    /// # Errors
    /// [`BvhError`] for a missing or malformed skeleton file or unknown joint names.
    pub fn start(config: &BvhStreamConfig) -> Result<Self, BvhError> {
        let (skeleton, _) = Skeleton::load(&config.skeleton)?;
        let reference = skeleton.joint(&config.reference_joint)?;
        let hand = skeleton.joint(&config.hand_joint)?;
        let arm = match &config.arm {
            Some(a) => Some(ArmJoints {
                shoulder: skeleton.joint(&a.shoulder_joint)?,
                elbow: skeleton.joint(&a.elbow_joint)?,
                mapping: ImuArmMapping::new(a).map_err(|e| BvhError::Arm(e.to_string()))?,
            }),
            None => None,
        };
        let shared = Arc::new(Mutex::new(Shared::default()));
        let reader = Reader {
            skeleton,
            reference,
            hand,
            arm,
            avatar_index: config.avatar_index,
            to_metres: config.to_metres,
            address: config.address.clone(),
            reconnect: Duration::from_secs_f64(config.reconnect_s),
            shared: shared.clone(),
        };
        std::thread::Builder::new()
            .name("bvh-stream".into())
            .spawn(move || reader.run())
            .map_err(|e| BvhError::Io {
                path: PathBuf::from(&config.address),
                reason: format!("cannot start the reader thread: {e}"),
            })?;
        Ok(Self {
            shared,
            stale_after: Duration::from_secs_f64(config.stale_after_s),
        })
    }

    /// The reader's counters.
    pub fn counters(&self) -> BvhStreamCounters {
        self.shared.lock().map(|s| s.counters).unwrap_or_default()
    }
}

impl std::fmt::Debug for BvhStreamTracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BvhStreamTracker")
            .field("counters", &self.counters())
            .field("stale_after", &self.stale_after)
            .finish_non_exhaustive()
    }
}

impl Drop for BvhStreamTracker {
    fn drop(&mut self) {
        if let Ok(mut s) = self.shared.lock() {
            s.stop = true;
        }
    }
}

impl WristTracker for BvhStreamTracker {
    fn read(&mut self, _now_s: f64) -> Result<Option<Isometry3<f64>>, HardwareError> {
        let s = self
            .shared
            .lock()
            .map_err(|_| HardwareError::Fault("BVH reader thread panicked".into()))?;
        match s.latest {
            Some((at, pose)) if at.elapsed() <= self.stale_after => Ok(Some(pose)),
            _ if !s.connected => Err(HardwareError::NotConnected(format!(
                "BVH stream: {}",
                s.last_error.as_deref().unwrap_or("not connected yet")
            ))),
            _ => Ok(None),
        }
    }
}

/// The joints and the mapping of the chapter-6 registration.
struct ArmJoints {
    shoulder: usize,
    elbow: usize,
    mapping: ImuArmMapping,
}

struct Reader {
    skeleton: Skeleton,
    reference: usize,
    hand: usize,
    arm: Option<ArmJoints>,
    avatar_index: u32,
    to_metres: f64,
    address: String,
    reconnect: Duration,
    shared: Arc<Mutex<Shared>>,
}

impl Reader {
    fn stopped(&self) -> bool {
        self.shared.lock().map_or(true, |s| s.stop)
    }

    fn update(&self, f: impl FnOnce(&mut Shared)) {
        if let Ok(mut s) = self.shared.lock() {
            f(&mut s);
        }
    }

    fn run(self) {
        while !self.stopped() {
            match TcpStream::connect(&self.address) {
                Ok(stream) => {
                    self.update(|s| {
                        s.connected = true;
                        s.counters.connections += 1;
                    });
                    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
                    let reason = self.read_stream(stream);
                    tracing::warn!(address = %self.address, %reason, "BVH stream lost");
                    self.update(|s| {
                        s.connected = false;
                        s.last_error = Some(reason);
                    });
                }
                Err(e) => {
                    let reason = format!("cannot connect to {}: {e}", self.address);
                    self.update(|s| s.last_error = Some(reason));
                }
            }
            std::thread::sleep(self.reconnect);
        }
    }

    /// Reads frames until the stream ends or fails; returns why it stopped.
    fn read_stream(&self, stream: TcpStream) -> String {
        let mut reader = BufReader::new(stream);
        let mut pending: Vec<u8> = Vec::new();
        // How far `pending` is known to hold no separator: each byte is scanned once,
        // not once per read (a sender trickling a long frame cannot make the scan
        // quadratic).
        let mut scanned = 0;
        loop {
            if self.stopped() {
                return "stopped".into();
            }
            match reader.fill_buf() {
                Ok([]) => return "the server closed the connection".into(),
                Ok(bytes) => {
                    pending.extend_from_slice(bytes);
                    let n = bytes.len();
                    reader.consume(n);
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue;
                }
                Err(e) => return e.to_string(),
            }
            while let Some(at) = pending[scanned..].windows(2).position(|w| w == b"||") {
                let end = scanned + at;
                let frame: Vec<u8> = pending.drain(..end + 2).take(end).collect();
                self.handle(&frame);
                scanned = 0;
            }
            // The last byte may be the first half of a separator.
            scanned = pending.len().saturating_sub(1);
            if pending.len() > 1 << 20 {
                pending.clear();
                scanned = 0;
                self.update(|s| s.counters.rejected += 1);
            }
        }
    }

    /// The source's pose for one frame: the palm in the spine frame, or with the arm
    /// registration the PR2 palm target in the torso frame.
    fn pose(&self, values: &[f64]) -> Result<Isometry3<f64>, BvhError> {
        let Some(arm) = &self.arm else {
            return self
                .skeleton
                .relative_pose(values, self.reference, self.hand, self.to_metres);
        };
        let human = self.skeleton.arm_in(
            values,
            self.reference,
            [arm.shoulder, arm.elbow, self.hand],
            self.to_metres,
        )?;
        arm.mapping
            .palm_target(&human)
            .ok_or(BvhError::DegenerateArm)
    }

    fn handle(&self, bytes: &[u8]) {
        let Ok(text) = std::str::from_utf8(bytes) else {
            self.update(|s| s.counters.rejected += 1);
            return;
        };
        if text.trim().is_empty() {
            return;
        }
        let pose = parse_stream_frame(text).and_then(|f| {
            if f.avatar_index != self.avatar_index {
                return Ok(None);
            }
            self.pose(&f.values).map(Some)
        });
        match pose {
            Ok(Some(pose)) => self.update(|s| {
                s.latest = Some((Instant::now(), pose));
                s.counters.frames += 1;
            }),
            Ok(None) => self.update(|s| s.counters.other_avatars += 1),
            Err(e) => {
                tracing::debug!(error = %e, "BVH frame rejected");
                self.update(|s| s.counters.rejected += 1);
            }
        }
    }
}

/// Reads all of `source` (for tests and file replay of a captured broadcast) and
/// returns its frames.
///
/// # Errors
/// The first malformed frame's error.
pub fn parse_stream<R: Read>(mut source: R) -> Result<Vec<StreamFrame>, BvhError> {
    let mut text = String::new();
    source.read_to_string(&mut text).map_err(|e| BvhError::Io {
        path: PathBuf::from("<stream>"),
        reason: e.to_string(),
    })?;
    text.split("||")
        .filter(|t| !t.trim().is_empty())
        .map(parse_stream_frame)
        .collect()
}
