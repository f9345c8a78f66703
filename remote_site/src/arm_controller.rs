//! PR2 arm relative control (thesis ch. 6.2.3 and 7.5), as a pure core: no clock, no
//! network. [`ArmController::step`] takes the time, the latest operator inputs (with the
//! time they were received) and the measured arm state, and returns the joint velocity
//! command.
//!
//! # Behaviour
//!
//! * **Gate.** The arm moves only while the [`OperatorGate`] is open: operator site
//!   alive, fresh operator input, a valid motion scale, the enable (deadman) switch
//!   held and the clutch pedal pressed.
//! * **Clutch.** On engage the controller remembers the operator's hand pose `H_ref`
//!   (the tracked marker pose times the marker-to-hand calibration) and the robot's
//!   palm pose `R_ref`. While engaged the target follows the operator's motion since
//!   then, its translation multiplied by the motion scale (the thesis used 1/3 for fine
//!   tasks), in one of three frames ([`RelativeFrame`]):
//!   * **base-aligned translation, hand rotation** (default): the hand's displacement
//!     `H_now.t - H_ref.t` in the tracker frame is turned into the robot's base frame by
//!     the fixed operator-to-robot rotation `A`, and the hand's rotation since the press
//!     taken about its own axes is applied about the palm's:
//!     `t = R_ref.t + s A (H_now.t - H_ref.t)`, `R = R_ref.R (H_ref.R^T H_now.R)`.
//!     Moving the hand to the operator's right moves the robot to the robot's right;
//!     turning the hand about its fingers turns the palm about its fingers (pouring),
//!     however the hand and the robot's forearm lie;
//!   * **base-aligned**: the same translation, the rotation `H_now.R H_ref.R^T` also in
//!     the base's axes: `R = (A H_now.R H_ref.R^T A^T) R_ref.R` (the default until the
//!     pouring task: an operator's fingers-up turn became a yaw of the PR2's
//!     horizontal forearm that its joints could not make in place, 1.1 cm off);
//!   * **wrist** (the earliest behaviour): `R_ref * scale(H_ref^-1 * H_now)`, the motion
//!     taken in the operator's hand frame and applied in the robot's palm frame, so the
//!     direction depends on how hand and palm were turned at the press.
//!
//!   Releasing the clutch stops the arm; pressing it again starts from the new poses,
//!   so the operator can re-centre.
//! * **Absolute mode** ([`ArmMode::Absolute`], thesis ch. 6 with the IMU suit): each
//!   wrist pose is the palm's target in the torso frame, scaled to the robot's arm by
//!   the operator site; the target is `base_from_frame * pose`. The clutch engages only
//!   when that target is near the palm (`absolute.engage_within_m` / `_deg`), so the
//!   arm never sets off across its workspace; everything below applies unchanged.
//! * **Filters.** Every wrist pose passes the jump filter (> 50 cm along an axis or > 60
//!   deg since the last accepted pose is rejected, named and counted); the target passes
//!   the Cartesian limiter (0.2 m/s, 2 rad/s, 2 m/s^2); the IK (thesis: bio_ik with a
//!   pose goal of weight 1 and a regularization goal of weight 0.5; see
//!   [`ArmControllerConfig::regularization_weight`] for how the weights map onto ours)
//!   is warm-started from its last solution; the velocity law is eq. 6.1 with its gains
//!   expressed per second ([`ArmControllerConfig::feedback_gain_per_s`]):
//!   `v = d1 (q_ik(t) - q_ik(t-1)) / dt + k (q_ik(t) - q_robot(t))`, so it behaves the
//!   same at 30 Hz and at 1 kHz; then the joint velocity limiter (URDF limits, uniform
//!   scaling so the direction is kept; positions never driven past their limits).
//! * **Time step.** `dt` is measured between steps (a skipped tick gives a longer
//!   step) and clamped to `max_dt_s`.
//! * **Watchdog.** No valid wrist pose for longer than `pose_deadline_s` while engaged,
//!   the gate closing for any reason but the clutch (operator input stale, enable
//!   released, operator site lost, invalid motion scale) or a non-finite arm state:
//!   zero velocity at once and disengage. After such a *safety* stop the arm re-engages
//!   only on a fresh clutch press (the clutch must be seen released first); so does a
//!   controller that starts (or restarts after a crash) while the operator holds the
//!   clutch: it engages only after seeing the operator let go once.

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use teleop_control::{
    CartesianLimiter, CartesianLimits, Closed, GateMode, JointLimiterConfig, JointLimits,
    JointVelocityLimiter, JumpFilter, JumpFilterConfig, OperatorGate, TransformConfig,
    VelocityLimitStrategy,
};

