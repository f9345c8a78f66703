//! Serde configuration of the hand controllers, with defaults and validation.
//!
//! Every per-joint number is a [`PerJoint`]: one value for all joints (`2.0`) or an
//! array of `N` values (`[2.0, 2.0, ...]`). Structs use `deny_unknown_fields` and
//! `default`, so an empty TOML table gives the defaults below.
//!
//! # Where the defaults come from
//!
//! The thesis (ch. 8.2.2) gives the control law but **no numbers**: "the open
//! parameters ... need to be manually set" (ch. 8.5). Its only literal constants are
//! the phase dynamics `ṡ = -s` (time constant 1 s, [`BasisConfig::phase_time_constant_s`])
//! and the form of the basis (eqs. 8.7-8.8). The effort limit of 2 N m is the finger
//! joints' `effort` limit in the Shadow hand description
//! (`shared/kinematics/urdf/shadow_hand.urdf`; the thumb's THJ5/THJ4 allow 5 and 3 N m,
//! see [`SHADOW_FINGER_MAX_EFFORT_NM`]). Every other default is **ours**, chosen for a
//! finger joint of about 1e-3 kg m² (link plus reflected drive inertia) controlled at
//! 1 kHz, and checked by the simulations in `tests/hand_*.rs`. Re-tune the gains when
//! the loop runs much slower: a discrete PD needs `Kd dt / I` and `Kp dt² / I` well
//! below 1; on the test joint the default position servo is stable at 200 Hz and
//! oscillates at 100 Hz (`Kd dt / I = 2`).

use nalgebra::SVector;
use serde::{Deserialize, Serialize};

use crate::error::ConfigError;

/// Largest accepted value of a gain or rate. Far above anything useful; bounding the
/// configuration keeps every product in a `step` finite (no `inf - inf` NaN).
pub const MAX_CONFIG_VALUE: f64 = 1e9;

/// Effort limits of the 17 finger joints in the remote site's `SHADOW_FINGER_JOINTS` order
/// (FF J4-J2, MF J4-J2, RF J4-J2, LF J5-J2, TH J5-J2), N m, from the `effort` attribute of the Shadow hand URDF
/// (`shared/kinematics/urdf/shadow_hand.urdf`). Use as
/// `PerJoint::Each(SVector::from(SHADOW_FINGER_MAX_EFFORT_NM))` for per-joint limits;
/// the default is the uniform 2 N m that every joint allows.
pub const SHADOW_FINGER_MAX_EFFORT_NM: [f64; 17] = [
    2.0, 2.0, 2.0, // FFJ4, FFJ3, FFJ2
    2.0, 2.0, 2.0, // MFJ4, MFJ3, MFJ2
    2.0, 2.0, 2.0, // RFJ4, RFJ3, RFJ2
    2.0, 2.0, 2.0, 2.0, // LFJ5, LFJ4, LFJ3, LFJ2
    5.0, 3.0, 2.0, 2.0, // THJ5, THJ4, THJ3, THJ2
];

/// A per-joint number: the same value for every joint, or one value per joint.
/// Serde form: a number, or an array of `N` numbers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerJoint<const N: usize> {
    /// One value for every joint.
    Uniform(f64),
    /// One value per joint, in joint order.
    Each(SVector<f64, N>),
}

impl<const N: usize> PerJoint<N> {
    /// The value of every joint.
    pub fn to_vector(&self) -> SVector<f64, N> {
        match self {
            PerJoint::Uniform(x) => SVector::repeat(*x),
            PerJoint::Each(v) => *v,
        }
    }

    /// Checks every value is finite and within `min..=max`.
    ///
    /// # Errors
    ///
    /// [`ConfigError::OutOfRange`] naming the field, with the first bad value.
    pub fn check(&self, name: &'static str, min: f64, max: f64) -> Result<(), ConfigError> {
        check_vector(name, &self.to_vector(), min, max)
    }
}

impl<const N: usize> From<f64> for PerJoint<N> {
    fn from(x: f64) -> Self {
        PerJoint::Uniform(x)
    }
}

impl<const N: usize> From<SVector<f64, N>> for PerJoint<N> {
    fn from(v: SVector<f64, N>) -> Self {
        PerJoint::Each(v)
    }
}

