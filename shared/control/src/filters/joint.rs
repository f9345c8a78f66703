//! Joint velocity limiter for an `N`-joint arm (thesis ch. 7.4-7.5).
//!
//! "The maximum velocity in the joint space of the UR5 is 3 rad/s. The velocity
//! limits of five joints on the right PR2 arm are the default values from the PR2
//! manual" (ch. 7.5). Limits are inputs ([`JointLimits`]): the UR5's from
//! [`UR5_MAX_JOINT_VELOCITY_RAD_S`], the PR2's and the Shadow wrist's from their URDF.
//!
//! # Semantics
//!
//! [`JointVelocityLimiter::step`] takes a joint velocity command, the joints' current
//! positions and the control period `dt`, and returns the velocity to send, after
//! three stages in this order:
//!
//! 1. **Velocity limit** `|v_i| <= max_velocity_rad_s[i]`, by the
//!    [`VelocityLimitStrategy`]: `ScaleUniformly` (default) divides the whole vector
//!    by `max_i |v_i| / max_i` when that exceeds 1, so the worst joint lands exactly
//!    on its limit and the direction in joint space — hence, to first order, the
//!    Cartesian direction of motion — is kept; `Clamp` clamps each joint alone (the
//!    direction changes); `Reject` refuses the command.
//! 2. **Acceleration limit** (if `max_acceleration_rad_s2` is set)
//!    `|v_i - v_prev_i| <= max_acceleration_rad_s2[i] * dt`, `v_prev` the previous
//!    output, by the same strategy applied to the change `v - v_prev` (scale the
//!    change uniformly, clamp each component, or reject). `dt` is capped at
//!    `max_dt_s` for this stage, so a stalled loop does not license a large change.
//! 3. **Position limit**, per joint and for every strategy: a component that would
//!    take the joint past `max_position_rad` (or below `min_position_rad`) within `dt`,
//!    `q_i + v_i dt > max_i`, is set to zero. With an acceleration limit, a joint
//!    moving toward a position limit is instead capped at the speed from which it can
//!    still brake at its acceleration limit before the limit (exact discrete braking
//!    speed, as in the Cartesian limiter): it decelerates smoothly and lands exactly
//!    on the limit. A joint beyond a limit may only move back toward its range.
//!    This stage changes single components whatever the strategy — the joint at its
//!    limit stops, the others continue — and it overrides stage 2 when the positions
//!    given are not those the previous outputs led to. Infinite limits (continuous
//!    joints) never trigger.
//!
//! Every output satisfies the velocity limits; with an acceleration limit, each
//! output differs from the previous one by at most `a dt` unless stage 3 had to stop a
//! joint that the given positions put closer to its limit than its braking distance.
//!
//! A rejected command (non-finite numbers, invalid `dt`, or `Reject` with a limit
//! exceeded) leaves the state unchanged; the caller sends zero velocity or the
//! previous command, its choice. Each output is remembered as `v_prev`;
//! [`JointVelocityLimiter::reset`] sets it (to the measured velocity, or zero) when
//! control resumes.

use nalgebra::SVector;
use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, Rejection, RejectionCounts, positive};
use crate::filters::approach::braking_speed;

/// UR5 joint speed limit used by the thesis for every joint, rad/s (ch. 7.5).
pub const UR5_MAX_JOINT_VELOCITY_RAD_S: f64 = 3.0;

/// How a command above a limit is brought within it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocityLimitStrategy {
    /// Clamp each joint to its limit independently. The direction of motion changes
    /// when some joints are clamped and others are not.
    Clamp,
    /// Scale the whole vector by one factor so the worst joint sits exactly at its
    /// limit; keeps the direction of motion. Default.
    #[default]
    ScaleUniformly,
    /// Refuse the command ([`Rejection::JointVelocityLimit`] /
    /// [`Rejection::JointAccelerationLimit`] naming the first offending joint).
    Reject,
}

