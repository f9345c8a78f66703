//! Bags to a LeRobotDataset v3.0.
//!
//! Layout (as LeRobot 0.4 reads it): `meta/info.json`, `meta/tasks.parquet` (task
//! text as the index, `task_index`), `meta/episodes/chunk-000/file-000.parquet`,
//! `meta/stats.json`, `data/chunk-XXX/file-YYY.parquet` (one row per frame),
//! `videos/<key>/chunk-XXX/file-YYY.mp4` (episodes one after another; each episode's
//! `from_timestamp` / `to_timestamp` in its row of the episodes table).
//!
//! Features: `observation.state` = the PR2 arm chain's 7 joint positions and the
//! Shadow hand's 17 finger joint positions (the robot site's feedback topics);
//! `observation.fingertip_forces` = the five fingertip forces (N), when recorded;
//! `action` = what the operator site sent or what the robot site's controllers sent to
//! the robots ([`ActionSource`]); `observation.images.top|side` = the camera views the
//! robot site sent (JPEG, unchanged, as MJPEG MP4); `source_age_ms` = for each input,
//! how old its message was at the frame's time (ms, by source stamps).
//!
//! Alignment ([`crate::align`]): frame `k` of an episode is at `start + k / fps`, and
//! takes each input's newest message stamped at or before it, if at most `max_age` old;
//! a frame missing an input is not written: the episode is cut there, the frames are
//! counted per input in the summary, and runs shorter than `min_episode_s` are dropped
//! and counted.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_json::json;
use teleop_interfaces::joints::{FINGERTIPS, PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_interfaces::topics;
use teleop_msgs::{
    CompressedImage, FingertipPressures, JointCommand, JointState, NodeStatus, OperatorInput,
    PoseStamped,
};

use crate::DatasetError;
use crate::align::{Stream, complete_runs, frame_time_ns, newest_at};
use crate::jpeg::{JpegInfo, jpeg_info};
use crate::mp4::MjpegMp4Writer;
use crate::table::{Column, Values, write_table};

/// The format version written (LeRobot's `CODEBASE_VERSION`).
pub const CODEBASE_VERSION: &str = "v3.0";
/// Files per chunk directory (LeRobot's default).
pub const CHUNKS_SIZE: usize = 1000;

/// Where episodes come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EpisodeSource {
    /// Each clutch engagement (clutch pedal and enable switch held) is an episode.
    #[default]
    Clutch,
    /// The robot world's job as the simulator judged it (its `job.*` status counters):
    /// from the first clutch engagement to the verdict (success or failure).
    Job,
    /// The whole recording: from the first to the last instant every input is there.
    Whole,
}

impl std::str::FromStr for EpisodeSource {
    type Err = DatasetError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "clutch" => Ok(Self::Clutch),
            "job" => Ok(Self::Job),
            "whole" => Ok(Self::Whole),
            other => Err(DatasetError::Config(format!(
                "episodes: unknown source {other:?} (clutch, job or whole)"
            ))),
        }
    }
}

/// What the `action` feature holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionSource {
    /// What the operator site sent (27): the wrist pose (position m, quaternion x y z
    /// w), clutch and enable (0/1), the motion scale, the 17 finger joint targets (rad).
    #[default]
    Operator,
    /// What the robot site's controllers sent to the robots (24): the PR2 arm chain's 7
    /// joint velocities (rad/s, `/teleop/hw/pr2_arm/command`) and the hand's 17 joint
    /// position set points (rad, `/teleop/hw/shadow_hand/command` in position or
    /// impedance mode); in `teleop record --all` recordings at the robot site.
    Robot,
}

impl ActionSource {
    /// The action's width.
    #[must_use]
    pub fn width(self) -> usize {
        match self {
            Self::Operator => 27,
            Self::Robot => 24,
        }
    }
}

impl std::str::FromStr for ActionSource {
    type Err = DatasetError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "operator" => Ok(Self::Operator),
            "robot" => Ok(Self::Robot),
            other => Err(DatasetError::Config(format!(
                "action: unknown source {other:?} (operator or robot)"
            ))),
        }
    }
}

/// How to export.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExportOptions {
    /// Frames per second.
    pub fps: u32,
    pub episodes: EpisodeSource,
    /// What `action` holds.
    pub action: ActionSource,
    /// Each episode's task text (default: by episode source, see [`default_task`]).
    pub task: Option<String>,
    /// The oldest a message may be at a frame's time, s, for every input (default per
    /// input: three of its nominal periods, at least two frame periods).
    pub max_age_s: Option<f64>,
    /// Shorter runs of complete frames are dropped (and counted), s.
    pub min_episode_s: f64,
    /// Export the camera views (when recorded).
    pub cameras: bool,
    /// A new data file once the current one holds this much (at an episode boundary).
    pub data_file_mb: f64,
    /// A new video file once the current one holds this much (at an episode boundary).
    pub video_file_mb: f64,
    /// `robot_type` of info.json.
    pub robot_type: String,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            fps: 30,
            episodes: EpisodeSource::Clutch,
            action: ActionSource::Operator,
            task: None,
            max_age_s: None,
            min_episode_s: 0.5,
            cameras: true,
            data_file_mb: 100.0,
            video_file_mb: 200.0,
            robot_type: "pr2_shadow_hand".to_owned(),
        }
    }
}

impl ExportOptions {
    /// # Errors
    /// [`DatasetError::Config`] naming the field out of range.
    pub fn validate(&self) -> Result<(), DatasetError> {
        let bad = |what: String| Err(DatasetError::Config(what));
        if !(1..=1000).contains(&self.fps) {
            return bad(format!("fps: {} is outside 1..=1000", self.fps));
        }
        if let Some(a) = self.max_age_s
            && !(a.is_finite() && a > 0.0)
        {
            return bad(format!(
                "max_age_s: {a} is not a positive number of seconds"
            ));
        }
        if !(self.min_episode_s.is_finite() && self.min_episode_s >= 0.0) {
            return bad(format!(
                "min_episode_s: {} is not a non-negative number of seconds",
                self.min_episode_s
            ));
        }
        for (name, v) in [
            ("data_file_mb", self.data_file_mb),
            ("video_file_mb", self.video_file_mb),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name}: {v} is not a positive size"));
            }
        }
        if let Some(t) = &self.task
            && t.trim().is_empty()
        {
            return bad("task: empty text".to_owned());
        }
        Ok(())
    }
}

/// The task text of episodes from `source` when none is given.
#[must_use]
pub fn default_task(source: EpisodeSource) -> &'static str {
    match source {
        EpisodeSource::Clutch | EpisodeSource::Whole => {
            "teleoperate the PR2 arm and the Shadow hand"
        }
        EpisodeSource::Job => "pick up the object and place it on the target",
    }
}

