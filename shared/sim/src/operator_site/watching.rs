//! The operator who watches the display (issue 29): instead of replaying a script, the
//! simulated operator closes the loop as the thesis's operators did, through what
//! reaches the operator site and nothing else.
//!
//! # What it perceives
//! * The robot: the PR2 arm's and the Shadow hand's joint states as they arrive over
//!   the WAN ([`RobotPercept`]: the palm's pose by the nominal forward kinematics, the
//!   mean flexion of the four fingers' J3), as a 3D view of the received joint states
//!   would show them.
//! * The objects: only as the newest camera view the site has received shows them. The
//!   robot-site simulator publishes the objects' true poses stamped like the views it
//!   renders from the same world state; [`ViewGate`] hands on the newest pose sample
//!   no newer than the newest received view, so a lost, late or withheld view leaves
//!   the operator with the older picture.
//! * Everything a reaction delay (default 200 ms) after it arrived.
//!
//! # What it does
//! A pick-and-place job as a sequence of goals for the robot's palm ([`Phase`]): hover
//! above the object, descend to the grasp, close the hand (the power synergy), lift,
//! check it came along (else open and try again), carry over the target, lower until
//! the object rests, open, retreat upward, go back to the starting pose, let go of the
//! clutch. Each goal is reached by submovements, as people move: a minimum-jerk move of
//! the hand that, by the operator's learned mapping (hand displacement times the motion
//! scale, turned by the operator-to-robot rotation), should bring the palm to the goal;
//! then a wait until a view captured after the move shows the robot at rest; then a
//! correction by the remaining error, until it is within the phase's tolerance. Delay,
//! loss and a bandwidth cap thus lengthen every wait and every correction, as they
//! would a person's. Every decision is logged with what was perceived.
//!
//! The core is pure: [`WatchingOperator::step`] takes the time and returns the hand's
//! offset, rotation, finger posture and clutch; percepts come in through
//! [`WatchingOperator::perceive_robot`] / [`WatchingOperator::perceive_scene`].

use std::collections::VecDeque;

use nalgebra::{Isometry3, Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_hand_model::sampling::Synergy;

use super::tasks::{Grasp, TaskSample};

/// Which operator model drives the operator-site world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OperatorModel {
    /// The scripted, open-loop task ([`super::TaskKind`]).
    #[default]
    Scripted,
    /// The operator who watches the display and does the robot world's pick job.
    Watching,
}

/// Where a placement puts its object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Onto {
    /// On the table, this far from the palm's starting position (world x-y, m).
    Table { from_start_palm_xy_m: [f64; 2] },
    /// On top of another object, centred on it as seen; `half_height_m` is that
    /// object's half height as the operator sees it.
    Object { name: String, half_height_m: f64 },
}

/// One object to move, and where to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// The object, by its name in the robot world.
    pub object: String,
    /// Its half height (upright) as the operator sees it, m: the grasp goes
    /// `grasp_above_top_m` above its top, and on another object it rests this much
    /// above that object's top. The per-seed variation of sizes is not seen.
    pub half_height_m: f64,
    pub onto: Onto,
}

impl Placement {
    /// The pick job's: the can (23 cm tall) onto the table 10 cm beyond the palm's start
    /// (the robot world's default target, `[pick.job]`).
    #[must_use]
    pub fn pick_can() -> Self {
        Self {
            object: "can".to_owned(),
            half_height_m: 0.115,
            onto: Onto::Table {
                from_start_palm_xy_m: [0.1, 0.0],
            },
        }
    }
}

/// Settings of the watching operator. The job (which objects, where to) must match the
/// robot world's (`[pick.job]`, `[tower]`): the operator is told the task as a person
/// would be.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WatchingConfig {
    /// Time from a percept's arrival until the operator acts on it, s. Default 0.2 (a
    /// visual reaction time).
    pub reaction_delay_s: f64,
    /// The objects to move, in order. Default: the pick job's can onto the table
    /// ([`Placement::pick_can`]); the tower job puts one block on another, then a third
    /// on those.
    pub placements: Vec<Placement>,
    /// The rotation the operator has learned between its hand's motion and the robot's
    /// (roll, pitch, yaw, deg). Default identity: the arm controller's default
    /// `operator_to_robot_rpy_deg`.
    pub robot_from_operator_rpy_deg: [f64; 3],
    /// Before reaching, turn the hand about its fingers so the robot's palm faces the
    /// object (a side grasp: at the PR2's working posture the palm faces down and
    /// forward, the thumb hanging below it). Default false: the pick job grasps the can
    /// from the top, the palm facing down as it starts
    /// ([`crate::PICK_TOP_GRASP_POSTURE_RAD`]); no side grasp of the can held in the
    /// physical world (docs/physics.md).
    pub turn_to_face_object: bool,
    /// Speed of that turn, deg/s. Default 14 (the pouring task's 90 deg in 6.5 s, which
    /// the camera arm can follow).
    pub turn_speed_deg_s: f64,
    /// A point in the palm's frame (-y out of the palm, z along the fingers) that goes
    /// `grasp_above_top_m` above the object's top at the grasp, m. Default [0,
    /// -0.017, 0.075]: 5 mm out of the palm's 12 mm half thickness, 7.5 cm along the
    /// fingers, where the closing fingers wrap the can's rim from the far side and the
    /// thumb from the near side. Measured with `cargo run --release -p teleop-sim
    /// --example grasp_study` from the pick job's start posture, with the fingers'
    /// targets of the power synergy and those the hand network sent in a run: the grasp
    /// lifted and carried the can with its axis 6-9 cm along the fingers and 1 cm to
    /// either side, its top from 0 to 1.5 cm below that point; 2 cm below, it tipped or
    /// stayed behind.
    pub object_in_palm_m: [f64; 3],
    /// The grasp puts that point this far above the object's top, m. Default 0.0075:
    /// the middle of the window that held the can (its height varies by 5 % per seed,
    /// +-6 mm at its top, which the operator does not see).
    pub grasp_above_top_m: f64,
    /// The pre-grasp pose and the retreat are this far back along the palm's back (the
    /// retreat also `lift_m` up), m. Default 0.08.
    pub approach_m: f64,
    /// Care for tall objects left standing (the tower job): retreat straight up
    /// (`approach_m` + `lift_m`) instead of back along the palm's back, whose sideways
    /// part pulled a placed block over, and go back level to above the start before
    /// descending to it, instead of straight, which swept the hand through the tower
    /// standing higher than the start. Default false.
    pub clear_tall_objects: bool,
    /// Closure of the power synergy for the grasp, (0, 1]. Default 1.
    pub grasp_closure: f64,
    /// How long closing or opening the hand takes, s. Default 2.5 (closed in 1 s, the
    /// fingers flung the can).
    pub close_s: f64,
    /// Lift height, m. Default 0.08.
    pub lift_m: f64,
    /// An object carried onto another is lifted at least so high that its bottom
    /// clears the other's top by this much, m. Default 0.03.
    pub carry_clearance_m: f64,
    /// The object is let go this far above its resting height (below: pressed onto
    /// it), m. Default 0.005.
    pub release_above_m: f64,
    /// Peak speed of the palm in a submovement (at the motion scale), m/s. Default
    /// 0.12 (the arm's Cartesian limit is 0.2).
    pub peak_speed_m_s: f64,
    /// Shortest submovement, s. Default 0.5.
    pub min_move_s: f64,
    /// After a move, the operator waits for a view captured this long after its end,
    /// showing the palm at rest, s. Default 0.3.
    pub settle_s: f64,
    /// The palm counts as at rest below this speed, m/s. Default 0.02.
    pub rest_speed_m_s: f64,
    /// While approaching, the operator stops and closes the hand once it sees the
    /// object pushed this far, m. Default 0.008.
    pub contact_push_m: f64,
    /// Tolerances of the coarse goals (hover, carry, retreat) and the fine ones
    /// (descend, lower, return), m. Defaults 0.015 and 0.006.
    pub coarse_tolerance_m: f64,
    pub fine_tolerance_m: f64,
    /// Corrections per goal before the operator goes on with what it has. Default 6.
    pub max_corrections: u32,
    /// Grasp attempts before giving up. Default 3.
    pub max_attempts: u32,
}

