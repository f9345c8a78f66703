//! MuJoCo's kinematics of the generated model equal the project's forward kinematics
//! (`teleop_kinematics`, from the same URDF) for random configurations of all 24 joints.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_interfaces::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_kinematics::robots;
use teleop_physics::{ARM_DOF, HAND_DOF, PhysicsConfig, PhysicsWorld, RobotParams, SceneSpec};

fn config() -> PhysicsConfig {
    PhysicsConfig {
        robot: RobotParams::default(),
        scene: SceneSpec {
            table: Some(teleop_physics::TableSpec::default()),
            objects: Vec::new(),
        },
        timestep_s: 0.001,
        arm_initial_rad: [0.0; ARM_DOF],
        hand_initial_rad: [0.0; HAND_DOF],
    }
}

#[test]
fn mujoco_body_poses_equal_the_projects_forward_kinematics() -> anyhow::Result<()> {
    let robot = robots::pr2_arm()?;
    let mut world = PhysicsWorld::new(&robot, &config())?;
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let mut state = robot.new_state();
    let mut worst_m: f64 = 0.0;
    let mut worst_rad: f64 = 0.0;
    let mut compared = 0;
    for _ in 0..50 {
        let mut positions = vec![0.0; robot.dof()];
        let mut draw = |name: &str| -> anyhow::Result<f64> {
            let id = robot.joint_id(name)?;
            let (lo, hi) = match robot.joint(id).limits {
                Some(l) if l.is_bounded() => (l.lower, l.upper),
                _ => (-std::f64::consts::PI, std::f64::consts::PI),
            };
            let v = rng.random_range(lo..=hi);
            positions[robot.dof_index(name)?] = v;
            Ok(v)
        };
        let mut arm = [0.0; ARM_DOF];
        for (i, j) in PR2_ARM_JOINTS.iter().enumerate() {
            arm[i] = draw(j)?;
        }
        let mut hand = [0.0; HAND_DOF];
        for (i, j) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            hand[i] = draw(j)?;
        }
        assert_eq!(robot.dof(), ARM_DOF + HAND_DOF, "every DoF drawn");
        world.set_positions(&arm, &hand)?;
        robot.update(&mut state, &positions)?;
        for link in robot.links() {
            let id = robot.link_id(&link.name)?;
            let ours = robot.link_pose(&state, id);
            let theirs = world.body_pose(&link.name)?;
            let dp = (ours.translation.vector - theirs.translation.vector).norm();
            let dr = ours.rotation.angle_to(&theirs.rotation);
            worst_m = worst_m.max(dp);
            worst_rad = worst_rad.max(dr);
            compared += 1;
        }
    }
    println!("{compared} link poses compared: worst {worst_m:.2e} m, {worst_rad:.2e} rad");
    assert!(compared >= 50 * 40, "all links compared ({compared})");
    assert!(worst_m < 1e-9, "position differs by {worst_m} m");
    assert!(worst_rad < 1e-7, "orientation differs by {worst_rad} rad");
    Ok(())
}

#[test]
fn the_generated_model_carries_the_urdf_masses() -> anyhow::Result<()> {
    let robot = robots::pr2_arm()?;
    let world = PhysicsWorld::new(&robot, &config())?;
    let mut mujoco_mass = 0.0;
    for link in robot.links() {
        mujoco_mass += world.body_mass_kg(&link.name)?;
    }
    let urdf = robot.total_mass_kg();
    assert!(
        (mujoco_mass - urdf).abs() < 1e-3,
        "MuJoCo {mujoco_mass} kg vs URDF {urdf} kg"
    );
    Ok(())
}
