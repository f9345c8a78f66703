//! One Shadow hand control period at the robot site, 17 finger joints, adaptive mode:
//! the supervisor (target message check + watchdog + gravity compensation from the
//! URDF masses + control law) against the bare control law in the same run, on states
//! recorded from the simulated hand closing on the cup (so contacts, errors and
//! adaptation are realistic).
//!
//! Also the hardware safety layer's step on the supervisor's commands (what
//! `remote_sim` adds per period).
//!
//! `cargo bench --workspace --bench hand_step`

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::Instant;

use nalgebra::SVector;
use teleop_control::OperatorSample;
use teleop_control::hand::{HandControllerConfig, HandMode, ShadowHandController};
use teleop_hardware::HandState;
use teleop_hardware::safety::{HandLimits, HandSafety, HandSafetyConfig};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_msgs::JointState;
use teleop_remote_site::hand_controller::{HandSupervisor, HandSupervisorConfig};
use teleop_sim::{CupGraspConfig, World};

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    const DT: f64 = 0.001;
    let config = CupGraspConfig::default();
    let target = SVector::<f64, 17>::from(config.closed_posture_rad);
    // Record 5 s of states of the hand closing on the cup under adaptive control.
    let mut w = World::cup_grasp(&config).unwrap();
    let mut c = ShadowHandController::new(HandControllerConfig::default()).unwrap();
    let mut states: Vec<HandState> = Vec::with_capacity(5000);
    for _ in 0..5000 {
        let s = w.hand_state();
        let out = c
            .step(DT, &s.position_rad, &s.velocity_rad_s, &target)
            .unwrap();
        w.command_hand(&teleop_hardware::HandCommand::from(out));
        w.step(DT);
        states.push(s);
    }
    let msg = JointState {
        name: SHADOW_FINGER_JOINTS
            .iter()
            .map(|s| (*s).to_owned())
            .collect(),
        position: target.iter().copied().collect(),
        ..Default::default()
    };
    let (lo, hi) = HandSupervisor::shadow_hand_limits().unwrap();
    let arm = SVector::<f64, 7>::from(config.arm_posture_rad);
    println!("| step (17 joints, adaptive) | periods | p50 | p99 |\n|---|---|---|---|");
    for round in 0..2 {
        let mut sup = HandSupervisor::new(HandSupervisorConfig::default(), lo, hi).unwrap();
        // The operator's switch heard released once (a supervisor does not take a
        // switch held since before its start for a press); not timed.
        let released = Some(OperatorSample::released(-DT));
        sup.step(-DT, released, true, &states[0], Some(&arm));
        let mut bare = ShadowHandController::new(HandControllerConfig {
            mode: HandMode::Adaptive,
            ..HandControllerConfig::default()
        })
        .unwrap();
        let (mut t_sup, mut t_target, mut t_bare) = (Vec::new(), Vec::new(), Vec::new());
        let mut t_safety = Vec::new();
        let mut safety =
            HandSafety::new(HandLimits::shadow().unwrap(), HandSafetyConfig::default()).unwrap();
        for (k, s) in states.iter().enumerate() {
            let t = k as f64 * DT;
            let t0 = Instant::now();
            sup.accept_target(&msg, t).unwrap();
            t_target.push(t0.elapsed().as_secs_f64() * 1e6);
            let enable = Some(OperatorSample {
                received_s: t,
                clutch: true,
                enable: true,
                motion_scale: 1.0,
            });
            let t0 = Instant::now();
            let out = sup.step(t, enable, true, s, Some(&arm));
            t_sup.push(t0.elapsed().as_secs_f64() * 1e6);
            let t0 = Instant::now();
            let limited = safety.step(t, Some(&out.command), Some(s));
            t_safety.push(t0.elapsed().as_secs_f64() * 1e6);
            std::hint::black_box((out, limited));
            let t0 = Instant::now();
            let out = bare.step(DT, &s.position_rad, &s.velocity_rad_s, &target);
            t_bare.push(t0.elapsed().as_secs_f64() * 1e6);
            std::hint::black_box(out.unwrap());
        }
        if round == 0 {
            continue; // warm-up
        }
        let n = states.len();
        for (name, v) in [
            (
                "supervisor step (watchdog + gravity model + law)",
                &mut t_sup,
            ),
            ("target message check (by name, limits)", &mut t_target),
            ("hardware safety step (remote_sim)", &mut t_safety),
            ("baseline: bare adaptive law", &mut t_bare),
        ] {
            println!(
                "| {name} | {n} | {:.2} us | {:.2} us |",
                pct(v, 0.5),
                pct(v, 0.99)
            );
        }
    }
}