/// Checks every component is finite (not NaN) and within `min..=max`.
pub(crate) fn check_vector<const N: usize>(
    name: &'static str,
    v: &SVector<f64, N>,
    min: f64,
    max: f64,
) -> Result<(), ConfigError> {
    match v
        .iter()
        .find(|x| !(x.is_finite() && **x >= min && **x <= max))
    {
        None => Ok(()),
        Some(&value) => Err(ConfigError::OutOfRange {
            name,
            value,
            min,
            max,
        }),
    }
}

/// Checks `lo_i <= hi_i` for every joint.
pub(crate) fn check_ordered<const N: usize>(
    name: &'static str,
    lo: &SVector<f64, N>,
    hi: &SVector<f64, N>,
) -> Result<(), ConfigError> {
    match (0..N).find(|&i| lo[i] > hi[i]) {
        None => Ok(()),
        Some(i) => Err(ConfigError::OutOfRange {
            name,
            value: lo[i],
            min: f64::NEG_INFINITY,
            max: hi[i],
        }),
    }
}

/// Which control law drives the hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HandMode {
    /// PD position servo to the target (the real hand's position controllers; the
    /// thesis' baseline "position control mode").
    Position,
    /// Impedance with constant gains (the thesis' "fixed-gain based force control",
    /// Fig. 8.7(b)).
    FixedImpedance,
    /// The biomimetic adaptive impedance + feedforward controller of ch. 8.2.2
    /// (eqs. 8.1-8.17). Default: the hand's compliant mode in this system.
    #[default]
    Adaptive,
}

/// Who closes the position loop in [`HandMode::Position`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PositionServo {
    /// This crate's PD law computes efforts ([`HandOutput::Effort`](super::HandOutput)).
    /// Default.
    #[default]
    Effort,
    /// The hardware's own position controllers: the output is the target itself
    /// ([`HandOutput::Position`](super::HandOutput)). The effort limits must then be set
    /// in the hardware (its `max_force`) to the same values.
    Hardware,
}

/// How the effort-computing laws reach the hardware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HardwareInterface {
    /// The law's efforts ([`HandOutput::Effort`](super::HandOutput)): the loop closes
    /// through the caller, so it must run fast and close to the hardware (the
    /// in-process simulations at 1 kHz). Default.
    #[default]
    Effort,
    /// The law as a joint impedance the hardware evaluates in its own loop
    /// ([`HandOutput::Impedance`](super::HandOutput)): stiffness, damping, set point and
    /// feed-forward, updated every period, the stiff part never waiting for the caller.
    /// For a controller that reaches the hand over a network (the
    /// `shadow_hand_controller` node).
    Impedance,
}

/// Gains of the PD position servo (our values; the thesis gives none).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionConfig<const N: usize> {
    /// Proportional gain `Kp`, N m/rad. Default 20 (the effort limit is reached at
    /// 0.1 rad of error: stiff, like a position-controlled hand).
    #[serde(default = "position_stiffness_nm_rad")]
    pub stiffness_nm_rad: PerJoint<N>,
    /// Derivative gain `Kd`, N m s/rad. Default 0.2.
    #[serde(default = "position_damping_nm_s_rad")]
    pub damping_nm_s_rad: PerJoint<N>,
    /// Who closes the loop. Default [`PositionServo::Effort`].
    #[serde(default)]
    pub servo: PositionServo,
}

impl<const N: usize> Default for PositionConfig<N> {
    fn default() -> Self {
        Self {
            stiffness_nm_rad: PerJoint::Uniform(20.0),
            damping_nm_s_rad: PerJoint::Uniform(0.2),
            servo: PositionServo::Effort,
        }
    }
}

impl<const N: usize> PositionConfig<N> {
    /// # Errors
    ///
    /// [`ConfigError::OutOfRange`] for a gain that is NaN, negative or above
    /// [`MAX_CONFIG_VALUE`].
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.stiffness_nm_rad
            .check("position.stiffness_nm_rad", 0.0, MAX_CONFIG_VALUE)?;
        self.damping_nm_s_rad
            .check("position.damping_nm_s_rad", 0.0, MAX_CONFIG_VALUE)
    }
}

