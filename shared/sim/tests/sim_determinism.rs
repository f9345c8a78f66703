//! Same seed, same commands: bit-identical runs. Plus config round trips.
#![allow(clippy::unwrap_used)]

use nalgebra::SVector;
use teleop_hardware::{ArmState, HandCommand, HandState};
use teleop_sim::{TouchingTaskConfig, World, WorldConfig};

fn run(seed: u64) -> Vec<(ArmState<7>, HandState)> {
    let mut config = TouchingTaskConfig::default();
    config.world.seed = seed;
    config.world.noise.joint_position_std_rad = 1e-3;
    config.world.noise.joint_velocity_std_rad_s = 1e-2;
    config.world.noise.fingertip_force_std_n = 0.05;
    let mut w = World::touching_task(&config).unwrap();
    let reference = SVector::<f64, 17>::from(config.hand_posture_rad);
    let mut out = Vec::new();
    for k in 0..3000 {
        let s = f64::from(k) * 1e-3;
        let mut q = reference;
        q[1] += 0.3 * s.sin();
        q[2] += 0.3 * s.sin();
        w.command_hand(&HandCommand::Position(q));
        let mut v = SVector::<f64, 7>::zeros();
        v[2] = 0.2 * (3.0 * s).cos();
        w.command_arm(&v);
        w.step(1e-3);
        out.push((w.arm_state(), w.hand_state()));
    }
    out
}

#[test]
fn two_runs_are_bit_identical() {
    let a = run(7);
    let b = run(7);
    assert!(a.iter().zip(&b).all(|(x, y)| {
        x.0.position_rad
            .iter()
            .chain(x.1.position_rad.iter())
            .zip(y.0.position_rad.iter().chain(y.1.position_rad.iter()))
            .all(|(p, q)| p.to_bits() == q.to_bits())
            && x == y
    }));
    assert!(
        a.iter().any(|(_, h)| h.fingertip_force_n[0] > 0.0),
        "contact happened"
    );
    let c = run(8);
    assert_ne!(a, c, "another seed, other noise");
}

#[test]
fn config_round_trips_and_rejects_unknown_fields() {
    let text = serde_json::to_string(&TouchingTaskConfig::default()).unwrap();
    let back: TouchingTaskConfig = serde_json::from_str(&text).unwrap();
    assert_eq!(back, TouchingTaskConfig::default());
    let partial: WorldConfig =
        serde_json::from_str(r#"{"dt_s": 0.0005, "hand": {"substeps": 1}}"#).unwrap();
    assert_eq!(partial.dt_s, 0.0005);
    assert_eq!(partial.hand.substeps, 1);
    assert_eq!(partial.arm, WorldConfig::default().arm);
    assert!(serde_json::from_str::<WorldConfig>(r#"{"dt": 0.001}"#).is_err());
    assert!(serde_json::from_str::<WorldConfig>(r#"{"hand": {"kp": 1}}"#).is_err());
    let mut bad = WorldConfig::default();
    bad.hand.substeps = 0;
    assert!(World::new(bad).is_err());
    let bad = WorldConfig {
        dt_s: f64::NAN,
        ..WorldConfig::default()
    };
    assert!(World::new(bad).is_err());
}

/// The default world is not the nominal model: its factors are drawn from the seed,
/// within the configured fractions, and the same seed draws the same robot.
#[test]
fn the_default_robot_is_perturbed_within_its_fractions_and_repeatably() {
    use teleop_sim::PerturbationConfig;
    let a = World::new(WorldConfig::default()).unwrap();
    let b = World::new(WorldConfig::default()).unwrap();
    assert_eq!(a.perturbation(), b.perturbation());
    let p = a.perturbation();
    let f = PerturbationConfig::default();
    assert!(!p.link_mass_scale.is_empty());
    let within = |x: f64, frac: f64| (1.0 - frac..=1.0 + frac).contains(&x);
    assert!(
        p.link_mass_scale
            .iter()
            .all(|(_, s)| within(*s, f.mass_fraction))
    );
    assert!(
        p.link_mass_scale
            .iter()
            .any(|(_, s)| (s - 1.0).abs() > 0.02)
    );
    assert!(
        p.damping_scale
            .iter()
            .all(|s| within(*s, f.damping_fraction))
    );
    assert!(
        p.motor_gain_scale
            .iter()
            .all(|s| within(*s, f.motor_gain_fraction))
    );
    assert!(within(p.friction_scale, f.friction_fraction));
    assert!(
        p.arm_lag_scale
            .iter()
            .all(|s| within(*s, f.arm_lag_fraction))
    );
    // The nominal world's inertias differ from the perturbed one's.
    let n = World::new(WorldConfig::nominal()).unwrap();
    assert!((n.hand_inertia_kg_m2() - a.hand_inertia_kg_m2()).amax() > 1e-6);
    assert_eq!(n.perturbation().friction_scale, 1.0);
    // Another seed, another robot.
    let mut other = WorldConfig::default();
    other.perturbation.seed += 1;
    let c = World::new(other).unwrap();
    assert_ne!(c.perturbation(), a.perturbation());
}
