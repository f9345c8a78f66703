//! [`PhysicsWorld`]: the PR2 arm with the Shadow hand and the scene, on MuJoCo.
//!
//! **Arm** (7 joints of [`PR2_ARM_JOINTS`]): the simulated PR2 driver's velocity loop,
//! [`ArmSim`] (the previous simulator's kinematic arm): each step the commanded velocity
//! goes through a first-order lag (`velocity_lag_s`), an acceleration clamp and the URDF
//! velocity limit (or, once the newest command is older than `command_timeout_s`, a
//! constant-deceleration ramp to zero, as the real driver's watchdog does) and is
//! integrated into a position reference inside the joint limits, here also kept within
//! `max_tracking_error_rad` of the measured position (no wind-up while the arm is
//! blocked). A MuJoCo position servo with velocity feed-forward tracks it,
//! `tau = kp (q_ref - q) + kv (v_ref - qd)`, clamped to the URDF effort, its damping
//! integrated implicitly (`implicitfast`). Gravity and Coriolis torques of the arm's
//! joints are compensated by the true model (the PR2's spring counterbalance and its
//! controllers' feed-forward), so the effort limit is spent on motion and contact: the
//! arm now feels what it touches and what it carries.
//!
//! **Hand** (17 joints of [`SHADOW_FINGER_JOINTS`]): joint torque motors, clamped to
//! `hand_max_effort_nm`; the hand's own servo or impedance loop runs in the caller at the
//! simulation rate, as the real hand's 1 kHz loop does. Joint damping, armature and dry
//! friction are MuJoCo's. Finger gravity acts (the Shadow hand does not compensate it).
//!
//! **Contacts**: MuJoCo's soft constraints, elliptic friction cones, `impratio` 100
//! ([`RobotParams::impratio`]) for grasps that do not creep; objects use `condim` 4
//! (torsional friction) so a pinched object does not spin. **BioTacs**: a touch sensor over each distal link's collision
//! primitives (the sum of the normal forces of the contacts inside it), summed per
//! finger.

use mujoco_rs::prelude::*;
use nalgebra::{Isometry3, Quaternion, SVector, Translation3, UnitQuaternion};
use teleop_hardware::velocity_driver::{ArmJointLimits, ArmSim};
use teleop_interfaces::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_kinematics::{JointLimits, Robot, robots};

use crate::error::PhysicsError;
use crate::mjcf::{JointDynamics, RobotMjcf, num};
use crate::scene::SceneSpec;

/// Arm joints.
pub const ARM_DOF: usize = 7;
/// Actuated finger joints.
pub const HAND_DOF: usize = 17;

/// The robot's physical parameters beyond the URDF, and the driver loops' settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotParams {
    /// The five PR2 joints: damping N m s/rad, armature kg m^2, dry friction N m.
    pub pr2_damping: f64,
    pub pr2_armature: f64,
    pub pr2_frictionloss: f64,
    /// The Shadow wrist joints (WRJ2, WRJ1).
    pub wrist_damping: f64,
    pub wrist_armature: f64,
    pub wrist_frictionloss: f64,
    /// The finger joints.
    pub finger_damping: f64,
    pub finger_armature: f64,
    pub finger_frictionloss: f64,
    /// Per arm joint ([`PR2_ARM_JOINTS`] order): position gain N m/rad and velocity gain
    /// N m s/rad of the driver's servo.
    pub arm_kp: [f64; ARM_DOF],
    pub arm_kv: [f64; ARM_DOF],
    /// Per arm joint: the velocity loop's lag, s.
    pub arm_velocity_lag_s: [f64; ARM_DOF],
    /// The driver's acceleration clamp (also its braking deceleration), rad/s^2.
    pub arm_acceleration_limit_rad_s2: f64,
    /// The driver stops the arm when its newest command is older than this, s.
    pub arm_command_timeout_s: f64,
    /// The reference is kept within this of the measured position, rad.
    pub arm_max_tracking_error_rad: f64,
    /// The finger motors' torque limit, N m.
    pub hand_max_effort_nm: f64,
    /// Sliding friction of the robot's surfaces (the BioTac's silicone skin).
    pub robot_friction: f64,
    /// How far the touch sites reach beyond the BioTac geoms, m.
    pub touch_margin_m: f64,
    /// MuJoCo's `impratio`: how much stiffer the friction constraints are than the
    /// normal ones (with elliptic cones). Default 100: MuJoCo's soft friction lets a
    /// grasped object creep out of a grip held still, which a silicone-skinned fingertip
    /// does not do; at 10 the pick job's can (top grasp, 35 placements and postures) was
    /// still held after 10 s in 8, at 100 in 27, as many as with MuJoCo's no-slip
    /// solver at 2.5x the cost per step (`cargo run --release -p teleop-sim --example
    /// grasp_study -- 'p20 z0.075'`).
    pub impratio: f64,
    /// Mass (and inertia) factor of every link moved by a finger joint.
    pub finger_mass_scale: f64,
    /// Per finger joint ([`SHADOW_FINGER_JOINTS`] order): factors on `finger_damping`
    /// and `finger_armature` (a simulated hand whose joints differ from one another).
    pub finger_damping_scale: [f64; HAND_DOF],
    pub finger_armature_scale: [f64; HAND_DOF],
    /// Further mass (and inertia) factors by link name, on top of `finger_mass_scale`.
    pub link_mass_scale: Vec<(String, f64)>,
}

