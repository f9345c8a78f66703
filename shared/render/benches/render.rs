//! Depth frames of the 40-primitive synthetic hand at 0.4 m, 640x480 and 96x96, with
//! the brute-force parry3d baseline (every pixel against every shape) in the same run.
//!
//! `cargo bench --workspace --bench render -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Isometry3;
use teleop_render::scenes::{hand_facing_camera, synthetic_hand};
use teleop_render::{
    Camera, Channels, DepthNoise, DepthRange, Frame, Intrinsics, NoiseParams, RayBackend, Renderer,
};

fn cameras() -> [(&'static str, Camera); 2] {
    // 96x96: the ~250 mm window around the hand at 0.4 m, resized (the network input).
    let crop = Intrinsics::sr300()
        .cropped(185, 105, 270, 270)
        .and_then(|k| k.resized(96, 96))
        .expect("crop fits the SR300 image");
    [
        ("640x480", Camera::default()),
        (
            "96x96",
            Camera::new(crop, DepthRange::sr300(), Isometry3::identity()),
        ),
    ]
}

fn bench(c: &mut Criterion) {
    let scene = synthetic_hand(&hand_facing_camera(0.4), 0.3).expect("hand scene");
    for (size, camera) in cameras() {
        let mut group = c.benchmark_group(format!("hand_{size}"));
        let cases = [
            ("analytic_depth", RayBackend::Analytic, Channels::DEPTH_ONLY),
            ("analytic_all_images", RayBackend::Analytic, Channels::ALL),
            (
                "parry_in_rect_depth",
                RayBackend::ParryInRect,
                Channels::DEPTH_ONLY,
            ),
        ];
        for (name, backend, channels) in cases {
            let mut renderer = Renderer::with_backend(backend);
            let mut frame = Frame::new(channels);
            group.bench_function(name, |b| {
                b.iter(|| {
                    renderer.render(black_box(&scene), black_box(&camera), &mut frame);
                    black_box(frame.depth_mm()[0])
                });
            });
        }
        // Fixed per-frame cost: clearing and resolving the buffers.
        let empty = teleop_render::Scene::new();
        let mut renderer = Renderer::new();
        let mut frame = Frame::new(Channels::DEPTH_ONLY);
        group.bench_function("empty_scene_depth", |b| {
            b.iter(|| {
                renderer.render(black_box(&empty), black_box(&camera), &mut frame);
                black_box(frame.depth_mm()[0])
            });
        });
        let mut clean = Frame::new(Channels::DEPTH_ONLY);
        renderer.render(&scene, &camera, &mut clean);
        let mut noise = DepthNoise::new(NoiseParams::sr300(), 1).expect("valid noise");
        let mut noisy = clean.clone();
        group.bench_function("noise_sr300", |b| {
            b.iter(|| {
                noisy.depth_mm_mut().copy_from_slice(clean.depth_mm());
                noise.apply(&mut noisy);
                black_box(noisy.depth_mm()[0])
            });
        });
        // The baseline takes ~1 s per 640x480 frame: few samples.
        group.sample_size(10);
        let mut renderer = Renderer::with_backend(RayBackend::ParryBruteForce);
        let mut frame = Frame::new(Channels::DEPTH_ONLY);
        group.bench_function("baseline_parry_brute_force_depth", |b| {
            b.iter(|| {
                renderer.render(black_box(&scene), black_box(&camera), &mut frame);
                black_box(frame.depth_mm()[0])
            });
        });
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
