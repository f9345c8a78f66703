//! The hand controller wrapper on the simulated plant: reaching targets, effort limits
//! in every mode (property test), NaN rejection, hold behaviour, determinism.
#![allow(clippy::unwrap_used, missing_docs)]

mod hand_plant;

use hand_plant::Plant;
use nalgebra::{SVector, Vector1};
use proptest::prelude::*;
use teleop_control::hand::{
    HandController, HandControllerConfig, HandMode, HandOutput, JointInput, PerJoint,
    PositionServo, SHADOW_FINGER_MAX_EFFORT_NM, ShadowHandController,
};
use teleop_control::{Rejection, RejectionKind};

const DT: f64 = 1e-3;

const MODES: [HandMode; 3] = [
    HandMode::Position,
    HandMode::FixedImpedance,
    HandMode::Adaptive,
];

fn controller<const N: usize>(mode: HandMode) -> HandController<N> {
    HandController::new(HandControllerConfig {
        mode,
        ..Default::default()
    })
    .unwrap()
}

fn effort<const N: usize>(out: &HandOutput<N>) -> SVector<f64, N> {
    *out.effort_nm().unwrap()
}

// ---------------------------------------------------------------------------------
// (a) Free space: the target is reached.

#[test]
fn position_mode_reaches_the_target_in_free_space() {
    let mut c = controller::<1>(HandMode::Position);
    let mut p = Plant::new(Vector1::new(0.0));
    let target = Vector1::new(0.8);
    let mut overshoot: f64 = 0.0;
    for _ in 0..1000 {
        let out = c
            .step(DT, &p.position_rad, &p.velocity_rad_s, &target)
            .unwrap();
        p.step(&effort(&out), DT);
        overshoot = overshoot.max(p.position_rad[0] - target[0]);
    }
    println!(
        "position 1-DoF: error after 1 s {:.2e} rad, overshoot {overshoot:.4} rad",
        (p.position_rad[0] - target[0]).abs()
    );
    assert!((p.position_rad[0] - target[0]).abs() < 1e-4);
    assert!(p.velocity_rad_s[0].abs() < 1e-3);
    assert!(overshoot < 0.05);
}

#[test]
fn every_mode_reaches_the_targets_of_all_17_joints() {
    // Targets inside the Shadow joint ranges, per-joint URDF effort limits.
    let target = SVector::<f64, 17>::from_fn(|i, _| -0.2 + 0.07 * i as f64);
    let config = HandControllerConfig::<17> {
        max_effort_nm: PerJoint::Each(SVector::from(SHADOW_FINGER_MAX_EFFORT_NM)),
        ..Default::default()
    };
    for mode in MODES {
        let mut c = ShadowHandController::new(HandControllerConfig { mode, ..config }).unwrap();
        let mut p = Plant::new(SVector::zeros());
        // The adaptive mode starts soft (K_s = 1 N m/rad) and settles by adapting.
        let steps = if mode == HandMode::Adaptive {
            4000
        } else {
            1000
        };
        for _ in 0..steps {
            let out = c
                .step(DT, &p.position_rad, &p.velocity_rad_s, &target)
                .unwrap();
            p.step(&effort(&out), DT);
        }
        let error = (p.position_rad - target).amax();
        println!("{mode:?} 17-DoF: largest error {error:.2e} rad");
        let tolerance = if mode == HandMode::Adaptive {
            1e-3
        } else {
            1e-4
        };
        assert!(error < tolerance, "{mode:?}: {error}");
    }
}

// ---------------------------------------------------------------------------------
// (d) Efforts never exceed the limits, whatever the input.

/// A number from the joints' working range, or far outside it (finite).
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -3.0..3.0f64,
        1 => -1e6..1e6f64,
        1 => prop_oneof![Just(1e300), Just(-1e300), Just(f64::MAX), Just(-f64::MAX)],
    ]
}

fn vector() -> impl Strategy<Value = SVector<f64, 17>> {
    proptest::array::uniform17(value()).prop_map(SVector::from)
}

fn mode() -> impl Strategy<Value = HandMode> {
    prop_oneof![
        Just(HandMode::Position),
        Just(HandMode::FixedImpedance),
        Just(HandMode::Adaptive)
    ]
}

fn config() -> impl Strategy<Value = HandControllerConfig<17>> {
    (
        mode(),
        proptest::array::uniform17(0.1..5.0f64),
        0.05..1.0f64,
        0.0..100.0f64,
        0.0..100.0f64,
    )
        .prop_map(|(mode, max, hold_fraction, theta_v, theta_k)| {
            let max = SVector::from(max);
            let mut c = HandControllerConfig::<17> {
                mode,
                max_effort_nm: PerJoint::Each(max),
                hold_max_effort_nm: PerJoint::Each(max * hold_fraction),
                ..Default::default()
            };
            c.adaptive.feedforward_adaptation = PerJoint::Uniform(theta_v);
            c.adaptive.stiffness_adaptation = PerJoint::Uniform(theta_k);
            c.adaptive.max_feedforward_nm = PerJoint::Uniform(10.0);
            c
        })
}