/// What the export did.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct ExportSummary {
    pub bags: usize,
    pub messages_read: u64,
    pub bag_bytes: u64,
    /// Messages refused (undecodable, non-finite, joints missing, bad stamps, views not
    /// JPEG or of another size), per topic.
    pub rejected: BTreeMap<String, u64>,
    /// Episode intervals found (before cutting at missing inputs).
    pub intervals: usize,
    pub episodes: usize,
    pub frames: usize,
    /// Frames not written because an input was missing, per input (a frame missing two
    /// inputs counts under both).
    pub frames_missing_input: BTreeMap<String, u64>,
    /// Frames not written because an input was missing (each once).
    pub frames_missing: u64,
    /// Frames of complete runs shorter than `min_episode_s`, not written.
    pub frames_in_short_runs: u64,
    /// Intervals cut into more than one episode by missing inputs.
    pub intervals_cut: usize,
    /// Inputs the bags lack entirely, left out of the features (optional ones only).
    pub inputs_absent: Vec<String>,
    pub tasks: Vec<String>,
    pub video_frames: u64,
    /// Bytes of the dataset written.
    pub bytes_written: u64,
    pub seconds: f64,
}

/// The inputs, in `source_age_ms` order.
const ARM: &str = "arm_state";
const HAND: &str = "hand_state";
const FORCES: &str = "fingertip_forces";
const WRIST: &str = "wrist_pose";
const PEDALS: &str = "operator_input";
const FINGERS: &str = "finger_targets";
const ARM_COMMAND: &str = "arm_command";
const HAND_COMMAND: &str = "hand_command";
const VIEWS: [(&str, &str); 2] = [
    ("top", "observation.images.top"),
    ("side", "observation.images.side"),
];

#[derive(Debug, Clone, Copy, PartialEq)]
struct Pedals {
    clutch: bool,
    enable: bool,
    scale: f32,
}

/// The job's standing in one status of the simulator.
#[derive(Debug, Clone, PartialEq)]
struct JobStanding {
    verdict: Option<String>,
}

/// One bag's inputs.
#[derive(Debug, Default)]
struct Recording {
    name: String,
    arm: Stream<Vec<f32>>,
    hand: Stream<Vec<f32>>,
    forces: Stream<Vec<f32>>,
    wrist: Stream<Vec<f32>>,
    pedals: Stream<Pedals>,
    fingers: Stream<Vec<f32>>,
    arm_command: Stream<Vec<f32>>,
    hand_command: Stream<Vec<f32>>,
    views: [Stream<Vec<u8>>; 2],
    view_info: [Option<JpegInfo>; 2],
    job: Stream<JobStanding>,
}

fn topic_name(spec: &teleop_interfaces::TopicSpec) -> String {
    format!("/{}", spec.name.trim_start_matches('/'))
}

fn stamp_ns(h: &teleop_msgs::Header) -> Result<i64, String> {
    let ns = h.stamp.as_nanos();
    if ns <= 0 {
        return Err("stamp at or before the epoch".to_owned());
    }
    Ok(ns)
}

fn finite(values: impl IntoIterator<Item = f64>) -> Result<Vec<f32>, String> {
    values
        .into_iter()
        .map(|v| {
            if v.is_finite() {
                Ok(v as f32)
            } else {
                Err(format!("non-finite value {v}"))
            }
        })
        .collect()
}

fn positions_by_name(js: &JointState, names: &[&str]) -> Result<Vec<f32>, String> {
    by_name(&js.name, &js.position, "positions", names)
}

/// `values` (one per name of `have`) in the order of `want`.
fn by_name(have: &[String], values: &[f64], what: &str, want: &[&str]) -> Result<Vec<f32>, String> {
    if values.len() != have.len() {
        return Err(format!("{} names but {} {what}", have.len(), values.len()));
    }
    finite(want.iter().map(|w| {
        have.iter()
            .position(|n| n == w)
            .map_or(f64::NAN, |i| values[i])
    }))
    .map_err(
        |e| match want.iter().find(|w| !have.iter().any(|n| n == *w)) {
            Some(missing) => format!("joint {missing} missing"),
            None => e,
        },
    )
}

fn decode<T: teleop_msgs::Message>(data: &[u8]) -> Result<T, String> {
    teleop_msgs::decode::<T>(data).map_err(|e| e.to_string())
}

