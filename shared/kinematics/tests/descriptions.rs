//! The robot descriptions themselves: every file parses, the Shadow hand's joints and
//! limits match the thesis table (SYSTEM.md), the hand is the same in both files,
//! the bodies are plausible, and bad input gives typed errors.

use std::f64::consts::PI;
use teleop_kinematics::{JointKind, KinematicsError, Robot, Shape, robots};

fn deg(d: f64) -> f64 {
    d * PI / 180.0
}

/// SYSTEM.md, "Joint ranges of the Shadow hand with BioTac (Table 3.1, degrees)", plus
/// the wrist ranges of the issue (WRJ2 -30..10, WRJ1 -40..28).
const TABLE_DEG: [(&str, f64, f64); 19] = [
    ("rh_WRJ2", -30.0, 10.0),
    ("rh_WRJ1", -40.0, 28.0),
    ("rh_THJ5", -60.0, 60.0),
    ("rh_THJ4", 0.0, 70.0),
    ("rh_THJ3", -12.0, 12.0),
    ("rh_THJ2", -30.0, 30.0),
    ("rh_FFJ4", -20.0, 20.0),
    ("rh_FFJ3", -15.0, 90.0),
    ("rh_FFJ2", 0.0, 90.0),
    ("rh_MFJ4", -20.0, 20.0),
    ("rh_MFJ3", -15.0, 90.0),
    ("rh_MFJ2", 0.0, 90.0),
    ("rh_RFJ4", -20.0, 20.0),
    ("rh_RFJ3", -15.0, 90.0),
    ("rh_RFJ2", 0.0, 90.0),
    ("rh_LFJ5", 0.0, 45.0),
    ("rh_LFJ4", -20.0, 20.0),
    ("rh_LFJ3", -15.0, 90.0),
    ("rh_LFJ2", 0.0, 90.0),
];

fn check_shadow_table(robot: &Robot) {
    for (name, lo, hi) in TABLE_DEG {
        let j = robot.joint(robot.joint_id(name).expect(name));
        assert_eq!(j.kind, JointKind::Revolute, "{name}");
        let l = j.limits.expect("revolute joints have limits");
        assert!(
            (l.lower - deg(lo)).abs() < 1e-12,
            "{name} lower {}",
            l.lower
        );
        assert!(
            (l.upper - deg(hi)).abs() < 1e-12,
            "{name} upper {}",
            l.upper
        );
        assert!(l.velocity > 0.0 && l.effort > 0.0, "{name}");
    }
    for name in robots::shadow::FIXED_J1 {
        let j = robot.joint(robot.joint_id(name).expect(name));
        assert_eq!(j.kind, JointKind::Fixed, "{name} is fixed by the BioTac");
        assert!(j.dof.is_none());
        // The fixed rotation: 20 deg about the joint's x axis (after the thumb's yaw).
        let (roll, pitch, _yaw) = j.origin.rotation.euler_angles();
        assert!(
            (roll - robots::shadow::J1_FIXED_RAD).abs() < 1e-12,
            "{name}"
        );
        assert!(pitch.abs() < 1e-12, "{name}");
    }
    for name in robots::shadow::ALL_JOINTS {
        robot.joint_id(name).expect("all 24 Shadow joints exist");
    }
}

#[test]
fn shadow_hand_joints_and_limits_match_the_thesis_table() {
    let robot = robots::shadow_hand().expect("embedded");
    assert_eq!(robot.dof(), 19, "24 joints minus 5 fixed J1");
    check_shadow_table(&robot);
    let moving: Vec<&str> = robot.dof_joints().map(|j| j.name.as_str()).collect();
    let mut expected: Vec<&str> = TABLE_DEG.iter().map(|t| t.0).collect();
    let mut sorted = moving.clone();
    sorted.sort_unstable();
    expected.sort_unstable();
    assert_eq!(sorted, expected, "exactly the 19 DoF of the table move");
    let total: usize = robots::shadow::ALL_JOINTS.len();
    assert_eq!(total, 24);
    for f in [
        robots::shadow::TIPS,
        robots::shadow::DIPS,
        robots::shadow::PIPS,
        robots::shadow::MCPS,
    ] {
        for link in f {
            robot.link_id(link).expect("retargeting frame exists");
        }
    }
}

#[test]
fn pr2_file_carries_the_same_hand() {
    let hand = robots::shadow_hand().expect("embedded");
    let pr2 = robots::pr2_arm().expect("embedded");
    check_shadow_table(&pr2);
    for j in hand.joints() {
        let other = pr2.joint(pr2.joint_id(&j.name).expect("same joint names"));
        assert_eq!(j.kind, other.kind, "{}", j.name);
        assert_eq!(j.origin, other.origin, "{}", j.name);
        assert_eq!(j.axis, other.axis, "{}", j.name);
        assert_eq!(j.limits, other.limits, "{}", j.name);
        assert_eq!(hand.link(j.child).name, pr2.link(other.child).name);
    }
    for l in hand.links() {
        let other = pr2.link(pr2.link_id(&l.name).expect("same link names"));
        assert_eq!(l.inertial, other.inertial, "{}", l.name);
        assert_eq!(l.collisions, other.collisions, "{}", l.name);
    }
    let chain = pr2
        .chain(robots::pr2::BASE, robots::pr2::WRIST)
        .expect("chain");
    let arm: Vec<&str> = chain.joint_names().collect();
    assert_eq!(arm, teleop_interfaces::joints::PR2_ARM_JOINTS);
}