pub use teleop_control::OperatorSample;
use teleop_ik::{Goal, IkSettings, Solver};
use teleop_kinematics::FixedChain;

use teleop_hardware::{ArmCommand, ArmState};
use teleop_interfaces::StepTimer;

/// The PR2 chain's command (5 arm joints and the Shadow hand's 2 wrist joints).
pub type Pr2ArmCommand = ArmCommand<7>;
/// The PR2 chain's state.
pub type Pr2ArmState = ArmState<7>;

/// The thesis's control period (30 Hz): the rate its IK weights were tuned at, s.
pub const THESIS_PERIOD_S: f64 = 1.0 / 30.0;

/// In which frame the operator's relative motion is applied to the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RelativeFrame {
    /// Displacements and rotations in the tracker frame, turned into the robot's base
    /// frame by the fixed operator-to-robot rotation (see the [module docs](self)).
    BaseAligned,
    /// The motion in the hand's own frame applied in the palm's frame.
    Wrist,
    /// Translations as [`RelativeFrame::BaseAligned`] (along the base's axes);
    /// rotations as [`RelativeFrame::Wrist`] (about the hand's own axes, applied about
    /// the palm's): turning the hand about its fingers turns the palm about its fingers,
    /// however the robot's forearm lies (the pouring turn is a forearm roll on both).
    /// Assumes the hand frame (Fig. 3.6) and the palm frame name the same axes (z along
    /// the fingers), as the retargeting's common frame does. The default.
    #[default]
    BaseAlignedHandRotation,
}

/// How the arm follows the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArmMode {
    /// Clutched relative control (thesis ch. 7): the arm copies the hand's motion since
    /// the clutch press. The default.
    #[default]
    Relative,
    /// Absolute following (thesis ch. 6, the IMU suit): each wrist pose is the palm's
    /// target in [`AbsoluteConfig::frame_id`] (the torso), already scaled to the robot's
    /// arm by the operator site. Same gate, clutch, filters, limits and watchdogs; the
    /// motion scale is not applied (the arm-length ratio is the scale).
    Absolute,
}

/// The absolute mode's settings, `[arm.absolute]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AbsoluteConfig {
    /// The frame the targets must be in (their `header.frame_id`); a pose in any other
    /// frame is refused and counted (`wrist_pose.rejected_frame_id`). Default
    /// `torso_lift_link`.
    pub frame_id: String,
    /// That frame in the arm's base frame (`base_link`). Default: the torso at the
    /// model's height, `(-0.05, 0, 0.739675)` m (the PR2 URDF's `torso_lift_joint`).
    pub base_from_frame: TransformConfig,
    /// The clutch engages only while the target is within this distance of the palm,
    /// m (otherwise the arm holds, `arm.stop.target_far_from_arm`): the operator first
    /// brings the arm's pose to the robot's. Default 0.15.
    pub engage_within_m: f64,
    /// ... and within this angle of the palm's orientation, deg. Default 45.
    pub engage_within_deg: f64,
}

impl Default for AbsoluteConfig {
    fn default() -> Self {
        Self {
            frame_id: teleop_kinematics::robots::pr2::TORSO.into(),
            base_from_frame: TransformConfig {
                translation_m: [-0.05, 0.0, 0.739675],
                rpy_deg: [0.0; 3],
            },
            engage_within_m: 0.15,
            engage_within_deg: 45.0,
        }
    }
}

/// What the IK's regularization goal pulls toward.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegularizationReference {
    /// The previous IK solution (default): measured on the simulated arm, pulling toward
    /// the arm that lags its IK solution by design (`d1 < 1`) makes the target drift.
    #[default]
    PreviousSolution,
    /// The measured joints, as the thesis text reads ("close to the current state").
    MeasuredJoints,
}

