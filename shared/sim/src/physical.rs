//! The robot site's physical world: [`teleop_physics::PhysicsWorld`] (MuJoCo) with the
//! drivers' side the simulator process needs, behind the same [`RobotWorld`] interface as
//! the joint-space [`World`].
//!
//! * **Arm**: the PR2 driver's velocity loop in the physics crate; commands stored now
//!   apply from the next step.
//! * **Hand**: the Shadow hand's own joint loop ([`HandCommand`]: position through the PD
//!   servo, effort, or a joint impedance) evaluated every physics step with the newest
//!   state, as the real hand's 1 kHz loop does; the loop's own stiffness and damping are
//!   taken linearly implicitly on each joint's diagonal inertia (MuJoCo's `dof_M0`), so
//!   stiff impedances stay stable at 1 ms. The reported effort is the torque the motors
//!   applied.
//! * **Model mismatch** ([`PerturbationConfig`], on by default): the same seeded draw as
//!   the joint-space world (finger link masses, per-joint damping and armature, motor
//!   gains, contact friction, arm velocity lags) is applied to the physical parameters;
//!   the objects' mass, friction, size and placement vary by [`ObjectVariation`] from the
//!   same seed. The controllers keep the nominal model.
//! * **Measurement**: [`NoiseConfig`] noise on what the drivers report (seeded);
//!   ground truth ([`MujocoWorld::physics`], [`MujocoWorld::object_poses`]) stays exact.
//! * **Cameras**: the robot's links are drawn from the URDF's collision primitives
//!   (MuJoCo collides with the same primitives, the phalanx cylinders as capsules) and
//!   the objects and table from the scene at MuJoCo's poses.

use nalgebra::{Isometry3, Point3, SVector, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use teleop_hardware::{ArmState, HandCommand, HandState};
use teleop_interfaces::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_kinematics::{KinematicState, Robot, robots};
use teleop_physics::{
    ARM_DOF, HAND_DOF, ObjectShape, ObjectSpec, ObjectVariation, PhysicsConfig, PhysicsWorld,
    RobotParams, SceneSpec,
};
use teleop_render::{Primitive, Rgb8};

use crate::camera::{CameraError, CameraScene, Part, SceneObject};
use crate::config::{NoiseConfig, PerturbationConfig};
use crate::error::SimError;
use crate::geometry::Capsule;
use crate::hand_loop::{MotorLaw, motor_torques};
use crate::hardware::RobotWorld;
use crate::measure::{TrueState, at_rest, measured};
use crate::objects::{ExternalLoad, LoadTarget, Object, ObjectShape as FixtureShape};
use crate::world::{Perturbation, World};

/// Settings of the physical world (the scene comes separately).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MujocoWorldConfig {
    /// Physics step, s. Default 0.001 (the hand's 1 kHz loop).
    pub timestep_s: f64,
    /// Seed of the measurement noise.
    pub seed: u64,
    /// The simulated robot's nominal physical parameters and driver settings (the
    /// perturbation multiplies them).
    pub robot: RobotParams,
    /// The hand's position servo, N m/rad and N m s/rad (as the joint-space world's).
    pub servo_kp_nm_rad: f64,
    pub servo_kd_nm_s_rad: f64,
    /// Measurement noise on what the drivers report.
    pub noise: NoiseConfig,
    /// How far the simulated robot lies from the controllers' model; its seed also draws
    /// the objects' variation.
    pub perturbation: PerturbationConfig,
    /// How far the objects' properties vary per seed.
    pub objects: ObjectVariation,
    /// Initial joint positions, rad.
    pub arm_initial_rad: [f64; ARM_DOF],
    pub hand_initial_rad: [f64; HAND_DOF],
}

impl Default for MujocoWorldConfig {
    fn default() -> Self {
        Self {
            timestep_s: 0.001,
            seed: 0,
            robot: RobotParams::default(),
            servo_kp_nm_rad: 2.0,
            servo_kd_nm_s_rad: 0.01,
            noise: NoiseConfig::default(),
            perturbation: PerturbationConfig::default(),
            objects: ObjectVariation::default(),
            arm_initial_rad: [0.0; ARM_DOF],
            hand_initial_rad: [0.0; HAND_DOF],
        }
    }
}

