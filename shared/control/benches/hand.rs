//! One 17-joint step of each hand control law (and the hold), through
//! `HandController` with the default configuration. Goal: an adaptive step well below
//! 10 us (the hand's effort loop runs at 1 kHz).
//!
//! `cargo bench --workspace --bench hand`; medians are in
//! `$CARGO_TARGET_DIR/criterion/hand_17/<name>/new/estimates.json`.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::SVector;
use teleop_control::hand::{HandControllerConfig, HandMode, ShadowHandController};

const DT: f64 = 1e-3;

type State = (SVector<f64, 17>, SVector<f64, 17>, SVector<f64, 17>);

/// A moving hand: positions, velocities and targets of 1024 periods.
fn states() -> Vec<State> {
    (0..1024)
        .map(|k| {
            let t = k as f64 * DT;
            let q = SVector::from_fn(|i, _| 0.4 + 0.3 * (t * (1.0 + 0.1 * i as f64)).sin());
            let dq = SVector::from_fn(|i, _| 0.3 * (t * (1.0 + 0.1 * i as f64)).cos());
            let target = SVector::from_fn(|i, _| 0.45 + 0.3 * (t + 0.05 * i as f64).sin());
            (q, dq, target)
        })
        .collect()
}

fn hand(c: &mut Criterion) {
    let stream = states();
    let mut g = c.benchmark_group("hand_17");
    for (name, mode) in [
        ("position_step", HandMode::Position),
        ("fixed_impedance_step", HandMode::FixedImpedance),
        ("adaptive_step", HandMode::Adaptive),
    ] {
        let mut h = ShadowHandController::new(HandControllerConfig {
            mode,
            ..Default::default()
        })
        .expect("config");
        let mut k = 0;
        g.bench_function(name, |b| {
            b.iter(|| {
                k = (k + 1) % stream.len();
                let (q, dq, target) = &stream[k];
                black_box(h.step(
                    black_box(DT),
                    black_box(q),
                    black_box(dq),
                    black_box(target),
                ))
            })
        });
    }
    let mut h = ShadowHandController::new(HandControllerConfig::default()).expect("config");
    let mut k = 0;
    g.bench_function("adaptive_hold", |b| {
        b.iter(|| {
            k = (k + 1) % stream.len();
            let (q, dq, _) = &stream[k];
            black_box(h.hold(black_box(DT), black_box(q), black_box(dq)))
        })
    });
    g.finish();
}

criterion_group!(benches, hand);
criterion_main!(benches);