impl Default for WatchingConfig {
    fn default() -> Self {
        Self {
            reaction_delay_s: 0.2,
            placements: vec![Placement::pick_can()],
            robot_from_operator_rpy_deg: [0.0; 3],
            turn_to_face_object: false,
            turn_speed_deg_s: 14.0,
            object_in_palm_m: [0.0, -0.017, 0.075],
            grasp_above_top_m: 0.0075,
            approach_m: 0.08,
            clear_tall_objects: false,
            grasp_closure: 1.0,
            close_s: 2.5,
            lift_m: 0.08,
            carry_clearance_m: 0.03,
            release_above_m: 0.005,
            peak_speed_m_s: 0.12,
            min_move_s: 0.5,
            settle_s: 0.3,
            rest_speed_m_s: 0.02,
            contact_push_m: 0.008,
            coarse_tolerance_m: 0.015,
            fine_tolerance_m: 0.006,
            max_corrections: 6,
            max_attempts: 3,
        }
    }
}

impl WatchingConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        teleop_control::check_ranges(
            "operator_site.watching",
            &[
                ("reaction_delay_s", self.reaction_delay_s, 0.0, 5.0),
                (
                    "robot_from_operator_rpy_deg[0]",
                    self.robot_from_operator_rpy_deg[0],
                    -180.0,
                    180.0,
                ),
                (
                    "robot_from_operator_rpy_deg[1]",
                    self.robot_from_operator_rpy_deg[1],
                    -180.0,
                    180.0,
                ),
                (
                    "robot_from_operator_rpy_deg[2]",
                    self.robot_from_operator_rpy_deg[2],
                    -180.0,
                    180.0,
                ),
                ("turn_speed_deg_s", self.turn_speed_deg_s, 1.0, 180.0),
                ("object_in_palm_m[0]", self.object_in_palm_m[0], -0.3, 0.3),
                ("object_in_palm_m[1]", self.object_in_palm_m[1], -0.3, 0.3),
                ("object_in_palm_m[2]", self.object_in_palm_m[2], -0.3, 0.3),
                ("grasp_above_top_m", self.grasp_above_top_m, -0.5, 0.5),
                ("approach_m", self.approach_m, 0.0, 0.5),
                ("grasp_closure", self.grasp_closure, 0.05, 1.0),
                ("close_s", self.close_s, 0.05, 10.0),
                ("lift_m", self.lift_m, 0.01, 0.5),
                ("carry_clearance_m", self.carry_clearance_m, 0.0, 0.3),
                ("release_above_m", self.release_above_m, -0.05, 0.1),
                ("peak_speed_m_s", self.peak_speed_m_s, 0.005, 1.0),
                ("min_move_s", self.min_move_s, 0.05, 10.0),
                ("settle_s", self.settle_s, 0.0, 10.0),
                ("rest_speed_m_s", self.rest_speed_m_s, 1e-4, 1.0),
                ("contact_push_m", self.contact_push_m, 1e-4, 0.2),
                ("coarse_tolerance_m", self.coarse_tolerance_m, 1e-4, 0.2),
                ("fine_tolerance_m", self.fine_tolerance_m, 1e-4, 0.2),
            ],
        )?;
        if self.placements.is_empty() {
            return Err("operator_site.watching.placements: no object to move".into());
        }
        for (i, p) in self.placements.iter().enumerate() {
            let field = format!("operator_site.watching.placements[{i}]");
            if p.object.trim().is_empty() {
                return Err(format!("{field}.object must name an object"));
            }
            let mut ranges = vec![("half_height_m", p.half_height_m, 1e-3, 0.5)];
            match &p.onto {
                Onto::Table {
                    from_start_palm_xy_m: [x, y],
                } => {
                    ranges.push(("onto.table.from_start_palm_xy_m[0]", *x, -1.0, 1.0));
                    ranges.push(("onto.table.from_start_palm_xy_m[1]", *y, -1.0, 1.0));
                }
                Onto::Object {
                    name,
                    half_height_m,
                } => {
                    if name.trim().is_empty() || *name == p.object {
                        return Err(format!(
                            "{field}.onto.object.name must name another object than {:?}, got {name:?}",
                            p.object
                        ));
                    }
                    ranges.push(("onto.object.half_height_m", *half_height_m, 1e-3, 0.5));
                }
            }
            teleop_control::check_ranges(&field, &ranges)?;
        }
        if self.max_attempts == 0 {
            return Err("operator_site.watching.max_attempts must be >= 1".into());
        }
        Ok(())
    }
}

/// The robot as the operator site has received it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobotPercept {
    /// Capture stamp of the joint states, s (node clock).
    pub stamp_s: f64,
    /// The palm's pose by the nominal forward kinematics, world frame.
    pub palm: Isometry3<f64>,
    /// Mean J3 flexion of the four fingers, rad.
    pub finger_flex_rad: f64,
}

/// The objects as a received camera view shows them.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenePercept {
    /// Capture stamp of the view, s (node clock).
    pub stamp_s: f64,
    /// Each object's pose, world frame.
    pub objects: Vec<(String, Isometry3<f64>)>,
}

impl ScenePercept {
    /// The pose of `name`.
    #[must_use]
    pub fn object(&self, name: &str) -> Option<&Isometry3<f64>> {
        self.objects.iter().find(|(n, _)| n == name).map(|(_, p)| p)
    }
}

/// Pairs the simulator's object poses with the camera views received: only poses no
/// newer than the newest received view pass.
#[derive(Debug, Clone, Default)]
pub struct ViewGate {
    poses: VecDeque<ScenePercept>,
    newest_view_s: Option<f64>,
    shown_s: Option<f64>,
}

/// Pose samples kept while waiting for their view (3 s of them at 30 Hz).
const GATE_DEPTH: usize = 90;

impl ViewGate {
    /// An empty gate.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// A ground-truth sample of the objects arrived.
    pub fn object_poses(&mut self, poses: ScenePercept) {
        if self
            .poses
            .back()
            .is_some_and(|p| p.stamp_s >= poses.stamp_s)
        {
            return;
        }
        if self.poses.len() == GATE_DEPTH {
            self.poses.pop_front();
        }
        self.poses.push_back(poses);
    }

    /// A camera view captured at `stamp_s` arrived.
    pub fn view_received(&mut self, stamp_s: f64) {
        if stamp_s.is_finite() && self.newest_view_s.is_none_or(|v| stamp_s > v) {
            self.newest_view_s = Some(stamp_s);
        }
    }

    /// Capture stamp of the newest view received.
    #[must_use]
    pub fn newest_view_s(&self) -> Option<f64> {
        self.newest_view_s
    }

    /// What the newest received view shows, once: the newest pose sample no newer than
    /// that view, if it has not been handed out before.
    pub fn take_visible(&mut self) -> Option<ScenePercept> {
        let view = self.newest_view_s?;
        let i = self.poses.iter().rposition(|p| p.stamp_s <= view + 1e-6)?;
        let visible = self.poses[i].clone();
        // Older samples can never be shown again.
        self.poses.drain(..i);
        if self.shown_s.is_some_and(|s| s >= visible.stamp_s) {
            return None;
        }
        self.shown_s = Some(visible.stamp_s);
        Some(visible)
    }
}

/// The steps of the pick-and-place job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Waiting to see the robot and the object (and the start delay).
    WaitingForView,
    /// Turning the hand so the palm faces the object.
    Turn,
    /// The palm to the pre-grasp pose, backed off from the grasp.
    Hover,
    /// In to the grasp.
    Approach,
    /// Closing the hand.
    Close,
    /// Lifting; checks the object came along.
    Lift,
    /// Opening the hand after a failed lift (then hover again).
    Reopen,
    /// Over the target.
    Carry,
    /// Down until the object rests on the table.
    Lower,
    /// Opening the hand.
    Release,
    /// Up, clear of the object.
    Retreat,
    /// Back to the starting pose.
    Return,
    /// Job done; the clutch is released.
    Done,
    /// Out of grasp attempts; the clutch is released.
    GaveUp,
}

