//! Simulated Shadow hand: free-space dynamics, gravity, limits, stability.
#![allow(clippy::unwrap_used)]

use nalgebra::SVector;
use teleop_hardware::{HandCommand, HandHardware, HandImpedance};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_sim::{TouchingTaskConfig, World, WorldConfig};

fn idx(name: &str) -> usize {
    SHADOW_FINGER_JOINTS
        .iter()
        .position(|j| *j == name)
        .unwrap()
}

#[test]
fn constant_effort_accelerates_per_inertia_and_settles_against_damping() {
    let config = WorldConfig {
        gravity_m_s2: [0.0; 3],
        ..WorldConfig::nominal()
    };
    let b = config.hand.damping_nm_s_rad;
    let mut w = World::new(config).unwrap();
    let j = idx("rh_FFJ2");
    let mut q0 = SVector::<f64, 17>::zeros();
    q0[j] = 0.2;
    w.set_hand_position(&q0);
    let inertia = w.hand_inertia_kg_m2()[j];
    assert!(inertia > 2e-4 && inertia < 1e-3, "{inertia}");
    let tau = 0.02;
    let mut cmd = SVector::<f64, 17>::zeros();
    cmd[j] = tau;
    w.command_hand(&HandCommand::Effort(cmd));
    // Exact solution of I qdd = tau - b qd from rest: v(t) = tau/b (1 - exp(-b t / I)),
    // i.e. initial acceleration tau / I; the implicit Euler stays within a few per cent.
    let exact = |t: f64| tau / b * (1.0 - (-b * t / inertia).exp());
    w.step_once();
    let v1 = w.hand_velocity_rad_s()[j];
    assert!(
        (v1 / exact(w.dt_s()) - 1.0).abs() < 0.06,
        "{v1} vs {}",
        exact(w.dt_s())
    );
    w.step(0.004);
    let v5 = w.hand_velocity_rad_s()[j];
    assert!(
        (v5 / exact(0.005) - 1.0).abs() < 0.06,
        "{v5} vs {}",
        exact(0.005)
    );
    // Terminal velocity tau / b after many time constants I / b (~8 ms).
    w.step(0.08);
    let v = w.hand_velocity_rad_s()[j];
    assert!((v - tau / b).abs() < 1e-3 * tau / b, "{v}");
    assert_eq!(w.hand_state().effort_nm[j], tau);
    // Other joints stay still.
    assert_eq!(w.hand_velocity_rad_s()[idx("rh_MFJ2")], 0.0);
}

#[test]
fn effort_is_clamped_and_limits_hold() {
    let mut w = World::new(WorldConfig::nominal()).unwrap();
    let j = idx("rh_FFJ3");
    let mut cmd = SVector::<f64, 17>::zeros();
    cmd[j] = 50.0;
    w.command_hand(&HandCommand::Effort(cmd));
    w.step(1.0);
    let state = w.hand_state();
    let max = WorldConfig::default().hand.max_effort_nm;
    assert_eq!(state.effort_nm[j], max);
    let (_, upper) = w.hand_limits_rad();
    let over = state.position_rad[j] - upper[j];
    // 2 N m against 50 N m/rad: 0.04 rad past the limit, at rest.
    assert!(over > 0.0 && over < 1.5 * max / 50.0, "{over}");
    assert!(state.velocity_rad_s[j].abs() < 1e-6);
}

#[test]
fn gravity_flexes_passive_fingers_when_palm_faces_down() {
    // Arm at zero: palm down. Zero effort: the fingers hang.
    let mut w = World::new(WorldConfig::nominal()).unwrap();
    let palm = w.palm_pose();
    assert!(
        (palm.rotation * nalgebra::Vector3::y()).z > 0.99,
        "palm faces down (-y down)"
    );
    let tip0 = w.fingertip_positions_m()[0];
    w.command_hand(&HandCommand::Effort(SVector::zeros()));
    w.step(0.2);
    let j3 = w.hand_position_rad()[idx("rh_FFJ3")];
    assert!(j3 > 0.05, "FFJ3 flexed by gravity: {j3}");
    assert!(w.fingertip_positions_m()[0].z < tip0.z - 0.005);

    // Palm up (forearm rolled by pi): gravity extends the fingers instead.
    let mut config = WorldConfig::nominal();
    config.arm.initial_position_rad[4] = std::f64::consts::PI;
    let mut w = World::new(config).unwrap();
    w.command_hand(&HandCommand::Effort(SVector::zeros()));
    w.step(0.2);
    assert!(w.hand_position_rad()[idx("rh_FFJ3")] < -0.05);
}

#[test]
fn position_servo_reaches_target_in_free_space() {
    let (shared, _arm, mut hand) = teleop_sim::share(World::new(WorldConfig::nominal()).unwrap());
    let mut target = SVector::<f64, 17>::zeros();
    target[idx("rh_MFJ3")] = 0.8;
    target[idx("rh_THJ4")] = 0.5;
    hand.write(0.0, &HandCommand::Position(target)).unwrap();
    shared.lock().unwrap().step(2.0);
    let state = hand.read(0.0).unwrap();
    // The P servo leaves a gravity droop of a few hundredths of a rad.
    assert!((state.position_rad[idx("rh_MFJ3")] - 0.8).abs() < 0.05);
    assert!((state.position_rad[idx("rh_THJ4")] - 0.5).abs() < 0.05);
    assert!(state.velocity_rad_s.amax() < 1e-3);
    assert!(
        hand.write(0.0, &HandCommand::Effort(SVector::repeat(f64::INFINITY)))
            .is_err()
    );
}