impl MujocoWorldConfig {
    /// The nominal robot and objects: no perturbation, no variation, no noise.
    #[must_use]
    pub fn nominal() -> Self {
        Self {
            noise: NoiseConfig::none(),
            perturbation: PerturbationConfig::none(),
            objects: ObjectVariation {
                mass_fraction: 0.0,
                friction_fraction: 0.0,
                size_fraction: 0.0,
                position_m: 0.0,
                yaw_rad: 0.0,
            },
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<(), SimError> {
        for (field, value) in [
            ("servo_kp_nm_rad", self.servo_kp_nm_rad),
            ("servo_kd_nm_s_rad", self.servo_kd_nm_s_rad),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(SimError::InvalidConfig {
                    field,
                    value,
                    reason: "must be finite and >= 0",
                });
            }
        }
        self.noise.validate()?;
        self.perturbation.validate()
    }
}

/// The physical robot-site world ([module docs](self)).
#[derive(Debug)]
pub struct MujocoWorld {
    config: MujocoWorldConfig,
    robot: Robot,
    kin: KinematicState,
    q_full: Vec<f64>,
    arm_dof: [usize; ARM_DOF],
    hand_dof: [usize; HAND_DOF],
    physics: PhysicsWorld,
    /// The scene as simulated (after the per-seed variation).
    scene: SceneSpec,
    perturbation: Perturbation,
    hand_lower: SVector<f64, HAND_DOF>,
    hand_upper: SVector<f64, HAND_DOF>,
    hand_inertia: SVector<f64, HAND_DOF>,
    hand_command: HandCommand,
    steps: u64,
    target_time_s: f64,
    rng: ChaCha8Rng,
    measured_arm: ArmState<ARM_DOF>,
    measured_hand: HandState,
    /// External loads on finger joints: (joint index, full torque N m, when).
    loads: Vec<(usize, f64, ExternalLoad)>,
}

impl MujocoWorld {
    /// Builds the world: the robot at its initial positions at rest (the hand holding
    /// them with its servo), the scene varied by the configured seed.
    ///
    /// # Errors
    /// Bad settings or scene ([`SimError::InvalidConfig`], [`SimError::Physics`]), or
    /// MuJoCo refusing the model.
    pub fn new(scene: &SceneSpec, config: MujocoWorldConfig) -> Result<Self, SimError> {
        config.validate()?;
        let robot = robots::pr2_arm()?;
        let limits: Vec<_> = robot.dof_limits().collect();
        let mut arm_dof = [0; ARM_DOF];
        for (i, name) in PR2_ARM_JOINTS.iter().enumerate() {
            arm_dof[i] = robot.dof_index(name)?;
        }
        let mut hand_dof = [0; HAND_DOF];
        let mut dof_hand = vec![None; robot.dof()];
        let mut hand_lower = SVector::<f64, HAND_DOF>::zeros();
        let mut hand_upper = SVector::<f64, HAND_DOF>::zeros();
        for (i, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            let d = robot.dof_index(name)?;
            hand_dof[i] = d;
            dof_hand[d] = Some(i);
            hand_lower[i] = limits[d].lower;
            hand_upper[i] = limits[d].upper;
        }
        let perturbation = Perturbation::draw(&config.perturbation, &robot, &dof_hand);
        let mut params = config.robot.clone();
        params
            .link_mass_scale
            .extend(perturbation.link_mass_scale.iter().cloned());
        for i in 0..HAND_DOF {
            params.finger_damping_scale[i] *= perturbation.damping_scale[i];
            params.finger_armature_scale[i] *= perturbation.armature_scale[i];
        }
        params.robot_friction *= perturbation.friction_scale;
        for (lag, f) in params
            .arm_velocity_lag_s
            .iter_mut()
            .zip(perturbation.arm_lag_scale)
        {
            *lag *= f;
        }
        let scene = scene.varied(&config.objects, config.perturbation.seed);
        let hand_initial: [f64; HAND_DOF] =
            std::array::from_fn(|i| config.hand_initial_rad[i].clamp(hand_lower[i], hand_upper[i]));
        let physics = PhysicsWorld::new(
            &robot,
            &PhysicsConfig {
                robot: params,
                scene: scene.clone(),
                timestep_s: config.timestep_s,
                arm_initial_rad: config.arm_initial_rad,
                hand_initial_rad: hand_initial,
            },
        )?;
        let hand_inertia = SVector::from(physics.hand_inertia_kg_m2());
        let kin = robot.new_state();
        let q_full = robot.neutral_positions();
        let rng = ChaCha8Rng::seed_from_u64(config.seed);
        let mut world = Self {
            config,
            robot,
            kin,
            q_full,
            arm_dof,
            hand_dof,
            physics,
            scene,
            perturbation,
            hand_lower,
            hand_upper,
            hand_inertia,
            hand_command: HandCommand::Position(SVector::from(hand_initial)),
            steps: 0,
            target_time_s: 0.0,
            rng,
            measured_arm: at_rest().0,
            measured_hand: at_rest().1,
            loads: Vec::new(),
        };
        world.refresh_kinematics();
        world.measure();
        Ok(world)
    }

