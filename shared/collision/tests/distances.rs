//! Distances against analytic values, on small URDFs written for the purpose.
#![allow(clippy::unwrap_used)]

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use teleop_collision::{AllowReason, CollisionError, CollisionModel, ExternalVolume, Primitive};
use teleop_kinematics::Robot;

/// Root `a` with a sphere of radius 0.1 at its origin; link `b` on a prismatic x joint
/// with `b_geometry` at its origin; link `c` fixed 1 m up with a small sphere (so the
/// a-b pair is not adjacent: b hangs off c).
fn robot(b_geometry: &str) -> Robot {
    let urdf = format!(
        r#"<robot name="probe">
  <link name="a"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
  <link name="c"><collision><geometry><sphere radius="0.01"/></geometry></collision></link>
  <link name="b"><collision><geometry>{b_geometry}</geometry></collision></link>
  <joint name="up" type="fixed"><parent link="a"/><child link="c"/><origin xyz="0 0 1"/></joint>
  <joint name="slide" type="prismatic"><parent link="c"/><child link="b"/>
    <origin xyz="0 0 -1"/><axis xyz="1 0 0"/><limit lower="0.5" upper="5" effort="1" velocity="1"/></joint>
</robot>"#
    );
    Robot::from_urdf_str(&urdf).unwrap()
}

