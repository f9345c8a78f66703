//! The operator site's simulated world, the counterpart of the robot site's
//! [`World`](crate::World): a simulated operator performing the thesis's tasks
//! ([`tasks`]), the motion capture that tracks the marker on the back of their hand
//! ([`mocap`]), the pedals, the UR5 carrying the depth camera, and the SR300 depth
//! camera rendering the operator's hand from wherever the UR5 has put it. If the camera
//! arm lags or aims badly, the hand leaves the image: the loop is closed for real.
//!
//! # Ground truth
//! The operator's true hand frame ([`OperatorWorld::hand_pose`], thesis Fig. 3.6, UR5
//! base frame), finger posture, and those fingers retargeted to the Shadow hand
//! ([`OperatorWorld::shadow_joints`]); the camera's true pose; which keypoints are in
//! view ([`OperatorWorld::hand_in_view`]).
//!
//! # The simulated UR5 differs from the model the controllers use
//! Kinematic, velocity-commanded ([`ArmSim`], as the PR2 arm): per-joint first-order
//! velocity lag (nominal 30 ms, each joint scaled by a seeded U(1 - f, 1 + f),
//! `lag_fraction` 0.2), acceleration limit 8 rad/s^2, URDF velocity and position limits,
//! its own brake after 0.1 s without a command; and each joint's true angle differs
//! from its encoder reading by a seeded N(0, `joint_offset_sd_rad` = 2 mrad) calibration
//! offset, so the camera's true pose (what the image is rendered from) differs from the
//! forward kinematics of the reported joints by a few millimetres.
//!
//! # The depth camera
//! SR300-like: 640 x 480, 73 x 59 deg, 30 Hz, depth 0.2-2 m (the range the hand
//! network's dataset was rendered with), SR300 noise model (`teleop_render`), the
//! operator's hand and forearm rendered with the hand model's capsules
//! (`teleop_hand_model::scene::push_human`), the same renderer as the dataset.

pub mod mocap;
pub mod reclutch;
pub mod tasks;
pub mod watching;

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};

