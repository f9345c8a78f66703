//! The analytic capsule distances of the simulator against parry3d's.
#![allow(clippy::unwrap_used)]

use nalgebra::{Point3, Vector3};
use parry3d::math::{Pose, Vector};
use parry3d::shape::{Ball, Capsule as ParryCapsule, Segment};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_sim::geometry::{Capsule, capsule_distance, penetration};

fn v(p: &Point3<f64>) -> Vector {
    Vector::new(p.x as f32, p.y as f32, p.z as f32)
}

fn random_capsule(rng: &mut ChaCha8Rng, ball: bool) -> Capsule {
    let mut p = || {
        Point3::new(
            rng.random_range(-0.05..0.05),
            rng.random_range(-0.05..0.05),
            rng.random_range(-0.05..0.05),
        )
    };
    let a = p();
    let b = if ball { a } else { p() };
    Capsule {
        a,
        b,
        radius_m: 0.005 + 0.01 * rng.random::<f64>(),
    }
}

#[test]
fn distances_match_parry3d() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut checked = 0;
    let mut parry_off = 0;
    let mut worst: f64 = 0.0;
    for k in 0..2000 {
        let c1 = random_capsule(&mut rng, false);
        let c2 = random_capsule(&mut rng, k % 3 == 0);
        let ours = capsule_distance(&c1, &c2);
        let id = Pose::IDENTITY;
        // parry's analytic paths: segment-segment closest points, and ball-vs-capsule
        // point projection. (Its capsule-capsule path is GJK; see the test below.)
        let theirs = if c2.a == c2.b {
            let s1 = ParryCapsule::new(v(&c1.a), v(&c1.b), c1.radius_m as f32);
            let ball = Ball::new(c2.radius_m as f32);
            parry3d::query::distance(&id, &s1, &Pose::from_translation(v(&c2.a)), &ball)
                .unwrap()
                .distance
        } else {
            let s1 = Segment::new(v(&c1.a), v(&c1.b));
            let s2 = Segment::new(v(&c2.a), v(&c2.b));
            let d = parry3d::query::distance(&id, &s1, &id, &s2)
                .unwrap()
                .distance;
            (d - (c1.radius_m + c2.radius_m) as f32).max(0.0)
        };
        // Brute force over the two segments.
        let mut brute = f64::INFINITY;
        for i in 0..=400 {
            let p1 = c1.a + (c1.b - c1.a) * (f64::from(i) / 400.0);
            for j in 0..=400 {
                let p2 = c2.a + (c2.b - c2.a) * (f64::from(j) / 400.0);
                brute = brute.min((p2 - p1).norm());
            }
        }
        let brute = brute - c1.radius_m - c2.radius_m;
        assert!(
            brute >= ours - 1e-12 && brute - ours < 2e-4,
            "brute {brute} vs {ours}"
        );
        if ours > 0.0 {
            checked += 1;
            let gap = (ours - f64::from(theirs)).abs();
            if c2.a == c2.b {
                // Ball vs capsule: parry's analytic point projection, f32 rounding only.
                assert!(gap < 1e-6, "{ours} vs {theirs}: {c1:?} {c2:?}");
            } else if gap > 1e-6 {
                parry_off += 1;
                worst = worst.max(gap);
            }
        } else {
            assert!(theirs <= 1e-5);
            let p = penetration(&c1, &c2, &Vector3::z()).unwrap();
            assert!((p.depth_m + ours).abs() < 1e-15);
            assert!((p.normal.norm() - 1.0).abs() < 1e-12);
        }
    }
    // parry 0.31's segment-segment distance disagrees with the exact (brute-force
    // confirmed) value on some pairs; recorded for the report, not asserted.
    println!("parry segment pairs off by > 1e-6 m: {parry_off} of {checked}, worst {worst:.2e} m");
    assert!(checked > 500);
}

/// Why the simulator does not use parry's `query::distance`/`contact` for capsule pairs:
/// that path is GJK in f32, and on some separated pairs it is far off the exact value
/// (found by the test above before it switched to segment pairs). Recorded, not asserted
/// as a parry property: this only documents the case.
#[test]
fn parry_gjk_capsule_case_on_record() {
    let c1 = Capsule {
        a: Point3::new(
            0.007720913713370782,
            -0.04005404771688906,
            -0.02360824318658037,
        ),
        b: Point3::new(
            -0.004654027534465775,
            -0.021977127472603764,
            0.04910323734014958,
        ),
        radius_m: 0.014123549281413305,
    };
    let c2 = Capsule {
        a: Point3::new(
            0.044711747690697454,
            -0.036675608757469204,
            -0.015631588872952108,
        ),
        b: Point3::new(
            -0.0019697752733520008,
            -0.010266556377469385,
            -0.04863024572996766,
        ),
        radius_m: 0.005489196842054948,
    };
    let ours = capsule_distance(&c1, &c2);
    let id = Pose::IDENTITY;
    let seg = parry3d::query::distance(
        &id,
        &Segment::new(v(&c1.a), v(&c1.b)),
        &id,
        &Segment::new(v(&c2.a), v(&c2.b)),
    )
    .unwrap()
    .distance;
    let gjk = parry3d::query::distance(
        &id,
        &ParryCapsule::new(v(&c1.a), v(&c1.b), c1.radius_m as f32),
        &id,
        &ParryCapsule::new(v(&c2.a), v(&c2.b), c2.radius_m as f32),
    )
    .unwrap()
    .distance;
    let seg = f64::from(seg) - c1.radius_m - c2.radius_m;
    assert!((ours - seg).abs() < 1e-6, "{ours} vs {seg}");
    println!("exact {ours:.6} m, parry segment path {seg:.6} m, parry capsule GJK {gjk:.6} m");
}
