//! The hand controller in closed loop with the simulated hand, in process and at the
//! controller's rate: the scenarios behind the thesis's ch. 8 figures (touching task,
//! cup grasp, a load pushing a grasped finger). Tests assert on them
//! (`tests/scenario_touching.rs`, `tests/scenario_grasp.rs`); the example
//! `hand_scenarios` writes their traces and plots to `docs/`.
//!
//! Each run builds its own [`World`] and [`ShadowHandController`], so runs are
//! independent and deterministic.

use nalgebra::{Point3, SVector};
use teleop_control::ConfigError;
use teleop_control::Rejection;
use teleop_control::hand::{HandControllerConfig, JointInput, ShadowHandController};
use teleop_interfaces::joints::{
    FINGERTIPS, FLEXION_JOINTS, SHADOW_FINGER_JOINTS as FINGER_JOINTS,
};
use teleop_remote_site::gravity::HandGravity;
use teleop_remote_site::hand_controller::hand_command;
use teleop_sim::{CupGraspConfig, SimError, TouchingTaskConfig, World};

/// Why a scenario could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    #[error("simulator: {0}")]
    Sim(#[from] SimError),
    #[error("hand controller config: {0}")]
    Controller(#[from] ConfigError),
    #[error("hand controller refused a step: {0}")]
    Rejected(#[from] Rejection),
    #[error("unknown finger joint {0:?}")]
    UnknownJoint(String),
    #[error("robot model: {0}")]
    Model(#[from] teleop_kinematics::KinematicsError),
}

/// Index of a finger joint in [`FINGER_JOINTS`] order.
///
/// # Errors
/// [`ScenarioError::UnknownJoint`].
pub fn finger_joint_index(name: &str) -> Result<usize, ScenarioError> {
    FINGER_JOINTS
        .iter()
        .position(|j| *j == name)
        .ok_or_else(|| ScenarioError::UnknownJoint(name.to_owned()))
}

/// One control period: read the simulated hand, step the controller toward `target`
/// with gravity compensation (as the `shadow_hand_controller` node does), command,
/// advance the world by `dt_s`.
///
/// # Errors
/// [`ScenarioError::Rejected`] if the controller refuses the input.
pub fn control_step(
    world: &mut World,
    controller: &mut ShadowHandController,
    gravity: &mut HandGravity,
    target_rad: &SVector<f64, 17>,
    dt_s: f64,
) -> Result<(), ScenarioError> {
    let s = world.hand_state();
    let g = gravity.compensation_nm(&world.arm_position_rad(), &s.position_rad);
    let input = JointInput::new(s.position_rad, s.velocity_rad_s, *target_rad).with_gravity(g);
    let out = controller.step_input(dt_s, &input)?;
    world.command_hand(&hand_command(out));
    world.step(dt_s);
    Ok(())
}

/// Settings of the touching task runs.
#[derive(Debug, Clone, PartialEq)]
pub struct TouchingRun {
    pub task: TouchingTaskConfig,
    /// How far the commanded FFJ3 lies beyond the surface contact posture, rad
    /// (FFJ2 gets 2/3 of it). Default 0.15.
    pub overshoot_rad: f64,
    /// Trial `k` of `n` perturbs the commanded FFJ3 by `(k - (n-1)/2) * perturbation`,
    /// rad (FFJ2 by half of it, opposite). Default 0.01.
    pub perturbation_rad: f64,
    /// Control period, s. Default 0.001 (1 kHz, the Shadow hand's control loop).
    pub dt_s: f64,
    /// Length of a trial, s. Default 2.
    pub duration_s: f64,
    /// Contact forces before this time are not counted (the approach), s. Default 0.2.
    pub settle_s: f64,
}

impl Default for TouchingRun {
    fn default() -> Self {
        Self {
            task: TouchingTaskConfig::default(),
            overshoot_rad: 0.15,
            perturbation_rad: 0.01,
            dt_s: 0.001,
            duration_s: 2.0,
            settle_s: 0.2,
        }
    }
}

/// Result of one touching trial (the task's finger, fingertip force).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TouchTrial {
    /// Largest fingertip contact force after the approach, N.
    pub max_force_n: f64,
    /// Mean fingertip contact force after the approach, N.
    pub mean_force_n: f64,
    /// Mean contact point on the surface while touching (world frame), m; `None` if
    /// the finger never touched.
    pub mean_contact_point_m: Option<Point3<f64>>,
}

/// Runs trial `k` of `trials` of the touching task under `controller`.
///
/// # Errors
/// Simulator or controller configuration errors, or a refused step.
pub fn touching_trial(
    run: &TouchingRun,
    controller: &HandControllerConfig<17>,
    k: usize,
    trials: usize,
) -> Result<TouchTrial, ScenarioError> {
    let mut world = World::touching_task(&run.task)?;
    let mut ctrl = ShadowHandController::new(*controller)?;
    let mut gravity = HandGravity::new(run.task.world.gravity_m_s2.into())?;
    // `World::touching_task` has refused an unknown finger already.
    let finger = FINGERTIPS
        .iter()
        .position(|f| *f == run.task.finger)
        .unwrap_or(0);
    let [j3, j2] = FLEXION_JOINTS[finger];
    let (j3, j2) = (finger_joint_index(j3)?, finger_joint_index(j2)?);
    let mut target = SVector::<f64, 17>::from(run.task.hand_posture_rad);
    // Trial counts are small.
    #[allow(clippy::cast_precision_loss)]
    let p = (k as f64 - (trials.saturating_sub(1)) as f64 / 2.0) * run.perturbation_rad;
    target[j3] += run.overshoot_rad + p;
    target[j2] += run.overshoot_rad * 2.0 / 3.0 - p / 2.0;

    let (mut max, mut sum, mut n) = (0.0_f64, 0.0, 0u32);
    let (mut point_sum, mut points) = (nalgebra::Vector3::zeros(), 0u32);
    while world.time_s() < run.duration_s - 1e-9 {
        control_step(&mut world, &mut ctrl, &mut gravity, &target, run.dt_s)?;
        if world.time_s() >= run.settle_s {
            let f = world.fingertip_force_n()[finger];
            max = max.max(f);
            sum += f;
            n += 1;
            for c in world
                .contacts()
                .iter()
                .filter(|c| c.fingertip == Some(finger))
            {
                point_sum += c.point_m.coords;
                points += 1;
            }
        }
    }
    Ok(TouchTrial {
        max_force_n: max,
        mean_force_n: if n > 0 { sum / f64::from(n) } else { 0.0 },
        mean_contact_point_m: (points > 0).then(|| Point3::from(point_sum / f64::from(points))),
    })
}

/// Summary of a mode's touching trials.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TouchSummary {
    /// Largest force of all trials, N.
    pub max_force_n: f64,
    /// Mean of the trials' mean forces, N.
    pub mean_force_n: f64,
    /// RMS distance of the trials' mean contact points from their centroid, m.
    pub contact_spread_m: f64,
    /// Trials in which the finger touched the surface.
    pub touched: usize,
}

/// Runs `trials` trials and summarizes them.
///
/// # Errors
/// As [`touching_trial`].
pub fn touching_trials(
    run: &TouchingRun,
    controller: &HandControllerConfig<17>,
    trials: usize,
) -> Result<TouchSummary, ScenarioError> {
    let results = (0..trials)
        .map(|k| touching_trial(run, controller, k, trials))
        .collect::<Result<Vec<_>, _>>()?;
    let points: Vec<Point3<f64>> = results
        .iter()
        .filter_map(|t| t.mean_contact_point_m)
        .collect();
    let spread = if points.is_empty() {
        0.0
    } else {
        // At most a few dozen points.
        #[allow(clippy::cast_precision_loss)]
        let count = points.len() as f64;
        let centroid = points
            .iter()
            .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords)
            / count;
        (points
            .iter()
            .map(|p| (p.coords - centroid).norm_squared())
            .sum::<f64>()
            / count)
            .sqrt()
    };
    #[allow(clippy::cast_precision_loss)]
    let n = results.len().max(1) as f64;
    Ok(TouchSummary {
        max_force_n: results.iter().map(|t| t.max_force_n).fold(0.0, f64::max),
        mean_force_n: results.iter().map(|t| t.mean_force_n).sum::<f64>() / n,
        contact_spread_m: spread,
        touched: points.len(),
    })
}

