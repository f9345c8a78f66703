//! The system's robots: generated ACMs, self-collision, the operator-hand volume,
//! and the chain mapping the IK constraints use.
#![allow(clippy::unwrap_used)]

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use teleop_collision::{AllowReason, ChainBodies, ExternalVolume, robots};
use teleop_kinematics::{Robot, robots as kin};

fn names(robot: &Robot, a: teleop_kinematics::LinkId, b: teleop_kinematics::LinkId) -> String {
    format!("{} / {}", robot.link(a).name, robot.link(b).name)
}

fn ur5_at(robot: &Robot, q: [f64; 6]) -> Vec<Isometry3<f64>> {
    robot.forward_kinematics(&q).unwrap()
}

#[test]
fn ur5_zero_configuration_is_free_with_the_generated_acm() {
    let robot = kin::ur5().unwrap();
    let model = robots::ur5(&robot).unwrap();
    // Every link with geometry is a body; adjacent pairs are allowed.
    assert_eq!(model.bodies().len(), 8);
    let id = |n: &str| robot.link_id(n).unwrap();
    assert_eq!(
        model.allowed(id("upper_arm_link"), id("forearm_link")),
        Some(AllowReason::Adjacent)
    );
    // tool0 has no geometry: the camera mount is adjacent to wrist_3 through it.
    assert_eq!(
        model.allowed(id("wrist_3_link"), id("camera_mount")),
        Some(AllowReason::Adjacent)
    );
    assert_eq!(model.allowed(id("base_link"), id("forearm_link")), None);

    let poses = ur5_at(&robot, [0.0; 6]);
    assert!(!model.in_self_collision(&poses).unwrap());
    assert!(model.self_collisions(&poses).unwrap().is_empty());
    let closest = model.self_distance(&poses).unwrap().unwrap();
    assert!(closest.distance_m > 0.0, "{closest:?}");
    // The ACM is reproducible.
    let again = robots::ur5(&robot).unwrap();
    assert_eq!(
        model.allowed_pairs().collect::<Vec<_>>(),
        again.allowed_pairs().collect::<Vec<_>>()
    );
}

#[test]
fn ur5_folded_onto_itself_is_detected() {
    let robot = kin::ur5().unwrap();
    let model = robots::ur5(&robot).unwrap();
    // Upper arm horizontal, elbow folded back by 165 deg: the wrist and camera come
    // back onto the shoulder and upper arm.
    let poses = ur5_at(&robot, [0.0, -1.2, 2.9, -1.5, 1.5, 0.0]);
    let hits = model.self_collisions(&poses).unwrap();
    assert!(!hits.is_empty(), "folded arm not detected");
    assert!(model.in_self_collision(&poses).unwrap());
    for h in &hits {
        assert!(h.distance_m <= 0.0);
        assert_eq!(model.allowed(h.a, h.b), None, "{}", names(&robot, h.a, h.b));
    }
    let closest = model.self_distance(&poses).unwrap().unwrap();
    assert!(closest.distance_m <= 0.0);
    let deepest = hits
        .iter()
        .map(|h| h.distance_m)
        .fold(f64::INFINITY, f64::min);
    assert!((closest.distance_m - deepest).abs() < 1e-9);
}

fn shadow_q(robot: &Robot, joints: &[(&str, f64)]) -> Vec<Isometry3<f64>> {
    let mut q = robot.neutral_positions();
    for (name, v) in joints {
        q[robot.dof_index(name).unwrap()] = *v;
    }
    robot.forward_kinematics(&q).unwrap()
}

fn is_ff_mf(robot: &Robot, a: teleop_kinematics::LinkId, b: teleop_kinematics::LinkId) -> bool {
    let (a, b) = (&robot.link(a).name, &robot.link(b).name);
    (a.starts_with("rh_ff") && b.starts_with("rh_mf"))
        || (a.starts_with("rh_mf") && b.starts_with("rh_ff"))
}