impl Default for RobotParams {
    fn default() -> Self {
        Self {
            // [EST]: pr2_description gives the five joints damping 0.1-10; armature from
            // the PR2's geared motors (reflected rotor inertia of order 0.1 kg m^2).
            pr2_damping: 1.0,
            pr2_armature: 0.1,
            pr2_frictionloss: 0.1,
            wrist_damping: 0.1,
            wrist_armature: 0.005,
            wrist_frictionloss: 0.01,
            // As the previous simulator: damping 0.05, armature 2e-4 (MuJoCo Menagerie's
            // Shadow hand); dry friction [EST].
            finger_damping: 0.05,
            finger_armature: 2e-4,
            finger_frictionloss: 0.005,
            arm_kp: [2000.0, 2000.0, 1000.0, 1000.0, 500.0, 200.0, 200.0],
            arm_kv: [200.0, 200.0, 60.0, 60.0, 20.0, 4.0, 4.0],
            arm_velocity_lag_s: [0.03; ARM_DOF],
            arm_acceleration_limit_rad_s2: 8.0,
            arm_command_timeout_s: 0.1,
            arm_max_tracking_error_rad: 0.2,
            hand_max_effort_nm: 2.0,
            robot_friction: 1.0,
            touch_margin_m: 0.002,
            impratio: 100.0,
            finger_mass_scale: 1.0,
            finger_damping_scale: [1.0; HAND_DOF],
            finger_armature_scale: [1.0; HAND_DOF],
            link_mass_scale: Vec::new(),
        }
    }
}

/// Everything a world is made from.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicsConfig {
    pub robot: RobotParams,
    pub scene: SceneSpec,
    /// Simulation step, s.
    pub timestep_s: f64,
    pub arm_initial_rad: [f64; ARM_DOF],
    pub hand_initial_rad: [f64; HAND_DOF],
}

/// Indices of one joint in MuJoCo's arrays.
#[derive(Debug, Clone, Copy)]
struct JointIdx {
    qpos: usize,
    dof: usize,
    actuator: usize,
}

/// The physical world ([module docs](self)).
#[derive(Debug)]
pub struct PhysicsWorld {
    data: MjData<Box<MjModel>>,
    xml: String,
    params: RobotParams,
    arm: [JointIdx; ARM_DOF],
    hand: [JointIdx; HAND_DOF],
    /// Sensor data addresses of the touch sensors, per finger.
    touch: [Vec<usize>; 5],
    /// Bodies of the scene's objects, in [`SceneSpec::objects`] order.
    objects: Vec<(String, usize)>,
    /// The PR2 driver's velocity loop: its position and velocity are the servos' reference.
    driver: ArmSim<ARM_DOF>,
    hand_torque: [f64; HAND_DOF],
    /// External torques on the finger joints (a load on the hand), N m.
    hand_external: [f64; HAND_DOF],
    /// Bodies of the distal links ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS)
    /// order): where a fingertip contact is.
    distal_bodies: [usize; 5],
}

fn missing(kind: &'static str, name: &str) -> PhysicsError {
    PhysicsError::MissingName {
        kind,
        name: name.to_owned(),
    }
}