/// Settings of a cup-grasp run: close on the cup, optionally under a load.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspRun {
    /// The world (its `loads` apply).
    pub cup: CupGraspConfig,
    /// The joint whose position and effort are traced (the loaded one). Default
    /// `"rh_THJ4"`, the screw-pouring load's joint.
    pub traced_joint: String,
    /// Control period, s. Default 0.001.
    pub dt_s: f64,
    /// Length of the run, s. Default 9.
    pub duration_s: f64,
    /// A sample every this many control periods. Default 10.
    pub sample_every: usize,
}

impl Default for GraspRun {
    fn default() -> Self {
        Self {
            cup: CupGraspConfig::default(),
            traced_joint: "rh_THJ4".to_owned(),
            dt_s: 0.001,
            duration_s: 9.0,
            sample_every: 10,
        }
    }
}

/// One sample of a grasp run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspSample {
    pub time_s: f64,
    /// Fingertip contact forces ([`FINGERTIPS`] order), N.
    pub fingertip_force_n: [f64; 5],
    /// Traced joint: position, rad.
    pub joint_rad: f64,
    /// Traced joint: commanded (target) position, rad.
    pub joint_target_rad: f64,
    /// Traced joint: effort applied by the motor, N m.
    pub joint_effort_nm: f64,
}

/// Runs the grasp: from the open pre-grasp posture, the target is the closed posture
/// from the start (the operator closes the hand), held for the whole run.
///
/// # Errors
/// As [`touching_trial`], or an unknown traced joint.
pub fn grasp_run(
    run: &GraspRun,
    controller: &HandControllerConfig<17>,
) -> Result<Vec<GraspSample>, ScenarioError> {
    let mut world = World::cup_grasp(&run.cup)?;
    let mut ctrl = ShadowHandController::new(*controller)?;
    let mut gravity = HandGravity::new(run.cup.world.gravity_m_s2.into())?;
    let j = finger_joint_index(&run.traced_joint)?;
    let target = SVector::<f64, 17>::from(run.cup.closed_posture_rad);
    let mut samples = Vec::new();
    let mut step = 0usize;
    while world.time_s() < run.duration_s - 1e-9 {
        control_step(&mut world, &mut ctrl, &mut gravity, &target, run.dt_s)?;
        step += 1;
        if step.is_multiple_of(run.sample_every.max(1)) {
            let s = world.hand_state();
            samples.push(GraspSample {
                time_s: world.time_s(),
                fingertip_force_n: world.fingertip_force_n(),
                joint_rad: s.position_rad[j],
                joint_target_rad: target[j],
                joint_effort_nm: s.effort_nm[j],
            });
        }
    }
    Ok(samples)
}
