//! Evidence: relative tracking through the clutch on the simulated PR2 arm (its own
//! perturbed velocity lags, velocity/acceleration limits, noisy encoders), through the
//! hardware safety layer `remote_sim` wraps it in. The operator's wrist traces a square
//! with sharp corners (the shape of the thesis's Fig. 7.12); the error is the palm's
//! distance to the scaled operator motion applied to the robot's reference pose in the
//! base-aligned frame. Prints the figures
//! (`cargo test --release --workspace --test scenario_tracking -- --nocapture`).
#![allow(clippy::unwrap_used)]

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use teleop_hardware::safety::ArmSafety;
use teleop_hardware::{ArmHardware, SafeArm};
use teleop_kinematics::robots;
use teleop_remote_site::arm_controller::{
    ArmController, ArmControllerConfig, ArmInputs, OperatorSample, RegularizationReference,
    WristSample,
};
use teleop_sim::{WORKING_POSTURE_RAD, World, WorldConfig};
use teleop_sim_nodes::remote_sim::SimSafetyConfig;

/// Square path with sharp corners in the tracker frame, side `side_m`, at
/// `speed_m_s`, with a slow wrist rotation.
fn operator(t: f64, side_m: f64, speed_m_s: f64) -> Isometry3<f64> {
    let s = (t * speed_m_s).rem_euclid(4.0 * side_m);
    let edge = ((s / side_m).floor() as usize).min(3);
    let f = (s - edge as f64 * side_m) / side_m;
    let c = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(side_m, 0.0, 0.0),
        Vector3::new(side_m, side_m, 0.0),
        Vector3::new(0.0, side_m, 0.0),
    ];
    let p = c[edge] + (c[(edge + 1) % 4] - c[edge]) * f;
    let w = 8f64.to_radians();
    Isometry3::from_parts(
        Translation3::from(Vector3::new(0.45, -0.1, 1.0) + p),
        UnitQuaternion::from_euler_angles(w * (0.3 * t).sin(), w * (0.2 * t).sin(), 0.0),
    )
}

#[derive(Debug, Clone, Copy)]
struct Figures {
    mean_mm: f64,
    max_mm: f64,
    rms_mm: f64,
    /// Periods in which the hardware safety layer cut the tool speed, of `periods`.
    tool_speed_trims: u64,
    periods: u64,
}

/// `duration_s` of tracking at the controller's rate, motion scale `scale`, the
/// operator's square `side_m` at `speed_m_s`.
fn run(
    cfg: ArmControllerConfig,
    scale: f64,
    side_m: f64,
    speed_m_s: f64,
    duration_s: f64,
) -> Figures {
    let dt = 1.0 / cfg.rate_hz;
    let mut world = World::new(WorldConfig::default()).unwrap();
    world.set_arm_position(&SVector::from(WORKING_POSTURE_RAD));
    let chain = robots::pr2_arm_chain().unwrap();
    let (world, sim_arm, _hand) = teleop_sim::share(world);
    let safety = ArmSafety::new(chain.clone(), SimSafetyConfig::default().arm).unwrap();
    let mut arm = SafeArm::new(sim_arm, safety);
    let mut ctrl = ArmController::new(chain.clone(), cfg).unwrap();
    // The controller hears the pedals released once (as at any start: a clutch held
    // since before it started is not a press); the clutch is pressed from the first
    // period of the run.
    let released = ArmInputs {
        operator: Some(OperatorSample {
            received_s: 0.0,
            clutch: false,
            enable: true,
            motion_scale: scale,
        }),
        wrist: None,
        operator_site_alive: true,
        hand_alive: true,
        commander_conflict: false,
    };
    let stopped = ctrl.step(0.0, &released, &arm.read(0.0).unwrap()).stopped;
    assert!(stopped.is_some(), "nothing moves before the clutch");
    let mut t = 0.0;
    let mut errors = Vec::new();
    let mut refs: Option<(Isometry3<f64>, Isometry3<f64>)> = None;
    let steps = (duration_s / dt).round() as usize;
    for _ in 0..steps {
        t += dt;
        let human = operator(t, side_m, speed_m_s);
        let state = arm.read(t).unwrap();
        let inputs = ArmInputs {
            operator: Some(OperatorSample {
                received_s: t,
                clutch: true,
                enable: true,
                motion_scale: scale,
            }),
            wrist: Some(WristSample {
                received_s: t,
                pose: human,
            }),
            operator_site_alive: true,
            hand_alive: true,
            commander_conflict: false,
        };
        let out = ctrl.step(t, &inputs, &state);
        assert!(out.stopped.is_none(), "{:?}", out.stopped);
        if refs.is_none() {
            let w = world.lock().unwrap();
            refs = Some((human, chain.end_pose(&w.arm_position_rad())));
        }
        arm.write(t, &out.command).unwrap();
        let mut w = world.lock().unwrap();
        w.step(dt);
        let (h_ref, r_ref) = refs.unwrap();
        let expected = r_ref.translation.vector
            + (human.translation.vector - h_ref.translation.vector) * scale;
        let palm = chain.end_pose(&w.arm_position_rad());
        errors.push((palm.translation.vector - expected).norm());
    }
    // The safety layer does not change the controller's commands in normal operation:
    // the controller's own Cartesian limit (0.2 m/s) stays under the layer's tool-speed
    // cap (callers check `tool_speed_trims`; only the fast square's instant corners
    // reach the cap).
    let c = arm.safety().counters();
    assert_eq!(
        c.get(teleop_hardware::safety::Intervention::Velocity),
        0,
        "{c:?}"
    );
    println!(
        "  hardware safety layer: {} commands, acceleration limited in {} periods",
        c.commands,
        c.get(teleop_hardware::safety::Intervention::Acceleration)
    );
    let n = errors.len() as f64;
    Figures {
        tool_speed_trims: c.get(teleop_hardware::safety::Intervention::ToolSpeed),
        periods: c.periods,
        mean_mm: errors.iter().sum::<f64>() / n * 1e3,
        max_mm: errors.iter().copied().fold(0.0, f64::max) * 1e3,
        rms_mm: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt() * 1e3,
    }
}

