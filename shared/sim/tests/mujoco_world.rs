//! The physical robot-site world (`MujocoWorld`) behind the simulator's hardware
//! interfaces: the hand's own loop, the arm's driver, model mismatch by default, the
//! joint-space scenes' fixtures, the pick scene's free objects and the camera views.

use nalgebra::SVector;
use teleop_hardware::{ArmCommand, ArmHardware, HandCommand, HandHardware, HandImpedance};
use teleop_sim::camera::Part;
use teleop_sim::{
    CameraViewsConfig, MujocoWorld, MujocoWorldConfig, PickSceneConfig, RobotWorld, SceneCameras,
    TouchingTaskConfig, View, WORKING_POSTURE_RAD, World, WorldConfig,
};

fn pick_world(config: &MujocoWorldConfig) -> anyhow::Result<MujocoWorld> {
    let pick = PickSceneConfig::default();
    Ok(MujocoWorld::new(&pick.scene()?, pick.world_config(config))?)
}

#[test]
fn model_mismatch_is_on_by_default() -> anyhow::Result<()> {
    let world = pick_world(&MujocoWorldConfig::default())?;
    let p = world.perturbation();
    assert!(
        p.damping_scale.iter().any(|f| (f - 1.0).abs() > 0.01),
        "finger damping drawn away from the model: {:?}",
        p.damping_scale
    );
    assert!(
        p.link_mass_scale
            .iter()
            .any(|(_, f)| (f - 1.0).abs() > 0.01)
    );
    // The simulated finger links' masses are not the description's.
    let (name, factor) = p
        .link_mass_scale
        .iter()
        .find(|(_, f)| (f - 1.0).abs() > 0.01)
        .ok_or_else(|| anyhow::anyhow!("no link perturbed"))?;
    let urdf = world
        .robot()
        .links()
        .iter()
        .find(|l| &l.name == name)
        .and_then(|l| l.inertial)
        .ok_or_else(|| anyhow::anyhow!("{name} has no inertial"))?
        .mass_kg;
    let simulated = world.physics().body_mass_kg(name)?;
    assert!(
        (simulated - urdf * factor).abs() < 1e-9 * urdf.max(1.0),
        "{name}: {simulated} kg simulated, URDF {urdf} x {factor}"
    );
    // The objects vary too: the nominal scene's can weighs 0.2 kg.
    let can = world.physics().body_mass_kg("can")?;
    assert!((can - 0.2).abs() > 1e-6, "can mass {can} kg not varied");

    let nominal = pick_world(&MujocoWorldConfig::nominal())?;
    assert!((nominal.physics().body_mass_kg("can")? - 0.2).abs() < 1e-12);
    Ok(())
}

#[test]
fn the_hand_follows_position_and_impedance_commands_and_holds_under_gravity() -> anyhow::Result<()>
{
    let world = pick_world(&MujocoWorldConfig::default())?;
    let (shared, _arm, mut hand) = teleop_sim::share(world);
    let start = hand.read(0.0)?.position_rad;
    // Held by the initial command for 1 s.
    shared
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned"))?
        .step(1.0)?;
    let held = hand.read(1.0)?.position_rad;
    assert!(
        (held - start).amax() < 0.05,
        "drift {} rad",
        (held - start).amax()
    );

    // A flexed target through the position servo.
    let mut target = SVector::<f64, 17>::zeros();
    for name in ["FFJ3", "MFJ3", "RFJ3", "LFJ3", "FFJ2", "MFJ2"] {
        let i = teleop_interfaces::joints::finger_joint_index(&format!("rh_{name}"))
            .ok_or_else(|| anyhow::anyhow!("{name}"))?;
        target[i] = 0.8;
    }
    hand.write(1.0, &HandCommand::Position(target))?;
    shared
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned"))?
        .step(1.0)?;
    let state = hand.read(2.0)?;
    let err = (state.position_rad - target).amax();
    assert!(err < 0.08, "position servo error {err} rad");

    // A stiff impedance (50 N m/rad, 1 N m s/rad: unstable if taken explicitly at 1 ms
    // on these light joints) holds the fingers at its set point without blowing up.
    let z = HandImpedance {
        position_rad: SVector::zeros(),
        velocity_rad_s: SVector::zeros(),
        stiffness_nm_rad: SVector::repeat(50.0),
        damping_nm_s_rad: SVector::repeat(1.0),
        feedforward_nm: SVector::zeros(),
        max_effort_nm: SVector::repeat(2.0),
    };
    hand.write(2.0, &HandCommand::Impedance(z))?;
    shared
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned"))?
        .step(1.0)?;
    let state = hand.read(3.0)?;
    assert!(state.position_rad.iter().all(|v| v.is_finite()));
    assert!(
        state.position_rad.amax() < 0.05,
        "impedance set point error {} rad",
        state.position_rad.amax()
    );
    assert!(state.velocity_rad_s.amax() < 0.5, "still moving");

    // Non-finite commands are refused and change nothing.
    assert!(
        hand.write(3.0, &HandCommand::Position(SVector::repeat(f64::NAN)))
            .is_err()
    );
    Ok(())
}