    /// The joint-space world's scene in MuJoCo: its fixed objects (a sphere, an upright
    /// capsule) welded to the world with no table, the robot at its current positions.
    ///
    /// # Errors
    /// An object MuJoCo's scene cannot express (a capsule that is not upright); as
    /// [`MujocoWorld::new`].
    pub fn from_joint_world(
        world: &World,
        mut config: MujocoWorldConfig,
    ) -> Result<Self, SimError> {
        let objects = world
            .objects()
            .iter()
            .enumerate()
            .map(|(i, o)| fixture_spec(o, i))
            .collect::<Result<Vec<_>, _>>()?;
        config.arm_initial_rad = world.arm_position_rad().into();
        config.hand_initial_rad = world.hand_position_rad().into();
        let mut out = Self::new(
            &SceneSpec {
                table: None,
                objects,
            },
            config,
        )?;
        for load in world.loads() {
            out.add_load(load.clone())?;
        }
        Ok(out)
    }

    /// Adds an external load on the hand: a torque on a finger joint (MuJoCo's applied
    /// force on that joint, ramped as the load says).
    ///
    /// # Errors
    /// [`SimError::UnknownFingerJoint`], [`SimError::InvalidConfig`] for a number that
    /// is not finite, [`SimError::Unsupported`] for a force at a fingertip.
    pub fn add_load(&mut self, load: ExternalLoad) -> Result<(), SimError> {
        load.validate()?;
        match &load.target {
            LoadTarget::JointTorque { joint, torque_nm } => {
                let i = teleop_interfaces::joints::finger_joint_index(joint)
                    .ok_or_else(|| SimError::UnknownFingerJoint(joint.clone()))?;
                self.loads.push((i, *torque_nm, load));
                Ok(())
            }
            LoadTarget::FingertipForce { .. } => Err(SimError::Unsupported(
                "a load as a force at a fingertip (a torque on a finger joint is)",
            )),
        }
    }

    /// Ground truth: the BioTacs' normal forces, N
    /// ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order), without the
    /// sensors' noise.
    #[must_use]
    pub fn fingertip_force_n(&self) -> [f64; 5] {
        self.physics.fingertip_forces_n()
    }

    /// Ground truth: the fingertips' contacts with the scene, finger index and world
    /// point, m.
    #[must_use]
    pub fn fingertip_contacts(&self) -> Vec<(usize, Point3<f64>)> {
        self.physics
            .fingertip_contacts()
            .into_iter()
            .map(|(f, p)| (f, Point3::from(p)))
            .collect()
    }

    /// The settings in use.
    #[must_use]
    pub fn config(&self) -> &MujocoWorldConfig {
        &self.config
    }

    /// The physics (ground truth: bodies, contacts, touch sensors).
    #[must_use]
    pub fn physics(&self) -> &PhysicsWorld {
        &self.physics
    }

    /// The scene as simulated (after this seed's variation).
    #[must_use]
    pub fn scene(&self) -> &SceneSpec {
        &self.scene
    }

    /// The factors drawn for this simulated robot.
    #[must_use]
    pub fn perturbation(&self) -> &Perturbation {
        &self.perturbation
    }

    /// The robot description.
    #[must_use]
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The robot's configuration as of the last step (ground truth).
    #[must_use]
    pub fn kinematic_state(&self) -> &KinematicState {
        &self.kin
    }

    /// The palm (Shadow wrist frame) in the world, ground truth.
    #[must_use]
    pub fn palm_pose(&self) -> Isometry3<f64> {
        self.robot.link_id(robots::pr2::WRIST).map_or_else(
            |_| Isometry3::identity(),
            |id| self.robot.link_pose(&self.kin, id),
        )
    }

    /// The fingertip frames in the world ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order), ground truth.
    #[must_use]
    pub fn fingertip_positions_m(&self) -> [Point3<f64>; 5] {
        std::array::from_fn(|f| {
            self.robot.link_id(robots::shadow::TIPS[f]).map_or_else(
                |_| Point3::origin(),
                |id| self.robot.link_pose(&self.kin, id) * Point3::origin(),
            )
        })
    }

    /// Simulation time, s.
    #[must_use]
    pub fn time_s(&self) -> f64 {
        // Step counts stay far below 2^53.
        #[allow(clippy::cast_precision_loss)]
        let steps = self.steps as f64;
        steps * self.config.timestep_s
    }