/// A stiff joint impedance held over a long command period (as a controller across a
/// bus sends it): the hand's own loop evaluates it every substep, so the finger settles
/// on the set point without oscillating, and its effort respects the command's cap.
#[test]
fn joint_impedance_is_evaluated_in_the_hands_own_loop() {
    let config = WorldConfig {
        gravity_m_s2: [0.0; 3],
        ..WorldConfig::nominal()
    };
    let mut w = World::new(config).unwrap();
    let j = idx("rh_FFJ3");
    let mut z = HandImpedance {
        position_rad: SVector::zeros(),
        velocity_rad_s: SVector::zeros(),
        stiffness_nm_rad: SVector::repeat(20.0),
        damping_nm_s_rad: SVector::repeat(0.2),
        feedforward_nm: SVector::zeros(),
        max_effort_nm: SVector::repeat(2.0),
    };
    z.position_rad[j] = 0.8;
    w.command_hand(&HandCommand::Impedance(z));
    // Sampled every 4 ms, as the bus sees it; the command never changes.
    let mut peak_effort: f64 = 0.0;
    let mut late_speed: f64 = 0.0;
    for k in 0..250 {
        w.step(0.004);
        let s = w.hand_state();
        peak_effort = peak_effort.max(s.effort_nm.amax());
        if k >= 200 {
            late_speed = late_speed.max(s.velocity_rad_s.amax());
        }
    }
    let s = w.hand_state();
    assert!(
        (s.position_rad[j] - 0.8).abs() < 0.01,
        "FFJ3 at {}",
        s.position_rad[j]
    );
    assert!(
        late_speed < 1e-2,
        "still moving after 0.8 s: {late_speed} rad/s"
    );
    assert!(
        peak_effort <= 2.0 + 1e-9,
        "effort above the cap: {peak_effort}"
    );
    // A lower cap binds: 0.3 N m cannot hold the finger far from a 20 N m/rad set point
    // against nothing, but it limits the push.
    z.max_effort_nm = SVector::repeat(0.3);
    z.position_rad[j] = 0.0;
    w.command_hand(&HandCommand::Impedance(z));
    w.step(0.002);
    assert!(w.hand_state().effort_nm.amax() <= 0.3 + 1e-9);
}

/// Zero effort for 10 s in the touching scene: the fingers fall onto the mouse and
/// against their limits; nothing may gain energy.
#[test]
fn energy_stays_bounded_with_zero_command() {
    let mut w = World::touching_task(&TouchingTaskConfig {
        world: WorldConfig::nominal(),
        ..TouchingTaskConfig::default()
    })
    .unwrap();
    w.command_hand(&HandCommand::Effort(SVector::zeros()));
    let mut peak: f64 = 0.0;
    let mut first_second: f64 = 0.0;
    let mut last_second: f64 = 0.0;
    for k in 0..10_000 {
        w.step_once();
        let v = w.hand_velocity_rad_s();
        assert!(v.iter().all(|x| x.is_finite()));
        peak = peak.max(v.amax());
        if k < 1000 {
            first_second = first_second.max(v.amax());
        } else if k >= 9000 {
            last_second = last_second.max(v.amax());
        }
    }
    assert!(peak < 10.0, "peak joint speed {peak} rad/s");
    // Hanging fingers creep slowly towards equilibrium (near-vertical phalanges feel
    // little gravity torque), never faster than they started.
    assert!(
        last_second < 0.05 && last_second < first_second / 10.0,
        "{first_second} -> {last_second}"
    );
    assert!(
        w.fingertip_force_n()
            .iter()
            .all(|f| f.is_finite() && *f < 5.0)
    );
}

/// Full effort, alternating sign every 50 ms, for 10 s, at dt = 1 ms and with a single
/// substep: the stiffest the hand is driven.
#[test]
fn bang_bang_effort_is_stable_with_one_substep() {
    let mut config = TouchingTaskConfig {
        world: WorldConfig::nominal(),
        ..TouchingTaskConfig::default()
    };
    config.world.hand.substeps = 1;
    let mut w = World::touching_task(&config).unwrap();
    let mut peak: f64 = 0.0;
    for k in 0..10_000 {
        let sign = if (k / 50) % 2 == 0 { 1.0 } else { -1.0 };
        w.command_hand(&HandCommand::Effort(SVector::repeat(sign)));
        w.step_once();
        peak = peak.max(w.hand_velocity_rad_s().amax());
        assert!(w.hand_position_rad().iter().all(|x| x.is_finite()));
    }
    // 1 N m against 0.05 N m s/rad: 20 rad/s terminal in free space; rebounds off the
    // limit springs and contacts add a little, instability would add without bound.
    assert!(peak < 30.0, "{peak}");
    let (lower, upper) = w.hand_limits_rad();
    let q = w.hand_position_rad();
    for i in 0..17 {
        assert!(
            q[i] > lower[i] - 0.05 && q[i] < upper[i] + 0.05,
            "joint {i}: {}",
            q[i]
        );
    }
}
