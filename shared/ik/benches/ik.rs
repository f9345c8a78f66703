//! IK benchmark, ours vs. the `k` crate's `JacobianIkSolver`, same robots, same targets,
//! same run:
//!
//! * cold: random reachable poses (FK of uniformly drawn joint vectors), success at
//!   1e-5 m / 1e-5 rad, both solvers restarting from random joint vectors until success
//!   or a 5 ms cap per target (TRAC-IK's table uses the same kind of timeout);
//! * tracking: a square wrist path with sharp corners and a slow rotation, sampled at
//!   30 Hz and 1 kHz, each step warm-started from the previous solution.
//!
//! `cargo bench --workspace --bench ik` (full: 10,000 cold targets per robot), or
//! `cargo bench --workspace --bench ik -- --quick` (1,000).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::{Duration, Instant};

use k::InverseKinematicsSolver;
use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use teleop_ik::{ColdBudget, Goal, IkSettings, Solver};
use teleop_kinematics::{FixedChain, robots};

const CAP: Duration = Duration::from_millis(5);
const TOL: f64 = 1e-5;

fn urdf_path(file: &str) -> String {
    format!("{}/../kinematics/urdf/{file}", env!("CARGO_MANIFEST_DIR"))
}

fn to_k(p: &Isometry3<f64>) -> k::nalgebra::Isometry3<f64> {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    k::nalgebra::Isometry3::from_parts(
        k::nalgebra::Translation3::new(t.x, t.y, t.z),
        k::nalgebra::UnitQuaternion::new_normalize(k::nalgebra::Quaternion::new(
            q.w, q.i, q.j, q.k,
        )),
    )
}

fn from_k(p: &k::nalgebra::Isometry3<f64>) -> Isometry3<f64> {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    Isometry3::from_parts(
        Translation3::new(t.x, t.y, t.z),
        UnitQuaternion::new_normalize(nalgebra::Quaternion::new(q.w, q.i, q.j, q.k)),
    )
}

fn errors(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let dp = (a.translation.vector - b.translation.vector).norm();
    let da = (a.rotation * b.rotation.inverse()).angle();
    (dp, da)
}

fn pct(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let i = ((v.len() as f64 - 1.0) * p).round() as usize;
    v[i]
}

/// A uniformly drawn joint vector within the limits (same sampler for both solvers).
struct Rng(u64);
impl Rng {
    fn f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn q<const N: usize>(&mut self, chain: &FixedChain<N>) -> SVector<f64, N> {
        let lo = chain.lower_limits();
        let hi = chain.upper_limits();
        SVector::from_fn(|i, _| {
            let (l, h) = (
                lo[i].max(-std::f64::consts::PI),
                hi[i].min(std::f64::consts::PI),
            );
            l + (h - l) * self.f64()
        })
    }
}

struct KArm {
    _chain: k::Chain<f64>,
    arm: k::SerialChain<f64>,
    solver: k::JacobianIkSolver<f64>,
}

impl KArm {
    fn new(file: &str, tip: &str) -> Self {
        let chain = k::Chain::<f64>::from_urdf_file(urdf_path(file)).expect("k loads URDF");
        let end = chain.find_link(tip).expect("tip link");
        let arm = k::SerialChain::from_end(end);
        let solver = k::JacobianIkSolver::new(TOL, TOL, 0.5, 100);
        Self {
            _chain: chain,
            arm,
            solver,
        }
    }
    fn solve_from(&self, q0: &[f64], target: &Isometry3<f64>) -> bool {
        self.arm.set_joint_positions_clamped(q0);
        let t = to_k(target);
        if self.solver.solve(&self.arm, &t).is_err() {
            return false;
        }
        self.arm.update_transforms();
        let (dp, da) = errors(&from_k(&self.arm.end_transform()), target);
        dp <= TOL && da <= TOL
    }
    fn q(&self) -> Vec<f64> {
        self.arm.joint_positions()
    }
}

struct ColdRow {
    solver: &'static str,
    success: f64,
    p50_us: f64,
    p99_us: f64,
}

