//! Judging a pick-and-place job from ground truth, a pure core: [`PickPlaceJudge::step`]
//! takes the simulation time, the arm's joint positions and every object's true pose, and says whether the job is still running, succeeded (with its completion
//! time) or failed (and why).
//!
//! The completion time is measured as in the thesis (ch. 6.4, after Table 6.1): "when
//! the robot started to move until it went back to the starting pose". What counts as
//! success is ours (the thesis gives none in numbers): the object was lifted off its
//! resting place, came to rest with its centre inside the target region, and the arm
//! returned to where it started, with no object fallen off the table and within the
//! time limit.

use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

/// Where the object's centre must come to rest, world frame: an axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetRegion {
    /// Centre of the box, m.
    pub centre_m: [f64; 3],
    /// Half extents along x, y, z, m.
    pub half_extent_m: [f64; 3],
}

impl TargetRegion {
    /// Whether `p` lies inside (boundary included).
    #[must_use]
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (0..3).all(|i| (p[i] - self.centre_m[i]).abs() <= self.half_extent_m[i])
    }
}

/// What a pick-and-place job is and how strictly it is judged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PickPlaceConfig {
    /// The object to move (its name in the scene).
    pub object: String,
    /// Where it must come to rest.
    pub target: TargetRegion,
    /// Height of the table top, m: an object whose centre falls more than
    /// `fallen_below_table_m` below it has fallen off.
    pub table_top_z_m: f64,
    /// The object counts as lifted once its centre rose this far above where it first
    /// rested, m. Default 0.02.
    #[serde(default = "defaults::lift_m")]
    pub lift_m: f64,
    /// The object is at rest below this speed of its centre, m/s. Default 0.01.
    #[serde(default = "defaults::settle_speed_m_s")]
    pub settle_speed_m_s: f64,
    /// ... for at least this long, s. Default 0.5.
    #[serde(default = "defaults::settle_s")]
    pub settle_s: f64,
    /// The robot has started once any arm joint moved this far from its first reading,
    /// rad. Default 0.02.
    #[serde(default = "defaults::start_motion_rad")]
    pub start_motion_rad: f64,
    /// The arm is back at its starting pose within this much on every joint, rad.
    /// Default 0.05.
    #[serde(default = "defaults::home_tolerance_rad")]
    pub home_tolerance_rad: f64,
    /// Default 0.05 m.
    #[serde(default = "defaults::fallen_below_table_m")]
    pub fallen_below_table_m: f64,
    /// The job fails this long after the judge's first step, s. Default 300.
    #[serde(default = "defaults::time_limit_s")]
    pub time_limit_s: f64,
}

mod defaults {
    pub fn lift_m() -> f64 {
        0.02
    }
    pub fn settle_speed_m_s() -> f64 {
        0.01
    }
    pub fn settle_s() -> f64 {
        0.5
    }
    pub fn start_motion_rad() -> f64 {
        0.02
    }
    pub fn home_tolerance_rad() -> f64 {
        0.05
    }
    pub fn fallen_below_table_m() -> f64 {
        0.05
    }
    pub fn time_limit_s() -> f64 {
        300.0
    }
}

impl PickPlaceConfig {
    fn clock_limits(&self) -> ClockLimits {
        ClockLimits {
            table_top_z_m: self.table_top_z_m,
            fallen_below_table_m: self.fallen_below_table_m,
            time_limit_s: self.time_limit_s,
            start_motion_rad: self.start_motion_rad,
        }
    }

    /// A job moving `object` into `target` above a table top at `table_top_z_m`, judged
    /// with the default tolerances.
    #[must_use]
    pub fn new(object: &str, target: TargetRegion, table_top_z_m: f64) -> Self {
        Self {
            object: object.to_owned(),
            target,
            table_top_z_m,
            lift_m: defaults::lift_m(),
            settle_speed_m_s: defaults::settle_speed_m_s(),
            settle_s: defaults::settle_s(),
            start_motion_rad: defaults::start_motion_rad(),
            home_tolerance_rad: defaults::home_tolerance_rad(),
            fallen_below_table_m: defaults::fallen_below_table_m(),
            time_limit_s: defaults::time_limit_s(),
        }
    }

    /// Every number finite and in range, the object named.
    ///
    /// # Errors
    /// [`JudgeError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), JudgeError> {
        if self.object.trim().is_empty() {
            return Err(JudgeError::Config {
                field: "object",
                why: "empty".into(),
            });
        }
        let finite = [
            (
                "target.centre_m",
                self.target.centre_m.iter().all(|v| v.is_finite()),
            ),
            ("table_top_z_m", self.table_top_z_m.is_finite()),
        ];
        for (field, ok) in finite {
            if !ok {
                return Err(JudgeError::Config {
                    field,
                    why: "not finite".into(),
                });
            }
        }
        let positive = [
            (
                "target.half_extent_m",
                self.target
                    .half_extent_m
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, least),
            ),
            ("lift_m", self.lift_m),
            ("settle_speed_m_s", self.settle_speed_m_s),
            ("settle_s", self.settle_s),
            ("start_motion_rad", self.start_motion_rad),
            ("home_tolerance_rad", self.home_tolerance_rad),
            ("fallen_below_table_m", self.fallen_below_table_m),
            ("time_limit_s", self.time_limit_s),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(JudgeError::Config {
                    field,
                    why: format!("{v} is not a positive number"),
                });
            }
        }
        Ok(())
    }
}

/// The smaller of two numbers, NaN if either is (`f64::min` passes NaN over, so a
/// NaN among sizes would not be refused).
fn least(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.min(b)
    }
}

