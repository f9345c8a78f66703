//! Shadow hand joint controllers (thesis ch. 8): position servo, fixed-gain
//! impedance, and the biomimetic adaptive impedance + feedforward controller.
//!
//! Pure cores, generic over the number of joints `N` (the hand: `N = 17`, the
//! remote site's `SHADOW_FINGER_JOINTS` order; [`ShadowHandController`]). No clock, no I/O,
//! no allocation after construction: the caller reads the hardware, passes the
//! measured state, the target from the operator's hand inference and the period
//! `dt`, and writes the returned command.
//!
//! | mode | law (per joint, `e = q - q_d`, `ė = q̇ - q̇_d`) | core |
//! |---|---|---|
//! | [`HandMode::Position`] | `τ = G - Kp e - Kd ė`, or the target itself for the hardware's servo | [`FixedImpedance::pd_servo`] |
//! | [`HandMode::FixedImpedance`] | `τ = τ0 + G - K_s e - K_d ė`, constant gains | [`FixedImpedance`] |
//! | [`HandMode::Adaptive`] | `τ = G - Γε - (K_s e + K_d ė) - v`, `K_s`, `K_d`, `v` adapted online (eqs. 8.1-8.17) | [`AdaptiveImpedance`] |
//!
//! Every effort, in every mode, is clamped to `±max_effort_nm` (the same maximum
//! across modes). Units: rad, rad/s, N m, seconds.
//!
//! # The wrapper: [`HandController`]
//!
//! * [`step`](HandController::step)`(dt, q, q̇, q_d)` → [`HandOutput`] (effort, or
//!   position for [`PositionServo::Hardware`]). NaN/inf in any input, or `dt` NaN,
//!   infinite or `<= 0`, is refused with a [`Rejection`] and changes **nothing**:
//!   [`last_output`](HandController::last_output) is still the command to send.
//! * [`set_mode`](HandController::set_mode) switches the law and resets the
//!   controllers (adaptive profiles back to their initial values, phase `s = 1`).
//! * [`hold`](HandController::hold)`(dt, q, q̇)` for a stale command stream (expired
//!   watchdog): keeps the **last accepted target** — the last safe posture, which for
//!   a grasp lies inside the object — with the current law frozen (no adaptation, no
//!   phase progress: stale data must not train the profiles) and the effort clamped to
//!   `hold_max_effort_nm` (`<= max_effort_nm`). So a held object stays held, with at
//!   most the hold effort, rather than dropped (zero effort) or squeezed harder. If
//!   no target was ever accepted, the posture measured at the first `hold` is kept.

pub mod adaptive;
pub mod basis;
pub mod config;
pub mod fixed;
pub mod input;
pub mod position;

pub use adaptive::{AdaptiveImpedance, CompliantProfiles};
pub use basis::GaussianBasis;
pub use config::{
    AdaptiveConfig, BasisConfig, FixedImpedanceConfig, HandControllerConfig, HandMode,
    HardwareInterface, PerJoint, PositionConfig, PositionServo, SHADOW_FINGER_MAX_EFFORT_NM,
};
pub use fixed::FixedImpedance;
pub use input::JointInput;

use nalgebra::SVector;
pub use teleop_hardware::JointImpedance;
use teleop_hardware::{FINGER_DOF, HandCommand};

use crate::error::{ConfigError, Rejection, RejectionCounts};
use input::check_dt;

/// Number of actuated finger joints of the Shadow hand with BioTacs (the five J1 are
/// fixed; the wrist belongs to the arm chain).
pub const SHADOW_FINGER_JOINT_COUNT: usize = FINGER_DOF;

/// The hand controller for the Shadow hand's 17 finger joints.
pub type ShadowHandController = HandController<SHADOW_FINGER_JOINT_COUNT>;

/// A command for the hand.
#[derive(Debug, Clone, Copy, PartialEq)]
// Copied every control period without allocating: the impedance stays inline.
#[allow(clippy::large_enum_variant)]
pub enum HandOutput<const N: usize> {
    /// Joint efforts, N m, within the effort limits.
    Effort(SVector<f64, N>),
    /// Joint position targets for the hardware's own servo, rad
    /// ([`PositionServo::Hardware`]).
    Position(SVector<f64, N>),
    /// The law as a joint impedance for the hardware's own loop
    /// ([`HardwareInterface::Impedance`]).
    Impedance(JointImpedance<N>),
}