/// Reads one bag (a directory or one MCAP file) into its inputs.
fn read_recording(
    path: &Path,
    summary: &mut ExportSummary,
    cameras: bool,
) -> Result<Recording, DatasetError> {
    let files = teleop_bag::mcap_files(path)
        .map_err(|e| DatasetError::Bag(format!("{}: {e}", path.display())))?;
    let arm_t = Input::Arm.topic();
    let hand_t = Input::Hand.topic();
    let forces_t = Input::Forces.topic();
    let wrist_t = Input::Wrist.topic();
    let pedals_t = Input::Pedals.topic();
    let fingers_t = Input::Fingers.topic();
    let views_t = [Input::View(0).topic(), Input::View(1).topic()];
    let status_t = topic_name(&topics::NODE_STATUS.spec);
    let arm_command_t = Input::ArmCommand.topic();
    let hand_command_t = Input::HandCommand.topic();

    let mut arm = Vec::new();
    let mut hand = Vec::new();
    let mut forces = Vec::new();
    let mut wrist = Vec::new();
    let mut pedals = Vec::new();
    let mut fingers = Vec::new();
    let mut views: [Vec<(u64, i64, Vec<u8>)>; 2] = [Vec::new(), Vec::new()];
    let mut view_info: [Option<JpegInfo>; 2] = [None, None];
    let mut job = Vec::new();
    let mut arm_command = Vec::new();
    let mut hand_command = Vec::new();

    for file in files {
        let buf = std::fs::read(&file).map_err(|e| DatasetError::io(&file, e))?;
        summary.bag_bytes += buf.len() as u64;
        let msgs = teleop_bag::messages(&buf)
            .map_err(|e| DatasetError::Bag(format!("{}: {e}", file.display())))?;
        for m in msgs {
            let m = match m {
                Ok(m) => m,
                Err(e) => {
                    // A file cut short: what came before is kept.
                    tracing::warn!("{}: reading stopped: {e}", file.display());
                    *summary
                        .rejected
                        .entry(format!("{} (unreadable rest)", file.display()))
                        .or_default() += 1;
                    break;
                }
            };
            summary.messages_read += 1;
            let topic = m.channel.topic.as_str();
            let log = m.log_time;
            let joints = |names: &[&str]| -> Result<(u64, i64, Vec<f32>), String> {
                let js: JointState = decode(&m.data)?;
                Ok((log, stamp_ns(&js.header)?, positions_by_name(&js, names)?))
            };
            let result: Result<(), String> = (|| {
                if topic == arm_t {
                    arm.push(joints(&PR2_ARM_JOINTS)?);
                } else if topic == hand_t {
                    hand.push(joints(&SHADOW_FINGER_JOINTS)?);
                } else if topic == fingers_t {
                    fingers.push(joints(&SHADOW_FINGER_JOINTS)?);
                } else if topic == forces_t {
                    let f: FingertipPressures = decode(&m.data)?;
                    forces.push((
                        log,
                        stamp_ns(&f.header)?,
                        finite([f.ff, f.mf, f.rf, f.lf, f.th])?,
                    ));
                } else if topic == wrist_t {
                    let p: PoseStamped = decode(&m.data)?;
                    let (x, q) = (p.pose.position, p.pose.orientation);
                    wrist.push((
                        log,
                        stamp_ns(&p.header)?,
                        finite([x.x, x.y, x.z, q.x, q.y, q.z, q.w])?,
                    ));
                } else if topic == pedals_t {
                    let o: OperatorInput = decode(&m.data)?;
                    let scale = finite([o.motion_scale])?[0];
                    pedals.push((
                        log,
                        stamp_ns(&o.header)?,
                        Pedals {
                            clutch: o.clutch,
                            enable: o.enable,
                            scale,
                        },
                    ));
                } else if let Some(i) = views_t.iter().position(|t| t == topic) {
                    if !cameras {
                        return Ok(());
                    }
                    let c: CompressedImage = decode(&m.data)?;
                    if c.codec() != Some("jpeg") {
                        return Err(format!("format {:?} is not JPEG", c.format));
                    }
                    let info = jpeg_info(&c.data).map_err(|e| e.to_string())?;
                    match view_info[i] {
                        None => view_info[i] = Some(info),
                        Some(first) if first != info => {
                            return Err(format!(
                                "a {}x{} view among {}x{} ones",
                                info.width, info.height, first.width, first.height
                            ));
                        }
                        Some(_) => {}
                    }
                    views[i].push((log, stamp_ns(&c.header)?, c.data));
                } else if topic == arm_command_t {
                    let js: JointState = decode(&m.data)?;
                    arm_command.push((
                        log,
                        stamp_ns(&js.header)?,
                        by_name(&js.name, &js.velocity, "velocities", &PR2_ARM_JOINTS)?,
                    ));
                } else if topic == hand_command_t {
                    let c: JointCommand = decode(&m.data)?;
                    if c.mode != "position" && c.mode != "impedance" {
                        return Err(format!(
                            "mode {:?} has no position set points (position or impedance)",
                            c.mode
                        ));
                    }
                    hand_command.push((
                        log,
                        stamp_ns(&c.header)?,
                        by_name(&c.name, &c.position, "positions", &SHADOW_FINGER_JOINTS)?,
                    ));
                } else if topic == status_t {
                    let s: NodeStatus = decode(&m.data)?;
                    if s.node_name == "remote_sim"
                        && let Some(standing) = job_standing(&s)
                    {
                        job.push((log, stamp_ns(&s.header)?, standing));
                    }
                }
                Ok(())
            })();
            if let Err(why) = result {
                tracing::debug!("{topic}: refused: {why}");
                *summary.rejected.entry(topic.to_owned()).or_default() += 1;
            }
        }
    }
    let [top, side] = views;
    Ok(Recording {
        name: path.display().to_string(),
        arm: Stream::from_arrivals(arm),
        hand: Stream::from_arrivals(hand),
        forces: Stream::from_arrivals(forces),
        wrist: Stream::from_arrivals(wrist),
        pedals: Stream::from_arrivals(pedals),
        fingers: Stream::from_arrivals(fingers),
        views: [Stream::from_arrivals(top), Stream::from_arrivals(side)],
        view_info,
        job: Stream::from_arrivals(job),
        arm_command: Stream::from_arrivals(arm_command),
        hand_command: Stream::from_arrivals(hand_command),
    })
}

/// The job's standing in a status of the simulator, if it has a job.
fn job_standing(s: &NodeStatus) -> Option<JobStanding> {
    use teleop_interfaces::status::job;
    s.counter(job::LIFTED)?;
    let verdict = if s.counter(job::SUCCEEDED).unwrap_or(0) > 0 {
        Some("succeeded".to_owned())
    } else {
        s.counter_names
            .iter()
            .zip(&s.counter_values)
            .find(|(n, v)| n.starts_with(job::FAILED_PREFIX) && **v > 0)
            .map(|(n, _)| format!("failed: {}", n.trim_start_matches(job::FAILED_PREFIX)))
    };
    Some(JobStanding { verdict })
}

/// An episode interval of a recording: [start, end) ns, and what it is.
#[derive(Debug, Clone, PartialEq)]
struct Interval {
    start: i64,
    end: i64,
    outcome: String,
}

fn clutch_intervals(pedals: &Stream<Pedals>) -> Vec<Interval> {
    let mut out = Vec::new();
    let mut start = None;
    for (&t, p) in pedals.stamps().iter().zip(pedals.values()) {
        let engaged = p.clutch && p.enable;
        match (engaged, start) {
            (true, None) => start = Some(t),
            (false, Some(s)) => {
                out.push(Interval {
                    start: s,
                    end: t,
                    outcome: "clutch released".to_owned(),
                });
                start = None;
            }
            _ => {}
        }
    }
    if let (Some(s), Some(last)) = (start, pedals.last_stamp())
        && last > s
    {
        out.push(Interval {
            start: s,
            end: last,
            outcome: "recording ended while clutched".to_owned(),
        });
    }
    out
}

fn job_interval(rec: &Recording) -> Result<Vec<Interval>, DatasetError> {
    let Some(first_status) = rec.job.first_stamp() else {
        return Err(DatasetError::Config(format!(
            "{}: no status of remote_sim with a job (job.* counters) in the bag: record /teleop/status of a run with a job (teleop launch --task pick), or use --episodes clutch",
            rec.name
        )));
    };
    let verdict = rec
        .job
        .stamps()
        .iter()
        .zip(rec.job.values())
        .find_map(|(&t, s)| s.verdict.clone().map(|v| (t, v)));
    let start = clutch_intervals(&rec.pedals)
        .first()
        .map_or(first_status, |i| i.start);
    let (end, outcome) = match verdict {
        Some((t, v)) => (t, v),
        None => (
            rec.job.last_stamp().unwrap_or(first_status),
            "unfinished (no verdict before the recording ended)".to_owned(),
        ),
    };
    Ok(if end > start {
        vec![Interval {
            start,
            end,
            outcome,
        }]
    } else {
        Vec::new()
    })
}

fn whole_interval(rec: &Recording, required: &[&dyn HasSpan]) -> Vec<Interval> {
    let start = required.iter().filter_map(|s| s.first()).max();
    let end = required.iter().filter_map(|s| s.last()).min();
    match (start, end) {
        (Some(s), Some(e)) if e > s => vec![Interval {
            start: s,
            end: e,
            outcome: format!("whole recording {}", rec.name),
        }],
        _ => Vec::new(),
    }
}

