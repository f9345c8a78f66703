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
    // The same noise and perturbation checks as the joint-space world's.
    let mut bad = MujocoWorldConfig::default();
    bad.noise.joint_velocity_std_rad_s = -1.0;
    let Err(e) = pick_world(&bad) else {
        panic!("negative noise accepted");
    };
    assert!(
        e.to_string().contains("noise.joint_velocity_std_rad_s"),
        "{e}"
    );
    let mut bad = MujocoWorldConfig::default();
    bad.perturbation.mass_fraction = 0.95;
    let Err(e) = pick_world(&bad) else {
        panic!("a perturbation that could make a mass vanish accepted");
    };
    assert!(e.to_string().contains("perturbation.mass_fraction"), "{e}");
    let bad = PickSceneConfig {
        table_below_palm_m: 5.0,
        ..PickSceneConfig::default()
    };
    let Err(e) = bad.scene() else {
        panic!("table under the floor accepted");
    };
    assert!(e.to_string().contains("table_below_palm_m"), "{e}");
}

/// The pick scene's job: the can to a spot 10 cm further out than the palm, between the
/// can and the cube, at the can's resting height; at rest nobody moved it, so a world
/// left alone for 2 s is judged still running, the can never lifted; bad settings named.
#[test]
fn the_pick_scenes_job_is_judged_from_the_worlds_ground_truth() -> anyhow::Result<()> {
    let pick = PickSceneConfig::default();
    let job = pick.job_config()?;
    let scene = pick.scene()?;
    let [can, cube] = [&scene.objects[0], &scene.objects[1]];
    assert_eq!(job.object, "can");
    let spot = job.target.centre_m;
    assert!((spot[1] - (can.position_m[1] + cube.position_m[1]) / 2.0).abs() < 1e-9);
    assert!((spot[0] - (can.position_m[0] + 0.1)).abs() < 1e-9);
    assert!((spot[2] - can.position_m[2]).abs() < 1e-9);
    let mut world = pick_world(&MujocoWorldConfig::default())?;
    let mut judge = teleop_physics::PickPlaceJudge::new(job)?;
    for _ in 0..200 {
        world.advance(0.01)?;
        judge.step(
            world.time_s(),
            world.arm_state().position_rad.as_slice(),
            &world.object_poses(),
        )?;
    }
    assert_eq!(*judge.verdict(), teleop_physics::Verdict::Running);
    assert!(!judge.lifted());
    assert_eq!(judge.started_s(), None, "the arm held still");

    let mut bad = PickSceneConfig::default();
    bad.job.object = "bowl".into();
    let e = bad.job_config().unwrap_err();
    assert!(e.to_string().contains("pick.job.object"), "{e}");
    let mut bad = PickSceneConfig::default();
    bad.job.target_half_xy_m = 0.0;
    let e = bad.job_config().unwrap_err();
    assert!(e.to_string().contains("pick.job.target_half_xy_m"), "{e}");
    Ok(())
}