/// Gains of the fixed-gain impedance controller (our values).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixedImpedanceConfig<const N: usize> {
    /// Stiffness `Ks`, N m/rad. Default 10 (half the position servo's `Kp`: the
    /// "moderate" baseline of Fig. 8.7(b), still stiff enough to hold a grasp).
    #[serde(default = "fixed_stiffness_nm_rad")]
    pub stiffness_nm_rad: PerJoint<N>,
    /// Damping `Kd`, N m s/rad. Default 0.15.
    #[serde(default = "fixed_damping_nm_s_rad")]
    pub damping_nm_s_rad: PerJoint<N>,
    /// Constant bias torque `τ0`, N m. Default 0.
    #[serde(default = "fixed_bias_nm")]
    pub bias_nm: PerJoint<N>,
}

impl<const N: usize> Default for FixedImpedanceConfig<N> {
    fn default() -> Self {
        Self {
            stiffness_nm_rad: PerJoint::Uniform(10.0),
            damping_nm_s_rad: PerJoint::Uniform(0.15),
            bias_nm: PerJoint::Uniform(0.0),
        }
    }
}

impl<const N: usize> FixedImpedanceConfig<N> {
    /// # Errors
    ///
    /// [`ConfigError::OutOfRange`] for a gain that is NaN, negative or above
    /// [`MAX_CONFIG_VALUE`], or a bias beyond `±MAX_CONFIG_VALUE`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.stiffness_nm_rad
            .check("fixed_impedance.stiffness_nm_rad", 0.0, MAX_CONFIG_VALUE)?;
        self.damping_nm_s_rad
            .check("fixed_impedance.damping_nm_s_rad", 0.0, MAX_CONFIG_VALUE)?;
        self.bias_nm.check(
            "fixed_impedance.bias_nm",
            -MAX_CONFIG_VALUE,
            MAX_CONFIG_VALUE,
        )
    }
}

/// The normalized Gaussian basis `g(s)` of eqs. 8.7-8.8 and its phase `s`.
///
/// The thesis fixes the phase dynamics `ṡ = -s` but not the centres `c_n`, the widths
/// `h_n` nor `N_g`. Ours, as usual for DMPs: `s(0) = 1` at reset,
/// `ṡ = -s / phase_time_constant_s`; the centres are the phase values at `count`
/// equally spaced times over `[0, horizon_s]`, `c_n = exp(-t_n / τ_s)`; the widths
/// `h_n = 2 / Δc_n²` (`Δc_n` the distance to the next centre, the previous one for the
/// last) so neighbouring units overlap at `ω = e^-1`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BasisConfig {
    /// Number of Gaussians `N_g`, `1..=64`. Default 10 (ours).
    pub count: usize,
    /// Time constant of the phase, seconds: `ṡ = -s / τ_s`. Default 1.0 (the
    /// thesis' `ṡ = -s`, in seconds).
    pub phase_time_constant_s: f64,
    /// Time after a reset covered by the centres, seconds. Default 5 (ours; `s` has
    /// fallen to `e^-5` by then). Afterwards `g` is constant (about 80 % on the last
    /// unit): the controller continues as one adaptive impedance.
    pub horizon_s: f64,
}

impl Default for BasisConfig {
    fn default() -> Self {
        Self {
            count: 10,
            phase_time_constant_s: 1.0,
            horizon_s: 5.0,
        }
    }
}

/// Largest number of Gaussians.
pub const MAX_BASIS_COUNT: usize = 64;

impl BasisConfig {
    /// # Errors
    ///
    /// [`ConfigError::OutOfRange`] for `count` outside `1..=64`;
    /// [`ConfigError::NotPositive`] for times that are not finite and positive.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(1..=MAX_BASIS_COUNT).contains(&self.count) {
            return Err(ConfigError::OutOfRange {
                name: "adaptive.basis.count",
                value: self.count as f64,
                min: 1.0,
                max: MAX_BASIS_COUNT as f64,
            });
        }
        let positive = |name, v: f64| {
            if v.is_finite() && v > 0.0 && v <= MAX_CONFIG_VALUE {
                Ok(())
            } else {
                Err(ConfigError::NotPositive { name, value: v })
            }
        };
        positive(
            "adaptive.basis.phase_time_constant_s",
            self.phase_time_constant_s,
        )?;
        positive("adaptive.basis.horizon_s", self.horizon_s)
    }
}

