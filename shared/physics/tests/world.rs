//! The physical world on its own: a cube grasped, lifted and carried by the Shadow hand;
//! the same arm motion with the hand open leaves it on the table; objects rest; bad
//! input is refused and changes nothing; a missing library is named with how to get it;
//! a whole scripted pick-and-place job judged from ground truth.

use nalgebra::Point3;
use teleop_kinematics::robots;
use teleop_physics::library::{self, MUJOCO_VERSION};
use teleop_physics::scripted::{CubeUnderPalm, GraspLiftCarry};
use teleop_physics::{
    HAND_DOF, PhysicsError, PhysicsWorld, PickPlaceConfig, PickPlaceJudge, TargetRegion, Verdict,
};

struct Run {
    start: Point3<f64>,
    lifted_z_m: f64,
    end: Point3<f64>,
    /// Distance from the palm to the cube at the end, m.
    end_palm_distance_m: f64,
    max_fingertip_force_n: f64,
}

/// The world of the scripted grasp, with the cube `gap_m` below the palm.
fn cube_under_palm(gap_m: f64) -> anyhow::Result<PhysicsWorld> {
    let robot = robots::pr2_arm()?;
    let config = CubeUnderPalm {
        gap_m,
        ..CubeUnderPalm::default()
    }
    .config(&robot)?;
    Ok(PhysicsWorld::new(&robot, &config)?)
}

fn run(script: &GraspLiftCarry, seconds: f64) -> anyhow::Result<Run> {
    let mut world = cube_under_palm(CubeUnderPalm::default().gap_m)?;
    let cube =
        |w: &PhysicsWorld| -> Point3<f64> { w.object_poses()[0].1.translation.vector.into() };
    let start = cube(&world);
    let lift_end = script.lift_start_s + script.lift_s;
    let mut lifted_z_m = f64::NAN;
    let mut max_fingertip_force_n: f64 = 0.0;
    let steps = (seconds / world.timestep_s()).round() as usize;
    for _ in 0..steps {
        script.step(&mut world)?;
        if lifted_z_m.is_nan() && world.time_s() >= lift_end {
            lifted_z_m = cube(&world).z;
        }
        max_fingertip_force_n = max_fingertip_force_n.max(
            world
                .fingertip_forces_n()
                .iter()
                .copied()
                .fold(0.0, f64::max),
        );
    }
    let end = cube(&world);
    let palm = world.body_pose(robots::shadow::PALM)?;
    Ok(Run {
        start,
        lifted_z_m,
        end,
        end_palm_distance_m: (palm.translation.vector - end.coords).norm(),
        max_fingertip_force_n,
    })
}

#[test]
fn the_shadow_hand_lifts_and_carries_a_cube() -> anyhow::Result<()> {
    let r = run(&GraspLiftCarry::default(), 5.0)?;
    let lift = r.lifted_z_m - r.start.z;
    let carried = ((r.end.x - r.start.x).powi(2) + (r.end.y - r.start.y).powi(2)).sqrt();
    println!(
        "lifted {lift:.3} m, carried {carried:.3} m, cube {:.3} m from the palm at the end, \
         fingertip force up to {:.1} N",
        r.end_palm_distance_m, r.max_fingertip_force_n
    );
    assert!(lift > 0.15, "the cube rose {lift} m with the arm");
    assert!(
        r.end.z - r.start.z > 0.15,
        "still up at the end: {:?}",
        r.end
    );
    assert!(carried > 0.25, "carried {carried} m sideways");
    assert!(r.end_palm_distance_m < 0.08, "still in the hand");
    assert!(r.max_fingertip_force_n > 1.0, "the BioTacs felt the grasp");
    Ok(())
}