trait HasSpan {
    fn first(&self) -> Option<i64>;
    fn last(&self) -> Option<i64>;
}
impl<T> HasSpan for Stream<T> {
    fn first(&self) -> Option<i64> {
        self.first_stamp()
    }
    fn last(&self) -> Option<i64> {
        self.last_stamp()
    }
}

/// An input's column in the frame table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Input {
    Arm,
    Hand,
    Forces,
    Wrist,
    Pedals,
    Fingers,
    ArmCommand,
    HandCommand,
    View(usize),
}

impl Input {
    fn name(self) -> &'static str {
        match self {
            Input::Arm => ARM,
            Input::Hand => HAND,
            Input::Forces => FORCES,
            Input::Wrist => WRIST,
            Input::Pedals => PEDALS,
            Input::Fingers => FINGERS,
            Input::ArmCommand => ARM_COMMAND,
            Input::HandCommand => HAND_COMMAND,
            Input::View(i) => VIEWS[i].0,
        }
    }
    fn rate_hz(self) -> f64 {
        self.spec().rate_hz
    }
    fn topic(self) -> String {
        topic_name(&self.spec())
    }
    /// The input's topic in the table.
    fn spec(self) -> teleop_interfaces::TopicSpec {
        match self {
            Input::Arm => topics::PR2_JOINT_STATES.spec,
            Input::Hand => topics::SHADOW_JOINT_STATES.spec,
            Input::Forces => topics::FINGERTIP_PRESSURES.spec,
            Input::Wrist => topics::WRIST_POSE.spec,
            Input::Pedals => topics::OPERATOR_INPUT.spec,
            Input::Fingers => topics::HAND_JOINT_TARGETS.spec,
            Input::ArmCommand => topics::HW_PR2_ARM_COMMAND.spec,
            Input::HandCommand => topics::HW_HAND_COMMAND.spec,
            Input::View(0) => topics::REMOTE_CAMERA_TOP.spec,
            Input::View(_) => topics::REMOTE_CAMERA_SIDE.spec,
        }
    }
}

/// The oldest a message of `input` may be at a frame, ns.
fn max_age_ns(input: Input, opts: &ExportOptions) -> i64 {
    let s = opts
        .max_age_s
        .unwrap_or_else(|| (3.0 / input.rate_hz().max(1e-3)).max(2.0 / f64::from(opts.fps)));
    (s * 1e9).round() as i64
}

/// The frames of every episode, column by column.
#[derive(Debug, Default)]
struct Frames {
    /// Values per row of `action`.
    action_width: usize,
    state: Vec<f32>,
    forces: Vec<f32>,
    action: Vec<f32>,
    ages: Vec<f32>,
    timestamp: Vec<f32>,
    frame_index: Vec<i64>,
    episode_index: Vec<i64>,
    index: Vec<i64>,
    task_index: Vec<i64>,
}

impl Frames {
    fn rows(&self) -> usize {
        self.index.len()
    }
}

/// One episode's row of the episodes table.
#[derive(Debug, Clone)]
struct EpisodeRow {
    index: i64,
    task: String,
    length: i64,
    data_file: (usize, usize),
    from_index: i64,
    to_index: i64,
    /// Per video key: (chunk, file), from, to (s).
    videos: Vec<((usize, usize), f64, f64)>,
    start_ns: i64,
    source: String,
}

/// Chunk/file counter of LeRobot's layout.
#[derive(Debug, Clone, Copy, Default)]
struct FileIndex {
    chunk: usize,
    file: usize,
}
impl FileIndex {
    fn next(self) -> Self {
        if self.file + 1 >= CHUNKS_SIZE {
            Self {
                chunk: self.chunk + 1,
                file: 0,
            }
        } else {
            Self {
                chunk: self.chunk,
                file: self.file + 1,
            }
        }
    }
    fn path(self, root: &Path, dir: &str, ext: &str) -> PathBuf {
        root.join(dir)
            .join(format!("chunk-{:03}", self.chunk))
            .join(format!("file-{:03}.{ext}", self.file))
    }
}

/// A video key's current file.
#[derive(Debug)]
struct VideoOut {
    key: &'static str,
    index: FileIndex,
    writer: Option<MjpegMp4Writer>,
    info: Option<JpegInfo>,
    /// Per-channel sums over the frames sampled for the statistics (0..1 values).
    stats: ImageStats,
}

/// Writes a LeRobotDataset v3.0 at `out` (which must not exist) from `bags`; on an
/// error nothing is left at `out`.
///
/// # Errors
/// [`DatasetError`] naming the bag, the input or the option at fault: a bag without a
/// required input, no episode found, files that cannot be written.
pub fn export_lerobot(
    bags: &[PathBuf],
    out: &Path,
    opts: &ExportOptions,
) -> Result<ExportSummary, DatasetError> {
    opts.validate()?;
    if bags.is_empty() {
        return Err(DatasetError::Config("no bag given".to_owned()));
    }
    if out.exists() {
        return Err(DatasetError::Config(format!(
            "{} exists: the dataset is written to a new directory",
            out.display()
        )));
    }
    let written = export_into(bags, out, opts);
    if written.is_err() {
        // A dataset cut short is no dataset.
        let _ = std::fs::remove_dir_all(out);
    }
    written
}