fn at_rate(rate_hz: f64) -> ArmControllerConfig {
    ArmControllerConfig {
        rate_hz,
        ..ArmControllerConfig::default()
    }
}

/// The thesis's IK and velocity-law gains (regularization 0.5, `d1` 0.7, 3 /s), which
/// the defaults replaced (docs/local-site.md, "Tuning the arms").
fn thesis_gains(rate_hz: f64) -> ArmControllerConfig {
    ArmControllerConfig {
        regularization_weight: 0.5,
        d1: 0.7,
        feedback_gain_per_s: 3.0,
        ..at_rate(rate_hz)
    }
}

fn print(label: &str, f: Figures) {
    println!(
        "{label:<62} mean {:6.2} mm  rms {:6.2} mm  max {:6.2} mm  tool speed cut in {} of {} periods",
        f.mean_mm, f.rms_mm, f.max_mm, f.tool_speed_trims, f.periods
    );
    if !label.starts_with("defaults, square") {
        assert_eq!(
            f.tool_speed_trims, 0,
            "{label}: the safety layer cut the tool speed"
        );
    }
}

/// The thesis's fine-task scale (1/3) on a 20 cm square and full scale on a square of
/// the same robot-side size; operator at 5 cm/s resp. 1.7 cm/s (one lap in 16 s).
#[test]
fn relative_tracking_error_through_the_clutch() {
    for (scale, side, speed, label) in [
        (1.0 / 3.0, 0.2, 0.05, "1/3"),
        (1.0, 0.2 / 3.0, 0.05 / 3.0, "1"),
    ] {
        let f = run(at_rate(30.0), scale, side, speed, 16.0);
        print(&format!("defaults, 30 Hz, motion scale {label}"), f);
        let thesis = run(thesis_gains(30.0), scale, side, speed, 16.0);
        print(
            &format!("thesis gains, 30 Hz, motion scale {label}"),
            thesis,
        );
        assert!(
            f.mean_mm <= 5.0,
            "mean error {} mm at scale {label}",
            f.mean_mm
        );
        // The defaults follow more closely than the thesis's gains.
        assert!(
            f.mean_mm < 0.5 * thesis.mean_mm,
            "defaults {} mm vs thesis gains {} mm",
            f.mean_mm,
            thesis.mean_mm
        );
        assert!(
            f.max_mm <= 30.0,
            "max error {} mm at scale {label}",
            f.max_mm
        );
    }
}

