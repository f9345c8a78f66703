//! The robot world's speed with a grasped object: MuJoCo (`teleop-physics`: the PR2 arm
//! and the Shadow hand holding a free cube it lifted, the driver's loop and the hand's
//! PD loop every step) against the previous simulator in the same run (`teleop-sim`'s
//! home-made joint-space hand with penalty contacts, the hand closed on its fixed cup),
//! both at a 1 ms step on one thread. Alternating repetitions; medians and the ratio.
//! A third column steps MuJoCo as `remote_sim` does (`teleop_sim::MujocoWorld`: the
//! hand's own loop every step, and per 4 ms tick the commands, the kinematics and the
//! drivers' measurements), the same script on the same scene.
//!
//! `cargo run --release -p teleop-system-tests --example physics_bench [-- REPS SECONDS]`

use std::time::Instant;

use nalgebra::SVector;
use teleop_hardware::HandCommand;
use teleop_kinematics::robots;
use teleop_physics::PhysicsWorld;
use teleop_physics::scripted::{CubeUnderPalm, GraspLiftCarry};
use teleop_sim::{CupGraspConfig, MujocoWorld, MujocoWorldConfig, RobotWorld, World};

struct Sample {
    steps_per_s: f64,
    mean_contacts: f64,
}

/// MuJoCo: grasp and lift (3 s, not timed), then `seconds` of carrying and holding, timed.
fn mujoco(seconds: f64) -> anyhow::Result<Sample> {
    let robot = robots::pr2_arm()?;
    let script = GraspLiftCarry::default();
    let mut world = PhysicsWorld::new(&robot, &CubeUnderPalm::default().config(&robot)?)?;
    while world.time_s() < script.lift_start_s + script.lift_s {
        script.step(&mut world)?;
    }
    let start_z = world.object_poses()[0].1.translation.z;
    let steps = (seconds / world.timestep_s()).round() as usize;
    let mut contacts = 0usize;
    let t0 = Instant::now();
    for _ in 0..steps {
        script.step(&mut world)?;
        contacts += world.contact_count();
    }
    let wall = t0.elapsed().as_secs_f64();
    let end_z = world.object_poses()[0].1.translation.z;
    anyhow::ensure!(
        (end_z - start_z).abs() < 0.05,
        "the cube was dropped while timing"
    );
    Ok(Sample {
        steps_per_s: steps as f64 / wall,
        mean_contacts: contacts as f64 / steps as f64,
    })
}

/// `remote_sim`'s tick, s (250 Hz).
const TICK_S: f64 = 0.004;

/// MuJoCo as `remote_sim` steps it: the same script through `MujocoWorld` (nominal
/// robot, the script's hand gains as its position servo), commands per 4 ms tick.
fn mujoco_world(seconds: f64) -> anyhow::Result<Sample> {
    let robot = robots::pr2_arm()?;
    let script = GraspLiftCarry::default();
    let physics = CubeUnderPalm::default().config(&robot)?;
    let mut world = MujocoWorld::new(
        &physics.scene,
        MujocoWorldConfig {
            robot: physics.robot.clone(),
            timestep_s: physics.timestep_s,
            servo_kp_nm_rad: script.kp,
            servo_kd_nm_s_rad: script.kd,
            arm_initial_rad: physics.arm_initial_rad,
            hand_initial_rad: physics.hand_initial_rad,
            ..MujocoWorldConfig::nominal()
        },
    )?;
    let tick = |world: &mut MujocoWorld| -> anyhow::Result<usize> {
        let t = world.time_s();
        world.command_hand(&HandCommand::Position(SVector::from(
            script.hand_targets(t),
        )));
        world.command_arm(&SVector::from(script.arm_velocity(t)));
        world.step(TICK_S)?;
        Ok(world.physics().contact_count())
    };
    while world.time_s() < script.lift_start_s + script.lift_s {
        tick(&mut world)?;
    }
    let start_z = world.physics().object_poses()[0].1.translation.z;
    let ticks = (seconds / TICK_S).round() as usize;
    let mut contacts = 0usize;
    let t0 = Instant::now();
    for _ in 0..ticks {
        contacts += tick(&mut world)?;
    }
    let wall = t0.elapsed().as_secs_f64();
    let end_z = world.physics().object_poses()[0].1.translation.z;
    anyhow::ensure!(
        (end_z - start_z).abs() < 0.05,
        "the cube was dropped while timing (MujocoWorld)"
    );
    let steps = ticks as f64 * TICK_S / physics.timestep_s;
    Ok(Sample {
        steps_per_s: steps / wall,
        mean_contacts: contacts as f64 / ticks as f64,
    })
}

/// The previous simulator: the hand closed on the cup (position command), timed.
fn previous(seconds: f64) -> anyhow::Result<Sample> {
    let config = CupGraspConfig::default();
    let mut world = World::cup_grasp(&config)?;
    let closed = HandCommand::Position(SVector::from(config.closed_posture_rad));
    world.command_hand(&closed);
    world.step(1.0);
    let steps = (seconds / 0.001).round() as usize;
    let mut contacts = 0usize;
    let t0 = Instant::now();
    for _ in 0..steps {
        world.command_hand(&closed);
        world.step(0.001);
        contacts += world.contacts().len();
    }
    let wall = t0.elapsed().as_secs_f64();
    Ok(Sample {
        steps_per_s: steps as f64 / wall,
        mean_contacts: contacts as f64 / steps as f64,
    })
}

fn median(v: Vec<f64>) -> f64 {
    teleop_node::stats::median(&v)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let reps: usize = args.first().map_or(Ok(5), |s| s.parse())?;
    let seconds: f64 = args.get(1).map_or(Ok(3.0), |s| s.parse())?;
    let mut m = Vec::new();
    let mut w = Vec::new();
    let mut p = Vec::new();
    for r in 0..reps {
        let a = mujoco(seconds)?;
        let c = mujoco_world(seconds)?;
        let b = previous(seconds)?;
        println!(
            "rep {r}: MuJoCo {:.0} steps/s ({:.1} contacts), MujocoWorld {:.0} steps/s ({:.1} contacts), previous {:.0} steps/s ({:.1} contacts)",
            a.steps_per_s,
            a.mean_contacts,
            c.steps_per_s,
            c.mean_contacts,
            b.steps_per_s,
            b.mean_contacts
        );
        m.push(a);
        w.push(c);
        p.push(b);
    }
    let wm = median(w.iter().map(|s| s.steps_per_s).collect());
    let mm = median(m.iter().map(|s| s.steps_per_s).collect());
    let pm = median(p.iter().map(|s| s.steps_per_s).collect());
    println!("| world | steps/s (median of {reps}) | x real time at 1 kHz | contacts (mean) |");
    println!("|---|---|---|---|");
    println!(
        "| MuJoCo, cube held by the Shadow hand | {mm:.0} | {:.1} | {:.1} |",
        mm / 1000.0,
        median(m.iter().map(|s| s.mean_contacts).collect())
    );
    println!(
        "| MuJoCo as remote_sim steps it (MujocoWorld, 4 ms ticks), cube held | {wm:.0} | {:.1} | {:.1} |",
        wm / 1000.0,
        median(w.iter().map(|s| s.mean_contacts).collect())
    );
    println!(
        "| previous simulator, hand closed on the fixed cup | {pm:.0} | {:.1} | {:.1} |",
        pm / 1000.0,
        median(p.iter().map(|s| s.mean_contacts).collect())
    );
    println!(
        "ratio MuJoCo / previous: {:.2}; MujocoWorld / previous: {:.2}",
        mm / pm,
        wm / pm
    );
    Ok(())
}