impl Phase {
    /// Every phase, in order of the job.
    pub const ALL: [Phase; 14] = [
        Phase::WaitingForView,
        Phase::Turn,
        Phase::Hover,
        Phase::Approach,
        Phase::Close,
        Phase::Lift,
        Phase::Reopen,
        Phase::Carry,
        Phase::Lower,
        Phase::Release,
        Phase::Retreat,
        Phase::Return,
        Phase::Done,
        Phase::GaveUp,
    ];

    /// The name in logs.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Phase::WaitingForView => "waiting_for_view",
            Phase::Turn => "turn",
            Phase::Hover => "hover",
            Phase::Approach => "approach",
            Phase::Close => "close",
            Phase::Lift => "lift",
            Phase::Reopen => "reopen",
            Phase::Carry => "carry",
            Phase::Lower => "lower",
            Phase::Release => "release",
            Phase::Retreat => "retreat",
            Phase::Return => "return",
            Phase::Done => "done",
            Phase::GaveUp => "gave_up",
        }
    }

    /// Its index in [`Phase::ALL`] (a counter's value).
    #[must_use]
    pub fn index(self) -> u64 {
        Phase::ALL.iter().position(|p| *p == self).unwrap_or(0) as u64
    }
}

/// One decision of the operator, with what it perceived then.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    /// When, s (node clock).
    pub t_s: f64,
    /// The phase it entered (or stayed in, for a correction).
    pub phase: Phase,
    pub what: String,
}

/// Counters of the watching operator.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WatchingCounters {
    pub robot_percepts: u64,
    pub scene_percepts: u64,
    pub submovements: u64,
    pub grasp_attempts: u64,
    /// Goals given up on after `max_corrections` (the operator went on).
    pub goals_not_reached: u64,
}

/// A minimum-jerk move of a value from `from` to `to` over `[t0, t1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Move<T> {
    from: T,
    to: T,
    t0: f64,
    t1: f64,
}

fn min_jerk(t: f64, t0: f64, t1: f64) -> f64 {
    if t1 <= t0 {
        return 1.0;
    }
    let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
}

impl Move<Vector3<f64>> {
    fn at(&self, t: f64) -> Vector3<f64> {
        self.from + (self.to - self.from) * min_jerk(t, self.t0, self.t1)
    }
}

impl Move<f64> {
    fn at(&self, t: f64) -> f64 {
        self.from + (self.to - self.from) * min_jerk(t, self.t0, self.t1)
    }
}

/// Outcome of one step toward a goal.
enum Reach {
    Busy,
    Arrived,
}

/// The operator who watches the display.
#[derive(Debug, Clone)]
pub struct WatchingOperator {
    cfg: WatchingConfig,
    /// Operator axes -> robot axes.
    robot_from_operator: Rotation3<f64>,
    motion_scale: f64,
    start_delay_s: f64,
    pending: VecDeque<(f64, Percept)>,
    robot: Option<RobotPercept>,
    /// The robot percepts of the last [`HISTORY_S`], oldest first.
    robot_history: VecDeque<RobotPercept>,
    scene: Option<ScenePercept>,
    phase: Phase,
    phase_since_s: f64,
    first_step_s: Option<f64>,
    hand: Move<Vector3<f64>>,
    /// The hand's turn about its fingers, rad.
    turn: Move<f64>,
    closure: Move<f64>,
    clutch: bool,
    corrections: u32,
    start_palm: Option<Isometry3<f64>>,
    /// Which placement is under way (index into the config's).
    placement: usize,
    /// Grasp attempts of this placement.
    attempts_here: u32,
    /// Where the placement's object stood when the operator went for it, z, m.
    object_rest_z_m: f64,
    /// The phase's fixed goal (lift, retreat), world frame.
    fixed_goal: Option<Vector3<f64>>,
    decisions: Vec<Decision>,
    counters: WatchingCounters,
}

#[derive(Debug, Clone)]
enum Percept {
    Robot(RobotPercept),
    Scene(ScenePercept),
}

/// An object seen this far below its resting height has fallen off the table, m.
const LOST_BELOW_M: f64 = 0.1;
/// The operator does not reach for an object farther than this from the palm's start, m.
const REACH_M: f64 = 0.6;

/// How much of the robot's perceived past the operator keeps to judge motion, s.
const HISTORY_S: f64 = 0.3;
/// Motion is judged over at least this much of it, s.
const MOTION_WINDOW_S: f64 = 0.05;

impl WatchingOperator {
    /// An operator that starts `start_delay_s` after its first step, with the clutch
    /// released, the hand open at its resting place, sending `motion_scale`.
    ///
    /// # Errors
    /// An invalid config (the text names the field).
    pub fn new(cfg: WatchingConfig, motion_scale: f64, start_delay_s: f64) -> Result<Self, String> {
        cfg.validate()?;
        if !(motion_scale.is_finite() && motion_scale > 0.0) {
            return Err(format!("motion scale {motion_scale} must be > 0"));
        }
        let [r, p, y] = cfg.robot_from_operator_rpy_deg.map(f64::to_radians);
        let still = Move {
            from: Vector3::zeros(),
            to: Vector3::zeros(),
            t0: 0.0,
            t1: 0.0,
        };
        Ok(Self {
            robot_from_operator: Rotation3::from_euler_angles(r, p, y),
            motion_scale,
            start_delay_s: start_delay_s.max(0.0),
            pending: VecDeque::new(),
            robot: None,
            robot_history: VecDeque::new(),
            scene: None,
            phase: Phase::WaitingForView,
            phase_since_s: 0.0,
            first_step_s: None,
            hand: still,
            turn: Move {
                from: 0.0,
                to: 0.0,
                t0: 0.0,
                t1: 0.0,
            },
            closure: Move {
                from: 0.0,
                to: 0.0,
                t0: 0.0,
                t1: 0.0,
            },
            clutch: false,
            corrections: 0,
            start_palm: None,
            placement: 0,
            attempts_here: 0,
            object_rest_z_m: f64::NAN,
            fixed_goal: None,
            decisions: Vec::new(),
            counters: WatchingCounters::default(),
            cfg,
        })
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &WatchingConfig {
        &self.cfg
    }

    /// The current phase.
    #[must_use]
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Counters so far.
    #[must_use]
    pub fn counters(&self) -> WatchingCounters {
        self.counters
    }

    /// The robot as the operator perceives it now (after the reaction delay).
    #[must_use]
    pub fn perceived_robot(&self) -> Option<&RobotPercept> {
        self.robot.as_ref()
    }

    /// The objects as the operator perceives them now.
    #[must_use]
    pub fn perceived_scene(&self) -> Option<&ScenePercept> {
        self.scene.as_ref()
    }

    /// Decisions since the last call (the node logs them).
    pub fn take_decisions(&mut self) -> Vec<Decision> {
        std::mem::take(&mut self.decisions)
    }

    /// Joint states arrived at `arrival_s` (node clock).
    pub fn perceive_robot(&mut self, arrival_s: f64, percept: RobotPercept) {
        let finite = percept.stamp_s.is_finite()
            && percept.finger_flex_rad.is_finite()
            && percept
                .palm
                .translation
                .vector
                .iter()
                .all(|v| v.is_finite())
            && percept.palm.rotation.coords.iter().all(|v| v.is_finite());
        if finite && arrival_s.is_finite() {
            self.pending.push_back((arrival_s, Percept::Robot(percept)));
        }
    }

    /// A view's objects (from [`ViewGate::take_visible`]) arrived at `arrival_s`.
    pub fn perceive_scene(&mut self, arrival_s: f64, percept: ScenePercept) {
        let finite = percept.stamp_s.is_finite()
            && percept.objects.iter().all(|(_, p)| {
                p.translation.vector.iter().all(|v| v.is_finite())
                    && p.rotation.coords.iter().all(|v| v.is_finite())
            });
        if finite && arrival_s.is_finite() {
            self.pending.push_back((arrival_s, Percept::Scene(percept)));
        }
    }

    /// The operator at `t_s` (node clock): hand offset from its resting place (UR5
    /// base axes), rotation (none: the palm keeps its orientation), fingers, clutch.
    pub fn step(&mut self, t_s: f64) -> TaskSample {
        let first = *self.first_step_s.get_or_insert(t_s);
        self.absorb(t_s);
        self.decide(t_s, first);
        let closure = self.closure.at(t_s).clamp(0.0, 1.0);
        TaskSample {
            offset_m: self.hand.at(t_s),
            rotation: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.turn.at(t_s)),
            posture: Grasp {
                synergy: Synergy::Power,
                closure,
            }
            .posture(),
            under_way: self.clutch,
        }
    }