/// Per-joint limits of an `N`-joint arm. Serde form: arrays of `N` numbers; TOML
/// allows `inf` / `-inf` for the position limits of continuous joints.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointLimits<const N: usize> {
    /// Largest speed of each joint, rad/s (or m/s for a prismatic joint).
    pub max_velocity_rad_s: SVector<f64, N>,
    /// Lower position limit of each joint, rad; `-inf` for none.
    pub min_position_rad: SVector<f64, N>,
    /// Upper position limit of each joint, rad; `inf` for none.
    pub max_position_rad: SVector<f64, N>,
    /// Largest acceleration of each joint, rad/s²; `None`: not limited.
    #[serde(default)]
    pub max_acceleration_rad_s2: Option<SVector<f64, N>>,
}

impl<const N: usize> JointLimits<N> {
    /// Velocity limits only: no position limits, no acceleration limit.
    pub fn velocity_only(max_velocity_rad_s: SVector<f64, N>) -> Self {
        Self {
            max_velocity_rad_s,
            min_position_rad: SVector::repeat(f64::NEG_INFINITY),
            max_position_rad: SVector::repeat(f64::INFINITY),
            max_acceleration_rad_s2: None,
        }
    }

    /// The same velocity limit on every joint (the UR5's
    /// [`UR5_MAX_JOINT_VELOCITY_RAD_S`]).
    pub fn uniform_velocity(max_velocity_rad_s: f64) -> Self {
        Self::velocity_only(SVector::repeat(max_velocity_rad_s))
    }

    /// With position limits.
    #[must_use]
    pub fn with_position_limits(
        mut self,
        min_position_rad: SVector<f64, N>,
        max_position_rad: SVector<f64, N>,
    ) -> Self {
        self.min_position_rad = min_position_rad;
        self.max_position_rad = max_position_rad;
        self
    }

    /// With acceleration limits.
    #[must_use]
    pub fn with_acceleration_limits(mut self, max_acceleration_rad_s2: SVector<f64, N>) -> Self {
        self.max_acceleration_rad_s2 = Some(max_acceleration_rad_s2);
        self
    }

    /// Checks every limit.
    ///
    /// # Errors
    ///
    /// [`ConfigError::JointNotPositive`] for a velocity or acceleration limit that is
    /// not finite and positive; [`ConfigError::JointPositionLimits`] for NaN position
    /// limits or lower above upper.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for i in 0..N {
            let v = self.max_velocity_rad_s[i];
            if !(v.is_finite() && v > 0.0) {
                return Err(ConfigError::JointNotPositive {
                    joint: i,
                    name: "max_velocity_rad_s",
                    value: v,
                });
            }
            if let Some(a) = &self.max_acceleration_rad_s2 {
                let a = a[i];
                if !(a.is_finite() && a > 0.0) {
                    return Err(ConfigError::JointNotPositive {
                        joint: i,
                        name: "max_acceleration_rad_s2",
                        value: a,
                    });
                }
            }
            let (lo, hi) = (self.min_position_rad[i], self.max_position_rad[i]);
            let not_an_interval = lo.is_nan()
                || hi.is_nan()
                || lo > hi
                || lo == f64::INFINITY
                || hi == f64::NEG_INFINITY;
            if not_an_interval {
                return Err(ConfigError::JointPositionLimits {
                    joint: i,
                    lower_rad: lo,
                    upper_rad: hi,
                });
            }
        }
        Ok(())
    }
}

/// Settings of a [`JointVelocityLimiter`] other than the robot's limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointLimiterConfig {
    /// What to do with a command above a velocity or acceleration limit. Default
    /// `scale_uniformly`.
    pub strategy: VelocityLimitStrategy,
    /// Longest time step honoured by the acceleration limit, seconds. Default 0.1.
    pub max_dt_s: f64,
}

impl Default for JointLimiterConfig {
    fn default() -> Self {
        Self {
            strategy: VelocityLimitStrategy::default(),
            max_dt_s: 0.1,
        }
    }
}