/// The tower job's scene at the posture `teleop launch --task tower` starts from: the
/// three blocks rest on the table where the config puts them, the judge says running
/// with nothing stacked; the same blocks put on one another in MuJoCo (this seed's
/// sizes, which the judge does not know) stand, and the judge reads them as a tower of
/// two on the base; bad settings are named.
#[test]
fn the_tower_scene_stands_and_a_stack_in_it_is_read_as_a_tower() -> anyhow::Result<()> {
    let pick = PickSceneConfig {
        arm_posture_rad: teleop_sim::PICK_TOP_GRASP_POSTURE_RAD,
        table_below_palm_m: teleop_sim::PICK_TOP_GRASP_TABLE_BELOW_PALM_M,
        ..PickSceneConfig::default()
    };
    let tower = teleop_sim::TowerJobConfig::default();
    let scene = pick.tower_scene(&tower)?;
    let job = pick.tower_job_config(&tower)?;
    assert_eq!(job.blocks, ["base", "middle", "top"]);
    let config = pick.world_config(&MujocoWorldConfig::default());
    let judge_for = |world: &mut MujocoWorld| -> anyhow::Result<teleop_physics::TowerJudge> {
        let mut judge = teleop_physics::TowerJudge::new(job.clone())?;
        for _ in 0..200 {
            world.advance(0.01)?;
            judge.step(
                world.time_s(),
                world.arm_state().position_rad.as_slice(),
                &world.object_poses(),
            )?;
        }
        Ok(judge)
    };
    let mut world = MujocoWorld::new(&scene, config.clone())?;
    let before = world.object_poses();
    let judge = judge_for(&mut world)?;
    for ((name, a), (_, b)) in before.iter().zip(&world.object_poses()) {
        let moved = (b.translation.vector - a.translation.vector).norm();
        assert!(moved < 0.005, "{name} moved {moved} m while resting");
    }
    assert_eq!(*judge.verdict(), teleop_physics::Verdict::Running);
    assert_eq!(judge.stacked(), 0);
    assert!(!judge.lifted());

    // Stacked by hand (the nominal heights; this seed's sizes differ by up to 5 %).
    let mut stacked = scene.clone();
    let base = stacked.objects[0].position_m;
    let mut z = base[2] + tower.blocks[0].half_m[2];
    for (i, block) in tower.blocks.iter().enumerate().skip(1) {
        z += block.half_m[2];
        stacked.objects[i].position_m = [base[0], base[1], z + 0.002];
        z += block.half_m[2] + 0.002;
    }
    let mut world = MujocoWorld::new(&stacked, config)?;
    let judge = judge_for(&mut world)?;
    assert_eq!(judge.stacked(), 2, "{:?}", world.object_poses());
    for (name, pose) in world.object_poses() {
        let tilt = (pose.rotation * nalgebra::Vector3::z())
            .angle(&nalgebra::Vector3::z())
            .to_degrees();
        assert!(tilt < 1.0, "{name} leans {tilt} deg");
    }

    let mut bad = tower.clone();
    bad.blocks.truncate(1);
    let e = pick.tower_job_config(&bad).unwrap_err();
    assert!(e.to_string().contains("blocks"), "{e}");
    let mut bad = tower;
    bad.blocks[1].half_m[2] = f64::NAN;
    let e = pick.tower_scene(&bad).unwrap_err();
    assert!(e.to_string().contains("tower.blocks.half_m"), "{e}");
    Ok(())
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

/// A joint pressed into its limit through the safety layer, at the 250 Hz `remote_sim`
/// applies it: the adaptive controller's command of 2026-12-05 (the thumb base's set
/// point at its upper limit, 0.885 N m feedforward toward it, 7.44 N m/rad, 0.07 N m
/// s/rad). With a cut that switched at the limit the thumb chattered at +-2 rad/s and
/// shook the wrist at 0.04 rad/s with the arm stopped (the compose fault test's
/// failure); the faded cut lets it settle.
#[test]
fn a_joint_pressed_into_its_limit_through_the_safety_layer_settles() -> anyhow::Result<()> {
    use teleop_hardware::safety::HandLimits;
    use teleop_hardware::{HandSafety, HandSafetyConfig, SafeHand};
    let world = pick_world(&MujocoWorldConfig::default())?;
    let (shared, mut arm, hand) = teleop_sim::share(world);
    let limits = HandLimits::shadow()?;
    let mut hand = SafeHand::new(hand, HandSafety::new(limits, HandSafetyConfig::default())?);
    let pressed: Vec<usize> = ["THJ5", "LFJ5", "FFJ3"]
        .iter()
        .map(|n| {
            teleop_interfaces::joints::finger_joint_index(&format!("rh_{n}"))
                .ok_or_else(|| anyhow::anyhow!("{n}"))
        })
        .collect::<anyhow::Result<_>>()?;
    let mut z = HandImpedance {
        position_rad: SVector::zeros(),
        velocity_rad_s: SVector::zeros(),
        stiffness_nm_rad: SVector::repeat(1.2),
        damping_nm_s_rad: SVector::repeat(0.07),
        feedforward_nm: SVector::zeros(),
        max_effort_nm: SVector::repeat(1.0),
    };
    for &i in &pressed {
        z.position_rad[i] = limits.upper_rad[i];
        z.stiffness_nm_rad[i] = 7.44;
        z.feedforward_nm[i] = 0.885;
    }
    let dt = 1.0 / 250.0;
    let (mut finger_v, mut wrist_v, mut over) = (0.0_f64, 0.0_f64, 0.0_f64);
    for k in 0..750 {
        let t = f64::from(k) * dt;
        hand.write(t, &HandCommand::Impedance(z))?;
        shared
            .lock()
            .map_err(|_| anyhow::anyhow!("poisoned"))?
            .step(dt)?;
        // The last second, once pressed.
        if t >= 2.0 {
            let h = hand.read(t + dt)?;
            let a = arm.read(t + dt)?;
            for &i in &pressed {
                finger_v = finger_v.max(h.velocity_rad_s[i].abs());
                over = over.max(h.position_rad[i] - limits.upper_rad[i]);
            }
            wrist_v = wrist_v.max(a.velocity_rad_s[5].abs().max(a.velocity_rad_s[6].abs()));
        }
    }
    println!(
        "pressed into the limit: fastest pressed joint {finger_v:.3} rad/s, past the limit \
         {over:.4} rad, fastest wrist joint {wrist_v:.4} rad/s"
    );
    assert!(finger_v < 0.1, "chatter: {finger_v} rad/s");
    assert!(over < 0.01, "{over} rad past the limit");
    assert!(wrist_v < 0.01, "wrist shaken at {wrist_v} rad/s");
    assert!(
        hand.safety()
            .counters()
            .get(teleop_hardware::safety::Intervention::PositionLimit)
            > 0
    );
    Ok(())
}

/// An external load on a finger joint (the screw-pouring stand-in) pushes it against
/// the hand's servo; loads the MuJoCo world lacks or names it does not know are refused.
#[test]
fn a_load_on_a_finger_joint_pushes_it_and_bad_loads_are_refused() -> anyhow::Result<()> {
    use teleop_sim::{ExternalLoad, LoadTarget, SimError};
    let mut world = pick_world(&MujocoWorldConfig::nominal())?;
    let j = teleop_interfaces::joints::finger_joint_index("rh_THJ4")
        .ok_or_else(|| anyhow::anyhow!("THJ4"))?;
    // THJ4 in the middle of its range (0..1.22 rad), held by the hand's servo.
    let mut target = world.hand_state().position_rad;
    target[j] = 0.6;
    world.command_hand(&HandCommand::Position(target));
    world.step(1.0)?;
    let before = world.hand_state().position_rad[j];
    let mut load = ExternalLoad::screw_pouring(1.5);
    load.ramp_s = 0.0;
    load.target = LoadTarget::JointTorque {
        joint: "rh_THJ4".into(),
        torque_nm: -0.3,
    };
    world.add_load(load.clone())?;
    world.step(0.4)?;
    let unloaded = world.hand_state().position_rad[j];
    world.step(1.1)?;
    let loaded = world.hand_state().position_rad[j];
    println!("THJ4 {before:.4} -> {unloaded:.4} before the load, {loaded:.4} under it");
    assert!((unloaded - before).abs() < 0.02, "moved before the load");
    // The servo's 2 N m/rad against 0.3 N m: ~0.15 rad.
    assert!(before - loaded > 0.08, "{before} -> {loaded}");
    let mut bad = load.clone();
    bad.target = LoadTarget::JointTorque {
        joint: "rh_XXJ9".into(),
        torque_nm: 0.1,
    };
    assert!(matches!(
        world.add_load(bad),
        Err(SimError::UnknownFingerJoint(_))
    ));
    bad = load.clone();
    bad.start_s = f64::NAN;
    assert!(matches!(
        world.add_load(bad),
        Err(SimError::InvalidConfig { .. })
    ));
    bad = load;
    bad.target = LoadTarget::FingertipForce {
        finger: "th".into(),
        force_n: [0.0, 0.0, 1.0],
    };
    let Err(e) = world.add_load(bad) else {
        panic!("a fingertip force accepted");
    };
    assert!(
        e.to_string().contains("not supported by the MuJoCo world"),
        "{e}"
    );
    Ok(())
}