#[test]
fn shadow_open_hand_is_free_and_curled_crossed_fingers_collide() {
    let robot = kin::shadow_hand().unwrap();
    let model = robots::shadow_hand(&robot).unwrap();
    // Allowed by hand (and, with the merged capsule's joint-end cap, already in
    // contact at the neutral configuration).
    assert!(
        model
            .allowed(
                robot.link_id("rh_palm").unwrap(),
                robot.link_id("rh_lfproximal").unwrap()
            )
            .is_some()
    );
    // Knuckles are joint crosses: the proximal phalanx is adjacent to the palm.
    assert_eq!(
        model.allowed(
            robot.link_id("rh_palm").unwrap(),
            robot.link_id("rh_ffproximal").unwrap()
        ),
        Some(AllowReason::Adjacent)
    );
    // Finger against finger stays checked.
    assert_eq!(
        model.allowed(
            robot.link_id("rh_ffproximal").unwrap(),
            robot.link_id("rh_mfproximal").unwrap()
        ),
        None
    );

    let open = shadow_q(&robot, &[]);
    assert!(!model.in_self_collision(&open).unwrap());
    let closest = model.self_distance(&open).unwrap().unwrap();
    assert!(closest.distance_m > 0.001, "{closest:?}");

    // FF and MF flexed, their J4s turned toward each other (FFJ4 > 0 moves FF to -x,
    // MFJ4 < 0 moves MF to +x).
    let curled = shadow_q(
        &robot,
        &[
            ("rh_FFJ4", 0.3),
            ("rh_FFJ3", 1.2),
            ("rh_FFJ2", 1.0),
            ("rh_MFJ4", -0.3),
            ("rh_MFJ3", 1.2),
            ("rh_MFJ2", 1.0),
        ],
    );
    let hits = model.self_collisions(&curled).unwrap();
    assert!(
        hits.iter().any(|h| is_ff_mf(&robot, h.a, h.b)),
        "{:?}",
        hits.iter()
            .map(|h| names(&robot, h.a, h.b))
            .collect::<Vec<_>>()
    );
    let closest = model.self_distance(&curled).unwrap().unwrap();
    assert!(closest.distance_m <= 0.0);

    // The same flexion with the J4s turned apart leaves a gap between FF and MF.
    let apart = shadow_q(
        &robot,
        &[
            ("rh_FFJ4", -0.3),
            ("rh_FFJ3", 1.2),
            ("rh_FFJ2", 1.0),
            ("rh_MFJ4", 0.0),
            ("rh_MFJ3", 1.2),
            ("rh_MFJ2", 1.0),
        ],
    );
    let hits = model.self_collisions(&apart).unwrap();
    assert!(
        !hits.iter().any(|h| is_ff_mf(&robot, h.a, h.b)),
        "{:?}",
        hits.iter()
            .map(|h| names(&robot, h.a, h.b))
            .collect::<Vec<_>>()
    );
}

#[test]
fn pr2_model_builds_and_its_neutral_pose_is_free() {
    let robot = kin::pr2_arm().unwrap();
    let model = robots::pr2_arm(&robot).unwrap();
    let poses = robot
        .forward_kinematics(&robot.neutral_positions())
        .unwrap();
    assert!(!model.in_self_collision(&poses).unwrap());
}

/// Hand frame at the camera: fingers along the image's -y, palm normal along the
/// optical axis, `gap_m` in front of the camera housing's front face.
fn hand_in_front_of_camera(optical: &Isometry3<f64>, gap_m: f64) -> Isometry3<f64> {
    // Thickness 0.05 along the optical axis: the near face is at gap_m.
    optical
        * Translation3::new(0.0, 0.0, gap_m + 0.025)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
}