/// Why a job failed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Failure {
    /// An object (the one to move or another) fell off the table.
    FellOffTable { object: String },
    /// The time limit passed first.
    TimedOut,
}

/// Where a job stands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum Verdict {
    Running,
    /// `completion_s`: from the robot's first motion to its return to the starting pose.
    Succeeded {
        completion_s: f64,
    },
    /// `at_s`: the judge's time when it failed.
    Failed {
        failure: Failure,
        at_s: f64,
    },
}

impl Verdict {
    /// Succeeded or failed: the verdict no longer changes.
    #[must_use]
    pub fn is_final(&self) -> bool {
        !matches!(self, Verdict::Running)
    }
}

/// Input the judge cannot use (nothing is changed when it is refused).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JudgeError {
    #[error("task judge config: {field}: {why}")]
    Config { field: &'static str, why: String },
    #[error("task judge: no object named {0} in the world's poses")]
    MissingObject(String),
    #[error("task judge: {what} is not finite")]
    NonFinite { what: String },
    #[error("task judge: time went back from {last_s} s to {now_s} s")]
    TimeWentBack { last_s: f64, now_s: f64 },
    #[error("task judge: {got} arm joints, {expected} at the first step")]
    ArmSize { got: usize, expected: usize },
}

/// Where the robot started: the judge's first observation.
#[derive(Debug, Clone)]
struct Start {
    time_s: f64,
    arm_rad: Vec<f64>,
}

/// What every job's judge does alike: refuses input it cannot use, fixes the arm's
/// starting pose, notes the robot's first motion, fails the job on an object fallen off
/// the table or on the time limit, and says how far the arm is from its start.
#[derive(Debug, Clone, Default)]
struct JobClock {
    start: Option<Start>,
    moved_at_s: Option<f64>,
    last_time_s: Option<f64>,
}

/// The limits [`JobClock`] judges by.
struct ClockLimits {
    table_top_z_m: f64,
    fallen_below_table_m: f64,
    time_limit_s: f64,
    start_motion_rad: f64,
}

impl JobClock {
    /// Every input finite, time not going back, the same arm size as at the start, the
    /// objects named in `required` present. Changes nothing.
    fn check(
        &self,
        time_s: f64,
        arm_rad: &[f64],
        objects: &[(String, Isometry3<f64>)],
        required: &[&str],
    ) -> Result<(), JudgeError> {
        if !time_s.is_finite() {
            return Err(JudgeError::NonFinite {
                what: "the time".into(),
            });
        }
        if let Some(last_s) = self.last_time_s
            && time_s < last_s
        {
            return Err(JudgeError::TimeWentBack {
                last_s,
                now_s: time_s,
            });
        }
        if let Some(i) = arm_rad.iter().position(|v| !v.is_finite()) {
            return Err(JudgeError::NonFinite {
                what: format!("arm joint {i}"),
            });
        }
        if let Some((name, _)) = objects.iter().find(|(_, p)| {
            !(p.translation.vector.iter().all(|v| v.is_finite())
                && p.rotation.coords.iter().all(|v| v.is_finite()))
        }) {
            return Err(JudgeError::NonFinite {
                what: format!("the pose of {name}"),
            });
        }
        if let Some(missing) = required
            .iter()
            .find(|r| !objects.iter().any(|(n, _)| n == *r))
        {
            return Err(JudgeError::MissingObject((*missing).to_owned()));
        }
        if let Some(start) = &self.start
            && start.arm_rad.len() != arm_rad.len()
        {
            return Err(JudgeError::ArmSize {
                got: arm_rad.len(),
                expected: start.arm_rad.len(),
            });
        }
        Ok(())
    }

    /// One checked observation: the arm's largest joint distance from its start, rad;
    /// `None` with a failure it sees (fallen object, time limit) written into `verdict`.
    fn observe(
        &mut self,
        verdict: &mut Verdict,
        time_s: f64,
        arm_rad: &[f64],
        objects: &[(String, Isometry3<f64>)],
        limits: &ClockLimits,
    ) -> Option<f64> {
        self.last_time_s = Some(time_s);
        let start = self.start.get_or_insert_with(|| Start {
            time_s,
            arm_rad: arm_rad.to_vec(),
        });
        if let Some((name, _)) = objects
            .iter()
            .find(|(_, p)| p.translation.z < limits.table_top_z_m - limits.fallen_below_table_m)
        {
            *verdict = Verdict::Failed {
                failure: Failure::FellOffTable {
                    object: name.clone(),
                },
                at_s: time_s,
            };
            return None;
        }
        if time_s - start.time_s > limits.time_limit_s {
            *verdict = Verdict::Failed {
                failure: Failure::TimedOut,
                at_s: time_s,
            };
            return None;
        }
        let away_rad = arm_rad
            .iter()
            .zip(&start.arm_rad)
            .map(|(q, q0)| (q - q0).abs())
            .fold(0.0, f64::max);
        if self.moved_at_s.is_none() && away_rad > limits.start_motion_rad {
            self.moved_at_s = Some(time_s);
        }
        Some(away_rad)
    }
}

/// An object's speed between two observations; unknown (infinite) without an earlier
/// one, zero for a repeated stamp at the same place.
fn speed(previous: Option<(f64, Vector3<f64>)>, time_s: f64, p: &Vector3<f64>) -> f64 {
    match previous {
        Some((t, q)) if time_s > t => (p - q).norm() / (time_s - t),
        Some((_, q)) if *p == q => 0.0,
        _ => f64::INFINITY,
    }
}

