//! Evidence: relative tracking through the clutch on the simulated PR2 arm (first-order
//! joint lag, velocity/acceleration limits). The operator's wrist traces a square with
//! sharp corners (the shape of the thesis's Fig. 7.12); the controller runs at 30 Hz;
//! the error is the palm's distance to the scaled operator motion applied to the
//! robot's reference pose. Prints the figures (`cargo test --release -p
//! teleop-remote-site --test scenario_tracking -- --nocapture`).
#![allow(clippy::unwrap_used)]

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use teleop_kinematics::robots;
use teleop_remote_site::arm_controller::{
    ArmController, ArmControllerConfig, ArmInputs, OperatorSample, WristSample,
};
use teleop_sim::{World, WorldConfig};

/// Square path with sharp corners in the operator's wrist frame, side `side_m`, at
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

struct Figures {
    mean_mm: f64,
    max_mm: f64,
    rms_mm: f64,
}

fn run(scale: f64, side_m: f64, speed_m_s: f64, duration_s: f64) -> Figures {
    let cfg = ArmControllerConfig::default();
    let rate = 30.0;
    let dt = 1.0 / rate;
    let mut world = World::new(WorldConfig::default()).unwrap();
    let q0 = SVector::<f64, 7>::from_column_slice(&[-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1]);
    world.set_arm_position(&q0);
    let chain = robots::pr2_arm_chain().unwrap();
    let mut ctrl = ArmController::new(chain.clone(), cfg).unwrap();
    let mut t = 0.0;
    let mut errors = Vec::new();
    let mut refs: Option<(Isometry3<f64>, Isometry3<f64>)> = None;
    let steps = (duration_s * rate) as usize;
    for _ in 0..steps {
        t += dt;
        let human = operator(t, side_m, speed_m_s);
        let state = world.arm_state();
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
        };
        let out = ctrl.step(t, &inputs, &state);
        assert!(out.stopped.is_none(), "{:?}", out.stopped);
        if refs.is_none() {
            refs = Some((human, chain.end_pose(&state.position_rad)));
        }
        world.command_arm(&out.command.velocity_rad_s);
        world.step(dt);
        let (h_ref, r_ref) = refs.unwrap();
        let mut delta = h_ref.inverse() * human;
        delta.translation.vector *= scale;
        let expected = r_ref * delta;
        let palm = chain.end_pose(&world.arm_position_rad());
        errors.push((palm.translation.vector - expected.translation.vector).norm());
    }
    let n = errors.len() as f64;
    Figures {
        mean_mm: errors.iter().sum::<f64>() / n * 1e3,
        max_mm: errors.iter().copied().fold(0.0, f64::max) * 1e3,
        rms_mm: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt() * 1e3,
    }
}

#[test]
fn relative_tracking_error_through_the_clutch() {
    // The thesis's fine-task scale (1/3) on a 20 cm square, and full scale on a square
    // of the same robot-side size; operator at 5 cm/s resp. 1.7 cm/s (one lap in 16 s).
    for (scale, side, speed, label) in [
        (1.0 / 3.0, 0.2, 0.05, "1/3"),
        (1.0, 0.2 / 3.0, 0.05 / 3.0, "1"),
    ] {
        let f = run(scale, side, speed, 16.0);
        println!(
            "motion scale {label}: mean {:.2} mm, rms {:.2} mm, max {:.2} mm (30 Hz, 16 s, operator square {side:.3} m at {speed:.3} m/s)",
            f.mean_mm, f.rms_mm, f.max_mm
        );
        assert!(
            f.mean_mm <= 5.0,
            "mean error {} mm at scale {label}",
            f.mean_mm
        );
        assert!(
            f.max_mm <= 30.0,
            "max error {} mm at scale {label}",
            f.max_mm
        );
    }
}
