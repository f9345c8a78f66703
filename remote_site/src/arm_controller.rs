//! PR2 arm relative control (thesis ch. 6.2.3 and 7.5), as a pure core: no clock, no
//! network. [`ArmController::step`] takes the time, the latest operator inputs (with the
//! time they were received) and the measured arm state, and returns the joint velocity
//! command.
//!
//! # Behaviour
//!
//! * **Clutch.** The arm moves only while the operator's clutch pedal is pressed *and*
//!   the enable (deadman) switch is held, with fresh operator input and the operator
//!   site alive. On engage the controller remembers the operator's wrist pose `H_ref`
//!   and the robot's wrist pose `R_ref`; while engaged the target is
//!   `R_ref * scale(H_ref^-1 * H_now)`, where `scale` multiplies the translation of the
//!   relative motion by the motion scale (the thesis used 1/3 for fine tasks). Releasing
//!   the clutch stops the arm; pressing it again starts from the new poses, so the
//!   operator can re-centre.
//! * **Filters.** Every wrist pose passes the jump filter (> 50 cm along an axis or > 60
//!   deg since the last accepted pose is rejected, named and counted); the target passes
//!   the Cartesian limiter (0.2 m/s, 2 rad/s, 2 m/s^2); the IK (pose goal weight 1 and
//!   regularization, weight 0.5, toward the controller's current joint solution, i.e. the
//!   previous IK solution) is warm-started from its last solution; the velocity law is
//!   `v = (d1 (q_ik(t) - q_ik(t-1)) + d2 (q_ik(t) - q_robot(t))) / dt` (eq. 6.1 with the
//!   joint differences per control period turned into rad/s: `d1` scales the IK's
//!   feed-forward velocity, `d2 / dt` is a proportional gain), then the joint velocity
//!   limiter (URDF limits, uniform scaling so the direction is kept; positions never
//!   driven past their limits).
//! * **Watchdog.** No valid wrist pose for longer than `pose_deadline_s` while engaged,
//!   operator input older than `input_deadline_s`, the enable switch released, the
//!   operator site's liveliness lost, an invalid motion scale or a non-finite arm state:
//!   zero velocity at once and disengage. After such a *safety* stop the arm re-engages
//!   only on a fresh clutch press (the clutch must be seen released first).

use nalgebra::{Isometry3, SVector, Translation3};
use serde::{Deserialize, Serialize};
use teleop_control::{
    CartesianLimiter, CartesianLimits, JointLimiterConfig, JointLimits, JointVelocityLimiter,
    JumpFilter, JumpFilterConfig, VelocityLimitStrategy,
};
use teleop_ik::{Goal, IkSettings, Solver};
use teleop_kinematics::FixedChain;

use teleop_hardware::{ArmCommand as Command, ArmState as State};

/// The PR2 chain's command.
pub type ArmCommand = Command<7>;
/// The PR2 chain's state.
pub type ArmState = State<7>;

/// Settings of the arm controller. Defaults are the thesis values.
///
/// The regularization goal pulls toward the previous IK solution, not toward the
/// measured joints: with `d1 = 0.7` the arm lags its IK solution by design, and pulling
/// the IK toward the lagging measurement makes the target drift (measured on the
/// simulated arm, 1/3 scale, 20 cm square: 45 mm mean error toward the measured joints,
/// 4 mm toward the previous solution; `tests/scenario_tracking.rs`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmControllerConfig {
    /// Control rate, Hz (thesis: 30; up to 1000).
    pub rate_hz: f64,
    /// Weight of the regularization goal toward the current joints (thesis: 0.5).
    pub regularization_weight: f64,
    /// Feed-forward factor `d1` of eq. 6.1 (thesis: 0.7).
    pub d1: f64,
    /// Feedback factor `d2` of eq. 6.1 (thesis: 0.1).
    pub d2: f64,
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
}

impl Default for ArmControllerConfig {
    fn default() -> Self {
        Self {
            rate_hz: 30.0,
            regularization_weight: 0.5,
            d1: 0.7,
            d2: 0.1,
            pose_deadline_s: 0.1,
            input_deadline_s: 0.2,
            max_ik_position_error_m: 0.01,
            joint_velocity_fraction: 1.0,
            jump: JumpFilterConfig::default(),
            cartesian: CartesianLimits::default(),
        }
    }
}

impl ArmControllerConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("rate_hz", self.rate_hz, 1.0, 1000.0),
            (
                "regularization_weight",
                self.regularization_weight,
                0.0,
                100.0,
            ),
            ("d1", self.d1, 0.0, 10.0),
            ("d2", self.d2, 0.0, 10.0),
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
        ];
        for (name, v, lo, hi) in checks {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(format!("arm.{name} must be in [{lo}, {hi}], got {v}"));
            }
        }
        self.jump.validate().map_err(|e| format!("arm.jump: {e}"))?;
        self.cartesian
            .validate()
            .map_err(|e| format!("arm.cartesian: {e}"))
    }
}

/// The operator's pedals and switches as received (robot clock).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatorSample {
    pub received_s: f64,
    pub clutch: bool,
    pub enable: bool,
    pub motion_scale: f64,
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
    /// The motion scale is not in (0, 1].
    InvalidMotionScale,
    /// The measured arm state is not finite.
    InvalidArmState,
    /// Waiting for the clutch to be released after a safety stop.
    AwaitingClutchRelease,
    /// Clutch pressed, but no fresh wrist pose to engage from.
    NoWristPose,
}