/// Settings of the arm controller. Defaults are the thesis values where it gives them,
/// except the three gains of the IK and the velocity law (regularization 0.3, `d1` 1.0,
/// feedback 10 /s): measured in the closed loop (`teleop launch`, docs/local-site.md,
/// "Tuning the arms"), the thesis's 0.5 / 0.7 / 3 /s (its 0.5 mapped without bio_ik's
/// per-joint factors, so stiffer than the thesis's) made the palm follow the operator
/// 155 ms late (12 mm mean error on the pick-and-place task); these follow within
/// 30-65 ms (3 mm). The thesis's values remain a config away.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmControllerConfig {
    /// Control rate, Hz (thesis: 30; up to 1000).
    pub rate_hz: f64,
    /// Longest time step used, s (after a stall the law does not extrapolate further).
    /// Default 0.1.
    pub max_dt_s: f64,
    /// Weight of the IK's regularization goal **as bio_ik weighs goals**, at the
    /// thesis's 30 Hz (thesis: 0.5; 1.0 over-smoothed). bio_ik minimizes
    /// `sum_i w_i^2 c_i` with each goal's cost `c_i` (position error in m^2, joint
    /// displacement in rad^2), so this weight enters our solver's cost squared: 0.5
    /// here is 0.25 in `teleop_ik` terms. bio_ik's minimal-displacement goal also
    /// multiplies each joint's displacement by a factor from the velocity limits
    /// (summing to 1, 0.098-0.176 for this arm), which this mapping leaves out: with
    /// them the thesis's 0.5 is 0.0024-0.0077 per joint in our terms, 32-104x less
    /// (docs/remote-site.md, "What that mapping leaves out"). Toward the previous solution the goal
    /// penalizes each step's joint displacement, which shrinks with the step: so that
    /// the smoothing does not change with the rate, the weight is also multiplied by
    /// `(1/30 s) / dt` ([`ArmControllerConfig::ik_regularization_weight`]). Default 0.3:
    /// with 0.5 the regularized solution trailed the moving target by several periods;
    /// with 0.2 the 7-joint arm's redundancy drifted into its joint limits on a fast
    /// square (tests/scenario_tracking.rs).
    pub regularization_weight: f64,
    /// What the regularization goal pulls toward.
    pub regularization_reference: RegularizationReference,
    /// Weight of the rotation error in the pose goal, on the rotation vector (rad).
    /// Default 0.25: bio_ik's pose goal weighs the squared quaternion difference
    /// (~ angle^2 / 4) by `rotation_scale^2` with its default 0.5, i.e. the rotation
    /// vector by 0.25.
    pub rotation_scale: f64,
    /// Feed-forward factor `d1` of eq. 6.1 (thesis: 0.7): the fraction of the IK's own
    /// joint velocity commanded. Default 1.0: with `d1 < 1` the arm lags its IK
    /// solution by `(1 - d1) / k` of motion (0.1 s with the thesis's values).
    pub d1: f64,
    /// Feedback gain of eq. 6.1 per second: the thesis's `d2 = 0.1` acted once per
    /// 30 Hz period, i.e. 3 /s. Written per second so the law does not change with the
    /// rate (at 1 kHz `d2` per period would be 33x stiffer). Default 10 /s: pulls the
    /// arm's own lag (30 ms servo lags) back onto the IK solution in ~0.1 s.
    pub feedback_gain_per_s: f64,
    /// Frame of the relative motion.
    pub frame: RelativeFrame,
    /// Rotation from the operator's tracker frame to the robot's base frame
    /// (base-aligned mode), roll/pitch/yaw in deg. Default identity: the tracker's x, y,
    /// z are the robot's (the operator faces the way the robot faces).
    pub operator_to_robot_rpy_deg: [f64; 3],
    /// The hand's frame relative to the tracked marker on the back of the hand
    /// (calibration). Default identity.
    pub marker_to_hand: TransformConfig,
    /// Longest time without a valid wrist pose while engaged, s.
    pub pose_deadline_s: f64,
    /// Longest age of the operator input (pedals, enable), s. Default 0.2 (ten periods
    /// of the 50 Hz pedal stream).
    pub input_deadline_s: f64,
    /// An IK step that did not converge is still used when the tip is within this
    /// distance of the target (the regularization goal alone keeps it from converging
    /// exactly); otherwise the arm holds.
    pub max_ik_position_error_m: f64,
    /// Fraction of the URDF joint velocity limits the arm may use, (0, 1].
    pub joint_velocity_fraction: f64,
    pub jump: JumpFilterConfig,
    pub cartesian: CartesianLimits,
    /// Relative (default) or absolute following.
    pub mode: ArmMode,
    /// The absolute mode's settings.
    pub absolute: AbsoluteConfig,
}