#[test]
fn pr2_arm_limits_follow_pr2_description() {
    let pr2 = robots::pr2_arm().expect("embedded");
    let lim = |n: &str| pr2.joint(pr2.joint_id(n).expect(n)).limits.expect(n);
    let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
    let pan = lim("r_shoulder_pan_joint");
    assert!(close(pan.lower, -PI / 4.0 - 1.5) && close(pan.upper, -PI / 4.0 + 1.5));
    let lift = lim("r_shoulder_lift_joint");
    // pr2_description writes -0.5236 (not exactly -pi/6) and 1.3963.
    #[allow(clippy::approx_constant)]
    let (lift_lower, lift_upper) = (-0.5236, 1.3963);
    assert!(close(lift.lower, lift_lower) && close(lift.upper, lift_upper));
    let roll = lim("r_upper_arm_roll_joint");
    assert!(close(roll.lower, -3.9) && close(roll.upper, 0.8));
    let elbow = lim("r_elbow_flex_joint");
    assert!(close(elbow.lower, -2.3213) && close(elbow.upper, 0.0));
    let fore = lim("r_forearm_roll_joint");
    assert!(!fore.is_bounded());
}

#[test]
fn ur5_limits_and_names() {
    let ur5 = robots::ur5().expect("embedded");
    assert_eq!(ur5.dof(), 6);
    let names: Vec<&str> = ur5.dof_joints().map(|j| j.name.as_str()).collect();
    assert_eq!(names, teleop_interfaces::joints::UR5_JOINTS);
    for l in ur5.dof_limits() {
        assert!((l.lower + 2.0 * PI).abs() < 1e-12 && (l.upper - 2.0 * PI).abs() < 1e-12);
        assert_eq!(l.velocity, 3.15);
    }
    robots::ur5_camera_chain().expect("camera chain has 6 DoF");
}

/// Masses and inertias plausible for joint-space dynamics: every body with
/// collision geometry has positive mass, inertia tensors are symmetric positive
/// definite and satisfy the triangle inequality; totals are in the expected range.
#[test]
fn bodies_are_physically_plausible() {
    for (name, robot, lo, hi) in [
        ("ur5", robots::ur5().expect("embedded"), 18.0, 22.0),
        ("shadow", robots::shadow_hand().expect("embedded"), 0.5, 1.2),
        ("pr2", robots::pr2_arm().expect("embedded"), 190.0, 210.0),
    ] {
        let m = robot.total_mass_kg();
        assert!(m > lo && m < hi, "{name}: total mass {m} kg");
        for l in robot.links() {
            if !l.collisions.is_empty() {
                assert!(
                    l.inertial.is_some(),
                    "{name}: {} has geometry but no mass",
                    l.name
                );
            }
            for c in &l.collisions {
                assert!(
                    !matches!(c.shape, Shape::Mesh { .. }),
                    "{name}: {} uses a mesh",
                    l.name
                );
            }
            if let Some(i) = l.inertial {
                let t = i.inertia;
                assert_eq!(t, t.transpose());
                let eig = t.symmetric_eigenvalues();
                assert!(eig.min() > 0.0, "{name}: {} inertia not positive", l.name);
                let (a, b, c) = (eig[0], eig[1], eig[2]);
                assert!(
                    a + b >= c * (1.0 - 1e-9)
                        && b + c >= a * (1.0 - 1e-9)
                        && a + c >= b * (1.0 - 1e-9),
                    "{name}: {} violates the triangle inequality",
                    l.name
                );
            }
        }
    }
}

#[test]
fn every_file_parses_with_urdf_rs() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/urdf");
    let mut count = 0;
    for entry in std::fs::read_dir(dir).expect("urdf dir") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "urdf") {
            let parsed = urdf_rs::read_file(&path).expect("urdf-rs parses");
            assert!(!parsed.links.is_empty());
            let robot = Robot::from_urdf_file(&path).expect("our loader accepts it");
            assert_eq!(robot.links().len(), parsed.links.len());
            assert_eq!(robot.joints().len(), parsed.joints.len());
            count += 1;
        }
    }
    assert_eq!(count, 3);
    // The embedded copies are the files.
    let ur5 = std::fs::read_to_string(format!("{dir}/ur5.urdf")).expect("file");
    assert_eq!(ur5, robots::UR5_URDF);
}