/// Parameters of the adaptive impedance + feedforward controller (ch. 8.2.2).
///
/// Symbols of the thesis in brackets. The thesis gives no values ("manually set in
/// the experiments"); all defaults are ours, tuned on the simulated finger joint of
/// `tests/hand_adaptive.rs` (1e-3 kg m², 1 kHz). The bounds are our safety addition.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveConfig<const N: usize> {
    /// Initial stiffness `K_s` (every `θ_k` weight), N m/rad. Default 1: compliant
    /// until the error says otherwise.
    #[serde(default = "adaptive_initial_stiffness_nm_rad")]
    pub initial_stiffness_nm_rad: PerJoint<N>,
    /// Initial damping `K_d` (every `θ_d` weight), N m s/rad. Default 0.05.
    #[serde(default = "adaptive_initial_damping_nm_s_rad")]
    pub initial_damping_nm_s_rad: PerJoint<N>,
    /// Initial feedforward `v` (every `θ_v` weight), N m. Default 0.
    #[serde(default = "adaptive_initial_feedforward_nm")]
    pub initial_feedforward_nm: PerJoint<N>,
    /// Lower bound of `K_s`, N m/rad. Default 0.2. (Ours.)
    #[serde(default = "adaptive_min_stiffness_nm_rad")]
    pub min_stiffness_nm_rad: PerJoint<N>,
    /// Upper bound of `K_s`, N m/rad. Default 20, the position servo's `Kp`. (Ours.)
    #[serde(default = "adaptive_max_stiffness_nm_rad")]
    pub max_stiffness_nm_rad: PerJoint<N>,
    /// Lower bound of `K_d`, N m s/rad. Default 0.02. (Ours.)
    #[serde(default = "adaptive_min_damping_nm_s_rad")]
    pub min_damping_nm_s_rad: PerJoint<N>,
    /// Upper bound of `K_d`, N m s/rad. Default 0.3. (Ours.)
    #[serde(default = "adaptive_max_damping_nm_s_rad")]
    pub max_damping_nm_s_rad: PerJoint<N>,
    /// Bound of `|v|`, N m. Default 2, the default effort limit. (Ours.)
    #[serde(default = "adaptive_max_feedforward_nm")]
    pub max_feedforward_nm: PerJoint<N>,
    /// Stiffness adaptation gain `Θ_k` (eq. 8.15), N m/rad³. Default 10.
    #[serde(default = "adaptive_stiffness_adaptation")]
    pub stiffness_adaptation: PerJoint<N>,
    /// Damping adaptation gain `Θ_d` (eq. 8.16), N m s²/rad³. Default 0.05.
    #[serde(default = "adaptive_damping_adaptation")]
    pub damping_adaptation: PerJoint<N>,
    /// Feedforward adaptation gain `Θ_v` (eq. 8.17), N m/rad. Default 2.
    #[serde(default = "adaptive_feedforward_adaptation")]
    pub feedforward_adaptation: PerJoint<N>,
    /// Sliding-error gain `ζ` (`ε = ė + ζ e`, eq. 8.9), 1/s. Default 10.
    #[serde(default = "adaptive_sliding_gain_per_s")]
    pub sliding_gain_per_s: PerJoint<N>,
    /// Sliding-error feedback `Γ` (the `-Γ ε` of `τ0`, eq. 8.2; "positive definite
    /// with minimal eigenvalue"), N m s/rad. Default 0.02.
    #[serde(default = "adaptive_sliding_feedback_nm_s_rad")]
    pub sliding_feedback_nm_s_rad: PerJoint<N>,
    /// Forgetting rate `α`, 1/s: every weight relaxes toward its initial value at
    /// rate `γ = α / (1 + β ε²)`. **Not in the thesis**: eqs. 8.15-8.17 have no decay
    /// term. The form follows the forgetting factor of the biomimetic controller the
    /// thesis builds on (its reference 167, Yang et al., IEEE T-RO 2011), as we recall
    /// it (not checked against that paper here), relaxing toward the initial profile
    /// rather than zero. Default 1/s (ours): without it (`0`, the law as printed)
    /// `K_s`, `K_d` and `v` can only ratchet up on a lasting contact (see the
    /// [module docs](super::adaptive)); on the simulated touching task the printed law
    /// peaks at 0.52x the position mode's force, the default at 0.49x
    /// (`tests/scenario_touching.rs`).
    #[serde(default = "adaptive_forgetting_rate_per_s")]
    pub forgetting_rate_per_s: PerJoint<N>,
    /// `β` of the forgetting factor, s²/rad²: forgetting fades while the sliding
    /// error is large, so learning against a slip or a load (a growing error) is not
    /// weakened. Default 4 (ours): at `ε = 0.5 rad/s` forgetting runs at half its rate,
    /// at `1 rad/s` at a fifth. The trade-off, measured on the simulated hand
    /// (`docs/remote-site.md`): touching peaks at 0.41x (`β = 0`), 0.49x (4), 0.51x
    /// (16) the position mode's force, while the thumb's error under the load ramp
    /// falls from 0.033 to 0.027 and 0.022 rad.
    #[serde(default = "adaptive_forgetting_error_scale_s2_rad2")]
    pub forgetting_error_scale_s2_rad2: PerJoint<N>,
    /// The Gaussian basis and its phase.
    #[serde(default)]
    pub basis: BasisConfig,
}

