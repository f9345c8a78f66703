//! One step of each filter.
//!
//! `cargo bench --workspace --bench filters`; medians are in
//! `$CARGO_TARGET_DIR/criterion/<group>/<name>/new/estimates.json`.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion};
use teleop_control::{
    CartesianLimiter, CartesianLimits, JointLimiterConfig, JointLimits, JointVelocityLimiter,
    JumpFilter, JumpFilterConfig, VelocityLimitStrategy,
};

const DT: f64 = 1.0 / 30.0;

/// A slowly moving pose stream (the filters see realistic, accepted input).
fn poses(n: usize) -> Vec<Isometry3<f64>> {
    (0..n)
        .map(|k| {
            let t = k as f64 * DT;
            Isometry3::from_parts(
                Translation3::new(0.3 * t.sin(), 0.2 * (0.7 * t).cos(), 1.0 + 0.1 * t.sin()),
                UnitQuaternion::from_euler_angles(0.5 * t.sin(), 0.3 * t.cos(), 0.2 * t),
            )
        })
        .collect()
}

fn jump(c: &mut Criterion) {
    let stream = poses(1024);
    let mut f = JumpFilter::new(JumpFilterConfig::default()).expect("config");
    let mut k = 0;
    let mut g = c.benchmark_group("jump_filter");
    g.bench_function("filter", |b| {
        b.iter(|| {
            k = (k + 1) % stream.len();
            black_box(f.filter(black_box(&stream[k])))
        })
    });
    g.finish();
}

fn cartesian(c: &mut Criterion) {
    let stream = poses(1024);
    let mut g = c.benchmark_group("cartesian_limiter");
    for (name, limits) in [
        ("step", CartesianLimits::default()),
        (
            "step_angular_accel",
            CartesianLimits {
                max_angular_acceleration_rad_s2: Some(5.0),
                ..Default::default()
            },
        ),
    ] {
        let mut l = CartesianLimiter::new(limits, &stream[0]).expect("limits");
        let mut k = 0;
        g.bench_function(name, |b| {
            b.iter(|| {
                k = (k + 1) % stream.len();
                black_box(l.step(black_box(&stream[k]), black_box(DT)))
            })
        });
    }
    g.finish();
}

fn joint<const N: usize>(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    strategy: VelocityLimitStrategy,
) {
    let limits = JointLimits::<N>::uniform_velocity(3.0)
        .with_position_limits(SVector::repeat(-3.0), SVector::repeat(3.0))
        .with_acceleration_limits(SVector::repeat(10.0));
    let config = JointLimiterConfig {
        strategy,
        ..Default::default()
    };
    let mut l = JointVelocityLimiter::new(limits, config).expect("limits");
    let commands: Vec<SVector<f64, N>> = (0..1024)
        .map(|k| SVector::from_fn(|i, _| 4.0 * ((k * (i + 1)) as f64 * 0.01).sin()))
        .collect();
    let q = SVector::<f64, N>::from_fn(|i, _| 0.3 * i as f64 - 1.0);
    let mut k = 0;
    g.bench_function(name, |b| {
        b.iter(|| {
            k = (k + 1) % commands.len();
            black_box(l.step(black_box(&commands[k]), black_box(&q), black_box(DT)))
        })
    });
}

fn joints(c: &mut Criterion) {
    let mut g = c.benchmark_group("joint_limiter");
    joint::<6>(&mut g, "ur5_6_scale", VelocityLimitStrategy::ScaleUniformly);
    joint::<6>(&mut g, "ur5_6_clamp", VelocityLimitStrategy::Clamp);
    joint::<7>(&mut g, "pr2_7_scale", VelocityLimitStrategy::ScaleUniformly);
    g.finish();
}

criterion_group!(benches, jump, cartesian, joints);
criterion_main!(benches);
