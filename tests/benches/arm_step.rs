//! One PR2 arm controller step (filters + IK + velocity law + joint limiter) while the
//! operator moves, at 30 Hz and at 1 kHz control rates; the baseline in the same run is
//! the IK solve alone on the same targets. Also the hardware safety layer's step on the
//! controller's commands (what `remote_sim` adds per period).
//!
//! `cargo bench --workspace --bench arm_step`

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::Instant;

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion};
use teleop_hardware::ArmCommand;
use teleop_hardware::safety::ArmSafety;
use teleop_ik::{Goal, IkSettings, Solver};
use teleop_kinematics::robots;
use teleop_remote_site::arm_controller::Pr2ArmState;
use teleop_remote_site::arm_controller::{
    ArmController, ArmControllerConfig, ArmInputs, OperatorSample, WristSample,
};

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn run(rate_hz: f64, steps: usize) {
    let cfg = ArmControllerConfig {
        rate_hz,
        ..ArmControllerConfig::default()
    };
    let chain = robots::pr2_arm_chain().unwrap();
    let mut ctrl = ArmController::new(chain.clone(), cfg).unwrap();
    let ik = Solver::new(
        chain,
        IkSettings {
            tracking_iterations: 30,
            ..IkSettings::default()
        },
    );
    let dt = 1.0 / rate_hz;
    let mut q = SVector::<f64, 7>::from_column_slice(&[-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1]);
    let wrist0 = Isometry3::from_parts(
        Translation3::new(0.4, -0.2, 1.0),
        UnitQuaternion::identity(),
    );
    let mut t_ctrl = Vec::with_capacity(steps);
    let mut t_ik = Vec::with_capacity(steps);
    let mut t_safety = Vec::with_capacity(steps);
    let mut safety = ArmSafety::new(
        robots::pr2_arm_chain().unwrap(),
        teleop_sim_nodes::remote_sim::SimSafetyConfig::default().arm,
    )
    .unwrap();
    let mut q_ik = q;
    // The pedals heard released once before the run (a clutch held since before the
    // controller started is not a press); not timed.
    let released = ArmInputs {
        operator: Some(OperatorSample {
            received_s: -dt,
            clutch: false,
            enable: true,
            motion_scale: 1.0,
        }),
        wrist: None,
        operator_site_alive: true,
        hand_alive: true,
        commander_conflict: false,
    };
    let idle = Pr2ArmState {
        time_s: -dt,
        position_rad: q,
        velocity_rad_s: SVector::zeros(),
    };
    assert!(ctrl.step(-dt, &released, &idle).stopped.is_some());
    for k in 0..steps {
        let t = k as f64 * dt;
        // Operator: a 0.1 m square at 0.1 m/s in the wrist's x-y plane.
        let s = (t * 0.1).rem_euclid(0.4);
        let (x, y) = match (s / 0.1) as usize {
            0 => (s, 0.0),
            1 => (0.1, s - 0.1),
            2 => (0.3 - s, 0.1),
            _ => (0.0, 0.4 - s),
        };
        let wrist = wrist0 * Isometry3::translation(x, y, 0.0);
        let inputs = ArmInputs {
            operator: Some(OperatorSample {
                received_s: t,
                clutch: true,
                enable: true,
                motion_scale: 1.0,
            }),
            wrist: Some(WristSample {
                received_s: t,
                pose: wrist,
            }),
            operator_site_alive: true,
            hand_alive: true,
            commander_conflict: false,
        };
        let state = Pr2ArmState {
            time_s: t,
            position_rad: q,
            velocity_rad_s: SVector::zeros(),
        };
        let t0 = Instant::now();
        let out = ctrl.step(t, &inputs, &state);
        t_ctrl.push(t0.elapsed().as_secs_f64() * 1e6);
        // Baseline: the IK solve alone on the controller's own (limited) target.
        if let Some(target) = out.target {
            let cfg = ctrl.config();
            let goals = [
                Goal::Pose {
                    target,
                    weight: 1.0,
                    rotation_scale: cfg.rotation_scale,
                },
                Goal::JointRegularization {
                    reference: q_ik,
                    weight: cfg.ik_regularization_weight(dt),
                },
            ];
            let t0 = Instant::now();
            let r = ik.solve_tracking(&goals, &q_ik);
            t_ik.push(t0.elapsed().as_secs_f64() * 1e6);
            q_ik = match r {
                Ok(s) => s.q,
                Err(e) => e.best.q,
            };
        }
        let command: ArmCommand<7> = out.command;
        let t0 = Instant::now();
        let limited = safety.step(t, Some(&command), Some(&state));
        t_safety.push(t0.elapsed().as_secs_f64() * 1e6);
        q += limited.velocity_rad_s * dt;
    }
    println!(
        "| {rate_hz} Hz | {steps} | {:.2} us | {:.2} us | {:.2} us | {:.2} us | {:.2} us | {:.2} us |",
        pct(&mut t_ctrl, 0.5),
        pct(&mut t_ctrl, 0.99),
        pct(&mut t_ik, 0.5),
        pct(&mut t_ik, 0.99),
        pct(&mut t_safety, 0.5),
        pct(&mut t_safety, 0.99)
    );
}

fn main() {
    println!(
        "| control rate | steps | controller step p50 | p99 | IK alone p50 | p99 | hardware safety step p50 | p99 |\n|---|---|---|---|---|---|---|---|"
    );
    run(30.0, 3_000);
    run(1000.0, 20_000);
}
