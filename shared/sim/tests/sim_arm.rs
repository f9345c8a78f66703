//! Simulated PR2 arm: lag, acceleration/velocity/position limits, command timeout.
#![allow(clippy::unwrap_used)]

use nalgebra::SVector;
use teleop_hardware::{ArmCommand, ArmHardware};
use teleop_sim::{World, WorldConfig};

fn world() -> World {
    World::new(WorldConfig::nominal()).unwrap()
}

fn joint_cmd(i: usize, v: f64) -> SVector<f64, 7> {
    let mut c = SVector::zeros();
    c[i] = v;
    c
}

/// Re-sends the command every step (as a 1 kHz loop would) for `duration_s`.
fn drive(w: &mut World, cmd: &SVector<f64, 7>, duration_s: f64) {
    let n = (duration_s / w.dt_s()).round() as usize;
    for _ in 0..n {
        w.command_arm(cmd);
        w.step_once();
    }
}

#[test]
fn small_step_follows_first_order_lag() {
    let mut w = world();
    // Upper-arm roll (joint 2): 0.1 rad/s needs 3.3 rad/s^2 at most: below the limit.
    let cmd = joint_cmd(2, 0.1);
    drive(&mut w, &cmd, 0.03);
    let v_tau = w.arm_velocity_rad_s()[2];
    assert!(
        (v_tau / 0.1 - (1.0 - (-1.0f64).exp())).abs() < 0.01,
        "{v_tau}"
    );
    drive(&mut w, &cmd, 0.27);
    assert!((w.arm_velocity_rad_s()[2] - 0.1).abs() < 1e-4);
    // Other joints untouched.
    assert_eq!(w.arm_velocity_rad_s()[0], 0.0);
}

#[test]
fn large_step_is_acceleration_then_velocity_limited() {
    let mut w = world();
    let limits = w.arm_velocity_limits_rad_s();
    // Shoulder pan towards its lower limit (-2.29 rad), far away.
    let cmd = joint_cmd(0, -10.0);
    drive(&mut w, &cmd, 0.05);
    // 8 rad/s^2 for 50 ms.
    assert!(
        (w.arm_velocity_rad_s()[0] + 0.4).abs() < 1e-9,
        "{}",
        w.arm_velocity_rad_s()[0]
    );
    drive(&mut w, &cmd, 0.4);
    assert!((w.arm_velocity_rad_s()[0] + limits[0]).abs() < 1e-12);
    assert!((limits[0] - 2.088).abs() < 1e-12, "URDF limit");
}

#[test]
fn stops_at_position_limit() {
    let mut w = world();
    // Elbow flex starts at its upper limit 0; commanding + keeps it there.
    drive(&mut w, &joint_cmd(3, 1.0), 0.2);
    assert_eq!(w.arm_position_rad()[3], 0.0);
    assert_eq!(w.arm_velocity_rad_s()[3], 0.0);
    // Shoulder lift up to its upper limit 1.3963.
    drive(&mut w, &joint_cmd(1, 2.0), 1.5);
    assert!((w.arm_position_rad()[1] - 1.3963).abs() < 1e-12);
    assert_eq!(w.arm_velocity_rad_s()[1], 0.0);
}

#[test]
fn command_timeout_brakes_the_arm() {
    let (shared, mut arm, _hand) = teleop_sim::share(world());
    let cmd = ArmCommand {
        velocity_rad_s: joint_cmd(2, 1.0),
    };
    for _ in 0..300 {
        arm.write(0.0, &cmd).unwrap();
        shared.lock().unwrap().step(0.001);
    }
    let v0 = arm.read(0.0).unwrap().velocity_rad_s[2];
    assert!((v0 - 1.0).abs() < 1e-3);
    // Silence: the command stays in force for 100 ms, then the arm brakes at 8 rad/s^2.
    shared.lock().unwrap().step(0.095);
    assert!((arm.read(0.0).unwrap().velocity_rad_s[2] - 1.0).abs() < 1e-3);
    assert!(shared.lock().unwrap().arm_command_active());
    shared.lock().unwrap().step(0.015);
    assert!(!shared.lock().unwrap().arm_command_active());
    shared.lock().unwrap().step(0.2);
    let state = arm.read(0.0).unwrap();
    assert_eq!(state.velocity_rad_s[2], 0.0);
    let q_stop = state.position_rad[2];
    shared.lock().unwrap().step(1.0);
    assert_eq!(arm.read(0.0).unwrap().position_rad[2], q_stop);
    // A fresh command moves it again.
    arm.write(0.0, &cmd).unwrap();
    shared.lock().unwrap().step(0.05);
    assert!(arm.read(0.0).unwrap().velocity_rad_s[2] > 0.1);
}

#[test]
fn non_finite_command_is_refused() {
    let (shared, mut arm, _hand) = teleop_sim::share(world());
    let bad = ArmCommand {
        velocity_rad_s: joint_cmd(0, f64::NAN),
    };
    assert!(arm.write(0.0, &bad).is_err());
    shared.lock().unwrap().step(0.1);
    assert_eq!(
        arm.read(0.0).unwrap().velocity_rad_s,
        SVector::<f64, 7>::zeros()
    );
}

#[test]
fn time_slicing_does_not_matter() {
    let mut a = world();
    let mut b = world();
    a.command_arm(&joint_cmd(2, 0.5));
    b.command_arm(&joint_cmd(2, 0.5));
    a.step(0.05);
    for _ in 0..200 {
        b.step(0.00025);
    }
    assert_eq!(a.time_s(), b.time_s());
    assert_eq!(a.arm_position_rad(), b.arm_position_rad());
}