impl Default for ArmControllerConfig {
    fn default() -> Self {
        Self {
            rate_hz: 30.0,
            max_dt_s: 0.1,
            regularization_weight: 0.3,
            regularization_reference: RegularizationReference::PreviousSolution,
            rotation_scale: 0.25,
            d1: 1.0,
            feedback_gain_per_s: 10.0,
            frame: RelativeFrame::BaseAlignedHandRotation,
            operator_to_robot_rpy_deg: [0.0; 3],
            marker_to_hand: TransformConfig::default(),
            pose_deadline_s: 0.1,
            input_deadline_s: 0.2,
            max_ik_position_error_m: 0.01,
            joint_velocity_fraction: 1.0,
            jump: JumpFilterConfig::default(),
            cartesian: CartesianLimits::default(),
            mode: ArmMode::Relative,
            absolute: AbsoluteConfig::default(),
        }
    }
}

impl ArmControllerConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("rate_hz", self.rate_hz, 1.0, 1000.0),
            ("max_dt_s", self.max_dt_s, 1e-3, 1.0),
            (
                "regularization_weight",
                self.regularization_weight,
                0.0,
                100.0,
            ),
            ("rotation_scale", self.rotation_scale, 0.0, 10.0),
            ("d1", self.d1, 0.0, 10.0),
            ("feedback_gain_per_s", self.feedback_gain_per_s, 0.0, 1000.0),
            ("pose_deadline_s", self.pose_deadline_s, 1e-3, 10.0),
            ("input_deadline_s", self.input_deadline_s, 1e-3, 10.0),
            (
                "max_ik_position_error_m",
                self.max_ik_position_error_m,
                0.0,
                1.0,
            ),
            (
                "joint_velocity_fraction",
                self.joint_velocity_fraction,
                1e-3,
                1.0,
            ),
            (
                "absolute.engage_within_m",
                self.absolute.engage_within_m,
                1e-3,
                2.0,
            ),
            (
                "absolute.engage_within_deg",
                self.absolute.engage_within_deg,
                0.1,
                180.0,
            ),
        ];
        teleop_control::check_ranges("arm", &checks)?;
        TransformConfig {
            translation_m: [0.0; 3],
            rpy_deg: self.operator_to_robot_rpy_deg,
        }
        .validate("arm.operator_to_robot_rpy_deg")?;
        self.marker_to_hand.validate("arm.marker_to_hand")?;
        self.absolute
            .base_from_frame
            .validate("arm.absolute.base_from_frame")?;
        if self.absolute.frame_id.trim().is_empty() {
            return Err("arm.absolute.frame_id is empty".into());
        }
        self.jump.validate().map_err(|e| format!("arm.jump: {e}"))?;
        self.cartesian
            .validate()
            .map_err(|e| format!("arm.cartesian: {e}"))
    }

    /// The regularization weight in `teleop_ik`'s terms for a step of `dt_s`: the
    /// bio_ik weight squared, times `(1/30 s) / dt` toward the previous solution (see
    /// [`ArmControllerConfig::regularization_weight`]).
    pub fn ik_regularization_weight(&self, dt_s: f64) -> f64 {
        let w = self.regularization_weight * self.regularization_weight;
        match self.regularization_reference {
            RegularizationReference::PreviousSolution => w * THESIS_PERIOD_S / dt_s,
            RegularizationReference::MeasuredJoints => w,
        }
    }
}

/// A wrist pose as received (robot clock), in the operator's tracker frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WristSample {
    pub received_s: f64,
    pub pose: Isometry3<f64>,
}

/// What the controller sees of the operator site at one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmInputs {
    pub operator: Option<OperatorSample>,
    pub wrist: Option<WristSample>,
    /// The operator site's nodes are alive (liveliness).
    pub operator_site_alive: bool,
    /// The hand on the arm is commanded: its controller and the source of its targets
    /// are alive (liveliness). Always `true` for an arm without a hand.
    pub hand_alive: bool,
    /// The wrist poses and the pedals come from different operator sites (the node
    /// checks the publishers' identities): the arm does not engage. An engaged arm keeps
    /// following the sources it locked onto.
    pub commander_conflict: bool,
}