use nalgebra::{Isometry3, Point3, SVector, Translation3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use teleop_control::TransformConfig;
use teleop_hand_model::human::{HandCapsule, HandShape, HumanHand, HumanPose};
use teleop_hand_model::keypoints::HandKeypoints;
use teleop_hand_model::retarget::{RetargetSettings, Retargeter, SHADOW_FINGER_DOF};
use teleop_hand_model::scene::{Forearm, push_human};
use teleop_hand_model::{HandModelError, hand_frame};
use teleop_hardware::{ArmCommand, ArmHardware, ArmState, HardwareError, PedalState};
use teleop_kinematics::{FixedChain, KinematicsError, robots};
use teleop_render::{
    Camera, Channels, DepthNoise, DepthRange, Frame, Intrinsics, NoiseParams, RenderError,
    Renderer, Scene,
};

pub use mocap::{Mocap, MocapConfig, MocapCounts, MocapReading};
pub use reclutch::{Reclutch, ReclutchConfig, ReclutchCounts};
pub use tasks::{TaskKind, TaskSample, TaskScript};
use teleop_hardware::velocity_driver::{ArmJointLimits, ArmSim};
pub use watching::{Onto, OperatorModel, Placement, WatchingConfig, WatchingOperator};

/// UR5 joint count.
pub const UR5_DOF: usize = 6;

pub use teleop_interfaces::calibration::{default_base_from_mocap, default_hand_from_marker};

/// The UR5's start posture, rad: elbow up, the camera level, looking along the base's
/// -x at the operator's resting hand, image up = world up.
pub const UR5_START_RAD: [f64; UR5_DOF] = [0.0, -1.57, 1.0, 0.57, 1.57, std::f64::consts::PI];

/// Errors of the operator-site world.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OperatorSiteError {
    #[error("invalid operator-site config: {0}")]
    Config(String),
    #[error("UR5 model: {0}")]
    Kinematics(#[from] KinematicsError),
    #[error("hand model: {0}")]
    HandModel(#[from] HandModelError),
    #[error("depth camera: {0}")]
    Render(#[from] RenderError),
}

/// The operator's hand shape: drawn from the world's seed (operators differ), or the
/// average hand.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandShapeConfig {
    /// Draw a shape (false: the average adult hand).
    pub random: bool,
    /// Standard deviation of the overall scale.
    pub scale_sd: f64,
    /// Standard deviation of each segment's length.
    pub segment_sd: f64,
}

impl Default for HandShapeConfig {
    fn default() -> Self {
        // The hand network's training distribution.
        Self {
            random: true,
            scale_sd: 0.07,
            segment_sd: 0.04,
        }
    }
}

/// The simulated UR5.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ur5SimConfig {
    pub initial_position_rad: [f64; UR5_DOF],
    /// Nominal velocity lag (the driver's servo smoothing), s.
    pub velocity_lag_s: f64,
    /// Each joint's lag is the nominal times U(1 - f, 1 + f), seeded.
    pub lag_fraction: f64,
    pub acceleration_limit_rad_s2: f64,
    /// The simulated driver brakes on its own after this long without a command, s.
    pub command_timeout_s: f64,
    /// Calibration offsets between encoder and true joint angle: N(0, sd), seeded, rad.
    pub joint_offset_sd_rad: f64,
    /// Integration step, s.
    pub dt_s: f64,
}

impl Default for Ur5SimConfig {
    fn default() -> Self {
        Self {
            initial_position_rad: UR5_START_RAD,
            velocity_lag_s: 0.03,
            lag_fraction: 0.2,
            acceleration_limit_rad_s2: 8.0,
            command_timeout_s: 0.1,
            joint_offset_sd_rad: 0.002,
            dt_s: 0.001,
        }
    }
}

/// The simulated SR300 depth camera on the UR5.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthCameraConfig {
    pub enabled: bool,
    /// Frame rate, Hz (SR300 depth: 30, up to 60).
    pub rate_hz: f64,
    /// Depth range, m.
    pub range_m: [f64; 2],
    /// Apply the SR300 noise model.
    pub noise: bool,
}

impl Default for DepthCameraConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            rate_hz: 30.0,
            range_m: [0.2, 2.0],
            noise: true,
        }
    }
}

/// Settings of the operator-site world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OperatorSiteConfig {
    /// Seed of everything random (hand shape, noise, the UR5's perturbation).
    pub seed: u64,
    /// Who moves the operator's hand: the scripted `task` (default) or the operator who
    /// watches the display and does the robot world's pick job (`watching`).
    pub operator: OperatorModel,
    /// The scripted operator's task.
    pub task: TaskKind,
    /// The watching operator's settings.
    pub watching: WatchingConfig,
    /// Both operators' foot on the clutch after a safety stop shown on the display.
    pub reclutch: ReclutchConfig,
    /// The operator waits this long before the first task (the camera settles), s.
    pub start_delay_s: f64,
    /// Repeat the task (with `pause_s` between repetitions) until stopped.
    pub repeat: bool,
    /// Rest between repetitions, s (clutch released).
    pub pause_s: f64,
    /// The hand frame at rest (Fig. 3.6), UR5 base frame: in front of the camera's
    /// start pose, palm toward it.
    pub rest_pose: TransformConfig,
    pub hand_shape: HandShapeConfig,
    /// Whether the enable (deadman) switch is held.
    pub enable: bool,
    /// Motion scale sent with the pedals, (0, 1].
    pub motion_scale: f64,
    pub mocap: MocapConfig,
    pub ur5: Ur5SimConfig,
    pub camera: DepthCameraConfig,
}

