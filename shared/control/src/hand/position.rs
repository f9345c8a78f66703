//! PD position servo (the hand's "position control mode", the thesis' baseline).
//!
//! ```text
//! τ = G - Kp e - Kd ė,   e = q - q_d,  ė = q̇ - q̇_d      (eq. 8.5 errors)
//! τ ← clamp(τ, -τ_max, τ_max)
//! ```
//!
//! i.e. `Kp (q_d - q) + Kd (q̇_d - q̇)`, the usual servo, plus the gravity torque if
//! one is given: the fixed-gain impedance law ([`FixedImpedance`]) with zero bias, so
//! it is that law, built from the position mode's gains.

use nalgebra::SVector;

use crate::error::ConfigError;
use crate::hand::FixedImpedance;
use crate::hand::config::PositionConfig;

impl<const N: usize> FixedImpedance<N> {
    /// The PD servo: the gains of `config`, no bias, effort limits `max_effort_nm`
    /// (N m).
    ///
    /// # Errors
    ///
    /// [`PositionConfig::validate`]'s error; [`ConfigError::OutOfRange`] for an effort
    /// limit that is not finite and positive.
    pub fn pd_servo(
        config: &PositionConfig<N>,
        max_effort_nm: SVector<f64, N>,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        Self::with_gains(
            config.stiffness_nm_rad.to_vector(),
            config.damping_nm_s_rad.to_vector(),
            SVector::zeros(),
            max_effort_nm,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hand::JointInput;
    use nalgebra::Vector2;

    #[test]
    fn pd_law_and_clamp() {
        let mut s =
            FixedImpedance::pd_servo(&PositionConfig::default(), Vector2::repeat(2.0)).unwrap();
        assert_eq!(s.impedance().2, Vector2::zeros(), "no bias");
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