/// Judges one pick-and-place job; see the module documentation.
#[derive(Debug, Clone)]
pub struct PickPlaceJudge {
    config: PickPlaceConfig,
    clock: JobClock,
    rest_m: Option<Vector3<f64>>,
    lifted: bool,
    last: Option<(f64, Vector3<f64>)>,
    resting_in_target_since_s: Option<f64>,
    verdict: Verdict,
}

impl PickPlaceJudge {
    /// # Errors
    /// [`JudgeError::Config`] naming a bad setting.
    pub fn new(config: PickPlaceConfig) -> Result<Self, JudgeError> {
        config.validate()?;
        Ok(Self {
            config,
            clock: JobClock::default(),
            rest_m: None,
            lifted: false,
            last: None,
            resting_in_target_since_s: None,
            verdict: Verdict::Running,
        })
    }

    /// The job's settings.
    #[must_use]
    pub fn config(&self) -> &PickPlaceConfig {
        &self.config
    }

    /// The verdict so far.
    #[must_use]
    pub fn verdict(&self) -> &Verdict {
        &self.verdict
    }

    /// When the robot first moved (judge time, s).
    #[must_use]
    pub fn started_s(&self) -> Option<f64> {
        self.clock.moved_at_s
    }

    /// Whether the object has been lifted off its resting place.
    #[must_use]
    pub fn lifted(&self) -> bool {
        self.lifted
    }

    /// One observation at `time_s`: the arm's joint positions and every object's pose.
    /// The first observation fixes the arm's starting pose and the object's resting place.
    /// A final verdict stays as it is.
    ///
    /// # Errors
    /// [`JudgeError`] for input it cannot use: non-finite numbers, time going back, the
    /// job's object missing, a different number of arm joints. Nothing is changed then.
    pub fn step(
        &mut self,
        time_s: f64,
        arm_rad: &[f64],
        objects: &[(String, Isometry3<f64>)],
    ) -> Result<&Verdict, JudgeError> {
        let c = &self.config;
        self.clock
            .check(time_s, arm_rad, objects, &[c.object.as_str()])?;
        let object = objects
            .iter()
            .find(|(n, _)| *n == c.object)
            .map(|(_, p)| p.translation.vector)
            .ok_or_else(|| JudgeError::MissingObject(c.object.clone()))?;
        let rest = *self.rest_m.get_or_insert(object);
        let previous = self.last.replace((time_s, object));
        if self.verdict.is_final() {
            self.clock.last_time_s = Some(time_s);
            return Ok(&self.verdict);
        }
        let limits = c.clock_limits();
        let Some(away_rad) =
            self.clock
                .observe(&mut self.verdict, time_s, arm_rad, objects, &limits)
        else {
            return Ok(&self.verdict);
        };
        if object.z > rest.z + c.lift_m {
            self.lifted = true;
        }
        let speed = speed(previous, time_s, &object);
        if self.lifted && c.target.contains(&object) && speed < c.settle_speed_m_s {
            self.resting_in_target_since_s.get_or_insert(time_s);
        } else if speed.is_finite() || !c.target.contains(&object) {
            // A repeated time stamp (speed unknown) keeps the count going.
            self.resting_in_target_since_s = None;
        }
        let placed = self
            .resting_in_target_since_s
            .is_some_and(|since| time_s - since >= c.settle_s);
        if let Some(moved) = self.clock.moved_at_s
            && placed
            && away_rad <= c.home_tolerance_rad
        {
            self.verdict = Verdict::Succeeded {
                completion_s: time_s - moved,
            };
        }
        Ok(&self.verdict)
    }
}

/// What a tower-building job is (thesis ch. 7.6.2, Table 7.1: "stack three different
/// objects on top of each other") and how strictly it is judged. Success (ours; the
/// thesis gives none in numbers): every block but the lowest lifted, each resting on the
/// one below (its centre within `align_m` of that block's, horizontally, and as high
/// above it as their half heights add up to, within `seat_m`; leaning no more than
/// `upright_deg`), the whole tower at rest for `stand_s`, and the arm back where it
/// started; nothing fallen off the table; within the time limit. Completion time as
/// [`PickPlaceJudge`]'s.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TowerConfig {
    /// The blocks from the bottom of the tower up (their names in the scene), at
    /// least two.
    pub blocks: Vec<String>,
    /// Each block's half height (upright), in the order of `blocks`, m.
    pub half_heights_m: Vec<f64>,
    /// Height of the table top, m.
    pub table_top_z_m: f64,
    /// Default 0.02 m.
    #[serde(default = "tower_defaults::align_m")]
    pub align_m: f64,
    /// Default 0.01 m.
    #[serde(default = "tower_defaults::seat_m")]
    pub seat_m: f64,
    /// Default 10 deg.
    #[serde(default = "tower_defaults::upright_deg")]
    pub upright_deg: f64,
    /// The tower stands this long, s. Default 2.
    #[serde(default = "tower_defaults::stand_s")]
    pub stand_s: f64,
    /// A block counts as lifted once its centre rose this far above where it first
    /// rested, m. Default 0.02.
    #[serde(default = "defaults::lift_m")]
    pub lift_m: f64,
    /// The blocks are at rest below this speed of their centres, m/s. Default 0.01.
    #[serde(default = "defaults::settle_speed_m_s")]
    pub settle_speed_m_s: f64,
    /// Default 0.02 rad.
    #[serde(default = "defaults::start_motion_rad")]
    pub start_motion_rad: f64,
    /// Default 0.05 rad.
    #[serde(default = "defaults::home_tolerance_rad")]
    pub home_tolerance_rad: f64,
    /// Default 0.05 m.
    #[serde(default = "defaults::fallen_below_table_m")]
    pub fallen_below_table_m: f64,
    /// Default 300 s.
    #[serde(default = "defaults::time_limit_s")]
    pub time_limit_s: f64,
}