#[test]
fn the_arm_moves_on_velocity_commands_and_its_driver_stops_it_without_them() -> anyhow::Result<()> {
    let world = pick_world(&MujocoWorldConfig::default())?;
    let (shared, mut arm, _hand) = teleop_sim::share(world);
    let q0 = arm.read(0.0)?.position_rad;
    let mut v = SVector::<f64, 7>::zeros();
    v[0] = 0.2;
    for k in 0..50 {
        let t = f64::from(k) * 0.01;
        arm.write(t, &ArmCommand { velocity_rad_s: v })?;
        shared
            .lock()
            .map_err(|_| anyhow::anyhow!("poisoned"))?
            .step(0.01)?;
    }
    let moved = arm.read(0.5)?.position_rad[0] - q0[0];
    assert!(
        (0.06..0.1).contains(&moved),
        "joint 0 moved {moved} rad in 0.5 s at 0.2 rad/s"
    );
    // No more commands: the driver's watchdog brakes (0.1 s timeout, then 8 rad/s^2).
    shared
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned"))?
        .step(0.5)?;
    let state = arm.read(1.0)?;
    assert!(
        state.velocity_rad_s.amax() < 0.01,
        "still moving {}",
        state.velocity_rad_s.amax()
    );
    assert!(
        arm.write(
            1.0,
            &ArmCommand {
                velocity_rad_s: SVector::repeat(f64::INFINITY)
            }
        )
        .is_err()
    );
    Ok(())
}

#[test]
fn the_pick_scene_rests_on_its_table_and_the_cameras_show_it() -> anyhow::Result<()> {
    let mut world = pick_world(&MujocoWorldConfig::default())?;
    let before = world.object_poses();
    assert_eq!(before.len(), 2);
    world.step(1.0)?;
    let after = RobotWorld::object_poses(&world);
    for ((name, a), (_, b)) in before.iter().zip(&after) {
        let moved = (b.translation.vector - a.translation.vector).norm();
        assert!(moved < 0.005, "{name} moved {moved} m while resting");
    }
    // The cameras frame the working posture's hand: the objects beside it and the
    // table under it are in the views.
    let mut cameras = SceneCameras::new(&world, &CameraViewsConfig::default())?;
    cameras.render(&world)?;
    let mut seen = std::collections::BTreeSet::new();
    for view in View::ALL {
        for &id in cameras.frame(view).ids().unwrap_or_default() {
            if let Some(part) = cameras.part(id) {
                seen.insert(format!("{part:?}"));
            }
        }
    }
    for part in [Part::Hand, Part::Table, Part::Object(0), Part::Object(1)] {
        assert!(
            seen.contains(&format!("{part:?}")),
            "{part:?} not in the views: {seen:?}"
        );
    }
    Ok(())
}

