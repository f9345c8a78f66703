//! Jacobians against finite differences, the UR5 against its DH closed form, camera
//! and hand frame conventions, and the chain / tree API.

use nalgebra::{
    Isometry3, Matrix4, Matrix6xX, Point3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3,
    Vector6,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{FRAC_PI_2, PI};
use teleop_kinematics::{Chain, KinematicsError, Robot, robots};

fn random_in_limits(limits: &[teleop_kinematics::JointLimits], rng: &mut ChaCha8Rng) -> Vec<f64> {
    limits
        .iter()
        .map(|l| {
            if l.is_bounded() {
                rng.random_range(l.lower..=l.upper)
            } else {
                rng.random_range(-PI..=PI)
            }
        })
        .collect()
}

/// Central-difference Jacobian of a pose function: linear rows from the position,
/// angular rows from log(R(q+h) R(q-h)^T) / 2h.
fn numeric_jacobian(q: &[f64], pose: impl Fn(&[f64]) -> Isometry3<f64>) -> Matrix6xX<f64> {
    let h = 1e-6;
    let mut jac = Matrix6xX::zeros(q.len());
    let mut qp = q.to_vec();
    let mut qm = q.to_vec();
    for i in 0..q.len() {
        qp[i] = q[i] + h;
        qm[i] = q[i] - h;
        let (a, b) = (pose(&qp), pose(&qm));
        let lin = (a.translation.vector - b.translation.vector) / (2.0 * h);
        let ang = (a.rotation * b.rotation.inverse()).scaled_axis() / (2.0 * h);
        jac.fixed_view_mut::<3, 1>(0, i).copy_from(&lin);
        jac.fixed_view_mut::<3, 1>(3, i).copy_from(&ang);
        qp[i] = q[i];
        qm[i] = q[i];
    }
    jac
}

fn check_chain_jacobian(chain: &Chain, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits: Vec<_> = chain.limits().collect();
    let mut jac = Matrix6xX::zeros(chain.dof());
    for _ in 0..200 {
        let q = random_in_limits(&limits, &mut rng);
        let pose = chain
            .end_pose_and_jacobian_into(&q, &mut jac)
            .expect("sizes");
        let numeric = numeric_jacobian(&q, |q| chain.end_pose(q).expect("len"));
        let err = (&jac - &numeric).abs().max();
        assert!(
            err < 1e-6,
            "{} -> {}: analytic vs numeric Jacobian differ by {err:e}",
            chain.base_name(),
            chain.tip_name()
        );
        let plain = chain.end_pose(&q).expect("len");
        assert!((pose.translation.vector - plain.translation.vector).norm() < 1e-15);
    }
}

#[test]
fn ur5_camera_and_flange_jacobians_match_finite_differences() {
    let robot = robots::ur5().expect("embedded");
    check_chain_jacobian(&robot.chain("base_link", "tool0").expect("chain"), 1);
    check_chain_jacobian(
        &robot
            .chain("base_link", "camera_optical_frame")
            .expect("chain"),
        2,
    );
    // A chain that starts mid-arm is expressed in its own base frame.
    check_chain_jacobian(&robot.chain("upper_arm_link", "tool0").expect("chain"), 3);
}

#[test]
fn pr2_arm_jacobian_matches_finite_differences() {
    let robot = robots::pr2_arm().expect("embedded");
    let chain = robot.chain("base_link", "rh_palm").expect("chain");
    assert_eq!(chain.dof(), 7);
    check_chain_jacobian(&chain, 4);
    check_chain_jacobian(
        &robot.chain("torso_lift_link", "rh_fftip").expect("chain"),
        5,
    );
}

#[test]
fn shadow_fingertip_jacobians_match_finite_differences() {
    let robot = robots::shadow_hand().expect("embedded");
    for (i, tip) in robots::shadow::TIPS.iter().enumerate() {
        let chain = robot.chain("rh_forearm", tip).expect("chain");
        check_chain_jacobian(&chain, 10 + i as u64);
    }
}

/// The tree Jacobian of a link (all 19 hand DoF as columns) equals the chain Jacobian
/// in the chain's columns, is zero elsewhere, and matches finite differences for a
/// point offset in the link.
#[test]
fn tree_jacobian_matches_chain_and_finite_differences() {
    let robot = robots::shadow_hand().expect("embedded");
    let mut state = robot.new_state();
    let limits: Vec<_> = robot.dof_limits().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut jac = Matrix6xX::zeros(robot.dof());
    let offset = Point3::new(0.003, -0.004, 0.005);
    for _ in 0..100 {
        let q = random_in_limits(&limits, &mut rng);
        robot.update(&mut state, &q).expect("len");
        for tip in robots::shadow::TIPS {
            let link = robot.link_id(tip).expect("tip");
            let chain = robot.chain("rh_forearm", tip).expect("chain");
            let p = robot
                .link_jacobian_into(&state, link, &Point3::origin(), &mut jac)
                .expect("cols");
            let mut qc = vec![0.0; chain.dof()];
            chain.gather(&q, &mut qc).expect("len");
            let (pose, cj) = chain.end_pose_and_jacobian(&qc).expect("len");
            assert!((pose.translation.vector - p.coords).norm() < 1e-14);
            let moving = robot.dofs_moving(link);
            for (c, j) in chain.joints().iter().enumerate() {
                assert_eq!(moving[c], j.robot_dof);
                let diff = (jac.column(j.robot_dof) - cj.column(c)).abs().max();
                assert!(diff < 1e-14, "{tip}: column {c} differs by {diff:e}");
            }
            for col in 0..robot.dof() {
                if !moving.contains(&col) {
                    assert_eq!(jac.column(col).abs().max(), 0.0);
                }
            }
            // Offset point: linear part against finite differences over the whole tree.
            robot
                .link_jacobian_into(&state, link, &offset, &mut jac)
                .expect("cols");
            let numeric = numeric_jacobian(&q, |q| {
                let mut s = robot.new_state();
                robot.update(&mut s, q).expect("len");
                robot.link_pose(&s, link) * Translation3::from(offset.coords)
            });
            let err = (&jac - &numeric).abs().max();
            assert!(err < 1e-6, "{tip}: tree Jacobian vs numeric {err:e}");
        }
    }
}

/// Universal Robots' standard DH closed form: T = prod Rz(theta) Tz(d) Tx(a) Rx(alpha).
fn ur5_dh(q: &[f64; 6]) -> Matrix4<f64> {
    const D: [f64; 6] = [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823];
    const A: [f64; 6] = [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0];
    const ALPHA: [f64; 6] = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let mut t = Matrix4::identity();
    for i in 0..6 {
        let (st, ct) = q[i].sin_cos();
        let (sa, ca) = ALPHA[i].sin_cos();
        #[rustfmt::skip]
        let a = Matrix4::new(
            ct, -st * ca,  st * sa, A[i] * ct,
            st,  ct * ca, -ct * sa, A[i] * st,
            0.0,      sa,       ca,      D[i],
            0.0,     0.0,      0.0,       1.0,
        );
        t *= a;
    }
    t
}

#[test]
fn ur5_flange_matches_dh_closed_form() {
    let chain = robots::ur5_flange_chain().expect("embedded");
    let configs: [[f64; 6]; 6] = [
        [0.0; 6],
        [0.1, -1.2, 1.3, -0.4, 0.5, 2.6],
        [PI / 2.0, -PI / 2.0, 0.0, -PI / 2.0, 0.0, 0.0],
        [-2.0, -0.7, -1.9, 3.0, -1.5, -6.0],
        [6.0, 5.0, -4.0, 3.0, -2.0, 1.0],
        [0.3, -2.2, 2.0, -1.4, -1.57, 0.8],
    ];
    for q in configs {
        let ours = chain.end_pose(&SVector::from(q)).to_homogeneous();
        let dh = ur5_dh(&q);
        let err = (ours - dh).abs().max();
        assert!(err < 1e-12, "q = {q:?}: URDF vs DH differ by {err:e}");
    }
    // Universal Robots' zero pose: flange at (a2 + a3, -(d4 + d6), d1 - d5).
    let zero = chain.end_pose(&SVector::zeros());
    let expected = Vector3::new(-0.81725, -0.19145, 0.089159 - 0.09465);
    assert!((zero.translation.vector - expected).norm() < 1e-12);
}

#[test]
fn camera_optical_axis_is_flange_z() {
    let robot = robots::ur5().expect("embedded");
    let mut state = robot.new_state();
    let flange = robot.link_id(robots::ur5::FLANGE).expect("flange");
    let cam = robot
        .link_id(robots::ur5::CAMERA_OPTICAL_FRAME)
        .expect("camera");
    let body = robot.link_id("camera_link").expect("camera_link");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let limits: Vec<_> = robot.dof_limits().collect();
    for _ in 0..100 {
        let q = random_in_limits(&limits, &mut rng);
        robot.update(&mut state, &q).expect("len");
        let f = robot.link_pose(&state, flange);
        let c = robot.link_pose(&state, cam);
        let b = robot.link_pose(&state, body);
        let rel = f.inverse() * c;
        // Optical frame: same axes as the flange, 32 mm out along the flange z.
        assert!(rel.rotation.angle() < 1e-12);
        assert!((rel.translation.vector - Vector3::new(0.0, 0.0, 0.032)).norm() < 1e-12);
        // REP 103 body frame: x forward = optical z.
        let fwd_body = b.rotation * Vector3::x();
        let fwd_optical = c.rotation * Vector3::z();
        assert!((fwd_body - fwd_optical).norm() < 1e-12);
    }
}

#[test]
fn shadow_hand_frame_conventions() {
    let robot = robots::shadow_hand().expect("embedded");
    let state = robot.new_state();
    let pose = |n: &str| {
        robot
            .link_pose(&state, robot.link_id(n).expect("link"))
            .translation
            .vector
    };
    // Fingers point along +z, thumb on +x, FF on +x of LF.
    assert!(pose("rh_fftip").z > 0.2);
    assert!(pose("rh_thtip").x > 0.05);
    assert!(pose("rh_ffmcp").x > pose("rh_lfmcp").x);
    // J1 at 20 deg bends the BioTac towards the palm (-y): tip below the DIP frame.
    let dip = pose("rh_ffdip");
    let tip = pose("rh_fftip");
    let bend = ((tip - dip).y / (tip - dip).norm()).asin();
    assert!(
        (bend + robots::shadow::J1_FIXED_RAD).abs() < 1e-12,
        "bend {bend}"
    );
    // Flexing FFJ3 moves the fingertip towards -y (the palm side).
    let mut q = robot.neutral_positions();
    q[robot.dof_index("rh_FFJ3").expect("joint")] = 1.0;
    let mut s = robot.new_state();
    robot.update(&mut s, &q).expect("len");
    let flexed = robot
        .link_pose(&s, robot.link_id("rh_fftip").expect("tip"))
        .translation
        .vector;
    assert!(flexed.y < tip.y - 0.03);
}

#[test]
fn pr2_hand_mount_is_palm_down_and_forward() {
    let robot = robots::pr2_arm().expect("embedded");
    let state = robot.new_state();
    let palm = robot.link_pose(&state, robot.link_id("rh_palm").expect("palm"));
    let fingers = palm.rotation * Vector3::z();
    let palm_normal = palm.rotation * -Vector3::y();
    assert!((fingers - Vector3::x()).norm() < 1e-12);
    assert!((palm_normal - -Vector3::z()).norm() < 1e-12);
    // Shoulder 0.188 m right of the torso, wrist at 0.1 + 0.4 + 0.321 m forward of it.
    let wrist = robot.link_pose(&state, robot.link_id("rh_forearm").expect("mount"));
    let expected = Vector3::new(-0.05 + 0.1 + 0.4 + 0.321, -0.188, 0.739675);
    assert!((wrist.translation.vector - expected).norm() < 1e-12);
}

#[test]
fn fixed_chain_agrees_with_dynamic_chain() {
    let dynamic = robots::pr2_arm()
        .expect("embedded")
        .chain("base_link", "rh_palm")
        .expect("chain");
    let fixed = dynamic.fixed::<7>().expect("7 DoF");
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let limits: Vec<_> = dynamic.limits().collect();
    for _ in 0..100 {
        let q = random_in_limits(&limits, &mut rng);
        let qs = SVector::<f64, 7>::from_column_slice(&q);
        let (p1, j1): (Isometry3<f64>, SMatrix<f64, 6, 7>) = fixed.end_pose_and_jacobian(&qs);
        let (p2, j2) = dynamic.end_pose_and_jacobian(&q).expect("len");
        assert_eq!(p1, p2);
        assert_eq!(j1.as_slice(), j2.as_slice());
        assert!(fixed.within_limits(&qs));
    }
    let over = SVector::<f64, 7>::repeat(10.0);
    let clamped = fixed.clamp(&over);
    assert!(fixed.within_limits(&clamped));
    assert_eq!(clamped[4], 10.0, "forearm roll is continuous");
    assert_eq!(fixed.upper_limits()[0], 0.7146018366);
    assert_eq!(fixed.velocity_limits()[0], 2.088);
}

#[test]
fn chain_frames_end_in_the_tip_pose() {
    let chain = robots::ur5()
        .expect("embedded")
        .chain("base_link", "camera_optical_frame")
        .expect("chain");
    let q = [0.1, -1.0, 1.2, 0.3, -0.4, 0.5];
    let mut frames = [Isometry3::identity(); 7];
    chain.frames_into(&q, &mut frames).expect("sizes");
    assert_eq!(frames[6], chain.end_pose(&q).expect("len"));
    let names: Vec<&str> = chain.joint_names().collect();
    assert_eq!(names, teleop_interfaces::joints::UR5_JOINTS);
}

#[test]
fn wrong_sizes_are_typed_errors() {
    let robot = robots::ur5().expect("embedded");
    let chain = robot.chain("base_link", "tool0").expect("chain");
    let mut state = robot.new_state();
    assert!(matches!(
        robot.update(&mut state, &[0.0; 5]),
        Err(KinematicsError::JointCount {
            expected: 6,
            actual: 5
        })
    ));
    assert!(matches!(
        chain.end_pose(&[0.0; 7]),
        Err(KinematicsError::JointCount { .. })
    ));
    let mut narrow = Matrix6xX::zeros(5);
    assert!(matches!(
        chain.end_pose_and_jacobian_into(&[0.0; 6], &mut narrow),
        Err(KinematicsError::JacobianColumns {
            expected: 6,
            actual: 5
        })
    ));
    assert!(matches!(
        robot.link_jacobian_into(&state, robot.root(), &Point3::origin(), &mut narrow),
        Err(KinematicsError::JacobianColumns { .. })
    ));
    assert!(matches!(
        chain.fixed::<7>(),
        Err(KinematicsError::ChainDof {
            expected: 7,
            actual: 6,
            ..
        })
    ));
    assert!(matches!(
        robot.chain("tool0", "base_link"),
        Err(KinematicsError::NotAncestor { .. })
    ));
    assert!(matches!(
        robot.chain("base_link", "gripper"),
        Err(KinematicsError::UnknownLink { link }) if link == "gripper"
    ));
}

#[test]
fn prismatic_joints_translate_along_their_axis() {
    let urdf = r#"<robot name="slider">
      <link name="a"/><link name="b"/><link name="c"/>
      <joint name="slide" type="prismatic">
        <parent link="a"/><child link="b"/>
        <origin xyz="0 0 1" rpy="0 0 1.5707963267948966"/>
        <axis xyz="1 0 0"/>
        <limit lower="0" upper="0.5" effort="1" velocity="1"/>
      </joint>
      <joint name="turn" type="continuous">
        <parent link="b"/><child link="c"/>
        <origin xyz="0.2 0 0"/>
        <axis xyz="0 0 2"/>
      </joint>
    </robot>"#;
    let robot = Robot::from_urdf_str(urdf).expect("valid");
    let chain = robot.chain("a", "c").expect("chain");
    let (pose, jac) = chain.end_pose_and_jacobian(&[0.3, 0.7]).expect("len");
    // Slide along the rotated x (= world y), then 0.2 m further along it.
    assert!((pose.translation.vector - Vector3::new(0.0, 0.5, 1.0)).norm() < 1e-12);
    let expected_slide = Vector6::new(0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
    assert!((jac.column(0) - expected_slide).norm() < 1e-12);
    let expected_turn = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    assert!((jac.column(1) - expected_turn).norm() < 1e-12);
    let numeric = numeric_jacobian(&[0.3, 0.7], |q| chain.end_pose(q).expect("len"));
    assert!((jac - numeric).abs().max() < 1e-6);
    let expected = UnitQuaternion::from_euler_angles(0.0, 0.0, FRAC_PI_2 + 0.7);
    assert!(pose.rotation.angle_to(&expected) < 1e-12);
}