    /// Percepts whose reaction delay has passed become what the operator sees.
    fn absorb(&mut self, t_s: f64) {
        while let Some((arrival, _)) = self.pending.front() {
            if arrival + self.cfg.reaction_delay_s > t_s {
                break;
            }
            let Some((_, p)) = self.pending.pop_front() else {
                break;
            };
            match p {
                Percept::Robot(r) => {
                    if self.robot.is_some_and(|old| old.stamp_s >= r.stamp_s) {
                        continue;
                    }
                    self.counters.robot_percepts += 1;
                    self.robot = Some(r);
                    self.robot_history.push_back(r);
                    while self
                        .robot_history
                        .front()
                        .is_some_and(|o| o.stamp_s < r.stamp_s - HISTORY_S)
                    {
                        self.robot_history.pop_front();
                    }
                }
                Percept::Scene(s) => {
                    if self
                        .scene
                        .as_ref()
                        .is_some_and(|old| old.stamp_s >= s.stamp_s)
                    {
                        continue;
                    }
                    self.counters.scene_percepts += 1;
                    self.scene = Some(s);
                }
            }
        }
    }

    fn enter(&mut self, t_s: f64, phase: Phase, what: String) {
        self.phase = phase;
        self.phase_since_s = t_s;
        self.corrections = 0;
        self.fixed_goal = None;
        self.decisions.push(Decision { t_s, phase, what });
    }

    fn note(&mut self, t_s: f64, what: String) {
        self.decisions.push(Decision {
            t_s,
            phase: self.phase,
            what,
        });
    }

    /// The placement under way (the last once all are done).
    fn current(&self) -> &Placement {
        let last = self.cfg.placements.len().saturating_sub(1);
        &self.cfg.placements[self.placement.min(last)]
    }

    /// Which placement is under way, from 0.
    #[must_use]
    pub fn placement(&self) -> usize {
        self.placement
    }

    /// The object the placement under way moves.
    #[must_use]
    pub fn object_name(&self) -> &str {
        &self.current().object
    }

    /// A named object's perceived position.
    fn seen(&self, name: &str) -> Option<Vector3<f64>> {
        self.scene
            .as_ref()
            .and_then(|s| s.object(name))
            .map(|p| p.translation.vector)
    }

    /// The object's perceived position.
    fn object(&self) -> Option<Vector3<f64>> {
        self.seen(&self.current().object)
    }

    /// Where the object goes, as perceived: the spot's x-y and the height its centre
    /// rests at there.
    fn target(&self) -> Option<([f64; 2], f64)> {
        let p = self.current();
        match &p.onto {
            Onto::Table {
                from_start_palm_xy_m: [x, y],
            } => {
                let start = self.start_palm?.translation.vector;
                Some(([start.x + x, start.y + y], self.object_rest_z_m))
            }
            Onto::Object {
                name,
                half_height_m,
            } => {
                let below = self.seen(name)?;
                Some((
                    [below.x, below.y],
                    below.z + half_height_m + p.half_height_m,
                ))
            }
        }
    }

    /// Where the palm's origin goes to grasp the object as perceived, with the palm's
    /// orientation as perceived.
    fn grasp_goal(&self) -> Option<Vector3<f64>> {
        let object = self.object()?;
        let palm = self.robot?.palm;
        let above = self.current().half_height_m + self.cfg.grasp_above_top_m;
        let centre = object + Vector3::z() * above;
        Some(centre - palm.rotation * Vector3::from(self.cfg.object_in_palm_m))
    }

    /// The palm's back (+y of its frame, away from the object), world frame.
    fn palm_back(&self) -> Option<Vector3<f64>> {
        self.robot.map(|r| r.palm.rotation * Vector3::y())
    }

    /// The turn about the fingers (rad, the hand's and so the palm's own z) that points
    /// the palm's face as nearly as it can at `object`, horizontally: the palm's face
    /// `n` and side `x` turn as `cos a n + sin a x`, nearest to the horizontal
    /// direction `d` at `a = atan2(x.d, n.d)`.
    fn facing_turn(palm: &Isometry3<f64>, object: &Vector3<f64>) -> f64 {
        let d = object - palm.translation.vector;
        let d = Vector3::new(d.x, d.y, 0.0);
        let n = palm.rotation * -Vector3::y();
        let x = palm.rotation * Vector3::x();
        x.dot(&d).atan2(n.dot(&d))
    }

    /// The robot percept at least [`MOTION_WINDOW_S`] older than the newest.
    fn robot_before(&self) -> Option<(RobotPercept, RobotPercept)> {
        let now = self.robot?;
        let before = self
            .robot_history
            .iter()
            .rev()
            .find(|r| r.stamp_s <= now.stamp_s - MOTION_WINDOW_S)?;
        Some((*before, now))
    }

    /// The palm's perceived speed, m/s.
    fn palm_speed(&self) -> f64 {
        self.robot_before().map_or(f64::INFINITY, |(a, b)| {
            (b.palm.translation.vector - a.palm.translation.vector).norm() / (b.stamp_s - a.stamp_s)
        })
    }

    /// Whether a view captured `settle_s` after the last move (of the hand and the
    /// fingers) has been perceived, showing the palm at rest.
    fn settled(&self) -> bool {
        let since = self
            .hand
            .t1
            .max(self.turn.t1)
            .max(self.closure.t1)
            .max(self.phase_since_s)
            + self.cfg.settle_s;
        self.robot.is_some_and(|r| r.stamp_s >= since)
            && self.palm_speed() <= self.cfg.rest_speed_m_s
    }

    /// One step toward `goal` (world frame): wait for the move and the view, then
    /// arrive or correct.
    fn reach(&mut self, t_s: f64, goal: Vector3<f64>, tolerance_m: f64) -> Reach {
        if t_s < self.hand.t1.max(self.turn.t1) || !self.settled() {
            return Reach::Busy;
        }
        let Some(robot) = self.robot else {
            return Reach::Busy;
        };
        let error = goal - robot.palm.translation.vector;
        if error.norm() <= tolerance_m {
            return Reach::Arrived;
        }
        if self.corrections > self.cfg.max_corrections {
            // Given up on already (and said so): the caller is waiting for something
            // else (a fresher view) before it goes on.
            return Reach::Arrived;
        }
        if self.corrections == self.cfg.max_corrections {
            self.corrections += 1;
            self.counters.goals_not_reached += 1;
            self.note(
                t_s,
                format!(
                    "{} still {:.1} mm off after {} corrections; going on",
                    self.phase.name(),
                    error.norm() * 1e3,
                    self.cfg.max_corrections
                ),
            );
            return Reach::Arrived;
        }
        self.corrections += 1;
        self.plan_move(t_s, error);
        if self.corrections > 1 {
            self.note(
                t_s,
                format!(
                    "{} correction {}: palm {:.1} mm off (seen at {:.3} s)",
                    self.phase.name(),
                    self.corrections,
                    error.norm() * 1e3,
                    robot.stamp_s
                ),
            );
        }
        Reach::Busy
    }

    /// A submovement of the hand that should move the palm by `error` (world frame).
    fn plan_move(&mut self, t_s: f64, error: Vector3<f64>) {
        self.counters.submovements += 1;
        let hand_now = self.hand.at(t_s);
        let step = self.robot_from_operator.inverse() * error / self.motion_scale;
        let duration = (1.875 * error.norm() / self.cfg.peak_speed_m_s).max(self.cfg.min_move_s);
        self.hand = Move {
            from: hand_now,
            to: hand_now + step,
            t0: t_s,
            t1: t_s + duration,
        };
    }

    fn move_fingers(&mut self, t_s: f64, to: f64) {
        self.closure = Move {
            from: self.closure.at(t_s),
            to,
            t0: t_s,
            t1: t_s + self.cfg.close_s,
        };
    }

