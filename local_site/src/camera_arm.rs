//! Active-vision camera arm (thesis ch. 7.4) as a pure core: no clock, no network.
//! [`CameraArmController::step`] takes the time, the operator's hand pose and pedals as
//! received, and the UR5's measured joints, and returns the joint velocity command that
//! keeps the depth camera looking at the hand.
//!
//! # Behaviour
//!
//! * **Goal.** The camera's optical frame (`camera_optical_frame`, +z along the view)
//!   is driven to a pose `standoff_m` (0.40 m) from the hand centre along the hand
//!   frame's Y axis (Fig. 3.6), looking back at the hand centre, with the image's "up"
//!   along the fingers. **Side:** the hand frame's +Y is the palm normal of a right
//!   hand (`Y = MF x RF`), so [`ViewSide::Palm`] (default) puts the camera in front of
//!   the palm, looking back along -Y: where ch. 7 puts it ("40 cm back along the Y-axis
//!   of the hand"), beta = 0 of ch. 5.4.4's recommended [0, 30] deg if beta is read
//!   hand-to-camera, and the side the hand networks were trained on
//!   (docs/local-site.md, "Which side of the hand"). [`ViewSide::Back`] looks at the
//!   back of the hand.
//!   **Within reach:** a goal farther than `max_reach_m` (0.75 m) from the UR5's
//!   shoulder (a hand turned so its palm faces away from the arm, as in pouring) is
//!   moved round the hand, at the same standoff and still looking at it, to the nearest
//!   reachable view ([`camera_goal_within_reach`]).
//! * **IK.** A pose goal (weight 1, rotation weighed by `rotation_scale`), a
//!   regularization goal toward the previous solution (the thesis's 0.5 in bio_ik's
//!   terms, but without bio_ik's per-joint factors: docs/remote-site.md; 1
//!   over-smoothed by ~10 cm on fast motion), the thesis's anti-redundancy rule (the
//!   forearm's and the second wrist link's z axes stay more than
//!   `redundancy_margin_deg` away from the inverse of their directions at start, so the
//!   elbow and wrist do not flip), and a keep-out goal holding every moving link at
//!   least `hand_clearance_m` from a box around the operator's hand
//!   (`teleop_collision::ExternalVolume::hand_volume`), which moves with the hand.
//! * **Checked before execution.** Every IK solution is checked against the hand
//!   volume at the newest hand pose; a solution closer than `hand_clearance_m` minus a
//!   millimetre is not executed: the arm holds (zero velocity), counted as
//!   `camera_arm.rejected_collision`.
//! * **Limits.** The camera target passes the Cartesian limiter (0.2 m/s, 2 rad/s,
//!   2 m/s^2), the joint velocities the joint limiter (<= 3 rad/s, direction kept,
//!   positions never driven past their limits). Velocity law: eq. 6.1, the thesis's
//!   PR2 arm law (ch. 6.2.3), used here for the UR5 too; the thesis's UR5 had "30 Hz
//!   joint-space trajectory generation" from bio_ik (ch. 7) and gives no such law for it.
//! * **Pedals.** The arm moves only with fresh operator input (`input_deadline_s`),
//!   the enable switch held and the left pedal (camera stop) released; otherwise zero
//!   velocity at once. It needs no clutch: it follows the hand absolutely.
//! * **Jumps.** Every hand pose passes the jump filter (50 cm / 60 deg). With no clutch
//!   to re-centre, a rejected jump would freeze the camera for good if the hand really
//!   moved; so poses that stay within `reacquire_radius_m` of each other for
//!   `reacquire_after_s` after a rejection are taken as the new hand position: the
//!   filter is reset there and the Cartesian limiter moves the camera over at its
//!   speed limit (counted as `camera_arm.reacquired`).
//! * **Watchdog.** No accepted hand pose for `pose_deadline_s`, or a non-finite arm
//!   state: zero velocity. Following resumes by itself when fresh poses return, from
//!   the camera's current pose (no jump).

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Rotation3, SVector, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_collision::{ChainBodies, ChainVolumeDistance, ExternalVolume};
use teleop_control::{
    CartesianLimiter, CartesianLimits, JointLimiterConfig, JointLimits, JointVelocityLimiter,
    JumpFilter, JumpFilterConfig, VelocityLimitStrategy,
};
use teleop_hardware::{ArmCommand, ArmState};
use teleop_ik::{DistanceConstraint, Goal, IkSettings, Solver};
use teleop_interfaces::StepTimer;
use teleop_kinematics::FixedChain;