/// The scripted job (grasp, lift, carry, put down, let go, go back) run on MuJoCo and
/// judged every 10 ms by [`PickPlaceJudge`]; the target is where the carry's shoulder
/// pan takes the cube's starting place (5 cm either way).
fn judged_pick_and_place(close_hand: bool) -> anyhow::Result<(PickPlaceJudge, Point3<f64>)> {
    let script = GraspLiftCarry {
        close_hand,
        place_and_return: true,
        ..GraspLiftCarry::default()
    };
    let robot = robots::pr2_arm()?;
    let config = CubeUnderPalm::default().config(&robot)?;
    let table_top_z_m = config.scene.table.map_or(f64::NAN, |t| t.top_z_m);
    let mut world = PhysicsWorld::new(&robot, &config)?;
    let start = world.object_poses()[0].1.translation.vector;
    let mut kin = robot.new_state();
    robot.update(&mut kin, &vec![0.0; robot.dof()])?;
    let pan = robot
        .link_pose(&kin, robot.link_id("r_shoulder_pan_link")?)
        .translation
        .vector;
    let turn = nalgebra::Rotation2::new(script.carry_rad_s * script.carry_s);
    let there = turn * nalgebra::Vector2::new(start.x - pan.x, start.y - pan.y);
    let target = TargetRegion {
        centre_m: [pan.x + there.x, pan.y + there.y, start.z],
        half_extent_m: [0.05, 0.05, 0.02],
    };
    let mut judge = PickPlaceJudge::new(PickPlaceConfig::new("cube", target, table_top_z_m))?;
    let steps = ((script.end_s() + 1.5) / world.timestep_s()).round() as usize;
    for k in 0..steps {
        script.step(&mut world)?;
        if k % 10 == 0 {
            let poses: Vec<_> = world
                .object_poses()
                .into_iter()
                .map(|(n, p)| (n.to_owned(), p))
                .collect();
            judge.step(world.time_s(), &world.arm_position(), &poses)?;
        }
    }
    let end = world.object_poses()[0].1.translation.vector.into();
    Ok((judge, end))
}

#[test]
fn a_scripted_pick_and_place_on_mujoco_is_judged_a_success_timed_as_in_the_thesis()
-> anyhow::Result<()> {
    let (judge, end) = judged_pick_and_place(true)?;
    println!(
        "verdict {:?}, first motion at {:?} s, cube at {end:?}, target {:?}",
        judge.verdict(),
        judge.started_s(),
        judge.config().target.centre_m
    );
    assert!(judge.lifted());
    let Verdict::Succeeded { completion_s } = judge.verdict().clone() else {
        panic!("not a success: {:?}", judge.verdict());
    };
    // The arm moves from 1.5 s (the lift) to 11.5 s (the last lowering ends); the
    // judge needs the arm within 0.05 rad of its start and the cube at rest 0.5 s.
    let started = judge.started_s().unwrap_or(f64::NAN);
    assert!((1.5..1.8).contains(&started), "first motion at {started} s");
    assert!(
        (9.0..11.5).contains(&completion_s),
        "completion {completion_s} s"
    );
    Ok(())
}

#[test]
fn with_the_hand_open_the_scripted_job_is_not_a_success() -> anyhow::Result<()> {
    let (judge, end) = judged_pick_and_place(false)?;
    println!("verdict {:?}, cube at {end:?}", judge.verdict());
    assert!(!judge.lifted());
    assert_eq!(*judge.verdict(), Verdict::Running);
    Ok(())
}

#[test]
fn with_the_hand_open_the_same_motion_leaves_the_cube_on_the_table() -> anyhow::Result<()> {
    let script = GraspLiftCarry {
        close_hand: false,
        ..GraspLiftCarry::default()
    };
    let r = run(&script, 5.0)?;
    println!("cube moved {:?}", r.end - r.start);
    assert!(
        (r.end.z - r.start.z).abs() < 0.005,
        "cube stayed on the table"
    );
    assert!(r.end_palm_distance_m > 0.2, "the hand left without it");
    assert!(r.max_fingertip_force_n < 0.5, "nothing touched the BioTacs");
    Ok(())
}

#[test]
fn a_cube_rests_on_the_table() -> anyhow::Result<()> {
    let mut world = cube_under_palm(0.05)?;
    let start = world.object_poses()[0].1;
    for _ in 0..1000 {
        world.set_hand_torques(&[0.0; HAND_DOF])?;
        world.step()?;
    }
    let end = world.object_poses()[0].1;
    let moved = (end.translation.vector - start.translation.vector).norm();
    assert!(moved < 0.002, "moved {moved} m at rest");
    assert!(world.contact_count() >= 1, "in contact with the table");
    Ok(())
}

