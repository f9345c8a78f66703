//! The adaptive hand law's forgetting factor `γ = α / (1 + β ε²)` on the simulated hand,
//! through the node's supervisor and the hardware safety layer (the scenario harness):
//! for each `(α, β)`, the touching task's peak force against the position mode's (thesis
//! Fig. 8.7, goal <= 0.5x) and the grasped thumb's error under the -0.3 N m load ramp
//! (the screw-pouring stand-in). The trade-off behind the default `β`.
//!
//! `cargo run --release -p teleop-system-tests --example forgetting_sweep`

use teleop_control::hand::{HandControllerConfig, HandMode, PerJoint};
use teleop_sim::{ExternalLoad, LoadTarget};
use teleop_system_tests::scenarios::{
    GraspRun, GraspSample, TouchingRun, grasp_run, touching_trials,
};

fn mean_over(s: &[GraspSample], t0: f64, t1: f64, f: impl Fn(&GraspSample) -> f64) -> f64 {
    let v: Vec<f64> = s
        .iter()
        .filter(|x| x.time_s >= t0 && x.time_s <= t1)
        .map(f)
        .collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn main() -> anyhow::Result<()> {
    let touching = TouchingRun::default();
    let mode = |m| HandControllerConfig {
        mode: m,
        ..HandControllerConfig::default()
    };
    let position = touching_trials(&touching, &mode(HandMode::Position), 10)?;
    let mut load = ExternalLoad::screw_pouring(3.0);
    load.target = LoadTarget::JointTorque {
        joint: "rh_THJ4".into(),
        torque_nm: -0.3,
    };
    let mut grasp = GraspRun::default();
    grasp.cup.loads = vec![load];
    println!(
        "| alpha (1/s) | beta (s^2/rad^2) | touching max | / position | touching mean | THJ4 error before the load | at 7-9 s | peak | THJ4 effort before | at 7-9 s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (alpha, beta) in [
        (0.0, 0.0),
        (1.0, 0.0),
        (1.0, 1.0),
        (1.0, 4.0),
        (1.0, 16.0),
        (2.0, 4.0),
    ] {
        let mut c = mode(HandMode::Adaptive);
        c.adaptive.forgetting_rate_per_s = PerJoint::Uniform(alpha);
        c.adaptive.forgetting_error_scale_s2_rad2 = PerJoint::Uniform(beta);
        let t = touching_trials(&touching, &c, 10)?;
        let s = grasp_run(&grasp, &c)?;
        let err = |x: &GraspSample| (x.joint_rad - x.joint_target_rad).abs();
        let peak = s
            .iter()
            .filter(|x| x.time_s >= 3.0)
            .map(err)
            .fold(0.0, f64::max);
        println!(
            "| {alpha} | {beta} | {:.2} N | {:.2}x | {:.2} N | {:.4} rad | {:.4} rad | {:.4} rad | {:.3} N m | {:.3} N m |",
            t.max_force_n,
            t.max_force_n / position.max_force_n,
            t.mean_force_n,
            mean_over(&s, 2.5, 2.99, err),
            mean_over(&s, 7.0, 9.0, err),
            peak,
            mean_over(&s, 2.5, 2.99, |x| x.joint_effort_nm),
            mean_over(&s, 7.0, 9.0, |x| x.joint_effort_nm),
        );
    }
    println!(
        "position mode: touching max {:.2} N, mean {:.2} N",
        position.max_force_n, position.mean_force_n
    );
    Ok(())
}
