//! Bounded-velocity, bounded-acceleration approach of a target, in discrete time.
//!
//! Shared by the Cartesian limiter (linear and angular parts) and the joint
//! limiter's position-limit braking. The integration is semi-implicit Euler: the
//! velocity chosen for a step is the one the position moves with during that step,
//! `x_{k+1} = x_k + v_{k+1} dt`, so the velocity measured from consecutive outputs is
//! exactly the velocity this module chose.

use nalgebra::Vector3;

/// Largest speed from which a discrete braking sequence, losing `accel * dt` of speed
/// per step, stops within `distance` (semi-implicit Euler). With `accel = None`
/// (no acceleration limit) it is `distance / dt`: arrive in one step.
///
/// For speed `v = (n + f) h`, `h = a dt`, `n` integer, `f` in `[0, 1)`, braking at
/// `a` visits `v, v - h, ..., v - n h` and covers `d(v) = h dt (n + 1)(n + 2f) / 2`.
/// This inverts `d(v)` exactly, so that from `v = braking_speed(d)` the next step
/// leaves `d - v dt` and `braking_speed(d - v dt) = v - h`: braking at exactly `a`
/// ends exactly on the target, never past it. (The continuous `sqrt(2 a d)` would
/// ask for slightly more than `a` on the last steps.) For `d < a dt^2` it is
/// `d / dt`.
pub(crate) fn braking_speed(distance: f64, accel: Option<f64>, dt_s: f64) -> f64 {
    if distance <= 0.0 || distance.is_nan() {
        return 0.0;
    }
    let Some(a) = accel else {
        return distance / dt_s;
    };
    let h = a * dt_s;
    // u = (n + 1)(n + 2f), n = largest integer with n (n + 1) <= u.
    let u = 2.0 * distance / (h * dt_s);
    let mut n = ((-1.0 + (1.0 + 4.0 * u).sqrt()) * 0.5).floor();
    // Guard the floor against rounding on either side.
    if n * (n + 1.0) > u {
        n -= 1.0;
    } else if (n + 1.0) * (n + 2.0) <= u {
        n += 1.0;
    }
    let n = n.max(0.0);
    let f = ((u / (n + 1.0) - n) * 0.5).clamp(0.0, 1.0);
    (n + f) * h
}

/// One step of a 3-vector quantity (position, or rotation vector) toward a target:
/// given the current velocity and the remaining error vector (target - current),
/// returns the velocity to move with during this step.
///
/// * Desired velocity: along the error, speed `min(v_max, braking_speed(|error|))`.
/// * The change from `velocity` is limited in norm to `a_max dt` (if `a_max` is set),
///   keeping its direction; otherwise the desired velocity is taken as is.
///
/// Invariants, given `|velocity| <= v_max`: the result has norm `<= v_max` (it lies
/// on the segment between two vectors of norm `<= v_max`) and differs from
/// `velocity` by at most `a_max dt`. With zero initial velocity and a fixed target,
/// the motion is a straight line that ends exactly on the target.
pub(crate) fn approach_velocity(
    velocity: &Vector3<f64>,
    error: &Vector3<f64>,
    v_max: f64,
    a_max: Option<f64>,
    dt_s: f64,
) -> Vector3<f64> {
    let distance = error.norm();
    let desired = if distance > 0.0 {
        let speed = v_max.min(braking_speed(distance, a_max, dt_s));
        error * (speed / distance)
    } else {
        Vector3::zeros()
    };
    match a_max {
        None => desired,
        Some(a) => limit_change(velocity, &desired, a * dt_s),
    }
}

/// `desired`, or the point at distance `max_change` from `current` on the way to it
/// (a change within `1e-12` relative of `max_change` counts as within it).
pub(crate) fn limit_change(
    current: &Vector3<f64>,
    desired: &Vector3<f64>,
    max_change: f64,
) -> Vector3<f64> {
    let change = desired - current;
    let norm = change.norm();
    // The relative slack lets a change that is the limit up to rounding (braking
    // from 0.2 m/s by three steps of 2/30 m/s) finish in that step instead of leaving
    // a 1e-17 remainder for the next one.
    if norm <= max_change * (1.0 + 1e-12) {
        *desired
    } else {
        current + change * (max_change / norm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance covered braking from `v` at `a` per the discrete rule.
    fn discrete_stop_distance(mut v: f64, a: f64, dt: f64) -> f64 {
        let mut d = 0.0;
        while v > 0.0 {
            d += v * dt;
            v -= a * dt;
        }
        d
    }

    #[test]
    fn braking_speed_inverts_the_discrete_stopping_distance() {
        let (a, dt) = (2.0, 1.0 / 30.0);
        for i in 1..2000 {
            let d = i as f64 * 1.7e-4;
            let v = braking_speed(d, Some(a), dt);
            let stop = discrete_stop_distance(v, a, dt);
            assert!((stop - d).abs() < 1e-12, "d = {d}, v = {v}, stop = {stop}");
        }
    }

    #[test]
    fn braking_speed_small_distance_arrives_in_one_step() {
        let (a, dt) = (2.0, 0.01);
        let d = 0.5 * a * dt * dt;
        assert!((braking_speed(d, Some(a), dt) - d / dt).abs() < 1e-15);
        assert_eq!(braking_speed(0.25, None, 0.5), 0.5);
        assert_eq!(braking_speed(0.0, Some(a), dt), 0.0);
        assert_eq!(braking_speed(-1.0, Some(a), dt), 0.0);
        assert_eq!(braking_speed(f64::NAN, Some(a), dt), 0.0);
    }

    #[test]
    fn braking_speed_is_monotone() {
        let (a, dt) = (3.0, 0.002);
        let mut last = 0.0;
        for i in 0..5000 {
            let v = braking_speed(i as f64 * 1e-5, Some(a), dt);
            assert!(v >= last - 1e-15);
            last = v;
        }
    }

    #[test]
    fn limit_change_keeps_direction() {
        let c = Vector3::new(1.0, 0.0, 0.0);
        let d = Vector3::new(1.0, 2.0, 0.0);
        let r = limit_change(&c, &d, 0.5);
        assert!((r - Vector3::new(1.0, 0.5, 0.0)).norm() < 1e-15);
        assert_eq!(limit_change(&c, &d, 5.0), d);
    }
}