/// Why the arm is not moving.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum StopReason {
    /// The clutch pedal is released (normal operation).
    ClutchReleased,
    /// The enable (deadman) switch is released.
    EnableReleased,
    /// No operator input within `input_deadline_s`.
    StaleOperatorInput,
    /// No valid wrist pose within `pose_deadline_s` while engaged.
    StaleWristPose,
    /// The operator site's liveliness is lost.
    OperatorSiteLost,
    /// A node commanding the hand on the arm (its controller, the source of its
    /// targets) lost its liveliness: an arm does not carry a hand nobody commands
    /// into the scene.
    HandNodeLost,
    /// The motion scale is not in (0, 1].
    InvalidMotionScale,
    /// The measured arm state is not finite.
    InvalidArmState,
    /// Waiting for the clutch to be released after a safety stop.
    AwaitingClutchRelease,
    /// Clutch pressed, but no fresh wrist pose to engage from.
    NoWristPose,
    /// Clutch pressed, but the wrist poses and the pedals come from different operator
    /// sites: no engagement.
    CommanderConflict,
    /// Absolute mode: clutch pressed, but the target is farther from the palm than
    /// `absolute.engage_within_m` / `_deg`: no engagement.
    TargetFarFromArm,
}

impl StopReason {
    /// Short name for counters.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::ClutchReleased => "clutch_released",
            StopReason::EnableReleased => "enable_released",
            StopReason::StaleOperatorInput => "stale_operator_input",
            StopReason::StaleWristPose => "stale_wrist_pose",
            StopReason::OperatorSiteLost => "operator_site_lost",
            StopReason::HandNodeLost => "hand_node_lost",
            StopReason::InvalidMotionScale => "invalid_motion_scale",
            StopReason::InvalidArmState => "invalid_arm_state",
            StopReason::AwaitingClutchRelease => "awaiting_clutch_release",
            StopReason::NoWristPose => "no_wrist_pose",
            StopReason::CommanderConflict => "commander_conflict",
            StopReason::TargetFarFromArm => "target_far_from_arm",
        }
    }

    /// Safety stops latch: re-engaging needs a fresh clutch press.
    pub fn is_safety_stop(self) -> bool {
        !matches!(
            self,
            StopReason::ClutchReleased
                | StopReason::AwaitingClutchRelease
                | StopReason::NoWristPose
                | StopReason::CommanderConflict
                | StopReason::TargetFarFromArm
        )
    }
}

/// The result of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmStep {
    pub command: Pr2ArmCommand,
    /// `None` while engaged and moving; otherwise why the arm is stopped.
    pub stopped: Option<StopReason>,
    /// The Cartesian target after the limiter (while engaged).
    pub target: Option<Isometry3<f64>>,
}

#[derive(Debug, Clone, Copy)]
struct Engaged {
    human_ref: Isometry3<f64>,
    robot_ref: Isometry3<f64>,
    human_now: Isometry3<f64>,
    last_pose_s: f64,
    last_pose_received_s: f64,
    q_ik: SVector<f64, 7>,
}

/// Counters for the node status.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ArmCounters {
    pub steps: u64,
    pub engagements: u64,
    pub safety_stops: u64,
    pub ik_failures: u64,
    pub rejected_wrist_poses: u64,
    pub rejected_operator_inputs: u64,
}

/// The PR2 arm's relative-control core.
#[derive(Debug)]
pub struct ArmController {
    cfg: ArmControllerConfig,
    gate: OperatorGate,
    operator_to_robot: UnitQuaternion<f64>,
    marker_to_hand: Isometry3<f64>,
    base_from_absolute: Isometry3<f64>,
    step_timer: StepTimer,
    solver: Solver<7>,
    jump: JumpFilter,
    limiter: CartesianLimiter,
    joint_limiter: JointVelocityLimiter<7>,
    engaged: Option<Engaged>,
    latched: Option<StopReason>,
    /// The operator has been seen letting go (clutch or enable released) since the
    /// controller started: until then it does not engage.
    armed: bool,
    last_stop: Option<StopReason>,
    counters: ArmCounters,
    stop_counts: std::collections::BTreeMap<&'static str, u64>,
}

/// Errors building the controller.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ArmControllerError {
    #[error("invalid arm controller config: {0}")]
    Config(String),
}

