//! Searches a PR2 start posture for the pick job's grasp and room in every joint for the
//! moves the job needs from there (12 cm forward and back, 15 cm toward the object, 8 cm
//! down, 12 cm up, three diagonals; for the top grasp 15 cm down), each walked in 1 cm
//! steps of the tracking IK the arm controller runs. Side grasp: the palm facing
//! sideways (world +y, turned by a yaw), the fingers level (or pitched). Top grasp
//! (`top`): the palm facing down, the fingers level (or pitched) and forward, turned by
//! a yaw. Prints every posture that beats the best so far: its worst distance to a
//! joint limit over all the moves (rad) and which joint.
//!
//!     cargo run --release -p teleop-ik --example pick_posture
//!     cargo run --release -p teleop-ik --example pick_posture -- top
//!     cargo run --release -p teleop-ik --example pick_posture -- -0.23,0.862,-0.328,-1.327,1.756,-0.082,-0.109
//!
//! With a posture (7 joint angles, rad) it only rates that one over the same moves.
//!
//! Why: at the working posture the Shadow wrist (WRJ2 -0.52..0.17 rad, WRJ1
//! -0.70..0.49) leaves no side grasp with level fingers within reach (docs/physics.md,
//! "The operator who watches the display").
#![allow(clippy::unwrap_used, clippy::print_stdout)]

use nalgebra::{Isometry3, Matrix3, Rotation3, SVector, UnitQuaternion, Vector3};
use teleop_ik::{ColdBudget, Goal, IkSettings, Solver};
use teleop_kinematics::robots;

fn margin(s: &Solver<7>, q: &SVector<f64, 7>) -> (f64, usize) {
    let lo = s.chain().lower_limits();
    let hi = s.chain().upper_limits();
    let mut best = (f64::INFINITY, 0);
    for i in 0..7 {
        let m = (q[i] - lo[i]).min(hi[i] - q[i]);
        if m < best.0 {
            best = (m, i);
        }
    }
    best
}

/// Walks from `q` to `target * offset` in 1 cm steps; the worst margin on the way, or
/// None if a step is not reached.
fn walk(
    s: &Solver<7>,
    q0: &SVector<f64, 7>,
    start: &Isometry3<f64>,
    d: Vector3<f64>,
) -> Option<(f64, usize)> {
    let n = (d.norm() / 0.01).ceil().max(1.0) as usize;
    let mut q = *q0;
    let mut worst = margin(s, q0);
    for k in 1..=n {
        let mut t = *start;
        t.translation.vector += d * (k as f64 / n as f64);
        let sol = match s.solve_tracking(&[Goal::pose(t)], &q) {
            Ok(sol) => sol,
            Err(e) => *e.best,
        };
        if sol.position_error_m > 0.002 || sol.orientation_error_rad > 0.02 {
            return None;
        }
        q = sol.q;
        let m = margin(s, &q);
        if m.0 < worst.0 {
            worst = m;
        }
    }
    Some(worst)
}

/// The worst margin of `q` over `moves` from its own palm pose; None if a move is out of
/// reach.
fn rate(s: &Solver<7>, q: &SVector<f64, 7>, moves: &[Vector3<f64>]) -> Option<(f64, usize)> {
    let start = s.chain().end_pose(q);
    let mut worst = margin(s, q);
    for d in moves {
        let m = walk(s, q, &start, *d)?;
        if m.0 < worst.0 {
            worst = m;
        }
    }
    Some(worst)
}