impl<const N: usize> HandOutput<N> {
    /// The efforts, if this is an effort command.
    pub fn effort_nm(&self) -> Option<&SVector<f64, N>> {
        match self {
            HandOutput::Effort(t) => Some(t),
            _ => None,
        }
    }

    /// The positions, if this is a position command.
    pub fn position_rad(&self) -> Option<&SVector<f64, N>> {
        match self {
            HandOutput::Position(q) => Some(q),
            _ => None,
        }
    }

    /// The impedance, if this is an impedance command.
    pub fn impedance(&self) -> Option<&JointImpedance<N>> {
        match self {
            HandOutput::Impedance(z) => Some(z),
            _ => None,
        }
    }
}

/// A control law's output as the hardware command that carries it.
impl From<HandOutput<FINGER_DOF>> for HandCommand {
    fn from(out: HandOutput<FINGER_DOF>) -> Self {
        match out {
            HandOutput::Effort(t) => HandCommand::Effort(t),
            HandOutput::Position(q) => HandCommand::Position(q),
            HandOutput::Impedance(z) => HandCommand::Impedance(z),
        }
    }
}

/// The hand controller: one of three laws, effort limits, hold behaviour; see the
/// [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct HandController<const N: usize> {
    config: HandControllerConfig<N>,
    mode: HandMode,
    interface: HardwareInterface,
    max_effort_nm: SVector<f64, N>,
    hold_max_effort_nm: SVector<f64, N>,
    position: FixedImpedance<N>,
    fixed: FixedImpedance<N>,
    adaptive: AdaptiveImpedance<N>,
    last_output: HandOutput<N>,
    hold_target_rad: Option<SVector<f64, N>>,
    holding: bool,
    rejections: RejectionCounts,
}

impl<const N: usize> HandController<N> {
    /// A controller in `config.mode`, with zero effort as its last output (before the
    /// first valid step the hand is limp).
    ///
    /// # Errors
    ///
    /// [`HandControllerConfig::validate`]'s error.
    pub fn new(config: HandControllerConfig<N>) -> Result<Self, ConfigError> {
        config.validate()?;
        let max_effort_nm = config.max_effort_nm.to_vector();
        Ok(Self {
            config,
            mode: config.mode,
            interface: HardwareInterface::default(),
            max_effort_nm,
            hold_max_effort_nm: config.hold_max_effort_nm.to_vector(),
            position: FixedImpedance::pd_servo(&config.position, max_effort_nm)?,
            fixed: FixedImpedance::new(&config.fixed_impedance, max_effort_nm)?,
            adaptive: AdaptiveImpedance::new(&config.adaptive, max_effort_nm, config.max_dt_s)?,
            last_output: HandOutput::Effort(SVector::zeros()),
            hold_target_rad: None,
            holding: false,
            rejections: RejectionCounts::default(),
        })
    }

    /// The same controller sending its law in the form `interface` (efforts by
    /// default).
    #[must_use]
    pub fn with_interface(mut self, interface: HardwareInterface) -> Self {
        self.interface = interface;
        self
    }

    /// The form the laws' outputs take.
    pub fn interface(&self) -> HardwareInterface {
        self.interface
    }

    /// One control period with measured positions `q` (rad) and velocities `q̇`
    /// (rad/s) and the target positions `q_d` (rad); zero target velocity and gravity.
    ///
    /// # Errors
    ///
    /// As [`step_input`](Self::step_input).
    pub fn step(
        &mut self,
        dt_s: f64,
        position_rad: &SVector<f64, N>,
        velocity_rad_s: &SVector<f64, N>,
        target_rad: &SVector<f64, N>,
    ) -> Result<HandOutput<N>, Rejection> {
        self.step_input(
            dt_s,
            &JointInput::new(*position_rad, *velocity_rad_s, *target_rad),
        )
    }

