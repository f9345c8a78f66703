//! The chapter-6 arm registration: IMU-suit skeleton frames to PR2 palm targets in the
//! torso frame, checked against the PR2 model's own forward kinematics.
#![allow(clippy::unwrap_used)]

use nalgebra::{UnitQuaternion, Vector3};
use teleop_kinematics::robots::{self, pr2};
use teleop_local_site::tracking::bvh::Skeleton;
use teleop_local_site::tracking::imu_arm::{HumanArm, ImuArmConfig, ImuArmMapping};

fn fixture() -> String {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/upper_body.bvh");
    std::fs::read_to_string(path).unwrap()
}

/// The fixture with the upper arm and forearm lengths (cm) replaced.
fn skeleton(upper_cm: f64, fore_cm: f64) -> Skeleton {
    let text = fixture()
        .replace("OFFSET -29 0 0", &format!("OFFSET -{upper_cm} 0 0"))
        .replace("OFFSET -25 0 0", &format!("OFFSET -{fore_cm} 0 0"));
    Skeleton::parse(&text).unwrap().0
}

/// One frame: hips position (cm) and rotation, then Y X Z degrees of the spine,
/// shoulder, upper arm, forearm and hand.
fn frame(hips: [f64; 6], joints: [[f64; 3]; 5]) -> Vec<f64> {
    let mut v = hips.to_vec();
    for j in joints {
        v.extend_from_slice(&j);
    }
    v
}

fn human_arm(s: &Skeleton, values: &[f64]) -> HumanArm {
    let j = |name: &str| s.joint(name).unwrap();
    s.arm_in(
        values,
        j("Spine3"),
        [j("RightArm"), j("RightForeArm"), j("RightHand")],
        0.01,
    )
    .unwrap()
}

fn palm_in_torso(q: [f64; 7]) -> nalgebra::Isometry3<f64> {
    let robot = robots::pr2_arm().unwrap();
    let chain = robot.chain(pr2::TORSO, pr2::WRIST).unwrap();
    chain.end_pose(&q).unwrap()
}

const STILL: [f64; 6] = [0.0, 100.0, 0.0, 0.0, 0.0, 0.0];

#[test]
fn a_straight_arm_forward_maps_onto_the_pr2_arm_at_zero_for_any_operator_size() {
    let mapping = ImuArmMapping::new(&ImuArmConfig::default()).unwrap();
    assert!((mapping.robot_arm_length_m() - 0.721).abs() < 1e-9);
    assert!((mapping.robot_shoulder() - Vector3::new(0.1, -0.188, 0.0)).norm() < 1e-9);
    let want = palm_in_torso([0.0; 7]);
    // Upper arm turned 90 deg about the body's vertical: the arm points forward (+Z).
    let forward = frame(
        STILL,
        [[0.0; 3], [0.0; 3], [90.0, 0.0, 0.0], [0.0; 3], [0.0; 3]],
    );
    for (upper, fore) in [(29.0, 25.0), (33.0, 28.0), (24.0, 21.0)] {
        let arm = human_arm(&skeleton(upper, fore), &forward);
        assert!((arm.length_m() - (upper + fore) / 100.0).abs() < 1e-9);
        let got = mapping.palm_target(&arm).unwrap();
        let dp = (got.translation.vector - want.translation.vector).norm();
        let da = got.rotation.angle_to(&want.rotation);
        assert!(
            dp < 1e-9,
            "{upper}/{fore} cm: palm {dp} m from the PR2's at zero"
        );
        assert!(
            da < 1e-9,
            "{upper}/{fore} cm: palm turned {da} rad from the PR2's"
        );
    }
}

#[test]
fn the_t_pose_maps_onto_the_arm_stretched_right_with_the_palm_down() {
    let mapping = ImuArmMapping::new(&ImuArmConfig::default()).unwrap();
    let arm = human_arm(&skeleton(29.0, 25.0), &frame(STILL, [[0.0; 3]; 5]));
    let got = mapping.palm_target(&arm).unwrap();
    let mut q = [0.0; 7];
    q[0] = -std::f64::consts::FRAC_PI_2;
    let stretched = palm_in_torso(q);
    // The orientation is the PR2's with the shoulder panned -90 deg (palm down,
    // fingers to the right) ...
    assert!(got.rotation.angle_to(&stretched.rotation) < 1e-9);
    let fingers = got.rotation * Vector3::z();
    assert!(
        (fingers - -Vector3::y()).norm() < 1e-6,
        "fingers along {fingers}"
    );
    // ... and the wrist is one robot arm to the right of the scaling centre, so the
    // palm lies on the same line as the stretched robot palm, 0.1 m (the PR2's
    // shoulder offset, which pans with the arm) further forward.
    let d = got.translation.vector - stretched.translation.vector;
    assert!(
        (d - Vector3::new(0.1, 0.1, 0.0)).norm() < 1e-6,
        "offset {d}"
    );
}