/// One period of input: state, target, target velocity, gravity, dt, hold?
type Period = (
    SVector<f64, 17>,
    SVector<f64, 17>,
    SVector<f64, 17>,
    SVector<f64, 17>,
    SVector<f64, 17>,
    f64,
    bool,
);

fn period() -> impl Strategy<Value = Period> {
    (
        vector(),
        vector(),
        vector(),
        vector(),
        vector(),
        prop_oneof![4 => 1e-4..0.02f64, 1 => 0.02..10.0f64],
        proptest::bool::weighted(0.2),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn efforts_never_exceed_the_limits(
        config in config(),
        periods in proptest::collection::vec(period(), 1..60),
    ) {
        let max = config.max_effort_nm.to_vector();
        let hold_max = config.hold_max_effort_nm.to_vector();
        let mut c = HandController::new(config).unwrap();
        for (q, dq, target, target_velocity, gravity, dt, hold) in periods {
            let (out, limit) = if hold {
                (c.hold_with_gravity(dt, &q, &dq, &gravity).unwrap(), hold_max)
            } else {
                let input = JointInput::new(q, dq, target)
                    .with_target_velocity(target_velocity)
                    .with_gravity(gravity);
                (c.step_input(dt, &input).unwrap(), max)
            };
            let tau = effort(&out);
            for i in 0..17 {
                prop_assert!(tau[i].is_finite());
                prop_assert!(tau[i].abs() <= limit[i], "joint {} effort {} limit {}", i, tau[i], limit[i]);
            }
            let p = c.profiles();
            prop_assert!(p.stiffness_nm_rad.iter().all(|k| (0.2..=20.0).contains(k)));
            prop_assert!(p.damping_nm_s_rad.iter().all(|k| (0.02..=0.3).contains(k)));
            prop_assert!(p.feedforward_nm.iter().all(|v| v.abs() <= 10.0));
        }
    }

    #[test]
    fn a_mode_switch_never_exceeds_the_limits(
        modes in proptest::collection::vec(mode(), 1..8),
        q in vector(),
        target in vector(),
    ) {
        let mut c = controller::<17>(HandMode::Adaptive);
        for m in modes {
            c.set_mode(m);
            for _ in 0..20 {
                let tau = effort(&c.step(DT, &q, &SVector::zeros(), &target).unwrap());
                prop_assert!(tau.iter().all(|t| t.abs() <= 2.0));
            }
        }
    }
}

// ---------------------------------------------------------------------------------
// (e) NaN / inf rejection: typed error, nothing changes.

#[test]
fn non_finite_inputs_are_rejected_and_the_last_output_is_kept() {
    for mode in MODES {
        let mut c = controller::<17>(mode);
        let q = SVector::<f64, 17>::repeat(0.1);
        let target = SVector::<f64, 17>::repeat(0.3);
        for _ in 0..50 {
            c.step(DT, &q, &SVector::zeros(), &target).unwrap();
        }
        let before = c.clone();
        let good = JointInput::new(q, SVector::zeros(), target);
        for bad_value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let cases: [(&str, JointInput<17>); 5] = [
                ("position_rad", {
                    let mut i = good;
                    i.position_rad[3] = bad_value;
                    i
                }),
                ("velocity_rad_s", {
                    let mut i = good;
                    i.velocity_rad_s[16] = bad_value;
                    i
                }),
                ("target_rad", {
                    let mut i = good;
                    i.target_rad[0] = bad_value;
                    i
                }),
                ("target_velocity_rad_s", {
                    let mut i = good;
                    i.target_velocity_rad_s[5] = bad_value;
                    i
                }),
                ("gravity_nm", {
                    let mut i = good;
                    i.gravity_nm[9] = bad_value;
                    i
                }),
            ];
            for (field, input) in cases {
                assert_eq!(
                    c.step_input(DT, &input),
                    Err(Rejection::NonFinite { field }),
                    "{mode:?} {field}"
                );
            }
            let mut bad_q = q;
            bad_q[7] = bad_value;
            assert!(c.hold(DT, &bad_q, &SVector::zeros()).is_err());
            assert!(c.step(bad_value, &q, &SVector::zeros(), &target).is_err());
            assert!(c.hold(bad_value, &q, &SVector::zeros()).is_err());
        }
        for bad_dt in [0.0, -1e-3, -0.0] {
            assert_eq!(
                c.step(bad_dt, &q, &SVector::zeros(), &target),
                Err(Rejection::InvalidTimeStep { dt_s: bad_dt })
            );
        }
        // Nothing changed but the counters.
        assert_eq!(c.last_output(), before.last_output());
        assert_eq!(c.profiles(), before.profiles());
        assert_eq!(c.adaptive(), before.adaptive());
        assert_eq!(c.hold_target_rad(), before.hold_target_rad());
        assert_eq!(c.is_holding(), before.is_holding());
        assert_eq!(c.rejections().get(RejectionKind::NonFinite), 3 * (5 + 1));
        assert_eq!(
            c.rejections().get(RejectionKind::InvalidTimeStep),
            3 * 2 + 3
        );
        // And the next valid step is the one the controller would have made anyway.
        let mut reference = before.clone();
        assert_eq!(
            c.step(DT, &q, &SVector::zeros(), &target),
            reference.step(DT, &q, &SVector::zeros(), &target)
        );
    }
}

