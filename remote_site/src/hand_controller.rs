//! Shadow hand control at the robot site, as a pure core: no clock, no network.
//! [`HandSupervisor`] wraps the control laws of [`teleop_control::hand`] (position,
//! fixed-gain impedance, adaptive impedance + feedforward) with what the network and
//! the operator can get wrong.
//!
//! # Behaviour
//!
//! * **Targets.** The operator site's hand inference sends `JointState` targets for the
//!   17 finger joints, matched by name ([`SHADOW_FINGER_JOINTS`]; the two wrist joints belong
//!   to the arm). A message with a missing joint, a length mismatch or a non-finite
//!   value is refused; so is a target beyond a joint limit by more than
//!   `target_limit_margin_rad` (within the margin it is clamped to the limit: inference
//!   noise at a limit is normal). Refusals are counted by reason and change nothing.
//! * **Gate.** The hand follows the targets only while the [`OperatorGate`] is open —
//!   the same gate as the arm's: operator site alive, fresh operator input, a valid
//!   motion scale, the enable switch held and, in the thesis's gating
//!   (`gate = "clutch_and_enable"`, the default: ch. 7.3, the right pedal and the switch
//!   enable both the arm and the hand), the clutch pedal pressed; with
//!   `gate = "enable_only"` the switch alone — and the newest target is younger than
//!   `command_timeout_s`. A supervisor that starts (or restarts) while the operator
//!   holds the gate open waits until the operator lets go once (`awaiting_release`),
//!   so a restarted controller does not resume on pedals held from before. Each time
//!   the gate opens (a new engagement) the control law
//!   restarts: the adaptive profiles go back to their initial values and the phase to
//!   `s = 1`, as the adaptive law's time-indexed basis expects.
//! * **Hold.** Otherwise the hand **holds**: it
//!   keeps the last accepted target (the last safe posture; for a grasp it lies inside
//!   the object) with the control law frozen and every effort capped at
//!   `controller.hold_max_effort_nm`, so a held object stays held rather than dropped
//!   or squeezed harder. Before any target the hold posture is the measured one: the
//!   hand starts still.
//! * **Hardware lost.** Without a fresh hand state no effort can be computed; the
//!   supervisor then asks the hardware's own position servo to keep the hold posture
//!   ([`HandSupervisor::hardware_lost`]), or sends nothing if it never saw the hand.
//! * **Bad state.** A non-finite measured state is refused by the control law (counted);
//!   the previous command is sent again.
//! * **Gravity.** Every law adds the gravity compensation `G(q)` of eq. 8.2, computed
//!   from the URDF masses with the hand posed by the measured arm
//!   ([`crate::gravity`]); without an arm posture it adds none (counted).

use std::collections::BTreeMap;

use nalgebra::SVector;
use serde::{Deserialize, Serialize};
use teleop_control::hand::{
    HandControllerConfig, HandMode, HardwareInterface, JointInput, ShadowHandController,
};
use teleop_control::{Closed, ConfigError, GateMode, OperatorGate, OperatorSample};
use teleop_hardware::wire::{self, WireError};
use teleop_hardware::{HandCommand, HandState};
use teleop_interfaces::StepTimer;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_msgs::JointState;

use crate::gravity::HandGravity;

/// Settings of the hand supervisor; the control laws' gains are in `controller`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandSupervisorConfig {
    /// Control rate, Hz. Default 500 (the laws' gains are tuned for 1 kHz and stable
    /// at 200 Hz; see `teleop_control::hand::config`).
    pub rate_hz: f64,
    /// Targets older than this put the hand on hold, s. Default 0.2 (six periods of the
    /// 30 Hz inference stream).
    pub command_timeout_s: f64,
    /// Which operator inputs open the hand: the thesis's clutch pedal and enable switch
    /// (default), or the enable switch alone.
    pub gate: GateMode,
    /// Operator input (enable switch) older than this puts the hand on hold, s.
    /// Default 0.2, as the arm's `input_deadline_s`.
    pub input_timeout_s: f64,
    /// Targets beyond a joint limit by at most this much are clamped to it; further
    /// out they are refused, rad. Default 0.1.
    pub target_limit_margin_rad: f64,
    /// Compensate gravity on the fingers (the `G` of eq. 8.2) from the URDF masses,
    /// with the hand posed by the measured arm. Default true.
    pub gravity_compensation: bool,
    /// Gravity in the PR2 `base_link` frame, m/s^2. Default `[0, 0, -9.81]`.
    pub gravity_m_s2: [f64; 3],
    /// How the laws reach the hand: `"impedance"` (default) sends each period the law
    /// as a joint impedance (gains, set point, feed-forward) that the hand's own loop
    /// evaluates with its newest measurement, so the stiff part of the fingers' loop
    /// never crosses the bus; `"effort"` sends the efforts, closing the whole loop
    /// through the bus (its delay then limits the usable gains: over the bus at
    /// 500 Hz the default gains make the fingers chatter, docs/remote-site.md).
    pub interface: HardwareInterface,
    /// The control laws, their gains and effort limits.
    pub controller: HandControllerConfig<17>,
}