impl Default for OperatorSiteConfig {
    fn default() -> Self {
        Self {
            seed: 11,
            operator: OperatorModel::Scripted,
            task: TaskKind::PickAndPlace,
            watching: WatchingConfig::default(),
            reclutch: ReclutchConfig::default(),
            start_delay_s: 2.0,
            repeat: true,
            pause_s: 2.0,
            rest_pose: default_rest_pose(),
            hand_shape: HandShapeConfig::default(),
            enable: true,
            motion_scale: 1.0,
            mocap: MocapConfig::default(),
            ur5: Ur5SimConfig::default(),
            camera: DepthCameraConfig::default(),
        }
    }
}

/// The default resting hand frame: 0.85 m in front of the UR5 (its base's -x), fingers
/// up, the palm facing the robot, where the camera at [`UR5_START_RAD`] sees the palm
/// from 0.40 m as the camera arm's goal puts it (checked by a test).
pub fn default_rest_pose() -> TransformConfig {
    TransformConfig {
        translation_m: [-0.85, -0.11, 0.55],
        rpy_deg: [0.0, 0.0, -90.0],
    }
}

impl OperatorSiteConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        let u = &self.ur5;
        teleop_control::check_ranges(
            "operator_site",
            &[
                ("start_delay_s", self.start_delay_s, 0.0, 3600.0),
                ("pause_s", self.pause_s, 0.0, 3600.0),
                ("motion_scale", self.motion_scale, 1e-3, 1.0),
                ("hand_shape.scale_sd", self.hand_shape.scale_sd, 0.0, 0.12),
                (
                    "hand_shape.segment_sd",
                    self.hand_shape.segment_sd,
                    0.0,
                    0.1,
                ),
                ("ur5.velocity_lag_s", u.velocity_lag_s, 0.0, 1.0),
                ("ur5.lag_fraction", u.lag_fraction, 0.0, 0.9),
                (
                    "ur5.acceleration_limit_rad_s2",
                    u.acceleration_limit_rad_s2,
                    0.1,
                    100.0,
                ),
                ("ur5.command_timeout_s", u.command_timeout_s, 1e-3, 10.0),
                ("ur5.joint_offset_sd_rad", u.joint_offset_sd_rad, 0.0, 0.1),
                ("ur5.dt_s", u.dt_s, 1e-4, 0.01),
                ("camera.rate_hz", self.camera.rate_hz, 1.0, 60.0),
                ("camera.range_m[0]", self.camera.range_m[0], 0.05, 10.0),
                ("camera.range_m[1]", self.camera.range_m[1], 0.05, 10.0),
            ],
        )?;
        if self.camera.range_m[0] >= self.camera.range_m[1] {
            return Err("operator_site.camera.range_m must be [near, far] with near < far".into());
        }
        if u.initial_position_rad.iter().any(|v| !v.is_finite()) {
            return Err("operator_site.ur5.initial_position_rad must be finite".into());
        }
        self.rest_pose.validate("operator_site.rest_pose")?;
        if self.operator == OperatorModel::Watching {
            self.watching.validate()?;
        }
        self.reclutch.validate()?;
        self.mocap.validate()
    }
}

/// Which part of the hand the camera sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InView {
    /// Keypoints (of 21) inside the image and the depth range.
    pub keypoints: usize,
    /// All 21.
    pub fully: bool,
}

/// The operator site's world.
#[derive(Debug)]
pub struct OperatorWorld {
    cfg: OperatorSiteConfig,
    time_s: f64,
    pending_s: f64,
    script: TaskScript,
    rest: Isometry3<f64>,
    hand: HumanHand,
    retargeter: Retargeter,
    /// Shadow joints at `shadow_at_s`, warm start of the next retargeting.
    shadow: Option<(f64, [f64; SHADOW_FINGER_DOF])>,
    mocap: Mocap,
    chain: FixedChain<UR5_DOF>,
    ur5: ArmSim<UR5_DOF>,
    joint_offsets_rad: SVector<f64, UR5_DOF>,
    renderer: Renderer,
    scene: Scene,
    frame: Frame,
    capsules: Vec<HandCapsule>,
    noise: Option<DepthNoise>,
    camera_camera: Camera,
    /// The live operator's samples (sim time, sample), oldest first: the last second.
    live: VecDeque<(f64, TaskSample)>,
}