fn export_into(
    bags: &[PathBuf],
    out: &Path,
    opts: &ExportOptions,
) -> Result<ExportSummary, DatasetError> {
    let began = std::time::Instant::now();
    let mut summary = ExportSummary {
        bags: bags.len(),
        ..ExportSummary::default()
    };
    let mut recordings = Vec::new();
    for bag in bags {
        recordings.push(read_recording(bag, &mut summary, opts.cameras)?);
    }
    // Features: the required inputs; fingertip forces and views when every bag has them.
    for rec in &recordings {
        let required = match opts.action {
            ActionSource::Operator => vec![
                (Input::Arm, rec.arm.is_empty()),
                (Input::Hand, rec.hand.is_empty()),
                (Input::Wrist, rec.wrist.is_empty()),
                (Input::Pedals, rec.pedals.is_empty()),
                (Input::Fingers, rec.fingers.is_empty()),
            ],
            ActionSource::Robot => vec![
                (Input::Arm, rec.arm.is_empty()),
                (Input::Hand, rec.hand.is_empty()),
                (Input::ArmCommand, rec.arm_command.is_empty()),
                (Input::HandCommand, rec.hand_command.is_empty()),
            ],
        };
        for (input, empty) in required {
            if empty {
                return Err(DatasetError::Bag(format!(
                    "{}: no usable message of {} ({}){}",
                    rec.name,
                    input.topic(),
                    input.name(),
                    match summary.rejected.get(&input.topic()) {
                        Some(n) => format!(", {n} refused"),
                        None => String::new(),
                    }
                )));
            }
        }
    }
    let with_forces = recordings.iter().all(|r| !r.forces.is_empty());
    if !with_forces {
        summary.inputs_absent.push(Input::Forces.topic());
    }
    let mut view_keys: Vec<usize> = Vec::new();
    for i in 0..VIEWS.len() {
        let sizes: BTreeSet<_> = recordings
            .iter()
            .map(|r| r.view_info[i].map(|v| (v.width, v.height, v.pix_fmt)))
            .collect();
        let present = opts.cameras && recordings.iter().all(|r| !r.views[i].is_empty());
        if present && sizes.len() == 1 {
            view_keys.push(i);
        } else if present {
            return Err(DatasetError::Video(format!(
                "{}: the bags' views differ in size ({sizes:?}); export them separately",
                Input::View(i).topic()
            )));
        } else if opts.cameras {
            summary.inputs_absent.push(Input::View(i).topic());
        }
    }
    let mut inputs = vec![Input::Arm, Input::Hand];
    if with_forces {
        inputs.push(Input::Forces);
    }
    match opts.action {
        ActionSource::Operator => inputs.extend([Input::Wrist, Input::Pedals, Input::Fingers]),
        ActionSource::Robot => inputs.extend([Input::ArmCommand, Input::HandCommand]),
    }
    inputs.extend(view_keys.iter().map(|&i| Input::View(i)));
    let ages: Vec<i64> = inputs.iter().map(|&i| max_age_ns(i, opts)).collect();
    let task = opts
        .task
        .clone()
        .unwrap_or_else(|| default_task(opts.episodes).to_owned());
    summary.tasks = vec![task.clone()];

    std::fs::create_dir_all(out.join("meta")).map_err(|e| DatasetError::io(out, e))?;
    let mut videos: Vec<VideoOut> = view_keys
        .iter()
        .map(|&i| VideoOut {
            key: VIEWS[i].1,
            index: FileIndex::default(),
            writer: None,
            info: recordings.first().and_then(|r| r.view_info[i]),
            stats: ImageStats::default(),
        })
        .collect();
    let mut frames = Frames {
        action_width: opts.action.width(),
        ..Frames::default()
    };
    let mut all_numeric = NumericStats::default();
    let mut episodes: Vec<EpisodeRow> = Vec::new();
    let mut data_index = FileIndex::default();
    let mut data_rows_before_file = 0usize;
    let row_bytes = 4 * (24 + 5 + opts.action.width() + inputs.len()) + 4 + 8 * 4;
    let min_frames = ((opts.min_episode_s * f64::from(opts.fps)).ceil() as usize).max(1);
    let frame_period_s = 1.0 / f64::from(opts.fps);

    for rec in &recordings {
        let intervals = match opts.episodes {
            EpisodeSource::Clutch => clutch_intervals(&rec.pedals),
            EpisodeSource::Job => job_interval(rec)?,
            EpisodeSource::Whole => whole_interval(
                rec,
                &[&rec.arm, &rec.hand, &rec.wrist, &rec.pedals, &rec.fingers],
            ),
        };
        summary.intervals += intervals.len();
        for interval in intervals {
            let n = u64::try_from(
                (i128::from(interval.end - interval.start) * i128::from(opts.fps))
                    .div_euclid(1_000_000_000),
            )
            .unwrap_or(0);
            // Per frame: the index of each input's message, or None.
            let mut picks: Vec<Vec<Option<usize>>> = Vec::with_capacity(n as usize);
            let mut complete = Vec::with_capacity(n as usize);
            let mut frame_ages: Vec<Vec<f32>> = Vec::with_capacity(n as usize);
            for k in 0..n {
                let t = frame_time_ns(interval.start, k, opts.fps);
                let mut row = Vec::with_capacity(inputs.len());
                let mut age_row = Vec::with_capacity(inputs.len());
                for (j, &input) in inputs.iter().enumerate() {
                    let stamps = match input {
                        Input::Arm => rec.arm.stamps(),
                        Input::Hand => rec.hand.stamps(),
                        Input::Forces => rec.forces.stamps(),
                        Input::Wrist => rec.wrist.stamps(),
                        Input::Pedals => rec.pedals.stamps(),
                        Input::Fingers => rec.fingers.stamps(),
                        Input::ArmCommand => rec.arm_command.stamps(),
                        Input::HandCommand => rec.hand_command.stamps(),
                        Input::View(i) => rec.views[i].stamps(),
                    };
                    let pick = newest_at(stamps, t, ages[j]);
                    age_row.push(pick.map_or(f32::NAN, |i| (t - stamps[i]) as f32 / 1e6));
                    row.push(pick);
                }
                let ok = row.iter().all(Option::is_some);
                if !ok {
                    summary.frames_missing += 1;
                    for (j, p) in row.iter().enumerate() {
                        if p.is_none() {
                            *summary
                                .frames_missing_input
                                .entry(inputs[j].name().to_owned())
                                .or_default() += 1;
                        }
                    }
                }
                complete.push(ok);
                picks.push(row);
                frame_ages.push(age_row);
            }
            let runs = complete_runs(&complete, min_frames);
            let complete_frames = complete.iter().filter(|&&c| c).count();
            let kept: usize = runs.iter().map(|(a, b)| b - a).sum();
            summary.frames_in_short_runs += (complete_frames - kept) as u64;
            if runs.len() > 1 {
                summary.intervals_cut += 1;
            }
            for (a, b) in runs {
                // Roll the data file at an episode boundary.
                if (frames.rows() - data_rows_before_file) * row_bytes
                    >= (opts.data_file_mb * 1024.0 * 1024.0) as usize
                {
                    summary.bytes_written += flush_data(
                        out,
                        data_index,
                        &frames,
                        data_rows_before_file,
                        with_forces,
                        &inputs,
                    )?;
                    data_rows_before_file = frames.rows();
                    data_index = data_index.next();
                }
                let episode = episodes.len() as i64;
                let from_index = frames.rows() as i64;
                let mut video_rows = Vec::new();
                for (v, &view) in videos.iter_mut().zip(&view_keys) {
                    let limit = (opts.video_file_mb * 1024.0 * 1024.0) as u64;
                    if v.writer.as_ref().is_some_and(|w| w.bytes() >= limit) {
                        if let Some(w) = v.writer.take() {
                            w.finish()?;
                        }
                        v.index = v.index.next();
                    }
                    if v.writer.is_none() {
                        let path = v.index.path(out, &format!("videos/{}", v.key), "mp4");
                        if let Some(dir) = path.parent() {
                            std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, e))?;
                        }
                        v.writer = Some(MjpegMp4Writer::create(&path, opts.fps)?);
                    }
                    let Some(w) = v.writer.as_mut() else {
                        continue;
                    };
                    let from = w.frames() as f64 * frame_period_s;
                    let column = inputs
                        .iter()
                        .position(|&i| i == Input::View(view))
                        .unwrap_or(0);
                    let stride = ((b - a) / STATS_FRAMES_PER_EPISODE).max(1);
                    for (k, row) in picks[a..b].iter().enumerate() {
                        let Some(i) = row[column] else { continue };
                        let jpeg = &rec.views[view].values()[i];
                        w.push(jpeg)?;
                        summary.video_frames += 1;
                        if k % stride == 0 {
                            v.stats.add_jpeg(jpeg);
                        }
                    }
                    let to = w.frames() as f64 * frame_period_s;
                    video_rows.push(((v.index.chunk, v.index.file), from, to));
                }
                for (k, row) in picks[a..b].iter().enumerate() {
                    let get = |input: Input| {
                        inputs
                            .iter()
                            .position(|&i| i == input)
                            .and_then(|c| row[c])
                            .unwrap_or(0)
                    };
                    let state_start = frames.state.len();
                    frames
                        .state
                        .extend_from_slice(&rec.arm.values()[get(Input::Arm)]);
                    frames
                        .state
                        .extend_from_slice(&rec.hand.values()[get(Input::Hand)]);
                    if with_forces {
                        frames
                            .forces
                            .extend_from_slice(&rec.forces.values()[get(Input::Forces)]);
                    }
                    let action_start = frames.action.len();
                    match opts.action {
                        ActionSource::Operator => {
                            frames
                                .action
                                .extend_from_slice(&rec.wrist.values()[get(Input::Wrist)]);
                            let p = rec.pedals.values()[get(Input::Pedals)];
                            frames.action.extend_from_slice(&[
                                f32::from(u8::from(p.clutch)),
                                f32::from(u8::from(p.enable)),
                                p.scale,
                            ]);
                            frames
                                .action
                                .extend_from_slice(&rec.fingers.values()[get(Input::Fingers)]);
                        }
                        ActionSource::Robot => {
                            frames.action.extend_from_slice(
                                &rec.arm_command.values()[get(Input::ArmCommand)],
                            );
                            frames.action.extend_from_slice(
                                &rec.hand_command.values()[get(Input::HandCommand)],
                            );
                        }
                    }
                    frames.ages.extend_from_slice(&frame_ages[a + k]);
                    all_numeric.add("observation.state", &frames.state[state_start..]);
                    all_numeric.add("action", &frames.action[action_start..]);
                    if with_forces {
                        let f = frames.forces.len();
                        all_numeric.add("observation.fingertip_forces", &frames.forces[f - 5..]);
                    }
                    let g = frames.ages.len();
                    all_numeric.add("source_age_ms", &frames.ages[g - inputs.len()..]);
                    let ts = (k as f64 * frame_period_s) as f32;
                    let index = frames.rows() as i64;
                    frames.timestamp.push(ts);
                    frames.frame_index.push(k as i64);
                    frames.episode_index.push(episode);
                    frames.index.push(index);
                    frames.task_index.push(0);
                    all_numeric.add("timestamp", &[ts]);
                    all_numeric.add("frame_index", &[k as f32]);
                    all_numeric.add("episode_index", &[episode as f32]);
                    all_numeric.add("index", &[index as f32]);
                    all_numeric.add("task_index", &[0.0]);
                }
                episodes.push(EpisodeRow {
                    index: episode,
                    task: task.clone(),
                    length: (b - a) as i64,
                    data_file: (data_index.chunk, data_index.file),
                    from_index,
                    to_index: frames.rows() as i64,
                    videos: video_rows,
                    start_ns: frame_time_ns(interval.start, a as u64, opts.fps),
                    source: interval.outcome.clone(),
                });
            }
        }
    }
    if episodes.is_empty() {
        return Err(DatasetError::Config(format!(
            "no episode to export: {} interval(s) found by {:?}, {} frame(s) missing an input ({:?}), {} in runs shorter than {} s",
            summary.intervals,
            opts.episodes,
            summary.frames_missing,
            summary.frames_missing_input,
            summary.frames_in_short_runs,
            opts.min_episode_s
        )));
    }
    summary.bytes_written += flush_data(
        out,
        data_index,
        &frames,
        data_rows_before_file,
        with_forces,
        &inputs,
    )?;
    for v in &mut videos {
        if let Some(w) = v.writer.take() {
            w.finish()?;
        }
    }
    summary.episodes = episodes.len();
    summary.frames = frames.rows();

    // Episodes table.
    let ep_path = FileIndex::default().path(out, "meta/episodes", "parquet");
    if let Some(dir) = ep_path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, e))?;
    }
    let mut cols = vec![
        Column::new(
            "episode_index",
            Values::I64(episodes.iter().map(|e| e.index).collect()),
        ),
        Column::new(
            "tasks",
            Values::StrList(episodes.iter().map(|e| vec![e.task.clone()]).collect()),
        ),
        Column::new(
            "length",
            Values::I64(episodes.iter().map(|e| e.length).collect()),
        ),
        Column::new(
            "data/chunk_index",
            Values::I64(episodes.iter().map(|e| e.data_file.0 as i64).collect()),
        ),
        Column::new(
            "data/file_index",
            Values::I64(episodes.iter().map(|e| e.data_file.1 as i64).collect()),
        ),
        Column::new(
            "dataset_from_index",
            Values::I64(episodes.iter().map(|e| e.from_index).collect()),
        ),
        Column::new(
            "dataset_to_index",
            Values::I64(episodes.iter().map(|e| e.to_index).collect()),
        ),
    ];
    for (j, v) in videos.iter().enumerate() {
        let key = v.key;
        cols.push(Column::new(
            format!("videos/{key}/chunk_index"),
            Values::I64(episodes.iter().map(|e| e.videos[j].0.0 as i64).collect()),
        ));
        cols.push(Column::new(
            format!("videos/{key}/file_index"),
            Values::I64(episodes.iter().map(|e| e.videos[j].0.1 as i64).collect()),
        ));
        cols.push(Column::new(
            format!("videos/{key}/from_timestamp"),
            Values::F64(episodes.iter().map(|e| e.videos[j].1).collect()),
        ));
        cols.push(Column::new(
            format!("videos/{key}/to_timestamp"),
            Values::F64(episodes.iter().map(|e| e.videos[j].2).collect()),
        ));
    }
    cols.extend([
        Column::new(
            "meta/episodes/chunk_index",
            Values::I64(vec![0; episodes.len()]),
        ),
        Column::new(
            "meta/episodes/file_index",
            Values::I64(vec![0; episodes.len()]),
        ),
        Column::new(
            "teleop/start_time_ns",
            Values::I64(episodes.iter().map(|e| e.start_ns).collect()),
        ),
        Column::new(
            "teleop/source",
            Values::Str(episodes.iter().map(|e| e.source.clone()).collect()),
        ),
    ]);
    summary.bytes_written += write_table(&ep_path, &cols, Vec::new())?;

    // Tasks table: the task text is the (pandas) index.
    let pandas = json!({
        "index_columns": ["task"],
        "column_indexes": [],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64", "metadata": null},
            {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": null}
        ],
        "creator": {"library": "teleop", "version": env!("CARGO_PKG_VERSION")},
        "pandas_version": "2.2.0"
    });
    summary.bytes_written += write_table(
        &out.join("meta/tasks.parquet"),
        &[
            Column::new("task_index", Values::I64(vec![0])),
            Column::new("task", Values::Str(vec![task.clone()])),
        ],
        vec![("pandas".to_owned(), pandas.to_string())],
    )?;

    // info.json and stats.json.
    let mut features = serde_json::Map::new();
    let names = |v: Vec<String>| json!(v);
    let state_names: Vec<String> = PR2_ARM_JOINTS
        .iter()
        .chain(SHADOW_FINGER_JOINTS.iter())
        .map(|s| (*s).to_owned())
        .collect();
    features.insert(
        "observation.state".into(),
        json!({"dtype": "float32", "shape": [24], "names": names(state_names)}),
    );
    if with_forces {
        features.insert(
            "observation.fingertip_forces".into(),
            json!({"dtype": "float32", "shape": [5], "names": names(FINGERTIPS.iter().map(|f| format!("{f}_force_n")).collect())}),
        );
    }
    let action_names: Vec<String> = match opts.action {
        ActionSource::Operator => [
            "wrist_x_m",
            "wrist_y_m",
            "wrist_z_m",
            "wrist_qx",
            "wrist_qy",
            "wrist_qz",
            "wrist_qw",
            "clutch",
            "enable",
            "motion_scale",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .chain(SHADOW_FINGER_JOINTS.iter().map(|j| format!("{j}_target")))
        .collect(),
        ActionSource::Robot => PR2_ARM_JOINTS
            .iter()
            .map(|j| format!("{j}_velocity_cmd"))
            .chain(
                SHADOW_FINGER_JOINTS
                    .iter()
                    .map(|j| format!("{j}_position_cmd")),
            )
            .collect(),
    };
    features.insert(
        "action".into(),
        json!({"dtype": "float32", "shape": [opts.action.width()], "names": names(action_names)}),
    );
    features.insert(
        "source_age_ms".into(),
        json!({"dtype": "float32", "shape": [inputs.len()], "names": names(inputs.iter().map(|i| i.name().to_owned()).collect())}),
    );
    for v in &videos {
        let info = v.info.unwrap_or(JpegInfo {
            width: 0,
            height: 0,
            components: 3,
            pix_fmt: "other",
        });
        let channels = if info.components == 1 { 1 } else { 3 };
        features.insert(
            v.key.into(),
            json!({
                "dtype": "video",
                "shape": [info.height, info.width, channels],
                "names": ["height", "width", "channels"],
                "info": {
                    "video.height": info.height,
                    "video.width": info.width,
                    "video.codec": "mjpeg",
                    "video.pix_fmt": info.pix_fmt,
                    "video.is_depth_map": false,
                    "video.fps": opts.fps,
                    "video.channels": channels,
                    "has_audio": false
                }
            }),
        );
    }
    for (name, dtype) in [
        ("timestamp", "float32"),
        ("frame_index", "int64"),
        ("episode_index", "int64"),
        ("index", "int64"),
        ("task_index", "int64"),
    ] {
        features.insert(
            name.into(),
            json!({"dtype": dtype, "shape": [1], "names": null}),
        );
    }
    let info = json!({
        "codebase_version": CODEBASE_VERSION,
        "robot_type": opts.robot_type,
        "total_episodes": episodes.len(),
        "total_frames": frames.rows(),
        "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": opts.data_file_mb,
        "video_files_size_in_mb": opts.video_file_mb,
        "fps": opts.fps,
        "splits": {"train": format!("0:{}", episodes.len())},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": if videos.is_empty() { serde_json::Value::Null } else { json!("videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4") },
        "features": features,
    });
    summary.bytes_written += write_json(&out.join("meta/info.json"), &info)?;
    let mut stats = all_numeric.to_json();
    for v in &videos {
        if let Some(s) = v.stats.to_json() {
            stats.insert(v.key.to_owned(), s);
        }
    }
    summary.bytes_written += write_json(
        &out.join("meta/stats.json"),
        &serde_json::Value::Object(stats),
    )?;
    for v in &videos {
        let dir = out.join("videos").join(v.key);
        summary.bytes_written += dir_bytes(&dir);
    }
    summary.seconds = began.elapsed().as_secs_f64();
    Ok(summary)
}

