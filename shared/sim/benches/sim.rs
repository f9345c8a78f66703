//! One `World::step_once` (dt = 1 ms, 2 hand substeps) of the touching scene with the
//! first finger pressed into the mouse (one active contact), and of the cup grasp with
//! all five fingertips in contact.
//!
//! The operator site's depth frame, piece by piece as `local_sim` makes one: the
//! 640 x 480 render with the SR300 noise, the hand-in-view check, and the world's step
//! with the true fingers retargeted (one frame period each).
//!
//! The remote camera views: posing the scene and rendering both default 320x240 views
//! of the touching scene (arm at the simulator node's working posture), one view alone,
//! and copying both frames into `rgb8` messages, against a baseline in the same run: a
//! plain copy of the same image bytes.
//!
//! The views as they cross the WAN: both compressed to JPEG at the feedback publisher's
//! default quality (80) and CDR-encoded, against the raw views CDR-encoded as they
//! were sent before (the sizes are printed).
//!
//! ```text
//! cargo bench --workspace --bench sim
//! ```

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::SVector;
use teleop_hardware::HandCommand;
use teleop_msgs::{Image, Time};
use teleop_sim::WORKING_POSTURE_RAD;
use teleop_sim::{
    CameraViewsConfig, CupGraspConfig, SceneCameras, TouchingTaskConfig, View, World,
};

fn bench(c: &mut Criterion) {
    let config = TouchingTaskConfig::default();
    let Ok(mut touching) = World::touching_task(&config) else {
        return;
    };
    let mut q = SVector::<f64, 17>::from(config.hand_posture_rad);
    q[1] += 0.3;
    q[2] += 0.3;
    touching.command_hand(&HandCommand::Position(q));
    touching.step(1.0);
    assert!(
        touching.fingertip_force_n()[0] > 0.0,
        "bench scene in contact"
    );
    c.bench_function("touching_step_1ms", |b| b.iter(|| touching.step_once()));

    // The operator site's depth frame, piece by piece (what local_sim does per frame).
    if let Ok(mut op) = teleop_sim::operator_site::OperatorWorld::new(Default::default()) {
        op.step(2.0);
        c.bench_function("operator_depth_frame_render_with_noise_640x480", |b| {
            b.iter(|| op.render_depth().map(|d| d.len()))
        });
        c.bench_function("operator_hand_in_view", |b| b.iter(|| op.hand_in_view()));
        c.bench_function("operator_step_and_true_shadow_joints_per_frame", |b| {
            b.iter(|| {
                op.step(1.0 / 30.0);
                op.shadow_joints()
            })
        });
        c.bench_function("operator_step_per_frame", |b| {
            b.iter(|| op.step(1.0 / 30.0))
        });
    }

    let cup_config = CupGraspConfig::default();
    let Ok(mut cup) = World::cup_grasp(&cup_config) else {
        return;
    };
    cup.command_hand(&HandCommand::Position(SVector::from(
        cup_config.closed_posture_rad,
    )));
    cup.step(1.0);
    c.bench_function("cup_grasp_step_1ms", |b| b.iter(|| cup.step_once()));

    let Ok(scene) = World::touching_task(&TouchingTaskConfig {
        arm_posture_rad: WORKING_POSTURE_RAD,
        ..TouchingTaskConfig::default()
    }) else {
        return;
    };
    let Ok(mut cameras) = SceneCameras::new(&scene, &CameraViewsConfig::default()) else {
        return;
    };
    c.bench_function("cameras_render_both_views_320x240", |b| {
        b.iter(|| cameras.render(&scene))
    });
    c.bench_function("cameras_render_top_view_320x240", |b| {
        b.iter(|| cameras.render_view(&scene, View::Top))
    });
    let mut images = [Image::default(), Image::default()];
    c.bench_function("cameras_frames_to_rgb8_messages", |b| {
        b.iter(|| {
            for (view, image) in View::ALL.into_iter().zip(&mut images) {
                cameras.write_image(view, Time::default(), image);
            }
        })
    });
    // Baseline: copying the same bytes (two 320x240 rgb8 images).
    let source: Vec<Vec<u8>> = View::ALL
        .iter()
        .map(|v| cameras.frame(*v).rgb().unwrap_or_default().to_vec())
        .collect();
    let mut copies = vec![Vec::new(), Vec::new()];
    c.bench_function("baseline_memcpy_two_rgb8_320x240", |b| {
        b.iter(|| {
            for (from, to) in source.iter().zip(&mut copies) {
                to.clear();
                to.extend_from_slice(std::hint::black_box(from));
            }
        })
    });
    for (view, image) in View::ALL.into_iter().zip(&mut images) {
        cameras.write_image(view, Time::default(), image);
    }
    let jpeg = |q| {
        images
            .iter()
            .map(|i| teleop_msgs::image_codec::jpeg_from_rgb8(i, q))
            .collect::<Result<Vec<_>, _>>()
    };
    let Ok(sample) = jpeg(80) else {
        return;
    };
    let raw_bytes: usize = images
        .iter()
        .map(|i| teleop_msgs::encode(i).map_or(0, |b| b.len()))
        .sum();
    let jpeg_bytes: usize = sample
        .iter()
        .map(|i| teleop_msgs::encode(i).map_or(0, |b| b.len()))
        .sum();
    println!("both views on the wire: raw {raw_bytes} B, JPEG q80 {jpeg_bytes} B");
    c.bench_function("views_jpeg_q80_both_320x240", |b| {
        b.iter(|| {
            jpeg(80).map(|v| {
                v.iter()
                    .map(|i| teleop_msgs::encode(i).map_or(0, |b| b.len()))
                    .sum::<usize>()
            })
        })
    });
    c.bench_function("baseline_views_raw_cdr_both_320x240", |b| {
        b.iter(|| {
            images
                .iter()
                .map(|i| teleop_msgs::encode(std::hint::black_box(i)).map_or(0, |b| b.len()))
                .sum::<usize>()
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
