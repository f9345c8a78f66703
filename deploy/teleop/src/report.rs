//! The end-of-run report of `teleop launch`: what the closed loop did, measured against
//! the simulation's ground truth, from what crossed the bus during the run.
//!
//! * **Latency per stage**, p50/p99 (receive time at the launcher minus the sample's
//!   header stamp, which every stage sets to the capture time of what it carries):
//!   motion capture -> wrist pose, camera pose, depth frame -> finger targets, robot
//!   feedback; plus the stages hand inference measures itself (from its status).
//! * **UR5 camera tracking error**: the camera's pose (forward kinematics of the
//!   measured UR5 joints, as the camera arm publishes it) against the goal the camera
//!   arm aims for, computed from the operator's TRUE hand pose at the same time.
//! * **Hand in view**: the fraction of depth frames in which every keypoint of the
//!   operator's hand was inside the image (from the simulator's ground truth).
//! * **PR2 end-effector error** against the scaled operator motion: while the clutch is
//!   held, the PR2 palm's displacement since the press against the true hand's
//!   displacement times the motion scale (base-aligned relative control).
//! * **Hand joint error**: each published finger target against the true fingers
//!   retargeted to the Shadow hand for the same depth frame (paired by stamp).
//! * **Contact forces**: the fingertip sensors' readings.
//! * **Goals**: the local-site goals judged on these figures ([`RunReport::judge_goals`]).

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use hdrhistogram::Histogram;
use nalgebra::{Isometry3, Translation3, Vector3};
use serde::Serialize;
use teleop_bus::{Bus, Subscriber};
use teleop_hardware::wire;
use teleop_interfaces::joints::PR2_ARM_JOINTS;
use teleop_interfaces::topics;
use teleop_kinematics::FixedChain;
use teleop_local_site::camera_arm::CameraArmConfig;
use teleop_msgs::{
    FingertipPressures, JointState, Lifecycle, NodeStatus, OperatorInput, Pose, PoseStamped,
};

/// One latency stage.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct StageLatency {
    pub stage: String,
    pub samples: u64,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
}

/// Summary of a series of errors.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Default)]
pub struct ErrorSummary {
    pub samples: usize,
    pub mean: f64,
    pub p50: f64,
    pub p99: f64,
    pub max: f64,
}

impl ErrorSummary {
    fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
        Self {
            samples: v.len(),
            mean: v.iter().sum::<f64>() / v.len() as f64,
            p50: at(0.5),
            p99: at(0.99),
            max: v[v.len() - 1],
        }
    }
}

/// The closed loop's hand joint error may be at most this many times the model's
/// offline test error (local-site goal).
pub const HAND_ERROR_FACTOR: f64 = 1.2;
/// Depth frame -> finger targets received at the robot site, p99, ms (local-site goal,
/// judged in real time only).
pub const LATENCY_GOAL_P99_MS: f64 = 10.0;

/// One of the local-site goals, judged on this run.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GoalCheck {
    /// What the goal asks.
    pub goal: String,
    /// What this run measured.
    pub measured: String,
    /// Met (`true`), missed (`false`), or not judged on this run (`None`: nothing to
    /// judge it on, or not in real time; `measured` says why).
    pub met: Option<bool>,
}

/// How the robot world's job ended, as `remote_sim` judged it.
#[derive(Debug, Clone, Serialize, PartialEq, Default)]
pub struct JobOutcome {
    pub lifted: bool,
    pub succeeded: bool,
    /// From the robot's first motion to its return to the starting pose, s.
    pub completion_s: Option<f64>,
    /// `fell_off_table` or `timed_out`; `None` while running or after a success.
    pub failure: Option<String>,
    /// Observations the judge refused (non-finite, missing object).
    pub judge_errors: u64,
}

impl JobOutcome {
    /// From the simulator's final status counters, if it judged a job.
    #[must_use]
    pub fn from_counters(counter: impl Fn(&str) -> Option<u64>) -> Option<Self> {
        use teleop_interfaces::status::job;
        let succeeded = counter(job::SUCCEEDED)? > 0;
        let failure = job::FAILURES
            .into_iter()
            .find(|f| counter(&format!("{}{f}", job::FAILED_PREFIX)).unwrap_or(0) > 0)
            .map(str::to_owned);
        Some(Self {
            lifted: counter(job::LIFTED).unwrap_or(0) > 0,
            succeeded,
            completion_s: succeeded
                .then(|| counter(job::COMPLETION_MS).map(|ms| ms as f64 / 1e3))
                .flatten(),
            failure,
            judge_errors: counter(job::JUDGE_ERRORS).unwrap_or(0),
        })
    }

    /// One line for the text report.
    #[must_use]
    pub fn describe(&self) -> String {
        let what = match (&self.failure, self.completion_s) {
            (Some(f), _) => format!("failed ({})", f.replace('_', " ")),
            (None, Some(t)) if self.succeeded => format!("succeeded in {t:.1} s"),
            _ if self.lifted => "not finished (the object was lifted)".to_owned(),
            _ => "not finished (the object was never lifted)".to_owned(),
        };
        if self.judge_errors > 0 {
            format!("{what}; {} observations refused", self.judge_errors)
        } else {
            what
        }
    }
}

/// What the operator who watches the display did (`local_sim`'s `operator.*`
/// counters), if it ran.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct OperatorOutcome {
    /// The phase it ended in (`done`, `gave_up`, or where it was stopped).
    pub phase: String,
    pub grasp_attempts: u64,
    pub submovements: u64,
    /// Goals it went on from without reaching them (after its corrections).
    pub goals_not_reached: u64,
    /// Camera views and robot states it perceived.
    pub views_received: u64,
    pub scene_percepts: u64,
    pub robot_percepts: u64,
    /// Largest distance between the object as the operator saw it and as it was at
    /// the newest ground truth received, mm.
    pub max_perceived_error_mm: u64,
    /// Feedback it could not use (missing joints, non-finite values).
    pub bad_input: u64,
}

impl OperatorOutcome {
    /// From the operator-site simulator's final status counters.
    #[must_use]
    pub fn from_counters(counter: impl Fn(&str) -> Option<u64>) -> Option<Self> {
        let phase = counter("operator.phase")?;
        let phase = teleop_sim::operator_site::watching::Phase::ALL
            .get(usize::try_from(phase).unwrap_or(usize::MAX))
            .map_or_else(|| format!("unknown ({phase})"), |p| p.name().to_owned());
        let c = |n: &str| counter(n).unwrap_or(0);
        Some(Self {
            phase,
            grasp_attempts: c("operator.grasp_attempts"),
            submovements: c("operator.submovements"),
            goals_not_reached: c("operator.goals_not_reached"),
            views_received: c("operator.views_received"),
            scene_percepts: c("operator.scene_percepts"),
            robot_percepts: c("operator.robot_percepts"),
            max_perceived_error_mm: c("operator.max_perceived_error_mm"),
            bad_input: c("operator.bad_input"),
        })
    }

    /// One line for the text report.
    #[must_use]
    pub fn describe(&self) -> String {
        format!(
            "ended in phase {}, {} grasp attempt(s), {} submovements ({} goals left unreached); saw {} of {} views received, the object up to {} mm from where it was; {} feedback messages unusable",
            self.phase,
            self.grasp_attempts,
            self.submovements,
            self.goals_not_reached,
            self.scene_percepts,
            self.views_received,
            self.max_perceived_error_mm,
            self.bad_input
        )
    }
}

