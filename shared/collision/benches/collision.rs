//! Collision queries per call, on precomputed link poses (forward kinematics not
//! included), 1,024 seeded configurations cycled:
//!
//! * UR5 links vs. the operator-hand volume, the hand 0.2-0.6 m in front of the
//!   camera (how active vision sees it): whole-robot distance, boolean check, and the
//!   IK constraint on chain frames (what `Goal::MinDistance` calls N + 1 times per
//!   iteration);
//! * Shadow hand self-collision at configurations drawn uniformly within the limits
//!   (about two thirds of them colliding): boolean check, the same on the
//!   collision-free ones only (every pair must be tried), all colliding pairs,
//!   minimum distance.
//!
//! `cargo bench --workspace --bench collision`; medians are in
//! `$CARGO_TARGET_DIR/criterion/<group>/<name>/new/estimates.json`.
#![allow(missing_docs, clippy::unwrap_used)]

use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_collision::{ChainBodies, ChainVolumeDistance, ExternalVolume, robots};
use teleop_ik::DistanceConstraint;
use teleop_kinematics::{Robot, robots as kin};

const N_CONFIGS: usize = 1024;

fn random_q(robot: &Robot, rng: &mut ChaCha8Rng) -> Vec<f64> {
    robot
        .dof_limits()
        .map(|l| {
            let (lo, hi) = (l.lower.max(-3.2), l.upper.min(3.2));
            rng.random_range(lo..=hi)
        })
        .collect()
}

fn ur5(c: &mut Criterion) {
    let robot = kin::ur5().unwrap();
    let model = robots::ur5(&robot).unwrap();
    let chain = kin::ur5_camera_chain().unwrap();
    let bodies = Arc::new(ChainBodies::new(&model, &robot, &chain).unwrap());
    let optical = robot.link_id(kin::ur5::CAMERA_OPTICAL_FRAME).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let hand = ExternalVolume::hand_volume(Isometry3::identity(), 0.02).unwrap();
    let cases: Vec<_> = (0..N_CONFIGS)
        .map(|_| {
            let q = random_q(&robot, &mut rng);
            let poses = robot.forward_kinematics(&q).unwrap();
            let gap = rng.random_range(0.2..0.6);
            let roll = rng.random_range(-3.1..3.1);
            let wrist = poses[optical.index()]
                * Translation3::new(0.0, 0.0, gap)
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll)
                * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.57);
            let qv = SVector::<f64, 6>::from_column_slice(&q);
            let mut frames = [Isometry3::identity(); 7];
            chain
                .chain()
                .frames_into(qv.as_slice(), &mut frames)
                .unwrap();
            let constraint = ChainVolumeDistance::new(bodies.clone(), hand.at(wrist).unwrap());
            (poses, hand.at(wrist).unwrap(), frames, constraint)
        })
        .collect();
    let mut g = c.benchmark_group("ur5_hand_volume");
    let mut i = 0;
    g.bench_function("volume_distance", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            let (poses, vol, _, _) = &cases[i];
            black_box(model.volume_distance(black_box(poses), vol).unwrap())
        })
    });
    g.bench_function("collides_with", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            let (poses, vol, _, _) = &cases[i];
            black_box(model.collides_with(black_box(poses), vol).unwrap())
        })
    });
    g.bench_function("chain_constraint_distance", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            let (_, _, frames, constraint) = &cases[i];
            black_box(constraint.distance(black_box(frames)))
        })
    });
    g.finish();
}

fn shadow(c: &mut Criterion) {
    let robot = kin::shadow_hand().unwrap();
    let model = robots::shadow_hand(&robot).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let poses: Vec<_> = (0..N_CONFIGS)
        .map(|_| {
            robot
                .forward_kinematics(&random_q(&robot, &mut rng))
                .unwrap()
        })
        .collect();
    // The collision-free ones (what a controller validating a good command sees; the
    // boolean check must then try every pair), cycled to the same count.
    let free: Vec<_> = poses
        .iter()
        .filter(|p| !model.in_self_collision(p).unwrap())
        .cloned()
        .collect();
    println!(
        "shadow: {} checked pairs, {}/{N_CONFIGS} sampled configurations in self-collision",
        model.checked_pairs().len(),
        N_CONFIGS - free.len()
    );
    let free: Vec<_> = free.iter().cycle().take(N_CONFIGS).cloned().collect();
    let mut g = c.benchmark_group("shadow_self_collision");
    let mut i = 0;
    g.bench_function("in_self_collision", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(model.in_self_collision(black_box(&poses[i])).unwrap())
        })
    });
    g.bench_function("in_self_collision_free", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(model.in_self_collision(black_box(&free[i])).unwrap())
        })
    });
    g.bench_function("self_collisions", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(model.self_collisions(black_box(&poses[i])).unwrap())
        })
    });
    g.bench_function("self_distance", |b| {
        b.iter(|| {
            i = (i + 1) % N_CONFIGS;
            black_box(model.self_distance(black_box(&poses[i])).unwrap())
        })
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(50)
}

criterion_group! { name = benches; config = config(); targets = ur5, shadow }
criterion_main!(benches);