impl ArmController {
    /// # Errors
    /// [`ArmControllerError::Config`] naming an invalid setting.
    pub fn new(chain: FixedChain<7>, cfg: ArmControllerConfig) -> Result<Self, ArmControllerError> {
        cfg.validate().map_err(ArmControllerError::Config)?;
        let limits =
            JointLimits::velocity_only(chain.velocity_limits() * cfg.joint_velocity_fraction)
                .with_position_limits(chain.lower_limits(), chain.upper_limits());
        let joint_limiter = JointVelocityLimiter::new(
            limits,
            JointLimiterConfig {
                strategy: VelocityLimitStrategy::ScaleUniformly,
                ..JointLimiterConfig::default()
            },
        )
        .map_err(|e| ArmControllerError::Config(format!("joint limits: {e}")))?;
        let jump =
            JumpFilter::new(cfg.jump).map_err(|e| ArmControllerError::Config(e.to_string()))?;
        let limiter = CartesianLimiter::new(cfg.cartesian, &Isometry3::identity())
            .map_err(|e| ArmControllerError::Config(e.to_string()))?;
        let solver = Solver::new(
            chain,
            IkSettings {
                tracking_iterations: 30,
                ..IkSettings::default()
            },
        );
        let [r, p, y] = cfg.operator_to_robot_rpy_deg.map(f64::to_radians);
        Ok(Self {
            gate: OperatorGate {
                input_timeout_s: cfg.input_deadline_s,
                mode: GateMode::ClutchAndEnable,
            },
            operator_to_robot: UnitQuaternion::from_euler_angles(r, p, y),
            marker_to_hand: cfg.marker_to_hand.isometry(),
            base_from_absolute: cfg.absolute.base_from_frame.isometry(),
            step_timer: StepTimer::new(),
            cfg,
            solver,
            jump,
            limiter,
            joint_limiter,
            engaged: None,
            latched: None,
            armed: false,
            last_stop: Some(StopReason::ClutchReleased),
            counters: ArmCounters::default(),
            stop_counts: Default::default(),
        })
    }

    pub fn config(&self) -> &ArmControllerConfig {
        &self.cfg
    }
    pub fn is_engaged(&self) -> bool {
        self.engaged.is_some()
    }
    /// The safety stop that latched the arm (it re-engages only on a fresh clutch
    /// press), if any.
    pub fn latched(&self) -> Option<StopReason> {
        self.latched
    }
    pub fn counters(&self) -> ArmCounters {
        self.counters
    }
    /// Whether the operator has been seen letting go since the controller started (until
    /// then a clutch press does not engage).
    pub fn armed(&self) -> bool {
        self.armed
    }
    /// The IK chain (base_link to the palm).
    pub fn chain(&self) -> &FixedChain<7> {
        self.solver.chain()
    }

    /// Named counters for the node status: steps, stops by reason, rejections.
    pub fn named_counters(&self) -> Vec<(String, u64)> {
        let c = self.counters;
        let mut out = vec![
            ("arm.steps".to_owned(), c.steps),
            ("arm.engagements".to_owned(), c.engagements),
            ("arm.safety_stops".to_owned(), c.safety_stops),
            ("arm.ik_failures".to_owned(), c.ik_failures),
            (
                "wrist_pose.rejected_by_controller".to_owned(),
                c.rejected_wrist_poses,
            ),
            (
                "operator_input.rejected_by_controller".to_owned(),
                c.rejected_operator_inputs,
            ),
        ];
        for (kind, n) in self.jump.rejections().iter() {
            out.push((format!("wrist_pose.rejected_{kind}"), n));
        }
        for (reason, n) in &self.stop_counts {
            out.push((format!("arm.stop.{reason}"), *n));
        }
        out
    }

    fn stop(&mut self, reason: StopReason) -> ArmStep {
        let was_engaged = self.engaged.take().is_some();
        if was_engaged || self.last_stop != Some(reason) {
            *self.stop_counts.entry(reason.name()).or_insert(0) += 1;
        }
        // A safety stop of a moving arm latches until the clutch is released; before
        // anything moved (e.g. the operator site not up yet) there is nothing to latch.
        if reason.is_safety_stop() && was_engaged {
            if self.latched.is_none() {
                self.counters.safety_stops += 1;
            }
            self.latched = Some(reason);
        }
        self.last_stop = Some(reason);
        self.joint_limiter.reset(SVector::zeros());
        ArmStep {
            command: Pr2ArmCommand::stop(),
            stopped: Some(reason),
            target: None,
        }
    }