mod tower_defaults {
    pub fn align_m() -> f64 {
        0.02
    }
    pub fn seat_m() -> f64 {
        0.01
    }
    pub fn upright_deg() -> f64 {
        10.0
    }
    pub fn stand_s() -> f64 {
        2.0
    }
}

impl TowerConfig {
    fn clock_limits(&self) -> ClockLimits {
        ClockLimits {
            table_top_z_m: self.table_top_z_m,
            fallen_below_table_m: self.fallen_below_table_m,
            time_limit_s: self.time_limit_s,
            start_motion_rad: self.start_motion_rad,
        }
    }

    /// A tower of `blocks` (bottom up, with their half heights) on a table top at
    /// `table_top_z_m`, judged with the default tolerances.
    #[must_use]
    pub fn new(blocks: &[(&str, f64)], table_top_z_m: f64) -> Self {
        Self {
            blocks: blocks.iter().map(|(n, _)| (*n).to_owned()).collect(),
            half_heights_m: blocks.iter().map(|(_, h)| *h).collect(),
            table_top_z_m,
            align_m: tower_defaults::align_m(),
            seat_m: tower_defaults::seat_m(),
            upright_deg: tower_defaults::upright_deg(),
            stand_s: tower_defaults::stand_s(),
            lift_m: defaults::lift_m(),
            settle_speed_m_s: defaults::settle_speed_m_s(),
            start_motion_rad: defaults::start_motion_rad(),
            home_tolerance_rad: defaults::home_tolerance_rad(),
            fallen_below_table_m: defaults::fallen_below_table_m(),
            time_limit_s: defaults::time_limit_s(),
        }
    }

    /// At least two blocks, named once each, a positive half height for each, every
    /// number finite and in range.
    ///
    /// # Errors
    /// [`JudgeError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), JudgeError> {
        let bad = |field: &'static str, why: String| Err(JudgeError::Config { field, why });
        if self.blocks.len() < 2 {
            return bad(
                "blocks",
                format!("{} named; a tower needs two or more", self.blocks.len()),
            );
        }
        if let Some(b) = self.blocks.iter().find(|b| b.trim().is_empty()) {
            return bad("blocks", format!("an empty name ({b:?})"));
        }
        for (i, b) in self.blocks.iter().enumerate() {
            if self.blocks[..i].contains(b) {
                return bad("blocks", format!("{b} named twice"));
            }
        }
        if self.half_heights_m.len() != self.blocks.len() {
            return bad(
                "half_heights_m",
                format!(
                    "{} given for {} blocks",
                    self.half_heights_m.len(),
                    self.blocks.len()
                ),
            );
        }
        if !self.table_top_z_m.is_finite() {
            return bad("table_top_z_m", "not finite".into());
        }
        let positive = [
            (
                "half_heights_m",
                self.half_heights_m
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, least),
            ),
            ("align_m", self.align_m),
            ("seat_m", self.seat_m),
            ("upright_deg", self.upright_deg),
            ("stand_s", self.stand_s),
            ("lift_m", self.lift_m),
            ("settle_speed_m_s", self.settle_speed_m_s),
            ("start_motion_rad", self.start_motion_rad),
            ("home_tolerance_rad", self.home_tolerance_rad),
            ("fallen_below_table_m", self.fallen_below_table_m),
            ("time_limit_s", self.time_limit_s),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, format!("{v} is not a positive number"));
            }
        }
        Ok(())
    }
}

/// Judges one tower-building job; see [`TowerConfig`].
#[derive(Debug, Clone)]
pub struct TowerJudge {
    config: TowerConfig,
    clock: JobClock,
    /// Where each block first rested.
    rest_m: Option<Vec<Vector3<f64>>>,
    lifted: Vec<bool>,
    last: Option<(f64, Vec<Vector3<f64>>)>,
    standing_since_s: Option<f64>,
    verdict: Verdict,
}

impl TowerJudge {
    /// # Errors
    /// [`JudgeError::Config`] naming a bad setting.
    pub fn new(config: TowerConfig) -> Result<Self, JudgeError> {
        config.validate()?;
        let n = config.blocks.len();
        Ok(Self {
            config,
            clock: JobClock::default(),
            rest_m: None,
            lifted: vec![false; n],
            last: None,
            standing_since_s: None,
            verdict: Verdict::Running,
        })
    }

    /// The job's settings.
    #[must_use]
    pub fn config(&self) -> &TowerConfig {
        &self.config
    }

    /// The verdict so far.
    #[must_use]
    pub fn verdict(&self) -> &Verdict {
        &self.verdict
    }

    /// When the robot first moved (judge time, s).
    #[must_use]
    pub fn started_s(&self) -> Option<f64> {
        self.clock.moved_at_s
    }

    /// Whether any block above the lowest has been lifted off its resting place.
    #[must_use]
    pub fn lifted(&self) -> bool {
        self.lifted.iter().skip(1).any(|l| *l)
    }

    /// How many blocks stand on the lowest as a tower now (0 when the second does not
    /// rest on it): the highest `k` with blocks `1..=k` each resting on the one below.
    #[must_use]
    pub fn stacked(&self) -> usize {
        let Some((_, last)) = &self.last else {
            return 0;
        };
        self.stacked_of(last, None)
    }