/// The UR5's joint count.
pub const UR5_DOF: usize = 6;

/// The thesis's control period (30 Hz): the rate its IK weights were tuned at, s.
pub const THESIS_PERIOD_S: f64 = 1.0 / 30.0;

/// Which side of the hand the camera looks from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewSide {
    /// On the hand frame's +Y (the palm side of a right hand), looking along -Y.
    #[default]
    Palm,
    /// On -Y (the back of the hand), looking along +Y.
    Back,
}

/// Settings of the camera arm. Defaults are the thesis values where it gives them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraArmConfig {
    /// Control rate, Hz (thesis: 30).
    pub rate_hz: f64,
    /// Longest time step used, s.
    pub max_dt_s: f64,
    /// Distance from the hand centre to the camera, m (thesis: 0.40).
    pub standoff_m: f64,
    /// Which side of the hand the camera looks from.
    pub side: ViewSide,
    /// The point the camera looks at, in the hand frame, m (the hand's centre: 8 cm
    /// from the wrist toward the fingers).
    pub look_at_in_hand_m: [f64; 3],
    /// Weight of the rotation error in the pose goal (as the PR2 arm's).
    pub rotation_scale: f64,
    /// Regularization weight as bio_ik weighs goals, at 30 Hz, without bio_ik's per-joint
    /// factors (the thesis's 0.5 is 0.0069 per UR5 joint with them: docs/remote-site.md,
    /// "What that mapping leaves out"). Default 0.2,
    /// `d1` 1.0 and feedback 10 /s, as the PR2 arm's: measured in the closed loop
    /// (docs/local-site.md, "Tuning the arms"), 0.5 (mapped as above) / 0.7 / 3 /s kept the
    /// camera 280 ms behind its goal (1.6 cm mean error on pick-and-place, 6 cm at the
    /// fastest moves); these keep it within ~50 ms (0.3 cm).
    pub regularization_weight: f64,
    /// Feed-forward factor `d1` of eq. 6.1 (the thesis's PR2 arm: 0.7, ch. 6.4; it
    /// gives none for the UR5).
    pub d1: f64,
    /// Feedback gain of eq. 6.1, per second (the thesis's PR2 arm: `d2` = 0.1 at 30 Hz,
    /// 3 /s; none given for the UR5).
    pub feedback_gain_per_s: f64,
    /// Anti-redundancy: the forearm's and the second wrist link's z axes stay at
    /// least this far (deg) from the inverse of their start directions.
    pub redundancy_margin_deg: f64,
    /// Every moving link stays at least this far from the hand box, m.
    pub hand_clearance_m: f64,
    /// Joint speed cap, rad/s (thesis: 3).
    pub max_joint_velocity_rad_s: f64,
    /// Longest age of the pedal state, s.
    pub input_deadline_s: f64,
    /// Longest time without an accepted hand pose, s.
    pub pose_deadline_s: f64,
    /// Re-acquisition after a rejected jump: poses within this radius of each other...
    pub reacquire_radius_m: f64,
    /// ...for this long are the hand's new position.
    pub reacquire_after_s: f64,
    /// The view within reach: when the goal would put the camera farther than this from
    /// `reach_centre_m`, the camera moves round the hand (same standoff, still looking
    /// at it) to the nearest view direction that is within it, m. Default 0.75: the
    /// UR5's 0.85 m reach less the camera's mount and a margin for the orientation.
    pub max_reach_m: f64,
    /// The centre of the arm's reach in its base frame (the UR5's shoulder), m.
    pub reach_centre_m: [f64; 3],
    pub jump: JumpFilterConfig,
    pub cartesian: CartesianLimits,
}

