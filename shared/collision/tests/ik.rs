//! The distance constraints inside the IK: goals that would drive the robot into the
//! operator's hand volume or a finger into another finger are held off.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use teleop_collision::{
    ChainBodies, ChainSelfDistance, ChainVolumeDistance, ExternalVolume, robots,
};
use teleop_ik::{ColdBudget, DistanceConstraint, Goal, IkSettings, Solution, Solver};
use teleop_kinematics::robots as kin;

const MIN_M: f64 = 0.05;
/// The solver treats the distance goal as a stiff penalty: allow it a millimetre.
const TOL_M: f64 = 1e-3;

fn frames<const N: usize>(solver: &Solver<N>, q: &SVector<f64, N>) -> Vec<Isometry3<f64>> {
    let mut f = vec![Isometry3::identity(); N + 1];
    solver
        .chain()
        .chain()
        .frames_into(q.as_slice(), &mut f)
        .unwrap();
    f
}

fn solved<const N: usize>(r: Result<Solution<N>, teleop_ik::IkFailure<N>>) -> Solution<N> {
    match r {
        Ok(s) => s,
        Err(e) => *e.best,
    }
}

#[test]
fn ur5_camera_never_enters_the_hand_volume() {
    let robot = kin::ur5().unwrap();
    let model = robots::ur5(&robot).unwrap();
    let chain = kin::ur5_camera_chain().unwrap();
    let bodies = Arc::new(ChainBodies::new(&model, &robot, &chain).unwrap());
    let solver = Solver::new(chain, IkSettings::default());

    // Camera at (-0.44, -0.11, 0.63) looking along -x; the hand 0.25 m in front of it.
    let q0 = SVector::<f64, 6>::from([0.0, -1.57, 1.0, 0.57, 1.57, 0.0]);
    let optical = solver.chain().end_pose(&q0);
    let wrist = optical
        * Translation3::new(0.0, 0.0, 0.25 + 0.025)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
    let hand = ExternalVolume::hand_volume(wrist, 0.02).unwrap();
    let constraint = Arc::new(ChainVolumeDistance::new(bodies.clone(), hand.clone()));
    let start = constraint.distance(&frames(&solver, &q0));
    assert!((start - 0.23).abs() < 1e-4, "{start}");

    // Target: the camera origin at the centre of the hand box.
    let centre = wrist * nalgebra::Point3::new(0.0, 0.0, 0.095);
    let position = Goal::Position {
        target: centre.coords,
        weight: 0.01,
    };
    let keep_out = Goal::MinDistance {
        constraint: constraint.clone(),
        min_distance_m: MIN_M,
        weight: 100.0,
    };
    let goals = [position.clone(), keep_out];

    // Tracking, as in the control loop: each step warm-started from the last.
    let mut q = q0;
    let mut last = start;
    for _ in 0..60 {
        let sol = solved(solver.solve_tracking(&goals, &q));
        q = sol.q;
        last = constraint.distance(&frames(&solver, &q));
        assert!(last >= MIN_M - TOL_M, "entered the keep-out zone: {last}");
        // The whole-robot check agrees (chain base = robot root here).
        let mut full = robot.neutral_positions();
        full[..6].copy_from_slice(q.as_slice());
        let poses = robot.forward_kinematics(&full).unwrap();
        let p = model.volume_distance(&poses, &hand).unwrap().unwrap();
        assert!(p.distance_m >= MIN_M - TOL_M, "{p:?}");
    }
    // It did move towards the hand and stopped at the boundary.
    assert!(last <= MIN_M + 0.01, "did not approach: {last}");

    // Cold solve: the best it finds still keeps out.
    let sol = solved(solver.solve_cold(
        &goals,
        Some(&q0),
        7,
        ColdBudget {
            max_restarts: 20,
            time_limit: None,
        },
    ));
    let d = constraint.distance(&frames(&solver, &sol.q));
    assert!(d >= MIN_M - TOL_M, "cold: {d}");

    // Without the distance goal the same target drives the camera into the hand.
    let free = solved(solver.solve_cold(&[position], Some(&q0), 7, ColdBudget::default()));
    assert!(constraint.distance(&frames(&solver, &free.q)) < 0.0);
}

#[test]
fn shadow_first_finger_is_kept_off_the_middle_finger() {
    let robot = kin::shadow_hand().unwrap();
    let model = robots::shadow_hand(&robot).unwrap();
    let chain = robot
        .chain("rh_palm", "rh_fftip")
        .unwrap()
        .fixed::<3>()
        .unwrap();
    // The middle finger, outside the chain, rests flexed.
    let mut rest = robot.neutral_positions();
    for (j, v) in [("rh_MFJ3", 1.2), ("rh_MFJ2", 1.0)] {
        rest[robot.dof_index(j).unwrap()] = v;
    }
    let bodies = Arc::new(ChainBodies::with_rest(&model, &robot, &chain, &rest).unwrap());
    let constraint = Arc::new(ChainSelfDistance::new(bodies));
    let solver = Solver::new(chain, IkSettings::default());

    // Target: where the FF tip is when FF curls over into the MF (FFJ4 +0.35 turns FF
    // towards MF), which collides.
    let crossed = SVector::<f64, 3>::from([0.349, 1.2, 1.0]);
    assert!(constraint.distance(&frames(&solver, &crossed)) < 0.0);
    let target = solver.chain().end_pose(&crossed).translation.vector;
    let position = Goal::Position {
        target,
        weight: 1.0,
    };
    let min = 0.002;
    let goals = [
        position.clone(),
        Goal::MinDistance {
            constraint: constraint.clone(),
            min_distance_m: min,
            weight: 1e4,
        },
    ];
    let q0 = SVector::<f64, 3>::zeros();
    assert!(constraint.distance(&frames(&solver, &q0)) > min);

    let budget = ColdBudget {
        max_restarts: 20,
        time_limit: None,
    };
    let sol = solved(solver.solve_cold(&goals, Some(&q0), 3, budget));
    let d = constraint.distance(&frames(&solver, &sol.q));
    assert!(d >= min - TOL_M, "finger collision: {d}");
    // It still got the tip close to the target (within a finger's width).
    let tip = solver.chain().end_pose(&sol.q).translation.vector;
    assert!((tip - target).norm() < 0.03, "{}", (tip - target).norm());

    // Without the distance goal it reaches the colliding target.
    let free = solved(solver.solve_cold(&[position], Some(&q0), 3, budget));
    assert!(free.position_error_m < 1e-4);
    assert!(constraint.distance(&frames(&solver, &free.q)) < 0.0);
}