fn main() {
    let s = Solver::new(robots::pr2_arm_chain().unwrap(), IkSettings::default());
    let working = SVector::<f64, 7>::from([-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1]);
    let p0 = s.chain().end_pose(&working);
    println!("working palm {:?}", p0.translation.vector.as_slice());
    let r = p0.rotation;
    println!(
        "  normal {:?} fingers {:?} x {:?}",
        (r * -Vector3::y()).as_slice(),
        (r * Vector3::z()).as_slice(),
        (r * Vector3::x()).as_slice()
    );
    let args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--").collect();
    let top = args.iter().any(|a| a == "top");
    let down = if top { -0.15 } else { -0.08 };
    let moves = [
        Vector3::new(0.12, 0.0, 0.0),
        Vector3::new(-0.12, 0.0, 0.0),
        Vector3::new(0.0, 0.15, 0.0),
        Vector3::new(0.0, -0.10, 0.0),
        Vector3::new(0.0, 0.0, down),
        Vector3::new(0.0, 0.0, 0.12),
        Vector3::new(0.1, 0.1, 0.1),
        Vector3::new(-0.1, 0.1, -0.06),
        Vector3::new(0.1, 0.15, down),
    ];
    if let Some(arg) = args.iter().find(|a| *a != "top") {
        let v: Result<Vec<f64>, _> = arg.split(',').map(|x| x.trim().parse::<f64>()).collect();
        let v = match v {
            Ok(v) if v.len() == 7 && v.iter().all(|x| x.is_finite()) => v,
            _ => {
                eprintln!("error: {arg:?} is not 7 finite joint angles (rad), comma-separated");
                std::process::exit(2);
            }
        };
        let q = SVector::<f64, 7>::from_column_slice(&v);
        let p = s.chain().end_pose(&q);
        println!("palm {:?}", p.translation.vector.as_slice());
        match rate(&s, &q, &moves) {
            Some((m, j)) => println!("worst margin {m:.3} rad (joint {j}) over the moves"),
            None => println!("a move is out of reach"),
        }
        return;
    }
    let mut best: Option<(f64, SVector<f64, 7>, Isometry3<f64>, usize)> = None;
    let mut seed = 0;
    for pitch_deg in [0.0f64, -10.0, 10.0, 20.0, 30.0] {
        for yaw_deg in [0.0f64, 15.0, 30.0, 45.0, 60.0, -15.0, -30.0] {
            // Fingers forward (+x) turned by yaw about z and pitched; palm normal +y.
            let fingers =
                Rotation3::from_euler_angles(0.0, -pitch_deg.to_radians(), yaw_deg.to_radians())
                    * Vector3::x();
            let normal0 = if top {
                -Vector3::z()
            } else {
                Rotation3::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()) * Vector3::y()
            };
            let normal = (normal0 - fingers * fingers.dot(&normal0)).normalize();
            let y = -normal;
            let z = fingers;
            let x = y.cross(&z);
            let rot = UnitQuaternion::from_matrix(&Matrix3::from_columns(&[x, y, z]));
            for dx in [-0.1, 0.0, 0.1] {
                for dy in [-0.1, 0.0, 0.1] {
                    for dz in [-0.25, -0.2, -0.15, -0.1, -0.05] {
                        let pos = p0.translation.vector + Vector3::new(dx, dy, dz);
                        let target = Isometry3::from_parts(pos.into(), rot);
                        for _ in 0..8 {
                            seed += 1;
                            let Ok(sol) = s.solve_cold(
                                &[Goal::pose(target)],
                                None,
                                seed,
                                ColdBudget::default(),
                            ) else {
                                continue;
                            };
                            let mut worst = margin(&s, &sol.q);
                            let mut ok = true;
                            for d in &moves {
                                match walk(&s, &sol.q, &target, *d) {
                                    Some(m) if m.0 < worst.0 => worst = m,
                                    Some(_) => {}
                                    None => {
                                        ok = false;
                                        break;
                                    }
                                }
                            }
                            if ok && best.as_ref().is_none_or(|b| worst.0 > b.0) {
                                println!(
                                    "pitch {pitch_deg} yaw {yaw_deg} d [{dx}, {dy}, {dz}]: margin {:.3} (joint {}) q {:?}",
                                    worst.0,
                                    worst.1,
                                    sol.q
                                        .iter()
                                        .map(|v| (v * 1000.0).round() / 1000.0)
                                        .collect::<Vec<_>>()
                                );
                                best = Some((worst.0, sol.q, target, worst.1));
                            }
                        }
                    }
                }
            }
        }
    }
    if let Some((m, q, t, j)) = best {
        println!(
            "best margin {m:.3} (joint {j}) palm {:?} q {:?}",
            t.translation.vector.as_slice(),
            q.as_slice()
        );
    }
}
