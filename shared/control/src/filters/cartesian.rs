//! Cartesian pose-stream limiter (thesis ch. 6.2.3, 7.4-7.5).
//!
//! "In Cartesian space, the maximum linear velocity, angular velocity and linear
//! acceleration are 0.2 m/s, 2 rad/s and 2.0 m/s² for both robots" (ch. 7.5). The
//! thesis applied them inside bio_ik's trajectory generation; here they shape the pose
//! stream before IK, so the IK target itself moves within the limits.
//!
//! # Semantics
//!
//! The limiter holds an output pose and its linear and angular velocity (world
//! frame: the frame the poses are expressed in). Each [`step`](CartesianLimiter::step)
//! with a target pose and a time step `dt` moves the output toward the target:
//!
//! * **Translation.** Desired velocity points at the target with speed
//!   `min(v_max, v_brake(d))`, `d` the remaining distance and `v_brake` the largest
//!   speed from which braking at `a_max` stops within `d` in discrete time (the exact
//!   discrete form of `sqrt(2 a d)`, so the last steps need no more than `a_max`).
//!   The velocity moves toward the desired one by at most `a_max dt` (norm of the
//!   change), and the output moves by `velocity * dt`. From rest toward a fixed
//!   target this is a straight trapezoidal (or triangular) profile that ends exactly
//!   on the target with no overshoot: a step of `d = 1 m` takes
//!   `2 v/a + (d - v²/a)/v = d/v + v/a = 5.1 s` at the thesis limits (accelerate,
//!   cruise, brake; the discrete profile arrives within one step of it).
//! * **Rotation.** Same rule on the rotation vector of `target * output⁻¹`, with
//!   `w_max` and the optional `max_angular_acceleration_rad_s2` (the thesis gives
//!   none; default: no angular acceleration limit). Without it, each step rotates by
//!   `min(w_max dt, θ)` about the relative rotation's axis, which is exactly
//!   `slerp(output, target, min(1, w_max dt / θ))`.
//!
//! When the remaining distance and angle fall below [`ARRIVAL_TOLERANCE`] (1e-12 m,
//! 1e-12 rad) and the velocity can stop in one step, the output is set exactly to
//! the target and the velocity to zero ([`CartesianLimiter::is_at_rest`]).
//!
//! The limits hold for every step, whatever the targets: `|v| <= v_max`,
//! `|Δv| <= a_max dt`, `|w| <= w_max`, `|Δw| <= α_max dt` if set (velocities as
//! measured from consecutive outputs, `(x_k - x_{k-1}) / dt`). A target that moves
//! toward the output faster than it can brake is overshot (the acceleration limit
//! wins: that is what it is for), then approached again.
//!
//! # Rejections and time steps
//!
//! A target with a NaN/infinite component or a non-unit quaternion, and a `dt` that
//! is not finite and positive, are rejected: the state is unchanged and nothing is
//! output — no NaN ever reaches the state. The caller keeps stepping toward the last
//! good target, or calls [`brake`](CartesianLimiter::brake).
//!
//! A `dt` above `max_dt_s` (default 0.1 s, three periods at the thesis' 30 Hz) is
//! treated as `max_dt_s`: after a stall of the control loop the output does not leap
//! by what the whole gap would have allowed. The limits then hold with respect to
//! the clamped step, so also with respect to the real one.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, Rejection, RejectionCounts, positive};
use crate::filters::approach::{approach_velocity, limit_change};
use crate::filters::jump::check_pose;

/// Limits of the [`CartesianLimiter`]. Defaults are the thesis values (ch. 7.5).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CartesianLimits {
    /// Largest linear speed, m/s. Default 0.2.
    pub max_linear_velocity_m_s: f64,
    /// Largest angular speed, rad/s. Default 2.
    pub max_angular_velocity_rad_s: f64,
    /// Largest linear acceleration (norm), m/s². Default 2.
    pub max_linear_acceleration_m_s2: f64,
    /// Largest angular acceleration (norm), rad/s²; `None` (default, as in the
    /// thesis): not limited.
    pub max_angular_acceleration_rad_s2: Option<f64>,
    /// Longest time step honoured; larger ones are treated as this, seconds.
    /// Default 0.1.
    pub max_dt_s: f64,
}