impl Default for HandSupervisorConfig {
    fn default() -> Self {
        Self {
            rate_hz: 500.0,
            command_timeout_s: 0.2,
            gate: GateMode::ClutchAndEnable,
            input_timeout_s: 0.2,
            target_limit_margin_rad: 0.1,
            gravity_compensation: true,
            gravity_m_s2: [0.0, 0.0, -9.81],
            interface: HardwareInterface::Impedance,
            controller: HandControllerConfig::default(),
        }
    }
}

impl HandSupervisorConfig {
    /// # Errors
    /// A message naming the first bad field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.rate_hz.is_finite() && self.rate_hz >= 10.0 && self.rate_hz <= 1000.0) {
            return Err(format!(
                "rate_hz must be in [10, 1000], got {}",
                self.rate_hz
            ));
        }
        for (name, v) in [
            ("command_timeout_s", self.command_timeout_s),
            ("input_timeout_s", self.input_timeout_s),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 10.0) {
                return Err(format!("{name} must be in (0, 10] s, got {v}"));
            }
        }
        let m = self.target_limit_margin_rad;
        if !(m.is_finite() && (0.0..=0.5).contains(&m)) {
            return Err(format!(
                "target_limit_margin_rad must be in [0, 0.5], got {m}"
            ));
        }
        let g = nalgebra::Vector3::from(self.gravity_m_s2);
        if !(g.iter().all(|x| x.is_finite()) && g.norm() <= 20.0) {
            return Err(format!(
                "gravity_m_s2 must be finite with a norm <= 20, got {:?}",
                self.gravity_m_s2
            ));
        }
        self.controller
            .validate()
            .map_err(|e| format!("controller: {e}"))
    }
}

/// Why a supervisor could not be built.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SupervisorError {
    #[error("hand controller config: {0}")]
    Config(#[from] ConfigError),
    #[error("robot model for gravity compensation: {0}")]
    Model(#[from] teleop_kinematics::KinematicsError),
}

/// Why a target message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TargetRejection {
    #[error("malformed hand target: {0}")]
    Malformed(#[from] WireError),
    #[error(
        "hand target for `{joint}` is {value} rad, outside [{lower}, {upper}] by more than the margin"
    )]
    OutOfRange {
        joint: &'static str,
        value: f64,
        lower: f64,
        upper: f64,
    },
}

impl TargetRejection {
    /// Short name for counters.
    pub fn kind(&self) -> &'static str {
        match self {
            TargetRejection::Malformed(WireError::NonFinite { .. }) => "non_finite",
            TargetRejection::Malformed(WireError::MissingJoint(_)) => "missing_joint",
            TargetRejection::Malformed(_) => "malformed",
            TargetRejection::OutOfRange { .. } => "out_of_range",
        }
    }
}

/// Why the hand is holding instead of following.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum HoldReason {
    /// No target accepted yet.
    NoTarget,
    /// The newest target is older than `command_timeout_s`.
    StaleTarget,
    /// No operator input yet, or older than `input_timeout_s`.
    StaleOperatorInput,
    /// The enable switch is released.
    EnableReleased,
    /// The clutch pedal is released (thesis gating).
    ClutchReleased,
    /// The motion scale in the operator input is invalid.
    InvalidOperatorInput,
    /// None of the operator site's nodes is alive.
    OperatorSiteLost,
    /// The controller started while the operator held the gate open: it follows only
    /// after the operator has let go once (and pressed again).
    AwaitingRelease,
}

impl HoldReason {
    /// Short name for counters and logs.
    pub fn name(self) -> &'static str {
        match self {
            HoldReason::NoTarget => "no_target",
            HoldReason::StaleTarget => "stale_target",
            HoldReason::StaleOperatorInput => "stale_operator_input",
            HoldReason::EnableReleased => "enable_released",
            HoldReason::ClutchReleased => "clutch_released",
            HoldReason::InvalidOperatorInput => "invalid_operator_input",
            HoldReason::OperatorSiteLost => "operator_site_lost",
            HoldReason::AwaitingRelease => "awaiting_release",
        }
    }
}