    /// Advances by `duration_s` in fixed steps; durations accumulate, so how a caller
    /// slices time does not change the trajectory.
    ///
    /// # Errors
    /// [`SimError::Physics`] when the physics became unstable (the world stops there).
    pub fn step(&mut self, duration_s: f64) -> Result<(), SimError> {
        if !duration_s.is_finite() || duration_s <= 0.0 {
            return Ok(());
        }
        self.target_time_s += duration_s;
        let dt = self.config.timestep_s;
        let mut stepped = false;
        while self.time_s() + dt <= self.target_time_s + 1e-9 * dt {
            let result = self.step_once();
            stepped = true;
            if let Err(e) = result {
                self.target_time_s = self.time_s();
                self.refresh_kinematics();
                self.measure();
                return Err(e);
            }
        }
        if stepped {
            self.refresh_kinematics();
            self.measure();
        }
        Ok(())
    }

    fn step_once(&mut self) -> Result<(), SimError> {
        let h = self.config.timestep_s;
        let q = SVector::from(self.physics.hand_position());
        let v = SVector::from(self.physics.hand_velocity());
        let motors = motor_torques(
            &self.hand_command,
            &q,
            &v,
            &MotorLaw {
                lower: &self.hand_lower,
                upper: &self.hand_upper,
                gain: &self.perturbation.motor_gain_scale,
                max_nm: self.config.robot.hand_max_effort_nm,
                servo_kp_nm_rad: self.config.servo_kp_nm_rad,
                servo_kd_nm_s_rad: self.config.servo_kd_nm_s_rad,
            },
        );
        // The loop's stiffness k and damping c, linearly implicit on the diagonal:
        // tau = (tau_raw - h k v) I / (I + h c + h^2 k).
        let torque: [f64; HAND_DOF] = std::array::from_fn(|i| {
            let (k, c, inertia) = (motors.stiffness[i], motors.damping[i], self.hand_inertia[i]);
            if k > 0.0 || c > 0.0 {
                (motors.effort[i] - h * k * v[i]) * inertia / (inertia + h * c + h * h * k)
            } else {
                motors.effort[i]
            }
        });
        self.physics.set_hand_torques(&torque)?;
        if !self.loads.is_empty() {
            let t = self.time_s();
            let mut external = [0.0; HAND_DOF];
            for (i, torque_nm, load) in &self.loads {
                external[*i] += torque_nm * load.scale_at(t);
            }
            self.physics.set_hand_external_torques(&external)?;
        }
        self.physics.step()?;
        self.steps += 1;
        Ok(())
    }

    fn refresh_kinematics(&mut self) {
        let arm = self.physics.arm_position();
        let hand = self.physics.hand_position();
        for (i, &d) in self.arm_dof.iter().enumerate() {
            self.q_full[d] = arm[i];
        }
        for (i, &d) in self.hand_dof.iter().enumerate() {
            self.q_full[d] = hand[i];
        }
        // Lengths match by construction.
        let _ = self.robot.update(&mut self.kin, &self.q_full);
    }

    fn measure(&mut self) {
        let truth = TrueState {
            time_s: self.time_s(),
            arm_q: SVector::from(self.physics.arm_position()),
            arm_v: SVector::from(self.physics.arm_velocity()),
            hand_q: SVector::from(self.physics.hand_position()),
            hand_v: SVector::from(self.physics.hand_velocity()),
            hand_effort: SVector::from(self.physics.hand_effort()),
            tips: self.physics.fingertip_forces_n(),
        };
        (self.measured_arm, self.measured_hand) =
            measured(&truth, &self.config.noise, &mut self.rng);
    }
}

/// A fixed object of the joint-space world as a welded MuJoCo body.
fn fixture_spec(o: &Object, index: usize) -> Result<ObjectSpec, SimError> {
    let bad = |reason| SimError::InvalidObject {
        name: o.name.clone(),
        reason,
    };
    let shape = match o.shape {
        FixtureShape::Sphere { radius_m } => ObjectShape::Sphere { radius_m },
        FixtureShape::Capsule {
            radius_m,
            half_length_m,
        } => {
            let axis = o.pose.rotation * Vector3::z();
            if axis.z < 1.0 - 1e-9 {
                return Err(bad("a capsule in the physical world must be upright"));
            }
            ObjectShape::Capsule {
                radius_m,
                half_length_m,
            }
        }
    };
    let (_, _, yaw) = o.pose.rotation.euler_angles();
    // MJCF names: ASCII letters, digits and _.
    let mut name: String = o
        .name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if name.is_empty() {
        name = format!("object{index}");
    }
    let c = crate::camera::OBJECT_COLORS[index % crate::camera::OBJECT_COLORS.len()].0;
    Ok(ObjectSpec {
        name,
        shape,
        mass_kg: 0.1,
        friction: 0.8,
        position_m: o.pose.translation.vector.into(),
        yaw_rad: yaw,
        free: false,
        rgba: [
            f64::from(c[0]) / 255.0,
            f64::from(c[1]) / 255.0,
            f64::from(c[2]) / 255.0,
            1.0,
        ],
    })
}

/// An RGBA colour (0-1) as the renderer's.
fn rgb8(rgba: &[f64; 4]) -> Rgb8 {
    // Clamped to 0..=255 first.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let c = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    Rgb8([c(rgba[0]), c(rgba[1]), c(rgba[2])])
}

/// The render primitive of an object shape and its frame in the object's frame.
fn object_primitive(shape: &ObjectShape) -> (Primitive, Isometry3<f64>) {
    match *shape {
        ObjectShape::Box { half_m } => (
            Primitive::cuboid(&Vector3::from(half_m)),
            Isometry3::identity(),
        ),
        // The renderer's cylinders run along y, the scene's along z.
        ObjectShape::Cylinder {
            radius_m,
            half_height_m,
        } => (
            Primitive::cylinder_y(half_height_m, radius_m),
            Isometry3::from_parts(
                nalgebra::Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2),
            ),
        ),
        ObjectShape::Sphere { radius_m } => (Primitive::ball(radius_m), Isometry3::identity()),
        ObjectShape::Capsule {
            radius_m,
            half_length_m,
        } => (
            Primitive::capsule_z(half_length_m, radius_m),
            Isometry3::identity(),
        ),
    }
}