// ---------------------------------------------------------------------------------
// (5) Hold: do not drop what the hand holds.

/// The finger grasps an object (a stiff surface at 0.5 rad, target 0.1 rad behind it)
/// for 1.5 s, then the commands go stale and the controller holds for 2 s. Returns
/// the contact torque before the hold and at its end, and the largest hold effort.
fn grasp_then_hold(mode: HandMode) -> (f64, f64, f64) {
    let mut c = controller::<1>(mode);
    let mut p = Plant::new(Vector1::new(0.3));
    p.wall_rad = Vector1::new(0.5);
    let target = Vector1::new(0.6);
    for _ in 0..1500 {
        let out = c
            .step(DT, &p.position_rad, &p.velocity_rad_s, &target)
            .unwrap();
        p.step(&effort(&out), DT);
    }
    let before = p.contact_nm()[0];
    let mut largest: f64 = 0.0;
    let weights = c.adaptive().clone();
    for _ in 0..2000 {
        let out = c.hold(DT, &p.position_rad, &p.velocity_rad_s).unwrap();
        largest = largest.max(effort(&out)[0].abs());
        p.step(&effort(&out), DT);
    }
    assert!(c.is_holding());
    assert_eq!(c.hold_target_rad(), Some(&target));
    if mode == HandMode::Adaptive {
        // Frozen: stale data trains nothing, the phase stands still.
        assert_eq!(
            c.adaptive().stiffness_weights(),
            weights.stiffness_weights()
        );
        assert_eq!(
            c.adaptive().feedforward_weights(),
            weights.feedforward_weights()
        );
        assert_eq!(c.adaptive().phase(), weights.phase());
    }
    (before, p.contact_nm()[0], largest)
}

#[test]
fn hold_keeps_the_grasp_with_capped_effort() {
    for mode in MODES {
        let (before, after, largest) = grasp_then_hold(mode);
        println!(
            "hold {mode:?}: contact {before:.3} N m before, {after:.3} N m after 2 s of hold, hold effort <= {largest:.3} N m"
        );
        // Still holding the object: contact force kept, at most the hold limit.
        assert!(after > 0.1, "{mode:?} dropped the object");
        assert!(largest <= 1.0);
        assert!(after <= before.max(1.0) + 1e-6);
    }
}

#[test]
fn hold_keeps_a_loaded_posture_in_free_space() {
    let mut c = controller::<1>(HandMode::Adaptive);
    let mut p = Plant::new(Vector1::new(0.3));
    p.load_nm = Vector1::new(-0.3);
    let target = Vector1::new(0.3);
    // 10 s: past the basis horizon (5 s), where g is constant and v has converged.
    for _ in 0..10_000 {
        let out = c
            .step(DT, &p.position_rad, &p.velocity_rad_s, &target)
            .unwrap();
        p.step(&effort(&out), DT);
    }
    let before = p.position_rad[0];
    // Near the target (the default forgetting leaves a small steady error).
    assert!((before - 0.3).abs() < 0.05, "{before}");
    for _ in 0..3000 {
        let out = c.hold(DT, &p.position_rad, &p.velocity_rad_s).unwrap();
        p.step(&effort(&out), DT);
    }
    // The learned (frozen) feedforward keeps carrying the load during the hold.
    assert!(
        (p.position_rad[0] - before).abs() < 0.01,
        "{before} -> {}",
        p.position_rad[0]
    );
    // Commands resume: normal operation continues from there.
    let out = c
        .step(DT, &p.position_rad, &p.velocity_rad_s, &target)
        .unwrap();
    assert!(!c.is_holding());
    assert!(effort(&out)[0] > 0.25);
}