    /// One control period with a full input (target velocity, gravity). The target
    /// becomes the hold posture; the output becomes [`last_output`](Self::last_output).
    ///
    /// # Errors
    ///
    /// [`Rejection::InvalidTimeStep`] for `dt_s` NaN, infinite or `<= 0`;
    /// [`Rejection::NonFinite`] for a NaN or infinity in the input. Nothing changes:
    /// send [`last_output`](Self::last_output) again.
    pub fn step_input(
        &mut self,
        dt_s: f64,
        input: &JointInput<N>,
    ) -> Result<HandOutput<N>, Rejection> {
        self.checked(dt_s, input)?;
        let effort = match self.mode {
            HandMode::Position => match self.config.position.servo {
                PositionServo::Effort => self.position.effort(input, &self.max_effort_nm),
                PositionServo::Hardware => {
                    return Ok(self.accepted(input, HandOutput::Position(input.target_rad)));
                }
            },
            HandMode::FixedImpedance => self.fixed.effort(input, &self.max_effort_nm),
            // Adapts the profiles (either interface).
            HandMode::Adaptive => self.adaptive.step_checked(dt_s, input, &self.max_effort_nm),
        };
        let output = match self.interface {
            HardwareInterface::Effort => HandOutput::Effort(effort),
            HardwareInterface::Impedance => {
                HandOutput::Impedance(self.impedance(input, 1.0, &self.max_effort_nm))
            }
        };
        Ok(self.accepted(input, output))
    }

    /// The current law as a joint impedance about `input`'s target, its gains and
    /// feed-forward scaled by `scale`, clamped at `limit_nm`.
    fn impedance(
        &self,
        input: &JointInput<N>,
        scale: f64,
        limit_nm: &SVector<f64, N>,
    ) -> JointImpedance<N> {
        let (k, d, f) = match self.mode {
            HandMode::Position => self.position.impedance(),
            HandMode::FixedImpedance => self.fixed.impedance(),
            HandMode::Adaptive => self.adaptive.impedance(),
        };
        JointImpedance {
            position_rad: input.target_rad,
            velocity_rad_s: input.target_velocity_rad_s,
            stiffness_nm_rad: k * scale,
            damping_nm_s_rad: d * scale,
            feedforward_nm: (f + input.gravity_nm) * scale,
            max_effort_nm: *limit_nm,
        }
    }

    /// Records an accepted step's output.
    fn accepted(&mut self, input: &JointInput<N>, output: HandOutput<N>) -> HandOutput<N> {
        self.hold_target_rad = Some(input.target_rad);
        self.holding = false;
        self.last_output = output;
        output
    }

    /// One period of the hold behaviour (stale commands): keep the last accepted
    /// target with the current law frozen and the effort clamped to
    /// `hold_max_effort_nm`; see the [module docs](self).
    ///
    /// # Errors
    ///
    /// As [`step_input`](Self::step_input); nothing changes.
    pub fn hold(
        &mut self,
        dt_s: f64,
        position_rad: &SVector<f64, N>,
        velocity_rad_s: &SVector<f64, N>,
    ) -> Result<HandOutput<N>, Rejection> {
        self.hold_with_gravity(dt_s, position_rad, velocity_rad_s, &SVector::zeros())
    }

    /// [`hold`](Self::hold) with a gravity torque `G(q)`, N m.
    ///
    /// # Errors
    ///
    /// As [`step_input`](Self::step_input); nothing changes.
    pub fn hold_with_gravity(
        &mut self,
        dt_s: f64,
        position_rad: &SVector<f64, N>,
        velocity_rad_s: &SVector<f64, N>,
        gravity_nm: &SVector<f64, N>,
    ) -> Result<HandOutput<N>, Rejection> {
        let target = self.hold_target_rad.unwrap_or(*position_rad);
        let input =
            JointInput::new(*position_rad, *velocity_rad_s, target).with_gravity(*gravity_nm);
        self.checked(dt_s, &input)?;
        // The law's effort within the normal limits, then scaled down as a whole so no
        // joint exceeds its hold limit: the efforts keep their ratios, so each
        // fingertip keeps pushing in the same direction, only less hard (clamping joint
        // by joint would turn the fingertip forces and let a grasp slide).
        let limit = &self.max_effort_nm;
        let hold = self.hold_max_effort_nm;
        let effort = match self.mode {
            HandMode::Position => match self.config.position.servo {
                PositionServo::Effort => self.position.effort(&input, limit),
                PositionServo::Hardware => SVector::zeros(),
            },
            HandMode::FixedImpedance => self.fixed.effort(&input, limit),
            HandMode::Adaptive => self.adaptive.effort_frozen(&input, limit),
        };
        // The largest factor (<= 1) that brings every joint within its hold limit.
        let scale = (0..N)
            .filter(|&i| effort[i].abs() > hold[i])
            .map(|i| hold[i] / effort[i].abs())
            .fold(1.0, f64::min);
        let output = match (self.mode, self.config.position.servo, self.interface) {
            (HandMode::Position, PositionServo::Hardware, _) => HandOutput::Position(target),
            (_, _, HardwareInterface::Effort) => HandOutput::Effort(effort * scale),
            // The same scale on the whole impedance, from the effort now; the hardware
            // clamps each joint at its hold limit as the posture changes.
            (_, _, HardwareInterface::Impedance) => {
                HandOutput::Impedance(self.impedance(&input, scale, &hold))
            }
        };
        self.hold_target_rad = Some(target);
        self.holding = true;
        self.last_output = output;
        Ok(output)
    }