/// How often each stage changed a command (per step, not per joint).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InterventionCounts {
    /// Steps where stage 1 changed the command (clamped or scaled).
    pub velocity_limited: u64,
    /// Steps where stage 2 changed it.
    pub acceleration_limited: u64,
    /// Steps where stage 3 slowed or stopped a joint at a position limit.
    pub position_limited: u64,
}

impl InterventionCounts {
    /// `(name, count)` pairs for a status report.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, u64)> {
        [
            ("velocity_limited", self.velocity_limited),
            ("acceleration_limited", self.acceleration_limited),
            ("position_limited", self.position_limited),
        ]
        .into_iter()
    }
}

/// Brings joint velocity commands within velocity, acceleration and position limits;
/// see the [module docs](self).
#[derive(Debug, Clone)]
pub struct JointVelocityLimiter<const N: usize> {
    limits: JointLimits<N>,
    config: JointLimiterConfig,
    last_output_rad_s: SVector<f64, N>,
    rejections: RejectionCounts,
    interventions: InterventionCounts,
}

impl<const N: usize> JointVelocityLimiter<N> {
    /// A limiter whose previous output is zero (the arm at rest).
    ///
    /// # Errors
    ///
    /// [`JointLimits::validate`]'s error, or [`ConfigError::NotPositive`] for
    /// `max_dt_s`.
    pub fn new(limits: JointLimits<N>, config: JointLimiterConfig) -> Result<Self, ConfigError> {
        limits.validate()?;
        positive("max_dt_s", config.max_dt_s)?;
        Ok(Self {
            limits,
            config,
            last_output_rad_s: SVector::zeros(),
            rejections: RejectionCounts::default(),
            interventions: InterventionCounts::default(),
        })
    }

    /// Limits `command_rad_s` given the joints' `position_rad` and the period `dt_s`.
    ///
    /// # Errors
    ///
    /// [`Rejection::InvalidTimeStep`], [`Rejection::NonFinite`] (`command_rad_s` or
    /// `position_rad`), and with [`VelocityLimitStrategy::Reject`]
    /// [`Rejection::JointVelocityLimit`] / [`Rejection::JointAccelerationLimit`]. The
    /// state is unchanged.
    pub fn step(
        &mut self,
        command_rad_s: &SVector<f64, N>,
        position_rad: &SVector<f64, N>,
        dt_s: f64,
    ) -> Result<SVector<f64, N>, Rejection> {
        match self.limit(command_rad_s, position_rad, dt_s) {
            Ok(v) => {
                self.last_output_rad_s = v;
                Ok(v)
            }
            Err(r) => {
                self.rejections.record(&r);
                Err(r)
            }
        }
    }