#[test]
fn hold_with_the_hardware_servo_commands_the_last_target() {
    let mut config = HandControllerConfig::<17> {
        mode: HandMode::Position,
        ..Default::default()
    };
    config.position.servo = PositionServo::Hardware;
    let mut c = HandController::new(config).unwrap();
    let target = SVector::<f64, 17>::repeat(0.4);
    c.step(DT, &SVector::zeros(), &SVector::zeros(), &target)
        .unwrap();
    let out = c
        .hold(DT, &SVector::repeat(0.2), &SVector::zeros())
        .unwrap();
    assert_eq!(out, HandOutput::Position(target));
}

// ---------------------------------------------------------------------------------
// (f) Determinism.

/// 17 joints closing on walls at different angles with a load appearing: every
/// effort of every period.
fn run(mode: HandMode) -> Vec<SVector<f64, 17>> {
    let mut c = controller::<17>(mode);
    let mut p = Plant::new(SVector::zeros());
    p.wall_rad = SVector::from_fn(|i, _| 0.3 + 0.04 * i as f64);
    let mut out = Vec::new();
    for k in 0..3000 {
        let t = k as f64 * DT;
        if k == 1500 {
            p.load_nm = SVector::from_fn(|i, _| 0.05 * i as f64 - 0.4);
        }
        let target = SVector::from_fn(|i, _| (t * 0.8).min(0.4 + 0.04 * i as f64));
        let o = c
            .step(DT, &p.position_rad, &p.velocity_rad_s, &target)
            .unwrap();
        p.step(&effort(&o), DT);
        out.push(effort(&o));
    }
    out
}

#[test]
fn runs_are_repeatable_to_the_bit() {
    for mode in MODES {
        let (a, b) = (run(mode), run(mode));
        assert!(
            a.iter().zip(&b).all(|(x, y)| x
                .iter()
                .zip(y.iter())
                .all(|(u, v)| u.to_bits() == v.to_bits())),
            "{mode:?}"
        );
    }
    // A clone continues exactly like the original.
    let mut c = controller::<17>(HandMode::Adaptive);
    let q = SVector::<f64, 17>::repeat(0.1);
    for k in 0..100 {
        let target = SVector::repeat(0.2 + 1e-3 * k as f64);
        c.step(DT, &q, &SVector::zeros(), &target).unwrap();
    }
    let mut d = c.clone();
    for _ in 0..100 {
        let target = SVector::repeat(0.5);
        assert_eq!(
            c.step(DT, &q, &SVector::zeros(), &target),
            d.step(DT, &q, &SVector::zeros(), &target)
        );
    }
}

// ---------------------------------------------------------------------------------
// The joint-impedance interface: the same law, evaluated by the hardware.

/// On the same closed-loop trajectory, every mode's impedance, evaluated where it was
/// computed, is the effort the effort interface sends; while holding it is the same
/// direction, scaled to the hold limit.
#[test]
fn the_impedance_interface_is_the_same_law() {
    use teleop_control::hand::HardwareInterface;
    let target = SVector::<f64, 17>::from_fn(|i, _| 0.05 * i as f64);
    for mode in MODES {
        let mut by_effort = controller::<17>(mode);
        let mut by_impedance = controller::<17>(mode).with_interface(HardwareInterface::Impedance);
        assert_eq!(by_impedance.interface(), HardwareInterface::Impedance);
        let mut p = Plant::new(SVector::zeros());
        for k in 0..2000 {
            let gravity = SVector::<f64, 17>::repeat(0.01);
            let input =
                JointInput::new(p.position_rad, p.velocity_rad_s, target).with_gravity(gravity);
            let tau = effort(&by_effort.step_input(DT, &input).unwrap());
            let out = by_impedance.step_input(DT, &input).unwrap();
            let z = out.impedance().unwrap();
            assert_eq!(z.position_rad, target);
            let tau_z = z.effort_at(&p.position_rad, &p.velocity_rad_s);
            assert!(
                (tau - tau_z).amax() < 1e-9,
                "{mode:?} step {k}: {tau} vs {tau_z}"
            );
            p.step(&tau, DT);
        }
        // Holding: the law frozen, scaled so no joint exceeds the hold limit.
        let held = by_impedance
            .hold(DT, &(p.position_rad * 0.5), &p.velocity_rad_s)
            .unwrap();
        let tau_hold = effort(
            &by_effort
                .hold(DT, &(p.position_rad * 0.5), &p.velocity_rad_s)
                .unwrap(),
        );
        let z = held.impedance().unwrap();
        let tau_z = z.effort_at(&(p.position_rad * 0.5), &p.velocity_rad_s);
        assert!(
            z.max_effort_nm.iter().all(|m| *m == 1.0),
            "{mode:?}: hold cap"
        );
        assert!(
            (tau_hold - tau_z).amax() < 1e-9,
            "{mode:?} hold: {tau_hold} vs {tau_z}"
        );
    }
}