    /// The robot target for the operator's hand at `human_now`, given the references
    /// taken at the clutch press and the motion scale.
    pub fn relative_target(
        &self,
        human_ref: &Isometry3<f64>,
        human_now: &Isometry3<f64>,
        robot_ref: &Isometry3<f64>,
        motion_scale: f64,
    ) -> Isometry3<f64> {
        let a = self.operator_to_robot;
        // The base-aligned frames' translation: the hand's displacement in the base's axes.
        let base_aligned = || {
            let dp = human_now.translation.vector - human_ref.translation.vector;
            Translation3::from(robot_ref.translation.vector + a * (dp * motion_scale))
        };
        match self.cfg.frame {
            RelativeFrame::BaseAligned => {
                let dr = human_now.rotation * human_ref.rotation.inverse();
                Isometry3::from_parts(base_aligned(), a * dr * a.inverse() * robot_ref.rotation)
            }
            RelativeFrame::BaseAlignedHandRotation => {
                let dr = human_ref.rotation.inverse() * human_now.rotation;
                Isometry3::from_parts(base_aligned(), robot_ref.rotation * dr)
            }
            RelativeFrame::Wrist => {
                let mut delta = human_ref.inverse() * human_now;
                delta.translation = Translation3::from(delta.translation.vector * motion_scale);
                robot_ref * delta
            }
        }
    }

