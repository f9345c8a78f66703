//! What every hand control law reads each period, and its checks.

use nalgebra::SVector;

use crate::error::Rejection;

/// Largest joint position error used by the control laws, rad. A finite but absurd
/// measurement (1e300 rad) is saturated here so no product overflows to `inf` and
/// no `inf - inf` makes a NaN; a finger joint's range is under 2 rad, so real errors
/// never reach it.
pub const ERROR_LIMIT_RAD: f64 = 10.0;

/// Largest joint velocity error used by the control laws, rad/s (see
/// [`ERROR_LIMIT_RAD`]).
pub const ERROR_RATE_LIMIT_RAD_S: f64 = 1000.0;

/// Measured state and desired state of `N` joints for one control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointInput<const N: usize> {
    /// Measured joint positions `q`, rad.
    pub position_rad: SVector<f64, N>,
    /// Measured joint velocities `q̇`, rad/s.
    pub velocity_rad_s: SVector<f64, N>,
    /// Target positions `q_d` (the operator's hand inference), rad.
    pub target_rad: SVector<f64, N>,
    /// Target velocities `q̇_d`, rad/s. Zero with [`JointInput::new`]: the target
    /// stream (30 Hz network inference) is a set-point, differencing it would give
    /// spikes.
    pub target_velocity_rad_s: SVector<f64, N>,
    /// Gravity torque `G(q)` the joints must produce to stay still (the `G` of
    /// eq. 8.2), N m; added to the effort in every mode. Zero with
    /// [`JointInput::new`] (the adaptive feedforward `v` learns static loads).
    pub gravity_nm: SVector<f64, N>,
}

impl<const N: usize> JointInput<N> {
    /// State `q`, `q̇` and target `q_d`, with zero target velocity and gravity.
    pub fn new(
        position_rad: SVector<f64, N>,
        velocity_rad_s: SVector<f64, N>,
        target_rad: SVector<f64, N>,
    ) -> Self {
        Self {
            position_rad,
            velocity_rad_s,
            target_rad,
            target_velocity_rad_s: SVector::zeros(),
            gravity_nm: SVector::zeros(),
        }
    }

    /// With a target velocity `q̇_d`, rad/s.
    #[must_use]
    pub fn with_target_velocity(mut self, target_velocity_rad_s: SVector<f64, N>) -> Self {
        self.target_velocity_rad_s = target_velocity_rad_s;
        self
    }

    /// With a gravity torque `G(q)`, N m.
    #[must_use]
    pub fn with_gravity(mut self, gravity_nm: SVector<f64, N>) -> Self {
        self.gravity_nm = gravity_nm;
        self
    }

    /// Checks every number is finite.
    ///
    /// # Errors
    ///
    /// [`Rejection::NonFinite`] naming the first field with a NaN or infinity:
    /// `"position_rad"`, `"velocity_rad_s"`, `"target_rad"`,
    /// `"target_velocity_rad_s"` or `"gravity_nm"`.
    pub fn check(&self) -> Result<(), Rejection> {
        let fields: [(&'static str, &SVector<f64, N>); 5] = [
            ("position_rad", &self.position_rad),
            ("velocity_rad_s", &self.velocity_rad_s),
            ("target_rad", &self.target_rad),
            ("target_velocity_rad_s", &self.target_velocity_rad_s),
            ("gravity_nm", &self.gravity_nm),
        ];
        for (field, v) in fields {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(Rejection::NonFinite { field });
            }
        }
        Ok(())
    }

    /// Errors `(e, ė)` of eq. 8.5, `e = q - q_d`, `ė = q̇ - q̇_d`, each saturated at
    /// [`ERROR_LIMIT_RAD`] / [`ERROR_RATE_LIMIT_RAD_S`].
    pub fn errors(&self) -> (SVector<f64, N>, SVector<f64, N>) {
        let e = (self.position_rad - self.target_rad)
            .map(|x| x.clamp(-ERROR_LIMIT_RAD, ERROR_LIMIT_RAD));
        let de = (self.velocity_rad_s - self.target_velocity_rad_s)
            .map(|x| x.clamp(-ERROR_RATE_LIMIT_RAD_S, ERROR_RATE_LIMIT_RAD_S));
        (e, de)
    }
}

/// Checks a time step is finite and positive.
pub(crate) fn check_dt(dt_s: f64) -> Result<(), Rejection> {
    if dt_s.is_finite() && dt_s > 0.0 {
        Ok(())
    } else {
        Err(Rejection::InvalidTimeStep { dt_s })
    }
}

/// Clamps each component to `±limit_i`. A NaN component (impossible with validated
/// configurations and inputs) becomes 0, never NaN.
pub(crate) fn clamp_effort<const N: usize>(
    tau: &SVector<f64, N>,
    limit: &SVector<f64, N>,
) -> SVector<f64, N> {
    SVector::from_fn(|i, _| {
        let x = tau[i];
        if x.is_nan() {
            0.0
        } else {
            x.clamp(-limit[i], limit[i])
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    #[test]
    fn errors_are_q_minus_target_and_saturated() {
        let i = JointInput::new(
            Vector2::new(0.5, 1e300),
            Vector2::new(1.0, -1e300),
            Vector2::new(0.2, 0.0),
        )
        .with_target_velocity(Vector2::new(0.5, 0.0));
        let (e, de) = i.errors();
        assert!((e[0] - 0.3).abs() < 1e-15);
        assert_eq!(e[1], ERROR_LIMIT_RAD);
        assert_eq!(de[0], 0.5);
        assert_eq!(de[1], -ERROR_RATE_LIMIT_RAD_S);
    }

    #[test]
    fn non_finite_fields_are_named() {
        let ok = JointInput::new(Vector2::zeros(), Vector2::zeros(), Vector2::zeros());
        assert!(ok.check().is_ok());
        let mut bad = ok;
        bad.gravity_nm[1] = f64::NAN;
        assert_eq!(
            bad.check(),
            Err(Rejection::NonFinite {
                field: "gravity_nm"
            })
        );
        let mut bad = ok;
        bad.target_rad[0] = f64::INFINITY;
        assert_eq!(
            bad.check(),
            Err(Rejection::NonFinite {
                field: "target_rad"
            })
        );
    }

    #[test]
    fn clamp_handles_nan_and_infinity() {
        let c = clamp_effort(
            &Vector2::new(f64::NAN, f64::NEG_INFINITY),
            &Vector2::new(1.0, 2.0),
        );
        assert_eq!(c, Vector2::new(0.0, -2.0));
    }

    #[test]
    fn dt_checks() {
        assert!(check_dt(1e-3).is_ok());
        for bad in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
            assert!(check_dt(bad).is_err());
        }
    }
}
