//! PD position servo (the hand's "position control mode", the thesis' baseline).
//!
//! ```text
//! τ = G - Kp e - Kd ė,   e = q - q_d,  ė = q̇ - q̇_d      (eq. 8.5 errors)
//! τ ← clamp(τ, -τ_max, τ_max)
//! ```
//!
//! i.e. `Kp (q_d - q) + Kd (q̇_d - q̇)`, the usual servo, plus the gravity torque if
//! one is given. No state: `dt` is only checked.

use nalgebra::SVector;

use crate::error::{ConfigError, Rejection};
use crate::hand::config::{MAX_CONFIG_VALUE, PositionConfig, check_vector};
use crate::hand::input::{JointInput, check_dt, clamp_effort};

/// PD servo to the target with clamped effort; see the [module docs](self).
#[derive(Debug, Clone, PartialEq)]
pub struct PdServo<const N: usize> {
    stiffness_nm_rad: SVector<f64, N>,
    damping_nm_s_rad: SVector<f64, N>,
    max_effort_nm: SVector<f64, N>,
}

impl<const N: usize> PdServo<N> {
    /// A servo with the gains of `config` and effort limits `max_effort_nm` (N m).
    ///
    /// # Errors
    ///
    /// [`PositionConfig::validate`]'s error; [`ConfigError::OutOfRange`] for an effort
    /// limit that is not finite and positive.
    pub fn new(
        config: &PositionConfig<N>,
        max_effort_nm: SVector<f64, N>,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        check_vector(
            "max_effort_nm",
            &max_effort_nm,
            f64::MIN_POSITIVE,
            MAX_CONFIG_VALUE,
        )?;
        Ok(Self {
            stiffness_nm_rad: config.stiffness_nm_rad.to_vector(),
            damping_nm_s_rad: config.damping_nm_s_rad.to_vector(),
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
        let tau = input.gravity_nm
            - self.stiffness_nm_rad.component_mul(&e)
            - self.damping_nm_s_rad.component_mul(&de);
        clamp_effort(&tau, limit_nm)
    }

    /// The law as a joint impedance, `τ = G + f + K (q_d - q) + D (q̇_d - q̇)`:
    /// `(K, D, f)` = (`Kp`, `Kd`, 0).
    pub fn impedance(&self) -> (SVector<f64, N>, SVector<f64, N>, SVector<f64, N>) {
        (
            self.stiffness_nm_rad,
            self.damping_nm_s_rad,
            SVector::zeros(),
        )
    }

    /// Effort limits, N m.
    pub fn max_effort_nm(&self) -> &SVector<f64, N> {
        &self.max_effort_nm
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    #[test]
    fn pd_law_and_clamp() {
        let mut s = PdServo::new(&PositionConfig::default(), Vector2::repeat(2.0)).unwrap();
        // e = 0.05 - 0.1 = -0.05, ė = 0.5: τ = 20 * 0.05 - 0.2 * 0.5 = 0.9.
        let i = JointInput::new(
            Vector2::new(0.05, 0.0),
            Vector2::new(0.5, 0.0),
            Vector2::new(0.1, 1.0),
        );
        let tau = s.step(1e-3, &i).unwrap();
        assert!((tau[0] - 0.9).abs() < 1e-12);
        assert_eq!(tau[1], 2.0); // 20 N m/rad * 1 rad, clamped
        let g = i.with_gravity(Vector2::new(0.1, 0.0));
        assert!((s.step(1e-3, &g).unwrap()[0] - 1.0).abs() < 1e-12);
        assert!(s.step(0.0, &i).is_err());
    }
}
