//! The hand in closed loop with the simulated hand, in process: the scenarios behind
//! the thesis's ch. 8 figures (touching task, cup grasp, a load pushing a grasped
//! finger). Tests assert on them (`tests/scenario_touching.rs`,
//! `tests/scenario_grasp.rs`); the example `hand_scenarios` writes their traces and
//! plots to `docs/`.
//!
//! The code path is the shipped one: the `shadow_hand_controller` node's
//! [`HandSupervisor`] (gate, target checks, gravity model, control law) at its
//! configured rate, commanding the simulated hand through the hardware safety layer
//! ([`SafeHand`]) that `remote_sim` wraps it in; the operator holds the clutch and the
//! enable switch and the hand inference sends targets at 30 Hz. The simulated hand's
//! physical parameters are perturbed from the nominal model the supervisor uses
//! (`teleop_sim::PerturbationConfig`), and its sensors are noisy.
//!
//! Each run builds its own world and supervisor, so runs are independent and
//! deterministic. Every scenario runs in either simulated world ([`SimEngine`]): the
//! joint-space `World` (penalty contacts on fixed objects) or MuJoCo (`MujocoWorld`,
//! the same scene's objects welded in place, the same loads), with model mismatch on in
//! both.

use nalgebra::{Point3, SVector};
use teleop_control::ConfigError;
use teleop_control::OperatorSample;
use teleop_control::hand::HandControllerConfig;
use teleop_hardware::safety::{HandLimits, HandSafety, HandSafetyConfig, SafetyConfigError};
use teleop_hardware::{HandHardware, HardwareError, SafeHand, wire};
use teleop_interfaces::joints::{FINGERTIPS, FLEXION_JOINTS};
use teleop_remote_site::hand_controller::{HandSupervisor, HandSupervisorConfig, SupervisorError};
use teleop_sim::{
    CupGraspConfig, MujocoWorld, MujocoWorldConfig, RobotWorld, SharedWorld, SimError, SimHand,
    TouchingTaskConfig, World,
};

/// Which simulated world a scenario runs in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SimEngine {
    /// The joint-space world (`teleop_sim::World`).
    #[default]
    JointSpace,
    /// MuJoCo (`teleop_sim::MujocoWorld`, default settings: model mismatch on), the
    /// joint-space scene's objects welded in place.
    Mujoco,
}

impl SimEngine {
    /// The world's name in reports and plot titles.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            SimEngine::JointSpace => "joint-space world",
            SimEngine::Mujoco => "MuJoCo",
        }
    }
}

/// What the scenarios measure that the drivers do not report: the ground truth of either
/// world.
pub trait ScenarioWorld: RobotWorld + 'static {
    /// True fingertip contact forces ([`FINGERTIPS`] order), N.
    fn tip_forces_n(&self) -> [f64; 5];
    /// Where fingertip `finger` touches the scene now (world frame), m.
    fn tip_contact_points(&self, finger: usize) -> Vec<Point3<f64>>;
}

impl ScenarioWorld for World {
    fn tip_forces_n(&self) -> [f64; 5] {
        self.fingertip_force_n()
    }
    fn tip_contact_points(&self, finger: usize) -> Vec<Point3<f64>> {
        self.contacts()
            .iter()
            .filter(|c| c.fingertip == Some(finger))
            .map(|c| c.point_m)
            .collect()
    }
}

impl ScenarioWorld for MujocoWorld {
    fn tip_forces_n(&self) -> [f64; 5] {
        self.fingertip_force_n()
    }
    fn tip_contact_points(&self, finger: usize) -> Vec<Point3<f64>> {
        self.fingertip_contacts()
            .into_iter()
            .filter(|(f, _)| *f == finger)
            .map(|(_, p)| p)
            .collect()
    }
}

