//! Success rates and accuracy on random reachable targets, every goal kind, limits,
//! determinism and failure reporting.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;

use nalgebra::{Isometry3, SVector, Unit, Vector3};
use teleop_ik::{ColdBudget, DistanceConstraint, FailureKind, Goal, IkSettings, Solver};
use teleop_kinematics::robots;

fn ur5() -> Solver<6> {
    Solver::new(robots::ur5_flange_chain().unwrap(), IkSettings::default())
}
fn pr2() -> Solver<7> {
    Solver::new(robots::pr2_arm_chain().unwrap(), IkSettings::default())
}

fn cold_success_rate<const N: usize>(solver: &Solver<N>, n: u64) -> (usize, usize) {
    let mut ok = 0;
    for i in 0..n {
        let q_true = solver.random_q_from_seed(1000 + i);
        let target = solver.chain().end_pose(&q_true);
        let goals = [Goal::pose(target)];
        match solver.solve_cold(&goals, None, i, ColdBudget::default()) {
            Ok(sol) => {
                assert!(sol.position_error_m <= 1e-5, "{sol:?}");
                assert!(sol.orientation_error_rad <= 1e-5, "{sol:?}");
                assert!(solver.chain().within_limits(&sol.q));
                let tip = solver.chain().end_pose(&sol.q);
                assert!((tip.translation.vector - target.translation.vector).norm() <= 1e-5);
                ok += 1;
            }
            Err(e) => eprintln!("failed target {i}: {e}"),
        }
    }
    (ok, n as usize)
}

#[test]
fn cold_ur5_reaches_random_reachable_poses() {
    let (ok, n) = cold_success_rate(&ur5(), 300);
    assert!(ok * 1000 >= n * 995, "{ok}/{n}");
}

#[test]
fn cold_pr2_reaches_random_reachable_poses() {
    let (ok, n) = cold_success_rate(&pr2(), 300);
    assert!(ok * 1000 >= n * 995, "{ok}/{n}");
}

#[test]
fn cold_is_deterministic_for_a_seed() {
    let s = pr2();
    let target = s.chain().end_pose(&s.random_q_from_seed(5));
    let goals = [Goal::pose(target)];
    let a = s
        .solve_cold(&goals, None, 42, ColdBudget::default())
        .unwrap();
    let b = s
        .solve_cold(&goals, None, 42, ColdBudget::default())
        .unwrap();
    assert_eq!(a.q, b.q);
    assert_eq!(a.iterations, b.iterations);
}

#[test]
fn tracking_follows_a_small_motion_from_the_last_solution() {
    let s = pr2();
    let q0 = s.random_q_from_seed(77);
    let start = s.chain().end_pose(&q0);
    let mut q = q0;
    for k in 1..=50 {
        let mut target = start;
        target.translation.vector += Vector3::new(0.001, -0.0005, 0.0008) * f64::from(k);
        let sol = s.solve_tracking(&[Goal::pose(target)], &q).unwrap();
        assert!(sol.position_error_m <= 1e-5);
        // Warm start keeps the configuration continuous.
        assert!((sol.q - q).amax() < 0.1, "jumped: {}", (sol.q - q).amax());
        q = sol.q;
    }
}

#[test]
fn position_direction_and_look_at_goals() {
    let s = ur5();
    let q_true = s.random_q_from_seed(9);
    let tip = s.chain().end_pose(&q_true);
    let z = Unit::new_normalize(Vector3::z());
    // Position + direction.
    let dir = Unit::new_normalize(tip.rotation * Vector3::z());
    let goals = [
        Goal::Position {
            target: tip.translation.vector,
            weight: 1.0,
        },
        Goal::Direction {
            axis: z,
            direction: dir,
            weight: 1.0,
        },
    ];
    let sol = s
        .solve_cold(&goals, None, 1, ColdBudget::default())
        .unwrap();
    assert!(sol.position_error_m <= 1e-5);
    assert!(sol.orientation_error_rad <= 1e-5);
    // Look at a point 0.4 m in front of the flange, from the same position.
    let point = tip.translation.vector + dir.into_inner() * 0.4;
    let goals = [
        Goal::Position {
            target: tip.translation.vector,
            weight: 1.0,
        },
        Goal::LookAt {
            axis: z,
            point,
            weight: 1.0,
        },
    ];
    let sol = s
        .solve_cold(&goals, None, 2, ColdBudget::default())
        .unwrap();
    let d = sol.tip.rotation * Vector3::z();
    let u = (point - sol.tip.translation.vector).normalize();
    assert!(d.dot(&u) > 1.0 - 1e-9);
}