/// Writes rows `from..` of `frames` as the data file `index`.
fn flush_data(
    out: &Path,
    index: FileIndex,
    frames: &Frames,
    from: usize,
    with_forces: bool,
    inputs: &[Input],
) -> Result<u64, DatasetError> {
    let rows = frames.rows() - from;
    if rows == 0 {
        return Ok(0);
    }
    let action_width = frames.action_width;
    let path = index.path(out, "data", "parquet");
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, e))?;
    }
    let list = |v: &[f32], width: usize| Values::F32List {
        width,
        values: v[from * width..].to_vec(),
    };
    let mut cols = vec![Column::new("observation.state", list(&frames.state, 24))];
    if with_forces {
        cols.push(Column::new(
            "observation.fingertip_forces",
            list(&frames.forces, 5),
        ));
    }
    cols.push(Column::new("action", list(&frames.action, action_width)));
    cols.push(Column::new(
        "source_age_ms",
        list(&frames.ages, inputs.len()),
    ));
    cols.extend([
        Column::new("timestamp", Values::F32(frames.timestamp[from..].to_vec())),
        Column::new(
            "frame_index",
            Values::I64(frames.frame_index[from..].to_vec()),
        ),
        Column::new(
            "episode_index",
            Values::I64(frames.episode_index[from..].to_vec()),
        ),
        Column::new("index", Values::I64(frames.index[from..].to_vec())),
        Column::new(
            "task_index",
            Values::I64(frames.task_index[from..].to_vec()),
        ),
    ]);
    write_table(&path, &cols, Vec::new())
}