impl<const N: usize> Default for AdaptiveConfig<N> {
    fn default() -> Self {
        let u = PerJoint::Uniform;
        Self {
            initial_stiffness_nm_rad: u(1.0),
            initial_damping_nm_s_rad: u(0.05),
            initial_feedforward_nm: u(0.0),
            min_stiffness_nm_rad: u(0.2),
            max_stiffness_nm_rad: u(20.0),
            min_damping_nm_s_rad: u(0.02),
            max_damping_nm_s_rad: u(0.3),
            max_feedforward_nm: u(2.0),
            stiffness_adaptation: u(10.0),
            damping_adaptation: u(0.05),
            feedforward_adaptation: u(2.0),
            sliding_gain_per_s: u(10.0),
            sliding_feedback_nm_s_rad: u(0.02),
            forgetting_rate_per_s: u(1.0),
            forgetting_error_scale_s2_rad2: u(4.0),
            basis: BasisConfig::default(),
        }
    }
}

impl<const N: usize> AdaptiveConfig<N> {
    /// Checks every value: gains and rates finite, `>= 0` and at most
    /// [`MAX_CONFIG_VALUE`]; `min <= initial <= max` for `K_s` and `K_d`;
    /// `|initial v| <= max v`; the basis.
    ///
    /// # Errors
    ///
    /// [`ConfigError::OutOfRange`] naming the field, or the basis' error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let nonneg: [(&'static str, &PerJoint<N>); 13] = [
            (
                "adaptive.initial_stiffness_nm_rad",
                &self.initial_stiffness_nm_rad,
            ),
            (
                "adaptive.initial_damping_nm_s_rad",
                &self.initial_damping_nm_s_rad,
            ),
            ("adaptive.min_stiffness_nm_rad", &self.min_stiffness_nm_rad),
            ("adaptive.max_stiffness_nm_rad", &self.max_stiffness_nm_rad),
            ("adaptive.min_damping_nm_s_rad", &self.min_damping_nm_s_rad),
            ("adaptive.max_damping_nm_s_rad", &self.max_damping_nm_s_rad),
            ("adaptive.max_feedforward_nm", &self.max_feedforward_nm),
            ("adaptive.stiffness_adaptation", &self.stiffness_adaptation),
            ("adaptive.damping_adaptation", &self.damping_adaptation),
            (
                "adaptive.feedforward_adaptation",
                &self.feedforward_adaptation,
            ),
            ("adaptive.sliding_gain_per_s", &self.sliding_gain_per_s),
            (
                "adaptive.sliding_feedback_nm_s_rad",
                &self.sliding_feedback_nm_s_rad,
            ),
            (
                "adaptive.forgetting_rate_per_s",
                &self.forgetting_rate_per_s,
            ),
        ];
        for (name, v) in nonneg {
            v.check(name, 0.0, MAX_CONFIG_VALUE)?;
        }
        self.forgetting_error_scale_s2_rad2.check(
            "adaptive.forgetting_error_scale_s2_rad2",
            0.0,
            MAX_CONFIG_VALUE,
        )?;
        self.initial_feedforward_nm.check(
            "adaptive.initial_feedforward_nm",
            -MAX_CONFIG_VALUE,
            MAX_CONFIG_VALUE,
        )?;
        let (k0, kmin, kmax) = (
            self.initial_stiffness_nm_rad.to_vector(),
            self.min_stiffness_nm_rad.to_vector(),
            self.max_stiffness_nm_rad.to_vector(),
        );
        check_ordered("adaptive.min_stiffness_nm_rad", &kmin, &k0)?;
        check_ordered("adaptive.initial_stiffness_nm_rad", &k0, &kmax)?;
        let (d0, dmin, dmax) = (
            self.initial_damping_nm_s_rad.to_vector(),
            self.min_damping_nm_s_rad.to_vector(),
            self.max_damping_nm_s_rad.to_vector(),
        );
        check_ordered("adaptive.min_damping_nm_s_rad", &dmin, &d0)?;
        check_ordered("adaptive.initial_damping_nm_s_rad", &d0, &dmax)?;
        let v0 = self.initial_feedforward_nm.to_vector().abs();
        check_ordered(
            "adaptive.initial_feedforward_nm",
            &v0,
            &self.max_feedforward_nm.to_vector(),
        )?;
        self.basis.validate()
    }
}