    /// The fingers have finished moving, as seen.
    fn fingers_settled(&self, t_s: f64) -> bool {
        t_s >= self.closure.t1
            && self.settled()
            && self.robot_before().is_some_and(|(a, b)| {
                (b.finger_flex_rad - a.finger_flex_rad).abs() / (b.stamp_s - a.stamp_s) < 0.2
            })
    }

    fn regrasp(&mut self, t_s: f64, why: &str) {
        if self.attempts_here >= self.cfg.max_attempts {
            self.clutch = false;
            self.move_fingers(t_s, 0.0);
            self.enter(
                t_s,
                Phase::GaveUp,
                format!("{why}; {} attempts made, giving up", self.attempts_here),
            );
        } else {
            self.move_fingers(t_s, 0.0);
            self.enter(t_s, Phase::Reopen, format!("{why}; opening to try again"));
        }
    }

    /// The object as seen is out of reach: fallen off the table, or farther from the
    /// palm's start than the operator would reach for.
    fn object_lost(&self) -> Option<String> {
        let object = self.object()?;
        let start = self.start_palm?.translation.vector;
        let name = &self.current().object;
        if object.z < self.object_rest_z_m - LOST_BELOW_M {
            return Some(format!(
                "the {name} is {:.0} mm below where it stood (off the table)",
                (self.object_rest_z_m - object.z) * 1e3
            ));
        }
        let far = (object - start).norm();
        (far > REACH_M).then(|| format!("the {name} is {:.0} mm away, out of reach", far * 1e3))
    }

    #[allow(clippy::too_many_lines)]
    fn decide(&mut self, t_s: f64, first_s: f64) {
        let c = self.cfg.clone();
        let name = self.current().object.clone();
        if !matches!(
            self.phase,
            Phase::WaitingForView | Phase::Done | Phase::GaveUp
        ) && let Some(why) = self.object_lost()
        {
            self.clutch = false;
            self.move_fingers(t_s, 0.0);
            self.enter(t_s, Phase::GaveUp, format!("{why}; giving up"));
            return;
        }
        match self.phase {
            Phase::WaitingForView => {
                if t_s < first_s + self.start_delay_s {
                    return;
                }
                let (Some(robot), Some(object)) = (self.robot, self.object()) else {
                    return;
                };
                self.start_palm = Some(robot.palm);
                self.object_rest_z_m = object.z;
                let p = robot.palm.translation.vector;
                self.clutch = true;
                // The arm controller engages on the press: move a little later.
                let go_s = t_s + 0.3;
                let turn = if c.turn_to_face_object {
                    Self::facing_turn(&robot.palm, &object)
                } else {
                    0.0
                };
                self.turn = Move {
                    from: 0.0,
                    to: turn,
                    t0: go_s,
                    t1: go_s + turn.abs().to_degrees() / c.turn_speed_deg_s,
                };
                self.hand.t1 = go_s;
                self.enter(
                    t_s,
                    Phase::Turn,
                    format!(
                        "saw the palm at {:.3?} and the {} at {:.3?}; clutch pressed, turning the hand {:.0} deg to face it",
                        p.as_slice(),
                        name,
                        object.as_slice(),
                        turn.to_degrees()
                    ),
                );
            }
            Phase::Turn => {
                if t_s < self.turn.t1 || !self.settled() {
                    return;
                }
                let (Some(robot), Some(object)) = (self.robot, self.object()) else {
                    return;
                };
                let n = robot.palm.rotation * -Vector3::y();
                let to = (object - robot.palm.translation.vector).normalize();
                self.enter(
                    t_s,
                    Phase::Hover,
                    format!(
                        "turned: the palm faces {:.0} deg below the horizontal, {:.0} deg from the {}",
                        (-n.z).asin().to_degrees(),
                        n.dot(&to).clamp(-1.0, 1.0).acos().to_degrees(),
                        name
                    ),
                );
            }
            Phase::Hover => {
                let (Some(goal), Some(back)) = (self.grasp_goal(), self.palm_back()) else {
                    return;
                };
                if let Reach::Arrived =
                    self.reach(t_s, goal + back * c.approach_m, c.coarse_tolerance_m)
                {
                    self.enter(t_s, Phase::Approach, "at the pre-grasp pose".to_owned());
                }
            }
            Phase::Approach => {
                let (Some(goal), Some(object)) = (self.grasp_goal(), self.object()) else {
                    return;
                };
                // The object as it stood when the approach began: once the palm is seen
                // pushing it, the hand is there.
                let before = *self.fixed_goal.get_or_insert(object);
                let pushed = (object - before).norm();
                let touching = pushed > c.contact_push_m;
                if touching || matches!(self.reach(t_s, goal, c.fine_tolerance_m), Reach::Arrived) {
                    if touching {
                        // Stop the hand where it is.
                        let here = self.hand.at(t_s);
                        self.hand = Move {
                            from: here,
                            to: here,
                            t0: t_s,
                            t1: t_s,
                        };
                    }
                    let palm = self
                        .robot
                        .map(|r| r.palm.translation.vector)
                        .unwrap_or_default();
                    self.counters.grasp_attempts += 1;
                    self.attempts_here += 1;
                    self.move_fingers(t_s, c.grasp_closure);
                    self.enter(
                        t_s,
                        Phase::Close,
                        format!(
                            "{}; closing (attempt {}): palm at {:.3?}, the {} at {:.3?}",
                            if touching {
                                format!("the {} pushed {:.0} mm: touching", name, pushed * 1e3)
                            } else {
                                "at the grasp".to_owned()
                            },
                            self.attempts_here,
                            palm.as_slice(),
                            name,
                            object.as_slice()
                        ),
                    );
                }
            }
            Phase::Close => {
                if self.fingers_settled(t_s) {
                    let flex = self.robot.map_or(f64::NAN, |r| r.finger_flex_rad);
                    self.enter(
                        t_s,
                        Phase::Lift,
                        format!("fingers closed ({flex:.2} rad); lifting"),
                    );
                }
            }
            Phase::Lift => {
                let goal = match (self.fixed_goal, self.robot) {
                    (Some(g), _) => g,
                    (None, Some(r)) => {
                        // High enough to carry it over what it goes onto.
                        let Some((_, rest_z)) = self.target() else {
                            return;
                        };
                        let over = rest_z - self.object_rest_z_m + c.carry_clearance_m;
                        let g = r.palm.translation.vector + Vector3::z() * c.lift_m.max(over);
                        self.fixed_goal = Some(g);
                        g
                    }
                    (None, None) => return,
                };
                if let Reach::Arrived = self.reach(t_s, goal, c.coarse_tolerance_m) {
                    let Some(object) = self.object() else {
                        return;
                    };
                    // The newest view must show the robot at rest up here too.
                    let view_s = self.scene.as_ref().map_or(f64::NEG_INFINITY, |s| s.stamp_s);
                    if view_s < self.hand.t1 + c.settle_s {
                        return;
                    }
                    let raised = object.z - self.object_rest_z_m;
                    if raised >= 0.5 * c.lift_m {
                        self.enter(
                            t_s,
                            Phase::Carry,
                            format!(
                                "the {} came along ({:.0} mm up); carrying",
                                name,
                                raised * 1e3
                            ),
                        );
                    } else {
                        self.regrasp(
                            t_s,
                            &format!("the {name} stayed behind ({:.0} mm up)", raised * 1e3),
                        );
                    }
                }
            }
            Phase::Reopen => {
                if self.fingers_settled(t_s) {
                    self.enter(t_s, Phase::Hover, "hand open; hovering again".to_owned());
                }
            }
            Phase::Carry | Phase::Lower => {
                let (Some(robot), Some(object), Some((target_xy, rest_z))) =
                    (self.robot, self.object(), self.target())
                else {
                    return;
                };
                if self.phase == Phase::Carry
                    && self.settled()
                    && object.z - self.object_rest_z_m < 0.25 * c.lift_m
                {
                    self.regrasp(t_s, &format!("the {name} fell out of the hand"));
                    return;
                }
                let p = robot.palm.translation.vector;
                let shift = Vector3::new(target_xy[0] - object.x, target_xy[1] - object.y, 0.0);
                if self.phase == Phase::Carry {
                    let z = self.fixed_goal.get_or_insert(p).z;
                    let goal = Vector3::new(p.x + shift.x, p.y + shift.y, z);
                    if let Reach::Arrived = self.reach(t_s, goal, c.coarse_tolerance_m) {
                        self.enter(t_s, Phase::Lower, "over the target; lowering".to_owned());
                    }
                } else {
                    let down = object.z - rest_z - c.release_above_m;
                    let goal = Vector3::new(p.x + shift.x, p.y + shift.y, p.z - down);
                    // Down is where the object stands, not where the palm is.
                    let standing = self.settled() && down <= c.fine_tolerance_m;
                    if standing
                        || matches!(self.reach(t_s, goal, c.fine_tolerance_m), Reach::Arrived)
                    {
                        self.move_fingers(t_s, 0.0);
                        self.enter(
                            t_s,
                            Phase::Release,
                            format!(
                                "the {} {:.0} mm above its resting height, {:.0} mm from the target; opening",
                                name,
                                (object.z - rest_z) * 1e3,
                                (Vector3::new(shift.x, shift.y, 0.0)).norm() * 1e3
                            ),
                        );
                    }
                }
            }
            Phase::Release => {
                if self.fingers_settled(t_s) {
                    self.enter(t_s, Phase::Retreat, "hand open; retreating".to_owned());
                }
            }
            Phase::Retreat => {
                let goal = match (self.fixed_goal, self.robot, self.palm_back()) {
                    (Some(g), ..) => g,
                    (None, Some(r), Some(back)) => {
                        // Back off the palm's face and up, clear of the object.
                        let back = if c.clear_tall_objects {
                            Vector3::z()
                        } else {
                            back
                        };
                        let g = r.palm.translation.vector
                            + back * c.approach_m
                            + Vector3::z() * c.lift_m;
                        self.fixed_goal = Some(g);
                        g
                    }
                    _ => return,
                };
                if let Reach::Arrived = self.reach(t_s, goal, c.coarse_tolerance_m) {
                    if self.placement + 1 < c.placements.len() {
                        // The next object.
                        self.placement += 1;
                        let next = self.current().object.clone();
                        let Some(object) = self.object() else {
                            self.enter(
                                t_s,
                                Phase::GaveUp,
                                format!("the {next} is not in view; giving up"),
                            );
                            self.clutch = false;
                            return;
                        };
                        self.object_rest_z_m = object.z;
                        self.attempts_here = 0;
                        self.enter(
                            t_s,
                            Phase::Hover,
                            format!(
                                "clear; going for the {next} at {:.3?} (placement {} of {})",
                                object.as_slice(),
                                self.placement + 1,
                                c.placements.len()
                            ),
                        );
                        return;
                    }
                    // Back to the start, turning the hand back on the way.
                    self.turn = Move {
                        from: self.turn.at(t_s),
                        to: 0.0,
                        t0: t_s,
                        t1: t_s + self.turn.at(t_s).abs().to_degrees() / c.turn_speed_deg_s,
                    };
                    let mut via = None;
                    if let (Some(start), Some(r)) = (self.start_palm, self.robot) {
                        let (start, palm) = (start.translation.vector, r.palm.translation.vector);
                        // Level to above the start first, when the palm is above it.
                        let above = Vector3::new(start.x, start.y, palm.z);
                        let goal =
                            if c.clear_tall_objects && palm.z > start.z + c.coarse_tolerance_m {
                                via = Some(above);
                                above
                            } else {
                                start
                            };
                        self.plan_move(t_s, goal - palm);
                    }
                    self.enter(t_s, Phase::Return, "clear; going back".to_owned());
                    self.fixed_goal = via;
                }
            }
            Phase::Return => {
                let Some(start) = self.start_palm else {
                    return;
                };
                if let Some(via) = self.fixed_goal {
                    if let Reach::Arrived = self.reach(t_s, via, c.coarse_tolerance_m) {
                        self.fixed_goal = None;
                        self.corrections = 0;
                        self.note(t_s, "above the start; going down to it".to_owned());
                    }
                    return;
                }
                if let Reach::Arrived =
                    self.reach(t_s, start.translation.vector, c.fine_tolerance_m)
                {
                    self.clutch = false;
                    let placed = match (self.object(), self.target()) {
                        (Some(o), Some((xy, _))) => (o.x - xy[0]).hypot(o.y - xy[1]) * 1e3,
                        _ => f64::NAN,
                    };
                    self.enter(
                        t_s,
                        Phase::Done,
                        format!("back at the start; clutch released (the {name} seen {placed:.0} mm from the target)"),
                    );
                }
            }
            Phase::Done | Phase::GaveUp => {}
        }
    }
}