    fn checked(&mut self, dt_s: f64, input: &JointInput<N>) -> Result<(), Rejection> {
        let r = check_dt(dt_s).and_then(|()| input.check());
        if let Err(r) = &r {
            self.rejections.record(r);
        }
        r
    }

    /// Switches the control law. A different mode resets the controllers
    /// ([`reset`](Self::reset)); the same mode changes nothing.
    pub fn set_mode(&mut self, mode: HandMode) {
        if mode != self.mode {
            self.mode = mode;
            self.reset();
        }
    }

    /// Restarts the adaptation: initial profiles, phase `s = 1` (call when control
    /// resumes, e.g. the clutch re-engages). The last output and the hold posture
    /// are kept.
    pub fn reset(&mut self) {
        self.adaptive.reset();
    }

    /// The active control law.
    pub fn mode(&self) -> HandMode {
        self.mode
    }

    /// The last command returned by [`step`](Self::step) or [`hold`](Self::hold):
    /// the one to send again after a rejection. Zero effort before the first.
    pub fn last_output(&self) -> &HandOutput<N> {
        &self.last_output
    }

    /// The posture [`hold`](Self::hold) keeps: the last accepted target, rad.
    pub fn hold_target_rad(&self) -> Option<&SVector<f64, N>> {
        self.hold_target_rad.as_ref()
    }

    /// `true` while the last output came from [`hold`](Self::hold).
    pub fn is_holding(&self) -> bool {
        self.holding
    }

    /// `K_s`, `K_d`, `v`, `ε` of the adaptive controller at its last step, for
    /// logging (its initial profiles while another mode is active).
    pub fn profiles(&self) -> &CompliantProfiles<N> {
        self.adaptive.profiles()
    }

    /// The adaptive controller (weights, basis, phase).
    pub fn adaptive(&self) -> &AdaptiveImpedance<N> {
        &self.adaptive
    }

    /// Effort limits of every mode, N m.
    pub fn max_effort_nm(&self) -> &SVector<f64, N> {
        &self.max_effort_nm
    }

    /// Effort limits while holding, N m.
    pub fn hold_max_effort_nm(&self) -> &SVector<f64, N> {
        &self.hold_max_effort_nm
    }

    /// The configuration in use (its `mode` is the initial one; see
    /// [`mode`](Self::mode)).
    pub fn config(&self) -> &HandControllerConfig<N> {
        &self.config
    }