impl Default for CameraArmConfig {
    fn default() -> Self {
        Self {
            rate_hz: 30.0,
            max_dt_s: 0.1,
            standoff_m: 0.40,
            side: ViewSide::Palm,
            look_at_in_hand_m: [0.0, 0.0, 0.08],
            rotation_scale: 0.25,
            regularization_weight: 0.2,
            d1: 1.0,
            feedback_gain_per_s: 10.0,
            redundancy_margin_deg: 45.0,
            hand_clearance_m: 0.05,
            max_joint_velocity_rad_s: 3.0,
            input_deadline_s: 0.2,
            pose_deadline_s: 0.2,
            reacquire_radius_m: 0.05,
            reacquire_after_s: 0.5,
            max_reach_m: 0.75,
            reach_centre_m: [0.0, 0.0, 0.089159],
            jump: JumpFilterConfig::default(),
            cartesian: CartesianLimits::default(),
        }
    }
}

impl CameraArmConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("rate_hz", self.rate_hz, 1.0, 1000.0),
            ("max_dt_s", self.max_dt_s, 1e-3, 1.0),
            ("standoff_m", self.standoff_m, 0.1, 2.0),
            ("rotation_scale", self.rotation_scale, 0.0, 10.0),
            (
                "regularization_weight",
                self.regularization_weight,
                0.0,
                100.0,
            ),
            ("d1", self.d1, 0.0, 10.0),
            ("feedback_gain_per_s", self.feedback_gain_per_s, 0.0, 1000.0),
            (
                "redundancy_margin_deg",
                self.redundancy_margin_deg,
                0.0,
                90.0,
            ),
            ("hand_clearance_m", self.hand_clearance_m, 0.0, 0.5),
            (
                "max_joint_velocity_rad_s",
                self.max_joint_velocity_rad_s,
                0.01,
                3.15,
            ),
            ("input_deadline_s", self.input_deadline_s, 1e-3, 10.0),
            ("pose_deadline_s", self.pose_deadline_s, 1e-3, 10.0),
            ("reacquire_radius_m", self.reacquire_radius_m, 1e-3, 1.0),
            ("reacquire_after_s", self.reacquire_after_s, 0.0, 10.0),
            ("max_reach_m", self.max_reach_m, 0.2, 10.0),
        ];
        teleop_control::check_ranges("camera_arm", &checks)?;
        if !self
            .reach_centre_m
            .iter()
            .all(|v| v.is_finite() && v.abs() <= 2.0)
        {
            return Err("camera_arm.reach_centre_m must be finite and within 2 m".into());
        }
        if !self
            .look_at_in_hand_m
            .iter()
            .all(|v| v.is_finite() && v.abs() <= 0.5)
        {
            return Err("camera_arm.look_at_in_hand_m must be finite and within 0.5 m".into());
        }
        self.jump
            .validate()
            .map_err(|e| format!("camera_arm.jump: {e}"))?;
        self.cartesian
            .validate()
            .map_err(|e| format!("camera_arm.cartesian: {e}"))
    }
}