    /// The blocks resting one on another from the bottom (see [`Self::stacked`]), given
    /// their positions and (when known) their tilts.
    fn stacked_of(&self, p: &[Vector3<f64>], tilt_deg: Option<&[f64]>) -> usize {
        let c = &self.config;
        (1..p.len())
            .take_while(|&i| {
                let (below, above) = (p[i - 1], p[i]);
                let apart = (above - below).xy().norm();
                let rise = above.z - below.z - (c.half_heights_m[i - 1] + c.half_heights_m[i]);
                let upright =
                    tilt_deg.is_none_or(|t| t[i] <= c.upright_deg && t[i - 1] <= c.upright_deg);
                apart <= c.align_m && rise.abs() <= c.seat_m && upright
            })
            .count()
    }

    /// One observation at `time_s`: the arm's joint positions and every object's pose.
    /// The first observation fixes the arm's starting pose and the blocks' resting
    /// places. A final verdict stays as it is.
    ///
    /// # Errors
    /// [`JudgeError`] for input it cannot use: non-finite numbers, time going back, a
    /// block missing, a different number of arm joints. Nothing is changed then.
    pub fn step(
        &mut self,
        time_s: f64,
        arm_rad: &[f64],
        objects: &[(String, Isometry3<f64>)],
    ) -> Result<&Verdict, JudgeError> {
        let c = &self.config;
        let names: Vec<&str> = c.blocks.iter().map(String::as_str).collect();
        self.clock.check(time_s, arm_rad, objects, &names)?;
        let poses: Vec<Isometry3<f64>> = c
            .blocks
            .iter()
            .map(|b| {
                objects
                    .iter()
                    .find(|(n, _)| n == b)
                    .map(|(_, p)| *p)
                    .ok_or_else(|| JudgeError::MissingObject(b.clone()))
            })
            .collect::<Result<_, _>>()?;
        let p: Vec<Vector3<f64>> = poses.iter().map(|q| q.translation.vector).collect();
        let tilt_deg: Vec<f64> = poses
            .iter()
            .map(|q| {
                (q.rotation * Vector3::z())
                    .angle(&Vector3::z())
                    .to_degrees()
            })
            .collect();
        let rest = self.rest_m.get_or_insert_with(|| p.clone()).clone();
        let previous = self.last.replace((time_s, p.clone()));
        if self.verdict.is_final() {
            self.clock.last_time_s = Some(time_s);
            return Ok(&self.verdict);
        }
        let limits = c.clock_limits();
        let Some(away_rad) =
            self.clock
                .observe(&mut self.verdict, time_s, arm_rad, objects, &limits)
        else {
            return Ok(&self.verdict);
        };
        let c = &self.config;
        for (i, (now, was)) in p.iter().zip(&rest).enumerate() {
            if now.z > was.z + c.lift_m {
                self.lifted[i] = true;
            }
        }
        let fastest = match &previous {
            Some((t, q)) => p
                .iter()
                .zip(q)
                .map(|(a, b)| speed(Some((*t, *b)), time_s, a))
                .fold(0.0, f64::max),
            None => f64::INFINITY,
        };
        let built = self.lifted.iter().skip(1).all(|l| *l)
            && self.stacked_of(&p, Some(&tilt_deg)) == p.len() - 1;
        if built && fastest < c.settle_speed_m_s {
            self.standing_since_s.get_or_insert(time_s);
        } else if fastest.is_finite() || !built {
            // A repeated time stamp (speed unknown) keeps the count going.
            self.standing_since_s = None;
        }
        let stood = self
            .standing_since_s
            .is_some_and(|since| time_s - since >= c.stand_s);
        if let Some(moved) = self.clock.moved_at_s
            && stood
            && away_rad <= c.home_tolerance_rad
        {
            self.verdict = Verdict::Succeeded {
                completion_s: time_s - moved,
            };
        }
        Ok(&self.verdict)
    }
}

/// The judge of whichever job a scene has.
#[derive(Debug, Clone)]
pub enum JobJudge {
    PickPlace(PickPlaceJudge),
    Tower(TowerJudge),
}

impl JobJudge {
    /// The verdict so far.
    #[must_use]
    pub fn verdict(&self) -> &Verdict {
        match self {
            JobJudge::PickPlace(j) => j.verdict(),
            JobJudge::Tower(j) => j.verdict(),
        }
    }

    /// When the robot first moved (judge time, s).
    #[must_use]
    pub fn started_s(&self) -> Option<f64> {
        match self {
            JobJudge::PickPlace(j) => j.started_s(),
            JobJudge::Tower(j) => j.started_s(),
        }
    }

    /// Whether the (or, for a tower, any) object to move has been lifted.
    #[must_use]
    pub fn lifted(&self) -> bool {
        match self {
            JobJudge::PickPlace(j) => j.lifted(),
            JobJudge::Tower(j) => j.lifted(),
        }
    }

