//! [`World`]: the PR2 arm, the Shadow hand and fixed objects, stepped at a fixed `dt`.

use nalgebra::{Isometry3, Matrix6xX, Point3, SVector, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_hardware::{ArmState, HandCommand, HandState};
use teleop_interfaces::joints::{PR2_ARM_JOINTS as ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_kinematics::{GravityModel, KinematicState, LinkId, Robot, robots};

use super::config::WorldConfig;
use super::error::SimError;
use super::geometry::{Capsule, capsule_distance, penetration};
use super::hand_loop::{MotorLaw, motor_torques};
use super::measure::{TrueState, at_rest, measured};
use super::objects::{ExternalLoad, LoadTarget, Object, ResolvedTarget};
use teleop_hardware::velocity_driver::{ArmJointLimits, ArmSim};

/// Finger links by fingertip ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order): the BioTac is the distal link.
const DISTAL_LINKS: [&str; 5] = robots::shadow::DISTALS;
/// Fingertip frames ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order).
pub(super) const TIP_FRAMES: [&str; 5] = robots::shadow::TIPS;

/// One contact of the last step, in the world (PR2 `base_link`) frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactInfo {
    /// The finger link touching (look its name up with [`World::robot`]).
    pub link: LinkId,
    /// Fingertip index ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order) when the link is a BioTac (distal link).
    pub fingertip: Option<usize>,
    /// Index of the object in [`World::objects`].
    pub object: usize,
    /// Contact point, m.
    pub point_m: Point3<f64>,
    /// Unit normal from the object into the link (direction of the normal force on the
    /// link).
    pub normal: Vector3<f64>,
    /// Penetration depth, m.
    pub depth_m: f64,
    /// Normal force on the link, N (>= 0).
    pub normal_force_n: f64,
    /// Friction force on the link, N (perpendicular to `normal`).
    pub friction_force_n: Vector3<f64>,
}

/// A collision capsule fixed to a finger link.
#[derive(Debug, Clone)]
struct LinkCapsule {
    link: LinkId,
    local: Capsule,
    fingertip: Option<usize>,
    /// Robot DoF indices moving the link (arm and hand).
    dofs: Vec<usize>,
}

#[derive(Debug, Clone, Copy)]
struct ActiveLoad {
    load_index: usize,
    target: ResolvedTarget,
}

/// The factors drawn for one simulated robot ([`crate::PerturbationConfig`]): what
/// its physical parameters are, relative to the nominal model.
#[derive(Debug, Clone, PartialEq)]
pub struct Perturbation {
    /// Mass (and inertia) factor of each link moved by a finger joint, by link name.
    pub link_mass_scale: Vec<(String, f64)>,
    /// Per finger joint ([`SHADOW_FINGER_JOINTS`] order).
    pub damping_scale: SVector<f64, 17>,
    pub armature_scale: SVector<f64, 17>,
    pub motor_gain_scale: SVector<f64, 17>,
    /// Contact friction coefficient factor.
    pub friction_scale: f64,
    /// Per arm joint ([`ARM_JOINTS`] order).
    pub arm_lag_scale: [f64; 7],
}

impl Perturbation {
    pub(crate) fn draw(
        p: &crate::PerturbationConfig,
        robot: &Robot,
        dof_hand: &[Option<usize>],
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let mut factor = |f: f64| -> f64 {
            if f > 0.0 {
                1.0 + f * (2.0 * rng.random::<f64>() - 1.0)
            } else {
                1.0
            }
        };
        let mut link_mass_scale = Vec::new();
        for link in robot.links() {
            let Ok(id) = robot.link_id(&link.name) else {
                continue;
            };
            let moved = robot
                .dofs_moving(id)
                .iter()
                .any(|&d| dof_hand.get(d).copied().flatten().is_some());
            if moved && link.inertial.is_some() {
                link_mass_scale.push((link.name.clone(), factor(p.mass_fraction)));
            }
        }
        let damping_scale = SVector::from_fn(|_, _| factor(p.damping_fraction));
        let armature_scale = SVector::from_fn(|_, _| factor(p.armature_fraction));
        let motor_gain_scale = SVector::from_fn(|_, _| factor(p.motor_gain_fraction));
        let friction_scale = factor(p.friction_fraction);
        let arm_lag_scale = [(); 7].map(|()| factor(p.arm_lag_fraction));
        Self {
            link_mass_scale,
            damping_scale,
            armature_scale,
            motor_gain_scale,
            friction_scale,
            arm_lag_scale,
        }
    }

    /// The mass factor of link `name` (1 for links the draw did not cover).
    pub fn mass_scale_of(&self, name: &str) -> f64 {
        self.link_mass_scale
            .iter()
            .find(|(n, _)| n == name)
            .map_or(1.0, |(_, f)| *f)
    }
}

/// The simulated remote world: PR2 arm, Shadow hand, fixed objects, external loads.
///
/// Deterministic: the same config, seed and sequence of commands and steps give
/// bit-identical states. See the [module docs](super) for the models.
#[derive(Debug, Clone)]
pub struct World {
    config: WorldConfig,
    robot: Robot,
    kin: KinematicState,
    /// Robot DoF index of each arm joint ([`ARM_JOINTS`] order).
    arm_dof: [usize; 7],
    /// Robot DoF index of each finger joint ([`SHADOW_FINGER_JOINTS`] order).
    hand_dof: [usize; 17],
    /// Hand joint index of each robot DoF, if it is a finger joint.
    dof_hand: Vec<Option<usize>>,
    hand_lower: SVector<f64, 17>,
    hand_upper: SVector<f64, 17>,
    inertia: SVector<f64, 17>,
    /// Viscous damping per finger joint (perturbed), N m s/rad.
    damping: SVector<f64, 17>,
    /// Gravity on the fingers, from the simulated robot's own masses.
    gravity: GravityModel<17>,
    perturbation: Perturbation,
    capsules: Vec<LinkCapsule>,
    tip_links: [LinkId; 5],
    palm: LinkId,

    arm: ArmSim,
    hand_q: SVector<f64, 17>,
    hand_qd: SVector<f64, 17>,
    hand_command: HandCommand,
    hand_effort: SVector<f64, 17>,
    tip_force: [f64; 5],

    objects: Vec<Object>,
    object_capsules: Vec<Capsule>,
    loads: Vec<ExternalLoad>,
    resolved_loads: Vec<ActiveLoad>,
    contacts: Vec<ContactInfo>,

    q_full: Vec<f64>,
    qd_full: Vec<f64>,
    jac: Matrix6xX<f64>,
    steps: u64,
    target_time_s: f64,
    rng: ChaCha8Rng,
    measured_arm: ArmState<7>,
    measured_hand: HandState,
}

impl World {
    /// An empty world (no objects): arm at rest at its initial position, hand holding
    /// its initial posture with the position servo.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for bad settings; [`SimError::Kinematics`] if the
    /// embedded robot model lacks a joint or link the simulator needs.
    pub fn new(config: WorldConfig) -> Result<Self, SimError> {
        config.validate()?;
        let robot = robots::pr2_arm()?;
        let dof = robot.dof();
        let limits: Vec<_> = robot.dof_limits().collect();
        let joints: Vec<_> = robot.dof_joints().cloned().collect();

        let mut arm_dof = [0; 7];
        let mut arm_limits = [ArmJointLimits {
            lower_rad: 0.0,
            upper_rad: 0.0,
            velocity_rad_s: 0.0,
            acceleration_rad_s2: 0.0,
        }; 7];
        for (i, name) in ARM_JOINTS.iter().enumerate() {
            let d = robot.dof_index(name)?;
            arm_dof[i] = d;
            arm_limits[i] = ArmJointLimits {
                lower_rad: limits[d].lower,
                upper_rad: limits[d].upper,
                velocity_rad_s: limits[d].velocity * config.arm.velocity_limit_scale,
                acceleration_rad_s2: config.arm.acceleration_limit_rad_s2[i],
            };
        }
        let mut hand_dof = [0; 17];
        let mut dof_hand = vec![None; dof];
        let mut hand_axis_local = [Vector3::zeros(); 17];
        let mut hand_lower = SVector::<f64, 17>::zeros();
        let mut hand_upper = SVector::<f64, 17>::zeros();
        for (i, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            let d = robot.dof_index(name)?;
            hand_dof[i] = d;
            dof_hand[d] = Some(i);
            hand_axis_local[i] = joints[d].axis.into_inner();
            hand_lower[i] = limits[d].lower;
            hand_upper[i] = limits[d].upper;
        }

        let mut tip_links = [robot.root(); 5];
        let mut distal = [robot.root(); 5];
        for f in 0..5 {
            tip_links[f] = robot.link_id(TIP_FRAMES[f])?;
            distal[f] = robot.link_id(DISTAL_LINKS[f])?;
        }
        let palm = robot.link_id(robots::pr2::WRIST)?;

        // Links moved by finger joints: their collision capsules.
        let mut capsules = Vec::new();
        for (index, link) in robot.links().iter().enumerate() {
            let Ok(id) = robot.link_id(&link.name) else {
                continue;
            };
            debug_assert_eq!(id.index(), index);
            let dofs = robot.dofs_moving(id);
            if !dofs.iter().any(|&d| dof_hand[d].is_some()) {
                continue;
            }
            let fingertip = distal.iter().position(|&d| d == id);
            let mut locals: Vec<Capsule> = Vec::new();
            for shape in &link.collisions {
                let local = match shape.shape {
                    teleop_kinematics::Shape::Sphere { radius } => {
                        Capsule::ball(Point3::origin(), radius)
                    }
                    // A URDF finger phalanx is a cylinder plus a ball of the same radius
                    // at its far end: a capsule (with an extra cap hidden in the joint).
                    teleop_kinematics::Shape::Cylinder { radius, length }
                    | teleop_kinematics::Shape::Capsule { radius, length } => {
                        Capsule::along_z(length / 2.0, radius)
                    }
                    // Boxes (LF metacarpal) and meshes take no part in contacts.
                    _ => continue,
                };
                locals.push(local.transformed(&shape.origin));
            }
            // Drop balls inside another capsule of the link (the URDF's ball at the end
            // of each phalanx cylinder is the capsule's cap): one contact per touch.
            let kept: Vec<Capsule> = locals
                .iter()
                .enumerate()
                .filter(|&(i, c)| {
                    c.a != c.b
                        || !locals.iter().enumerate().any(|(k, other)| {
                            k != i
                                && other.a != other.b
                                && capsule_distance(&Capsule::ball(c.a, 0.0), other) + c.radius_m
                                    <= 1e-9
                        })
                })
                .map(|(_, c)| *c)
                .collect();
            for local in kept {
                capsules.push(LinkCapsule {
                    link: id,
                    local,
                    fingertip,
                    dofs: dofs.clone(),
                });
            }
        }

        // The simulated robot's own parameters: nominal times a seeded draw.
        let perturbation = Perturbation::draw(&config.perturbation, &robot, &dof_hand);

        // Diagonal joint inertia at the straight-finger posture (the largest it gets).
        let mut kin = robot.new_state();
        let neutral = robot.neutral_positions();
        robot.update(&mut kin, &neutral)?;
        let mut inertia = perturbation.armature_scale * config.hand.armature_kg_m2;
        for link in robot.links() {
            let Some(mut inertial) = link.inertial else {
                continue;
            };
            let scale = perturbation.mass_scale_of(&link.name);
            inertial.mass_kg *= scale;
            inertial.inertia *= scale;
            let id = robot.link_id(&link.name)?;
            let pose = robot.link_pose(&kin, id);
            let com_pose = pose * inertial.origin;
            let i_world = com_pose.rotation.to_rotation_matrix();
            let i_world = i_world.matrix() * inertial.inertia * i_world.matrix().transpose();
            for d in robot.dofs_moving(id) {
                let Some(h) = dof_hand[d] else { continue };
                let frame = &kin.dof_frames()[d];
                let axis = frame.rotation * hand_axis_local[h];
                let r = com_pose.translation.vector - frame.translation.vector;
                inertia[h] +=
                    inertial.mass_kg * axis.cross(&r).norm_squared() + axis.dot(&(i_world * axis));
            }
        }

        let arm_lag_s = perturbation
            .arm_lag_scale
            .map(|f| f * config.arm.velocity_lag_s);
        let arm = ArmSim::new(
            arm_limits,
            &SVector::from(config.arm.initial_position_rad),
            config.arm.velocity_lag_s,
            config.arm.command_timeout_s,
        )
        .with_lags(arm_lag_s);
        let hand_q = SVector::<f64, 17>::from_fn(|i, _| {
            config.hand.initial_position_rad[i].clamp(hand_lower[i], hand_upper[i])
        });
        let rng = ChaCha8Rng::seed_from_u64(config.seed);
        let mut gravity = GravityModel::new(
            robot.clone(),
            &SHADOW_FINGER_JOINTS,
            Vector3::from(config.gravity_m_s2),
        )?;
        gravity.scale_masses(|link| perturbation.mass_scale_of(link));
        let damping = perturbation.damping_scale * config.hand.damping_nm_s_rad;
        let mut world = Self {
            robot,
            kin,
            arm_dof,
            hand_dof,
            dof_hand,
            hand_lower,
            hand_upper,
            inertia,
            damping,
            gravity,
            capsules,
            perturbation,
            tip_links,
            palm,
            arm,
            hand_q,
            hand_qd: SVector::zeros(),
            hand_command: HandCommand::Position(hand_q),
            hand_effort: SVector::zeros(),
            tip_force: [0.0; 5],
            objects: Vec::new(),
            object_capsules: Vec::new(),
            loads: Vec::new(),
            resolved_loads: Vec::new(),
            contacts: Vec::with_capacity(64),
            q_full: vec![0.0; dof],
            qd_full: vec![0.0; dof],
            jac: Matrix6xX::zeros(dof),
            steps: 0,
            target_time_s: 0.0,
            rng,
            measured_arm: at_rest().0,
            measured_hand: at_rest().1,
            config,
        };
        world.refresh_kinematics();
        world.measure();
        Ok(world)
    }

    // ----- setup ------------------------------------------------------------------

    /// Adds a fixed object; returns its index in [`World::objects`].
    ///
    /// # Errors
    /// [`SimError::InvalidObject`] for a bad size or pose.
    pub fn add_object(&mut self, object: Object) -> Result<usize, SimError> {
        let capsule = object.world_capsule()?;
        self.objects.push(object);
        self.object_capsules.push(capsule);
        Ok(self.objects.len() - 1)
    }

    /// Adds an external load on the hand.
    ///
    /// # Errors
    /// [`SimError::UnknownFingerJoint`] for a joint or finger name the hand lacks,
    /// [`SimError::InvalidConfig`] for non-finite numbers.
    pub fn add_load(&mut self, load: ExternalLoad) -> Result<(), SimError> {
        load.validate()?;
        let target = match &load.target {
            LoadTarget::JointTorque { joint, torque_nm } => {
                let hand_index = teleop_interfaces::joints::finger_joint_index(joint)
                    .ok_or_else(|| SimError::UnknownFingerJoint(joint.clone()))?;
                ResolvedTarget::Joint {
                    hand_index,
                    torque_nm: *torque_nm,
                }
            }
            LoadTarget::FingertipForce { finger, force_n } => {
                let finger_index = teleop_interfaces::joints::fingertip_index(finger)
                    .ok_or_else(|| SimError::UnknownFingerJoint(finger.clone()))?;
                ResolvedTarget::Fingertip {
                    finger: finger_index,
                    force_n: Vector3::from(*force_n),
                }
            }
        };
        self.resolved_loads.push(ActiveLoad {
            load_index: self.loads.len(),
            target,
        });
        self.loads.push(load);
        Ok(())
    }

    /// Places the arm at rest at `position_rad` (clamped into its limits).
    pub fn set_arm_position(&mut self, position_rad: &SVector<f64, 7>) {
        self.arm.set_position(position_rad);
        self.refresh_kinematics();
        self.measure();
    }

    /// Places the hand at rest at `position_rad` (clamped into its limits) and makes the
    /// position servo hold it.
    pub fn set_hand_position(&mut self, position_rad: &SVector<f64, 17>) {
        self.hand_q =
            position_rad.zip_zip_map(&self.hand_lower, &self.hand_upper, |q, l, u| q.clamp(l, u));
        self.hand_qd = SVector::zeros();
        self.hand_command = HandCommand::Position(self.hand_q);
        self.refresh_kinematics();
        self.measure();
    }

    // ----- commands (what the hardware handles call) -----------------------------

    /// Stores an arm velocity command, time-stamped now; applied from the next step.
    pub fn command_arm(&mut self, velocity_rad_s: &SVector<f64, 7>) {
        self.arm.command(velocity_rad_s, self.time_s());
    }

    /// Stores a hand command; applied from the next step until replaced.
    pub fn command_hand(&mut self, command: &HandCommand) {
        self.hand_command = *command;
    }

    // ----- stepping -----------------------------------------------------------------

    /// The fixed step, s.
    pub fn dt_s(&self) -> f64 {
        self.config.dt_s
    }

    /// Sim time, s: number of steps taken times `dt`.
    pub fn time_s(&self) -> f64 {
        // Step counts stay far below 2^53.
        #[allow(clippy::cast_precision_loss)]
        let steps = self.steps as f64;
        steps * self.config.dt_s
    }

    /// Advances the world by `duration_s` in fixed steps of [`World::dt_s`]. Durations
    /// accumulate: calls shorter than `dt` step once their sum reaches it, so the
    /// trajectory depends only on the total time, never on how it was sliced.
    pub fn step(&mut self, duration_s: f64) {
        if !duration_s.is_finite() || duration_s <= 0.0 {
            return;
        }
        self.target_time_s += duration_s;
        let dt = self.config.dt_s;
        // A tolerance of 1e-9 dt absorbs the rounding of the accumulated target.
        while self.time_s() + dt <= self.target_time_s + 1e-9 * dt {
            self.step_once();
        }
    }

    /// Advances exactly one fixed step.
    pub fn step_once(&mut self) {
        let t = self.time_s();
        let dt = self.config.dt_s;
        self.arm.step(t, dt);
        let substeps = self.config.hand.substeps;
        let h = dt / f64::from(substeps);
        for k in 0..substeps {
            self.hand_substep(t + f64::from(k) * h, h);
        }
        self.steps += 1;
        self.target_time_s = self.target_time_s.max(self.time_s());
        self.refresh_kinematics();
        self.measure();
    }

    fn load_full_state(&mut self) {
        for i in 0..7 {
            self.q_full[self.arm_dof[i]] = self.arm.position_rad()[i];
            self.qd_full[self.arm_dof[i]] = self.arm.velocity_rad_s()[i];
        }
        for i in 0..17 {
            self.q_full[self.hand_dof[i]] = self.hand_q[i];
            self.qd_full[self.hand_dof[i]] = self.hand_qd[i];
        }
    }

    fn refresh_kinematics(&mut self) {
        self.load_full_state();
        // Lengths match by construction.
        let _ = self.robot.update(&mut self.kin, &self.q_full);
    }

    /// One semi-implicit Euler step of the hand: forces at the start of the step, with
    /// the stiff terms' diagonal (servo, limits, contacts, damping) taken implicitly.
    #[allow(clippy::too_many_lines)]
    fn hand_substep(&mut self, time_s: f64, h: f64) {
        self.refresh_kinematics();
        let cfg = &self.config;
        let q = self.hand_q;
        let v = self.hand_qd;
        let mut force = SVector::<f64, 17>::zeros();
        let mut stiff = SVector::<f64, 17>::zeros();
        let mut damp = self.damping;
        force -= v.component_mul(&self.damping);

        // Motors.
        let motors = motor_torques(
            &self.hand_command,
            &q,
            &v,
            &MotorLaw {
                lower: &self.hand_lower,
                upper: &self.hand_upper,
                gain: &self.perturbation.motor_gain_scale,
                max_nm: cfg.hand.max_effort_nm,
                servo_kp_nm_rad: cfg.hand.servo_kp_nm_rad,
                servo_kd_nm_s_rad: cfg.hand.servo_kd_nm_s_rad,
            },
        );
        stiff += motors.stiffness;
        damp += motors.damping;
        let effort = motors.effort;
        self.hand_effort = effort;
        force += effort;

        // Joint limits: one-sided penalty springs.
        for i in 0..17 {
            let over = if q[i] > self.hand_upper[i] {
                q[i] - self.hand_upper[i]
            } else if q[i] < self.hand_lower[i] {
                q[i] - self.hand_lower[i]
            } else {
                continue;
            };
            let k = cfg.hand.limit_stiffness_nm_rad;
            let c = cfg.hand.limit_damping_nm_s_rad;
            let tau = -k * over - c * v[i];
            // The limit pushes back, never pulls into the range's far side.
            if tau * over < 0.0 {
                force[i] += tau;
                stiff[i] += k;
                damp[i] += c;
            }
        }

        // Gravity on every finger link.
        self.gravity.add_torques(&self.kin, &mut force);

        // Contacts.
        self.contacts.clear();
        self.tip_force = [0.0; 5];
        let contact = &cfg.contact;
        for lc in &self.capsules {
            if self.object_capsules.is_empty() {
                break;
            }
            let pose = self.robot.link_pose(&self.kin, lc.link);
            let world_capsule = lc.local.transformed(&pose);
            for (oi, oc) in self.object_capsules.iter().enumerate() {
                let fallback = pose.rotation * Vector3::y();
                let Some(pen) = penetration(&world_capsule, oc, &fallback) else {
                    continue;
                };
                let local_point = pose.inverse_transform_point(&pen.point);
                if self
                    .robot
                    .link_jacobian_into(&self.kin, lc.link, &local_point, &mut self.jac)
                    .is_err()
                {
                    continue;
                }
                let mut vel = Vector3::zeros();
                for &d in &lc.dofs {
                    vel += self.jac.fixed_view::<3, 1>(0, d) * self.qd_full[d];
                }
                let vn = pen.normal.dot(&vel);
                let fn_raw = contact.stiffness_n_m * pen.depth_m - contact.damping_n_s_m * vn;
                let normal_force_n = fn_raw.max(0.0);
                let vt = vel - pen.normal * vn;
                let vt_norm = vt.norm();
                let limit = contact.friction_coefficient
                    * self.perturbation.friction_scale
                    * normal_force_n;
                let viscous = contact.friction_damping_n_s_m * vt_norm;
                let sticking = viscous < limit;
                let friction_force_n = if vt_norm > 1e-12 {
                    -vt * (viscous.min(limit) / vt_norm)
                } else {
                    Vector3::zeros()
                };
                let total = pen.normal * normal_force_n + friction_force_n;
                for &d in &lc.dofs {
                    let Some(j) = self.dof_hand[d] else { continue };
                    let col: Vector3<f64> = self.jac.fixed_view::<3, 1>(0, d).into_owned();
                    force[j] += col.dot(&total);
                    if fn_raw > 0.0 {
                        let cn = pen.normal.dot(&col);
                        stiff[j] += contact.stiffness_n_m * cn * cn;
                        damp[j] += contact.damping_n_s_m * cn * cn;
                    }
                    if sticking {
                        let ct = col - pen.normal * pen.normal.dot(&col);
                        damp[j] += contact.friction_damping_n_s_m * ct.norm_squared();
                    }
                }
                if let Some(f) = lc.fingertip {
                    self.tip_force[f] += normal_force_n;
                }
                self.contacts.push(ContactInfo {
                    link: lc.link,
                    fingertip: lc.fingertip,
                    object: oi,
                    point_m: pen.point,
                    normal: pen.normal,
                    depth_m: pen.depth_m,
                    normal_force_n,
                    friction_force_n,
                });
            }
        }

        // External loads.
        for al in &self.resolved_loads {
            let scale = self.loads[al.load_index].scale_at(time_s);
            if scale == 0.0 {
                continue;
            }
            match al.target {
                ResolvedTarget::Joint {
                    hand_index,
                    torque_nm,
                } => force[hand_index] += scale * torque_nm,
                ResolvedTarget::Fingertip { finger, force_n } => {
                    let link = self.tip_links[finger];
                    if self
                        .robot
                        .link_jacobian_into(&self.kin, link, &Point3::origin(), &mut self.jac)
                        .is_err()
                    {
                        continue;
                    }
                    for (d, hand) in self.dof_hand.iter().enumerate() {
                        if let Some(j) = hand {
                            let col = self.jac.fixed_view::<3, 1>(0, d);
                            force[*j] += scale * col.dot(&force_n);
                        }
                    }
                }
            }
        }

        // Linearly implicit Euler on the diagonal:
        // (I + h D + h^2 K) v+ = (I + h D) v + h f;  q+ = q + h v+.
        for i in 0..17 {
            let m = self.inertia[i] + h * damp[i];
            let v_new = (m * v[i] + h * force[i]) / (m + h * h * stiff[i]);
            self.hand_qd[i] = v_new;
            self.hand_q[i] = q[i] + h * v_new;
        }
    }

    fn measure(&mut self) {
        let truth = TrueState {
            time_s: self.time_s(),
            arm_q: *self.arm.position_rad(),
            arm_v: *self.arm.velocity_rad_s(),
            hand_q: self.hand_q,
            hand_v: self.hand_qd,
            hand_effort: self.hand_effort,
            tips: self.tip_force,
        };
        (self.measured_arm, self.measured_hand) =
            measured(&truth, &self.config.noise, &mut self.rng);
    }

    // ----- what the hardware reads ---------------------------------------------------

    /// The arm state as its driver reports it (with measurement noise, if configured).
    pub fn arm_state(&self) -> ArmState<7> {
        self.measured_arm
    }

    /// The hand state as its driver reports it (with measurement noise, if configured).
    pub fn hand_state(&self) -> HandState {
        self.measured_hand
    }

    // ----- ground truth ----------------------------------------------------------------

    /// The configuration.
    pub fn config(&self) -> &WorldConfig {
        &self.config
    }

    /// The robot model (PR2 torso + right arm + Shadow hand) the world runs on.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// Kinematic state of the whole robot at the current configuration.
    pub fn kinematic_state(&self) -> &KinematicState {
        &self.kin
    }

    /// True arm joint positions, rad.
    pub fn arm_position_rad(&self) -> SVector<f64, 7> {
        *self.arm.position_rad()
    }

    /// True arm joint velocities, rad/s.
    pub fn arm_velocity_rad_s(&self) -> SVector<f64, 7> {
        *self.arm.velocity_rad_s()
    }

    /// Velocity limits of the arm joints in use, rad/s.
    pub fn arm_velocity_limits_rad_s(&self) -> [f64; 7] {
        self.arm.limits().map(|l| l.velocity_rad_s)
    }

    /// Whether the arm's last command is fresh (false: the driver is braking/holding).
    pub fn arm_command_active(&self) -> bool {
        self.arm.command_active(self.time_s())
    }

    /// True finger joint positions, rad.
    pub fn hand_position_rad(&self) -> SVector<f64, 17> {
        self.hand_q
    }

    /// True finger joint velocities, rad/s.
    pub fn hand_velocity_rad_s(&self) -> SVector<f64, 17> {
        self.hand_qd
    }

    /// Finger joint limits `(lower, upper)`, rad.
    pub fn hand_limits_rad(&self) -> (SVector<f64, 17>, SVector<f64, 17>) {
        (self.hand_lower, self.hand_upper)
    }

    /// The factors by which this simulated robot differs from the nominal model.
    pub fn perturbation(&self) -> &Perturbation {
        &self.perturbation
    }

    /// Diagonal joint-space inertia of each finger joint, kg m^2 (armature included).
    pub fn hand_inertia_kg_m2(&self) -> SVector<f64, 17> {
        self.inertia
    }

    /// True fingertip normal forces ([`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order), N, without noise.
    pub fn fingertip_force_n(&self) -> [f64; 5] {
        self.tip_force
    }

    /// Pose of the palm (`rh_palm`) in the world.
    pub fn palm_pose(&self) -> Isometry3<f64> {
        self.robot.link_pose(&self.kin, self.palm)
    }

    /// Pose of a link in the world by name.
    ///
    /// # Errors
    /// [`SimError::Kinematics`] for an unknown link.
    pub fn link_pose(&self, name: &str) -> Result<Isometry3<f64>, SimError> {
        let id = self.robot.link_id(name)?;
        Ok(self.robot.link_pose(&self.kin, id))
    }

    /// Fingertip frame origins (`rh_<f>tip`, [`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order) in the world, m.
    pub fn fingertip_positions_m(&self) -> [Point3<f64>; 5] {
        self.tip_links
            .map(|l| Point3::from(self.robot.link_pose(&self.kin, l).translation.vector))
    }

    /// Contacts of the last step (those whose forces were applied in its last substep).
    pub fn contacts(&self) -> &[ContactInfo] {
        &self.contacts
    }

    /// The fixed objects.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// The external loads.
    pub fn loads(&self) -> &[ExternalLoad] {
        &self.loads
    }

    /// Finger collision capsules in the world frame at the current configuration (of
    /// `link` only, if given).
    pub fn link_capsules_world(&self, link: Option<LinkId>) -> impl Iterator<Item = Capsule> + '_ {
        self.capsules
            .iter()
            .filter(move |lc| link.is_none_or(|l| l == lc.link))
            .map(|lc| {
                let pose = self.robot.link_pose(&self.kin, lc.link);
                lc.local.transformed(&pose)
            })
    }

    /// Smallest surface distance (m) between the finger collision capsules (of `link`
    /// only, if given) and object `object` at the current configuration; negative when
    /// they overlap. `None` for an unknown object.
    pub fn clearance_m(&self, object: usize, link: Option<LinkId>) -> Option<f64> {
        let oc = self.object_capsules.get(object)?;
        self.link_capsules_world(link)
            .map(|c| capsule_distance(&c, oc))
            .min_by(f64::total_cmp)
    }

    /// The distal (BioTac) link of each fingertip, [`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) order.
    ///
    /// # Errors
    /// Only if the embedded model lacked the link (a test builds it).
    pub fn distal_link(&self, fingertip: usize) -> Result<LinkId, SimError> {
        let name = DISTAL_LINKS.get(fingertip).copied().unwrap_or("");
        Ok(self.robot.link_id(name)?)
    }
}