    fn limit(
        &mut self,
        command: &SVector<f64, N>,
        position: &SVector<f64, N>,
        dt_s: f64,
    ) -> Result<SVector<f64, N>, Rejection> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(Rejection::InvalidTimeStep { dt_s });
        }
        if !command.iter().all(|x| x.is_finite()) {
            return Err(Rejection::NonFinite {
                field: "command_rad_s",
            });
        }
        if !position.iter().all(|x| x.is_finite()) {
            return Err(Rejection::NonFinite {
                field: "position_rad",
            });
        }
        let strategy = self.config.strategy;
        let l = &self.limits;

        // 1. Velocity.
        let v = bound(command, &l.max_velocity_rad_s, 1.0, strategy).map_err(|(i, x)| {
            Rejection::JointVelocityLimit {
                joint: i,
                velocity_rad_s: x,
                limit_rad_s: l.max_velocity_rad_s[i],
            }
        })?;
        let velocity_limited = v != *command;

        // 2. Acceleration.
        let accel_dt_s = dt_s.min(self.config.max_dt_s);
        let mut acceleration_limited = false;
        let mut v = match &l.max_acceleration_rad_s2 {
            None => v,
            Some(a) => {
                let change = v - self.last_output_rad_s;
                let bounded = bound(&change, a, accel_dt_s, strategy).map_err(|(i, x)| {
                    Rejection::JointAccelerationLimit {
                        joint: i,
                        acceleration_rad_s2: x / accel_dt_s,
                        limit_rad_s2: a[i],
                    }
                })?;
                acceleration_limited = bounded != change;
                self.last_output_rad_s + bounded
            }
        };

        // 3. Position.
        let mut position_limited = false;
        for i in 0..N {
            let q = position[i];
            let (lo, hi) = (l.min_position_rad[i], l.max_position_rad[i]);
            let accel = l.max_acceleration_rad_s2.as_ref().map(|a| a[i]);
            let limited = if v[i] > 0.0 {
                cap_toward_limit(v[i], hi - q, accel, dt_s)
            } else if v[i] < 0.0 {
                -cap_toward_limit(-v[i], q - lo, accel, dt_s)
            } else {
                continue;
            };
            if limited != v[i] {
                v[i] = limited;
                position_limited = true;
            }
        }

        let c = &mut self.interventions;
        c.velocity_limited = c.velocity_limited.saturating_add(velocity_limited.into());
        c.acceleration_limited = c
            .acceleration_limited
            .saturating_add(acceleration_limited.into());
        c.position_limited = c.position_limited.saturating_add(position_limited.into());
        Ok(v)
    }

    /// Sets the previous output used by the acceleration limit (the measured joint
    /// velocity, or zero when the arm is known to be at rest).
    pub fn reset(&mut self, velocity_rad_s: SVector<f64, N>) {
        self.last_output_rad_s = velocity_rad_s;
    }

    /// The previous output.
    pub fn last_output_rad_s(&self) -> &SVector<f64, N> {
        &self.last_output_rad_s
    }

    /// The limits in use.
    pub fn limits(&self) -> &JointLimits<N> {
        &self.limits
    }

    /// The settings in use.
    pub fn config(&self) -> &JointLimiterConfig {
        &self.config
    }

    /// Rejections per reason.
    pub fn rejections(&self) -> &RejectionCounts {
        &self.rejections
    }

    /// How often each stage changed a command.
    pub fn interventions(&self) -> &InterventionCounts {
        &self.interventions
    }
}

/// Brings `x` within `|x_i| <= limit_i * scale` by `strategy`. `Err((joint, x_i))`
/// for the first offending joint under `Reject`.
fn bound<const N: usize>(
    x: &SVector<f64, N>,
    limit: &SVector<f64, N>,
    scale: f64,
    strategy: VelocityLimitStrategy,
) -> Result<SVector<f64, N>, (usize, f64)> {
    match strategy {
        VelocityLimitStrategy::Clamp => Ok(SVector::from_fn(|i, _| {
            let m = limit[i] * scale;
            x[i].clamp(-m, m)
        })),
        VelocityLimitStrategy::ScaleUniformly => {
            let worst = (0..N)
                .map(|i| x[i].abs() / (limit[i] * scale))
                .fold(0.0, f64::max);
            if worst > 1.0 {
                // Dividing can leave the worst joint a rounding error above its
                // limit; the clamp removes that (and changes nothing else).
                Ok(SVector::from_fn(|i, _| {
                    let m = limit[i] * scale;
                    (x[i] / worst).clamp(-m, m)
                }))
            } else {
                Ok(*x)
            }
        }
        VelocityLimitStrategy::Reject => match (0..N).find(|&i| x[i].abs() > limit[i] * scale) {
            Some(i) => Err((i, x[i])),
            None => Ok(*x),
        },
    }
}