#[test]
fn missing_file_is_an_io_error() {
    let err = Robot::from_urdf_file("/nonexistent/robot.urdf").expect_err("no file");
    assert!(
        matches!(&err, KinematicsError::Io { path, .. } if path.ends_with("robot.urdf")),
        "{err}"
    );
}

#[test]
fn malformed_xml_is_a_parse_error() {
    for text in ["<robot name=\"x\"><link name=\"a\">", "not xml at all", ""] {
        let err = Robot::from_urdf_str(text).expect_err("malformed");
        assert!(
            matches!(err, KinematicsError::Parse { .. }),
            "{text:?}: {err}"
        );
    }
}

fn two_links(joint: &str) -> String {
    format!(r#"<robot name="t"><link name="a"/><link name="b"/>{joint}</robot>"#)
}

#[test]
fn structural_errors_name_the_culprit() {
    type Check = fn(&KinematicsError) -> bool;
    let cases: Vec<(String, Check)> = vec![
        (
            two_links(
                r#"<joint name="j" type="fixed"><parent link="a"/><child link="zz"/></joint>"#,
            ),
            |e| matches!(e, KinematicsError::UndefinedLink { joint, link } if joint == "j" && link == "zz"),
        ),
        (
            two_links(
                r#"<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/><limit lower="1" upper="-1" effort="1" velocity="1"/></joint>"#,
            ),
            |e| matches!(e, KinematicsError::BadLimits { joint, .. } if joint == "j"),
        ),
        (
            two_links(
                r#"<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#,
            ),
            |e| matches!(e, KinematicsError::BadAxis { joint, .. } if joint == "j"),
        ),
        (
            two_links(
                r#"<joint name="j" type="floating"><parent link="a"/><child link="b"/></joint>"#,
            ),
            |e| matches!(e, KinematicsError::UnsupportedJointType { joint, kind } if joint == "j" && kind == "floating"),
        ),
        (
            two_links(""),
            |e| matches!(e, KinematicsError::RootCount { roots } if roots.len() == 2),
        ),
        (
            r#"<robot name="t"><link name="a"/><link name="a"/></robot>"#.to_owned(),
            |e| matches!(e, KinematicsError::DuplicateLink { link } if link == "a"),
        ),
        (
            r#"<robot name="t"><link name="a"/><link name="b"/><link name="c"/>
               <joint name="j1" type="fixed"><parent link="a"/><child link="c"/></joint>
               <joint name="j2" type="fixed"><parent link="b"/><child link="c"/></joint></robot>"#
                .to_owned(),
            |e| matches!(e, KinematicsError::MultipleParents { link, .. } if link == "c"),
        ),
        (
            r#"<robot name="t"><link name="a"/><link name="b"/><link name="c"/>
               <joint name="j1" type="fixed"><parent link="b"/><child link="c"/></joint>
               <joint name="j2" type="fixed"><parent link="c"/><child link="b"/></joint></robot>"#
                .to_owned(),
            |e| matches!(e, KinematicsError::Unreachable { .. }),
        ),
        (
            two_links(
                r#"<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="k"/></joint>"#,
            ),
            |e| matches!(e, KinematicsError::UnsupportedMimic { joint } if joint == "j"),
        ),
    ];
    for (text, check) in cases {
        let err = Robot::from_urdf_str(&text).expect_err(&text);
        assert!(check(&err), "{text}\n gave {err:?}");
        assert!(!err.to_string().is_empty());
    }
}

/// The joint tables every crate uses (`teleop_interfaces::joints`) name moving joints of
/// our models, and the per-finger frame arrays follow the one finger order.
#[test]
fn interface_tables_match_the_models() {
    use teleop_interfaces::joints::{FINGERTIPS, PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS, UR5_JOINTS};
    let hand = robots::shadow_hand().expect("embedded");
    let pr2 = robots::pr2_arm().expect("embedded");
    let ur5 = robots::ur5().expect("embedded");
    for j in SHADOW_FINGER_JOINTS {
        hand.dof_index(j)
            .expect("finger joint moves in the hand model");
        pr2.dof_index(j)
            .expect("finger joint moves in the PR2 + hand model");
    }
    for j in PR2_ARM_JOINTS {
        pr2.dof_index(j).expect("arm joint moves");
    }
    for j in UR5_JOINTS {
        ur5.dof_index(j).expect("UR5 joint moves");
    }
    let chain = robots::pr2_arm_chain().expect("chain");
    assert_eq!(
        chain.chain().joint_names().collect::<Vec<_>>(),
        PR2_ARM_JOINTS
    );
    for (i, f) in FINGERTIPS.iter().enumerate() {
        for frames in [
            robots::shadow::TIPS,
            robots::shadow::DISTALS,
            robots::shadow::DIPS,
            robots::shadow::PIPS,
            robots::shadow::MCPS,
        ] {
            assert!(
                frames[i].starts_with(&format!("rh_{f}")),
                "{} is not finger {f}",
                frames[i]
            );
            hand.link_id(frames[i]).expect("frame exists");
        }
    }
}