impl Default for CartesianLimits {
    fn default() -> Self {
        Self {
            max_linear_velocity_m_s: 0.2,
            max_angular_velocity_rad_s: 2.0,
            max_linear_acceleration_m_s2: 2.0,
            max_angular_acceleration_rad_s2: None,
            max_dt_s: 0.1,
        }
    }
}

impl CartesianLimits {
    /// Checks every limit is finite and positive.
    ///
    /// # Errors
    ///
    /// [`ConfigError::NotPositive`] naming the first bad field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive("max_linear_velocity_m_s", self.max_linear_velocity_m_s)?;
        positive(
            "max_angular_velocity_rad_s",
            self.max_angular_velocity_rad_s,
        )?;
        positive(
            "max_linear_acceleration_m_s2",
            self.max_linear_acceleration_m_s2,
        )?;
        if let Some(a) = self.max_angular_acceleration_rad_s2 {
            positive("max_angular_acceleration_rad_s2", a)?;
        }
        positive("max_dt_s", self.max_dt_s)
    }
}

/// Remaining distance (m) or angle (rad) below which the output is put exactly on
/// the target, so that rounding (a `1e-16` rad residue of `target * output⁻¹`) does
/// not keep it creeping forever: one picometre / picoradian.
pub const ARRIVAL_TOLERANCE: f64 = 1e-12;

/// The output is within [`ARRIVAL_TOLERANCE`] of the target and slow enough to stop
/// in this step.
fn arrived(error: &Vector3<f64>, velocity: &Vector3<f64>, accel: Option<f64>, dt_s: f64) -> bool {
    error.norm() <= ARRIVAL_TOLERANCE
        && accel.is_none_or(|a| velocity.norm() <= a * dt_s * (1.0 + 1e-12))
}

/// `exp(w dt) * q`, renormalized.
fn rotate(q: &UnitQuaternion<f64>, w: &Vector3<f64>, dt_s: f64) -> UnitQuaternion<f64> {
    let mut r = UnitQuaternion::from_scaled_axis(w * dt_s) * q;
    r.renormalize();
    r
}

/// Moves an output pose toward a stream of target poses within velocity and
/// acceleration limits; see the [module docs](self).
#[derive(Debug, Clone)]
pub struct CartesianLimiter {
    limits: CartesianLimits,
    pose: Isometry3<f64>,
    linear_velocity_m_s: Vector3<f64>,
    angular_velocity_rad_s: Vector3<f64>,
    rejections: RejectionCounts,
}

impl CartesianLimiter {
    /// A limiter at rest at `initial` (the robot's current pose).
    ///
    /// # Errors
    ///
    /// [`ConfigError`] for invalid limits; [`ConfigError::InitialState`] for a
    /// non-finite or non-normalized initial pose.
    pub fn new(limits: CartesianLimits, initial: &Isometry3<f64>) -> Result<Self, ConfigError> {
        limits.validate()?;
        check_pose(initial, "initial.translation", "initial.rotation")
            .map_err(ConfigError::InitialState)?;
        Ok(Self {
            limits,
            pose: *initial,
            linear_velocity_m_s: Vector3::zeros(),
            angular_velocity_rad_s: Vector3::zeros(),
            rejections: RejectionCounts::default(),
        })
    }

    /// One control period: moves toward `target` and returns the new output pose.
    ///
    /// # Errors
    ///
    /// [`Rejection::InvalidTimeStep`], [`Rejection::NonFinite`] (`target.*`; or
    /// `output`, a last guard that keeps a non-finite result out of the state should
    /// the arithmetic ever overflow), [`Rejection::NotNormalized`]. The state is
    /// unchanged.
    pub fn step(
        &mut self,
        target: &Isometry3<f64>,
        dt_s: f64,
    ) -> Result<Isometry3<f64>, Rejection> {
        let r = self.try_step(target, dt_s);
        if let Err(e) = &r {
            self.rejections.record(e);
        }
        r
    }