/// The law's gains are per second: the same behaviour at 30 Hz and 1 kHz. With the
/// earlier per-period `d2` (0.1 per period = 100 /s at 1 kHz) it was not. Shown with
/// the thesis's gains, whose lag dominates the error (with the defaults the error is
/// under a millimetre at either rate, printed).
#[test]
fn tracking_is_the_same_at_30_hz_and_1_khz() {
    let (scale, side, speed) = (1.0 / 3.0, 0.2, 0.05);
    let slow = run(thesis_gains(30.0), scale, side, speed, 16.0);
    let fast = run(thesis_gains(1000.0), scale, side, speed, 16.0);
    let per_period = run(
        ArmControllerConfig {
            feedback_gain_per_s: 0.1 * 1000.0,
            ..thesis_gains(1000.0)
        },
        scale,
        side,
        speed,
        16.0,
    );
    print("thesis gains, 30 Hz (gain 3 /s)", slow);
    print("thesis gains, 1 kHz (gain 3 /s)", fast);
    print(
        "thesis gains, 1 kHz with the per-period d2 = 0.1 (100 /s)",
        per_period,
    );
    let default_slow = run(at_rate(30.0), scale, side, speed, 16.0);
    let default_fast = run(at_rate(1000.0), scale, side, speed, 16.0);
    print("defaults, 30 Hz", default_slow);
    print("defaults, 1 kHz", default_fast);
    assert!(default_slow.mean_mm < 1.0 && default_fast.mean_mm < 1.0);
    let ratio = fast.mean_mm / slow.mean_mm;
    assert!(
        (0.75..=1.33).contains(&ratio),
        "1 kHz / 30 Hz mean error {ratio}"
    );
    // The per-period gain is 33x stiffer at 1 kHz: the arm hugs the IK solution
    // more tightly than at 30 Hz (the rest of the error is the IK's smoothing).
    assert!(
        per_period.mean_mm < 0.8 * fast.mean_mm,
        "per-period gain {} mm vs {} mm",
        per_period.mean_mm,
        fast.mean_mm
    );
}

/// The thesis's IK comparison (Figs. 7.12-7.13): regularization weight 0.5 vs 1
/// (bio_ik terms), toward the previous solution (default) and toward the measured
/// joints (as the thesis text reads), on a faster square (10 cm/s) where smoothing
/// shows at the corners; with the thesis's velocity law (`d1` 0.7, 3 /s), as it was
/// compared there. The defaults (weight 0.2, `d1` 1, 10 /s) on the same square are
/// printed and compared.
#[test]
fn regularization_weight_and_reference_compared() {
    let (scale, side, speed) = (1.0, 0.2, 0.1);
    let mut results = Vec::new();
    for reference in [
        RegularizationReference::PreviousSolution,
        RegularizationReference::MeasuredJoints,
    ] {
        for weight in [0.5, 1.0] {
            let cfg = ArmControllerConfig {
                regularization_weight: weight,
                regularization_reference: reference,
                ..thesis_gains(30.0)
            };
            let f = run(cfg, scale, side, speed, 8.0);
            print(
                &format!("{reference:?}, weight {weight}, square 0.2 m at 0.1 m/s"),
                f,
            );
            results.push((reference, weight, f));
        }
    }
    let get = |r, w| {
        results
            .iter()
            .find(|(rr, ww, _)| *rr == r && *ww == w)
            .unwrap()
            .2
    };
    // Weight 1 smooths more than 0.5 (the thesis's finding), for either reference.
    for r in [
        RegularizationReference::PreviousSolution,
        RegularizationReference::MeasuredJoints,
    ] {
        assert!(get(r, 1.0).max_mm > get(r, 0.5).max_mm, "{r:?}");
    }
    // Pulling toward the lagging measured joints costs accuracy.
    assert!(
        get(RegularizationReference::MeasuredJoints, 0.5).mean_mm
            > get(RegularizationReference::PreviousSolution, 0.5).mean_mm
    );
    let defaults = run(at_rate(30.0), scale, side, speed, 8.0);
    print("defaults, square 0.2 m at 0.1 m/s", defaults);
    // Its instant corners at 0.1 m/s are the one case here where the lighter
    // regularization swings the arm fast enough for the safety layer's tool-speed cap
    // (0.25 m/s) to cut in, in a few periods.
    assert!(
        defaults.tool_speed_trims * 10 <= defaults.periods,
        "{} of {} periods cut",
        defaults.tool_speed_trims,
        defaults.periods
    );
    assert!(
        defaults.mean_mm < 0.75 * get(RegularizationReference::PreviousSolution, 0.5).mean_mm,
        "defaults {} mm",
        defaults.mean_mm
    );
}
