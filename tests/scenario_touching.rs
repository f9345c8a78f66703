//! Evidence (thesis Fig. 8.7): the "mouse touching" task on the simulated hand. The
//! commanded FF posture lies 0.15 rad (FFJ3) beyond the surface contact (plus a small
//! per-trial perturbation); the hand controller runs at 1 kHz on the simulated joints
//! in position, fixed-gain impedance and adaptive modes, with the same 2 N m effort
//! limit in the controller and the simulated motors; 10 trials per mode. Prints the
//! figures (`cargo test --release --workspace --test scenario_touching -- --nocapture`).
#![allow(clippy::unwrap_used)]

use teleop_control::hand::{HandControllerConfig, HandMode, PerJoint};
use teleop_system_tests::scenarios::{SimEngine, TouchSummary, TouchingRun, touching_trials};

fn summary(mode: HandMode, forgetting_per_s: Option<f64>) -> TouchSummary {
    let mut cfg = HandControllerConfig {
        mode,
        ..HandControllerConfig::default()
    };
    if let Some(a) = forgetting_per_s {
        cfg.adaptive.forgetting_rate_per_s = PerJoint::Uniform(a);
    }
    let s = touching_trials(&TouchingRun::default(), &cfg, 10).unwrap();
    println!(
        "{:32} max {:6.2} N, mean {:6.2} N, contact-point spread {:.2} mm, touched {}/10",
        format!(
            "{mode:?}{}",
            forgetting_per_s.map_or(String::new(), |a| format!(" (forgetting {a}/s)"))
        ),
        s.max_force_n,
        s.mean_force_n,
        s.contact_spread_m * 1e3,
        s.touched
    );
    s
}

#[test]
fn adaptive_control_peaks_at_most_half_the_position_mode_force() {
    let pos = summary(HandMode::Position, None);
    let fixed = summary(HandMode::FixedImpedance, None);
    let ada = summary(HandMode::Adaptive, None);
    let printed = summary(HandMode::Adaptive, Some(0.0));
    println!(
        "adaptive / position: max {:.2}x, mean {:.2}x (this project's goal for the max: <= 0.5x; Fig. 8.7(d): \"significantly lower\"); law as printed (no forgetting): max {:.2}x",
        ada.max_force_n / pos.max_force_n,
        ada.mean_force_n / pos.mean_force_n,
        printed.max_force_n / pos.max_force_n,
    );
    for s in [&pos, &fixed, &ada, &printed] {
        assert_eq!(s.touched, 10, "every trial touches the surface: {s:?}");
        assert!(s.max_force_n > 0.5, "{s:?}");
    }
    // The thesis's finding, with the default (forgetting) adaptive controller.
    assert!(
        ada.max_force_n <= 0.5 * pos.max_force_n,
        "adaptive max {} N vs position max {} N",
        ada.max_force_n,
        pos.max_force_n
    );
    // Adaptive is the gentlest of the three, in peak and mean.
    assert!(ada.max_force_n < fixed.max_force_n && ada.mean_force_n < fixed.mean_force_n);
    assert!(ada.mean_force_n < pos.mean_force_n);
    // The law as printed is gentler than position control too, but less so.
    assert!(printed.max_force_n < pos.max_force_n && printed.max_force_n >= ada.max_force_n);
}

/// The same touching task in MuJoCo (the mouse's sphere welded in place, the robot with
/// MuJoCo's model mismatch): printed beside the joint-space figures
/// (`cargo test --release --workspace --test scenario_touching -- --nocapture`).
#[test]
fn in_mujoco_the_touching_task_compares() {
    let run = TouchingRun {
        engine: SimEngine::Mujoco,
        ..TouchingRun::default()
    };
    let mut out = Vec::new();
    for mode in [
        HandMode::Position,
        HandMode::FixedImpedance,
        HandMode::Adaptive,
    ] {
        let cfg = HandControllerConfig {
            mode,
            ..HandControllerConfig::default()
        };
        let s = touching_trials(&run, &cfg, 10).unwrap();
        println!(
            "MuJoCo {:24} max {:6.2} N, mean {:6.2} N, contact-point spread {:.2} mm, touched {}/10",
            format!("{mode:?}"),
            s.max_force_n,
            s.mean_force_n,
            s.contact_spread_m * 1e3,
            s.touched
        );
        out.push(s);
    }
    let (pos, fixed, ada) = (out[0], out[1], out[2]);
    println!(
        "MuJoCo adaptive / position: max {:.2}x, mean {:.2}x",
        ada.max_force_n / pos.max_force_n,
        ada.mean_force_n / pos.mean_force_n
    );
    // What holds in MuJoCo as in the joint-space world: every trial touches, and
    // adaptive is the gentlest of the three in peak and mean. (This project's 0.5x goal,
    // its reading of Fig. 8.7(d)'s "significantly lower", is not met in MuJoCo: 0.59x,
    // docs/remote-site.md.)
    for s in &out {
        assert_eq!(s.touched, 10, "every trial touches the surface: {s:?}");
    }
    assert!(ada.max_force_n < fixed.max_force_n && fixed.max_force_n < pos.max_force_n);
    assert!(ada.mean_force_n < fixed.mean_force_n && fixed.mean_force_n < pos.mean_force_n);
}