/// Turns received joint states into what a 3D view of them shows the operator: the
/// palm's pose by the nominal model of the PR2 with the Shadow hand (the same root
/// frame as the robot world's objects), and how far the fingers are curled.
#[derive(Debug, Clone)]
pub struct RobotEye {
    robot: teleop_kinematics::Robot,
    state: teleop_kinematics::KinematicState,
    q: Vec<f64>,
    arm_dofs: [usize; 7],
    palm: teleop_kinematics::LinkId,
    finger_flex_rad: f64,
}

/// The J3 joints of the four fingers, whose mean is the perceived closure.
const FLEX_JOINTS: [&str; 4] = ["rh_FFJ3", "rh_MFJ3", "rh_RFJ3", "rh_LFJ3"];

impl RobotEye {
    /// # Errors
    /// The robot description lacks a joint or the palm.
    pub fn new() -> Result<Self, teleop_kinematics::KinematicsError> {
        let robot = teleop_kinematics::robots::pr2_arm()?;
        let mut arm_dofs = [0; 7];
        for (slot, name) in arm_dofs
            .iter_mut()
            .zip(teleop_interfaces::joints::PR2_ARM_JOINTS)
        {
            *slot = robot.dof_index(name)?;
        }
        let palm = robot.link_id(teleop_kinematics::robots::shadow::PALM)?;
        Ok(Self {
            state: robot.new_state(),
            q: robot.neutral_positions(),
            arm_dofs,
            palm,
            finger_flex_rad: 0.0,
            robot,
        })
    }

    /// The Shadow hand's joint states (matched by name; others ignored).
    ///
    /// # Errors
    /// A missing flexion joint or a non-finite position (the last value stays).
    pub fn hand_joints(&mut self, names: &[String], positions: &[f64]) -> Result<(), String> {
        let mut sum = 0.0;
        for joint in FLEX_JOINTS {
            let v = names
                .iter()
                .position(|n| n == joint)
                .and_then(|i| positions.get(i))
                .ok_or_else(|| format!("hand joint states lack {joint}"))?;
            if !v.is_finite() {
                return Err(format!("hand joint state {joint} is {v}"));
            }
            sum += v;
        }
        self.finger_flex_rad = sum / FLEX_JOINTS.len() as f64;
        Ok(())
    }