    /// One observation; see [`PickPlaceJudge::step`] and [`TowerJudge::step`].
    ///
    /// # Errors
    /// [`JudgeError`] for input the judge cannot use; nothing is changed then.
    pub fn step(
        &mut self,
        time_s: f64,
        arm_rad: &[f64],
        objects: &[(String, Isometry3<f64>)],
    ) -> Result<&Verdict, JudgeError> {
        match self {
            JobJudge::PickPlace(j) => j.step(time_s, arm_rad, objects),
            JobJudge::Tower(j) => j.step(time_s, arm_rad, objects),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TABLE_Z: f64 = 0.55;
    const DT: f64 = 0.01;

    fn config() -> PickPlaceConfig {
        PickPlaceConfig::new(
            "can",
            TargetRegion {
                centre_m: [0.8, -0.3, TABLE_Z + 0.06],
                half_extent_m: [0.05, 0.05, 0.03],
            },
            TABLE_Z,
        )
    }

    fn poses(can: [f64; 3], cube: [f64; 3]) -> Vec<(String, Isometry3<f64>)> {
        vec![
            (
                "can".to_owned(),
                Isometry3::translation(can[0], can[1], can[2]),
            ),
            (
                "cube".to_owned(),
                Isometry3::translation(cube[0], cube[1], cube[2]),
            ),
        ]
    }

    fn lerp(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
        [0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * s)
    }

    const REST: [f64; 3] = [0.8, 0.0, TABLE_Z + 0.06];
    const CUBE: [f64; 3] = [0.9, 0.1, TABLE_Z + 0.02];
    const PLACED: [f64; 3] = [0.81, -0.29, TABLE_Z + 0.06];

    /// A scripted job: still for 1 s; the arm reaches out (1 s); carries the can up and
    /// over to `to` (2 s); lets go and goes home (1 s); holds still for 2 s.
    fn run(judge: &mut PickPlaceJudge, to: [f64; 3], lift: f64) -> Vec<(f64, Verdict)> {
        let mut out = Vec::new();
        let mut t = 0.0;
        let mut go = |t: f64, arm: f64, can: [f64; 3], judge: &mut PickPlaceJudge| {
            let v = judge
                .step(t, &[arm, -arm, 0.0, 0.0, 0.0, 0.0, 0.0], &poses(can, CUBE))
                .unwrap()
                .clone();
            out.push((t, v));
        };
        for _ in 0..100 {
            go(t, 0.0, REST, judge);
            t += DT;
        }
        for k in 0..100 {
            go(t, 0.3 * f64::from(k) / 100.0, REST, judge);
            t += DT;
        }
        let above = lerp(REST, to, 0.5);
        let high = [above[0], above[1], REST[2] + lift];
        for k in 0..200 {
            let s = f64::from(k) / 200.0;
            let p = if s < 0.5 {
                lerp(REST, high, s * 2.0)
            } else {
                lerp(high, to, (s - 0.5) * 2.0)
            };
            go(t, 0.3, p, judge);
            t += DT;
        }
        for k in 0..100 {
            go(t, 0.3 * (1.0 - f64::from(k + 1) / 100.0), to, judge);
            t += DT;
        }
        for _ in 0..200 {
            go(t, 0.0, to, judge);
            t += DT;
        }
        out
    }

    #[test]
    fn a_carried_and_placed_object_with_the_arm_home_succeeds_timed_from_the_first_motion() {
        let mut judge = PickPlaceJudge::new(config()).unwrap();
        let out = run(&mut judge, PLACED, 0.1);
        let Verdict::Succeeded { completion_s } = judge.verdict().clone() else {
            panic!("{:?}", judge.verdict());
        };
        // First motion at 1.07 s (past 0.02 rad of a 0.3 rad ramp over 1 s from 1.0 s);
        // the can at rest in the target from 4.01 s (0.5 s needed); the arm within
        // 0.05 rad of its start at 4.83 s.
        let started = judge.started_s().unwrap();
        assert!((started - 1.07).abs() < 0.005, "{started}");
        assert!(
            (completion_s - (4.83 - 1.07)).abs() < 0.005,
            "{completion_s}"
        );
        // Running until then, final afterwards.
        let first = out.iter().position(|(_, v)| v.is_final()).unwrap();
        assert!(out[..first].iter().all(|(_, v)| *v == Verdict::Running));
        assert!(out[first..].iter().all(|(_, v)| v.is_final()));
    }

    #[test]
    fn pushing_it_in_without_lifting_or_leaving_the_arm_out_is_not_success() {
        // Slid along the table (never 2 cm up).
        let mut judge = PickPlaceJudge::new(config()).unwrap();
        run(&mut judge, PLACED, 0.0);
        assert!(!judge.lifted());
        assert_eq!(*judge.verdict(), Verdict::Running);
        // Put down outside the target.
        let mut judge = PickPlaceJudge::new(config()).unwrap();
        run(&mut judge, [0.8, -0.15, REST[2]], 0.1);
        assert!(judge.lifted());
        assert_eq!(*judge.verdict(), Verdict::Running);
        // Placed, but the arm stays out.
        let mut judge = PickPlaceJudge::new(config()).unwrap();
        let mut t = 0.0;
        for (q, p) in [
            (0.0, REST),
            (0.3, REST),
            (0.3, [0.8, 0.0, 0.7]),
            (0.3, PLACED),
        ] {
            for _ in 0..100 {
                judge.step(t, &[q; 7], &poses(p, CUBE)).unwrap();
                t += DT;
            }
        }
        for _ in 0..300 {
            judge.step(t, &[0.3; 7], &poses(PLACED, CUBE)).unwrap();
            t += DT;
        }
        assert_eq!(*judge.verdict(), Verdict::Running);
        // ... and succeeds once it is back.
        judge.step(t, &[0.01; 7], &poses(PLACED, CUBE)).unwrap();
        assert!(matches!(judge.verdict(), Verdict::Succeeded { .. }));
    }

    #[test]
    fn an_object_off_the_table_or_the_time_limit_fails_and_the_verdict_stays() {
        let mut judge = PickPlaceJudge::new(config()).unwrap();
        judge.step(0.0, &[0.0; 7], &poses(REST, CUBE)).unwrap();
        judge
            .step(0.1, &[0.1; 7], &poses(REST, [1.2, 0.1, 0.3]))
            .unwrap();
        assert_eq!(
            *judge.verdict(),
            Verdict::Failed {
                failure: Failure::FellOffTable {
                    object: "cube".into()
                },
                at_s: 0.1
            }
        );
        judge.step(0.2, &[0.0; 7], &poses(PLACED, CUBE)).unwrap();
        assert!(matches!(judge.verdict(), Verdict::Failed { .. }));

        let mut c = config();
        c.time_limit_s = 1.0;
        let mut judge = PickPlaceJudge::new(c).unwrap();
        judge.step(0.0, &[0.0; 7], &poses(REST, CUBE)).unwrap();
        judge.step(1.0, &[0.0; 7], &poses(REST, CUBE)).unwrap();
        assert_eq!(*judge.verdict(), Verdict::Running);
        judge.step(1.01, &[0.0; 7], &poses(REST, CUBE)).unwrap();
        assert_eq!(
            *judge.verdict(),
            Verdict::Failed {
                failure: Failure::TimedOut,
                at_s: 1.01
            }
        );
    }

    #[test]
    fn bad_input_is_named_and_changes_nothing() {
        let mut judge = PickPlaceJudge::new(config()).unwrap();
        judge.step(1.0, &[0.0; 7], &poses(REST, CUBE)).unwrap();
        let e = judge.step(0.5, &[0.0; 7], &poses(REST, CUBE)).unwrap_err();
        assert!(e.to_string().contains("time went back"), "{e}");
        let e = judge
            .step(1.1, &[f64::NAN; 7], &poses(REST, CUBE))
            .unwrap_err();
        assert!(e.to_string().contains("arm joint 0"), "{e}");
        let e = judge
            .step(1.1, &[0.0; 7], &poses([f64::NAN, 0.0, 0.0], CUBE))
            .unwrap_err();
        assert!(e.to_string().contains("pose of can"), "{e}");
        let e = judge
            .step(1.1, &[0.0; 7], &poses(REST, CUBE)[1..])
            .unwrap_err();
        assert!(e.to_string().contains("no object named can"), "{e}");
        let e = judge.step(1.1, &[0.0; 6], &poses(REST, CUBE)).unwrap_err();
        assert!(e.to_string().contains("6 arm joints, 7"), "{e}");
        // None of the refused inputs changed the verdict.
        assert_eq!(*judge.verdict(), Verdict::Running);
        let mut c = config();
        c.settle_s = -1.0;
        let e = PickPlaceJudge::new(c).unwrap_err();
        assert!(e.to_string().contains("settle_s"), "{e}");
        let mut c = config();
        c.target.half_extent_m[2] = 0.0;
        let e = PickPlaceJudge::new(c).unwrap_err();
        assert!(e.to_string().contains("target.half_extent_m"), "{e}");
        let e = toml::from_str::<PickPlaceConfig>(
            "object = \"can\"\ntable_top_z_m = 0.55\nlift = 0.1\n[target]\ncentre_m = [0, 0, 0]\nhalf_extent_m = [1, 1, 1]\n",
        )
        .unwrap_err();
        assert!(e.to_string().contains("unknown field `lift`"), "{e}");
    }

    // Three blocks of half heights 0.03, 0.04, 0.025 m: the base stays, the other two
    // are stacked on it.
    const H: [f64; 3] = [0.03, 0.04, 0.025];
    const BASE: [f64; 3] = [0.8, -0.1, TABLE_Z + H[0]];
    const B0: [f64; 3] = [0.8, 0.05, TABLE_Z + H[1]];
    const C0: [f64; 3] = [0.8, 0.15, TABLE_Z + H[2]];

    fn tower_config() -> TowerConfig {
        TowerConfig::new(&[("base", H[0]), ("middle", H[1]), ("top", H[2])], TABLE_Z)
    }

    fn blocks(b: [f64; 3], m: [f64; 3], t: [f64; 3]) -> Vec<(String, Isometry3<f64>)> {
        [("base", b), ("middle", m), ("top", t)]
            .into_iter()
            .map(|(n, p)| (n.to_owned(), Isometry3::translation(p[0], p[1], p[2])))
            .collect()
    }

    /// On the base: `dxy` off its centre, `dz` above resting on it.
    fn on(below: [f64; 3], h_below: f64, h: f64, dxy: f64, dz: f64) -> [f64; 3] {
        [below[0] + dxy, below[1], below[2] + h_below + h + dz]
    }

    /// A scripted build: still 1 s; the arm out (1 s); the middle block carried up and
    /// onto `middle` (2 s), the top block onto `top` (2 s); the arm home (1 s); still
    /// for `hold_s`.
    fn build(judge: &mut TowerJudge, middle: [f64; 3], top: [f64; 3], hold_s: f64) {
        let mut t = 0.0;
        let mut go = |arm: f64, m: [f64; 3], tp: [f64; 3], judge: &mut TowerJudge| {
            judge.step(t, &[arm; 7], &blocks(BASE, m, tp)).unwrap();
            t += DT;
        };
        for _ in 0..100 {
            go(0.0, B0, C0, judge);
        }
        for k in 0..100 {
            go(0.3 * f64::from(k) / 100.0, B0, C0, judge);
        }
        let carry = |from: [f64; 3], to: [f64; 3], s: f64| {
            let high = [from[0], from[1], to[2] + 0.05];
            if s < 0.5 {
                lerp(from, high, s * 2.0)
            } else {
                lerp(high, to, (s - 0.5) * 2.0)
            }
        };
        for k in 0..200 {
            go(0.3, carry(B0, middle, f64::from(k) / 200.0), C0, judge);
        }
        for k in 0..200 {
            go(0.3, middle, carry(C0, top, f64::from(k) / 200.0), judge);
        }
        for k in 0..100 {
            go(0.3 * (1.0 - f64::from(k + 1) / 100.0), middle, top, judge);
        }
        for _ in 0..(hold_s / DT) as usize {
            go(0.0, middle, top, judge);
        }
    }

    #[test]
    fn a_tower_standing_two_seconds_with_the_arm_home_succeeds_timed_from_the_first_motion() {
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        let middle = on(BASE, H[0], H[1], 0.01, 0.002);
        let top = on(middle, H[1], H[2], -0.01, -0.003);
        build(&mut judge, middle, top, 2.5);
        let Verdict::Succeeded { completion_s } = judge.verdict().clone() else {
            panic!("{:?}", judge.verdict());
        };
        assert_eq!(judge.stacked(), 2);
        // First motion at 1.07 s; the top block at rest on the tower from 6.01 s (its
        // last step in at 6.0 s), standing 2 s at 8.01 s (+ one step of the summed
        // time's rounding), by when the arm is home (6.83 s).
        assert!((judge.started_s().unwrap() - 1.07).abs() < 0.005);
        assert!(
            (completion_s - (8.01 - 1.07)).abs() < 0.015,
            "{completion_s}"
        );
        // Standing for less than 2 s is not yet a success.
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        build(&mut judge, middle, top, 0.9);
        assert_eq!(*judge.verdict(), Verdict::Running);
        assert_eq!(judge.stacked(), 2);
    }

    #[test]
    fn blocks_beside_each_other_too_far_off_centre_or_tilted_are_no_tower() {
        // The top block put on the table beside the tower.
        let middle = on(BASE, H[0], H[1], 0.0, 0.0);
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        build(&mut judge, middle, [0.9, -0.1, TABLE_Z + H[2]], 3.0);
        assert_eq!(*judge.verdict(), Verdict::Running);
        assert_eq!(judge.stacked(), 1);
        // The middle block 2.5 cm off the base's centre (the top on it).
        let middle = on(BASE, H[0], H[1], 0.025, 0.0);
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        build(&mut judge, middle, on(middle, H[1], H[2], 0.0, 0.0), 3.0);
        assert_eq!(*judge.verdict(), Verdict::Running);
        assert_eq!(judge.stacked(), 0);
        // Held 2 cm above the base (not resting on it).
        let middle = on(BASE, H[0], H[1], 0.0, 0.02);
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        build(&mut judge, middle, on(middle, H[1], H[2], 0.0, 0.0), 3.0);
        assert_eq!(*judge.verdict(), Verdict::Running);
        // Tilted 20 deg: at rest on the tower, in place, but leaning.
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        let middle = on(BASE, H[0], H[1], 0.0, 0.0);
        let top = on(middle, H[1], H[2], 0.0, 0.0);
        let mut t = 0.0;
        for (arm, tilt) in [(0.0, 0.0), (0.3, 0.0), (0.0, 20f64.to_radians())] {
            for _ in 0..300 {
                let mut b = blocks(
                    BASE,
                    if tilt > 0.0 { middle } else { B0 },
                    if tilt > 0.0 { top } else { C0 },
                );
                b[2].1.rotation =
                    nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt);
                judge.step(t, &[arm; 7], &b).unwrap();
                t += DT;
            }
        }
        assert_eq!(*judge.verdict(), Verdict::Running);
        assert_eq!(judge.stacked(), 2, "positions alone are stacked");
    }

    #[test]
    fn a_tower_judge_refuses_bad_settings_and_input_by_name() {
        let e = TowerJudge::new(TowerConfig::new(&[("base", 0.03)], TABLE_Z)).unwrap_err();
        assert!(e.to_string().contains("blocks"), "{e}");
        let e =
            TowerJudge::new(TowerConfig::new(&[("a", 0.03), ("a", 0.03)], TABLE_Z)).unwrap_err();
        assert!(e.to_string().contains("a named twice"), "{e}");
        let e =
            TowerJudge::new(TowerConfig::new(&[("a", 0.03), ("b", -0.03)], TABLE_Z)).unwrap_err();
        assert!(e.to_string().contains("half_heights_m"), "{e}");
        let mut c = tower_config();
        c.half_heights_m.pop();
        let e = TowerJudge::new(c).unwrap_err();
        assert!(e.to_string().contains("2 given for 3 blocks"), "{e}");
        let mut c = tower_config();
        c.half_heights_m[1] = f64::NAN;
        assert!(
            TowerJudge::new(c)
                .unwrap_err()
                .to_string()
                .contains("half_heights_m")
        );
        let mut c = tower_config();
        c.stand_s = f64::NAN;
        assert!(
            TowerJudge::new(c)
                .unwrap_err()
                .to_string()
                .contains("stand_s")
        );
        let mut judge = TowerJudge::new(tower_config()).unwrap();
        judge.step(0.0, &[0.0; 7], &blocks(BASE, B0, C0)).unwrap();
        let e = judge
            .step(0.1, &[0.0; 7], &blocks(BASE, B0, C0)[..2])
            .unwrap_err();
        assert!(e.to_string().contains("no object named top"), "{e}");
        let e = judge
            .step(0.1, &[0.0; 7], &blocks(BASE, [f64::NAN; 3], C0))
            .unwrap_err();
        assert!(e.to_string().contains("pose of middle"), "{e}");
        // A block off the table fails the job.
        judge
            .step(0.2, &[0.0; 7], &blocks(BASE, B0, [1.3, 0.0, 0.2]))
            .unwrap();
        assert!(matches!(
            judge.verdict(),
            Verdict::Failed { failure: Failure::FellOffTable { object }, .. } if object == "top"
        ));
    }
}