fn write_json(path: &Path, value: &serde_json::Value) -> Result<u64, DatasetError> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| DatasetError::Config(format!("{}: {e}", path.display())))?;
    std::fs::write(path, &text).map_err(|e| DatasetError::io(path, e))?;
    Ok(text.len() as u64)
}

fn dir_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if let Ok(m) = e.metadata() {
                total += m.len();
            }
        }
    }
    total
}

/// Frames per episode and view decoded for the image statistics (LeRobot samples its
/// image statistics too).
const STATS_FRAMES_PER_EPISODE: usize = 20;

/// Per-feature min, max, mean, std, count over every frame.
#[derive(Debug, Default)]
struct NumericStats {
    features: BTreeMap<&'static str, Moments>,
}

#[derive(Debug, Default, Clone)]
struct Moments {
    n: u64,
    min: Vec<f64>,
    max: Vec<f64>,
    sum: Vec<f64>,
    sum_sq: Vec<f64>,
}

impl Moments {
    fn add(&mut self, v: &[f32]) {
        if self.min.is_empty() {
            self.min = vec![f64::INFINITY; v.len()];
            self.max = vec![f64::NEG_INFINITY; v.len()];
            self.sum = vec![0.0; v.len()];
            self.sum_sq = vec![0.0; v.len()];
        }
        for (i, &x) in v.iter().enumerate().take(self.min.len()) {
            let x = f64::from(x);
            self.min[i] = self.min[i].min(x);
            self.max[i] = self.max[i].max(x);
            self.sum[i] += x;
            self.sum_sq[i] += x * x;
        }
        self.n += 1;
    }
    fn to_json(&self, shape: &dyn Fn(Vec<f64>) -> serde_json::Value) -> serde_json::Value {
        let n = self.n.max(1) as f64;
        let mean: Vec<f64> = self.sum.iter().map(|s| s / n).collect();
        let std: Vec<f64> = self
            .sum_sq
            .iter()
            .zip(&mean)
            .map(|(s, m)| (s / n - m * m).max(0.0).sqrt())
            .collect();
        json!({
            "min": shape(self.min.clone()),
            "max": shape(self.max.clone()),
            "mean": shape(mean),
            "std": shape(std),
            "count": [self.n],
        })
    }
}

