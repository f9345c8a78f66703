//! Retargeting: round trips from Shadow poses, human-proportioned hands, registration.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use teleop_hand_model::human::{HandShape, HumanHand};
use teleop_hand_model::retarget::{RetargetSettings, Retargeter, SHADOW_FINGER_DOF};
use teleop_hand_model::sampling::{PoseSampler, Synergy};
use teleop_hand_model::{Finger, HandKeypoints, HandModelError};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;

fn random_shadow_pose(r: &Retargeter, rng: &mut impl Rng) -> [f64; SHADOW_FINGER_DOF] {
    let (lo, hi) = r.limits();
    let mut q = [0.0; SHADOW_FINGER_DOF];
    for i in 0..SHADOW_FINGER_DOF {
        // Stay 0.05 rad inside the limits: at a limit the goals do not pin the joint.
        q[i] = rng.random_range(lo[i] + 0.05..hi[i] - 0.05);
    }
    q
}

/// Keypoints made from Shadow poses (seen from an arbitrary camera) retarget to those
/// poses. Poses in which two fingers' capsules overlap are skipped: there the
/// self-collision goal rightly moves a finger away.
#[test]
fn round_trip_from_shadow_poses() {
    let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let camera_from_palm = Isometry3::from_parts(
        Translation3::new(0.05, -0.02, 0.45),
        UnitQuaternion::from_euler_angles(0.4, -0.3, 2.0),
    );
    let mut tested = 0;
    let mut worst = 0.0_f64;
    let mut errors = Vec::new();
    while tested < 200 {
        let q = random_shadow_pose(&r, &mut rng);
        let kp = r.shadow_keypoints(&q).transformed(&camera_from_palm);
        let out = r.retarget(&kp, None).expect("retarget");
        let free = r
            .retarget(&r.shadow_keypoints(&q), None)
            .map(|o| o.collision_resolves == 0)
            .unwrap_or(false);
        if !free {
            continue;
        }
        tested += 1;
        for i in 0..SHADOW_FINGER_DOF {
            let e = (out.joints[i] - q[i]).abs();
            worst = worst.max(e);
            errors.push(e);
            assert!(
                e < 0.02,
                "{}: {} vs {} (pose {q:?})",
                SHADOW_FINGER_JOINTS[i],
                out.joints[i],
                q[i]
            );
        }
        assert!(
            out.tip_error_m.iter().all(|e| *e < 1e-3),
            "{:?}",
            out.tip_error_m
        );
    }
    errors.sort_by(f64::total_cmp);
    println!(
        "round trip over {tested} poses: median joint error {:.2e} rad, worst {worst:.2e} rad",
        errors[errors.len() / 2]
    );
}

/// Human hands (random shapes and poses) retarget within the Shadow's limits; their
/// fingertips land near the human ones (reported), and fingers do not overlap.
#[test]
fn human_hands_retarget_within_limits() {
    let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    let (lo, hi) = r.limits();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
    let sampler = PoseSampler::default();
    let mut tips: [Vec<f64>; 5] = Default::default();
    let mut overlap = 0;
    let n = 300;
    for _ in 0..n {
        let hand = HumanHand::new(HandShape::sample(&mut rng, 0.07, 0.04)).expect("hand");
        let (pose, _) = sampler.sample(&mut rng);
        let out = r.retarget(&hand.keypoints(&pose), None).expect("retarget");
        for i in 0..SHADOW_FINGER_DOF {
            assert!(out.joints[i] >= lo[i] - 1e-12 && out.joints[i] <= hi[i] + 1e-12);
        }
        for f in Finger::ALL {
            tips[f.index()].push(out.tip_error_m[f.index()]);
        }
        if out.min_clearance_m < -0.003 {
            overlap += 1;
        }
    }
    let mut report = String::from("fingertip error (mm) median / 90th pct:");
    let mut too_far = Vec::new();
    for f in Finger::ALL {
        let v = &mut tips[f.index()];
        v.sort_by(f64::total_cmp);
        let (med, p90) = (v[v.len() / 2] * 1e3, v[v.len() * 9 / 10] * 1e3);
        report += &format!(" {f:?} {med:.1} / {p90:.1};");
        // The Shadow's fingers are longer than a person's (its little finger by about
        // 25 mm, more than its LFJ5 can make up when the finger is straight), it has
        // fewer joints, and the direction goals (unit-vector residuals, as in bio_ik)
        // keep the robot's phalanges parallel to the human's rather than chase the
        // tip: bounds on the median fingertip error.
        let bound = match f {
            Finger::Little => 25.0,
            Finger::Thumb => 20.0,
            // Index: 14.5 mm measured with random restarts in the collision re-solves,
            // 15.0 mm without them (generator v2; the price of 0.6 ms per hand).
            _ => 16.0,
        };
        if med >= bound {
            too_far.push(format!(
                "{f:?} median fingertip error {med:.1} mm >= {bound}"
            ));
        }
    }
    println!("{report} overlapping fingers in {overlap}/{n}");
    assert!(too_far.is_empty(), "{too_far:?}");
    assert!(
        overlap * 10 < n,
        "{overlap} of {n} retargeted hands overlap by > 3 mm"
    );
}

/// A pinch stays a pinch on the robot: thumb and index tips close together.
#[test]
fn a_pinch_retargets_to_a_pinch() {
    let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    let hand = HumanHand::average();
    let out = r
        .retarget(&hand.keypoints(&Synergy::Pinch.posture()), None)
        .expect("retarget");
    let kp = r.shadow_keypoints(&out.joints);
    let gap = (kp.finger(Finger::Thumb)[3] - kp.finger(Finger::Index)[3]).norm();
    assert!(gap < 0.035, "robot pinch gap {gap}");
    let open = r
        .retarget(&hand.keypoints(&Synergy::Open.posture()), None)
        .expect("retarget");
    let kp = r.shadow_keypoints(&open.joints);
    let open_gap = (kp.finger(Finger::Thumb)[3] - kp.finger(Finger::Index)[3]).norm();
    assert!(open_gap > gap + 0.03, "open {open_gap} vs pinch {gap}");
}

/// The registration puts the human wrist on rh_palm's origin (34 mm above rh_wrist)
/// whatever frame the keypoints come in.
#[test]
fn registration_is_frame_independent() {
    let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    let hand = HumanHand::average();
    let kp = hand.keypoints(&Synergy::Precision.posture());
    let moved = Isometry3::from_parts(
        Translation3::new(-0.2, 0.1, 0.6),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.3, 1.2, -0.7)),
    );
    let a = r.retarget(&kp, None).expect("a");
    let b = r.retarget(&kp.transformed(&moved), None).expect("b");
    for i in 0..SHADOW_FINGER_DOF {
        assert!((a.joints[i] - b.joints[i]).abs() < 1e-6);
    }
    let wrist =
        r.registration(&kp.transformed(&moved)).expect("reg") * kp.transformed(&moved).wrist();
    assert!(wrist.coords.norm() < 1e-9);
}

#[test]
fn degenerate_keypoints_are_refused() {
    let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    let mut kp = HumanHand::average().keypoints(&Synergy::Open.posture());
    kp.0[11].x = f64::NAN;
    assert!(matches!(
        r.retarget(&kp, None),
        Err(HandModelError::DegenerateHand { .. })
    ));
    let flat = HandKeypoints([nalgebra::Point3::origin(); 21]);
    assert!(r.retarget(&flat, None).is_err());
}