#[test]
fn non_finite_commands_are_refused_and_change_nothing() -> anyhow::Result<()> {
    let mut world = cube_under_palm(CubeUnderPalm::default().gap_m)?;
    let mut torques = [0.1; HAND_DOF];
    world.set_hand_torques(&torques)?;
    torques[3] = f64::NAN;
    let e = world.set_hand_torques(&torques);
    assert!(matches!(
        e,
        Err(PhysicsError::Invalid {
            what: "hand torques",
            ..
        })
    ));
    let mut v = [0.0; 7];
    v[2] = f64::INFINITY;
    let e = world.command_arm_velocity(&v);
    assert!(matches!(e, Err(PhysicsError::Invalid { .. })), "{e:?}");
    for _ in 0..200 {
        world.step()?;
    }
    assert!(
        world.arm_velocity().iter().all(|v| v.abs() < 1e-2),
        "the arm did not move"
    );
    assert!(
        world.hand_effort().iter().all(|t| (t - 0.1).abs() < 1e-9),
        "the old torques held"
    );
    Ok(())
}

#[test]
fn a_bad_scene_is_refused_with_its_name() -> anyhow::Result<()> {
    let robot = robots::pr2_arm()?;
    let mut config = CubeUnderPalm::default().config(&robot)?;
    config.scene.objects[0].mass_kg = f64::NAN;
    let e = PhysicsWorld::new(&robot, &config)
        .err()
        .map(|e| e.to_string());
    assert!(
        e.as_deref()
            .is_some_and(|e| e.contains("cube") && e.contains("mass_kg")),
        "{e:?}"
    );
    let mut config = CubeUnderPalm::default().config(&robot)?;
    config.scene.objects[0].name = "cube\"/><bad".into();
    let e = PhysicsWorld::new(&robot, &config)
        .err()
        .map(|e| e.to_string());
    assert!(e.as_deref().is_some_and(|e| e.contains("name")), "{e:?}");
    for bad in [f64::NAN, 0.5] {
        let mut config = CubeUnderPalm::default().config(&robot)?;
        config.robot.impratio = bad;
        let e = PhysicsWorld::new(&robot, &config)
            .err()
            .map(|e| e.to_string());
        assert!(
            e.as_deref().is_some_and(|e| e.contains("impratio")),
            "{bad}: {e:?}"
        );
    }
    Ok(())
}

#[test]
fn the_arm_stops_when_commands_stop() -> anyhow::Result<()> {
    let mut world = cube_under_palm(0.2)?;
    let mut v = [0.0; 7];
    v[0] = 0.3;
    world.command_arm_velocity(&v)?;
    for _ in 0..100 {
        world.step()?;
    }
    let moving = world.arm_velocity()[0];
    assert!(moving > 0.2, "moving at {moving} rad/s before the timeout");
    for _ in 0..400 {
        world.step()?;
    }
    let still = world.arm_velocity()[0].abs();
    assert!(
        still < 1e-2,
        "stopped by the driver's watchdog: {still} rad/s"
    );
    Ok(())
}

#[test]
fn a_missing_library_is_named_with_how_to_get_it() {
    let empty = std::env::temp_dir().join(format!("teleop-no-mujoco-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&empty);
    let dir = empty.clone();
    let e = library::find_with(&move |name| {
        (name == "MUJOCO_DYNAMIC_LINK_DIR").then(|| dir.clone().into_os_string())
    });
    let text = match e {
        Ok(found) => panic!("found {found:?} in an empty directory"),
        Err(e) => e.to_string(),
    };
    println!("{text}");
    assert!(
        text.contains(&empty.display().to_string()),
        "names where it looked"
    );
    assert!(
        text.contains(&format!("pip install mujoco=={MUJOCO_VERSION}")),
        "says how to get it"
    );
    assert!(
        text.contains("MUJOCO_DYNAMIC_LINK_DIR"),
        "says how to use one's own"
    );
    let _ = std::fs::remove_dir(&empty);
}

#[test]
fn the_library_this_build_linked_is_the_pinned_one() {
    // Linked from the wheel unless MUJOCO_DYNAMIC_LINK_DIR named another.
    if let Some(linked) = teleop_physics::linked_library() {
        assert!(linked.contains(library::MUJOCO_SONAME), "{linked}");
    }
    let found = library::find();
    assert!(found.is_ok(), "{found:?}");
}
