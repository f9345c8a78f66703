//! The response model of a velocity-commanded arm driver of `N` joints, kinematic (no
//! dynamics: the PR2's and the UR5's joint velocity loops are stiff against their
//! loads). The simulators use it: the previous robot-site world moves the PR2 arm
//! (+ Shadow wrist, 7 joints) with it, the operator site the UR5 (6), and the MuJoCo
//! world (`teleop-physics`) takes its position and velocity as the reference its joint
//! servos track.
//!
//! Per step `dt`, for each joint:
//! 1. first-order lag towards the commanded velocity, exactly discretised:
//!    `dv = (v_cmd - v) (1 - exp(-dt / tau))`; once the command is older than
//!    `command_timeout_s`, instead the driver's own safety brake: `dv = -v`;
//! 2. `|dv| <= a_max dt` (acceleration limit; the brake is thus a constant-deceleration
//!    ramp to a full stop), then `|v| <= v_max` (URDF velocity limit);
//! 3. `q += v dt`; a joint that would pass a position limit stops at the limit with
//!    zero velocity (continuous joints have no limit).

use nalgebra::SVector;

/// Limits of one arm joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmJointLimits {
    /// Lowest position, rad (`-inf` for continuous joints).
    pub lower_rad: f64,
    /// Highest position, rad (`+inf` for continuous joints).
    pub upper_rad: f64,
    /// Largest speed, rad/s.
    pub velocity_rad_s: f64,
    /// Largest acceleration, rad/s^2.
    pub acceleration_rad_s2: f64,
}

/// State and response model of the arm.
#[derive(Debug, Clone)]
pub struct ArmSim<const N: usize = 7> {
    limits: [ArmJointLimits; N],
    lag_s: [f64; N],
    timeout_s: f64,
    position_rad: SVector<f64, N>,
    velocity_rad_s: SVector<f64, N>,
    command_rad_s: SVector<f64, N>,
    /// Sim time of the last command; `None` before the first one (the arm holds still).
    command_time_s: Option<f64>,
}

impl<const N: usize> ArmSim<N> {
    /// An arm at rest at `initial_rad` (clamped into the limits), every joint with the
    /// velocity lag `lag_s`, braking on its own once the last command is older than
    /// `command_timeout_s`.
    pub fn new(
        limits: [ArmJointLimits; N],
        initial_rad: &SVector<f64, N>,
        lag_s: f64,
        command_timeout_s: f64,
    ) -> Self {
        let position_rad = SVector::<f64, N>::from_fn(|i, _| {
            initial_rad[i].clamp(limits[i].lower_rad, limits[i].upper_rad)
        });
        Self {
            limits,
            lag_s: [lag_s; N],
            timeout_s: command_timeout_s,
            position_rad,
            velocity_rad_s: SVector::zeros(),
            command_rad_s: SVector::zeros(),
            command_time_s: None,
        }
    }

    /// Per-joint velocity lags (the simulated robot's own, perturbed), s.
    #[must_use]
    pub fn with_lags(mut self, lag_s: [f64; N]) -> Self {
        self.lag_s = lag_s;
        self
    }

    /// Stores a velocity command received at sim time `time_s`.
    pub fn command(&mut self, velocity_rad_s: &SVector<f64, N>, time_s: f64) {
        self.command_rad_s = *velocity_rad_s;
        self.command_time_s = Some(time_s);
    }

    /// True while the last command is fresh (at sim time `time_s`).
    pub fn command_active(&self, time_s: f64) -> bool {
        self.command_time_s
            .is_some_and(|t| time_s - t <= self.timeout_s)
    }

    /// Advances by `dt_s`; `time_s` is the sim time at the start of the step.
    pub fn step(&mut self, time_s: f64, dt_s: f64) {
        let active = self.command_active(time_s);
        for i in 0..N {
            let blend = if self.lag_s[i] > 0.0 {
                1.0 - (-dt_s / self.lag_s[i]).exp()
            } else {
                1.0
            };
            let lim = &self.limits[i];
            let v = self.velocity_rad_s[i];
            let max_dv = lim.acceleration_rad_s2 * dt_s;
            let dv = if active {
                ((self.command_rad_s[i] - v) * blend).clamp(-max_dv, max_dv)
            } else {
                // Safety brake: constant deceleration to a full stop.
                (-v).clamp(-max_dv, max_dv)
            };
            let v = (v + dv).clamp(-lim.velocity_rad_s, lim.velocity_rad_s);
            let q = self.position_rad[i] + v * dt_s;
            let (q, v) = if q > lim.upper_rad {
                (lim.upper_rad, 0.0)
            } else if q < lim.lower_rad {
                (lim.lower_rad, 0.0)
            } else {
                (q, v)
            };
            self.position_rad[i] = q;
            self.velocity_rad_s[i] = v;
        }
    }

    /// Joint positions, rad.
    pub fn position_rad(&self) -> &SVector<f64, N> {
        &self.position_rad
    }

    /// Joint velocities, rad/s.
    pub fn velocity_rad_s(&self) -> &SVector<f64, N> {
        &self.velocity_rad_s
    }

    /// The joint limits in use.
    pub fn limits(&self) -> &[ArmJointLimits; N] {
        &self.limits
    }

    /// Keeps every joint's position within `max_error_rad` of `measured_rad` (a driver
    /// whose integrated reference must not run away from a blocked arm), velocities
    /// unchanged.
    pub fn hold_within(&mut self, measured_rad: &SVector<f64, N>, max_error_rad: f64) {
        for i in 0..N {
            self.position_rad[i] = self.position_rad[i].clamp(
                measured_rad[i] - max_error_rad,
                measured_rad[i] + max_error_rad,
            );
        }
    }

    /// Places the arm (clamped into its limits) at rest; for scenario setup.
    pub fn set_position(&mut self, position_rad: &SVector<f64, N>) {
        for i in 0..N {
            self.position_rad[i] =
                position_rad[i].clamp(self.limits[i].lower_rad, self.limits[i].upper_rad);
        }
        self.velocity_rad_s = SVector::zeros();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> [ArmJointLimits; 7] {
        [ArmJointLimits {
            lower_rad: -1.0,
            upper_rad: 1.0,
            velocity_rad_s: 2.0,
            acceleration_rad_s2: 8.0,
        }; 7]
    }

    #[test]
    fn no_command_no_motion() {
        let mut arm = ArmSim::new(limits(), &SVector::zeros(), 0.03, 0.1);
        for k in 0..100 {
            arm.step(f64::from(k) * 0.001, 0.001);
        }
        assert_eq!(arm.position_rad(), &SVector::<f64, 7>::zeros());
    }

    #[test]
    fn hold_within_keeps_the_position_near_the_measurement() {
        let mut arm = ArmSim::new(limits(), &SVector::repeat(0.5), 0.03, 0.1);
        arm.hold_within(&SVector::repeat(0.1), 0.2);
        assert!((arm.position_rad()[0] - 0.3).abs() < 1e-12);
        arm.hold_within(&SVector::repeat(0.4), 0.2);
        assert!(
            (arm.position_rad()[0] - 0.3).abs() < 1e-12,
            "inside: unchanged"
        );
    }

    #[test]
    fn stops_at_position_limit() {
        let mut arm = ArmSim::new(limits(), &SVector::zeros(), 0.03, 0.1);
        for k in 0..2000 {
            let t = f64::from(k) * 0.001;
            arm.command(&SVector::repeat(1.0), t);
            arm.step(t, 0.001);
        }
        assert_eq!(arm.position_rad()[0], 1.0);
        assert_eq!(arm.velocity_rad_s()[0], 0.0);
    }
}