/// The table's colour in the views.
const TABLE_COLOR: Rgb8 = Rgb8([150, 115, 80]);

impl CameraScene for MujocoWorld {
    fn scene_robot(&self) -> &Robot {
        &self.robot
    }

    fn scene_kinematics(&self) -> &KinematicState {
        &self.kin
    }

    fn finger_capsules(&self) -> Option<Vec<Capsule>> {
        None
    }

    fn scene_objects(&self, out: &mut Vec<SceneObject>) -> Result<(), CameraError> {
        out.clear();
        if let Some(t) = &self.scene.table {
            let half_z = t.top_z_m / 2.0;
            out.push(SceneObject {
                primitive: Primitive::cuboid(&Vector3::new(
                    t.size_xy_m[0] / 2.0,
                    t.size_xy_m[1] / 2.0,
                    half_z,
                )),
                pose: Isometry3::translation(t.centre_xy_m[0], t.centre_xy_m[1], half_z),
                color: TABLE_COLOR,
                part: Part::Table,
            });
        }
        for (index, (spec, (_, pose))) in self
            .scene
            .objects
            .iter()
            .zip(self.physics.object_poses())
            .enumerate()
        {
            let (primitive, offset) = object_primitive(&spec.shape);
            out.push(SceneObject {
                primitive,
                pose: pose * offset,
                color: rgb8(&spec.rgba),
                part: Part::Object(index),
            });
        }
        Ok(())
    }
}

impl RobotWorld for MujocoWorld {
    fn time_s(&self) -> f64 {
        MujocoWorld::time_s(self)
    }
    fn advance(&mut self, duration_s: f64) -> Result<(), SimError> {
        self.step(duration_s)
    }
    fn arm_state(&self) -> ArmState<7> {
        self.measured_arm
    }
    fn hand_state(&self) -> HandState {
        self.measured_hand
    }
    fn command_arm(&mut self, velocity_rad_s: &SVector<f64, 7>) {
        // Non-finite commands are refused by the hardware handles before they get here;
        // the physics refuses them again and keeps the previous one.
        let _ = self.physics.command_arm_velocity(&(*velocity_rad_s).into());
    }
    fn command_hand(&mut self, command: &HandCommand) {
        self.hand_command = *command;
    }
    fn object_poses(&self) -> Vec<(String, Isometry3<f64>)> {
        self.physics
            .object_poses()
            .into_iter()
            .map(|(n, p)| (n.to_owned(), p))
            .collect()
    }
}