/// Configuration of a [`HandController`](super::HandController).
///
/// TOML example (every field optional):
///
/// ```toml
/// mode = "adaptive"            # position | fixed_impedance | adaptive
/// max_effort_nm = 2.0          # or [2.0, 2.0, ...] (N values)
/// hold_max_effort_nm = 1.0
/// [adaptive]
/// feedforward_adaptation = 2.0
/// [adaptive.basis]
/// count = 10
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandControllerConfig<const N: usize> {
    /// The control law at start. Default [`HandMode::Adaptive`].
    #[serde(default)]
    pub mode: HandMode,
    /// Effort limit of every mode, N m: each output effort is clamped to
    /// `±max_effort_nm` (the thesis: the same maximum as position mode, SYSTEM.md).
    /// Default 2 (the finger joints' URDF limit).
    #[serde(default = "hand_max_effort_nm")]
    pub max_effort_nm: PerJoint<N>,
    /// Effort limit while holding ([`HandController::hold`](super::HandController::hold)),
    /// N m, at most `max_effort_nm`. Default 1 (ours).
    #[serde(default = "hand_hold_max_effort_nm")]
    pub hold_max_effort_nm: PerJoint<N>,
    /// Longest time step integrated by the adaptation and the phase, seconds: a
    /// stalled loop does not produce a jump of the parameters. Default 0.1.
    #[serde(default = "hand_max_dt_s")]
    pub max_dt_s: f64,
    /// [`HandMode::Position`] gains.
    #[serde(default)]
    pub position: PositionConfig<N>,
    /// [`HandMode::FixedImpedance`] gains.
    #[serde(default)]
    pub fixed_impedance: FixedImpedanceConfig<N>,
    /// [`HandMode::Adaptive`] parameters.
    #[serde(default)]
    pub adaptive: AdaptiveConfig<N>,
}

impl<const N: usize> Default for HandControllerConfig<N> {
    fn default() -> Self {
        Self {
            mode: HandMode::default(),
            max_effort_nm: PerJoint::Uniform(2.0),
            hold_max_effort_nm: PerJoint::Uniform(1.0),
            max_dt_s: 0.1,
            position: PositionConfig::default(),
            fixed_impedance: FixedImpedanceConfig::default(),
            adaptive: AdaptiveConfig::default(),
        }
    }
}