    /// The arm's joint states captured at `stamp_s` (matched by name) as a percept.
    ///
    /// # Errors
    /// A missing arm joint or a non-finite position.
    pub fn arm_joints(
        &mut self,
        stamp_s: f64,
        names: &[String],
        positions: &[f64],
    ) -> Result<RobotPercept, String> {
        for (joint, dof) in teleop_interfaces::joints::PR2_ARM_JOINTS
            .iter()
            .zip(self.arm_dofs)
        {
            let v = names
                .iter()
                .position(|n| n == joint)
                .and_then(|i| positions.get(i))
                .ok_or_else(|| format!("arm joint states lack {joint}"))?;
            if !v.is_finite() {
                return Err(format!("arm joint state {joint} is {v}"));
            }
            self.q[dof] = *v;
        }
        self.robot
            .update(&mut self.state, &self.q)
            .map_err(|e| e.to_string())?;
        Ok(RobotPercept {
            stamp_s,
            palm: self.robot.link_pose(&self.state, self.palm),
            finger_flex_rad: self.finger_flex_rad,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    fn palm_down(p: Vector3<f64>) -> Isometry3<f64> {
        // The palm's -y down, the fingers (+z) forward (+x): the PR2's working posture.
        let r = Rotation3::from_basis_unchecked(&[
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(1.0, 0.0, 0.0),
        ]);
        Isometry3::from_parts(
            Translation3::from(p),
            UnitQuaternion::from_rotation_matrix(&r),
        )
    }

    fn scene(t: f64, can: Vector3<f64>) -> ScenePercept {
        ScenePercept {
            stamp_s: t,
            objects: vec![(
                "can".to_owned(),
                Isometry3::from_parts(Translation3::from(can), UnitQuaternion::identity()),
            )],
        }
    }

    #[test]
    fn the_gate_shows_no_pose_newer_than_the_newest_received_view() {
        let mut gate = ViewGate::new();
        for k in 0..10 {
            gate.object_poses(scene(
                f64::from(k) * 0.1,
                Vector3::new(f64::from(k), 0.0, 0.0),
            ));
        }
        assert!(gate.take_visible().is_none(), "no view yet");
        gate.view_received(0.3);
        let seen = gate.take_visible().expect("the view of 0.3 s");
        assert!((seen.stamp_s - 0.3).abs() < 1e-9);
        assert!(gate.take_visible().is_none(), "shown once");
        // A view lost in between: the next one received shows its own instant.
        gate.view_received(0.75);
        assert!((gate.take_visible().expect("0.7").stamp_s - 0.7).abs() < 1e-9);
        // An older view arriving late changes nothing.
        gate.view_received(0.5);
        assert!(gate.take_visible().is_none());
        gate.view_received(f64::NAN);
        assert_eq!(gate.newest_view_s(), Some(0.75));
    }

    /// A kinematic stand-in for the robot site: the palm follows the operator's hand
    /// (relative control, scale 1, identity mapping) 150 ms late with a first-order
    /// lag, fingers follow the closure, the can is carried when the hand is closed
    /// around it; percepts reach the operator `latency_s` after capture.
    struct Loop {
        op: WatchingOperator,
        start: Vector3<f64>,
        can: Vector3<f64>,
        /// More objects (name, centre, half height): the blocks of a tower.
        others: Vec<(String, Vector3<f64>, f64)>,
        /// Which of `others` is held.
        holding: Option<usize>,
        palm: Vector3<f64>,
        /// The hand's turn as the robot has followed it.
        turn: UnitQuaternion<f64>,
        flex: f64,
        held: bool,
        history: VecDeque<(f64, Vector3<f64>, UnitQuaternion<f64>, f64)>,
        latency_s: f64,
        views: bool,
        can_follows: bool,
        hand_ref: Option<(Vector3<f64>, Vector3<f64>)>,
        /// The arm ignores its commands (stuck at a limit, say): the palm stays.
        arm_stuck: bool,
    }

    const TABLE_CAN_Z: f64 = 0.5;
    /// The table top under the can (23 cm tall).
    const TABLE_TOP_Z: f64 = TABLE_CAN_Z - 0.115;

    impl Loop {
        fn new(views: bool, can_follows: bool) -> Self {
            Self::with(WatchingConfig::default(), views, can_follows)
        }

        fn with(cfg: WatchingConfig, views: bool, can_follows: bool) -> Self {
            let start = Vector3::new(0.6, -0.2, TABLE_CAN_Z + 0.2);
            Self {
                op: WatchingOperator::new(cfg, 1.0, 1.0).expect("valid"),
                start,
                can: Vector3::new(0.6, -0.05, TABLE_CAN_Z),
                others: Vec::new(),
                holding: None,
                palm: start,
                turn: UnitQuaternion::identity(),
                flex: 0.0,
                held: false,
                history: VecDeque::new(),
                latency_s: 0.05,
                views,
                can_follows,
                hand_ref: None,
                arm_stuck: false,
            }
        }

        fn palm_pose(&self) -> Isometry3<f64> {
            let down = palm_down(self.palm);
            Isometry3::from_parts(down.translation, down.rotation * self.turn)
        }

        /// The other objects: one is held when the fingers are curled with the palm at
        /// its grasp; let go, it drops onto the table or onto an object under it.
        fn move_others(&mut self, palm: &Isometry3<f64>, grasp_in_palm: Vector3<f64>) {
            let above_top = self.op.config().grasp_above_top_m;
            let point = (palm * nalgebra::Point3::from(grasp_in_palm)).coords;
            let centre = |half: f64| point - Vector3::z() * (half + above_top);
            if self.flex < 0.2 {
                if let Some(i) = self.holding.take() {
                    let (_, p, half) = self.others[i].clone();
                    let support = self
                        .others
                        .iter()
                        .enumerate()
                        .filter(|(j, (_, q, _))| *j != i && (q.xy() - p.xy()).norm() < 0.03)
                        .map(|(_, (_, q, h))| q.z + h)
                        .fold(TABLE_TOP_Z, f64::max);
                    self.others[i].1.z = support + half;
                }
            } else if self.holding.is_none() && self.flex > 0.4 {
                self.holding = self
                    .others
                    .iter()
                    .position(|(_, p, half)| (centre(*half) - p).norm() < 0.02);
            }
            if let Some(i) = self.holding {
                self.others[i].1 = centre(self.others[i].2);
            }
        }

        fn run(&mut self, seconds: f64) -> Vec<Decision> {
            let dt = 0.01;
            let mut log = Vec::new();
            let steps = (seconds / dt).round() as usize;
            let grasp_in_palm = Vector3::from(self.op.config().object_in_palm_m);
            let above =
                self.op.config().placements[0].half_height_m + self.op.config().grasp_above_top_m;
            for k in 0..steps {
                let t = k as f64 * dt;
                let s = self.op.step(t);
                log.extend(self.op.take_decisions());
                // The robot: relative control while the clutch is held (the hand's turn
                // since the press, which starts at none, turns the palm about its own
                // axes).
                let target = match (s.under_way, self.hand_ref) {
                    (true, None) => {
                        self.hand_ref = Some((s.offset_m, self.palm));
                        self.palm
                    }
                    (true, Some((h0, p0))) => p0 + (s.offset_m - h0),
                    (false, _) => {
                        self.hand_ref = None;
                        self.palm
                    }
                };
                let open = Synergy::Open.posture();
                let closure = s
                    .posture
                    .q
                    .iter()
                    .zip(open.q)
                    .map(|(a, b)| (a - b).abs())
                    .sum::<f64>();
                let turn = if s.under_way { s.rotation } else { self.turn };
                self.history.push_back((t, target, turn, closure));
                // 150 ms late, 0.1 s lag.
                let delayed = self
                    .history
                    .iter()
                    .rev()
                    .find(|(ht, ..)| *ht <= t - 0.15)
                    .copied();
                if let Some((_, target, turn, closure)) = delayed {
                    if !self.arm_stuck {
                        self.palm += (target - self.palm) * (dt / 0.1);
                        self.turn = turn;
                    }
                    self.flex += (closure.min(1.0) * 0.9 - self.flex) * (dt / 0.2);
                }
                // The can: held when the fingers are curled with the palm at the grasp.
                let palm = self.palm_pose();
                let grasp = palm * nalgebra::Point3::from(grasp_in_palm) - Vector3::z() * above;
                let grasp = grasp.coords;
                self.move_others(&palm, grasp_in_palm);
                if self.flex > 0.4 && (grasp - self.can).norm() < 0.02 && self.can_follows {
                    self.held = true;
                }
                if self.flex < 0.2 {
                    self.held = false;
                }
                if self.held {
                    self.can = grasp;
                } else {
                    self.can.z = TABLE_CAN_Z;
                }
                // Percepts: joint states every 10 ms, views every 1/15 s.
                let capture = t - self.latency_s;
                self.op.perceive_robot(
                    t,
                    RobotPercept {
                        stamp_s: capture,
                        palm,
                        finger_flex_rad: self.flex,
                    },
                );
                if self.views && k % 7 == 0 {
                    let mut seen = scene(capture, self.can);
                    seen.objects.extend(
                        self.others
                            .iter()
                            .map(|(n, p, _)| (n.clone(), Isometry3::translation(p.x, p.y, p.z))),
                    );
                    self.op.perceive_scene(t, seen);
                }
            }
            log
        }
    }

    #[test]
    fn a_goal_it_cannot_reach_is_given_up_once_and_said_once() {
        // The arm never moves: every goal is given up after the corrections, and each
        // only once (the operator used to count and log it again on every tick while it
        // waited for a fresher view, 20 lines in one lift).
        let mut lp = Loop::new(true, true);
        lp.arm_stuck = true;
        let log = lp.run(200.0);
        assert_eq!(lp.op.phase(), Phase::GaveUp, "{log:#?}");
        let given_up: Vec<&Decision> = log.iter().filter(|d| d.what.contains("still")).collect();
        assert!(!given_up.is_empty(), "{log:#?}");
        assert_eq!(
            given_up.len() as u64,
            lp.op.counters().goals_not_reached,
            "{log:#?}"
        );
        for w in log.windows(2) {
            assert!(
                !(w[0].what.contains("still")
                    && w[1].what.contains("still")
                    && w[0].phase == w[1].phase),
                "the same goal given up twice in a row: {:?} / {:?}",
                w[0],
                w[1]
            );
        }
        let max = WatchingConfig::default().max_corrections;
        let corrections = log.iter().filter(|d| d.what.contains("correction")).count();
        assert!(
            corrections as u64 <= u64::from(max) * (given_up.len() as u64 + 3),
            "{log:#?}"
        );
    }

    #[test]
    fn without_views_the_operator_waits_with_the_clutch_released() {
        let mut lp = Loop::new(false, true);
        let log = lp.run(10.0);
        assert_eq!(lp.op.phase(), Phase::WaitingForView, "{log:?}");
        let s = lp.op.step(10.0);
        assert!(!s.under_way, "clutch released");
        assert_eq!(s.offset_m, Vector3::zeros(), "the hand stays where it was");
        assert!(log.is_empty());
        // The first view: the operator starts only a reaction delay after it arrived.
        lp.op.perceive_scene(10.0, scene(9.95, lp.can));
        lp.op.step(10.15);
        assert_eq!(lp.op.phase(), Phase::WaitingForView);
        lp.op.step(10.21);
        assert_eq!(lp.op.phase(), Phase::Turn);
        assert!(lp.op.step(10.22).under_way, "clutch pressed");
    }

    #[test]
    fn the_operator_does_the_job_through_a_lagging_robot() {
        // The default top grasp (the palm as it starts), and the side grasp (the hand
        // turned to face the can).
        let side = WatchingConfig {
            turn_to_face_object: true,
            object_in_palm_m: [0.0, -0.052, 0.10],
            // 4 cm above the can's centre.
            grasp_above_top_m: 0.04 - Placement::pick_can().half_height_m,
            ..WatchingConfig::default()
        };
        for (cfg, turn_deg) in [(WatchingConfig::default(), 0), (side, 90)] {
            let mut lp = Loop::with(cfg, true, true);
            let log = lp.run(90.0);
            let phases: Vec<&str> = log.iter().map(|d| d.phase.name()).collect();
            assert_eq!(lp.op.phase(), Phase::Done, "{log:#?}");
            for p in [
                Phase::Turn,
                Phase::Hover,
                Phase::Approach,
                Phase::Close,
                Phase::Lift,
                Phase::Carry,
                Phase::Lower,
                Phase::Release,
                Phase::Retreat,
                Phase::Return,
            ] {
                assert!(phases.contains(&p.name()), "{p:?} missing: {phases:?}");
            }
            let Onto::Table {
                from_start_palm_xy_m,
            } = lp.op.config().placements[0].onto
            else {
                panic!("the default job puts the can on the table");
            };
            let target = lp.start.xy() + Vector2Like::from(from_start_palm_xy_m);
            assert!(
                (lp.can.xy() - target).norm() < 0.02,
                "can at {:?}, target {target:?}",
                lp.can
            );
            assert!(
                (lp.palm - lp.start).norm() < 0.01,
                "palm back: {:?} vs {:?}",
                lp.palm,
                lp.start
            );
            // The palm turned to face the can beside it (side grasp), and back.
            let said = format!("turning the hand {turn_deg} deg");
            assert!(
                log.iter().any(|d| d.what.contains(&said)),
                "{said}: {log:#?}"
            );
            assert!(lp.turn.angle() < 1e-6, "turned back: {}", lp.turn.angle());
            assert_eq!(lp.op.counters().grasp_attempts, 1);
            assert!(!lp.op.step(90.0).under_way, "clutch released at the end");
        }
    }

    type Vector2Like = nalgebra::Vector2<f64>;

    #[test]
    fn the_operator_stacks_one_block_on_another_then_a_third_on_those() {
        // Three blocks on the table (the can stays out of the way): the middle one onto
        // the base, the top one onto the middle one, each seen where it is.
        let (hb, hm, ht) = (0.035, 0.05, 0.045);
        let cfg = WatchingConfig {
            placements: vec![
                Placement {
                    object: "middle".into(),
                    half_height_m: hm,
                    onto: Onto::Object {
                        name: "base".into(),
                        half_height_m: hb,
                    },
                },
                Placement {
                    object: "top".into(),
                    half_height_m: ht,
                    onto: Onto::Object {
                        name: "middle".into(),
                        half_height_m: hm,
                    },
                },
            ],
            ..WatchingConfig::default()
        };
        let mut lp = Loop::with(cfg, true, false);
        lp.can = Vector3::new(0.3, 0.3, TABLE_CAN_Z);
        let base = Vector3::new(0.7, -0.2, TABLE_TOP_Z + hb);
        lp.others = vec![
            ("base".into(), base, hb),
            (
                "middle".into(),
                Vector3::new(0.6, -0.05, TABLE_TOP_Z + hm),
                hm,
            ),
            ("top".into(), Vector3::new(0.6, -0.35, TABLE_TOP_Z + ht), ht),
        ];
        let log = lp.run(180.0);
        assert_eq!(lp.op.phase(), Phase::Done, "{log:#?}");
        assert_eq!(lp.op.placement(), 1);
        assert_eq!(lp.op.counters().grasp_attempts, 2, "{log:#?}");
        let middle = lp.others[1].1;
        let top = lp.others[2].1;
        assert!(
            (middle.xy() - base.xy()).norm() < 0.01,
            "middle {middle:?} on base {base:?}"
        );
        assert!(
            (middle.z - (base.z + hb + hm)).abs() < 1e-9,
            "middle on the base: {middle:?}"
        );
        assert!(
            (top.xy() - middle.xy()).norm() < 0.01,
            "top {top:?} on middle {middle:?}"
        );
        assert!(
            (top.z - (middle.z + hm + ht)).abs() < 1e-9,
            "top on the middle: {top:?}"
        );
        assert!(
            log.iter().any(|d| d.what.contains("going for the top")),
            "{log:#?}"
        );
        assert!((lp.palm - lp.start).norm() < 0.01, "palm back");
        assert!(!lp.op.step(180.0).under_way, "clutch released at the end");
    }

    #[test]
    fn a_grasp_that_never_holds_is_retried_then_given_up() {
        let mut lp = Loop::new(true, false);
        let log = lp.run(120.0);
        assert_eq!(lp.op.phase(), Phase::GaveUp, "{log:#?}");
        assert_eq!(lp.op.counters().grasp_attempts, 3);
        assert!(log.iter().any(|d| d.what.contains("stayed behind")));
        assert!(!lp.op.step(120.0).under_way);
    }

    #[test]
    fn bad_percepts_and_config_are_refused() {
        let mut op = WatchingOperator::new(WatchingConfig::default(), 1.0, 0.0).expect("valid");
        op.perceive_robot(
            0.0,
            RobotPercept {
                stamp_s: f64::NAN,
                palm: Isometry3::identity(),
                finger_flex_rad: 0.0,
            },
        );
        op.perceive_scene(0.0, scene(0.0, Vector3::new(f64::INFINITY, 0.0, 0.0)));
        op.step(5.0);
        assert!(op.perceived_robot().is_none() && op.perceived_scene().is_none());
        let bad = WatchingConfig {
            reaction_delay_s: -1.0,
            ..WatchingConfig::default()
        };
        assert!(
            WatchingOperator::new(bad, 1.0, 0.0)
                .unwrap_err()
                .contains("reaction_delay_s")
        );
        assert!(WatchingOperator::new(WatchingConfig::default(), 0.0, 0.0).is_err());
    }
}