impl OperatorWorld {
    /// The world of `cfg`.
    ///
    /// # Errors
    /// [`OperatorSiteError::Config`] for an invalid config; model errors.
    pub fn new(cfg: OperatorSiteConfig) -> Result<Self, OperatorSiteError> {
        cfg.validate().map_err(OperatorSiteError::Config)?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let shape = if cfg.hand_shape.random {
            HandShape::sample(&mut rng, cfg.hand_shape.scale_sd, cfg.hand_shape.segment_sd)
        } else {
            HandShape::average()
        };
        let hand = HumanHand::new(shape)?;
        let chain = robots::ur5_camera_chain()?;
        let (lower, upper, vel) = (
            chain.lower_limits(),
            chain.upper_limits(),
            chain.velocity_limits(),
        );
        let u = &cfg.ur5;
        let limits: [ArmJointLimits; UR5_DOF] = std::array::from_fn(|i| ArmJointLimits {
            lower_rad: lower[i],
            upper_rad: upper[i],
            velocity_rad_s: vel[i],
            acceleration_rad_s2: u.acceleration_limit_rad_s2,
        });
        let lags: [f64; UR5_DOF] = std::array::from_fn(|_| {
            u.velocity_lag_s * (1.0 + u.lag_fraction * rng.random_range(-1.0..=1.0))
        });
        let offset = Normal::new(0.0, u.joint_offset_sd_rad.max(0.0))
            .map_err(|e| OperatorSiteError::Config(format!("ur5.joint_offset_sd_rad: {e}")))?;
        let joint_offsets_rad = SVector::from_fn(|_, _| offset.sample(&mut rng));
        let ur5 = ArmSim::new(
            limits,
            &SVector::from(u.initial_position_rad),
            u.velocity_lag_s,
            u.command_timeout_s,
        )
        .with_lags(lags);
        let noise_seed = rng.random::<u64>();
        let mocap_seed = rng.random::<u64>();
        let noise = if cfg.camera.noise {
            Some(DepthNoise::new(NoiseParams::sr300(), noise_seed)?)
        } else {
            None
        };
        let range = DepthRange::new(cfg.camera.range_m[0], cfg.camera.range_m[1])?;
        let camera_camera = Camera::new(Intrinsics::sr300(), range, Isometry3::identity());
        Ok(Self {
            script: TaskScript::new(cfg.task),
            rest: cfg.rest_pose.isometry(),
            hand,
            retargeter: Retargeter::new(RetargetSettings::default())?,
            shadow: None,
            mocap: Mocap::new(cfg.mocap.clone(), mocap_seed),
            chain,
            ur5,
            joint_offsets_rad,
            renderer: Renderer::new(),
            scene: Scene::new(),
            frame: Frame::new(Channels::DEPTH_ONLY),
            capsules: Vec::new(),
            noise,
            camera_camera,
            live: VecDeque::new(),
            time_s: 0.0,
            pending_s: 0.0,
            cfg,
        })
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &OperatorSiteConfig {
        &self.cfg
    }

    /// Sim time, s (0 at start).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The operator's hand.
    #[must_use]
    pub fn hand(&self) -> &HumanHand {
        &self.hand
    }

    /// The UR5's calibration offsets (true angle minus encoder reading), rad.
    #[must_use]
    pub fn ur5_joint_offsets_rad(&self) -> &SVector<f64, UR5_DOF> {
        &self.joint_offsets_rad
    }

    /// The task script.
    #[must_use]
    pub fn script(&self) -> &TaskScript {
        &self.script
    }

    /// Where in its task the operator is at sim time `t_s`: the time into the current
    /// repetition's motion (negative before it starts), the repetition, and whether the
    /// clutch is held. The clutch is pressed 0.5 s before the motion starts and
    /// released 0.5 s after it ends, as a person would.
    fn phase(&self, t_s: f64) -> (f64, u64, bool) {
        const LEAD_S: f64 = 0.5;
        let d = self.script.duration_s();
        let t = t_s - self.cfg.start_delay_s;
        if t < 0.0 {
            return (t, 0, false);
        }
        let cycle = d + 2.0 * LEAD_S + self.cfg.pause_s;
        let (k, tau) = if self.cfg.repeat {
            let k = (t / cycle).floor();
            (k, t - k * cycle)
        } else {
            (0.0, t)
        };
        let clutch = tau < d + 2.0 * LEAD_S && (self.cfg.repeat || t < cycle);
        // Repetitions: far below 2^64.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        (tau - LEAD_S, k as u64, clutch)
    }

    /// The task's state now.
    #[must_use]
    pub fn task_sample(&self) -> TaskSample {
        self.sample_at(self.time_s)
    }

    /// The operator at sim time `t_s`: from the script, or from the live operator's
    /// samples (interpolated between them; the hand at rest, open, before the first).
    fn sample_at(&self, t_s: f64) -> TaskSample {
        if self.cfg.operator == OperatorModel::Scripted {
            return self.script.sample(self.phase(t_s).0);
        }
        let rest = || TaskSample {
            offset_m: nalgebra::Vector3::zeros(),
            rotation: nalgebra::UnitQuaternion::identity(),
            posture: teleop_hand_model::sampling::Synergy::Open.posture(),
            under_way: false,
        };
        let after = self.live.iter().position(|(t, _)| *t > t_s);
        match after {
            Some(0) => self.live.front().map_or_else(rest, |(_, s)| s.clone()),
            Some(i) => {
                let (t0, a) = &self.live[i - 1];
                let (t1, b) = &self.live[i];
                let f = ((t_s - t0) / (t1 - t0)).clamp(0.0, 1.0);
                TaskSample {
                    offset_m: a.offset_m.lerp(&b.offset_m, f),
                    rotation: a.rotation.slerp(&b.rotation, f),
                    posture: a.posture,
                    under_way: a.under_way,
                }
            }
            None => self.live.back().map_or_else(rest, |(_, s)| s.clone()),
        }
    }

    /// The live operator's sample for now (ignored by a scripted world). Samples are
    /// kept for a second, so the motion capture can measure between them.
    pub fn drive(&mut self, sample: TaskSample) {
        if self.live.back().is_some_and(|(t, _)| *t >= self.time_s) {
            self.live.pop_back();
        }
        self.live.push_back((self.time_s, sample));
        while self
            .live
            .front()
            .is_some_and(|(t, _)| *t < self.time_s - 1.0)
        {
            self.live.pop_front();
        }
    }

    /// Completed repetitions of the task.
    #[must_use]
    pub fn repetitions_done(&self) -> u64 {
        if self.cfg.operator == OperatorModel::Watching {
            return 0;
        }
        let (tau, k, _) = self.phase(self.time_s);
        if tau >= self.script.duration_s() {
            k + 1
        } else {
            k
        }
    }

    /// The true hand frame (Fig. 3.6) now, UR5 base frame.
    #[must_use]
    pub fn hand_pose(&self) -> Isometry3<f64> {
        self.hand_pose_of(&self.task_sample())
    }

    fn hand_pose_of(&self, s: &TaskSample) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.rest.translation.vector + s.offset_m),
            self.rest.rotation * s.rotation,
        )
    }

    /// The true finger posture now.
    #[must_use]
    pub fn posture(&self) -> HumanPose {
        self.task_sample().posture
    }

    /// The operator's 21 keypoints now, UR5 base frame.
    ///
    /// # Errors
    /// [`OperatorSiteError::HandModel`] for a degenerate hand (does not happen).
    pub fn keypoints(&self) -> Result<HandKeypoints, OperatorSiteError> {
        let s = self.task_sample();
        let kp = self.hand.keypoints(&s.posture);
        let base_from_canonical = self.hand_pose_of(&s) * hand_frame(&kp)?.inverse();
        Ok(kp.transformed(&base_from_canonical))
    }

    /// The pedals now.
    #[must_use]
    pub fn pedals(&self) -> PedalState {
        PedalState {
            clutch: match self.cfg.operator {
                OperatorModel::Scripted => self.phase(self.time_s).2,
                OperatorModel::Watching => self.task_sample().under_way,
            },
            enable: self.cfg.enable,
            camera_stop: false,
            motion_scale: self.cfg.motion_scale,
        }
    }

    /// The true fingers retargeted to the Shadow hand's 17 joints (the labels the hand
    /// network was trained on), rad.
    ///
    /// # Errors
    /// Hand-model errors (do not happen for the scripted postures).
    pub fn shadow_joints(&mut self) -> Result<[f64; SHADOW_FINGER_DOF], OperatorSiteError> {
        if let Some((t, j)) = self.shadow
            && t == self.time_s
        {
            return Ok(j);
        }
        let kp = self.hand.keypoints(&self.posture());
        let previous = self.shadow.map(|(_, j)| j);
        let joints = self.retargeter.retarget(&kp, previous.as_ref())?.joints;
        self.shadow = Some((self.time_s, joints));
        Ok(joints)
    }

    /// The true hand frame at sim time `t_s` (the task is scripted, so any time can be
    /// asked for).
    #[must_use]
    pub fn hand_pose_at(&self, t_s: f64) -> Isometry3<f64> {
        self.hand_pose_of(&self.sample_at(t_s))
    }

    /// One motion-capture sample at sim time `t_s` (call once per capture period, in
    /// order).
    pub fn measure_marker_at(&mut self, t_s: f64) -> MocapReading {
        let hand = self.hand_pose_at(t_s);
        self.mocap.measure(t_s, &hand)
    }

    /// The capture period, s.
    #[must_use]
    pub fn mocap_period_s(&self) -> f64 {
        1.0 / self.cfg.mocap.rate_hz
    }

    /// The UR5 as its encoders measure it.
    #[must_use]
    pub fn ur5_state(&self) -> ArmState<UR5_DOF> {
        ArmState {
            time_s: self.time_s,
            position_rad: *self.ur5.position_rad(),
            velocity_rad_s: *self.ur5.velocity_rad_s(),
        }
    }

    /// Stores a joint velocity command; applied from the next step.
    pub fn command_ur5(&mut self, velocity_rad_s: &SVector<f64, UR5_DOF>) {
        self.ur5.command(velocity_rad_s, self.time_s);
    }

    /// The camera optical frame's true pose, UR5 base frame.
    #[must_use]
    pub fn camera_pose(&self) -> Isometry3<f64> {
        self.chain
            .end_pose(&(self.ur5.position_rad() + self.joint_offsets_rad))
    }

    /// The UR5's camera chain (the nominal model).
    #[must_use]
    pub fn ur5_chain(&self) -> &FixedChain<UR5_DOF> {
        &self.chain
    }

    /// The depth camera's intrinsics.
    #[must_use]
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics::sr300()
    }

    /// Which of the hand's keypoints the camera sees now (inside the image and the
    /// depth range; occlusion not considered).
    ///
    /// # Errors
    /// As [`OperatorWorld::keypoints`].
    pub fn hand_in_view(&self) -> Result<InView, OperatorSiteError> {
        let camera_from_base = self.camera_pose().inverse();
        let k = self.intrinsics();
        let [near, far] = self.cfg.camera.range_m;
        let kp = self.keypoints()?;
        let seen =
            kp.0.iter()
                .filter(|p| {
                    let c: Point3<f64> = camera_from_base * **p;
                    c.z >= near
                        && c.z <= far
                        && k.project(&c).is_some_and(|(u, v)| {
                            u >= 0.0
                                && v >= 0.0
                                && u < f64::from(k.width())
                                && v < f64::from(k.height())
                        })
                })
                .count();
        Ok(InView {
            keypoints: seen,
            fully: seen == kp.0.len(),
        })
    }

    /// Renders the depth image the camera takes now (`16UC1` mm, 640 x 480, row-major).
    ///
    /// # Errors
    /// Render errors for a non-finite pose (does not happen).
    pub fn render_depth(&mut self) -> Result<&[u16], OperatorSiteError> {
        let s = self.task_sample();
        let posed = self.hand.pose(&s.posture);
        let base_from_canonical = self.hand_pose_of(&s) * hand_frame(&posed.keypoints)?.inverse();
        self.scene.clear();
        push_human(
            &mut self.scene,
            &self.hand,
            &posed,
            Forearm::default(),
            &base_from_canonical,
            &mut self.capsules,
        )?;
        self.camera_camera.world_from_camera = self.camera_pose();
        self.renderer
            .render(&self.scene, &self.camera_camera, &mut self.frame);
        if let Some(n) = &mut self.noise {
            n.apply(&mut self.frame);
        }
        Ok(self.frame.depth_mm())
    }

    /// Advances by `dt_s` in fixed UR5 steps (durations accumulate, so how a caller
    /// slices time does not change the trajectory).
    pub fn step(&mut self, dt_s: f64) {
        let h = self.cfg.ur5.dt_s;
        self.pending_s += dt_s.max(0.0);
        while self.pending_s >= h {
            self.ur5.step(self.time_s, h);
            self.time_s += h;
            self.pending_s -= h;
        }
    }
}