    /// One control step at time `now_s` (robot clock, seconds).
    pub fn step(&mut self, now_s: f64, inputs: &ArmInputs, arm: &Pr2ArmState) -> ArmStep {
        self.counters.steps += 1;
        let dt = self
            .step_timer
            .step(now_s, 1.0 / self.cfg.rate_hz, self.cfg.max_dt_s);
        if !(arm.position_rad.iter().all(|v| v.is_finite())
            && arm.velocity_rad_s.iter().all(|v| v.is_finite()))
        {
            return self.stop(StopReason::InvalidArmState);
        }
        let op = match self
            .gate
            .check(now_s, inputs.operator.as_ref(), inputs.operator_site_alive)
        {
            Ok(op) => op,
            Err(closed) => {
                self.armed |= closed.by_operator();
                let reason = match closed {
                    Closed::OperatorSiteLost => StopReason::OperatorSiteLost,
                    Closed::StaleInput => StopReason::StaleOperatorInput,
                    Closed::InvalidMotionScale => {
                        self.counters.rejected_operator_inputs += 1;
                        StopReason::InvalidMotionScale
                    }
                    Closed::EnableReleased => StopReason::EnableReleased,
                    Closed::ClutchReleased => {
                        // A released clutch clears a latched safety stop.
                        self.latched = None;
                        StopReason::ClutchReleased
                    }
                };
                return self.stop(reason);
            }
        };
        if !inputs.hand_alive {
            return self.stop(StopReason::HandNodeLost);
        }
        // A latched safety stop, or a controller started while the operator held the
        // pedals: the operator must let go and press again.
        if self.latched.is_some() || !self.armed {
            return self.stop(StopReason::AwaitingClutchRelease);
        }
        let wrist = inputs.wrist.filter(|w| {
            w.received_s.is_finite() && now_s - w.received_s <= self.cfg.pose_deadline_s
        });
        let mut engaged = match (self.engaged, wrist) {
            (Some(_), None) => return self.stop(StopReason::StaleWristPose),
            (None, None) => return self.stop(StopReason::NoWristPose),
            (Some(e), Some(_)) => e,
            (None, Some(_)) if inputs.commander_conflict => {
                return self.stop(StopReason::CommanderConflict);
            }
            (None, Some(w)) => {
                // Engage: the first pose must itself be valid.
                self.jump.reset();
                if let Err(e) = self.jump.filter(&w.pose) {
                    self.counters.rejected_wrist_poses += 1;
                    tracing::debug!("wrist pose rejected at engage: {e}");
                    return self.stop(StopReason::NoWristPose);
                }
                let robot_ref = self.solver.chain().end_pose(&arm.position_rad);
                let human = w.pose * self.marker_to_hand;
                if self.cfg.mode == ArmMode::Absolute {
                    let target = self.base_from_absolute * human;
                    let far = (target.translation.vector - robot_ref.translation.vector).norm()
                        > self.cfg.absolute.engage_within_m
                        || target.rotation.angle_to(&robot_ref.rotation).to_degrees()
                            > self.cfg.absolute.engage_within_deg;
                    if far {
                        return self.stop(StopReason::TargetFarFromArm);
                    }
                }
                if self.limiter.reset(&robot_ref).is_err() {
                    return self.stop(StopReason::InvalidArmState);
                }
                self.counters.engagements += 1;
                Engaged {
                    human_ref: human,
                    robot_ref,
                    human_now: human,
                    last_pose_s: now_s,
                    last_pose_received_s: w.received_s,
                    q_ik: arm.position_rad,
                }
            }
        };
        // A new wrist sample: filter it. A rejected one leaves the target where it was,
        // and does not count as a valid pose for the deadline.
        if let Some(w) = wrist
            && w.received_s > engaged.last_pose_received_s
        {
            engaged.last_pose_received_s = w.received_s;
            match self.jump.filter(&w.pose) {
                Ok(p) => {
                    engaged.human_now = p * self.marker_to_hand;
                    engaged.last_pose_s = now_s;
                }
                Err(e) => {
                    self.counters.rejected_wrist_poses += 1;
                    tracing::debug!("wrist pose rejected: {e}");
                }
            }
        }
        if now_s - engaged.last_pose_s > self.cfg.pose_deadline_s {
            self.engaged = Some(engaged);
            return self.stop(StopReason::StaleWristPose);
        }
        let target = match self.cfg.mode {
            ArmMode::Relative => self.relative_target(
                &engaged.human_ref,
                &engaged.human_now,
                &engaged.robot_ref,
                op.motion_scale,
            ),
            ArmMode::Absolute => self.base_from_absolute * engaged.human_now,
        };
        let limited = match self.limiter.step(&target, dt) {
            Ok(p) => p,
            Err(_) => {
                self.engaged = Some(engaged);
                return self.stop(StopReason::InvalidArmState);
            }
        };
        let reference = match self.cfg.regularization_reference {
            RegularizationReference::PreviousSolution => engaged.q_ik,
            RegularizationReference::MeasuredJoints => arm.position_rad,
        };
        let goals = [
            Goal::Pose {
                target: limited,
                weight: 1.0,
                rotation_scale: self.cfg.rotation_scale,
            },
            Goal::JointRegularization {
                reference,
                weight: self.cfg.ik_regularization_weight(dt),
            },
        ];
        let q_ik = match self.solver.solve_tracking(&goals, &engaged.q_ik) {
            Ok(s) => Some(s.q),
            // With the regularization goal the pose goal is rarely met exactly; the best
            // solution is used when it is close to the target, or closer than the last one
            // (a moving target that the regularized IK is still catching up with).
            Err(f) => {
                let before = self.solver.chain().end_pose(&engaged.q_ik);
                let err_before = (before.translation.vector - limited.translation.vector).norm();
                let err_best = f
                    .best
                    .residuals
                    .first()
                    .map_or(f64::INFINITY, |r| r.position_m);
                if matches!(f.kind, teleop_ik::FailureKind::NotConverged)
                    && (err_best <= self.cfg.max_ik_position_error_m || err_best < err_before)
                {
                    Some(f.best.q)
                } else {
                    tracing::debug!("IK step failed: {f}");
                    None
                }
            }
        };
        let Some(q_ik) = q_ik else {
            self.counters.ik_failures += 1;
            self.engaged = Some(engaged);
            self.joint_limiter.reset(SVector::zeros());
            return ArmStep {
                command: Pr2ArmCommand::stop(),
                stopped: None,
                target: Some(limited),
            };
        };
        // Eq. 6.1 with per-second gains: d1 times the IK's joint velocity, plus a
        // proportional pull toward the IK solution.
        let v = self.cfg.d1 * (q_ik - engaged.q_ik) / dt
            + self.cfg.feedback_gain_per_s * (q_ik - arm.position_rad);
        engaged.q_ik = q_ik;
        self.engaged = Some(engaged);
        self.last_stop = None;
        let v = self
            .joint_limiter
            .step(&v, &arm.position_rad, dt)
            .unwrap_or_else(|_| SVector::zeros());
        ArmStep {
            command: Pr2ArmCommand { velocity_rad_s: v },
            stopped: None,
            target: Some(limited),
        }
    }
}