impl NumericStats {
    fn add(&mut self, key: &'static str, v: &[f32]) {
        self.features.entry(key).or_default().add(v);
    }
    fn to_json(&self) -> serde_json::Map<String, serde_json::Value> {
        self.features
            .iter()
            .map(|(k, m)| ((*k).to_owned(), m.to_json(&|v| json!(v))))
            .collect()
    }
}

/// Per-channel statistics of sampled views, values in 0..1 (LeRobot's image stats have
/// shape (3, 1, 1)).
#[derive(Debug, Default)]
struct ImageStats {
    moments: Moments,
    frames: u64,
}

impl ImageStats {
    fn add_jpeg(&mut self, jpeg: &[u8]) {
        let Ok(img) = image::load_from_memory_with_format(jpeg, image::ImageFormat::Jpeg) else {
            return;
        };
        let rgb = img.to_rgb8();
        // Every 4th pixel in each direction is plenty for channel statistics.
        for y in (0..rgb.height()).step_by(4) {
            for x in (0..rgb.width()).step_by(4) {
                let p = rgb.get_pixel(x, y).0;
                self.moments.add(&[
                    f32::from(p[0]) / 255.0,
                    f32::from(p[1]) / 255.0,
                    f32::from(p[2]) / 255.0,
                ]);
            }
        }
        self.frames += 1;
    }
    fn to_json(&self) -> Option<serde_json::Value> {
        if self.frames == 0 {
            return None;
        }
        let mut v = self
            .moments
            .to_json(&|c| json!(c.into_iter().map(|x| vec![vec![x]]).collect::<Vec<_>>()));
        v["count"] = json!([self.frames]);
        Some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pedals(samples: &[(i64, bool, bool)]) -> Stream<Pedals> {
        Stream::new(
            samples
                .iter()
                .map(|&(t, clutch, enable)| {
                    (
                        t,
                        Pedals {
                            clutch,
                            enable,
                            scale: 1.0,
                        },
                    )
                })
                .collect(),
        )
    }

    #[test]
    fn clutch_engagements_need_the_enable_switch_too() {
        let p = pedals(&[
            (0, false, true),
            (10, true, false), // clutch without enable: not engaged
            (20, true, true),
            (30, true, true),
            (40, false, true),
            (50, true, true),
            (60, true, true),
        ]);
        let iv = clutch_intervals(&p);
        assert_eq!(iv.len(), 2);
        assert_eq!((iv[0].start, iv[0].end), (20, 40));
        assert_eq!((iv[1].start, iv[1].end), (50, 60));
        assert!(iv[1].outcome.contains("ended while clutched"));
    }

    #[test]
    fn the_jobs_verdict_is_read_from_the_counters() {
        let status = |names: &[(&str, u64)]| NodeStatus {
            node_name: "remote_sim".into(),
            counter_names: names.iter().map(|n| n.0.to_owned()).collect(),
            counter_values: names.iter().map(|n| n.1).collect(),
            ..NodeStatus::default()
        };
        assert_eq!(job_standing(&status(&[("x", 1)])), None);
        assert_eq!(
            job_standing(&status(&[("job.lifted", 1), ("job.succeeded", 0)])),
            Some(JobStanding { verdict: None })
        );
        assert_eq!(
            job_standing(&status(&[("job.lifted", 1), ("job.succeeded", 1)]))
                .and_then(|s| s.verdict),
            Some("succeeded".to_owned())
        );
        assert_eq!(
            job_standing(&status(&[("job.lifted", 0), ("job.failed.timed_out", 1)]))
                .and_then(|s| s.verdict),
            Some("failed: timed_out".to_owned())
        );
    }

    #[test]
    fn options_out_of_range_are_named() {
        for (opts, field) in [
            (
                ExportOptions {
                    fps: 0,
                    ..Default::default()
                },
                "fps",
            ),
            (
                ExportOptions {
                    max_age_s: Some(f64::NAN),
                    ..Default::default()
                },
                "max_age_s",
            ),
            (
                ExportOptions {
                    min_episode_s: -1.0,
                    ..Default::default()
                },
                "min_episode_s",
            ),
            (
                ExportOptions {
                    video_file_mb: 0.0,
                    ..Default::default()
                },
                "video_file_mb",
            ),
            (
                ExportOptions {
                    task: Some(" ".into()),
                    ..Default::default()
                },
                "task",
            ),
        ] {
            let err = opts.validate().expect_err(field);
            assert!(err.to_string().contains(field), "{err}");
        }
        assert!("sometimes".parse::<EpisodeSource>().is_err());
        assert_eq!(
            "job".parse::<EpisodeSource>().ok(),
            Some(EpisodeSource::Job)
        );
    }

    #[test]
    fn joints_are_taken_by_name_and_missing_ones_named() {
        let js = JointState {
            name: vec!["b".into(), "a".into()],
            position: vec![2.0, 1.0],
            ..JointState::default()
        };
        assert_eq!(positions_by_name(&js, &["a", "b"]), Ok(vec![1.0, 2.0]));
        let err = positions_by_name(&js, &["a", "c"]).expect_err("missing");
        assert!(err.contains("joint c missing"), "{err}");
        let nan = JointState {
            position: vec![f64::NAN, 1.0],
            ..js.clone()
        };
        assert!(positions_by_name(&nan, &["b"]).is_err());
    }
}