fn cold<const N: usize>(name: &str, ours: &Solver<N>, theirs: &KArm, n: usize) -> Vec<ColdRow> {
    let mut rng = Rng(0xC01D ^ N as u64);
    let targets: Vec<Isometry3<f64>> = (0..n)
        .map(|_| ours.chain().end_pose(&rng.q(ours.chain())))
        .collect();
    // Ours.
    let mut t_ours = Vec::with_capacity(n);
    let mut ok_ours = 0;
    for (i, target) in targets.iter().enumerate() {
        let goals = [Goal::pose(*target)];
        let t0 = Instant::now();
        let r = ours.solve_cold(
            &goals,
            None,
            i as u64,
            ColdBudget {
                max_restarts: 10_000,
                time_limit: Some(CAP),
            },
        );
        t_ours.push(t0.elapsed().as_secs_f64() * 1e6);
        if let Ok(sol) = r {
            let (dp, da) = errors(&ours.chain().end_pose(&sol.q), target);
            assert!(dp <= TOL && da <= TOL, "our success must be real");
            ok_ours += 1;
        }
    }
    // k: random restarts with the same cap.
    let mut t_k = Vec::with_capacity(n);
    let mut ok_k = 0;
    let mut rng = Rng(0xBEEF);
    for target in &targets {
        let t0 = Instant::now();
        let mut ok = false;
        while t0.elapsed() < CAP {
            let q0 = rng.q(ours.chain());
            if theirs.solve_from(q0.as_slice(), target) {
                ok = true;
                break;
            }
        }
        t_k.push(t0.elapsed().as_secs_f64() * 1e6);
        ok_k += usize::from(ok);
    }
    println!("cold {name}: ours {ok_ours}/{n}, k {ok_k}/{n}");
    vec![
        ColdRow {
            solver: "teleop-ik",
            success: ok_ours as f64 / n as f64,
            p50_us: pct(&mut t_ours, 0.5),
            p99_us: pct(&mut t_ours, 0.99),
        },
        ColdRow {
            solver: "k JacobianIkSolver",
            success: ok_k as f64 / n as f64,
            p50_us: pct(&mut t_k, 0.5),
            p99_us: pct(&mut t_k, 0.99),
        },
    ]
}

/// Square path (0.2 m side, 0.1 m/s) with sharp corners around `center`, slowly
/// rotating: the shape of the thesis's Fig. 7.12 trajectory.
fn wrist_path(center: &Isometry3<f64>, t: f64) -> Isometry3<f64> {
    let side = 0.2;
    let speed = 0.1;
    let s = (t * speed).rem_euclid(4.0 * side);
    let edge = ((s / side).floor() as usize).min(3);
    let f = (s - edge as f64 * side) / side;
    let h = side / 2.0;
    let c = [
        Vector3::new(-h, -h, 0.0),
        Vector3::new(h, -h, 0.0),
        Vector3::new(h, h, 0.0),
        Vector3::new(-h, h, 0.0),
    ];
    let p = c[edge] + (c[(edge + 1) % 4] - c[edge]) * f;
    let w = 10f64.to_radians();
    let rot = UnitQuaternion::from_euler_angles(
        w * (0.5 * t).sin(),
        w * (0.4 * t).sin(),
        w * (0.3 * t).sin(),
    );
    Isometry3::from_parts(
        Translation3::from(center.translation.vector + center.rotation * p),
        center.rotation * rot,
    )
}

struct TrackRow {
    solver: &'static str,
    rate_hz: f64,
    steps: usize,
    p50_us: f64,
    p99_us: f64,
    mean_pos_mm: f64,
    max_pos_mm: f64,
    max_ang_deg: f64,
    failures: usize,
}