/// Why a scenario could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScenarioError {
    #[error("simulator: {0}")]
    Sim(#[from] SimError),
    #[error("hand controller config: {0}")]
    Controller(#[from] ConfigError),
    #[error("hand supervisor: {0}")]
    Supervisor(#[from] SupervisorError),
    #[error("hardware safety layer: {0}")]
    Safety(#[from] SafetyConfigError),
    #[error("simulated hardware: {0}")]
    Hardware(#[from] HardwareError),
    #[error("target refused: {0}")]
    Target(String),
    #[error("unknown finger joint {0:?}")]
    UnknownJoint(String),
    #[error("simulated world lock poisoned")]
    Poisoned,
}

/// Index of a finger joint in [`SHADOW_FINGER_JOINTS`] order.
///
/// # Errors
/// [`ScenarioError::UnknownJoint`].
pub fn finger_joint_index(name: &str) -> Result<usize, ScenarioError> {
    teleop_interfaces::joints::finger_joint_index(name)
        .ok_or_else(|| ScenarioError::UnknownJoint(name.to_owned()))
}

/// Period of the hand inference's targets, s (30 Hz).
pub const TARGET_PERIOD_S: f64 = 1.0 / 30.0;

/// The hand as the node and `remote_sim` drive it: the supervisor with the node's
/// configuration (`controller` replaced), the simulated hand behind its safety layer.
pub struct HandLoop<W: ScenarioWorld = World> {
    world: SharedWorld<W>,
    hand: SafeHand<SimHand<W>>,
    supervisor: HandSupervisor,
    target: SVector<f64, 17>,
    next_target_s: f64,
    dt_s: f64,
}

impl<W: ScenarioWorld> std::fmt::Debug for HandLoop<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HandLoop")
            .field("dt_s", &self.dt_s)
            .finish()
    }
}

impl<W: ScenarioWorld> HandLoop<W> {
    /// The loop on `world` with the control law `controller`, aiming at `target`.
    ///
    /// # Errors
    /// Supervisor or safety configuration errors.
    pub fn new(
        world: W,
        controller: &HandControllerConfig<17>,
        target: SVector<f64, 17>,
    ) -> Result<Self, ScenarioError> {
        let config = HandSupervisorConfig {
            controller: *controller,
            ..HandSupervisorConfig::default()
        };
        let (lower, upper) = HandSupervisor::shadow_hand_limits()
            .map_err(|e| ScenarioError::Supervisor(SupervisorError::Model(e)))?;
        let mut supervisor = HandSupervisor::new(config, lower, upper)?;
        // The operator's switch heard released once before the run, as at any start (a
        // supervisor does not take a switch held since before it started for a press).
        let t0 = world.time_s();
        let released = OperatorSample::released(t0);
        supervisor.step(t0, Some(released), true, &world.hand_state(), None);
        let (world, _arm, sim_hand) = teleop_sim::share(world);
        let safety = HandSafety::new(HandLimits::shadow()?, HandSafetyConfig::default())?;
        Ok(Self {
            world,
            hand: SafeHand::new(sim_hand, safety),
            supervisor,
            target,
            next_target_s: 0.0,
            dt_s: 1.0 / config.rate_hz,
        })
    }

    /// The world (ground truth), locked.
    ///
    /// # Errors
    /// [`ScenarioError::Poisoned`].
    pub fn world(&self) -> Result<std::sync::MutexGuard<'_, W>, ScenarioError> {
        self.world.lock().map_err(|_| ScenarioError::Poisoned)
    }

    /// The supervisor (profiles, counters).
    pub fn supervisor(&self) -> &HandSupervisor {
        &self.supervisor
    }

    /// The safety layer (its counters).
    pub fn safety(&self) -> &HandSafety {
        self.hand.safety()
    }

    /// The control period, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// One control period: targets (every [`TARGET_PERIOD_S`]), pedals and switch
    /// held, the measured hand and arm, the supervisor's step, the command through the
    /// safety layer, the world advanced by one period.
    ///
    /// # Errors
    /// A refused target, the simulated hardware's errors, a poisoned lock.
    pub fn step(&mut self) -> Result<(), ScenarioError> {
        let now = self.world()?.time_s();
        if now >= self.next_target_s - 1e-9 {
            let msg = wire::finger_targets_msg(&self.target, now);
            self.supervisor
                .accept_target(&msg, now)
                .map_err(|e| ScenarioError::Target(e.to_string()))?;
            self.next_target_s += TARGET_PERIOD_S;
        }
        let operator = OperatorSample {
            received_s: now,
            clutch: true,
            enable: true,
            motion_scale: 1.0,
        };
        let state = self.hand.read(now)?;
        let arm = self.world()?.arm_state().position_rad;
        let out = self
            .supervisor
            .step(now, Some(operator), true, &state, Some(&arm));
        self.hand.write(now, &out.command)?;
        self.world()?.advance(self.dt_s)?;
        Ok(())
    }
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
    /// Length of a trial, s. Default 2.
    pub duration_s: f64,
    /// Contact forces before this time are not counted (the approach), s. Default 0.2.
    pub settle_s: f64,
    /// The simulated world. Default the joint-space one.
    pub engine: SimEngine,
}

impl Default for TouchingRun {
    fn default() -> Self {
        Self {
            task: TouchingTaskConfig::default(),
            overshoot_rad: 0.15,
            perturbation_rad: 0.01,
            duration_s: 2.0,
            settle_s: 0.2,
            engine: SimEngine::JointSpace,
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
    let world = World::touching_task(&run.task)?;
    match run.engine {
        SimEngine::JointSpace => touching_trial_in(world, run, controller, k, trials),
        SimEngine::Mujoco => touching_trial_in(
            MujocoWorld::from_joint_world(&world, MujocoWorldConfig::default())?,
            run,
            controller,
            k,
            trials,
        ),
    }
}

fn touching_trial_in<W: ScenarioWorld>(
    world: W,
    run: &TouchingRun,
    controller: &HandControllerConfig<17>,
    k: usize,
    trials: usize,
) -> Result<TouchTrial, ScenarioError> {
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

    let mut hand = HandLoop::new(world, controller, target)?;
    let (mut max, mut sum, mut n) = (0.0_f64, 0.0, 0u32);
    let (mut point_sum, mut points) = (nalgebra::Vector3::zeros(), 0u32);
    while hand.world()?.time_s() < run.duration_s - 1e-9 {
        hand.step()?;
        let world = hand.world()?;
        if world.time_s() >= run.settle_s {
            let f = world.tip_forces_n()[finger];
            max = max.max(f);
            sum += f;
            n += 1;
            for p in world.tip_contact_points(finger) {
                point_sum += p.coords;
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
    /// Length of the run, s. Default 9.
    pub duration_s: f64,
    /// A sample every this many control periods. Default 5 (10 ms at the node's
    /// 500 Hz).
    pub sample_every: usize,
    /// The simulated world. Default the joint-space one.
    pub engine: SimEngine,
}

impl Default for GraspRun {
    fn default() -> Self {
        Self {
            cup: CupGraspConfig::default(),
            traced_joint: "rh_THJ4".to_owned(),
            duration_s: 9.0,
            sample_every: 5,
            engine: SimEngine::JointSpace,
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
    let world = World::cup_grasp(&run.cup)?;
    match run.engine {
        SimEngine::JointSpace => grasp_run_in(world, run, controller),
        SimEngine::Mujoco => grasp_run_in(
            MujocoWorld::from_joint_world(&world, MujocoWorldConfig::default())?,
            run,
            controller,
        ),
    }
}

fn grasp_run_in<W: ScenarioWorld>(
    world: W,
    run: &GraspRun,
    controller: &HandControllerConfig<17>,
) -> Result<Vec<GraspSample>, ScenarioError> {
    let j = finger_joint_index(&run.traced_joint)?;
    let target = SVector::<f64, 17>::from(run.cup.closed_posture_rad);
    let mut hand = HandLoop::new(world, controller, target)?;
    let mut samples = Vec::new();
    let mut step = 0usize;
    while hand.world()?.time_s() < run.duration_s - 1e-9 {
        hand.step()?;
        step += 1;
        let world = hand.world()?;
        if step.is_multiple_of(run.sample_every.max(1)) {
            let s = world.hand_state();
            samples.push(GraspSample {
                time_s: world.time_s(),
                fingertip_force_n: world.tip_forces_n(),
                joint_rad: s.position_rad[j],
                joint_target_rad: target[j],
                joint_effort_nm: s.effort_nm[j],
            });
        }
    }
    Ok(samples)
}