/// The PR2's start posture for the pick job's top grasp (thesis ch. 7.6.2: "We
/// teleoperated the robot to grasp the Pringles can from the top and from the right side
/// by power grasp"): the palm facing down, the fingers 20 deg above the horizontal and
/// turned 15 deg to the left. Searched by `cargo run --release -p teleop-ik --example
/// pick_posture -- top`: of the palm-down postures around the working palm it keeps the
/// most room to every joint limit (0.128 rad, the Shadow wrist's WRJ2) over the job's
/// moves (12 cm forward and back, 15 cm toward the object, 15 cm down, 12 cm up,
/// diagonals) walked by the tracking IK; the working posture keeps 0.124 rad there.
/// At the working posture (the palm facing 40 deg below the horizontal, the fingers
/// 27 deg up) neither a side grasp nor a top grasp of the can held
/// (`cargo run --release -p teleop-sim --example grasp_study`, docs/physics.md).
pub const PICK_TOP_GRASP_POSTURE_RAD: [f64; ARM_DOF] =
    [-0.415, 0.685, -0.765, -1.381, 0.56, -0.158, 0.101];

/// The table top below the palm of [`PICK_TOP_GRASP_POSTURE_RAD`], m: the can's top
/// (23 cm tall) 10 cm below the palm, so the grasp is 8-9 cm down and 15 cm sideways.
pub const PICK_TOP_GRASP_TABLE_BELOW_PALM_M: f64 = 0.33;

/// A table in front of the robot with the objects of the pick tasks (thesis ch. 6.4's
/// Pringles can and cube) on it, placed from the palm at an arm posture: the table top
/// `table_below_palm_m` below the palm, the can and the cube `object_offset_m` to either
/// side of it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PickSceneConfig {
    /// The arm posture the scene is placed from (and the world starts at), rad.
    pub arm_posture_rad: [f64; ARM_DOF],
    /// The hand's initial posture, rad.
    pub hand_posture_rad: [f64; HAND_DOF],
    /// Height of the palm above the table top, m. Default 0.4: the launch tasks'
    /// scripted (open-loop) operator motions stay above it (at 0.25 m the pouring
    /// task's turn pressed the hand onto the table, and the PR2 missed its pose by
    /// 3.3 cm while held there).
    pub table_below_palm_m: f64,
    /// Sideways (world y) distance of the can and the cube from the palm, m. Default
    /// 0.15.
    pub object_offset_m: f64,
    /// The job judged in this scene (from ground truth, in the simulator's report).
    pub job: PickJobConfig,
}

/// The pick scene's job: move `object` onto a spot of the table, judged by
/// [`teleop_physics::PickPlaceJudge`] (lifted, at rest with its centre within
/// `target_half_xy_m` of the spot at its resting height +- 2 cm, the arm back at its
/// starting posture; nothing fallen off the table; within the time limit).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PickJobConfig {
    /// `can` or `cube`. Default `can` (thesis ch. 6.4: "pick a Pringles can").
    pub object: String,
    /// The spot, from the palm of the starting posture in the world's x-y plane, m.
    /// Default [0.1, 0]: on the table between the can and the cube, 10 cm further out.
    pub target_from_palm_xy_m: [f64; 2],
    /// Default 0.05 m.
    pub target_half_xy_m: f64,
    /// Default 300 s.
    pub time_limit_s: f64,
}

/// One block of the tower job, placed from the palm of the scene's starting posture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TowerBlock {
    pub name: String,
    /// Half extents of the box, m.
    pub half_m: [f64; 3],
    /// Where it stands, from the palm of the starting posture in the world's x-y plane, m.
    pub from_palm_xy_m: [f64; 2],
    /// Colour in the camera views, RGBA 0-1.
    pub rgba: [f64; 4],
}

/// The tower job (thesis ch. 7.6.2, Table 7.1: "stack three different objects on top
/// of each other"; 60 % success, 102.8 s): wooden blocks on the pick scene's table,
/// the lowest where the pick job's target is, the others to either side of the palm;
/// judged by [`teleop_physics::TowerJudge`] (each block resting on the one below,
/// centred within `align_m`, for `stand_s`, the arm back at its start).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TowerJobConfig {
    /// The blocks from the bottom of the tower up, at least two.
    pub blocks: Vec<TowerBlock>,
    /// An upper block's centre within this of the lower's, horizontally, m. Default
    /// 0.03: over the lower block's top face (the smaller blocks' half widths are 3.5
    /// and 4 cm) with 5 mm to spare; how far off still stands is the physics' to say,
    /// the judge's `stand_s` at rest.
    pub align_m: f64,
    /// Default 0.01 m: covers the blocks' size variation per seed (5 %, up to 4 mm over
    /// two half heights), which the judge does not know.
    pub seat_m: f64,
    /// Default 2 s.
    pub stand_s: f64,
    /// Default 300 s.
    pub time_limit_s: f64,
}

