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
                    .fold(f64::INFINITY, f64::min),
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

#[derive(Debug, Clone)]
struct Start {
    time_s: f64,
    arm_rad: Vec<f64>,
    rest_m: Vector3<f64>,
}

/// Judges one pick-and-place job; see the module documentation.
#[derive(Debug, Clone)]
pub struct PickPlaceJudge {
    config: PickPlaceConfig,
    start: Option<Start>,
    moved_at_s: Option<f64>,
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
            start: None,
            moved_at_s: None,
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
        self.moved_at_s
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
        if !time_s.is_finite() {
            return Err(JudgeError::NonFinite {
                what: "the time".into(),
            });
        }
        if let Some((last_s, _)) = self.last
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
        let object = objects
            .iter()
            .find(|(n, _)| *n == self.config.object)
            .map(|(_, p)| p.translation.vector)
            .ok_or_else(|| JudgeError::MissingObject(self.config.object.clone()))?;
        if let Some(start) = &self.start
            && start.arm_rad.len() != arm_rad.len()
        {
            return Err(JudgeError::ArmSize {
                got: arm_rad.len(),
                expected: start.arm_rad.len(),
            });
        }
        let start = self
            .start
            .get_or_insert_with(|| Start {
                time_s,
                arm_rad: arm_rad.to_vec(),
                rest_m: object,
            })
            .clone();
        let previous = self.last.replace((time_s, object));
        if self.verdict.is_final() {
            return Ok(&self.verdict);
        }
        let c = &self.config;
        if let Some((name, _)) = objects
            .iter()
            .find(|(_, p)| p.translation.z < c.table_top_z_m - c.fallen_below_table_m)
        {
            self.verdict = Verdict::Failed {
                failure: Failure::FellOffTable {
                    object: name.clone(),
                },
                at_s: time_s,
            };
            return Ok(&self.verdict);
        }
        if time_s - start.time_s > c.time_limit_s {
            self.verdict = Verdict::Failed {
                failure: Failure::TimedOut,
                at_s: time_s,
            };
            return Ok(&self.verdict);
        }
        let away_rad = arm_rad
            .iter()
            .zip(&start.arm_rad)
            .map(|(q, q0)| (q - q0).abs())
            .fold(0.0, f64::max);
        if self.moved_at_s.is_none() && away_rad > c.start_motion_rad {
            self.moved_at_s = Some(time_s);
        }
        if object.z > start.rest_m.z + c.lift_m {
            self.lifted = true;
        }
        // The object's speed from the last observation (none yet: not at rest).
        let speed = match previous {
            Some((t, p)) if time_s > t => (object - p).norm() / (time_s - t),
            Some((_, p)) if object == p => 0.0,
            _ => f64::INFINITY,
        };
        if self.lifted && c.target.contains(&object) && speed < c.settle_speed_m_s {
            self.resting_in_target_since_s.get_or_insert(time_s);
        } else if speed.is_finite() || !c.target.contains(&object) {
            // A repeated time stamp (speed unknown) keeps the count going.
            self.resting_in_target_since_s = None;
        }
        let placed = self
            .resting_in_target_since_s
            .is_some_and(|since| time_s - since >= c.settle_s);
        if let Some(moved) = self.moved_at_s
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
}