    /// Rejected inputs per reason.
    pub fn rejections(&self) -> &RejectionCounts {
        &self.rejections
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn controller(mode: HandMode) -> HandController<2> {
        HandController::new(HandControllerConfig {
            mode,
            ..Default::default()
        })
        .unwrap()
    }

    #[test]
    fn default_config_is_valid_and_parses_from_empty_toml() {
        let c: HandControllerConfig<17> = toml::from_str("").unwrap();
        assert_eq!(c, HandControllerConfig::default());
        assert!(ShadowHandController::new(c).is_ok());
    }

    #[test]
    fn toml_accepts_uniform_and_per_joint_values_and_refuses_unknown_keys() {
        let c: HandControllerConfig<2> = toml::from_str(
            r#"
            mode = "fixed_impedance"
            max_effort_nm = [2.0, 5.0]
            hold_max_effort_nm = 0.5
            [position]
            servo = "hardware"
            [adaptive]
            stiffness_adaptation = [1.0, 2.0]
            [adaptive.basis]
            count = 4
            "#,
        )
        .unwrap();
        assert_eq!(c.mode, HandMode::FixedImpedance);
        assert_eq!(c.max_effort_nm.to_vector(), Vector2::new(2.0, 5.0));
        assert_eq!(c.hold_max_effort_nm.to_vector(), Vector2::repeat(0.5));
        assert_eq!(c.position.servo, PositionServo::Hardware);
        assert_eq!(c.adaptive.basis.count, 4);
        assert!(HandController::new(c).is_ok());
        for bad in [
            "mode = \"torque\"",
            "max_effort = 2.0",
            "max_effort_nm = [1.0, 2.0, 3.0]",
            "[adaptive]\nzeta = 3.0",
            "[adaptive.basis]\nwidth = 3.0",
        ] {
            assert!(
                toml::from_str::<HandControllerConfig<2>>(bad).is_err(),
                "{bad}"
            );
        }
    }

    #[test]
    fn invalid_limits_are_refused() {
        let bad = [
            HandControllerConfig::<2> {
                max_effort_nm: PerJoint::Uniform(0.0),
                ..Default::default()
            },
            HandControllerConfig::<2> {
                hold_max_effort_nm: PerJoint::Uniform(3.0),
                ..Default::default()
            },
            HandControllerConfig::<2> {
                max_dt_s: f64::NAN,
                ..Default::default()
            },
            HandControllerConfig::<2> {
                max_effort_nm: PerJoint::Each(Vector2::new(2.0, f64::INFINITY)),
                ..Default::default()
            },
        ];
        for c in bad {
            assert!(HandController::new(c).is_err(), "{c:?}");
        }
    }

    #[test]
    fn hardware_servo_passes_the_target_through() {
        let mut config = HandControllerConfig::<2> {
            mode: HandMode::Position,
            ..Default::default()
        };
        config.position.servo = PositionServo::Hardware;
        let mut c = HandController::new(config).unwrap();
        let target = Vector2::new(0.3, 0.4);
        let out = c
            .step(1e-3, &Vector2::zeros(), &Vector2::zeros(), &target)
            .unwrap();
        assert_eq!(out, HandOutput::Position(target));
        let held = c
            .hold(1e-3, &Vector2::new(0.1, 0.1), &Vector2::zeros())
            .unwrap();
        assert_eq!(held, HandOutput::Position(target));
        assert_eq!(out.position_rad(), Some(&target));
        assert_eq!(out.effort_nm(), None);
    }

    #[test]
    fn set_mode_resets_the_adaptation() {
        let mut c = controller(HandMode::Adaptive);
        for _ in 0..100 {
            c.step(
                1e-3,
                &Vector2::new(0.1, 0.0),
                &Vector2::zeros(),
                &Vector2::zeros(),
            )
            .unwrap();
        }
        assert!(c.profiles().stiffness_nm_rad[0] > 1.0);
        assert!(c.adaptive().phase() < 1.0);
        c.set_mode(HandMode::Adaptive); // same mode: nothing
        assert!(c.profiles().stiffness_nm_rad[0] > 1.0);
        c.set_mode(HandMode::Position);
        assert_eq!(c.mode(), HandMode::Position);
        assert_eq!(c.profiles().stiffness_nm_rad[0], 1.0);
        assert_eq!(c.adaptive().phase(), 1.0);
    }

    #[test]
    fn hold_without_any_target_keeps_the_measured_posture() {
        let mut c = controller(HandMode::Position);
        let q = Vector2::new(0.2, 0.3);
        let out = c.hold(1e-3, &q, &Vector2::zeros()).unwrap();
        assert_eq!(out, HandOutput::Effort(Vector2::zeros()));
        assert_eq!(c.hold_target_rad(), Some(&q));
        assert!(c.is_holding());
        // Pushed away, it pulls back to the first held posture.
        let out = c
            .hold(1e-3, &Vector2::new(0.25, 0.3), &Vector2::zeros())
            .unwrap();
        assert!(out.effort_nm().unwrap()[0] < 0.0);
    }
}