/// The report.
#[derive(Debug, Clone, Serialize, PartialEq, Default)]
pub struct RunReport {
    /// Simulated seconds (wall seconds x `time_scale`).
    pub duration_s: f64,
    pub task: String,
    /// The emulated WAN between the sites (`teleop launch --wan`), if the run had one.
    pub wan: Option<String>,
    /// Simulated seconds per wall second (`--time-scale`; 1 = real time). Every time
    /// and latency in the report is in simulated time.
    pub time_scale: f64,
    /// `teleop launch --as-fast-as-possible`: what the pacer did (then `time_scale` is
    /// the run's mean rate).
    pub pacing: Option<crate::clock_pacer::PacingSummary>,
    /// The command that recorded it: `teleop launch` (the system it started) or
    /// `teleop report` (a system started elsewhere).
    pub recorded_by: String,
    pub latency: Vec<StageLatency>,
    /// Hand inference's own stage timings (its status counters), µs.
    pub hand_inference_stages_us: BTreeMap<String, u64>,
    /// The Shadow hand controller's own measurement (its status counters), µs: finger
    /// targets from their depth frame's capture to their arrival at the robot site.
    pub hand_controller_stages_us: BTreeMap<String, u64>,
    /// Camera position error against its goal, m.
    pub camera_position_error_m: ErrorSummary,
    /// Camera viewing-direction error against its goal, deg.
    pub camera_direction_error_deg: ErrorSummary,
    pub depth_frames: u64,
    pub frames_hand_fully_in_view: u64,
    pub fraction_hand_fully_in_view: f64,
    /// PR2 palm position error against the scaled operator motion while clutched, m.
    pub pr2_position_error_m: ErrorSummary,
    /// Mean absolute error per axis (x, y, z) while clutched, m (the thesis's L1).
    pub pr2_mean_abs_error_xyz_m: [f64; 3],
    /// The delay that best explains the PR2 error: the palm compared with the scaled
    /// operator motion this much earlier fits best (ms, searched 0-300 ms in 5 ms steps).
    pub pr2_best_fit_delay_ms: f64,
    /// The PR2 mean position error at that delay, m: what is left when the lag is taken
    /// out (the shape of the path, not its timing).
    pub pr2_error_at_best_delay_m: f64,
    /// The same for the camera against its goal.
    pub camera_best_fit_delay_ms: f64,
    pub camera_error_at_best_delay_m: f64,
    pub clutch_engagements: u64,
    /// Engagements measured from the references the arm controller took (its
    /// `arm.engaged_from_stamp_ns`), the others from the clutch press.
    pub arm_reference_engagements: u64,
    /// The PR2 error of the clutched samples in which the arm controller's newest status
    /// said it was Active (following the operator, not stopped), m: the tracking, apart
    /// from what the operator moved while a safety stop held the arm.
    pub pr2_following_error_m: ErrorSummary,
    /// Fraction of the clutched samples in which the arm was following (1 without a
    /// stop).
    pub pr2_fraction_following: f64,
    /// The PR2 arm controller's stops by reason (its `arm.stop.*` counters): a stale
    /// input or a lost site stops the arm, and the error above then grows.
    pub pr2_stops: BTreeMap<String, u64>,
    /// How often the simulated operator let go of the clutch and pressed it again on
    /// seeing a safety stop on the display (`local_sim`'s `operator.reclutches`); each
    /// press is one more of `clutch_engagements`.
    pub operator_reclutches: u64,
    /// The robot world's job, judged from ground truth by the simulator (`remote_sim`'s
    /// `job.*` counters; `None` when its scene has no job or it gave no final status).
    pub job: Option<JobOutcome>,
    /// The operator who watches the display, if it drove this run.
    pub operator: Option<OperatorOutcome>,
    pub finger_target_frames: usize,
    /// Mean absolute joint error per frame, rad.
    pub hand_joint_mean_error_rad: ErrorSummary,
    /// Fraction of frames whose largest joint error is within 0.1 / 0.2 rad.
    pub hand_frames_max_error_within_0_1_rad: f64,
    pub hand_frames_max_error_within_0_2_rad: f64,
    /// Largest and mean fingertip force per finger (ff, mf, rf, lf, th), N.
    pub fingertip_force_max_n: [f64; 5],
    pub fingertip_force_mean_n: [f64; 5],
    /// The hand model's mean joint error on its offline test set, rad, as the
    /// hand-inference node says it (from the evaluation beside the model), if known.
    pub hand_offline_test_error_rad: Option<f64>,
    /// The nodes that asked for real-time scheduling (`scheduling.realtime_priority`):
    /// what each asked for and got (0 = refused, normal time sharing), from their
    /// final status.
    pub realtime_scheduling: BTreeMap<String, RealtimeScheduling>,
    /// CPU (cores: 1.0 = one core busy throughout) and peak resident memory of each
    /// node's process over the run, sampled from `/proc` by the launcher (empty when
    /// the report was recorded from outside, `teleop report`).
    pub resources: BTreeMap<String, crate::proc_stat::ProcessUse>,
    /// The local-site goals judged on this run ([`RunReport::judge_goals`]).
    pub goals: Vec<GoalCheck>,
    /// Time series for the plots: (t, camera position error m).
    #[serde(skip)]
    pub camera_series: Vec<(f64, f64)>,
    /// (t, PR2 position error m).
    #[serde(skip)]
    pub pr2_series: Vec<(f64, f64)>,
    /// (t, hand joint mean error rad).
    #[serde(skip)]
    pub hand_series: Vec<(f64, f64)>,
    /// Per stage, sorted latencies (ms), for the CDF plot.
    #[serde(skip)]
    pub latency_samples: Vec<(String, Vec<f64>)>,
}

/// A node's real-time scheduling as its status says it.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
pub struct RealtimeScheduling {
    pub requested: u64,
    /// 0: refused (the process may not), normal time sharing.
    pub granted: u64,
}

/// The nodes whose status says they asked for real-time scheduling, with what they got.
fn realtime_scheduling(
    finals: &BTreeMap<String, NodeStatus>,
) -> BTreeMap<String, RealtimeScheduling> {
    finals
        .iter()
        .filter_map(|(node, s)| {
            let requested = s
                .counter("process.realtime_priority_requested")
                .filter(|&p| p > 0)?;
            let granted = s.counter("process.realtime_priority").unwrap_or(0);
            Some((node.clone(), RealtimeScheduling { requested, granted }))
        })
        .collect()
}

fn pose_of(p: &Pose) -> Option<Isometry3<f64>> {
    teleop_hardware::wire::checked_isometry(p, teleop_hardware::wire::POSE_QUATERNION_TOLERANCE)
        .ok()
}

fn secs(t: &teleop_msgs::Time) -> f64 {
    t.as_secs_f64()
}

/// A latency stage being recorded.
#[derive(Debug)]
struct Stage {
    name: &'static str,
    hist: Option<Histogram<u64>>,
    values_ms: Vec<f64>,
}

impl Stage {
    fn new(name: &'static str) -> Self {
        Self {
            name,
            hist: Histogram::new_with_bounds(1, 60_000_000, 3).ok(),
            values_ms: Vec::new(),
        }
    }
    fn add(&mut self, receive_s: f64, stamp_s: f64) {
        let us = ((receive_s - stamp_s) * 1e6).max(1.0);
        if let Some(h) = &mut self.hist {
            // Clamped into the histogram's range.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let _ = h.record((us as u64).clamp(1, 60_000_000));
        }
        if self.values_ms.len() < 200_000 {
            self.values_ms.push(us / 1000.0);
        }
    }
    fn summary(&self) -> StageLatency {
        let (n, p50, p99, max) = self.hist.as_ref().map_or((0, 0.0, 0.0, 0.0), |h| {
            (
                h.len(),
                h.value_at_quantile(0.5) as f64 / 1000.0,
                h.value_at_quantile(0.99) as f64 / 1000.0,
                h.max() as f64 / 1000.0,
            )
        });
        StageLatency {
            stage: self.name.to_owned(),
            samples: n,
            p50_ms: p50,
            p99_ms: p99,
            max_ms: max,
        }
    }
}