/// The whole MJCF of a world: robot (from `robot`'s description), scene, actuators and
/// sensors. Also returns the touch sites per finger.
///
/// # Errors
/// [`PhysicsError::Model`] / [`PhysicsError::Invalid`] for what cannot be expressed.
pub fn world_mjcf(
    robot: &Robot,
    config: &PhysicsConfig,
) -> Result<(String, [Vec<String>; 5]), PhysicsError> {
    config.scene.validate()?;
    let p = &config.robot;
    if !(config.timestep_s.is_finite() && config.timestep_s > 0.0 && config.timestep_s <= 0.01) {
        return Err(PhysicsError::Invalid {
            what: "timestep_s",
            why: format!("{} (must be in (0, 0.01])", config.timestep_s),
        });
    }
    if !(p.impratio.is_finite() && (1.0..=1e4).contains(&p.impratio)) {
        return Err(PhysicsError::Invalid {
            what: "robot.impratio",
            why: format!("{} (must be in [1, 10000])", p.impratio),
        });
    }
    let mut dynamics = Vec::new();
    for (i, j) in PR2_ARM_JOINTS.iter().enumerate() {
        let d = if i < 5 {
            JointDynamics {
                damping: p.pr2_damping,
                armature: p.pr2_armature,
                frictionloss: p.pr2_frictionloss,
            }
        } else {
            JointDynamics {
                damping: p.wrist_damping,
                armature: p.wrist_armature,
                frictionloss: p.wrist_frictionloss,
            }
        };
        dynamics.push(((*j).to_owned(), d));
    }
    let finger = JointDynamics {
        damping: p.finger_damping,
        armature: p.finger_armature,
        frictionloss: p.finger_frictionloss,
    };
    for (i, j) in SHADOW_FINGER_JOINTS.iter().enumerate() {
        let (d, a) = (p.finger_damping_scale[i], p.finger_armature_scale[i]);
        if !(d.is_finite() && d > 0.0 && a.is_finite() && a > 0.0) {
            return Err(PhysicsError::Invalid {
                what: "finger_damping_scale / finger_armature_scale",
                why: format!("{j}: {d} / {a} (must be > 0)"),
            });
        }
        dynamics.push((
            (*j).to_owned(),
            JointDynamics {
                damping: finger.damping * d,
                armature: finger.armature * a,
                ..finger
            },
        ));
    }
    let arm_limits = arm_joint_limits(robot)?;
    let mut mass_scale = finger_link_mass_scale(robot, p.finger_mass_scale)?;
    for (link, f) in &p.link_mass_scale {
        if !(f.is_finite() && *f > 0.0) || robot.link_id(link).is_err() {
            return Err(PhysicsError::Invalid {
                what: "link_mass_scale",
                why: format!("{link}: {f} (must be a link of the robot and > 0)"),
            });
        }
        match mass_scale.iter_mut().find(|(n, _)| n == link) {
            Some((_, g)) => *g *= f,
            None => mass_scale.push((link.clone(), *f)),
        }
    }
    let mjcf = RobotMjcf {
        robot,
        dynamics,
        default_dynamics: finger,
        touch_links: robots::shadow::DISTALS
            .iter()
            .map(|s| (*s).to_owned())
            .collect(),
        touch_margin_m: p.touch_margin_m,
        friction: p.robot_friction,
        mass_scale,
    };
    let (bodies, sites) = mjcf.body_tree()?;
    let mut xml = String::new();
    xml.push_str("<mujoco model=\"teleop_robot_site\">\n");
    xml.push_str(
        "  <compiler angle=\"radian\" autolimits=\"true\" boundmass=\"1e-6\" boundinertia=\"1e-10\"/>\n",
    );
    xml.push_str(&format!(
        "  <option timestep=\"{}\" integrator=\"implicitfast\" cone=\"elliptic\" impratio=\"{}\"/>\n",
        num(config.timestep_s),
        num(p.impratio)
    ));
    xml.push_str("  <worldbody>\n");
    xml.push_str("    <light pos=\"0.5 0 3\" dir=\"0 0 -1\" directional=\"true\"/>\n");
    xml.push_str(&config.scene.worldbody_xml());
    xml.push_str(&bodies);
    xml.push_str("  </worldbody>\n  <actuator>\n");
    for (i, j) in PR2_ARM_JOINTS.iter().enumerate() {
        let effort = arm_limits[i].map_or(30.0, |l| l.effort);
        xml.push_str(&format!(
            "    <position name=\"act_{j}\" joint=\"{j}\" kp=\"{}\" kv=\"{}\" forcerange=\"{} {}\"/>\n",
            num(p.arm_kp[i]),
            num(p.arm_kv[i]),
            num(-effort),
            num(effort)
        ));
    }
    for j in SHADOW_FINGER_JOINTS {
        xml.push_str(&format!(
            "    <motor name=\"act_{j}\" joint=\"{j}\" ctrlrange=\"{} {}\"/>\n",
            num(-p.hand_max_effort_nm),
            num(p.hand_max_effort_nm)
        ));
    }
    xml.push_str("  </actuator>\n  <sensor>\n");
    for finger in &sites {
        for s in finger {
            xml.push_str(&format!("    <touch name=\"{s}\" site=\"{s}\"/>\n"));
        }
    }
    xml.push_str("  </sensor>\n</mujoco>\n");
    let sites: [Vec<String>; 5] = sites
        .try_into()
        .map_err(|_| PhysicsError::Model("five BioTac links expected".into()))?;
    Ok((xml, sites))
}