fn tracking<const N: usize>(
    ours: &Solver<N>,
    theirs: &KArm,
    q_center: &SVector<f64, N>,
    rate_hz: f64,
    duration_s: f64,
) -> Vec<TrackRow> {
    let center = ours.chain().end_pose(q_center);
    let steps = (duration_s * rate_hz) as usize;
    let targets: Vec<Isometry3<f64>> = (0..steps)
        .map(|i| wrist_path(&center, i as f64 / rate_hz))
        .collect();
    // Start both on the path's first pose.
    let q0 = ours
        .solve_cold(
            &[Goal::pose(targets[0])],
            Some(q_center),
            1,
            ColdBudget::default(),
        )
        .expect("start pose")
        .q;

    let mut rows = Vec::new();
    // Ours.
    let mut q = q0;
    let (mut t, mut ep, mut ea, mut fails) = (Vec::new(), Vec::new(), Vec::new(), 0);
    for target in &targets {
        let goals = [Goal::pose(*target)];
        let t0 = Instant::now();
        let r = ours.solve_tracking(&goals, &q);
        t.push(t0.elapsed().as_secs_f64() * 1e6);
        q = match r {
            Ok(s) => s.q,
            Err(e) => {
                fails += 1;
                e.best.q
            }
        };
        let (dp, da) = errors(&ours.chain().end_pose(&q), target);
        ep.push(dp);
        ea.push(da);
    }
    rows.push(track_row("teleop-ik", rate_hz, &mut t, &ep, &ea, fails));
    // k, warm-started from its own last solution.
    theirs.arm.set_joint_positions_clamped(q0.as_slice());
    let (mut t, mut ep, mut ea, mut fails) = (Vec::new(), Vec::new(), Vec::new(), 0);
    for target in &targets {
        let q_prev = theirs.q();
        let t0 = Instant::now();
        let ok = theirs.solve_from(&q_prev, target);
        t.push(t0.elapsed().as_secs_f64() * 1e6);
        fails += usize::from(!ok);
        theirs.arm.update_transforms();
        let (dp, da) = errors(&from_k(&theirs.arm.end_transform()), target);
        ep.push(dp);
        ea.push(da);
    }
    rows.push(track_row(
        "k JacobianIkSolver",
        rate_hz,
        &mut t,
        &ep,
        &ea,
        fails,
    ));
    rows
}

fn track_row(
    solver: &'static str,
    rate_hz: f64,
    t: &mut [f64],
    ep: &[f64],
    ea: &[f64],
    failures: usize,
) -> TrackRow {
    TrackRow {
        solver,
        rate_hz,
        steps: t.len(),
        p50_us: pct(t, 0.5),
        p99_us: pct(t, 0.99),
        mean_pos_mm: ep.iter().sum::<f64>() / ep.len() as f64 * 1e3,
        max_pos_mm: ep.iter().copied().fold(0.0, f64::max) * 1e3,
        max_ang_deg: ea.iter().copied().fold(0.0, f64::max).to_degrees(),
        failures,
    }
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let n = if quick { 1_000 } else { 10_000 };
    let ur5 = Solver::new(
        robots::ur5_flange_chain().expect("ur5"),
        IkSettings::default(),
    );
    let pr2 = Solver::new(robots::pr2_arm_chain().expect("pr2"), IkSettings::default());
    let k_ur5 = KArm::new("ur5.urdf", robots::ur5::FLANGE);
    let k_pr2 = KArm::new("pr2_right_arm_shadow.urdf", robots::pr2::WRIST);

    println!(
        "## Cold IK: {n} random reachable poses per robot, success at 1e-5 m / 1e-5 rad, 5 ms cap\n"
    );
    println!("| robot | solver | success | p50 | p99 |\n|---|---|---|---|---|");
    for (name, rows) in [
        ("UR5 (6)", cold("UR5", &ur5, &k_ur5, n)),
        ("PR2 arm + wrist (7)", cold("PR2", &pr2, &k_pr2, n)),
    ] {
        for r in rows {
            println!(
                "| {name} | {} | {:.2} % | {:.1} us | {:.1} us |",
                r.solver,
                r.success * 100.0,
                r.p50_us,
                r.p99_us
            );
        }
    }

    println!(
        "\n## Tracking: square wrist path with sharp corners (0.2 m side, 0.1 m/s, +-10 deg rotation), warm start\n"
    );
    println!(
        "| robot | solver | rate | steps | p50 | p99 | mean pos err | max pos err | max ang err | failed steps |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    let ur5_center = SVector::<f64, 6>::from_column_slice(&[0.0, -1.2, 1.6, -1.9, -1.57, 0.0]);
    let pr2_center = SVector::<f64, 7>::from_column_slice(&[-0.6, 0.3, -1.0, -1.2, 0.0, -0.1, 0.0]);
    let duration = if quick { 4.0 } else { 8.0 };
    for rate in [30.0, 1000.0] {
        for (name, rows) in [
            ("UR5", tracking(&ur5, &k_ur5, &ur5_center, rate, duration)),
            ("PR2", tracking(&pr2, &k_pr2, &pr2_center, rate, duration)),
        ] {
            for r in rows {
                println!(
                    "| {name} | {} | {} Hz | {} | {:.1} us | {:.1} us | {:.4} mm | {:.4} mm | {:.4} deg | {} |",
                    r.solver,
                    r.rate_hz,
                    r.steps,
                    r.p50_us,
                    r.p99_us,
                    r.mean_pos_mm,
                    r.max_pos_mm,
                    r.max_ang_deg,
                    r.failures
                );
            }
        }
    }
}