/// Clutch state of the relative control.
/// Delays tried by [`DelayFit`]: 0 to 300 ms in 5 ms steps.
const DELAY_STEPS: usize = 61;
const DELAY_STEP_S: f64 = 0.005;

/// Mean error of a series against its reference delayed by each of [`DELAY_STEPS`]
/// delays, to tell a lag from an error of shape.
#[derive(Debug, Clone)]
struct DelayFit {
    sums: [f64; DELAY_STEPS],
    counts: [usize; DELAY_STEPS],
}

impl Default for DelayFit {
    fn default() -> Self {
        Self {
            sums: [0.0; DELAY_STEPS],
            counts: [0; DELAY_STEPS],
        }
    }
}

impl DelayFit {
    /// Adds the error of one sample at every delay (`error(delay_s)`, `None` where the
    /// reference is not known).
    fn add(&mut self, mut error: impl FnMut(f64) -> Option<f64>) {
        for (i, (sum, n)) in self.sums.iter_mut().zip(&mut self.counts).enumerate() {
            if let Some(e) = error(i as f64 * DELAY_STEP_S) {
                *sum += e;
                *n += 1;
            }
        }
    }

    /// The delay with the smallest mean error (only delays seen for at least 90 % as
    /// many samples as the zero delay), and that mean: `(delay ms, mean)`.
    fn best(&self) -> Option<(f64, f64)> {
        let n0 = self.counts[0];
        if n0 == 0 {
            return None;
        }
        (0..DELAY_STEPS)
            .filter(|&i| self.counts[i] * 10 >= n0 * 9)
            .map(|i| {
                (
                    i as f64 * DELAY_STEP_S * 1e3,
                    self.sums[i] / self.counts[i] as f64,
                )
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

#[derive(Debug, Clone, Copy)]
struct Engaged {
    human_ref: Vector3<f64>,
    robot_ref: Option<Vector3<f64>>,
    scale: f64,
}

/// The pose at `t_s` in a time-ordered series (linear/spherical interpolation); a
/// time outside it only within 20 ms of its end.
fn truth_at(truth: &[(f64, Isometry3<f64>)], t_s: f64) -> Option<Isometry3<f64>> {
    let i = truth.partition_point(|(t, _)| *t < t_s);
    if i == 0 || i >= truth.len() {
        return truth
            .last()
            .filter(|(t, _)| (t - t_s).abs() < 0.02)
            .map(|(_, p)| *p);
    }
    let (t0, a) = truth[i - 1];
    let (t1, b) = truth[i];
    let s = ((t_s - t0) / (t1 - t0)).clamp(0.0, 1.0);
    Some(Isometry3::from_parts(
        Translation3::from(a.translation.vector.lerp(&b.translation.vector, s)),
        a.rotation.slerp(&b.rotation, s),
    ))
}

/// Collects the run from the bus.
#[derive(Debug)]
pub struct Recorder {
    start_s: f64,
    truth_pose: Subscriber<PoseStamped>,
    truth_joints: Subscriber<JointState>,
    targets: Subscriber<JointState>,
    camera: Subscriber<PoseStamped>,
    wrist: Subscriber<PoseStamped>,
    pr2: Subscriber<JointState>,
    input: Subscriber<OperatorInput>,
    tips: Subscriber<FingertipPressures>,
    pr2_chain: FixedChain<7>,
    camera_cfg: CameraArmConfig,
    /// True hand poses by time (node clock), the last 5 s.
    truth: Vec<(f64, Isometry3<f64>)>,
    /// True Shadow joints by capture stamp (ns), with the time they were put on the
    /// bus (just before their depth frame, s), the last few hundred frames.
    truth_joints_by_stamp: BTreeMap<i64, (Vec<f64>, f64)>,
    /// Finger targets waiting for their frame's truth: (stamp ns, stamp s, received s,
    /// joints).
    pending_targets: Vec<(i64, f64, f64, Vec<f64>)>,
    engaged: Option<Engaged>,
    stages: Vec<Stage>,
    report: RunReport,
    pr2_abs: [f64; 3],
    pr2_n: usize,
    pr2_errors: Vec<f64>,
    /// The clutched samples' errors while the arm controller was Active.
    pr2_following: Vec<f64>,
    /// Whether the arm controller's newest status says Active.
    arm_active: bool,
    /// The capture stamp of the wrist pose the arm's newest engagement took as its
    /// reference (its status counter), ns.
    arm_engaged_from_ns: Option<u64>,
    /// A new engagement the arm controller reported (its wrist pose's stamp, the
    /// status's stamp, s) not yet applied: the clutch press or the truth at that stamp
    /// had not been taken in yet (the statuses come in beside `poll`).
    pending_engagement: Option<(u64, f64)>,
    /// The newest PR2 palm positions by stamp, s (for the arm's reference at its
    /// engagement).
    recent_palms: std::collections::VecDeque<(f64, Vector3<f64>)>,
    pr2_delay: DelayFit,
    camera_delay: DelayFit,
    camera_pos: Vec<f64>,
    camera_dir: Vec<f64>,
    hand_errors: Vec<f64>,
    hand_within: [usize; 2],
    force_sum: [f64; 5],
    force_n: usize,
}

/// PR2 states kept for the arm's reference at an engagement (about 1 s at 100 Hz).
const RECENT_PALMS: usize = 128;
const STAGE_WRIST: usize = 0;
const STAGE_CAMERA: usize = 1;
const STAGE_TARGETS: usize = 2;
const STAGE_PR2: usize = 3;
const STAGE_TIPS: usize = 4;
const STAGE_FRAME_SENT_TARGETS: usize = 5;
/// The stage the latency goal is judged on.
const FRAME_ON_THE_BUS_TO_TARGETS: &str = "depth frame on the bus -> finger targets";
/// The same from the capture stamp (reported beside it).
const CAPTURE_TO_TARGETS: &str = "depth frame -> finger targets";

impl Recorder {
    /// Subscribes to everything the report needs; the camera is judged against the
    /// goal of `camera` (the camera arm's control settings the run's `camera_arm` ran
    /// with: its standoff and view direction).
    ///
    /// # Errors
    /// Bus declarations; the PR2 model.
    pub async fn new(
        bus: &Bus,
        task: &str,
        recorded_by: &str,
        camera: CameraArmConfig,
    ) -> anyhow::Result<Self> {
        Ok(Self {
            start_s: bus.now_s(),
            truth_pose: bus.subscriber(&topics::SIM_OPERATOR_HAND_POSE).await?,
            truth_joints: bus.subscriber(&topics::SIM_OPERATOR_SHADOW_JOINTS).await?,
            targets: bus.subscriber(&topics::HAND_JOINT_TARGETS).await?,
            camera: bus.subscriber(&topics::CAMERA_POSE).await?,
            wrist: bus.subscriber(&topics::WRIST_POSE).await?,
            pr2: bus.subscriber(&topics::PR2_JOINT_STATES).await?,
            input: bus.subscriber(&topics::OPERATOR_INPUT).await?,
            tips: bus.subscriber(&topics::FINGERTIP_PRESSURES).await?,
            pr2_chain: teleop_kinematics::robots::pr2_arm_chain()?,
            camera_cfg: camera,
            truth: Vec::new(),
            truth_joints_by_stamp: BTreeMap::new(),
            pending_targets: Vec::new(),
            engaged: None,
            stages: vec![
                Stage::new("motion capture -> wrist pose"),
                Stage::new("UR5 joints -> camera pose"),
                Stage::new(CAPTURE_TO_TARGETS),
                Stage::new("PR2 joints -> feedback"),
                Stage::new("fingertip sensors -> feedback"),
                Stage::new(FRAME_ON_THE_BUS_TO_TARGETS),
            ],
            report: RunReport {
                task: task.to_owned(),
                time_scale: bus.clock().rate(),
                recorded_by: recorded_by.to_owned(),
                ..RunReport::default()
            },
            pr2_abs: [0.0; 3],
            pr2_n: 0,
            pr2_errors: Vec::new(),
            pr2_following: Vec::new(),
            arm_active: false,
            arm_engaged_from_ns: None,
            pending_engagement: None,
            recent_palms: std::collections::VecDeque::new(),
            pr2_delay: DelayFit::default(),
            camera_delay: DelayFit::default(),
            camera_pos: Vec::new(),
            camera_dir: Vec::new(),
            hand_errors: Vec::new(),
            hand_within: [0; 2],
            force_sum: [0.0; 5],
            force_n: 0,
        })
    }

    /// The true hand pose at `t_s` (linear/spherical interpolation), if recorded.
    fn truth_at(&self, t_s: f64) -> Option<Isometry3<f64>> {
        truth_at(&self.truth, t_s)
    }

    /// Takes everything that arrived since the last call.
    pub fn poll(&mut self) {
        while let Some(r) = self.truth_pose.try_recv() {
            if let Some(p) = pose_of(&r.msg.pose) {
                self.truth.push((secs(&r.msg.header.stamp), p));
            }
        }
        if let Some((t_last, _)) = self.truth.last().copied() {
            let keep = self.truth.partition_point(|(t, _)| *t < t_last - 5.0);
            self.truth.drain(..keep);
        }
        while let Some(r) = self.truth_joints.try_recv() {
            let sent_s = r.source_timestamp_ns as f64 * 1e-9;
            self.truth_joints_by_stamp
                .insert(r.msg.header.stamp.as_nanos(), (r.msg.position, sent_s));
        }
        while self.truth_joints_by_stamp.len() > 600 {
            self.truth_joints_by_stamp.pop_first();
        }
        while let Some(r) = self.wrist.try_recv() {
            self.stages[STAGE_WRIST].add(r.receive_time_s(), secs(&r.msg.header.stamp));
        }
        while let Some(r) = self.camera.try_recv() {
            let t = secs(&r.msg.header.stamp);
            self.stages[STAGE_CAMERA].add(r.receive_time_s(), t);
            if let (Some(cam), Some(hand)) = (pose_of(&r.msg.pose), self.truth_at(t)) {
                let c = &self.camera_cfg;
                let goal = c.goal_for(&hand);
                let e = (cam.translation.vector - goal.translation.vector).norm();
                let dir = (cam.rotation * Vector3::z())
                    .angle(&(goal.rotation * Vector3::z()))
                    .to_degrees();
                self.camera_pos.push(e);
                self.camera_dir.push(dir);
                let (truth, c) = (&self.truth, &self.camera_cfg);
                self.camera_delay.add(|d| {
                    truth_at(truth, t - d).map(|hand| {
                        let goal = c.goal_for(&hand);
                        (cam.translation.vector - goal.translation.vector).norm()
                    })
                });
                self.report.camera_series.push((t - self.start_s, e));
            }
        }
        while let Some(r) = self.input.try_recv() {
            let m = &r.msg;
            let on = m.clutch && m.enable;
            match (on, self.engaged) {
                (true, None) => {
                    if let Some(h) = self.truth_at(secs(&m.header.stamp)) {
                        self.engaged = Some(Engaged {
                            human_ref: h.translation.vector,
                            robot_ref: None,
                            scale: m.motion_scale,
                        });
                        self.report.clutch_engagements += 1;
                    }
                }
                (false, Some(_)) => {
                    self.engaged = None;
                    // An engagement the controller reported for this one is moot now.
                    self.pending_engagement = None;
                }
                _ => {}
            }
        }
        self.apply_engagement();
        while let Some(r) = self.pr2.try_recv() {
            let t = secs(&r.msg.header.stamp);
            self.stages[STAGE_PR2].add(r.receive_time_s(), t);
            let Ok(state) = wire::arm_state(&PR2_ARM_JOINTS, &r.msg) else {
                continue;
            };
            let palm = self
                .pr2_chain
                .end_pose(&state.position_rad)
                .translation
                .vector;
            if self.recent_palms.len() >= RECENT_PALMS {
                self.recent_palms.pop_front();
            }
            self.recent_palms.push_back((t, palm));
            let hand = self.truth_at(t);
            if let (Some(eng), Some(hand)) = (&mut self.engaged, hand) {
                let robot_ref = *eng.robot_ref.get_or_insert(palm);
                let expected = robot_ref + (hand.translation.vector - eng.human_ref) * eng.scale;
                let err = palm - expected;
                for (a, e) in self.pr2_abs.iter_mut().zip(err.iter()) {
                    *a += e.abs();
                }
                self.pr2_n += 1;
                self.pr2_errors.push(err.norm());
                if self.arm_active {
                    self.pr2_following.push(err.norm());
                }
                let (truth, eng) = (&self.truth, *eng);
                self.pr2_delay.add(|d| {
                    truth_at(truth, t - d).map(|h| {
                        let expected =
                            robot_ref + (h.translation.vector - eng.human_ref) * eng.scale;
                        (palm - expected).norm()
                    })
                });
                self.report.pr2_series.push((t - self.start_s, err.norm()));
            }
        }
        while let Some(r) = self.targets.try_recv() {
            let stamp = r.msg.header.stamp.as_nanos();
            self.stages[STAGE_TARGETS].add(r.receive_time_s(), secs(&r.msg.header.stamp));
            self.pending_targets.push((
                stamp,
                secs(&r.msg.header.stamp),
                r.receive_time_s(),
                r.msg.position,
            ));
        }
        // Pair targets with the truth of their frame (the truth may arrive later).
        let truth = &self.truth_joints_by_stamp;
        let mut unmatched = Vec::new();
        for (stamp, t, received_s, q) in self.pending_targets.drain(..) {
            match truth.get(&stamp) {
                Some((truth_q, sent_s)) if truth_q.len() == q.len() && !q.is_empty() => {
                    self.stages[STAGE_FRAME_SENT_TARGETS].add(received_s, *sent_s);
                    let errs: Vec<f64> =
                        q.iter().zip(truth_q).map(|(a, b)| (a - b).abs()).collect();
                    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
                    let max = errs.iter().copied().fold(0.0, f64::max);
                    self.hand_errors.push(mean);
                    self.hand_within[0] += usize::from(max <= 0.1);
                    self.hand_within[1] += usize::from(max <= 0.2);
                    self.report.hand_series.push((t - self.start_s, mean));
                }
                _ if truth.first_key_value().is_some_and(|(k, _)| *k > stamp) => {}
                _ => unmatched.push((stamp, t, received_s, q)),
            }
        }
        unmatched.retain(|(stamp, _, _, _)| {
            truth
                .last_key_value()
                .is_none_or(|(k, _)| *k < stamp + 1_000_000_000)
        });
        self.pending_targets = unmatched;
        while let Some(r) = self.tips.try_recv() {
            self.stages[STAGE_TIPS].add(r.receive_time_s(), secs(&r.msg.header.stamp));
            let f = [r.msg.ff, r.msg.mf, r.msg.rf, r.msg.lf, r.msg.th];
            if f.iter().all(|v| v.is_finite()) {
                for ((max, sum), v) in self
                    .report
                    .fingertip_force_max_n
                    .iter_mut()
                    .zip(&mut self.force_sum)
                    .zip(f)
                {
                    *max = max.max(v);
                    *sum += v;
                }
                self.force_n += 1;
            }
        }
    }

    /// A node's status as it arrives: the PR2 arm controller's lifecycle says whether
    /// the arm follows the operator (Active) or is stopped.
    ///
    /// Each engagement is measured against the references the controller took: a
    /// clutch pressed while the hand moves engages from the newest wrist pose the
    /// controller held at its step, some tens of ms after the press. When the
    /// controller reports a new engagement (`arm.engaged_from_stamp_ns`), the operator's
    /// reference becomes the true hand at that pose's capture stamp and the robot's the
    /// palm at the status's stamp (the arm is still then). Until then (and from a
    /// controller that does not report it) the press is the reference.
    pub fn on_status(&mut self, s: &NodeStatus) {
        if s.node_name != "pr2_arm_controller" {
            return;
        }
        self.arm_active = s.lifecycle() == Some(Lifecycle::Active);
        let from_ns = s
            .counter(teleop_interfaces::status::arm::ENGAGED_FROM_STAMP_NS)
            .filter(|&ns| ns > 0);
        let Some(from_ns) = from_ns else {
            return;
        };
        if !self.arm_active || self.arm_engaged_from_ns == Some(from_ns) {
            return;
        }
        self.arm_engaged_from_ns = Some(from_ns);
        self.pending_engagement = Some((from_ns, secs(&s.header.stamp)));
        self.apply_engagement();
    }

    /// Re-anchors the engagement under way on the arm controller's reported references
    /// once the press and the truth at its wrist pose's stamp are in.
    fn apply_engagement(&mut self) {
        let Some((from_ns, engaged_s)) = self.pending_engagement else {
            return;
        };
        #[allow(clippy::cast_precision_loss)]
        let from_s = from_ns as f64 * 1e-9;
        // The truth must reach past the stamp (else `truth_at` holds its newest).
        if self.truth.last().is_none_or(|(t, _)| *t < from_s) {
            return;
        }
        let human = self.truth_at(from_s);
        let palm = self
            .recent_palms
            .iter()
            .rev()
            .find(|(t, _)| *t <= engaged_s)
            .map(|(_, p)| *p);
        if let (Some(eng), Some(human)) = (&mut self.engaged, human) {
            eng.human_ref = human.translation.vector;
            eng.robot_ref = palm;
            self.report.arm_reference_engagements += 1;
            self.pending_engagement = None;
        }
    }

    /// The report, with the final statuses of the nodes (`local_sim`'s frame counts,
    /// hand inference's stage timings).
    pub fn finish(mut self, now_s: f64, finals: &BTreeMap<String, NodeStatus>) -> RunReport {
        self.poll();
        let mut r = self.report;
        r.duration_s = now_s - self.start_s;
        r.latency = self.stages.iter().map(Stage::summary).collect();
        r.latency_samples = self
            .stages
            .iter_mut()
            .map(|s| {
                s.values_ms.sort_by(f64::total_cmp);
                (s.name.to_owned(), std::mem::take(&mut s.values_ms))
            })
            .collect();
        r.camera_position_error_m = ErrorSummary::of(&self.camera_pos);
        r.camera_direction_error_deg = ErrorSummary::of(&self.camera_dir);
        r.pr2_position_error_m = ErrorSummary::of(&self.pr2_errors);
        r.pr2_following_error_m = ErrorSummary::of(&self.pr2_following);
        r.pr2_fraction_following = if self.pr2_errors.is_empty() {
            0.0
        } else {
            self.pr2_following.len() as f64 / self.pr2_errors.len() as f64
        };
        if let Some((d, e)) = self.pr2_delay.best() {
            (r.pr2_best_fit_delay_ms, r.pr2_error_at_best_delay_m) = (d, e);
        }
        if let Some((d, e)) = self.camera_delay.best() {
            (r.camera_best_fit_delay_ms, r.camera_error_at_best_delay_m) = (d, e);
        }
        if self.pr2_n > 0 {
            r.pr2_mean_abs_error_xyz_m = self.pr2_abs.map(|a| a / self.pr2_n as f64);
        }
        r.finger_target_frames = self.hand_errors.len();
        r.hand_joint_mean_error_rad = ErrorSummary::of(&self.hand_errors);
        if !self.hand_errors.is_empty() {
            let n = self.hand_errors.len() as f64;
            r.hand_frames_max_error_within_0_1_rad = self.hand_within[0] as f64 / n;
            r.hand_frames_max_error_within_0_2_rad = self.hand_within[1] as f64 / n;
        }
        if self.force_n > 0 {
            r.fingertip_force_mean_n = self.force_sum.map(|s| s / self.force_n as f64);
        }
        let counter = |node: &str, name: &str| finals.get(node).and_then(|s| s.counter(name));
        r.depth_frames = counter("local_sim", "camera.frames").unwrap_or(0);
        r.frames_hand_fully_in_view =
            counter("local_sim", "camera.frames_hand_fully_in_view").unwrap_or(0);
        if r.depth_frames > 0 {
            r.fraction_hand_fully_in_view =
                r.frames_hand_fully_in_view as f64 / r.depth_frames as f64;
        }
        if let Some(s) = finals.get("pr2_arm_controller") {
            for (n, v) in s.counter_names.iter().zip(&s.counter_values) {
                if let Some(reason) = n.strip_prefix("arm.stop.")
                    && *v > 0
                {
                    r.pr2_stops.insert(reason.to_owned(), *v);
                }
            }
        }
        r.operator_reclutches = counter("local_sim", "operator.reclutches").unwrap_or(0);
        r.job = JobOutcome::from_counters(|n| counter("remote_sim", n));
        r.operator = OperatorOutcome::from_counters(|n| counter("local_sim", n));
        r.realtime_scheduling = realtime_scheduling(finals);
        r.hand_offline_test_error_rad = counter(
            teleop_interfaces::nodes::HAND_INFERENCE,
            "hand_inference.model.offline_test_error_urad",
        )
        .map(|urad| urad as f64 * 1e-6);
        for (node, stages) in [
            (
                teleop_interfaces::nodes::HAND_INFERENCE,
                &mut r.hand_inference_stages_us,
            ),
            ("shadow_hand_controller", &mut r.hand_controller_stages_us),
        ] {
            if let Some(s) = finals.get(node) {
                for (n, v) in s.counter_names.iter().zip(&s.counter_values) {
                    if n.starts_with("latency.") {
                        stages.insert(n.clone(), *v);
                    }
                }
            }
        }
        r.goals = r.judge_goals();
        r
    }
}

impl RunReport {
    /// Writes `report.json` and `report.png` into `dir` (created if missing) and says
    /// so; a plot that cannot be drawn is reported, not an error.
    ///
    /// # Errors
    /// Creating the directory or writing the JSON.
    pub fn write_files(&self, dir: &std::path::Path) -> anyhow::Result<()> {
        use anyhow::Context;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let json = dir.join("report.json");
        let png = dir.join("report.png");
        self.write_json(&json)?;
        match self.write_png(&png) {
            Ok(()) => println!("report written to {} and {}", json.display(), png.display()),
            Err(e) => println!("report written to {}; no plot: {e}", json.display()),
        }
        Ok(())
    }

    /// Whether the run went in real time (not paced, scale 1; 0 is a report not yet
    /// filled in).
    fn in_real_time(&self) -> bool {
        self.pacing.is_none() && ((self.time_scale - 1.0).abs() < 1e-9 || self.time_scale == 0.0)
    }

    /// `""` in real time, else `" of simulated time at 0.5x real time"` and the like.
    fn time_scale_note(&self) -> String {
        if let Some(p) = &self.pacing {
            format!(
                " of simulated time as fast as possible: {:.2}x real time on average, {:.2}-{:.2}x in {} changes",
                self.time_scale, p.min_rate, p.max_rate, p.changes
            )
        } else if self.in_real_time() {
            String::new()
        } else {
            format!(" of simulated time at {}x real time", self.time_scale)
        }
    }

    /// The local-site goals (issue: local site; docs/local-site.md) judged on this run's
    /// figures: the camera within 1 cm on average and 3 cm at most of its goal, the hand
    /// fully in view in >= 99.5 % of the frames, the PR2 within 5 mm on average of the
    /// scaled operator motion, the hand joints within 1.2x the model's offline test
    /// error, and the depth frame on the bus -> finger targets at p99 <= 10 ms (in real
    /// time only: at another rate the latencies are in simulated time). A goal with
    /// nothing to judge it on (no frames, never clutched, no offline error) is not
    /// judged.
    #[must_use]
    pub fn judge_goals(&self) -> Vec<GoalCheck> {
        let check = |goal: &str, measured: String, met: Option<bool>| GoalCheck {
            goal: goal.to_owned(),
            measured,
            met,
        };
        let mut out = Vec::new();
        let c = &self.camera_position_error_m;
        let goal = "UR5 camera position error mean <= 1 cm, max <= 3 cm";
        out.push(if c.samples == 0 {
            check(goal, "no camera poses".into(), None)
        } else {
            check(
                goal,
                format!(
                    "mean {:.1} cm, max {:.1} cm ({} samples)",
                    c.mean * 100.0,
                    c.max * 100.0,
                    c.samples
                ),
                Some(c.mean <= 0.01 && c.max <= 0.03),
            )
        });
        let goal = "hand fully in view in >= 99.5 % of the depth frames";
        out.push(if self.depth_frames == 0 {
            check(goal, "no depth frames".into(), None)
        } else {
            check(
                goal,
                format!(
                    "{:.1} % of {}",
                    self.fraction_hand_fully_in_view * 100.0,
                    self.depth_frames
                ),
                Some(self.fraction_hand_fully_in_view >= 0.995),
            )
        });
        let p = &self.pr2_position_error_m;
        let goal = "PR2 end-effector mean error vs the scaled operator motion <= 5 mm";
        out.push(if p.samples == 0 {
            check(goal, "never clutched".into(), None)
        } else {
            check(
                goal,
                format!("mean {:.1} mm ({} samples)", p.mean * 1e3, p.samples),
                Some(p.mean <= 0.005),
            )
        });
        let h = &self.hand_joint_mean_error_rad;
        let goal = "hand joint mean error <= 1.2x the model's offline test error";
        out.push(match (h.samples, self.hand_offline_test_error_rad) {
            (0, _) => check(goal, "no finger targets".into(), None),
            (_, None) => check(
                goal,
                format!(
                    "mean {:.3} rad; the model's offline test error is not known (no evaluation beside it)",
                    h.mean
                ),
                None,
            ),
            (_, Some(offline)) => check(
                goal,
                format!(
                    "mean {:.3} rad, limit {:.3} rad (offline {:.4} rad)",
                    h.mean,
                    HAND_ERROR_FACTOR * offline,
                    offline
                ),
                Some(h.mean <= HAND_ERROR_FACTOR * offline),
            ),
        });
        let goal = "depth frame on the bus -> finger targets at the robot site p99 <= 10 ms";
        let stage = |name: &str| self.latency.iter().find(|l| l.stage == name);
        let at_the_hand = self
            .hand_controller_stages_us
            .get("latency.targets.capture_to_received_us.p99")
            .map(|us| format!(", {:.1} ms at the hand controller", *us as f64 / 1000.0))
            .unwrap_or_default();
        let from_capture = stage(CAPTURE_TO_TARGETS)
            .filter(|l| l.samples > 0)
            .map(|l| {
                format!(
                    " (from the capture stamp: p99 {:.1} ms{at_the_hand})",
                    l.p99_ms
                )
            })
            .unwrap_or_default();
        let real_time = self.in_real_time();
        out.push(match stage(FRAME_ON_THE_BUS_TO_TARGETS) {
            Some(l) if l.samples > 0 && real_time => check(
                goal,
                format!(
                    "p99 {:.1} ms over {} frames{from_capture}",
                    l.p99_ms, l.samples
                ),
                Some(l.p99_ms <= LATENCY_GOAL_P99_MS),
            ),
            Some(l) if l.samples > 0 => check(
                goal,
                format!(
                    "p99 {:.1} ms of simulated time: judged in real time only",
                    l.p99_ms
                ),
                None,
            ),
            _ => check(goal, "no finger targets".into(), None),
        });
        out
    }

    /// The report as text.
    #[must_use]
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "== {}: end-of-run report ({} task, {:.1} s{})",
            self.recorded_by,
            self.task,
            self.duration_s,
            self.time_scale_note()
        );
        if let Some(wan) = &self.wan {
            let _ = writeln!(s, "{wan}");
        }
        let _ = writeln!(
            s,
            "latency (capture -> received here)      samples    p50 ms    p99 ms    max ms"
        );
        for l in &self.latency {
            let _ = writeln!(
                s,
                "  {:<38} {:>7} {:>9.2} {:>9.2} {:>9.2}",
                l.stage, l.samples, l.p50_ms, l.p99_ms, l.max_ms
            );
        }
        for (who, stages) in [
            ("hand inference", &self.hand_inference_stages_us),
            (
                "Shadow hand controller (robot site)",
                &self.hand_controller_stages_us,
            ),
        ] {
            if stages.is_empty() {
                continue;
            }
            let stages: Vec<String> = stages
                .iter()
                .filter(|(k, _)| !k.ends_with(".max"))
                .map(|(k, v)| {
                    format!(
                        "{}={:.2} ms",
                        k.trim_start_matches("latency."),
                        *v as f64 / 1000.0
                    )
                })
                .collect();
            let _ = writeln!(s, "  {who}: {}", stages.join(", "));
        }
        if !self.resources.is_empty() {
            let cpu: f64 = self.resources.values().map(|u| u.cpu_cores).sum();
            let rss: f64 = self.resources.values().map(|u| u.peak_rss_mb).sum();
            let nodes: Vec<String> = self
                .resources
                .iter()
                .map(|(n, u)| format!("{n} {:.3} / {:.0}", u.cpu_cores, u.peak_rss_mb))
                .collect();
            let _ = writeln!(
                s,
                "resources (cores / peak MB, from /proc): all nodes {cpu:.2} cores, {rss:.0} MB (sum of peaks); {}",
                nodes.join(", ")
            );
        }
        if !self.realtime_scheduling.is_empty() {
            let nodes: Vec<String> = self
                .realtime_scheduling
                .iter()
                .map(|(node, r)| match r.granted {
                    0 => format!("{node} (asked {}, refused: normal)", r.requested),
                    p => format!("{node} {p}"),
                })
                .collect();
            let _ = writeln!(s, "  real-time FIFO scheduling: {}", nodes.join(", "));
        }
        let c = &self.camera_position_error_m;
        let _ = writeln!(
            s,
            "UR5 camera tracking error: position mean {:.1} cm, p99 {:.1} cm, max {:.1} cm; view direction mean {:.1} deg ({} samples)",
            c.mean * 100.0,
            c.p99 * 100.0,
            c.max * 100.0,
            self.camera_direction_error_deg.mean,
            c.samples
        );
        let _ = writeln!(
            s,
            "hand fully in view: {:.1} % of {} depth frames",
            self.fraction_hand_fully_in_view * 100.0,
            self.depth_frames
        );
        let p = &self.pr2_position_error_m;
        let [x, y, z] = self.pr2_mean_abs_error_xyz_m;
        let _ = writeln!(
            s,
            "PR2 end-effector error vs the scaled operator motion (clutched, {} engagements, {} from the arm's own references): mean {:.1} cm, p99 {:.1} cm; mean |error| x {:.1} / y {:.1} / z {:.1} cm ({} samples)",
            self.clutch_engagements,
            self.arm_reference_engagements,
            p.mean * 100.0,
            p.p99 * 100.0,
            x * 100.0,
            y * 100.0,
            z * 100.0,
            p.samples
        );
        if self.pr2_fraction_following < 1.0 && p.samples > 0 {
            let f = &self.pr2_following_error_m;
            let _ = writeln!(
                s,
                "  while the arm followed (Active, {:.0} % of the clutched samples): mean {:.1} cm, p99 {:.1} cm ({} samples)",
                self.pr2_fraction_following * 100.0,
                f.mean * 100.0,
                f.p99 * 100.0,
                f.samples
            );
        }
        let _ = writeln!(
            s,
            "  delay: the palm matches the operator's motion best {:.0} ms earlier (mean error there {:.1} cm); the camera its goal {:.0} ms earlier ({:.1} cm)",
            self.pr2_best_fit_delay_ms,
            self.pr2_error_at_best_delay_m * 100.0,
            self.camera_best_fit_delay_ms,
            self.camera_error_at_best_delay_m * 100.0
        );
        if !self.pr2_stops.is_empty() {
            let stops: Vec<String> = self
                .pr2_stops
                .iter()
                .map(|(k, v)| format!("{k} x{v}"))
                .collect();
            let _ = writeln!(s, "  PR2 arm stops: {}", stops.join(", "));
        }
        if self.operator_reclutches > 0 {
            let _ = writeln!(
                s,
                "  the operator let go of the clutch and pressed it again {} time(s) on seeing the arm's safety stop",
                self.operator_reclutches
            );
        }
        if let Some(job) = &self.job {
            let _ = writeln!(
                s,
                "robot world's job (judged by remote_sim from ground truth): {}",
                job.describe()
            );
        }
        if let Some(op) = &self.operator {
            let _ = writeln!(s, "operator watching the display: {}", op.describe());
        }
        let h = &self.hand_joint_mean_error_rad;
        let _ = writeln!(
            s,
            "hand joint error vs ground truth: mean {:.3} rad, p99 {:.3} rad over {} frames; max error <= 0.1 rad in {:.1} %, <= 0.2 rad in {:.1} % of frames",
            h.mean,
            h.p99,
            self.finger_target_frames,
            self.hand_frames_max_error_within_0_1_rad * 100.0,
            self.hand_frames_max_error_within_0_2_rad * 100.0
        );
        let _ = writeln!(
            s,
            "fingertip forces (ff mf rf lf th): max {:.2} {:.2} {:.2} {:.2} {:.2} N, mean {:.2} {:.2} {:.2} {:.2} {:.2} N",
            self.fingertip_force_max_n[0],
            self.fingertip_force_max_n[1],
            self.fingertip_force_max_n[2],
            self.fingertip_force_max_n[3],
            self.fingertip_force_max_n[4],
            self.fingertip_force_mean_n[0],
            self.fingertip_force_mean_n[1],
            self.fingertip_force_mean_n[2],
            self.fingertip_force_mean_n[3],
            self.fingertip_force_mean_n[4],
        );
        if !self.goals.is_empty() {
            let _ = writeln!(s, "goals (docs/local-site.md):");
            for g in &self.goals {
                let verdict = match g.met {
                    Some(true) => "met",
                    Some(false) => "MISSED",
                    None => "not judged",
                };
                let _ = writeln!(s, "  {verdict:<10} {}: {}", g.goal, g.measured);
            }
        }
        s
    }

    /// Writes the report as JSON.
    ///
    /// # Errors
    /// File errors.
    pub fn write_json(&self, path: &Path) -> anyhow::Result<()> {
        let text = serde_json::to_string_pretty(self)?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
    }

    /// Draws the tracking and latency plots (PNG).
    ///
    /// # Errors
    /// Font or drawing errors.
    pub fn write_png(&self, path: &Path) -> anyhow::Result<()> {
        use plotters::prelude::*;
        teleop_node::plot::register_fonts()?;
        let root = BitMapBackend::new(path, (1400, 1000)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
        let root = root
            .titled(
                &format!(
                    "{}: {} task, {:.0} s{}",
                    self.recorded_by,
                    self.task,
                    self.duration_s,
                    self.time_scale_note()
                ),
                ("sans-serif", 28),
            )
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let panels = root.split_evenly((2, 2));
        let t_max = self.duration_s.max(1.0);
        // (title, y label, data, scale to the label's unit, colour)
        type Panel<'a> = (&'a str, &'a str, &'a [(f64, f64)], f64, RGBColor);
        let series: [Panel<'_>; 3] = [
            (
                "UR5 camera position error vs its goal",
                "error (cm)",
                &self.camera_series,
                100.0,
                BLUE,
            ),
            (
                "PR2 palm error vs scaled operator motion (clutched)",
                "error (cm)",
                &self.pr2_series,
                100.0,
                RED,
            ),
            (
                "Hand joints: mean |inferred - true| per frame",
                "error (rad)",
                &self.hand_series,
                1.0,
                GREEN,
            ),
        ];
        for (area, (title, y_label, data, scale, color)) in panels.iter().zip(series) {
            let y_max = data
                .iter()
                .map(|(_, v)| v * scale)
                .fold(0.0, f64::max)
                .max(1e-3)
                * 1.1;
            let mut chart = ChartBuilder::on(area)
                .caption(title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..t_max, 0.0..y_max)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            chart
                .configure_mesh()
                .x_desc("time since launch (s)")
                .y_desc(y_label)
                .x_label_formatter(&teleop_node::plot::tick_label)
                .y_label_formatter(&teleop_node::plot::tick_label)
                .draw()
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            chart
                .draw_series(LineSeries::new(
                    data.iter().map(|(t, v)| (*t, v * scale)),
                    color,
                ))
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .label(format!("{} samples", data.len()))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
        // Latency CDFs.
        let x_max = self
            .latency_samples
            .iter()
            .filter_map(|(_, v)| v.get((v.len().saturating_sub(1) * 99) / 100).copied())
            .fold(1.0, f64::max)
            * 1.2;
        let mut chart = ChartBuilder::on(&panels[3])
            .caption(
                "Latency per stage (capture -> received), CDF",
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_max, 0.0..1.0)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("latency (ms)")
            .y_desc("fraction of samples")
            .x_label_formatter(&teleop_node::plot::tick_label)
            .y_label_formatter(&teleop_node::plot::tick_label)
            .draw()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        for (i, (name, v)) in self.latency_samples.iter().enumerate() {
            if v.is_empty() {
                continue;
            }
            let color = Palette99::pick(i).to_rgba();
            let n = v.len() as f64;
            let step = (v.len() / 500).max(1);
            chart
                .draw_series(LineSeries::new(
                    v.iter()
                        .enumerate()
                        .step_by(step)
                        .map(|(k, x)| (x.min(x_max), (k + 1) as f64 / n)),
                    color,
                ))
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_summary_of_known_values() {
        let s = ErrorSummary::of(&[3.0, 1.0, 2.0, 4.0]);
        assert_eq!(s.samples, 4);
        assert!((s.mean - 2.5).abs() < 1e-12);
        assert_eq!(s.max, 4.0);
        assert_eq!(ErrorSummary::of(&[]), ErrorSummary::default());
    }

    #[test]
    fn poses_with_bad_quaternions_are_refused() {
        let mut p = Pose::default();
        p.orientation.w = 0.0;
        assert!(pose_of(&p).is_none(), "zero quaternion");
        p.orientation.w = 1.0;
        assert!(pose_of(&p).is_some());
        p.position.x = f64::NAN;
        assert!(pose_of(&p).is_none());
    }

    fn summary(samples: usize, mean: f64, max: f64) -> ErrorSummary {
        ErrorSummary {
            samples,
            mean,
            p50: mean,
            p99: max,
            max,
        }
    }

    fn latency(stage: &str, p99_ms: f64) -> StageLatency {
        StageLatency {
            stage: stage.to_owned(),
            samples: 600,
            p50_ms: p99_ms / 2.0,
            p99_ms,
            max_ms: p99_ms,
        }
    }

    /// A run that met every goal, in real time.
    fn good_run() -> RunReport {
        RunReport {
            time_scale: 1.0,
            camera_position_error_m: summary(600, 0.003, 0.02),
            depth_frames: 600,
            frames_hand_fully_in_view: 600,
            fraction_hand_fully_in_view: 1.0,
            pr2_position_error_m: summary(900, 0.003, 0.01),
            hand_joint_mean_error_rad: summary(590, 0.05, 0.1),
            hand_offline_test_error_rad: Some(0.0948),
            latency: vec![
                latency(CAPTURE_TO_TARGETS, 12.5),
                latency(FRAME_ON_THE_BUS_TO_TARGETS, 7.5),
            ],
            ..RunReport::default()
        }
    }

    fn verdicts(r: &RunReport) -> Vec<Option<bool>> {
        r.judge_goals().iter().map(|g| g.met).collect()
    }

    #[test]
    fn goals_are_judged_met_missed_or_not_at_all_and_say_why() {
        let good = good_run();
        let goals = good.judge_goals();
        assert_eq!(verdicts(&good), [Some(true); 5], "{goals:?}");
        assert!(goals[3].measured.contains("limit 0.114 rad"), "{goals:?}");
        assert!(
            goals[4].measured.contains("capture stamp: p99 12.5 ms)"),
            "{goals:?}"
        );
        let mut r = good_run();
        r.hand_controller_stages_us
            .insert("latency.targets.capture_to_received_us.p99".into(), 11_900);
        let goals = r.judge_goals();
        assert!(
            goals[4]
                .measured
                .contains("capture stamp: p99 12.5 ms, 11.9 ms at the hand controller)"),
            "{goals:?}"
        );

        // Each goal missed on its own.
        let mut r = good_run();
        r.camera_position_error_m.max = 0.031;
        r.fraction_hand_fully_in_view = 0.99;
        r.pr2_position_error_m.mean = 0.0051;
        r.hand_joint_mean_error_rad.mean = 0.12;
        r.latency[1].p99_ms = 10.5;
        assert_eq!(verdicts(&r), [Some(false); 5]);

        // Nothing to judge on, or not in real time: not judged, and the reason named.
        let mut r = good_run();
        r.camera_position_error_m = ErrorSummary::default();
        r.depth_frames = 0;
        r.pr2_position_error_m = ErrorSummary::default();
        r.hand_offline_test_error_rad = None;
        r.time_scale = 2.0;
        let goals = r.judge_goals();
        assert_eq!(verdicts(&r), [None; 5], "{goals:?}");
        assert!(goals[2].measured.contains("never clutched"));
        assert!(goals[3].measured.contains("not known"));
        assert!(goals[4].measured.contains("real time only"));

        // The text says each verdict.
        let mut r = good_run();
        r.latency[1].p99_ms = 10.5;
        r.goals = r.judge_goals();
        let text = r.text();
        assert!(text.contains("goals (docs/local-site.md):"), "{text}");
        assert_eq!(text.matches("\n  met ").count(), 4, "{text}");
        assert!(text.contains("MISSED     depth frame on the bus"), "{text}");
    }

    #[test]
    fn the_report_names_the_real_time_nodes_and_the_refusals() {
        let status = |name: &str, counters: &[(&str, u64)]| NodeStatus {
            node_name: name.to_owned(),
            counter_names: counters.iter().map(|(n, _)| (*n).to_owned()).collect(),
            counter_values: counters.iter().map(|(_, v)| *v).collect(),
            ..NodeStatus::default()
        };
        let finals: BTreeMap<String, NodeStatus> = [
            status(
                "hand_inference",
                &[
                    ("process.realtime_priority", 50),
                    ("process.realtime_priority_requested", 50),
                ],
            ),
            status(
                "local_sim",
                &[
                    ("process.realtime_priority", 0),
                    ("process.realtime_priority_requested", 50),
                ],
            ),
            status(
                "camera_arm",
                &[
                    ("process.realtime_priority", 0),
                    ("process.realtime_priority_requested", 0),
                ],
            ),
            status("wrist_tracker", &[("tracker.samples", 3)]),
        ]
        .into_iter()
        .map(|s| (s.node_name.clone(), s))
        .collect();
        let rt = realtime_scheduling(&finals);
        assert_eq!(
            rt.into_iter().collect::<Vec<_>>(),
            [
                (
                    "hand_inference".to_owned(),
                    RealtimeScheduling {
                        requested: 50,
                        granted: 50
                    }
                ),
                (
                    "local_sim".to_owned(),
                    RealtimeScheduling {
                        requested: 50,
                        granted: 0
                    }
                ),
            ]
        );
        let mut r = good_run();
        r.realtime_scheduling = realtime_scheduling(&finals);
        let text = r.text();
        assert!(
            text.contains(
                "real-time FIFO scheduling: hand_inference 50, local_sim (asked 50, refused: normal)"
            ),
            "{text}"
        );
    }

    #[test]
    fn the_watching_operators_outcome_is_read_from_the_simulators_counters() {
        let counters = |pairs: &'static [(&'static str, u64)]| {
            move |n: &str| pairs.iter().find(|(k, _)| *k == n).map(|(_, v)| *v)
        };
        assert_eq!(OperatorOutcome::from_counters(counters(&[])), None);
        let done = OperatorOutcome::from_counters(counters(&[
            ("operator.phase", 12),
            ("operator.grasp_attempts", 2),
            ("operator.submovements", 17),
            ("operator.views_received", 600),
            ("operator.scene_percepts", 590),
            ("operator.max_perceived_error_mm", 31),
        ]))
        .unwrap();
        assert_eq!(done.phase, "done");
        let mut r = good_run();
        r.operator = Some(done);
        let text = r.text();
        assert!(
            text.contains("operator watching the display: ended in phase done, 2 grasp attempt(s), 17 submovements (0 goals left unreached); saw 590 of 600 views received, the object up to 31 mm"),
            "{text}"
        );
        let odd = OperatorOutcome::from_counters(counters(&[("operator.phase", 99)])).unwrap();
        assert_eq!(odd.phase, "unknown (99)");
    }

    #[test]
    fn the_job_outcome_is_read_from_the_simulators_counters() {
        let counters = |pairs: &'static [(&'static str, u64)]| {
            move |n: &str| pairs.iter().find(|(k, _)| *k == n).map(|(_, v)| *v)
        };
        assert_eq!(JobOutcome::from_counters(counters(&[])), None);
        let done = JobOutcome::from_counters(counters(&[
            ("job.lifted", 1),
            ("job.succeeded", 1),
            ("job.completion_ms", 9_640),
            ("job.failed.fell_off_table", 0),
            ("job.failed.timed_out", 0),
            ("job.judge_errors", 0),
        ]))
        .unwrap();
        assert_eq!(done.completion_s, Some(9.64));
        assert_eq!(done.describe(), "succeeded in 9.6 s");
        let fell = JobOutcome::from_counters(counters(&[
            ("job.lifted", 1),
            ("job.succeeded", 0),
            ("job.completion_ms", 0),
            ("job.failed.fell_off_table", 1),
            ("job.judge_errors", 2),
        ]))
        .unwrap();
        assert_eq!(
            fell.describe(),
            "failed (fell off table); 2 observations refused"
        );
        let running =
            JobOutcome::from_counters(counters(&[("job.lifted", 0), ("job.succeeded", 0)]))
                .unwrap();
        assert_eq!(
            running.describe(),
            "not finished (the object was never lifted)"
        );
    }
}