/// Speed `v >= 0` toward a limit `distance` away, made safe: without an acceleration
/// limit, zero if one step would cross the limit; with one, at most the braking speed.
fn cap_toward_limit(v: f64, distance: f64, accel: Option<f64>, dt_s: f64) -> f64 {
    if distance == f64::INFINITY {
        return v;
    }
    match accel {
        None => {
            if v * dt_s > distance {
                0.0
            } else {
                v
            }
        }
        Some(a) => v.min(braking_speed(distance, Some(a), dt_s)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::RejectionKind;
    use nalgebra::{SVector, Vector3, Vector6};

    const DT: f64 = 1.0 / 30.0;

    fn ur5(strategy: VelocityLimitStrategy) -> JointVelocityLimiter<6> {
        JointVelocityLimiter::new(
            JointLimits::uniform_velocity(UR5_MAX_JOINT_VELOCITY_RAD_S),
            JointLimiterConfig {
                strategy,
                ..Default::default()
            },
        )
        .unwrap()
    }

    #[test]
    fn within_limits_passes_unchanged() {
        for s in [
            VelocityLimitStrategy::Clamp,
            VelocityLimitStrategy::ScaleUniformly,
            VelocityLimitStrategy::Reject,
        ] {
            let mut l = ur5(s);
            let cmd = Vector6::new(3.0, -3.0, 0.5, 0.0, -2.9, 1.0);
            assert_eq!(l.step(&cmd, &Vector6::zeros(), DT), Ok(cmd));
            assert_eq!(l.interventions().velocity_limited, 0);
        }
    }

    #[test]
    fn scale_uniformly_keeps_direction_and_puts_worst_joint_on_its_limit() {
        let mut l = ur5(VelocityLimitStrategy::ScaleUniformly);
        let cmd = Vector6::new(6.0, -1.5, 0.3, 0.0, -4.5, 2.0);
        let out = l.step(&cmd, &Vector6::zeros(), DT).unwrap();
        assert!((out - cmd / 2.0).norm() < 1e-15, "{out}");
        assert_eq!(out[0], 3.0);
        assert_eq!(l.interventions().velocity_limited, 1);
    }

    #[test]
    fn scale_uniformly_with_unequal_limits() {
        let limits = JointLimits::velocity_only(Vector3::new(1.0, 2.0, 0.5));
        let mut l = JointVelocityLimiter::new(limits, JointLimiterConfig::default()).unwrap();
        let cmd = Vector3::new(1.0, 1.0, 1.0); // joint 2 is worst: 2x its limit
        let out = l.step(&cmd, &Vector3::zeros(), DT).unwrap();
        assert_eq!(out, Vector3::new(0.5, 0.5, 0.5));
    }

    #[test]
    fn clamp_is_per_joint() {
        let mut l = ur5(VelocityLimitStrategy::Clamp);
        let cmd = Vector6::new(6.0, -1.5, 0.3, 0.0, -4.5, 2.0);
        let out = l.step(&cmd, &Vector6::zeros(), DT).unwrap();
        assert_eq!(out, Vector6::new(3.0, -1.5, 0.3, 0.0, -3.0, 2.0));
    }

    #[test]
    fn reject_names_the_first_joint_and_keeps_state() {
        let mut l = ur5(VelocityLimitStrategy::Reject);
        let ok = Vector6::repeat(1.0);
        l.step(&ok, &Vector6::zeros(), DT).unwrap();
        let cmd = Vector6::new(0.0, 0.0, -3.5, 4.0, 0.0, 0.0);
        assert_eq!(
            l.step(&cmd, &Vector6::zeros(), DT),
            Err(Rejection::JointVelocityLimit {
                joint: 2,
                velocity_rad_s: -3.5,
                limit_rad_s: 3.0
            })
        );
        assert_eq!(l.last_output_rad_s(), &ok);
        assert_eq!(l.rejections().get(RejectionKind::JointVelocityLimit), 1);
    }

    #[test]
    fn non_finite_and_bad_time_steps_are_rejected() {
        let mut l = ur5(VelocityLimitStrategy::ScaleUniformly);
        let mut cmd = Vector6::zeros();
        cmd[4] = f64::NAN;
        assert_eq!(
            l.step(&cmd, &Vector6::zeros(), DT),
            Err(Rejection::NonFinite {
                field: "command_rad_s"
            })
        );
        let mut q = Vector6::zeros();
        q[0] = f64::INFINITY;
        assert_eq!(
            l.step(&Vector6::zeros(), &q, DT),
            Err(Rejection::NonFinite {
                field: "position_rad"
            })
        );
        for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                l.step(&Vector6::zeros(), &Vector6::zeros(), dt),
                Err(Rejection::InvalidTimeStep { .. })
            ));
        }
        assert_eq!(l.rejections().total(), 6);
    }

    #[test]
    fn position_limit_zeroes_components_that_would_cross() {
        let limits = JointLimits::uniform_velocity(3.0).with_position_limits(
            Vector3::new(-1.0, -1.0, f64::NEG_INFINITY),
            Vector3::new(1.0, 1.0, f64::INFINITY),
        );
        let mut l = JointVelocityLimiter::new(limits, JointLimiterConfig::default()).unwrap();
        // Joint 0 at 0.95 moving up at 3 rad/s would reach 1.05: zeroed. Joint 1 at
        // 0.95 moving down: fine. Joint 2 is continuous.
        let q = Vector3::new(0.95, 0.95, 100.0);
        let out = l.step(&Vector3::new(3.0, -3.0, 3.0), &q, DT).unwrap();
        assert_eq!(out, Vector3::new(0.0, -3.0, 3.0));
        assert_eq!(l.interventions().position_limited, 1);
        // Exactly reaching the limit is allowed.
        let out = l.step(&Vector3::new(1.5, 0.0, 0.0), &q, DT).unwrap();
        assert!((out[0] - 1.5).abs() < 1e-15);
        // Beyond the limit: may only move back.
        let q = Vector3::new(1.2, -1.3, 0.0);
        let out = l.step(&Vector3::new(0.1, -0.1, 0.0), &q, DT).unwrap();
        assert_eq!(out, Vector3::zeros());
        let out = l.step(&Vector3::new(-0.1, 0.1, 0.0), &q, DT).unwrap();
        assert_eq!(out, Vector3::new(-0.1, 0.1, 0.0));
    }

    fn accel_limiter(strategy: VelocityLimitStrategy) -> JointVelocityLimiter<3> {
        let limits = JointLimits::velocity_only(Vector3::new(2.0, 1.0, 3.0))
            .with_acceleration_limits(Vector3::new(10.0, 5.0, 3.0));
        JointVelocityLimiter::new(
            limits,
            JointLimiterConfig {
                strategy,
                ..Default::default()
            },
        )
        .unwrap()
    }

    #[test]
    fn acceleration_limit_by_strategy() {
        let cmd = Vector3::new(2.0, -1.0, 0.0);
        let q = Vector3::zeros();
        // Clamp: each joint changes by at most a_i dt.
        let mut l = accel_limiter(VelocityLimitStrategy::Clamp);
        let out = l.step(&cmd, &q, DT).unwrap();
        assert!((out - Vector3::new(10.0 * DT, -5.0 * DT, 0.0)).norm() < 1e-15);
        // Scale: the change keeps its direction; the worst joint (1: 1.0 / (5 dt)
        // vs joint 0: 2.0 / (10 dt), equal) sits on its limit.
        let mut l = accel_limiter(VelocityLimitStrategy::ScaleUniformly);
        let out = l.step(&cmd, &q, DT).unwrap();
        assert!((out - cmd * (5.0 * DT)).norm() < 1e-15, "{out}");
        assert_eq!(l.interventions().acceleration_limited, 1);
        // It then reaches the command in 1 / (5 dt) = 6 steps.
        let mut n = 1;
        while l.step(&cmd, &q, DT).unwrap() != cmd {
            n += 1;
            assert!(n < 100);
        }
        assert_eq!(n, 6);
        // Reject.
        let mut l = accel_limiter(VelocityLimitStrategy::Reject);
        match l.step(&cmd, &q, DT) {
            Err(Rejection::JointAccelerationLimit {
                joint: 0,
                acceleration_rad_s2,
                limit_rad_s2,
            }) => {
                assert!((acceleration_rad_s2 - 60.0).abs() < 1e-9);
                assert_eq!(limit_rad_s2, 10.0);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn long_time_step_does_not_license_a_large_change() {
        let mut l = accel_limiter(VelocityLimitStrategy::Clamp);
        let out = l
            .step(&Vector3::new(2.0, 0.0, 0.0), &Vector3::zeros(), 5.0)
            .unwrap();
        assert!((out[0] - 10.0 * 0.1).abs() < 1e-15);
    }

    #[test]
    fn braking_into_a_position_limit_is_smooth_and_exact() {
        // One joint, 3 rad/s max, 3 rad/s² max, upper limit at 1 rad, start at rest
        // at 0, commanded full speed upward forever: it accelerates, brakes, lands on
        // 1 rad exactly, never past, never above the acceleration limit.
        let limits = JointLimits::<1>::uniform_velocity(3.0)
            .with_position_limits(SVector::from([-1.0]), SVector::from([1.0]))
            .with_acceleration_limits(SVector::from([3.0]));
        let mut l = JointVelocityLimiter::new(limits, JointLimiterConfig::default()).unwrap();
        let mut q = 0.0;
        let mut prev = 0.0;
        for _ in 0..300 {
            let v = l
                .step(&SVector::from([3.0]), &SVector::from([q]), DT)
                .unwrap()[0];
            assert!((v - prev).abs() <= 3.0 * DT + 1e-12, "{prev} -> {v}");
            q += v * DT;
            assert!(q <= 1.0 + 1e-12, "{q}");
            prev = v;
        }
        assert!((q - 1.0).abs() < 1e-12, "{q}");
        assert_eq!(prev, 0.0);
    }

    #[test]
    fn limits_parse_validate_and_reject_bad_values() {
        // The PR2 right arm's five joints, as in teleop-kinematics'
        // pr2_right_arm_shadow.urdf (forearm roll is continuous).
        let text = "
            max_velocity_rad_s = [2.088, 2.082, 3.27, 3.3, 3.6]
            min_position_rad = [-2.2853981634, -0.5236, -3.9, -2.3213, -inf]
            max_position_rad = [0.7146018366, 1.3963, 0.8, 0.0, inf]
        ";
        let l: JointLimits<5> = toml::from_str(text).unwrap();
        l.validate().unwrap();
        assert_eq!(l.max_position_rad[4], f64::INFINITY);
        assert!(toml::from_str::<JointLimits<4>>(text).is_err());
        assert!(toml::from_str::<JointLimits<5>>(&format!("{text}\nfoo = 1")).is_err());
        let c: JointLimiterConfig = toml::from_str("strategy = \"clamp\"").unwrap();
        assert_eq!(c.strategy, VelocityLimitStrategy::Clamp);
        assert_eq!(
            toml::from_str::<JointLimiterConfig>("").unwrap(),
            JointLimiterConfig::default()
        );
        assert!(toml::from_str::<JointLimiterConfig>("strategy = \"warn\"").is_err());

        let bad_v = JointLimits::velocity_only(Vector3::new(1.0, 0.0, 1.0));
        assert!(matches!(
            bad_v.validate(),
            Err(ConfigError::JointNotPositive { joint: 1, .. })
        ));
        let bad_q = JointLimits::uniform_velocity(1.0).with_position_limits(
            Vector3::new(0.0, 1.0, f64::NAN),
            Vector3::new(1.0, 0.5, 0.0),
        );
        assert!(matches!(
            bad_q.validate(),
            Err(ConfigError::JointPositionLimits { joint: 1, .. })
        ));
        let bad_a = JointLimits::uniform_velocity(1.0).with_acceleration_limits(Vector3::new(
            1.0,
            1.0,
            f64::INFINITY,
        ));
        assert!(JointVelocityLimiter::new(bad_a, JointLimiterConfig::default()).is_err());
        let bad_dt = JointLimiterConfig {
            max_dt_s: 0.0,
            ..Default::default()
        };
        assert!(
            JointVelocityLimiter::new(JointLimits::<3>::uniform_velocity(1.0), bad_dt).is_err()
        );
    }
}