    fn try_step(
        &mut self,
        target: &Isometry3<f64>,
        dt_s: f64,
    ) -> Result<Isometry3<f64>, Rejection> {
        let dt_s = self.checked_dt(dt_s)?;
        check_pose(target, "target.translation", "target.rotation")?;
        let l = &self.limits;
        let error_m = target.translation.vector - self.pose.translation.vector;
        let a_lin = Some(l.max_linear_acceleration_m_s2);
        let (translation, v) = if arrived(&error_m, &self.linear_velocity_m_s, a_lin, dt_s) {
            (target.translation.vector, Vector3::zeros())
        } else {
            let v = approach_velocity(
                &self.linear_velocity_m_s,
                &error_m,
                l.max_linear_velocity_m_s,
                a_lin,
                dt_s,
            );
            (self.pose.translation.vector + v * dt_s, v)
        };
        let error_rad = (target.rotation * self.pose.rotation.inverse()).scaled_axis();
        let a_ang = l.max_angular_acceleration_rad_s2;
        let (rotation, w) = if arrived(&error_rad, &self.angular_velocity_rad_s, a_ang, dt_s) {
            (target.rotation, Vector3::zeros())
        } else {
            let w = approach_velocity(
                &self.angular_velocity_rad_s,
                &error_rad,
                l.max_angular_velocity_rad_s,
                a_ang,
                dt_s,
            );
            (rotate(&self.pose.rotation, &w, dt_s), w)
        };
        self.commit(translation, rotation, v, w)
    }

    /// One control period of braking: both velocities go toward zero as fast as the
    /// acceleration limits allow (angular velocity stops at once if it has no
    /// acceleration limit). Use it when commands stop arriving (watchdog expired) or
    /// the clutch is released. At rest, the pose stays.
    ///
    /// # Errors
    ///
    /// [`Rejection::InvalidTimeStep`]; the state is unchanged.
    pub fn brake(&mut self, dt_s: f64) -> Result<Isometry3<f64>, Rejection> {
        let r = self.try_brake(dt_s);
        if let Err(e) = &r {
            self.rejections.record(e);
        }
        r
    }

    fn try_brake(&mut self, dt_s: f64) -> Result<Isometry3<f64>, Rejection> {
        let dt_s = self.checked_dt(dt_s)?;
        let zero = Vector3::zeros();
        let v = limit_change(
            &self.linear_velocity_m_s,
            &zero,
            self.limits.max_linear_acceleration_m_s2 * dt_s,
        );
        let w = match self.limits.max_angular_acceleration_rad_s2 {
            Some(a) => limit_change(&self.angular_velocity_rad_s, &zero, a * dt_s),
            None => zero,
        };
        self.advance(v, w, dt_s)
    }

    fn checked_dt(&self, dt_s: f64) -> Result<f64, Rejection> {
        if dt_s.is_finite() && dt_s > 0.0 {
            Ok(dt_s.min(self.limits.max_dt_s))
        } else {
            Err(Rejection::InvalidTimeStep { dt_s })
        }
    }

    fn advance(
        &mut self,
        v: Vector3<f64>,
        w: Vector3<f64>,
        dt_s: f64,
    ) -> Result<Isometry3<f64>, Rejection> {
        let translation = self.pose.translation.vector + v * dt_s;
        let rotation = rotate(&self.pose.rotation, &w, dt_s);
        self.commit(translation, rotation, v, w)
    }

    /// Takes the new state if it is finite.
    fn commit(
        &mut self,
        translation: Vector3<f64>,
        rotation: UnitQuaternion<f64>,
        v: Vector3<f64>,
        w: Vector3<f64>,
    ) -> Result<Isometry3<f64>, Rejection> {
        let finite = translation.iter().all(|x| x.is_finite())
            && v.iter().all(|x| x.is_finite())
            && w.iter().all(|x| x.is_finite())
            && rotation.coords.iter().all(|x| x.is_finite());
        if !finite {
            return Err(Rejection::NonFinite { field: "output" });
        }
        self.pose = Isometry3::from_parts(Translation3::from(translation), rotation);
        self.linear_velocity_m_s = v;
        self.angular_velocity_rad_s = w;
        Ok(self.pose)
    }

    /// Puts the output at `pose`, at rest (e.g. the robot's measured pose when
    /// control resumes).
    ///
    /// # Errors
    ///
    /// [`Rejection::NonFinite`] / [`Rejection::NotNormalized`]; the state is
    /// unchanged.
    pub fn reset(&mut self, pose: &Isometry3<f64>) -> Result<(), Rejection> {
        check_pose(pose, "pose.translation", "pose.rotation")?;
        self.pose = *pose;
        self.linear_velocity_m_s = Vector3::zeros();
        self.angular_velocity_rad_s = Vector3::zeros();
        Ok(())
    }