impl StopReason {
    pub fn name(self) -> &'static str {
        match self {
            StopReason::ClutchReleased => "clutch_released",
            StopReason::EnableReleased => "enable_released",
            StopReason::StaleOperatorInput => "stale_operator_input",
            StopReason::StaleWristPose => "stale_wrist_pose",
            StopReason::OperatorSiteLost => "operator_site_lost",
            StopReason::InvalidMotionScale => "invalid_motion_scale",
            StopReason::InvalidArmState => "invalid_arm_state",
            StopReason::AwaitingClutchRelease => "awaiting_clutch_release",
            StopReason::NoWristPose => "no_wrist_pose",
        }
    }

    /// Safety stops latch: re-engaging needs a fresh clutch press.
    pub fn is_safety_stop(self) -> bool {
        !matches!(
            self,
            StopReason::ClutchReleased
                | StopReason::AwaitingClutchRelease
                | StopReason::NoWristPose
        )
    }
}

/// The result of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmStep {
    pub command: ArmCommand,
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
    solver: Solver<7>,
    jump: JumpFilter,
    limiter: CartesianLimiter,
    joint_limiter: JointVelocityLimiter<7>,
    engaged: Option<Engaged>,
    latched: Option<StopReason>,
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
        Ok(Self {
            cfg,
            solver,
            jump,
            limiter,
            joint_limiter,
            engaged: None,
            latched: None,
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
            command: ArmCommand::stop(),
            stopped: Some(reason),
            target: None,
        }
    }

    /// One control step at time `now_s` (robot clock, seconds).
    pub fn step(&mut self, now_s: f64, inputs: &ArmInputs, arm: &ArmState) -> ArmStep {
        self.counters.steps += 1;
        let dt = 1.0 / self.cfg.rate_hz;
        if !(arm.position_rad.iter().all(|v| v.is_finite())
            && arm.velocity_rad_s.iter().all(|v| v.is_finite()))
        {
            return self.stop(StopReason::InvalidArmState);
        }
        if !inputs.operator_site_alive {
            return self.stop(StopReason::OperatorSiteLost);
        }
        let Some(op) = inputs.operator.filter(|o| {
            o.received_s.is_finite() && now_s - o.received_s <= self.cfg.input_deadline_s
        }) else {
            return self.stop(StopReason::StaleOperatorInput);
        };
        if !(op.motion_scale.is_finite() && op.motion_scale > 0.0 && op.motion_scale <= 1.0) {
            self.counters.rejected_operator_inputs += 1;
            return self.stop(StopReason::InvalidMotionScale);
        }
        if !op.enable {
            return self.stop(StopReason::EnableReleased);
        }
        if !op.clutch {
            // A released clutch clears a latched safety stop.
            self.latched = None;
            return self.stop(StopReason::ClutchReleased);
        }
        if self.latched.is_some() {
            return self.stop(StopReason::AwaitingClutchRelease);
        }
        let wrist = inputs.wrist.filter(|w| {
            w.received_s.is_finite() && now_s - w.received_s <= self.cfg.pose_deadline_s
        });
        let mut engaged = match (self.engaged, wrist) {
            (Some(_), None) => return self.stop(StopReason::StaleWristPose),
            (None, None) => return self.stop(StopReason::NoWristPose),
            (Some(e), Some(_)) => e,
            (None, Some(w)) => {
                // Engage: the first pose must itself be valid.
                self.jump.reset();
                if let Err(e) = self.jump.filter(&w.pose) {
                    self.counters.rejected_wrist_poses += 1;
                    tracing::debug!("wrist pose rejected at engage: {e}");
                    return self.stop(StopReason::NoWristPose);
                }
                let robot_ref = self.solver.chain().end_pose(&arm.position_rad);
                if self.limiter.reset(&robot_ref).is_err() {
                    return self.stop(StopReason::InvalidArmState);
                }
                self.counters.engagements += 1;
                Engaged {
                    human_ref: w.pose,
                    robot_ref,
                    human_now: w.pose,
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
                    engaged.human_now = p;
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
        let mut delta = engaged.human_ref.inverse() * engaged.human_now;
        delta.translation = Translation3::from(delta.translation.vector * op.motion_scale);
        let target = engaged.robot_ref * delta;
        let limited = match self.limiter.step(&target, dt) {
            Ok(p) => p,
            Err(_) => {
                self.engaged = Some(engaged);
                return self.stop(StopReason::InvalidArmState);
            }
        };
        let goals = [
            Goal::pose(limited),
            Goal::JointRegularization {
                reference: engaged.q_ik,
                weight: self.cfg.regularization_weight,
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
                command: ArmCommand::stop(),
                stopped: None,
                target: Some(limited),
            };
        };
        let v =
            (self.cfg.d1 * (q_ik - engaged.q_ik) + self.cfg.d2 * (q_ik - arm.position_rad)) / dt;
        engaged.q_ik = q_ik;
        self.engaged = Some(engaged);
        self.last_stop = None;
        let v = self
            .joint_limiter
            .step(&v, &arm.position_rad, dt)
            .unwrap_or_else(|_| SVector::zeros());
        ArmStep {
            command: ArmCommand { velocity_rad_s: v },
            stopped: None,
            target: Some(limited),
        }
    }
}