/// Result of one control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandStep {
    /// What to write to the hardware.
    pub command: HandCommand,
    /// `Some` while holding.
    pub hold: Option<HoldReason>,
}

/// The hand controller with its input checks and watchdog; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct HandSupervisor {
    config: HandSupervisorConfig,
    controller: ShadowHandController,
    gravity: Option<HandGravity>,
    gravity_unknown: u64,
    lower: SVector<f64, 17>,
    upper: SVector<f64, 17>,
    target: Option<(SVector<f64, 17>, f64)>,
    step_timer: StepTimer,
    last_hold: Option<HoldReason>,
    /// The operator has been seen letting go (enable or clutch released) since the
    /// supervisor started: until then the hand holds.
    armed: bool,
    steps: u64,
    targets_accepted: u64,
    targets_rejected: BTreeMap<&'static str, u64>,
    holds: BTreeMap<&'static str, u64>,
    state_rejections: u64,
    engagements: u64,
}

impl HandSupervisor {
    /// A supervisor for a hand with the given finger joint limits ([`SHADOW_FINGER_JOINTS`]
    /// order), holding until the first target.
    ///
    /// # Errors
    /// The control laws' configuration errors; the robot model's, for gravity
    /// compensation.
    pub fn new(
        config: HandSupervisorConfig,
        lower_rad: SVector<f64, 17>,
        upper_rad: SVector<f64, 17>,
    ) -> Result<Self, SupervisorError> {
        let gravity = if config.gravity_compensation {
            Some(HandGravity::new(config.gravity_m_s2.into())?)
        } else {
            None
        };
        Ok(Self {
            controller: ShadowHandController::new(config.controller)?
                .with_interface(config.interface),
            gravity,
            gravity_unknown: 0,
            config,
            lower: lower_rad,
            upper: upper_rad,
            target: None,
            step_timer: StepTimer::new(),
            last_hold: Some(HoldReason::NoTarget),
            armed: false,
            steps: 0,
            targets_accepted: 0,
            targets_rejected: BTreeMap::new(),
            holds: BTreeMap::new(),
            state_rejections: 0,
            engagements: 0,
        })
    }

    /// The Shadow hand's finger joint limits from our URDF ([`SHADOW_FINGER_JOINTS`] order).
    ///
    /// # Errors
    /// Only if the embedded model lacked a finger joint.
    pub fn shadow_hand_limits()
    -> Result<(SVector<f64, 17>, SVector<f64, 17>), teleop_kinematics::KinematicsError> {
        let robot = teleop_kinematics::robots::shadow_hand()?;
        let limits: Vec<_> = robot.dof_limits().collect();
        let mut lower = SVector::zeros();
        let mut upper = SVector::zeros();
        for (i, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            let l = limits[robot.dof_index(name)?];
            lower[i] = l.lower;
            upper[i] = l.upper;
        }
        Ok((lower, upper))
    }

    /// Checks a target message received at `received_s` and makes it the newest
    /// target.
    ///
    /// # Errors
    /// [`TargetRejection`] naming the problem; counted, nothing changes.
    pub fn accept_target(
        &mut self,
        msg: &JointState,
        received_s: f64,
    ) -> Result<(), TargetRejection> {
        let r = self.check_target(msg);
        match r {
            Ok(q) => {
                self.target = Some((q, received_s));
                self.targets_accepted += 1;
                Ok(())
            }
            Err(e) => {
                *self.targets_rejected.entry(e.kind()).or_default() += 1;
                Err(e)
            }
        }
    }

    fn check_target(&self, msg: &JointState) -> Result<SVector<f64, 17>, TargetRejection> {
        let mut q = wire::finger_targets(msg)?;
        let m = self.config.target_limit_margin_rad;
        for i in 0..17 {
            let (lo, hi) = (self.lower[i], self.upper[i]);
            if q[i] < lo - m || q[i] > hi + m {
                return Err(TargetRejection::OutOfRange {
                    joint: SHADOW_FINGER_JOINTS[i],
                    value: q[i],
                    lower: lo,
                    upper: hi,
                });
            }
            q[i] = q[i].clamp(lo, hi);
        }
        Ok(q)
    }