/// The camera goal for a hand pose (hand frame of Fig. 3.6, in the UR5 base frame):
/// the optical frame's pose (z along the view, y down in the image).
pub fn camera_goal(
    hand: &Isometry3<f64>,
    standoff_m: f64,
    side: ViewSide,
    look_at_in_hand: &Vector3<f64>,
) -> Isometry3<f64> {
    let r = hand.rotation;
    let (hx, hy, hz) = (r * Vector3::x(), r * Vector3::y(), r * Vector3::z());
    let centre = hand * nalgebra::Point3::from(*look_at_in_hand);
    let (offset_dir, x_cam) = match side {
        // In front of the palm: view along -Y; image up (-y_cam) along the fingers.
        ViewSide::Palm => (hy, -hx),
        ViewSide::Back => (-hy, hx),
    };
    let z_cam = -offset_dir;
    let y_cam = -hz;
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_cam, y_cam, z_cam]));
    Isometry3::from_parts(
        (centre.coords + offset_dir * standoff_m).into(),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// The camera goal for a hand pose with the view kept within reach: [`camera_goal`],
/// unless that puts the camera farther than `max_reach_m` from `reach_centre`; then the
/// camera stays `standoff_m` from the hand centre and looking at it, on the nearest
/// direction (turned from the preferred one toward the reach centre) that is within
/// reach, image up still as close to the fingers as the view allows. A hand too far
/// for any view gets the direction toward the reach centre.
pub fn camera_goal_within_reach(
    hand: &Isometry3<f64>,
    standoff_m: f64,
    side: ViewSide,
    look_at_in_hand: &Vector3<f64>,
    reach_centre: &Vector3<f64>,
    max_reach_m: f64,
) -> Isometry3<f64> {
    let goal = camera_goal(hand, standoff_m, side, look_at_in_hand);
    if (goal.translation.vector - reach_centre).norm() <= max_reach_m {
        return goal;
    }
    let centre = (hand * nalgebra::Point3::from(*look_at_in_hand)).coords;
    let to_reach = reach_centre - centre;
    let d = to_reach.norm();
    let Some(u) = Unit::try_new(to_reach, 1e-9) else {
        return goal;
    };
    let preferred = -(goal.rotation * Vector3::z());
    // |centre + r dir - reach_centre| <= R  <=>  cos(dir, u) >= k.
    let k = (d * d + standoff_m * standoff_m - max_reach_m * max_reach_m) / (2.0 * standoff_m * d);
    let dir = if k >= 1.0 {
        u.into_inner()
    } else {
        let across = preferred - u.into_inner() * preferred.dot(&u);
        match Unit::try_new(across, 1e-9) {
            Some(w) => {
                let phi = k.max(-1.0).acos();
                u.into_inner() * phi.cos() + w.into_inner() * phi.sin()
            }
            None => u.into_inner(),
        }
    };
    let z_cam = -dir;
    let fingers = hand.rotation * Vector3::z();
    let up = -fingers - z_cam * (-fingers).dot(&z_cam);
    let y_cam = Unit::try_new(up, 1e-6)
        .map(Unit::into_inner)
        .unwrap_or_else(|| z_cam.cross(&Vector3::x()).normalize());
    let x_cam = y_cam.cross(&z_cam);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_cam, y_cam, z_cam]));
    Isometry3::from_parts(
        (centre + dir * standoff_m).into(),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

impl CameraArmConfig {
    /// The camera goal for a hand pose with these settings (within reach).
    pub fn goal_for(&self, hand: &Isometry3<f64>) -> Isometry3<f64> {
        camera_goal_within_reach(
            hand,
            self.standoff_m,
            self.side,
            &Vector3::from(self.look_at_in_hand_m),
            &Vector3::from(self.reach_centre_m),
            self.max_reach_m,
        )
    }
}

/// A hand pose as received (node clock): the hand frame in the UR5 base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandSample {
    pub received_s: f64,
    pub pose: Isometry3<f64>,
}

/// The pedals as received.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PedalSample {
    pub received_s: f64,
    pub enable: bool,
    /// The left pedal.
    pub camera_stop: bool,
}

/// What the controller sees at one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CameraInputs {
    pub hand: Option<HandSample>,
    pub pedals: Option<PedalSample>,
}