/// The URDF limits of the arm's joints ([`PR2_ARM_JOINTS`] order).
fn arm_joint_limits(robot: &Robot) -> Result<[Option<JointLimits>; ARM_DOF], PhysicsError> {
    let mut out = [None; ARM_DOF];
    for (i, j) in PR2_ARM_JOINTS.iter().enumerate() {
        out[i] = robot
            .joint(robot.joint_id(j).map_err(|_| missing("joint", j))?)
            .limits;
    }
    Ok(out)
}

/// The factor `scale` for every link moved by a finger joint.
fn finger_link_mass_scale(robot: &Robot, scale: f64) -> Result<Vec<(String, f64)>, PhysicsError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(PhysicsError::Invalid {
            what: "finger_mass_scale",
            why: format!("{scale} (must be > 0)"),
        });
    }
    let finger_dofs: Vec<usize> = SHADOW_FINGER_JOINTS
        .iter()
        .filter_map(|j| robot.dof_index(j).ok())
        .collect();
    let mut out = Vec::new();
    for link in robot.links() {
        let Ok(id) = robot.link_id(&link.name) else {
            continue;
        };
        if robot
            .dofs_moving(id)
            .iter()
            .any(|d| finger_dofs.contains(d))
        {
            out.push((link.name.clone(), scale));
        }
    }
    Ok(out)
}

fn obj_id(
    model: &MjModel,
    kind: MjtObjBase,
    what: &'static str,
    name: &str,
) -> Result<usize, PhysicsError> {
    model
        .name_to_id(kind, name)
        .ok_or_else(|| missing(what, name))
}

fn joint_idx(model: &MjModel, name: &str) -> Result<JointIdx, PhysicsError> {
    let j = obj_id(model, MjtObjBase::mjOBJ_JOINT, "joint", name)?;
    let a = obj_id(
        model,
        MjtObjBase::mjOBJ_ACTUATOR,
        "actuator",
        &format!("act_{name}"),
    )?;
    let qpos = usize::try_from(model.jnt_qposadr()[j]).map_err(|_| missing("joint", name))?;
    let dof = usize::try_from(model.jnt_dofadr()[j]).map_err(|_| missing("joint", name))?;
    Ok(JointIdx {
        qpos,
        dof,
        actuator: a,
    })
}