    /// One control period at `now_s` with the operator's pedals and switch, the operator
    /// site's liveliness, the measured hand state and the measured arm posture (for
    /// gravity compensation: without it, none is applied and the period is counted as
    /// `hand.gravity_unknown`).
    pub fn step(
        &mut self,
        now_s: f64,
        operator: Option<OperatorSample>,
        operator_site_alive: bool,
        state: &HandState,
        arm_position_rad: Option<&SVector<f64, 7>>,
    ) -> HandStep {
        let dt = self.step_timer.step(
            now_s,
            1.0 / self.config.rate_hz,
            self.config.controller.max_dt_s,
        );
        self.steps += 1;
        let hold = self.hold_reason(now_s, operator, operator_site_alive);
        if let Some(reason) = hold {
            if self.last_hold != Some(reason) {
                tracing::info!(reason = reason.name(), "hand on hold");
            }
            *self.holds.entry(reason.name()).or_default() += 1;
        } else if self.last_hold.is_some() {
            // A new engagement: the adaptive law starts over (profiles, phase s = 1).
            self.controller.reset();
            self.engagements += 1;
            tracing::info!("hand follows the operator's targets");
        }
        self.last_hold = hold;
        let gravity = match (&mut self.gravity, arm_position_rad) {
            (Some(model), Some(arm)) if arm.iter().all(|x| x.is_finite()) => {
                model.compensation_nm(arm, &state.position_rad)
            }
            (Some(_), _) => {
                self.gravity_unknown += 1;
                SVector::zeros()
            }
            (None, _) => SVector::zeros(),
        };
        let out = match (hold, self.target) {
            (None, Some((target, _))) => self.controller.step_input(
                dt,
                &JointInput::new(state.position_rad, state.velocity_rad_s, target)
                    .with_gravity(gravity),
            ),
            _ => self.controller.hold_with_gravity(
                dt,
                &state.position_rad,
                &state.velocity_rad_s,
                &gravity,
            ),
        };
        let command = match out {
            Ok(o) => HandCommand::from(o),
            Err(_) => {
                self.state_rejections += 1;
                HandCommand::from(*self.controller.last_output())
            }
        };
        HandStep { command, hold }
    }

    fn hold_reason(
        &mut self,
        now_s: f64,
        operator: Option<OperatorSample>,
        alive: bool,
    ) -> Option<HoldReason> {
        let gate = OperatorGate {
            input_timeout_s: self.config.input_timeout_s,
            mode: self.config.gate,
        };
        if let Err(closed) = gate.check(now_s, operator.as_ref(), alive) {
            self.armed |= closed.by_operator();
            return Some(match closed {
                Closed::OperatorSiteLost => HoldReason::OperatorSiteLost,
                Closed::StaleInput => HoldReason::StaleOperatorInput,
                Closed::InvalidMotionScale => HoldReason::InvalidOperatorInput,
                Closed::EnableReleased => HoldReason::EnableReleased,
                Closed::ClutchReleased => HoldReason::ClutchReleased,
            });
        }
        if !self.armed {
            return Some(HoldReason::AwaitingRelease);
        }
        match self.target {
            None => Some(HoldReason::NoTarget),
            Some((_, at)) if now_s - at > self.config.command_timeout_s => {
                Some(HoldReason::StaleTarget)
            }
            Some(_) => None,
        }
    }

    /// The command to send when the hand's state is lost: the hardware's own position
    /// servo keeps the hold posture; `None` if the hand was never seen.
    pub fn hardware_lost(&mut self) -> Option<HandCommand> {
        *self.holds.entry("hardware_lost").or_default() += 1;
        self.controller
            .hold_target_rad()
            .map(|q| HandCommand::Position(*q))
    }

    /// The active control law.
    pub fn mode(&self) -> HandMode {
        self.controller.mode()
    }

    /// The control laws (profiles, limits).
    pub fn controller(&self) -> &ShadowHandController {
        &self.controller
    }

    /// The newest accepted target, rad.
    pub fn target_rad(&self) -> Option<&SVector<f64, 17>> {
        self.target.as_ref().map(|(q, _)| q)
    }

    /// Why the last step held, if it did.
    pub fn hold_reason_now(&self) -> Option<HoldReason> {
        self.last_hold
    }

    /// Counters for the node status: steps, targets accepted/refused by reason, hold
    /// periods by reason, refused states, controller rejections.
    pub fn named_counters(&self) -> Vec<(String, u64)> {
        let mut out = vec![
            ("hand.steps".to_owned(), self.steps),
            ("hand.engagements".to_owned(), self.engagements),
            ("hand.targets_accepted".to_owned(), self.targets_accepted),
            ("hand.state_rejected".to_owned(), self.state_rejections),
            ("hand.gravity_unknown".to_owned(), self.gravity_unknown),
        ];
        for (k, n) in &self.targets_rejected {
            out.push((format!("hand.target_rejected.{k}"), *n));
        }
        for (k, n) in &self.holds {
            out.push((format!("hand.hold.{k}"), *n));
        }
        out
    }
}