/// An operator world shared between its stepping loop and the UR5's hardware handle.
pub type SharedOperatorWorld = Arc<Mutex<OperatorWorld>>;

fn lock(world: &SharedOperatorWorld) -> Result<MutexGuard<'_, OperatorWorld>, HardwareError> {
    world
        .lock()
        .map_err(|_| HardwareError::Fault("simulated operator world lock poisoned".to_owned()))
}

/// The simulated UR5 through [`ArmHardware`].
#[derive(Debug, Clone)]
pub struct SimUr5 {
    world: SharedOperatorWorld,
}

impl SimUr5 {
    /// A handle on `world`'s UR5.
    #[must_use]
    pub fn new(world: SharedOperatorWorld) -> Self {
        Self { world }
    }
}

impl ArmHardware<UR5_DOF> for SimUr5 {
    fn read(&mut self, _now_s: f64) -> Result<ArmState<UR5_DOF>, HardwareError> {
        Ok(lock(&self.world)?.ur5_state())
    }

    /// Stores the command; a non-finite one is refused (as a real driver would) and
    /// leaves the previous one in force.
    fn write(&mut self, _now_s: f64, command: &ArmCommand<UR5_DOF>) -> Result<(), HardwareError> {
        if !command.is_finite() {
            return Err(HardwareError::Fault(
                "non-finite UR5 velocity command".to_owned(),
            ));
        }
        lock(&self.world)?.command_ur5(&command.velocity_rad_s);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(cfg: OperatorSiteConfig) -> OperatorWorld {
        OperatorWorld::new(cfg).expect("world")
    }

    #[test]
    fn the_resting_hand_is_seen_from_the_start_posture_at_the_standoff() {
        let w = world(OperatorSiteConfig::default());
        let cam = w.camera_pose();
        let hand = w.hand_pose();
        // The look-at point: 8 cm from the wrist along the fingers, 0.40 m ahead of the
        // camera on its optical axis; the camera on the palm side (+y of the hand).
        let centre = hand * Point3::new(0.0, 0.0, 0.08);
        let in_cam = cam.inverse() * centre;
        assert!((in_cam.z - 0.40).abs() < 0.02, "{in_cam}");
        assert!(in_cam.x.abs() < 0.02 && in_cam.y.abs() < 0.02, "{in_cam}");
        let palm_normal = hand.rotation * nalgebra::Vector3::y();
        let view = cam.rotation * nalgebra::Vector3::z();
        assert!(palm_normal.dot(&view) < -0.95, "camera faces the palm");
        assert!(w.hand_in_view().expect("in view").fully);
    }

    #[test]
    fn the_depth_image_shows_the_hand_where_it_is() {
        let mut w = world(OperatorSiteConfig::default());
        let k = w.intrinsics();
        let depth = w.render_depth().expect("render").to_vec();
        assert_eq!(depth.len(), 640 * 480);
        let hand_px = depth.iter().filter(|d| **d > 0).count();
        assert!(hand_px > 5_000, "hand pixels: {hand_px}");
        // The image centre sees the palm at about the standoff.
        let (u, v) = (k.cx().round() as usize, k.cy().round() as usize);
        let mut near: Vec<u16> = (v - 10..v + 10)
            .flat_map(|r| depth[r * 640 + u - 10..r * 640 + u + 10].to_vec())
            .filter(|d| *d > 0)
            .collect();
        near.sort_unstable();
        assert!(!near.is_empty());
        let median = f64::from(near[near.len() / 2]) / 1000.0;
        assert!((0.34..0.42).contains(&median), "palm at {median} m");
    }

    #[test]
    fn the_ur5_moves_as_commanded_and_stops_without_commands() {
        let mut w = world(OperatorSiteConfig::default());
        let q0 = w.ur5_state().position_rad;
        let cmd = SVector::<f64, UR5_DOF>::from([0.2, 0.0, 0.0, 0.0, 0.0, 0.0]);
        for _ in 0..50 {
            w.command_ur5(&cmd);
            w.step(0.01);
        }
        let moved = w.ur5_state().position_rad[0] - q0[0];
        assert!((0.08..0.1).contains(&moved), "moved {moved} rad in 0.5 s");
        // No command: the driver's brake stops it.
        w.step(0.5);
        let q1 = w.ur5_state().position_rad;
        w.step(0.5);
        assert_eq!(w.ur5_state().position_rad, q1);
        assert!(w.ur5_state().velocity_rad_s.norm() == 0.0);
    }

    #[test]
    fn the_simulated_ur5_differs_from_its_model_by_a_seeded_calibration() {
        let a = world(OperatorSiteConfig::default());
        let b = world(OperatorSiteConfig::default());
        assert_eq!(a.ur5_joint_offsets_rad(), b.ur5_joint_offsets_rad());
        let offsets = a.ur5_joint_offsets_rad();
        assert!(offsets.norm() > 0.0 && offsets.amax() < 0.01, "{offsets}");
        let nominal = a.ur5_chain().end_pose(&a.ur5_state().position_rad);
        let err = (nominal.translation.vector - a.camera_pose().translation.vector).norm();
        assert!(err > 1e-4 && err < 0.02, "camera {err} m from its model");
    }

    #[test]
    fn pedals_follow_the_task() {
        let mut w = world(OperatorSiteConfig {
            repeat: false,
            ..OperatorSiteConfig::default()
        });
        assert!(!w.pedals().clutch, "waits before starting");
        w.step(2.6);
        assert!(w.pedals().clutch, "pressed before the motion starts");
        let d = w.script().duration_s();
        w.step(d + 1.0);
        assert!(!w.pedals().clutch, "released after the task");
        assert_eq!(w.repetitions_done(), 1);
        assert!(w.pedals().enable);
    }

    #[test]
    fn ground_truth_fingers_follow_the_grasp() {
        let mut w = world(OperatorSiteConfig::default());
        let open = w.shadow_joints().expect("joints");
        // Pick and place: grasped 3-8 s into the motion (starts at 2.5 s).
        w.step(2.5 + 5.0);
        let closed = w.shadow_joints().expect("joints");
        let flexion: f64 = closed.iter().zip(open).map(|(c, o)| c - o).sum();
        assert!(
            flexion > 1.0,
            "the Shadow fingers close with the operator's: {flexion}"
        );
    }
}