/// Why the camera arm is not moving.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum CameraStopReason {
    /// No pedal state, or older than `input_deadline_s`.
    StaleOperatorInput,
    /// The enable switch is released.
    EnableReleased,
    /// The left pedal is pressed.
    CameraStopPedal,
    /// No accepted hand pose within `pose_deadline_s`.
    NoHandPose,
    /// The measured joints are not finite.
    InvalidArmState,
    /// The IK found no usable solution this step.
    IkFailed,
    /// The solution would bring a link within `hand_clearance_m` of the hand.
    TooCloseToHand,
}

impl CameraStopReason {
    /// Short name for counters.
    pub fn name(self) -> &'static str {
        match self {
            Self::StaleOperatorInput => "stale_operator_input",
            Self::EnableReleased => "enable_released",
            Self::CameraStopPedal => "camera_stop_pedal",
            Self::NoHandPose => "no_hand_pose",
            Self::InvalidArmState => "invalid_arm_state",
            Self::IkFailed => "ik_failed",
            Self::TooCloseToHand => "too_close_to_hand",
        }
    }
}

/// The result of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraStep {
    pub command: ArmCommand<UR5_DOF>,
    /// `None` while following.
    pub stopped: Option<CameraStopReason>,
    /// The camera goal for the newest accepted hand pose.
    pub goal: Option<Isometry3<f64>>,
    /// The goal after the Cartesian limiter (what the IK was asked for).
    pub target: Option<Isometry3<f64>>,
    /// Smallest distance of the commanded solution's links to the hand box, m.
    pub hand_clearance_m: Option<f64>,
}

/// Counters for the node status.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CameraCounters {
    pub steps: u64,
    pub following_steps: u64,
    pub rejected_hand_poses: u64,
    pub reacquired: u64,
    pub rejected_collision: u64,
    pub ik_failures: u64,
}

/// A z axis of one chain frame kept away from the inverse of its start direction.
#[derive(Debug, Clone)]
struct AxisAwayFrom {
    frame: usize,
    start: Unit<Vector3<f64>>,
    /// cos of (180 deg - margin): the dot product must stay above `-cos(margin)`.
    min_dot: f64,
}

/// Anti-redundancy as a distance for the IK's `MinDistance` goal: positive while every
/// watched axis is more than the margin away from its start direction's inverse.
#[derive(Debug, Clone)]
struct AntiFlip {
    axes: Vec<AxisAwayFrom>,
}

