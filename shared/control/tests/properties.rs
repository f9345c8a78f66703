//! Property tests: for random limits and random input sequences, no output violates a
//! limit, every output is finite, and a constant target is reached.

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use teleop_control::{
    CartesianLimiter, CartesianLimits, JointLimiterConfig, JointLimits, JointVelocityLimiter,
    JumpFilter, JumpFilterConfig, Rejection, VelocityLimitStrategy,
};

/// Absolute slack for comparing measured rates with limits (rounding only).
const TOL: f64 = 1e-9;

fn vec3(range: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

/// A random rotation: rotation vector in the ball of radius ~pi.
fn rotation() -> impl Strategy<Value = UnitQuaternion<f64>> {
    vec3(1.8).prop_map(|v| {
        let v = if v.norm() > std::f64::consts::PI {
            v * (std::f64::consts::PI / v.norm())
        } else {
            v
        };
        UnitQuaternion::from_scaled_axis(v)
    })
}

fn pose(range_m: f64) -> impl Strategy<Value = Isometry3<f64>> {
    (vec3(range_m), rotation()).prop_map(|(t, r)| Isometry3::from_parts(Translation3::from(t), r))
}

fn cartesian_limits() -> impl Strategy<Value = CartesianLimits> {
    (
        0.05..1.0f64,
        0.2..4.0f64,
        0.5..10.0f64,
        proptest::option::of(1.0..20.0f64),
    )
        .prop_map(|(v, w, a, alpha)| CartesianLimits {
            max_linear_velocity_m_s: v,
            max_angular_velocity_rad_s: w,
            max_linear_acceleration_m_s2: a,
            max_angular_acceleration_rad_s2: alpha,
            ..Default::default()
        })
}

/// Targets, each held for a number of steps of a given dt (dt within `max_dt_s`, so
/// the velocity measured from the outputs is the limiter's own).
fn target_sequence() -> impl Strategy<Value = Vec<(Isometry3<f64>, usize, f64)>> {
    proptest::collection::vec((pose(1.5), 1usize..40, 0.001..0.1f64), 1..12)
}

struct Measured {
    prev: Isometry3<f64>,
    v: Vector3<f64>,
    w: Vector3<f64>,
}

impl Measured {
    /// Checks one output against the limits, from outputs alone.
    fn check(&mut self, out: &Isometry3<f64>, dt: f64, l: &CartesianLimits) {
        assert!(out.translation.vector.iter().all(|x| x.is_finite()));
        assert!(out.rotation.coords.iter().all(|x| x.is_finite()));
        assert!((out.rotation.quaternion().norm() - 1.0).abs() < 1e-12);
        let v = (out.translation.vector - self.prev.translation.vector) / dt;
        let w = (out.rotation * self.prev.rotation.inverse()).scaled_axis() / dt;
        assert!(
            v.norm() <= l.max_linear_velocity_m_s * (1.0 + TOL) + TOL,
            "|v| = {} > {}",
            v.norm(),
            l.max_linear_velocity_m_s
        );
        // Differences of positions lose precision relative to the positions (~1 m):
        // allow rounding of order 1e-15 m / dt^2.
        let slack = 1e-14 / (dt * dt);
        assert!(
            (v - self.v).norm() / dt <= l.max_linear_acceleration_m_s2 * (1.0 + TOL) + slack,
            "|a| = {} > {}",
            (v - self.v).norm() / dt,
            l.max_linear_acceleration_m_s2
        );
        assert!(
            w.norm() <= l.max_angular_velocity_rad_s * (1.0 + TOL) + 1e-14 / dt,
            "|w| = {} > {}",
            w.norm(),
            l.max_angular_velocity_rad_s
        );
        if let Some(alpha) = l.max_angular_acceleration_rad_s2 {
            assert!(
                (w - self.w).norm() / dt <= alpha * (1.0 + TOL) + slack,
                "|alpha| = {} > {alpha}",
                (w - self.w).norm() / dt
            );
        }
        self.prev = *out;
        self.v = v;
        self.w = w;
    }
}

/// Upper bound on the time to reach a fixed target from any state within the limits:
/// stop (v/a), come back over what the stop covered, then a rest-to-rest move.
fn reach_bound_s(l: &CartesianLimits, d_m: f64, angle_rad: f64) -> f64 {
    let (v, a, w) = (
        l.max_linear_velocity_m_s,
        l.max_linear_acceleration_m_s2,
        l.max_angular_velocity_rad_s,
    );
    let lin = 3.0 * (v / a) + (d_m + v * v / a) / v;
    let ang = match l.max_angular_acceleration_rad_s2 {
        Some(alpha) => 3.0 * (w / alpha) + (angle_rad + w * w / alpha) / w,
        None => angle_rad / w,
    };
    2.0 * lin.max(ang) + 1.0
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn cartesian_limits_hold_and_constant_target_is_reached(
        limits in cartesian_limits(),
        start in pose(1.0),
        sequence in target_sequence(),
        last in pose(1.5),
        last_dt in 0.005..0.05f64,
    ) {
        let mut l = CartesianLimiter::new(limits, &start).unwrap();
        let mut m = Measured { prev: start, v: Vector3::zeros(), w: Vector3::zeros() };
        for (target, steps, dt) in &sequence {
            for _ in 0..*steps {
                let out = l.step(target, *dt).unwrap();
                m.check(&out, *dt, &limits);
            }
        }
        // Now hold one target: the output converges to it exactly and stops.
        let d = (last.translation.vector - l.pose().translation.vector).norm();
        let angle = l.pose().rotation.angle_to(&last.rotation);
        let max_steps = (reach_bound_s(&limits, d, angle) / last_dt).ceil() as usize;
        let mut reached = None;
        for k in 0..max_steps {
            let out = l.step(&last, last_dt).unwrap();
            m.check(&out, last_dt, &limits);
            let dp = (out.translation.vector - last.translation.vector).norm();
            let dr = out.rotation.angle_to(&last.rotation);
            if dp < 1e-9 && dr < 1e-9 && l.is_at_rest() {
                reached = Some(k);
                break;
            }
        }
        prop_assert!(
            reached.is_some(),
            "not reached in {max_steps} steps: {} m, {} rad left, v {}, w {}",
            (l.pose().translation.vector - last.translation.vector).norm(),
            l.pose().rotation.angle_to(&last.rotation),
            l.linear_velocity_m_s().norm(),
            l.angular_velocity_rad_s().norm()
        );
    }

    #[test]
    fn cartesian_rejections_never_reach_the_state(
        start in pose(1.0),
        targets in proptest::collection::vec((pose(1.0), 0u8..6), 1..60),
    ) {
        let mut l = CartesianLimiter::new(CartesianLimits::default(), &start).unwrap();
        for (target, corrupt) in targets {
            let before = (*l.pose(), *l.linear_velocity_m_s());
            let mut t = target;
            let mut dt = 1.0 / 30.0;
            match corrupt {
                0 => t.translation.vector.y = f64::NAN,
                1 => t.translation.vector.z = f64::NEG_INFINITY,
                2 => dt = f64::NAN,
                3 => dt = -dt,
                _ => {}
            }
            match l.step(&t, dt) {
                Ok(out) => {
                    prop_assert!(corrupt > 3);
                    prop_assert!(out.translation.vector.iter().all(|x| x.is_finite()));
                }
                Err(r) => {
                    prop_assert!(corrupt <= 3, "{r}");
                    prop_assert_eq!((*l.pose(), *l.linear_velocity_m_s()), before);
                }
            }
        }
    }
}

fn joint_limits() -> impl Strategy<Value = JointLimits<7>> {
    (
        proptest::array::uniform7(0.2..4.0f64),
        proptest::array::uniform7(-3.0..-0.2f64),
        proptest::array::uniform7(0.2..3.0f64),
        proptest::array::uniform7(1.0..30.0f64),
        any::<bool>(),
    )
        .prop_map(|(v, lo, hi, a, with_accel)| {
            let mut l = JointLimits::velocity_only(SVector::from(v))
                .with_position_limits(SVector::from(lo), SVector::from(hi));
            if with_accel {
                l = l.with_acceleration_limits(SVector::from(a));
            }
            l
        })
}

fn strategy() -> impl Strategy<Value = VelocityLimitStrategy> {
    prop_oneof![
        Just(VelocityLimitStrategy::Clamp),
        Just(VelocityLimitStrategy::ScaleUniformly),
        Just(VelocityLimitStrategy::Reject),
    ]
}

fn joint_commands() -> impl Strategy<Value = Vec<(SVector<f64, 7>, usize)>> {
    proptest::collection::vec(
        (
            proptest::array::uniform7(-8.0..8.0f64).prop_map(SVector::from),
            1usize..30,
        ),
        1..10,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn joint_limits_hold_on_a_simulated_arm(
        limits in joint_limits(),
        strategy in strategy(),
        commands in joint_commands(),
        dt in 0.002..0.1f64,
    ) {
        let config = JointLimiterConfig { strategy, ..Default::default() };
        let mut l = JointVelocityLimiter::new(limits, config).unwrap();
        // The arm starts inside its range at rest and moves by the outputs.
        let mut q = (limits.min_position_rad + limits.max_position_rad) * 0.5;
        let mut prev = SVector::<f64, 7>::zeros();
        for (cmd, steps) in &commands {
            for _ in 0..*steps {
                let out = match l.step(cmd, &q, dt) {
                    Ok(out) => out,
                    Err(Rejection::JointVelocityLimit { joint, velocity_rad_s, limit_rad_s })
                    | Err(Rejection::JointAccelerationLimit {
                        joint,
                        acceleration_rad_s2: velocity_rad_s,
                        limit_rad_s2: limit_rad_s,
                    }) => {
                        prop_assert_eq!(strategy, VelocityLimitStrategy::Reject);
                        prop_assert!(velocity_rad_s.abs() > limit_rad_s, "joint {}", joint);
                        prop_assert_eq!(l.last_output_rad_s(), &prev);
                        continue;
                    }
                    Err(other) => return Err(TestCaseError::fail(format!("{other}"))),
                };
                for i in 0..7 {
                    prop_assert!(out[i].is_finite());
                    prop_assert!(out[i].abs() <= limits.max_velocity_rad_s[i] * (1.0 + 1e-12));
                    if let Some(a) = &limits.max_acceleration_rad_s2 {
                        prop_assert!(
                            (out[i] - prev[i]).abs() <= a[i] * dt * (1.0 + 1e-9) + 1e-12,
                            "joint {}: {} -> {}", i, prev[i], out[i]
                        );
                    }
                }
                q += out * dt;
                for i in 0..7 {
                    prop_assert!(
                        q[i] <= limits.max_position_rad[i] + 1e-12
                            && q[i] >= limits.min_position_rad[i] - 1e-12,
                        "joint {} at {} outside [{}, {}]",
                        i, q[i], limits.min_position_rad[i], limits.max_position_rad[i]
                    );
                }
                prev = out;
            }
        }
    }

    #[test]
    fn scale_uniformly_keeps_the_direction(
        v_max in proptest::array::uniform7(0.2..4.0f64),
        cmd in proptest::array::uniform7(-10.0..10.0f64),
    ) {
        let limits = JointLimits::velocity_only(SVector::from(v_max));
        let mut l = JointVelocityLimiter::new(limits, JointLimiterConfig::default()).unwrap();
        let cmd = SVector::<f64, 7>::from(cmd);
        let out = l.step(&cmd, &SVector::zeros(), 0.01).unwrap();
        // out = k cmd with 0 < k <= 1, and some joint at its limit when k < 1.
        let k = out.dot(&cmd) / cmd.norm_squared();
        prop_assert!(k > 0.0 && k <= 1.0 + 1e-15);
        prop_assert!((out - cmd * k).norm() <= 1e-12 * cmd.norm());
        if k < 1.0 {
            prop_assert!((0..7).any(|i| (out[i].abs() - v_max[i]).abs() < 1e-12));
        }
    }

    #[test]
    fn joint_output_converges_to_a_constant_command(
        limits in joint_limits(),
        cmd in proptest::array::uniform7(-8.0..8.0f64),
        dt in 0.002..0.05f64,
    ) {
        // Positions far from the limits: only velocity and acceleration act.
        let limits = JointLimits { min_position_rad: SVector::repeat(f64::NEG_INFINITY),
            max_position_rad: SVector::repeat(f64::INFINITY), ..limits };
        let mut l = JointVelocityLimiter::new(limits, JointLimiterConfig::default()).unwrap();
        let cmd = SVector::<f64, 7>::from(cmd);
        let worst = (0..7).map(|i| cmd[i].abs() / limits.max_velocity_rad_s[i]).fold(0.0, f64::max);
        let expected = if worst > 1.0 { cmd / worst } else { cmd };
        // Time to reach it at the acceleration limits (scaled uniformly, the slowest
        // joint sets the pace).
        let t_s = match &limits.max_acceleration_rad_s2 {
            Some(a) => (0..7).map(|i| expected[i].abs() / a[i]).fold(0.0, f64::max),
            None => 0.0,
        };
        let mut out = SVector::zeros();
        for _ in 0..((t_s / dt).ceil() as usize + 3) {
            out = l.step(&cmd, &SVector::zeros(), dt).unwrap();
        }
        prop_assert!((out - expected).amax() < 1e-12, "{} vs {}", out, expected);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn jump_filter_accepts_exactly_the_small_steps(
        start in pose(2.0),
        steps in proptest::collection::vec((vec3(0.8), vec3(1.6)), 1..50),
    ) {
        let config = JumpFilterConfig::default();
        let mut f = JumpFilter::new(config).unwrap();
        f.filter(&start).unwrap();
        let mut reference = start;
        for (dp, dr) in steps {
            let p = Isometry3::from_parts(
                Translation3::from(reference.translation.vector + dp),
                UnitQuaternion::from_scaled_axis(dr) * reference.rotation,
            );
            let small = dp.amax() <= config.max_position_jump_m
                && reference.rotation.angle_to(&p.rotation)
                    <= config.max_orientation_jump_deg.to_radians();
            match f.filter(&p) {
                Ok(out) => {
                    prop_assert!(small);
                    prop_assert_eq!(out, p);
                    reference = p;
                }
                Err(r) => {
                    prop_assert!(!small, "{}", r);
                    prop_assert_eq!(f.reference(), Some(&reference));
                }
            }
        }
    }

    #[test]
    fn total_angle_bounds_roll_pitch_yaw(axis in vec3(1.0), angle_deg in 0.0..90.0f64) {
        prop_assume!(axis.norm() > 1e-3);
        let angle = angle_deg.to_radians();
        let q = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
        let (r, p, y) = q.euler_angles();
        prop_assert!(r.abs() <= angle + 1e-9 && p.abs() <= angle + 1e-9 && y.abs() <= angle + 1e-9);
    }
}
