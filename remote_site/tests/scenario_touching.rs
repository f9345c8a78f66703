//! Evidence (thesis Fig. 8.7): the "mouse touching" task on the simulated hand. The
//! commanded FF posture lies 0.15 rad (FFJ3) beyond the surface contact (plus a small
//! per-trial perturbation); the hand controller runs at 1 kHz on the simulated joints in position,
//! fixed-gain impedance and adaptive modes; 10 trials per mode. Prints the figures
//! (`cargo test --release -p teleop-remote-site --test scenario_touching -- --nocapture`).
#![allow(clippy::unwrap_used)]

use nalgebra::SVector;
use teleop_control::hand::{HandControllerConfig, HandMode, HandOutput, ShadowHandController};
use teleop_remote_site::hardware::{FINGER_JOINTS, HandCommand};
use teleop_remote_site::sim::{TouchingTaskConfig, World};

fn idx(name: &str) -> usize {
    FINGER_JOINTS.iter().position(|j| *j == name).unwrap()
}

struct Trial {
    max_n: f64,
    mean_n: f64,
}

fn trial(mode: HandMode, k: usize) -> Trial {
    let config = TouchingTaskConfig::default();
    let mut w = World::touching_task(&config).unwrap();
    let cfg = HandControllerConfig {
        mode,
        ..HandControllerConfig::default()
    };

    let mut ctrl = ShadowHandController::new(cfg).unwrap();
    let mut target = SVector::<f64, 17>::from(config.hand_posture_rad);
    // Small deterministic perturbations of the commanded posture, as in the thesis's
    // repeated trials.
    let p = (k as f64 - 4.5) * 0.01;
    target[idx("rh_FFJ3")] += 0.15 + p;
    target[idx("rh_FFJ2")] += 0.1 - p / 2.0;
    let dt = 0.001;
    let mut forces = Vec::new();
    for step in 0..2000 {
        let s = w.hand_state();
        let out = ctrl
            .step(dt, &s.position_rad, &s.velocity_rad_s, &target)
            .unwrap();
        let cmd = match out {
            HandOutput::Effort(t) => HandCommand::Effort(t),
            HandOutput::Position(q) => HandCommand::Position(q),
        };
        w.command_hand(&cmd);
        w.step(dt);
        if step >= 200 {
            forces.push(w.fingertip_force_n()[0]);
        }
    }
    Trial {
        max_n: forces.iter().copied().fold(0.0, f64::max),
        mean_n: forces.iter().sum::<f64>() / forces.len() as f64,
    }
}

#[test]
fn adaptive_control_touches_more_gently_than_position_and_fixed_gain_control() {
    let mut summary = Vec::new();
    for (mode, label) in [
        (HandMode::Position, "position"),
        (HandMode::FixedImpedance, "fixed impedance"),
        (HandMode::Adaptive, "adaptive"),
    ] {
        let trials: Vec<Trial> = (0..10).map(|k| trial(mode, k)).collect();
        let max = trials.iter().map(|t| t.max_n).fold(0.0, f64::max);
        let mean = trials.iter().map(|t| t.mean_n).sum::<f64>() / 10.0;
        let spread = trials
            .iter()
            .map(|t| t.mean_n)
            .fold(f64::INFINITY, f64::min);
        println!(
            "{label:16} max {max:.2} N, mean {mean:.2} N, lowest trial mean {spread:.2} N (10 trials, 1.8 s of contact each)"
        );
        summary.push((max, mean));
    }
    let (pos_max, pos_mean) = summary[0];
    let (fix_max, fix_mean) = summary[1];
    let (ada_max, ada_mean) = summary[2];
    println!(
        "adaptive / position: max {:.2}x, mean {:.2}x (thesis goal for the max: <= 0.5x, not yet met)",
        ada_max / pos_max,
        ada_mean / pos_mean
    );
    assert!(
        summary.iter().all(|(m, _)| *m > 0.0),
        "every mode touches the surface"
    );
    // What holds today: adaptive touches more gently than both other modes.
    assert!(
        ada_max < fix_max && ada_max < pos_max,
        "max: adaptive {ada_max} N, fixed {fix_max} N, position {pos_max} N"
    );
    assert!(
        ada_mean < fix_mean && ada_mean < pos_mean,
        "mean: adaptive {ada_mean} N, fixed {fix_mean} N, position {pos_mean} N"
    );
}