impl DistanceConstraint<UR5_DOF> for AntiFlip {
    fn distance(&self, frames: &[Isometry3<f64>]) -> f64 {
        self.axes
            .iter()
            .map(|a| match frames.get(a.frame) {
                // Scaled to be comparable with metres: 0.1 per unit of cosine.
                Some(f) => 0.1 * ((f.rotation * Vector3::z()).dot(&a.start) - a.min_dot),
                None => f64::NEG_INFINITY,
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// Frames of the UR5 camera chain watched by the anti-redundancy rule: the forearm
/// (after the elbow joint, index 2) and the second wrist link (after wrist 2, index 4).
pub const ANTI_FLIP_FRAMES: [usize; 2] = [2, 4];

#[derive(Debug, Clone, Copy)]
struct Jumped {
    anchor: Isometry3<f64>,
    since_s: f64,
}

/// The active-vision camera arm's core.
pub struct CameraArmController {
    cfg: CameraArmConfig,
    solver: Solver<UR5_DOF>,
    bodies: Arc<ChainBodies<UR5_DOF>>,
    anti_flip: Option<Arc<AntiFlip>>,
    jump: JumpFilter,
    limiter: CartesianLimiter,
    joint_limiter: JointVelocityLimiter<UR5_DOF>,
    hand: Option<(f64, Isometry3<f64>)>,
    last_received_s: f64,
    jumped: Option<Jumped>,
    following: bool,
    q_ik: Option<SVector<f64, UR5_DOF>>,
    step_timer: StepTimer,
    counters: CameraCounters,
    stop_counts: std::collections::BTreeMap<&'static str, u64>,
    last_stop: Option<CameraStopReason>,
}

impl std::fmt::Debug for CameraArmController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CameraArmController")
            .field("following", &self.following)
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

/// Errors building the controller.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CameraArmError {
    #[error("invalid camera arm config: {0}")]
    Config(String),
}

impl CameraArmController {
    /// The controller for the UR5 camera chain (`base_link` to `camera_optical_frame`)
    /// and its collision bodies.
    ///
    /// # Errors
    /// [`CameraArmError::Config`] naming an invalid setting.
    pub fn new(
        chain: FixedChain<UR5_DOF>,
        bodies: Arc<ChainBodies<UR5_DOF>>,
        cfg: CameraArmConfig,
    ) -> Result<Self, CameraArmError> {
        cfg.validate().map_err(CameraArmError::Config)?;
        let cap = SVector::<f64, UR5_DOF>::repeat(cfg.max_joint_velocity_rad_s);
        let limits = JointLimits::velocity_only(chain.velocity_limits().inf(&cap))
            .with_position_limits(chain.lower_limits(), chain.upper_limits());
        let joint_limiter = JointVelocityLimiter::new(
            limits,
            JointLimiterConfig {
                strategy: VelocityLimitStrategy::ScaleUniformly,
                ..JointLimiterConfig::default()
            },
        )
        .map_err(|e| CameraArmError::Config(format!("joint limits: {e}")))?;
        let jump = JumpFilter::new(cfg.jump).map_err(|e| CameraArmError::Config(e.to_string()))?;
        let limiter = CartesianLimiter::new(cfg.cartesian, &Isometry3::identity())
            .map_err(|e| CameraArmError::Config(e.to_string()))?;
        let solver = Solver::new(
            chain,
            IkSettings {
                tracking_iterations: 30,
                ..IkSettings::default()
            },
        );
        Ok(Self {
            cfg,
            solver,
            bodies,
            anti_flip: None,
            jump,
            limiter,
            joint_limiter,
            hand: None,
            last_received_s: f64::NEG_INFINITY,
            jumped: None,
            following: false,
            q_ik: None,
            step_timer: StepTimer::new(),
            counters: CameraCounters::default(),
            stop_counts: Default::default(),
            last_stop: None,
        })
    }

    pub fn config(&self) -> &CameraArmConfig {
        &self.cfg
    }
    pub fn counters(&self) -> CameraCounters {
        self.counters
    }
    pub fn is_following(&self) -> bool {
        self.following
    }
    /// The camera chain.
    pub fn chain(&self) -> &FixedChain<UR5_DOF> {
        self.solver.chain()
    }

    /// Named counters for the node status.
    pub fn named_counters(&self) -> Vec<(String, u64)> {
        let c = self.counters;
        let mut out = vec![
            ("camera_arm.steps".to_owned(), c.steps),
            ("camera_arm.following_steps".to_owned(), c.following_steps),
            ("camera_arm.reacquired".to_owned(), c.reacquired),
            (
                "camera_arm.rejected_collision".to_owned(),
                c.rejected_collision,
            ),
            ("camera_arm.ik_failures".to_owned(), c.ik_failures),
            (
                "hand_pose.rejected_by_camera_arm".to_owned(),
                c.rejected_hand_poses,
            ),
        ];
        for (kind, n) in self.jump.rejections().iter() {
            out.push((format!("hand_pose.rejected_{kind}"), n));
        }
        for (reason, n) in &self.stop_counts {
            out.push((format!("camera_arm.stop.{reason}"), *n));
        }
        out
    }

    /// The camera goal for a hand pose, with this controller's settings.
    pub fn goal_for(&self, hand: &Isometry3<f64>) -> Isometry3<f64> {
        self.cfg.goal_for(hand)
    }

    fn frames(&self, q: &SVector<f64, UR5_DOF>) -> Option<Vec<Isometry3<f64>>> {
        let mut f = vec![Isometry3::identity(); UR5_DOF + 1];
        self.solver
            .chain()
            .chain()
            .frames_into(q.as_slice(), &mut f)
            .ok()?;
        Some(f)
    }

    fn stop(&mut self, reason: CameraStopReason, goal: Option<Isometry3<f64>>) -> CameraStep {
        if self.following || self.last_stop != Some(reason) {
            *self.stop_counts.entry(reason.name()).or_insert(0) += 1;
        }
        self.following = false;
        self.last_stop = Some(reason);
        self.joint_limiter.reset(SVector::zeros());
        CameraStep {
            command: ArmCommand::stop(),
            stopped: Some(reason),
            goal,
            target: None,
            hand_clearance_m: None,
        }
    }

    /// Takes a new hand sample through the jump filter and the re-acquisition rule.
    fn accept_hand(&mut self, now_s: f64, sample: HandSample) {
        if sample.received_s.is_nan() || sample.received_s <= self.last_received_s {
            return;
        }
        self.last_received_s = sample.received_s;
        match self.jump.filter(&sample.pose) {
            Ok(p) => {
                self.hand = Some((now_s, p));
                self.jumped = None;
            }
            Err(e) => {
                self.counters.rejected_hand_poses += 1;
                tracing::debug!("hand pose rejected: {e}");
                if !sample.pose.translation.vector.iter().all(|v| v.is_finite())
                    || !sample.pose.rotation.coords.iter().all(|v| v.is_finite())
                {
                    return;
                }
                // The same far-away place for long enough: the hand really is there.
                match self.jumped {
                    Some(j)
                        if (j.anchor.translation.vector - sample.pose.translation.vector)
                            .norm()
                            <= self.cfg.reacquire_radius_m =>
                    {
                        if now_s - j.since_s >= self.cfg.reacquire_after_s {
                            self.jump.reset();
                            if self.jump.filter(&sample.pose).is_ok() {
                                self.hand = Some((now_s, sample.pose));
                                self.counters.reacquired += 1;
                                tracing::info!("camera arm re-acquired the hand after a jump");
                            }
                            self.jumped = None;
                        }
                    }
                    _ => {
                        self.jumped = Some(Jumped {
                            anchor: sample.pose,
                            since_s: now_s,
                        });
                    }
                }
            }
        }
    }

    /// One control step at `now_s` (node clock, s).
    pub fn step(
        &mut self,
        now_s: f64,
        inputs: &CameraInputs,
        arm: &ArmState<UR5_DOF>,
    ) -> CameraStep {
        self.counters.steps += 1;
        let dt = self
            .step_timer
            .step(now_s, 1.0 / self.cfg.rate_hz, self.cfg.max_dt_s);
        if let Some(h) = inputs.hand {
            self.accept_hand(now_s, h);
        }
        let goal = self.hand.map(|(_, p)| self.goal_for(&p));
        if !(arm.position_rad.iter().all(|v| v.is_finite())
            && arm.velocity_rad_s.iter().all(|v| v.is_finite()))
        {
            return self.stop(CameraStopReason::InvalidArmState, goal);
        }
        let Some(pedals) = inputs.pedals.filter(|p| {
            p.received_s.is_finite() && now_s - p.received_s <= self.cfg.input_deadline_s
        }) else {
            return self.stop(CameraStopReason::StaleOperatorInput, goal);
        };
        if !pedals.enable {
            return self.stop(CameraStopReason::EnableReleased, goal);
        }
        if pedals.camera_stop {
            return self.stop(CameraStopReason::CameraStopPedal, goal);
        }
        let (Some((accepted_s, hand)), Some(goal)) = (self.hand, goal) else {
            return self.stop(CameraStopReason::NoHandPose, None);
        };
        if now_s - accepted_s > self.cfg.pose_deadline_s {
            return self.stop(CameraStopReason::NoHandPose, Some(goal));
        }
        if self.anti_flip.is_none() {
            // The start directions of the watched axes: the arm as it is when it first
            // follows.
            let Some(frames) = self.frames(&arm.position_rad) else {
                return self.stop(CameraStopReason::InvalidArmState, Some(goal));
            };
            let min_dot = -self.cfg.redundancy_margin_deg.to_radians().cos();
            self.anti_flip = Some(Arc::new(AntiFlip {
                axes: ANTI_FLIP_FRAMES
                    .iter()
                    .map(|&frame| AxisAwayFrom {
                        frame,
                        start: Unit::new_normalize(frames[frame].rotation * Vector3::z()),
                        min_dot,
                    })
                    .collect(),
            }));
        }
        if !self.following {
            // (Re)starting: the limiter and the IK from where the camera is.
            let here = self.solver.chain().end_pose(&arm.position_rad);
            if self.limiter.reset(&here).is_err() {
                return self.stop(CameraStopReason::InvalidArmState, Some(goal));
            }
            self.q_ik = Some(arm.position_rad);
        }
        let Ok(target) = self.limiter.step(&goal, dt) else {
            return self.stop(CameraStopReason::InvalidArmState, Some(goal));
        };
        let q_prev = self.q_ik.unwrap_or(arm.position_rad);
        let Ok(volume) = ExternalVolume::hand_volume(hand, 0.0) else {
            return self.stop(CameraStopReason::NoHandPose, Some(goal));
        };
        let keep_out = Arc::new(ChainVolumeDistance::new(self.bodies.clone(), volume));
        let w = self.cfg.regularization_weight;
        let mut goals = vec![
            Goal::Pose {
                target,
                weight: 1.0,
                rotation_scale: self.cfg.rotation_scale,
            },
            Goal::JointRegularization {
                reference: q_prev,
                weight: w * w * THESIS_PERIOD_S / dt,
            },
            Goal::MinDistance {
                constraint: keep_out.clone(),
                min_distance_m: self.cfg.hand_clearance_m,
                weight: 100.0,
            },
        ];
        if let Some(anti) = &self.anti_flip {
            goals.push(Goal::MinDistance {
                constraint: anti.clone(),
                min_distance_m: 0.0,
                weight: 100.0,
            });
        }
        let q_ik = match self.solver.solve_tracking(&goals, &q_prev) {
            Ok(s) => s.q,
            Err(f) if matches!(f.kind, teleop_ik::FailureKind::NotConverged) => f.best.q,
            Err(f) => {
                tracing::debug!("camera IK failed: {f}");
                self.counters.ik_failures += 1;
                return self.stop(CameraStopReason::IkFailed, Some(goal));
            }
        };
        // The check before execution: the solution against the hand box.
        let clearance = self
            .frames(&q_ik)
            .map_or(f64::NEG_INFINITY, |f| keep_out.distance(&f));
        if clearance < self.cfg.hand_clearance_m - 1e-3 {
            self.counters.rejected_collision += 1;
            let mut s = self.stop(CameraStopReason::TooCloseToHand, Some(goal));
            s.hand_clearance_m = Some(clearance);
            return s;
        }
        let v = self.cfg.d1 * (q_ik - q_prev) / dt
            + self.cfg.feedback_gain_per_s * (q_ik - arm.position_rad);
        self.q_ik = Some(q_ik);
        let v = self
            .joint_limiter
            .step(&v, &arm.position_rad, dt)
            .unwrap_or_else(|_| SVector::zeros());
        self.following = true;
        self.last_stop = None;
        self.counters.following_steps += 1;
        CameraStep {
            command: ArmCommand { velocity_rad_s: v },
            stopped: None,
            goal: Some(goal),
            target: Some(target),
            hand_clearance_m: Some(clearance),
        }
    }
}
