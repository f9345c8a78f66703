//! Retargeting time per hand (goal <= 1 ms) and preprocessing time per frame.
//!
//! `cargo bench -p teleop-hand-model --bench hand_model`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, Point3};
use rand::SeedableRng;
use teleop_hand_model::human::{HandShape, HumanHand};
use teleop_hand_model::preprocess::{PreprocessConfig, Scratch, preprocess};
use teleop_hand_model::retarget::{RetargetSettings, Retargeter};
use teleop_hand_model::sampling::PoseSampler;
use teleop_render::{Camera, Channels, Frame, Intrinsics, Renderer, Scene};

fn hands(n: usize) -> Vec<teleop_hand_model::HandKeypoints> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let sampler = PoseSampler::default();
    (0..n)
        .map(|_| {
            let hand = HumanHand::new(HandShape::sample(&mut rng, 0.07, 0.04)).expect("shape");
            let (pose, _) = sampler.sample(&mut rng);
            hand.keypoints(&pose)
        })
        .collect()
}

fn bench_retarget(c: &mut Criterion) {
    let retargeter = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    let hands = hands(256);
    let mut i = 0;
    // Reference in the same run: one forward kinematics of the whole Shadow hand with
    // its 21 keypoints (what checking a retargeted pose costs).
    let joints = retargeter
        .retarget(&hands[0], None)
        .expect("retarget")
        .joints;
    c.bench_function("retarget/reference: Shadow FK + keypoints", |b| {
        b.iter(|| black_box(retargeter.shadow_keypoints(black_box(&joints))));
    });
    let no_collision = Retargeter::new(RetargetSettings {
        collision_passes: 0,
        ..RetargetSettings::default()
    })
    .expect("retargeter");
    c.bench_function(
        "retarget/without the self-collision passes (per hand)",
        |b| {
            b.iter(|| {
                i = (i + 1) % hands.len();
                black_box(no_collision.retarget(&hands[i], None).expect("retarget"))
            });
        },
    );
    c.bench_function("retarget/cold (per hand)", |b| {
        b.iter(|| {
            i = (i + 1) % hands.len();
            black_box(retargeter.retarget(&hands[i], None).expect("retarget"))
        });
    });
}

fn bench_preprocess(c: &mut Criterion) {
    let hand = HumanHand::average();
    let posed = hand.pose(&teleop_hand_model::human::HumanPose::flat());
    let mut scene = Scene::new();
    let camera_from_hand = Isometry3::look_at_rh(
        &Point3::new(0.0, -0.45, 0.08),
        &Point3::new(0.0, 0.0, 0.08),
        &nalgebra::Vector3::z(),
    );
    // look_at_rh gives a view matrix with -Z forward; flip to the optical frame.
    let camera_from_hand =
        Isometry3::rotation(nalgebra::Vector3::x() * std::f64::consts::PI) * camera_from_hand;
    teleop_hand_model::scene::push_human(
        &mut scene,
        &hand,
        &posed,
        teleop_hand_model::scene::Forearm::default(),
        &camera_from_hand,
        &mut Vec::new(),
    )
    .expect("scene");
    let camera = Camera::sr300(Isometry3::identity());
    let mut frame = Frame::new(Channels::DEPTH_ONLY);
    Renderer::new().render(&scene, &camera, &mut frame);
    let centre = camera_from_hand * Point3::new(0.0, 0.0, 0.08);
    let cfg = PreprocessConfig::default();
    let mut out = vec![0.0f32; 96 * 96];
    let mut scratch = Scratch::default();
    let k = Intrinsics::sr300();
    c.bench_function("preprocess/640x480 at 0.45 m", |b| {
        b.iter(|| {
            black_box(
                preprocess(frame.depth_mm(), &k, &centre, &cfg, &mut scratch, &mut out)
                    .expect("preprocess"),
            )
        });
    });
}

criterion_group!(benches, bench_retarget, bench_preprocess);
criterion_main!(benches);
