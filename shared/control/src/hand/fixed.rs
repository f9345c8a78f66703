//! Fixed-gain impedance control (the thesis' "fixed-gain based force control",
//! Fig. 8.7(b): eq. 8.1 with constant `K_s`, `K_d` and no feedforward adaptation).
//!
//! ```text
//! τ = τ0 + G - K_s e - K_d ė,   e = q - q_d,  ė = q̇ - q̇_d
//! τ ← clamp(τ, -τ_max, τ_max)
//! ```
//!
//! `τ0` is a constant bias from the configuration (default 0), `G` the gravity torque
//! of the input. No state: `dt` is only checked. With `τ0 = 0` it is the position
//! mode's PD servo ([`FixedImpedance::pd_servo`]).

use nalgebra::SVector;

use crate::error::{ConfigError, Rejection};
use crate::hand::config::{FixedImpedanceConfig, MAX_CONFIG_VALUE, check_vector};
use crate::hand::input::{JointInput, check_dt, clamp_effort};

/// Constant-gain joint impedance with clamped effort; see the [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct FixedImpedance<const N: usize> {
    stiffness_nm_rad: SVector<f64, N>,
    damping_nm_s_rad: SVector<f64, N>,
    bias_nm: SVector<f64, N>,
    max_effort_nm: SVector<f64, N>,
}

impl<const N: usize> FixedImpedance<N> {
    /// A controller with the gains of `config` and effort limits `max_effort_nm`
    /// (N m).
    ///
    /// # Errors
    ///
    /// [`FixedImpedanceConfig::validate`]'s error; [`ConfigError::OutOfRange`] for an
    /// effort limit that is not finite and positive.
    pub fn new(
        config: &FixedImpedanceConfig<N>,
        max_effort_nm: SVector<f64, N>,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        Self::with_gains(
            config.stiffness_nm_rad.to_vector(),
            config.damping_nm_s_rad.to_vector(),
            config.bias_nm.to_vector(),
            max_effort_nm,
        )
    }

    /// The law with validated gains (the configs check them) and effort limits that
    /// are checked here.
    pub(crate) fn with_gains(
        stiffness_nm_rad: SVector<f64, N>,
        damping_nm_s_rad: SVector<f64, N>,
        bias_nm: SVector<f64, N>,
        max_effort_nm: SVector<f64, N>,
    ) -> Result<Self, ConfigError> {
        check_vector(
            "max_effort_nm",
            &max_effort_nm,
            f64::MIN_POSITIVE,
            MAX_CONFIG_VALUE,
        )?;
        Ok(Self {
            stiffness_nm_rad,
            damping_nm_s_rad,
            bias_nm,
            max_effort_nm,
        })
    }

    /// One period: checks `dt_s` and the input, returns the effort, N m.
    ///
    /// # Errors
    ///
    /// [`Rejection::InvalidTimeStep`], [`Rejection::NonFinite`].
    pub fn step(&mut self, dt_s: f64, input: &JointInput<N>) -> Result<SVector<f64, N>, Rejection> {
        check_dt(dt_s)?;
        input.check()?;
        Ok(self.effort(input, &self.max_effort_nm))
    }

    /// The effort for a checked `input`, clamped to `±limit_nm`.
    pub fn effort(&self, input: &JointInput<N>, limit_nm: &SVector<f64, N>) -> SVector<f64, N> {
        let (e, de) = input.errors();
        let tau = self.bias_nm + input.gravity_nm
            - self.stiffness_nm_rad.component_mul(&e)
            - self.damping_nm_s_rad.component_mul(&de);
        clamp_effort(&tau, limit_nm)
    }

    /// The law as a joint impedance, `τ = G + f + K (q_d - q) + D (q̇_d - q̇)`:
    /// `(K, D, f)` = (`K_s`, `K_d`, `τ0`).
    pub fn impedance(&self) -> (SVector<f64, N>, SVector<f64, N>, SVector<f64, N>) {
        (self.stiffness_nm_rad, self.damping_nm_s_rad, self.bias_nm)
    }

    /// Effort limits, N m.
    pub fn max_effort_nm(&self) -> &SVector<f64, N> {
        &self.max_effort_nm
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hand::config::PerJoint;
    use nalgebra::Vector1;

    #[test]
    fn impedance_law() {
        let config = FixedImpedanceConfig {
            stiffness_nm_rad: PerJoint::Uniform(10.0),
            damping_nm_s_rad: PerJoint::Uniform(0.1),
            bias_nm: PerJoint::Uniform(0.05),
        };
        let mut c = FixedImpedance::new(&config, Vector1::new(2.0)).unwrap();
        // e = 0.02, ė = -1: τ = 0.05 - 0.2 + 0.1 = -0.05.
        let i = JointInput::new(Vector1::new(0.12), Vector1::new(-1.0), Vector1::new(0.1));
        assert!((c.step(1e-3, &i).unwrap()[0] + 0.05).abs() < 1e-12);
        assert!(FixedImpedance::new(&config, Vector1::new(0.0)).is_err());
    }
}