impl Default for TowerJobConfig {
    fn default() -> Self {
        Self {
            blocks: vec![
                TowerBlock {
                    name: "base".to_owned(),
                    half_m: [0.05, 0.05, 0.02],
                    from_palm_xy_m: [0.05, -0.15],
                    rgba: [0.15, 0.3, 0.8, 1.0],
                },
                TowerBlock {
                    name: "middle".to_owned(),
                    half_m: [0.04, 0.04, 0.1],
                    from_palm_xy_m: [0.0, 0.15],
                    rgba: [0.9, 0.5, 0.1, 1.0],
                },
                TowerBlock {
                    name: "top".to_owned(),
                    half_m: [0.035, 0.035, 0.1],
                    from_palm_xy_m: [0.0, -0.32],
                    rgba: [0.2, 0.7, 0.2, 1.0],
                },
            ],
            align_m: 0.03,
            seat_m: 0.01,
            stand_s: 2.0,
            time_limit_s: 300.0,
        }
    }
}

impl TowerJobConfig {
    /// The operator's placements for this tower: each block above the lowest onto the
    /// one below, in order (the sizes as nominal, as a person sees them).
    #[must_use]
    pub fn placements(&self) -> Vec<crate::operator_site::Placement> {
        self.blocks
            .windows(2)
            .map(|w| crate::operator_site::Placement {
                object: w[1].name.clone(),
                half_height_m: w[1].half_m[2],
                onto: crate::operator_site::Onto::Object {
                    name: w[0].name.clone(),
                    half_height_m: w[0].half_m[2],
                },
            })
            .collect()
    }
}

impl Default for PickJobConfig {
    fn default() -> Self {
        Self {
            object: "can".to_owned(),
            target_from_palm_xy_m: [0.1, 0.0],
            target_half_xy_m: 0.05,
            time_limit_s: 300.0,
        }
    }
}

impl Default for PickSceneConfig {
    fn default() -> Self {
        Self {
            arm_posture_rad: crate::WORKING_POSTURE_RAD,
            hand_posture_rad: [0.0; HAND_DOF],
            table_below_palm_m: 0.4,
            object_offset_m: 0.15,
            job: PickJobConfig::default(),
        }
    }
}

impl PickSceneConfig {
    /// The scene.
    ///
    /// # Errors
    /// Offsets that are not finite and positive; a robot model without the palm.
    pub fn scene(&self) -> Result<SceneSpec, SimError> {
        let (table, p) = self.table()?;
        let top = table.top_z_m;
        let d = self.object_offset_m;
        Ok(SceneSpec {
            table: Some(table),
            objects: vec![
                teleop_physics::scene::can("can", [p.x, p.y + d], top),
                teleop_physics::scene::cube("cube", 0.05, [p.x, p.y - d], top),
            ],
        })
    }

    /// The table under the palm of the starting posture, and that palm's position, m.
    /// The scene's offsets checked.
    fn table(&self) -> Result<(teleop_physics::TableSpec, Vector3<f64>), SimError> {
        for (field, value) in [
            ("pick.table_below_palm_m", self.table_below_palm_m),
            ("pick.object_offset_m", self.object_offset_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(SimError::InvalidConfig {
                    field,
                    value,
                    reason: "must be finite and > 0",
                });
            }
        }
        let p = self.palm_m()?;
        let top = p.z - self.table_below_palm_m;
        if top <= 0.05 {
            return Err(SimError::InvalidConfig {
                field: "pick.table_below_palm_m",
                value: self.table_below_palm_m,
                reason: "puts the table top below the floor at this arm posture",
            });
        }
        let table = teleop_physics::TableSpec {
            centre_xy_m: [p.x + 0.1, p.y],
            top_z_m: top,
            ..teleop_physics::TableSpec::default()
        };
        Ok((table, p))
    }

    /// The palm's position at the starting posture, m.
    fn palm_m(&self) -> Result<Vector3<f64>, SimError> {
        let robot = robots::pr2_arm()?;
        let mut q = robot.neutral_positions();
        for (i, name) in PR2_ARM_JOINTS.iter().enumerate() {
            q[robot.dof_index(name)?] = self.arm_posture_rad[i];
        }
        let mut kin = robot.new_state();
        robot.update(&mut kin, &q)?;
        let palm = robot.link_pose(&kin, robot.link_id(robots::pr2::WRIST)?);
        Ok(palm.translation.vector)
    }