#[test]
fn the_target_depends_on_the_arm_relative_to_the_spine_only() {
    let mapping = ImuArmMapping::new(&ImuArmConfig::default()).unwrap();
    let s = skeleton(29.0, 25.0);
    let pose = [
        [0.0, 5.0, 0.0],
        [0.0; 3],
        [60.0, 10.0, -40.0],
        [-30.0, 0.0, 45.0],
        [0.0, 20.0, 10.0],
    ];
    let a = mapping
        .palm_target(&human_arm(&s, &frame(STILL, pose)))
        .unwrap();
    // The operator walks 2 m and turns 120 deg: the same target.
    let walked = [200.0, 98.0, -150.0, 120.0, 5.0, 0.0];
    let b = mapping
        .palm_target(&human_arm(&s, &frame(walked, pose)))
        .unwrap();
    assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
    assert!(a.rotation.angle_to(&b.rotation) < 1e-9);
    // A bigger operator in the same posture: the same target too (the ratio scales).
    let big = skeleton(34.8, 30.0);
    let c = mapping
        .palm_target(&human_arm(&big, &frame(STILL, pose)))
        .unwrap();
    assert!((a.translation.vector - c.translation.vector).norm() < 1e-9);
    // A fixed ratio instead: the bigger operator reaches 20 % further from the shoulder.
    let fixed = ImuArmMapping::new(&ImuArmConfig {
        arm_length_ratio: Some(0.721 / 0.54),
        ..ImuArmConfig::default()
    })
    .unwrap();
    let small_arm = human_arm(&s, &frame(STILL, pose));
    let big_arm = human_arm(&big, &frame(STILL, pose));
    let reach = |arm: &HumanArm, m: &ImuArmMapping| {
        let k = m.ratio(arm).unwrap();
        (arm.hand.translation.vector - arm.shoulder.coords).norm() * k
    };
    let r_small = reach(&small_arm, &fixed);
    let r_big = reach(&big_arm, &fixed);
    assert!((r_big / r_small - 1.2).abs() < 1e-9, "{r_big} / {r_small}");
    // The palm calibration turn is applied in the palm's frame.
    let turned = ImuArmMapping::new(&ImuArmConfig {
        palm_rpy_deg: [0.0, 0.0, 30.0],
        ..ImuArmConfig::default()
    })
    .unwrap()
    .palm_target(&small_arm)
    .unwrap();
    let rel = a.rotation.inverse() * turned.rotation;
    let want = UnitQuaternion::from_euler_angles(0.0, 0.0, 30f64.to_radians());
    assert!(rel.angle_to(&want) < 1e-9);
}

#[test]
fn degenerate_arms_and_bad_settings_are_refused() {
    let mapping = ImuArmMapping::new(&ImuArmConfig::default()).unwrap();
    let p = nalgebra::Point3::new(0.1, 0.2, 0.3);
    let collapsed = HumanArm {
        shoulder: p,
        elbow: p,
        hand: nalgebra::Isometry3::translation(0.1, 0.2, 0.3),
    };
    assert!(mapping.palm_target(&collapsed).is_none());
    for (cfg, needle) in [
        (
            ImuArmConfig {
                arm_length_ratio: Some(f64::NAN),
                ..ImuArmConfig::default()
            },
            "arm_length_ratio",
        ),
        (
            ImuArmConfig {
                torso_from_spine_rpy_deg: [0.0, 720.0, 0.0],
                ..ImuArmConfig::default()
            },
            "torso_from_spine_rpy_deg",
        ),
        (
            ImuArmConfig {
                elbow_joint: " ".into(),
                ..ImuArmConfig::default()
            },
            "elbow_joint",
        ),
    ] {
        let err = ImuArmMapping::new(&cfg).unwrap_err().to_string();
        assert!(err.contains(needle), "{err}");
    }
    let unknown: Result<ImuArmConfig, _> =
        toml::from_str("shoulder_joint = \"RightArm\"\nscale = 2\n");
    assert!(unknown.unwrap_err().to_string().contains("scale"));
    // The default skeleton joints are Axis Neuron's names.
    let s = Skeleton::parse(&fixture()).unwrap().0;
    let cfg = ImuArmConfig::default();
    assert!(s.joint(&cfg.shoulder_joint).is_ok() && s.joint(&cfg.elbow_joint).is_ok());
}
