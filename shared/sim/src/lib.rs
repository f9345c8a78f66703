//! The simulated worlds of both sites. The robot site's world (this crate's root) is a
//! deterministic simulated remote site: the PR2 right arm carrying the Shadow hand,
//! fixed objects for the thesis' hand experiments (ch. 8.3), and the hardware traits
//! over it, stepped at a fixed `dt` (default 1 ms) much faster than real time.
//!
//! # Use
//!
//! ```no_run
//! use teleop_hardware::{ArmCommand, ArmHardware, HandCommand, HandHardware};
//! use teleop_sim::{TouchingTaskConfig, World};
//!
//! let world = World::touching_task(&TouchingTaskConfig::default())?;
//! let (world, mut arm, mut hand) = teleop_sim::share(world);
//! for k in 0..1000 {
//!     let now_s = f64::from(k) * 0.001;
//!     let state = hand.read(now_s)?;                 // what a controller sees
//!     hand.write(now_s, &HandCommand::Position(state.position_rad))?;
//!     arm.write(now_s, &ArmCommand::stop())?;
//!     world.lock().map_err(|_| anyhow::anyhow!("poisoned"))?.step(0.001);
//! }
//! # Ok::<(), anyhow::Error>(())
//! ```
//!
//! [`World::step`] advances by a duration in fixed steps (durations accumulate, so how a
//! caller slices time does not change the trajectory); commands written through
//! [`SimArm`] / [`SimHand`] apply from the next step. Ground truth for tests and metrics:
//! [`World::palm_pose`], [`World::fingertip_positions_m`], [`World::contacts`],
//! [`World::fingertip_force_n`], [`World::clearance_m`].
//!
//! # Models
//!
//! The robot is `teleop_kinematics::robots::pr2_arm()` (PR2 torso, 5-joint right arm,
//! Shadow hand with BioTacs, 24 DoF); gravity acts along `-z` of the PR2 `base_link`.
//!
//! **Arm** ([`ArmSim`], 7 joints of [`PR2_ARM_JOINTS`](teleop_interfaces::joints::PR2_ARM_JOINTS)): kinematic and
//! velocity-commanded. Per step: exact first-order lag towards the commanded velocity
//! (`velocity_lag_s`, 30 ms), or, once the last command is older than
//! `command_timeout_s` (0.1 s), the simulated driver's own brake (like a real one's):
//! a constant-deceleration ramp to a full stop; acceleration clamp
//! (`acceleration_limit_rad_s2`, 8 rad/s^2, ours: the PR2 description has none; also the
//! braking deceleration); velocity clamp at the URDF limits
//! (already scaled 0.6 by `pr2_description`); a joint reaching a position limit stops
//! there with zero velocity. The arm does not feel the hand's or the contacts' forces.
//!
//! **Hand** (17 joints of [`SHADOW_FINGER_JOINTS`](teleop_interfaces::joints::SHADOW_FINGER_JOINTS); the J1s are fixed at
//! 20 deg in the URDF): independent joint-space dynamics per joint,
//!
//! `I_j qdd_j = tau_motor - b qd_j + tau_gravity(q, arm) + (J^T F_contact)_j + tau_limit
//! + tau_external`
//!
//! * `I_j`: **diagonal approximation** of the joint-space inertia: the links moved by
//!   joint `j` (URDF `Inertial`s), `sum m |a x r|^2 + a^T I_c a`, at the straight-finger
//!   posture (the largest value), plus an actuator `armature_kg_m2` (2e-4 kg m^2, as in
//!   MuJoCo Menagerie's Shadow hand; it dominates the 3e-5..3e-4 kg m^2 of the light
//!   phalanges). Off-diagonal coupling, Coriolis terms and the arm's acceleration are
//!   neglected.
//! * `b`: viscous damping (`damping_nm_s_rad`, 0.05 N m s/rad).
//! * gravity: exact generalized force `sum m g . (a_j x (c - o_j))` of every finger link,
//!   with the hand posed by the arm's current configuration.
//! * motors: [`teleop_hardware::HandCommand::Effort`] clamped to `max_effort_nm`
//!   (1 N m), or [`teleop_hardware::HandCommand::Position`] through an internal PD servo
//!   at the simulation rate (`servo_kp_nm_rad` 2, `servo_kd_nm_s_rad` 0.01), clamped
//!   the same. The initial command holds the initial posture. The reported effort is the
//!   motor torque actually applied.
//! * joint limits: one-sided penalty springs (`limit_stiffness_nm_rad` 50, damping 0.1).
//! * integration: semi-implicit (linearly implicit) Euler with the diagonal stiffness
//!   `K` and damping `D` of the stiff terms (servo while unsaturated, limit springs,
//!   contact normal stiffness/damping and sticking friction projected on each joint):
//!   `(I + h D + h^2 K) v+ = (I + h D) v + h f`, `q+ = q + h v+`, in `substeps` (2)
//!   substeps per step. Unconditionally stable for those terms; checked at dt = 1 ms by
//!   the energy tests in `tests/sim_hand.rs`.
//!
//! **Contacts** ([`geometry`]): finger links are capsules built from the URDF collision
//! primitives (each phalanx is a cylinder plus an end ball = a capsule; knuckle and thumb
//! base balls kept; the palm and LF metacarpal boxes take no part). Objects are spheres
//! or capsules ([`ObjectShape`]), fixed in the world. Penetration along the normal gives a
//! penalty force `F_n = max(0, k d - c v_n)` (`stiffness_n_m` 3000 N/m, `damping_n_s_m`
//! 5 N s/m) plus regularized Coulomb friction (`min(mu F_n, c_t |v_t|)` against the
//! sliding velocity; `mu` 0.8). The contact point's velocity and the joint torques
//! `J^T F` use `Robot::link_jacobian_into` at the contact point (all 24 DoF, so arm
//! motion into an object is felt). The BioTac reading of a finger
//! ([`teleop_hardware::HandState::fingertip_force_n`]) is the sum of the normal forces
//! on its distal link.
//!
//! **Scenarios** ([`World::touching_task`], [`World::cup_grasp`],
//! [`World::screw_pouring`]): objects are placed from the FK of the hand at a reference
//! posture, so flexing meets them: the "mouse" is a sphere cap along the flexion
//! direction of one fingertip at a set clearance; the cup an upright capsule placed by a
//! grid search so the open hand clears it and every BioTac reaches into it at the closed
//! posture. [`ExternalLoad`]s (a joint torque or a fingertip force, ramped) stand in for
//! the screws poured into the held cup.
//!
//! **Cameras** ([`camera`]): [`SceneCameras`] renders the world from the top and side
//! camera views (`rgb8`), as the simulator node publishes them.
//!
//! **Determinism**: no clock, no threads, no hash-ordered iteration; measurement noise
//! ([`NoiseConfig`], default none) comes from a seeded ChaCha8. Same config, seed and
//! command sequence give bit-identical states.

pub mod camera;
pub mod config;
pub mod error;
pub mod geometry;
mod hand_loop;
pub mod hardware;
mod measure;
pub mod objects;
pub mod operator;
pub mod operator_site;
pub mod physical;
mod scenarios;
mod world;

pub use camera::{CameraError, CameraScene, CameraViewsConfig, SceneCameras, SceneObject, View};
pub use config::{
    ArmSimConfig, ContactConfig, HandSimConfig, NoiseConfig, PerturbationConfig, WorldConfig,
};
pub use error::SimError;
pub use hardware::{RobotWorld, SharedWorld, SimArm, SimHand, share};
pub use objects::{ExternalLoad, LoadTarget, Object, ObjectShape};
pub use physical::{
    MujocoWorld, MujocoWorldConfig, PICK_TOP_GRASP_POSTURE_RAD, PICK_TOP_GRASP_TABLE_BELOW_PALM_M,
    PickJobConfig, PickSceneConfig, TowerBlock, TowerJobConfig,
};
pub use scenarios::{CupGraspConfig, TouchingTaskConfig, WORKING_POSTURE_RAD};
pub use teleop_hardware::velocity_driver::{ArmJointLimits, ArmSim};
pub use world::{ContactInfo, Perturbation, World};