#[test]
fn regularization_trades_accuracy_for_staying_close() {
    let s = pr2();
    let q0 = s.random_q_from_seed(3);
    let mut target = s.chain().end_pose(&q0);
    target.translation.vector += Vector3::new(0.05, 0.0, 0.0);
    let free = s.solve_tracking(&[Goal::pose(target)], &q0).unwrap();
    let reg = [
        Goal::pose(target),
        Goal::JointRegularization {
            reference: q0,
            weight: 0.5,
        },
    ];
    let held = s.solve_tracking(&reg, &q0);
    let held = match held {
        Ok(s) => s,
        Err(e) => *e.best,
    };
    assert!((held.q - q0).norm() < (free.q - q0).norm());
    assert!(held.residuals[1].satisfied);
}

struct FloorAbove(f64);
impl<const N: usize> DistanceConstraint<N> for FloorAbove {
    /// Height of the tip above a plane z = self.0.
    fn distance(&self, frames: &[Isometry3<f64>]) -> f64 {
        frames
            .last()
            .map_or(f64::INFINITY, |f| f.translation.vector.z - self.0)
    }
}

#[test]
fn min_distance_goal_pushes_away() {
    let s = ur5();
    let q0 = s.random_q_from_seed(11);
    let tip = s.chain().end_pose(&q0);
    let plane = tip.translation.vector.z + 0.05;
    let goals = [
        Goal::Position {
            target: tip.translation.vector + Vector3::new(0.0, 0.0, 0.0),
            weight: 0.01,
        },
        Goal::MinDistance {
            constraint: Arc::new(FloorAbove(plane)),
            min_distance_m: 0.0,
            weight: 100.0,
        },
    ];
    let sol = match s.solve_tracking(&goals, &q0) {
        Ok(s) => s,
        Err(e) => *e.best,
    };
    assert!(
        sol.tip.translation.vector.z >= plane - 1e-3,
        "{}",
        sol.tip.translation.vector.z - plane
    );
}

#[test]
fn limits_are_always_respected_and_unreachable_is_an_explicit_failure() {
    let s = pr2();
    let far = Isometry3::translation(5.0, 0.0, 1.0);
    let err = s
        .solve_cold(
            &[Goal::pose(far)],
            None,
            3,
            ColdBudget {
                max_restarts: 5,
                time_limit: None,
            },
        )
        .unwrap_err();
    assert_eq!(err.kind, FailureKind::NotConverged);
    assert!(s.chain().within_limits(&err.best.q));
    assert!(err.best.position_error_m > 3.0);
    assert!(!err.best.residuals[0].satisfied);
}

#[test]
fn invalid_inputs_are_refused_without_moving() {
    let s = ur5();
    let q = SVector::<f64, 6>::zeros();
    let mut bad = Isometry3::identity();
    bad.translation.vector.x = f64::NAN;
    let err = s.solve_tracking(&[Goal::pose(bad)], &q).unwrap_err();
    assert!(matches!(
        err.kind,
        FailureKind::InvalidGoal { index: 0, .. }
    ));
    assert_eq!(err.best.q, q);
    let mut q_nan = q;
    q_nan[2] = f64::NAN;
    let err = s
        .solve_tracking(&[Goal::pose(Isometry3::identity())], &q_nan)
        .unwrap_err();
    assert_eq!(err.kind, FailureKind::InvalidStart);
    let err = s
        .solve_tracking(
            &[Goal::Position {
                target: Vector3::zeros(),
                weight: -1.0,
            }],
            &q,
        )
        .unwrap_err();
    assert!(matches!(err.kind, FailureKind::InvalidGoal { .. }));
}