#[test]
fn sphere_sphere_self_distance_is_centre_distance_minus_radii() {
    let r = robot(r#"<sphere radius="0.05"/>"#);
    let m = CollisionModel::new(&r).unwrap();
    let (a, b) = (r.link_id("a").unwrap(), r.link_id("b").unwrap());
    assert_eq!(m.allowed(a, b), None, "a-b must be checked");
    assert_eq!(
        m.allowed(a, r.link_id("c").unwrap()),
        Some(AllowReason::Adjacent)
    );
    for x in [1.0, 0.3, 0.151, 0.149, 0.1, 0.02] {
        let poses = r.forward_kinematics(&[x]).unwrap();
        let p = m.self_distance(&poses).unwrap().unwrap();
        assert!(
            (p.distance_m - (x - 0.15)).abs() < 1e-6,
            "x {x}: {}",
            p.distance_m
        );
        assert_eq!((p.a, p.b), (a, b));
        let colliding = m.self_collisions(&poses).unwrap();
        assert_eq!(m.in_self_collision(&poses).unwrap(), x <= 0.15);
        assert_eq!(colliding.len(), usize::from(x <= 0.15));
        if let Some(c) = colliding.first() {
            assert!((c.distance_m - (x - 0.15)).abs() < 1e-6);
        }
    }
}

#[test]
fn sphere_against_a_sphere_volume() {
    let r = robot(r#"<sphere radius="0.05"/>"#);
    let m = CollisionModel::new(&r).unwrap();
    let poses = r.forward_kinematics(&[0.5]).unwrap();
    // Volume ball r = 0.02 (+ 0.01 margin) at (0.5, 0.4, 0): 0.4 - 0.05 - 0.03 from b.
    let v = ExternalVolume::new(Isometry3::translation(0.5, 0.4, 0.0))
        .unwrap()
        .with(
            Primitive::Sphere { radius_m: 0.02 },
            Isometry3::identity(),
            0.01,
        )
        .unwrap();
    let p = m.volume_distance(&poses, &v).unwrap().unwrap();
    assert!((p.distance_m - 0.32).abs() < 1e-6, "{}", p.distance_m);
    assert_eq!(p.link, r.link_id("b").unwrap());
    assert_eq!(p.volume_shape, 0);
    assert!(!m.collides_with(&poses, &v).unwrap());
}

#[test]
fn capsule_against_a_box_volume() {
    // Capsule: radius 0.03, cylinder part 0.2 long along z (segment z in [-0.1, 0.1]),
    // slid to x = 2 so sphere `a` at the origin is far away.
    let r = robot(r#"<capsule radius="0.03" length="0.2"/>"#);
    let m = CollisionModel::new(&r).unwrap();
    let poses = r.forward_kinematics(&[2.0]).unwrap();
    let half = Vector3::new(0.05, 0.04, 0.06);
    let boxed = |pose: Isometry3<f64>| {
        ExternalVolume::new(pose)
            .unwrap()
            .with(
                Primitive::Box {
                    half_extents_m: half,
                },
                Isometry3::identity(),
                0.0,
            )
            .unwrap()
    };
    let b = r.link_id("b").unwrap();
    let dist = |v: &ExternalVolume| {
        let p = m.volume_distance(&poses, v).unwrap().unwrap();
        assert_eq!(p.link, b);
        assert_eq!(m.collides_with(&poses, v).unwrap(), p.distance_m <= 0.0);
        p.distance_m
    };
    // Beside the capsule's side: face to cylinder, x0 - a - r.
    let d = dist(&boxed(Isometry3::translation(2.3, 0.0, 0.05)));
    assert!((d - (0.3 - 0.05 - 0.03)).abs() < 1e-6, "{d}");
    // Above and beside: box edge (x0 - a, z0 - c) to the segment end (0, 0, 0.1).
    let (x0, z0) = (0.25, 0.4);
    let expected = (x0 - half.x).hypot(z0 - half.z - 0.1) - 0.03;
    let d = dist(&boxed(Isometry3::translation(2.0 + x0, 0.0, z0)));
    assert!((d - expected).abs() < 1e-5, "{d} vs {expected}");
    // Box turned 90 deg about z (its x half-extent now along y), beside along y.
    let turned = Isometry3::from_parts(
        Translation3::new(2.0, 0.3, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
    );
    let d = dist(&boxed(turned));
    assert!((d - (0.3 - 0.05 - 0.03)).abs() < 1e-6, "{d}");
    // Straight above the segment end: z0 - c - 0.1 - r.
    let d = dist(&boxed(Isometry3::translation(2.0, 0.0, 0.5)));
    assert!((d - (0.5 - 0.06 - 0.1 - 0.03)).abs() < 1e-6, "{d}");
}

#[test]
fn penetration_depth_of_the_capsule_into_a_box() {
    // The same capsule alone (sphere `a` moved far away by a long slide).
    let r = robot(r#"<capsule radius="0.03" length="0.2"/>"#);
    let m = CollisionModel::new(&r).unwrap();
    let poses = r.forward_kinematics(&[2.0]).unwrap();
    let v = ExternalVolume::new(Isometry3::translation(2.0 + 0.07, 0.0, 0.0))
        .unwrap()
        .with(
            Primitive::Box {
                half_extents_m: Vector3::new(0.05, 0.2, 0.2),
            },
            Isometry3::identity(),
            0.0,
        )
        .unwrap();
    // Box face at x = 2.02, capsule side at x = 2.03: 1 cm deep.
    let p = m.volume_distance(&poses, &v).unwrap().unwrap();
    assert!((p.distance_m + 0.01).abs() < 1e-4, "{}", p.distance_m);
}

#[test]
fn manual_pairs_and_errors() {
    let r = robot(r#"<sphere radius="0.05"/>"#);
    let mut m = CollisionModel::new(&r).unwrap();
    let (a, b) = (r.link_id("a").unwrap(), r.link_id("b").unwrap());
    let n = m.checked_pairs().len();
    m.allow("a", "b").unwrap();
    assert_eq!(m.allowed(a, b), Some(AllowReason::User));
    assert_eq!(m.checked_pairs().len(), n - 1);
    let poses = r.forward_kinematics(&[0.0]).unwrap();
    assert!(!m.in_self_collision(&poses).unwrap());
    m.disallow("a", "b").unwrap();
    assert!(m.in_self_collision(&poses).unwrap());
    assert!(matches!(
        m.allow("a", "nope"),
        Err(CollisionError::UnknownLink { .. })
    ));
    assert!(matches!(
        m.self_distance(&poses[..2]),
        Err(CollisionError::PoseCount {
            expected: 3,
            actual: 2
        })
    ));
}

#[test]
fn meshes_are_refused_with_the_link_named() {
    let r = robot(r#"<mesh filename="package://x/y.stl"/>"#);
    match CollisionModel::new(&r) {
        Err(CollisionError::UnsupportedShape { link, shape }) => {
            assert_eq!(link, "b");
            assert!(shape.contains("y.stl"));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn cylinder_against_a_box_volume_within_gjk_tolerance() {
    // Cylinders go through GJK on a curved support map, which may stop at a relative
    // tolerance of ~1e-3 (parry's `sqrt(10 eps_f32)`): the distance is an upper bound.
    // Measured here: within 5e-7 m at 0.2 m.
    let r = robot(r#"<cylinder radius="0.03" length="0.2"/>"#);
    let m = CollisionModel::new(&r).unwrap();
    let poses = r.forward_kinematics(&[2.0]).unwrap();
    let half = Vector3::new(0.05, 0.04, 0.06);
    let mut worst: f64 = 0.0;
    for k in 0..24 {
        let yaw = f64::from(k) * 0.26;
        // Beside the side face along a direction turned by `yaw` about z: gap 0.2.
        let dir = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let pose = Isometry3::from_parts(
            Translation3::from(Vector3::new(2.0, 0.0, 0.0) + dir * (0.03 + 0.2 + half.x)),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        );
        let v = ExternalVolume::new(pose)
            .unwrap()
            .with(
                Primitive::Box {
                    half_extents_m: half,
                },
                Isometry3::identity(),
                0.0,
            )
            .unwrap();
        let d = m.volume_distance(&poses, &v).unwrap().unwrap().distance_m;
        let err = d - 0.2;
        assert!(err > -1e-6, "below the true distance: {err}");
        worst = worst.max(err);
    }
    assert!(worst < 1e-5, "{worst}");
}
