//! One `World::step_once` (dt = 1 ms, 2 hand substeps) of the touching scene with the
//! first finger pressed into the mouse (one active contact), and of the cup grasp with
//! all five fingertips in contact.
//!
//! ```text
//! cargo bench -p teleop-remote-site --bench sim
//! ```

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::SVector;
use teleop_remote_site::hardware::HandCommand;
use teleop_remote_site::sim::{CupGraspConfig, TouchingTaskConfig, World};

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

    let cup_config = CupGraspConfig::default();
    let Ok(mut cup) = World::cup_grasp(&cup_config) else {
        return;
    };
    cup.command_hand(&HandCommand::Position(SVector::from(
        cup_config.closed_posture_rad,
    )));
    cup.step(1.0);
    c.bench_function("cup_grasp_step_1ms", |b| b.iter(|| cup.step_once()));
}

criterion_group!(benches, bench);
criterion_main!(benches);