impl<const N: usize> HandControllerConfig<N> {
    /// Checks the whole configuration.
    ///
    /// # Errors
    ///
    /// [`ConfigError::OutOfRange`] for an effort limit that is not finite and positive
    /// (or above [`MAX_CONFIG_VALUE`]), a hold limit above the effort limit, or a gain's
    /// error; [`ConfigError::NotPositive`] for `max_dt_s`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let max = self.max_effort_nm.to_vector();
        check_vector("max_effort_nm", &max, f64::MIN_POSITIVE, MAX_CONFIG_VALUE)?;
        let hold = self.hold_max_effort_nm.to_vector();
        check_vector(
            "hold_max_effort_nm",
            &hold,
            f64::MIN_POSITIVE,
            MAX_CONFIG_VALUE,
        )?;
        check_ordered("hold_max_effort_nm", &hold, &max)?;
        crate::error::positive("max_dt_s", self.max_dt_s)?;
        self.position.validate()?;
        self.fixed_impedance.validate()?;
        self.adaptive.validate()
    }
}

// Field defaults for serde: its container-level `default` does not support const
// generics, so every field names a function returning the `Default` impl's value.
macro_rules! field_defaults {
    ($($name:ident: $ty:ident . $field:ident -> $out:ty;)*) => {
        $(fn $name<const N: usize>() -> $out {
            $ty::<N>::default().$field
        })*
    };
}

field_defaults! {
    position_stiffness_nm_rad: PositionConfig.stiffness_nm_rad -> PerJoint<N>;
    position_damping_nm_s_rad: PositionConfig.damping_nm_s_rad -> PerJoint<N>;
    fixed_stiffness_nm_rad: FixedImpedanceConfig.stiffness_nm_rad -> PerJoint<N>;
    fixed_damping_nm_s_rad: FixedImpedanceConfig.damping_nm_s_rad -> PerJoint<N>;
    fixed_bias_nm: FixedImpedanceConfig.bias_nm -> PerJoint<N>;
    adaptive_initial_stiffness_nm_rad: AdaptiveConfig.initial_stiffness_nm_rad -> PerJoint<N>;
    adaptive_initial_damping_nm_s_rad: AdaptiveConfig.initial_damping_nm_s_rad -> PerJoint<N>;
    adaptive_initial_feedforward_nm: AdaptiveConfig.initial_feedforward_nm -> PerJoint<N>;
    adaptive_min_stiffness_nm_rad: AdaptiveConfig.min_stiffness_nm_rad -> PerJoint<N>;
    adaptive_max_stiffness_nm_rad: AdaptiveConfig.max_stiffness_nm_rad -> PerJoint<N>;
    adaptive_min_damping_nm_s_rad: AdaptiveConfig.min_damping_nm_s_rad -> PerJoint<N>;
    adaptive_max_damping_nm_s_rad: AdaptiveConfig.max_damping_nm_s_rad -> PerJoint<N>;
    adaptive_max_feedforward_nm: AdaptiveConfig.max_feedforward_nm -> PerJoint<N>;
    adaptive_stiffness_adaptation: AdaptiveConfig.stiffness_adaptation -> PerJoint<N>;
    adaptive_damping_adaptation: AdaptiveConfig.damping_adaptation -> PerJoint<N>;
    adaptive_feedforward_adaptation: AdaptiveConfig.feedforward_adaptation -> PerJoint<N>;
    adaptive_sliding_gain_per_s: AdaptiveConfig.sliding_gain_per_s -> PerJoint<N>;
    adaptive_sliding_feedback_nm_s_rad: AdaptiveConfig.sliding_feedback_nm_s_rad -> PerJoint<N>;
    adaptive_forgetting_rate_per_s: AdaptiveConfig.forgetting_rate_per_s -> PerJoint<N>;
    adaptive_forgetting_error_scale_s2_rad2: AdaptiveConfig.forgetting_error_scale_s2_rad2 -> PerJoint<N>;
    hand_max_effort_nm: HandControllerConfig.max_effort_nm -> PerJoint<N>;
    hand_hold_max_effort_nm: HandControllerConfig.hold_max_effort_nm -> PerJoint<N>;
}

fn hand_max_dt_s() -> f64 {
    HandControllerConfig::<1>::default().max_dt_s
}