    /// The current output pose.
    pub fn pose(&self) -> &Isometry3<f64> {
        &self.pose
    }

    /// Linear velocity of the last step, m/s, world frame.
    pub fn linear_velocity_m_s(&self) -> &Vector3<f64> {
        &self.linear_velocity_m_s
    }

    /// Angular velocity of the last step, rad/s, world frame.
    pub fn angular_velocity_rad_s(&self) -> &Vector3<f64> {
        &self.angular_velocity_rad_s
    }

    /// Both velocities are exactly zero.
    pub fn is_at_rest(&self) -> bool {
        self.linear_velocity_m_s == Vector3::zeros()
            && self.angular_velocity_rad_s == Vector3::zeros()
    }

    /// The limits in use.
    pub fn limits(&self) -> &CartesianLimits {
        &self.limits
    }

    /// Rejections per reason.
    pub fn rejections(&self) -> &RejectionCounts {
        &self.rejections
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::RejectionKind;
    use nalgebra::{Quaternion, Unit};

    const DT: f64 = 1.0 / 30.0;
    const TOL: f64 = 1e-9;

    fn limiter() -> CartesianLimiter {
        CartesianLimiter::new(CartesianLimits::default(), &Isometry3::identity()).unwrap()
    }

    /// Steps toward a fixed target until it is reached (or `max_steps`), checking the
    /// limits on every step from the outputs alone. Returns the number of steps.
    fn run_to(l: &mut CartesianLimiter, target: &Isometry3<f64>, max_steps: usize) -> usize {
        let lim = *l.limits();
        let start = *l.pose();
        let dir = (target.translation.vector - start.translation.vector).normalize();
        let mut prev = start;
        let mut prev_v = *l.linear_velocity_m_s();
        let mut prev_w = *l.angular_velocity_rad_s();
        let mut prev_progress = 0.0;
        for k in 1..=max_steps {
            let out = l.step(target, DT).unwrap();
            let v = (out.translation.vector - prev.translation.vector) / DT;
            let w = (out.rotation * prev.rotation.inverse()).scaled_axis() / DT;
            assert!(
                v.norm() <= lim.max_linear_velocity_m_s + TOL,
                "step {k}: |v| {}",
                v.norm()
            );
            assert!(
                (v - prev_v).norm() / DT <= lim.max_linear_acceleration_m_s2 + TOL,
                "step {k}: |a| {}",
                (v - prev_v).norm() / DT
            );
            assert!(
                w.norm() <= lim.max_angular_velocity_rad_s + TOL,
                "step {k}: |w| {}",
                w.norm()
            );
            if let Some(alpha) = lim.max_angular_acceleration_rad_s2 {
                assert!((w - prev_w).norm() / DT <= alpha + 1e-6, "step {k}");
            }
            if dir.iter().all(|x| x.is_finite()) {
                // Straight line, monotone progress, never past the target.
                let travelled = out.translation.vector - start.translation.vector;
                let progress = travelled.dot(&dir);
                assert!((travelled - dir * progress).norm() < 1e-12, "off the line");
                assert!(progress >= prev_progress - 1e-15, "step {k}: went back");
                let total = (target.translation.vector - start.translation.vector).norm();
                assert!(
                    progress <= total + 1e-12,
                    "step {k}: overshoot {}",
                    progress - total
                );
                prev_progress = progress;
            }
            prev = out;
            prev_v = v;
            prev_w = w;
            let dp = (target.translation.vector - out.translation.vector).norm();
            let dr = target.rotation.angle_to(&out.rotation);
            if dp < 1e-12 && dr < 1e-12 {
                return k;
            }
        }
        panic!("target not reached in {max_steps} steps");
    }

    /// Rest-to-rest time of a trapezoidal profile: accelerate for `v/a`, cruise for
    /// `(d - v²/a)/v`, brake for `v/a`, i.e. `d/v + v/a`; triangular if `d < v²/a`.
    fn analytic_time_s(d: f64, v: f64, a: f64) -> f64 {
        if d >= v * v / a {
            2.0 * v / a + (d - v * v / a) / v
        } else {
            2.0 * (d / a).sqrt()
        }
    }

    #[test]
    fn one_metre_step_takes_the_time_the_limits_imply() {
        let mut l = limiter();
        let target = Isometry3::translation(1.0, 0.0, 0.0);
        let steps = run_to(&mut l, &target, 1000);
        let t = steps as f64 * DT;
        let expected = analytic_time_s(1.0, 0.2, 2.0);
        assert!((expected - 5.1).abs() < 1e-12);
        assert!(
            (t - expected).abs() <= 2.0 * DT,
            "t = {t}, expected {expected}"
        );
        // Ends exactly on target, at rest after one more step.
        assert_eq!(l.pose().translation.vector, target.translation.vector);
        l.step(&target, DT).unwrap();
        assert!(l.is_at_rest());
        assert_eq!(l.pose(), &target);
    }

    #[test]
    fn oblique_and_short_steps_are_straight_and_timely() {
        for (d, dir) in [
            (1.0, Vector3::new(1.0, 2.0, -2.0)),
            (0.015, Vector3::new(0.0, -1.0, 0.0)), // triangular profile
            (0.3, Vector3::new(-3.0, 0.5, 1.0)),
        ] {
            let mut l = limiter();
            let start = Isometry3::translation(0.2, -0.4, 1.1);
            l.reset(&start).unwrap();
            let mut target = start;
            target.translation.vector += dir.normalize() * d;
            let steps = run_to(&mut l, &target, 2000);
            let t = steps as f64 * DT;
            let expected = analytic_time_s(d, 0.2, 2.0);
            assert!(
                (t - expected).abs() <= 2.0 * DT,
                "d {d}: t = {t}, expected {expected}"
            );
        }
    }

    #[test]
    fn rotation_is_slerp_at_the_angular_velocity_limit() {
        let mut l = limiter();
        let axis = Unit::new_normalize(Vector3::new(0.3, -1.0, 0.2));
        let target = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&axis, 170f64.to_radians()),
        );
        let mut prev = *l.pose();
        for _ in 0..3 {
            let out = l.step(&target, DT).unwrap();
            let remaining = prev.rotation.angle_to(&target.rotation);
            let t = (2.0 * DT / remaining).min(1.0);
            let slerp = prev.rotation.slerp(&target.rotation, t);
            assert!(out.rotation.angle_to(&slerp) < 1e-12);
            prev = out;
        }
        let mut l = limiter();
        let steps = run_to(&mut l, &target, 1000);
        let expected = 170f64.to_radians() / 2.0;
        assert!((steps as f64 * DT - expected).abs() <= DT, "{steps}");
    }

    #[test]
    fn angular_acceleration_limit_when_configured() {
        let limits = CartesianLimits {
            max_angular_acceleration_rad_s2: Some(4.0),
            ..Default::default()
        };
        let mut l = CartesianLimiter::new(limits, &Isometry3::identity()).unwrap();
        let target = Isometry3::from_parts(
            Translation3::new(0.1, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(2.0, -1.0, 0.5),
        );
        run_to(&mut l, &target, 2000);
    }

    #[test]
    fn moving_target_stays_within_limits() {
        let mut l = limiter();
        let lim = *l.limits();
        let mut prev = *l.pose();
        let mut prev_v = Vector3::zeros();
        for k in 0..600 {
            let t = k as f64 * DT;
            // Faster than the limits allow, with direction reversals.
            let target = Isometry3::from_parts(
                Translation3::new((3.0 * t).sin(), (5.0 * t).cos() * 0.5, 0.2 * t),
                UnitQuaternion::from_euler_angles(4.0 * t, (7.0 * t).sin(), 0.0),
            );
            let out = l.step(&target, DT).unwrap();
            let v = (out.translation.vector - prev.translation.vector) / DT;
            let w = prev.rotation.angle_to(&out.rotation) / DT;
            assert!(v.norm() <= lim.max_linear_velocity_m_s + TOL);
            assert!((v - prev_v).norm() / DT <= lim.max_linear_acceleration_m_s2 + TOL);
            assert!(w <= lim.max_angular_velocity_rad_s + TOL);
            prev = out;
            prev_v = v;
        }
    }

    #[test]
    fn invalid_targets_and_time_steps_are_rejected_without_touching_state() {
        let mut l = limiter();
        let target = Isometry3::translation(1.0, 0.0, 0.0);
        for _ in 0..10 {
            l.step(&target, DT).unwrap();
        }
        let pose = *l.pose();
        let v = *l.linear_velocity_m_s();
        let nan = Isometry3::translation(f64::NAN, 0.0, 0.0);
        assert_eq!(
            l.step(&nan, DT),
            Err(Rejection::NonFinite {
                field: "target.translation"
            })
        );
        let bad_q = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::new_unchecked(Quaternion::new(f64::NAN, 0.0, 0.0, 0.0)),
        );
        assert_eq!(
            l.step(&bad_q, DT),
            Err(Rejection::NonFinite {
                field: "target.rotation"
            })
        );
        let unnormalized = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0)),
        );
        assert!(matches!(
            l.step(&unnormalized, DT),
            Err(Rejection::NotNormalized { .. })
        ));
        for dt in [0.0, -DT, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(matches!(
                l.step(&target, dt),
                Err(Rejection::InvalidTimeStep { .. })
            ));
            assert!(l.brake(dt).is_err());
        }
        assert_eq!(l.pose(), &pose);
        assert_eq!(l.linear_velocity_m_s(), &v);
        let r = l.rejections();
        assert_eq!(r.get(RejectionKind::NonFinite), 2);
        assert_eq!(r.get(RejectionKind::NotNormalized), 1);
        assert_eq!(r.get(RejectionKind::InvalidTimeStep), 10);
        // And it carries on from where it was.
        let next = l.step(&target, DT).unwrap();
        assert!(next.translation.x > pose.translation.x);
    }

    #[test]
    fn long_time_step_is_clamped() {
        let mut l = limiter();
        let target = Isometry3::translation(5.0, 0.0, 0.0);
        for _ in 0..10 {
            l.step(&target, DT).unwrap();
        }
        let x0 = l.pose().translation.x;
        let x1 = l.step(&target, 10.0).unwrap().translation.x;
        assert!(x1 - x0 <= 0.2 * 0.1 + 1e-12, "{}", x1 - x0);
    }

    #[test]
    fn brake_stops_within_the_acceleration_limit() {
        let mut l = limiter();
        let target = Isometry3::from_parts(
            Translation3::new(2.0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 3.0),
        );
        for _ in 0..30 {
            l.step(&target, DT).unwrap();
        }
        assert!((l.linear_velocity_m_s().norm() - 0.2).abs() < 1e-12);
        let mut prev_v = *l.linear_velocity_m_s();
        let mut n = 0;
        while !l.is_at_rest() {
            l.brake(DT).unwrap();
            let v = *l.linear_velocity_m_s();
            assert!((v - prev_v).norm() <= 2.0 * DT + 1e-12);
            prev_v = v;
            n += 1;
            assert!(n < 100);
        }
        // 0.2 m/s at 2 m/s² = 0.1 s = 3 steps.
        assert_eq!(n, 3);
        let p = *l.pose();
        assert_eq!(l.brake(DT).unwrap(), p);
    }

    #[test]
    fn limits_parse_and_validate() {
        let l: CartesianLimits = toml::from_str("").unwrap();
        assert_eq!(l, CartesianLimits::default());
        let l: CartesianLimits =
            toml::from_str("max_linear_velocity_m_s = 0.1\nmax_angular_acceleration_rad_s2 = 10.0")
                .unwrap();
        assert_eq!(l.max_linear_velocity_m_s, 0.1);
        assert_eq!(l.max_angular_acceleration_rad_s2, Some(10.0));
        assert!(toml::from_str::<CartesianLimits>("max_velocity = 1.0").is_err());
        let bad = CartesianLimits {
            max_linear_acceleration_m_s2: -2.0,
            ..Default::default()
        };
        assert!(matches!(
            CartesianLimiter::new(bad, &Isometry3::identity()),
            Err(ConfigError::NotPositive {
                name: "max_linear_acceleration_m_s2",
                ..
            })
        ));
        let bad = CartesianLimits {
            max_angular_acceleration_rad_s2: Some(f64::INFINITY),
            ..Default::default()
        };
        assert!(bad.validate().is_err());
        assert!(matches!(
            CartesianLimiter::new(
                CartesianLimits::default(),
                &Isometry3::translation(f64::NAN, 0.0, 0.0)
            ),
            Err(ConfigError::InitialState(_))
        ));
    }
}