#[test]
fn hand_volume_at_the_ur5_flange_is_detected() {
    let robot = kin::ur5().unwrap();
    let model = robots::ur5(&robot).unwrap();
    // Camera at (-0.44, -0.11, 0.63) looking horizontally away from the base (-x).
    let q = [0.0, -1.57, 1.0, 0.57, 1.57, 0.0];
    let poses = ur5_at(&robot, q);
    let flange = poses[robot.link_id(kin::ur5::FLANGE).unwrap().index()];
    let optical = poses[robot
        .link_id(kin::ur5::CAMERA_OPTICAL_FRAME)
        .unwrap()
        .index()];

    // Wrist on the flange: the hand overlaps the camera and the wrist links.
    let on_flange = ExternalVolume::hand_volume(flange, 0.02).unwrap();
    assert!(model.collides_with(&poses, &on_flange).unwrap());
    let p = model.volume_distance(&poses, &on_flange).unwrap().unwrap();
    assert!(p.distance_m < 0.0, "{p:?}");

    // 0.4 m in front of the camera (the thesis' camera distance), 5 cm margin: the
    // housing's front face (z = 0 in the optical frame) is 0.4 - 0.05 from the grown
    // box face.
    let margin = 0.05;
    let front =
        ExternalVolume::hand_volume(hand_in_front_of_camera(&optical, 0.4), margin).unwrap();
    assert!(!model.collides_with(&poses, &front).unwrap());
    let p = model.volume_distance(&poses, &front).unwrap().unwrap();
    assert!(
        (p.distance_m - (0.4 - margin)).abs() < 1e-5,
        "{} from {}",
        p.distance_m,
        robot.link(p.link).name
    );
    assert_eq!(robot.link(p.link).name, "camera_mount");

    // Moving the same volume to 3 cm (inside the margin) is a collision.
    let near = front.at(hand_in_front_of_camera(&optical, 0.03)).unwrap();
    assert!(model.collides_with(&poses, &near).unwrap());
    let p = model.volume_distance(&poses, &near).unwrap().unwrap();
    assert!((p.distance_m - (0.03 - margin)).abs() < 1e-5, "{p:?}");
}

#[test]
fn chain_mapping_reproduces_forward_kinematics() {
    // PR2 arm chain: the Shadow fingers hang below the chain's last joint (WRJ1) via
    // joints outside the chain, frozen at the rest configuration.
    let robot = kin::pr2_arm().unwrap();
    let model = robots::pr2_arm(&robot).unwrap();
    let chain = kin::pr2_arm_chain().unwrap();
    let mut rest = robot.neutral_positions();
    rest[robot.dof_index("rh_FFJ3").unwrap()] = 0.7;
    rest[robot.dof_index("rh_THJ5").unwrap()] = -0.4;
    let bodies = ChainBodies::with_rest(&model, &robot, &chain, &rest).unwrap();
    let moving: Vec<_> = bodies.moving_links().collect();
    assert!(moving.contains(&robot.link_id("rh_ffdistal").unwrap()));
    assert!(moving.contains(&robot.link_id("r_upper_arm_link").unwrap()));
    assert!(!moving.contains(&robot.link_id("base_link").unwrap()));
    assert!(!moving.contains(&robot.link_id("torso_lift_link").unwrap()));

    for seed in 0..20u64 {
        let q = SVector::<f64, 7>::from_fn(|i, _| {
            let l = chain.joints()[i].limits;
            let (lo, hi) = (l.lower.max(-3.0), l.upper.min(3.0));
            lo + (hi - lo) * (((seed * 7 + i as u64) * 2_654_435_761 % 1000) as f64 / 1000.0)
        });
        let mut full = rest.clone();
        for (j, v) in chain.joints().iter().zip(q.iter()) {
            full[j.robot_dof] = *v;
        }
        let fk = robot.forward_kinematics(&full).unwrap();
        let base_inv = fk[chain.chain().base().index()].inverse();
        let mut frames = [Isometry3::identity(); 8];
        chain
            .chain()
            .frames_into(q.as_slice(), &mut frames)
            .unwrap();
        let poses = bodies.link_poses(&frames).unwrap();
        assert_eq!(poses.len(), model.bodies().len());
        for (link, pose) in poses {
            let expected = base_inv * fk[link.index()];
            let err = (pose.translation.vector - expected.translation.vector).norm()
                + pose.rotation.angle_to(&expected.rotation);
            assert!(err < 1e-12, "{}: {err}", robot.link(link).name);
        }
    }
    // Too few frames is an error, not a panic.
    assert!(bodies.link_poses(&[Isometry3::identity(); 3]).is_err());
}