    /// The judge's settings for this scene's job: the target spot on the table at the
    /// job object's resting height.
    ///
    /// # Errors
    /// The scene's errors; an object not in the scene; a bad target size or time limit.
    pub fn job_config(&self) -> Result<teleop_physics::PickPlaceConfig, SimError> {
        for (field, value) in [
            (
                "pick.job.target_from_palm_xy_m",
                self.job.target_from_palm_xy_m[0],
            ),
            (
                "pick.job.target_from_palm_xy_m",
                self.job.target_from_palm_xy_m[1],
            ),
        ] {
            if !value.is_finite() {
                return Err(SimError::InvalidConfig {
                    field,
                    value,
                    reason: "must be finite",
                });
            }
        }
        for (field, value) in [
            ("pick.job.target_half_xy_m", self.job.target_half_xy_m),
            ("pick.job.time_limit_s", self.job.time_limit_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(SimError::InvalidConfig {
                    field,
                    value,
                    reason: "must be finite and > 0",
                });
            }
        }
        let scene = self.scene()?;
        let table_top_z_m = scene.table.map_or(0.0, |t| t.top_z_m);
        let object = scene
            .objects
            .iter()
            .find(|o| o.name == self.job.object)
            .ok_or_else(|| SimError::InvalidObject {
                name: self.job.object.clone(),
                reason: "pick.job.object names no object of the pick scene (can, cube)",
            })?;
        let p = self.palm_m()?;
        let h = self.job.target_half_xy_m;
        let mut job = teleop_physics::PickPlaceConfig::new(
            &self.job.object,
            teleop_physics::TargetRegion {
                centre_m: [
                    p.x + self.job.target_from_palm_xy_m[0],
                    p.y + self.job.target_from_palm_xy_m[1],
                    object.position_m[2],
                ],
                half_extent_m: [h, h, 0.02],
            },
            table_top_z_m,
        );
        job.time_limit_s = self.job.time_limit_s;
        job.validate().map_err(|_| SimError::InvalidConfig {
            field: "pick.job",
            value: f64::NAN,
            reason: "refused by the job's judge",
        })?;
        Ok(job)
    }

    /// The tower job's scene: this scene's table with `tower`'s blocks on it (wood,
    /// 600 kg/m^3).
    ///
    /// # Errors
    /// As [`Self::scene`]; a block whose sizes or place are not finite and positive.
    pub fn tower_scene(&self, tower: &TowerJobConfig) -> Result<SceneSpec, SimError> {
        let (table, p) = self.table()?;
        let top = table.top_z_m;
        let objects = tower
            .blocks
            .iter()
            .map(|b| {
                let bad_size = b.half_m.iter().find(|v| !(v.is_finite() && **v > 0.0));
                let bad_place = b.from_palm_xy_m.iter().find(|v| !v.is_finite());
                for (field, value, reason) in [
                    ("tower.blocks.half_m", bad_size, "must be finite and > 0"),
                    ("tower.blocks.from_palm_xy_m", bad_place, "must be finite"),
                ] {
                    if let Some(&value) = value {
                        return Err(SimError::InvalidConfig {
                            field,
                            value,
                            reason,
                        });
                    }
                }
                Ok(teleop_physics::ObjectSpec {
                    name: b.name.clone(),
                    shape: teleop_physics::ObjectShape::Box { half_m: b.half_m },
                    mass_kg: 600.0 * 8.0 * b.half_m.iter().product::<f64>(),
                    friction: 0.8,
                    position_m: [
                        p.x + b.from_palm_xy_m[0],
                        p.y + b.from_palm_xy_m[1],
                        top + b.half_m[2],
                    ],
                    yaw_rad: 0.0,
                    free: true,
                    rgba: b.rgba,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(SceneSpec {
            table: Some(table),
            objects,
        })
    }

    /// The judge's settings for the tower job in this scene.
    ///
    /// # Errors
    /// As [`Self::tower_scene`]; settings the judge refuses.
    pub fn tower_job_config(
        &self,
        tower: &TowerJobConfig,
    ) -> Result<teleop_physics::TowerConfig, SimError> {
        let scene = self.tower_scene(tower)?;
        let blocks: Vec<(&str, f64)> = tower
            .blocks
            .iter()
            .map(|b| (b.name.as_str(), b.half_m[2]))
            .collect();
        let mut job =
            teleop_physics::TowerConfig::new(&blocks, scene.table.map_or(0.0, |t| t.top_z_m));
        job.align_m = tower.align_m;
        job.seat_m = tower.seat_m;
        job.stand_s = tower.stand_s;
        job.time_limit_s = tower.time_limit_s;
        job.validate()?;
        Ok(job)
    }

    /// The config of a world that starts at this scene's arm and hand postures.
    #[must_use]
    pub fn world_config(&self, base: &MujocoWorldConfig) -> MujocoWorldConfig {
        MujocoWorldConfig {
            arm_initial_rad: self.arm_posture_rad,
            hand_initial_rad: self.hand_posture_rad,
            ..base.clone()
        }
    }
}