/// Frames of a chain at `q` (joints after motion, then the tip).
fn frames_of<const N: usize>(s: &Solver<N>, q: &SVector<f64, N>) -> Vec<Isometry3<f64>> {
    let mut f = vec![Isometry3::identity(); N + 1];
    s.chain().chain().frames_into(q.as_slice(), &mut f).unwrap();
    f
}

#[test]
fn frame_goals_reach_intermediate_frames() {
    // PR2 arm: the elbow frame (index 3) and the forearm's direction (frame 4's z) of a
    // random configuration are reached from another start; the tip is left free.
    let s = pr2();
    for seed in 0..20 {
        let q_true = s.random_q_from_seed(100 + seed);
        let f = frames_of(&s, &q_true);
        let offset = Vector3::new(0.01, -0.02, 0.03);
        let target = (f[3] * nalgebra::Point3::from(offset)).coords;
        let dir = Unit::new_normalize(f[4].rotation * Vector3::z());
        let goals = [
            Goal::FramePosition {
                frame: 3,
                offset,
                target,
                weight: 1.0,
            },
            Goal::FrameDirection {
                frame: 4,
                axis: Unit::new_normalize(Vector3::z()),
                direction: dir,
                weight: 1.0,
            },
        ];
        let sol = s
            .solve_cold(&goals, None, seed, ColdBudget::default())
            .unwrap();
        let g = frames_of(&s, &sol.q);
        let reached = (g[3] * nalgebra::Point3::from(offset)).coords;
        assert!((reached - target).norm() <= 1e-5, "seed {seed}");
        let d = g[4].rotation * Vector3::z();
        assert!(d.dot(&dir) > 1.0 - 1e-9, "seed {seed}");
        assert!(sol.residuals.iter().all(|r| r.satisfied));
    }
}

#[test]
fn frame_goal_on_the_tip_index_works_like_the_tip_goal() {
    // `frame = N` is the tip: a FramePosition on it behaves like Position.
    let s = ur5();
    let q_true = s.random_q_from_seed(5);
    let tip = s.chain().end_pose(&q_true).translation.vector;
    let start = s.random_q_from_seed(6);
    let a = s.solve_tracking(
        &[Goal::Position {
            target: tip,
            weight: 1.0,
        }],
        &start,
    );
    let b = s.solve_tracking(
        &[Goal::FramePosition {
            frame: 6,
            offset: Vector3::zeros(),
            target: tip,
            weight: 1.0,
        }],
        &start,
    );
    // Both reach the target (the problem is redundant, so rounding differences between
    // the two Jacobian computations may lead to different joint vectors).
    let a = a.unwrap();
    let b = b.unwrap();
    assert!((a.tip.translation.vector - tip).norm() <= 1e-5);
    assert!((b.tip.translation.vector - tip).norm() <= 1e-5);
    assert!(
        b.iterations <= a.iterations + 3,
        "{} vs {}",
        b.iterations,
        a.iterations
    );
}

#[test]
fn frame_goal_beyond_the_tip_is_refused() {
    let s = ur5();
    let q = SVector::<f64, 6>::zeros();
    let err = s
        .solve_tracking(
            &[Goal::FramePosition {
                frame: 7,
                offset: Vector3::zeros(),
                target: Vector3::zeros(),
                weight: 1.0,
            }],
            &q,
        )
        .unwrap_err();
    assert!(matches!(
        err.kind,
        FailureKind::InvalidGoal { index: 0, .. }
    ));
    assert_eq!(err.best.q, q);
}