#[test]
fn the_touching_scene_s_mouse_is_a_fixture_the_flexed_finger_presses() -> anyhow::Result<()> {
    let task = TouchingTaskConfig {
        arm_posture_rad: WORKING_POSTURE_RAD,
        world: WorldConfig::nominal(),
        ..TouchingTaskConfig::default()
    };
    let joint = World::touching_task(&task)?;
    let mut world = MujocoWorld::from_joint_world(&joint, MujocoWorldConfig::nominal())?;
    assert!(world.scene().table.is_none());
    world.step(0.3)?;
    assert!(
        world
            .physics()
            .fingertip_forces_n()
            .iter()
            .all(|f| *f < 0.05),
        "touching at the start: {:?}",
        world.physics().fingertip_forces_n()
    );
    let mouse_before = world.object_poses()[0].1;
    // Flex the first finger's J3 and J2 well past the posture that meets the mouse.
    let mut target = SVector::from(task.hand_posture_rad);
    for name in ["rh_FFJ3", "rh_FFJ2"] {
        let i = teleop_interfaces::joints::finger_joint_index(name)
            .ok_or_else(|| anyhow::anyhow!("{name}"))?;
        target[i] += 0.5;
    }
    world.command_hand(&HandCommand::Position(target));
    world.step(1.0)?;
    let ff = world.physics().fingertip_forces_n()[0];
    assert!(ff > 0.1, "first finger's BioTac reads {ff} N");
    let mouse_after = world.object_poses()[0].1;
    assert!(
        (mouse_after.translation.vector - mouse_before.translation.vector).norm() < 1e-9,
        "the fixture moved"
    );
    Ok(())
}

#[test]
fn bad_settings_are_refused_with_their_names() {
    let bad = MujocoWorldConfig {
        servo_kp_nm_rad: f64::NAN,
        ..MujocoWorldConfig::default()
    };
    let Err(e) = pick_world(&bad) else {
        panic!("NaN gain accepted");
    };
    assert!(e.to_string().contains("servo_kp_nm_rad"), "{e}");
    let bad = PickSceneConfig {
        table_below_palm_m: 5.0,
        ..PickSceneConfig::default()
    };
    let Err(e) = bad.scene() else {
        panic!("table under the floor accepted");
    };
    assert!(e.to_string().contains("table_below_palm_m"), "{e}");
}

/// Each arm joint alone stepped to a velocity command: how closely the physical arm
/// follows its driver (own overshoot) and how much the others move with it (coupling
/// through the arm's inertia, held by the servos' finite stiffness). Prints the figures
/// docs/physics.md quotes.
#[test]
fn each_arm_joint_follows_its_command_and_moves_the_others_little() -> anyhow::Result<()> {
    let mut world = pick_world(&MujocoWorldConfig::nominal())?;
    let commands = [0.3, 0.3, 0.4, 0.4, 0.8, 0.8, 0.8];
    for (j, &cmd) in commands.iter().enumerate() {
        let mut v = SVector::<f64, 7>::zeros();
        v[j] = cmd;
        let mut fastest = SVector::<f64, 7>::zeros();
        for _ in 0..400 {
            world.command_arm(&v);
            world.step(0.001)?;
            let s = world.arm_state();
            fastest = fastest.zip_map(&s.velocity_rad_s, |m, x| m.max(x.abs()));
        }
        for _ in 0..600 {
            world.command_arm(&SVector::zeros());
            world.step(0.001)?;
        }
        let own = fastest[j] / cmd;
        let others = (0..7)
            .filter(|&i| i != j)
            .map(|i| fastest[i])
            .fold(0.0, f64::max)
            / cmd;
        println!(
            "joint {j} at {cmd} rad/s: own peak {own:.3}x the command, others up to {others:.3}x"
        );
        assert!((0.95..1.1).contains(&own), "joint {j}: own peak {own}x");
        assert!(others < 0.35, "joint {j}: others at {others}x");
    }
    Ok(())
}