impl PhysicsWorld {
    /// Builds the world: generates the MJCF from `robot` (the PR2 arm with the Shadow
    /// hand, [`robots::pr2_arm`]) and `config`, compiles it and puts the robot at its
    /// initial positions, at rest.
    ///
    /// # Errors
    /// Invalid settings, a description that cannot be expressed, or MuJoCo's compiler
    /// refusing the model (its message).
    pub fn new(robot: &Robot, config: &PhysicsConfig) -> Result<Self, PhysicsError> {
        let (xml, sites) = world_mjcf(robot, config)?;
        let model =
            MjModel::from_xml_string(&xml).map_err(|e| PhysicsError::Compile(e.to_string()))?;
        let mut arm = [JointIdx {
            qpos: 0,
            dof: 0,
            actuator: 0,
        }; ARM_DOF];
        for (i, j) in PR2_ARM_JOINTS.iter().enumerate() {
            arm[i] = joint_idx(&model, j)?;
        }
        let mut hand = [arm[0]; HAND_DOF];
        for (i, j) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            hand[i] = joint_idx(&model, j)?;
        }
        let mut touch: [Vec<usize>; 5] = Default::default();
        for (f, finger) in sites.iter().enumerate() {
            for s in finger {
                let id = obj_id(&model, MjtObjBase::mjOBJ_SENSOR, "sensor", s)?;
                let adr =
                    usize::try_from(model.sensor_adr()[id]).map_err(|_| missing("sensor", s))?;
                touch[f].push(adr);
            }
        }
        let mut objects = Vec::new();
        for o in &config.scene.objects {
            objects.push((
                o.name.clone(),
                obj_id(&model, MjtObjBase::mjOBJ_BODY, "body", &o.name)?,
            ));
        }
        let p = &config.robot;
        let limits = arm_joint_limits(robot)?.map(|l| {
            let (lower_rad, upper_rad, velocity_rad_s) = match l {
                Some(l) if l.is_bounded() => (l.lower, l.upper, l.velocity),
                Some(l) => (f64::NEG_INFINITY, f64::INFINITY, l.velocity),
                None => (f64::NEG_INFINITY, f64::INFINITY, 1.0),
            };
            ArmJointLimits {
                lower_rad,
                upper_rad,
                velocity_rad_s,
                acceleration_rad_s2: p.arm_acceleration_limit_rad_s2,
            }
        });
        let driver = ArmSim::new(
            limits,
            &SVector::from(config.arm_initial_rad),
            0.0,
            p.arm_command_timeout_s,
        )
        .with_lags(p.arm_velocity_lag_s);
        let mut distal_bodies = [0; 5];
        for (f, link) in robots::shadow::DISTALS.iter().enumerate() {
            distal_bodies[f] = obj_id(&model, MjtObjBase::mjOBJ_BODY, "body", link)?;
        }
        let data = MjData::new(Box::new(model));
        let mut world = Self {
            data,
            xml,
            params: config.robot.clone(),
            arm,
            hand,
            touch,
            objects,
            driver,
            hand_torque: [0.0; HAND_DOF],
            hand_external: [0.0; HAND_DOF],
            distal_bodies,
        };
        world.set_positions(&config.arm_initial_rad, &config.hand_initial_rad)?;
        Ok(world)
    }

    /// The generated MJCF (for inspection; `docs/physics.md` shows how to open it in
    /// MuJoCo's viewer).
    #[must_use]
    pub fn mjcf(&self) -> &str {
        &self.xml
    }

    /// The compiled model.
    #[must_use]
    pub fn model(&self) -> &MjModel {
        self.data.model()
    }

    /// Simulation time, s.
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.data.time()
    }

    /// Simulation step, s.
    #[must_use]
    pub fn timestep_s(&self) -> f64 {
        self.data.model().opt().timestep
    }

    /// Puts the robot at `arm` / `hand` at rest (velocities zero, the driver's reference
    /// there) and recomputes the derived quantities.
    ///
    /// # Errors
    /// [`PhysicsError::Invalid`] for a value that is not finite.
    pub fn set_positions(
        &mut self,
        arm: &[f64; ARM_DOF],
        hand: &[f64; HAND_DOF],
    ) -> Result<(), PhysicsError> {
        if !arm.iter().chain(hand.iter()).all(|v| v.is_finite()) {
            return Err(PhysicsError::Invalid {
                what: "positions",
                why: "not finite".into(),
            });
        }
        {
            let qpos = self.data.qpos_mut();
            for (i, j) in self.arm.iter().enumerate() {
                qpos[j.qpos] = arm[i];
            }
            for (i, j) in self.hand.iter().enumerate() {
                qpos[j.qpos] = hand[i];
            }
        }
        {
            let qvel = self.data.qvel_mut();
            for j in self.arm.iter().chain(self.hand.iter()) {
                qvel[j.dof] = 0.0;
            }
        }
        self.driver.set_position(&SVector::from(*arm));
        self.data.forward();
        Ok(())
    }

    /// Commands arm joint velocities, rad/s, at the current simulation time (the driver's
    /// watchdog counts from there).
    ///
    /// # Errors
    /// [`PhysicsError::Invalid`] for a value that is not finite (nothing is changed).
    pub fn command_arm_velocity(
        &mut self,
        velocity_rad_s: &[f64; ARM_DOF],
    ) -> Result<(), PhysicsError> {
        if !velocity_rad_s.iter().all(|v| v.is_finite()) {
            return Err(PhysicsError::Invalid {
                what: "arm velocity command",
                why: "not finite".into(),
            });
        }
        self.driver
            .command(&SVector::from(*velocity_rad_s), self.data.time());
        Ok(())
    }

    /// Sets the finger motors' torques, N m (held until the next call; clamped to the
    /// motors' limit).
    ///
    /// # Errors
    /// [`PhysicsError::Invalid`] for a value that is not finite (nothing is changed).
    pub fn set_hand_torques(&mut self, torque_nm: &[f64; HAND_DOF]) -> Result<(), PhysicsError> {
        if !torque_nm.iter().all(|v| v.is_finite()) {
            return Err(PhysicsError::Invalid {
                what: "hand torques",
                why: "not finite".into(),
            });
        }
        let m = self.params.hand_max_effort_nm;
        self.hand_torque = torque_nm.map(|t| t.clamp(-m, m));
        Ok(())
    }

    /// Sets external torques on the finger joints, N m, positive about each joint's
    /// axis (a load on the hand: held until the next call; not clamped, not the motors').
    ///
    /// # Errors
    /// [`PhysicsError::Invalid`] for a value that is not finite (nothing is changed).
    pub fn set_hand_external_torques(
        &mut self,
        torque_nm: &[f64; HAND_DOF],
    ) -> Result<(), PhysicsError> {
        if !torque_nm.iter().all(|v| v.is_finite()) {
            return Err(PhysicsError::Invalid {
                what: "external hand torques",
                why: "not finite".into(),
            });
        }
        self.hand_external = *torque_nm;
        Ok(())
    }

    fn driver_step(&mut self, dt: f64) {
        self.driver.step(self.data.time(), dt);
        let measured = SVector::from(self.arm_position());
        self.driver
            .hold_within(&measured, self.params.arm_max_tracking_error_rad);
    }

    /// Advances the world by one step.
    ///
    /// # Errors
    /// [`PhysicsError::Unstable`] when the state stops being finite or MuJoCo reset it.
    pub fn step(&mut self) -> Result<(), PhysicsError> {
        let dt = self.timestep_s();
        self.driver_step(dt);
        let t0 = self.data.time();
        let bias: [f64; ARM_DOF] = {
            let b = self.data.qfrc_bias();
            self.arm.map(|j| b[j.dof])
        };
        {
            let ctrl = self.data.ctrl_mut();
            for (i, j) in self.arm.iter().enumerate() {
                let kp = self.params.arm_kp[i];
                let ff = if kp > 0.0 {
                    self.params.arm_kv[i] / kp * self.driver.velocity_rad_s()[i]
                } else {
                    0.0
                };
                ctrl[j.actuator] = self.driver.position_rad()[i] + ff;
            }
            for (i, j) in self.hand.iter().enumerate() {
                ctrl[j.actuator] = self.hand_torque[i];
            }
        }
        {
            let applied = self.data.qfrc_applied_mut();
            for (i, j) in self.arm.iter().enumerate() {
                applied[j.dof] = bias[i];
            }
            for (i, j) in self.hand.iter().enumerate() {
                applied[j.dof] = self.hand_external[i];
            }
        }
        self.data.step();
        let t1 = self.data.time();
        if t1 <= t0 || !self.data.qpos().iter().all(|v| v.is_finite()) {
            return Err(PhysicsError::Unstable {
                time_s: t0,
                why: "MuJoCo reset the state (bad accelerations) or it is not finite".into(),
            });
        }
        Ok(())
    }

    /// Arm joint positions, rad ([`PR2_ARM_JOINTS`] order).
    #[must_use]
    pub fn arm_position(&self) -> [f64; ARM_DOF] {
        let q = self.data.qpos();
        self.arm.map(|j| q[j.qpos])
    }

    /// Arm joint velocities, rad/s.
    #[must_use]
    pub fn arm_velocity(&self) -> [f64; ARM_DOF] {
        let v = self.data.qvel();
        self.arm.map(|j| v[j.dof])
    }

    /// Finger joint positions, rad ([`SHADOW_FINGER_JOINTS`] order).
    #[must_use]
    pub fn hand_position(&self) -> [f64; HAND_DOF] {
        let q = self.data.qpos();
        self.hand.map(|j| q[j.qpos])
    }

    /// Finger joint velocities, rad/s.
    #[must_use]
    pub fn hand_velocity(&self) -> [f64; HAND_DOF] {
        let v = self.data.qvel();
        self.hand.map(|j| v[j.dof])
    }

    /// The finger motors' applied torques, N m.
    #[must_use]
    pub fn hand_effort(&self) -> [f64; HAND_DOF] {
        let f = self.data.actuator_force();
        self.hand.map(|j| f[j.actuator])
    }

    /// The BioTac readings: normal force on each distal link, N
    /// ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order).
    #[must_use]
    pub fn fingertip_forces_n(&self) -> [f64; 5] {
        let s = self.data.sensordata();
        let mut out = [0.0; 5];
        for (f, adrs) in self.touch.iter().enumerate() {
            out[f] = adrs.iter().map(|&a| s[a]).sum();
        }
        out
    }

    /// The fingertips' contacts with the scene (the table, the objects, welded fixtures;
    /// not with the robot itself): finger index
    /// ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order) and the contact
    /// point in the world, m.
    #[must_use]
    pub fn fingertip_contacts(&self) -> Vec<(usize, [f64; 3])> {
        let model = self.data.model();
        let body_of = |g: i32| {
            usize::try_from(g)
                .ok()
                .and_then(|g| model.geom_bodyid().get(g).copied())
                .and_then(|b| usize::try_from(b).ok())
        };
        let scene = |b: usize| b == 0 || self.objects.iter().any(|(_, id)| *id == b);
        let mut out = Vec::new();
        for c in self.data.contact() {
            let (Some(b1), Some(b2)) = (body_of(c.geom1), body_of(c.geom2)) else {
                continue;
            };
            for (tip, other) in [(b1, b2), (b2, b1)] {
                if let Some(f) = self.distal_bodies.iter().position(|&d| d == tip)
                    && scene(other)
                {
                    out.push((f, c.pos));
                }
            }
        }
        out
    }

    /// Number of active contacts.
    #[must_use]
    pub fn contact_count(&self) -> usize {
        usize::try_from(self.data.ncon()).unwrap_or(0)
    }

    /// The world pose of body `name` (every URDF link and every object is a body).
    ///
    /// # Errors
    /// [`PhysicsError::MissingName`].
    pub fn body_pose(&self, name: &str) -> Result<Isometry3<f64>, PhysicsError> {
        let id = obj_id(self.data.model(), MjtObjBase::mjOBJ_BODY, "body", name)?;
        Ok(self.body_pose_by_id(id))
    }

    fn body_pose_by_id(&self, id: usize) -> Isometry3<f64> {
        let p = self.data.xpos()[id];
        let q = self.data.xquat()[id];
        Isometry3::from_parts(
            Translation3::new(p[0], p[1], p[2]),
            UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
        )
    }

    /// The mass of body `name`, kg.
    ///
    /// # Errors
    /// [`PhysicsError::MissingName`].
    pub fn body_mass_kg(&self, name: &str) -> Result<f64, PhysicsError> {
        let id = obj_id(self.data.model(), MjtObjBase::mjOBJ_BODY, "body", name)?;
        Ok(self.data.model().body_mass()[id])
    }

    /// The scene's objects and their world poses, in [`SceneSpec::objects`] order.
    #[must_use]
    pub fn object_poses(&self) -> Vec<(&str, Isometry3<f64>)> {
        self.objects
            .iter()
            .map(|(n, id)| (n.as_str(), self.body_pose_by_id(*id)))
            .collect()
    }

    /// The diagonal of the finger joints' inertia (links and armature) at the model's
    /// reference posture, kg m^2: what a motor loop evaluated between steps needs to keep
    /// its stiff terms stable.
    #[must_use]
    pub fn hand_inertia_kg_m2(&self) -> [f64; HAND_DOF] {
        let m0 = self.data.model().dof_m0();
        self.hand.map(|j| m0[j.dof])
    }
}
