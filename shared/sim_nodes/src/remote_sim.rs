//! The simulator process (`remote_sim`): owns the simulated world (PR2 arm, Shadow hand,
//! objects, camera views) and offers it to the site's controllers over the hardware
//! topics, as the robots' drivers would (the way Gazebo stands in for hardware).
//!
//! It is the process that owns the hardware, so the last safety layer lives here: the
//! arm and the hand are wrapped in [`SafeArm`] / [`SafeHand`], and the endpoints take
//! commands only from the interface's controller node. A command from anyone else is
//! dropped and counted; every command that gets through is limited (joint limits,
//! end-effector speed, effort, command timeout). The world steps in real time on the
//! node's clock.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher};
use teleop_hardware::safety::{
    ArmSafety, ArmSafetyConfig, HandLimits, HandSafety, HandSafetyConfig,
};
use teleop_hardware::{
    ArmCommand, ArmHardware, ArmState, HandCommand, HandHardware, HandState, HardwareError,
    SafeArm, SafeHand,
};
use teleop_hardware_bus::{
    ArmEndpoint, HandEndpoint, Ros2ControlArm, Ros2ControlConfig, Ros2ControlHand,
    Ros2ControlHandConfig,
};
use teleop_interfaces::hardware::{PR2_ARM, SHADOW_HAND};
use teleop_interfaces::topics;
use teleop_msgs::{Header, Image, Lifecycle, TFMessage, Transform, TransformStamped};
use teleop_node::{FinalReport, Node, NodeConfig, NodeErrors, Periodic, SchedulingConfig};
use teleop_sim::{
    CameraViewsConfig, CupGraspConfig, MujocoWorld, MujocoWorldConfig, PickSceneConfig, RobotWorld,
    SceneCameras, SimArm, SimHand, TouchingTaskConfig, TowerJobConfig, View, WORKING_POSTURE_RAD,
    World, WorldConfig,
};

/// Which world to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneKind {
    /// The arm and hand alone.
    Free,
    /// The "mouse touching" task (thesis Fig. 8.7).
    Touching,
    /// A cup held in place to grasp (thesis Fig. 8.8).
    CupGrasp,
    /// A table with a can and a cube free on it (thesis ch. 6.4's pick tasks); the
    /// physical engine only.
    Pick,
    /// The pick scene's table with the tower job's blocks on it (thesis ch. 7.6.2's
    /// tower building); the physical engine only.
    Tower,
}

/// Which simulator moves the robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Engine {
    /// MuJoCo (`teleop_sim::MujocoWorld`): rigid-body dynamics of the whole robot, the
    /// real shapes' contacts, free objects.
    Mujoco,
    /// The joint-space model (`teleop_sim::World`): a kinematic arm, per-joint finger
    /// dynamics, penalty contacts with fixed objects.
    JointSpace,
}

/// The world the simulator process owns, whichever engine moves it.
pub type SimWorld = Arc<Mutex<dyn RobotWorld>>;

/// The hardware safety layer of the simulated robots.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSafetyConfig {
    /// The only node whose arm commands are taken.
    pub arm_controller_node: String,
    /// The only node whose hand commands are taken.
    pub hand_controller_node: String,
    pub arm: ArmSafetyConfig,
    pub hand: HandSafetyConfig,
}

impl Default for SimSafetyConfig {
    fn default() -> Self {
        Self {
            arm_controller_node: PR2_ARM.controller_node.into(),
            hand_controller_node: SHADOW_HAND.controller_node.into(),
            arm: ArmSafetyConfig {
                // The palm origin and the fingertips' reach (0.2 m out along the palm's
                // z, past the straight fingers' tips).
                tool_points_m: vec![[0.0, 0.0, 0.0], [0.0, 0.0, 0.2]],
                ..ArmSafetyConfig::default()
            },
            hand: HandSafetyConfig::default(),
        }
    }
}

/// What runs a robot (the PR2 arm, the hand).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackendKind {
    /// The simulated world's robot.
    Sim,
    /// A robot run by ros2_control on ROS 2 (rmw_zenoh): a forward command controller
    /// and the joint state broadcaster (`teleop_hardware_bus::ros2_control`). The
    /// world's own robot then stays where it is.
    Ros2Control,
}

/// The PR2 arm's backend, behind the same safety layer and endpoint either way.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmBackendConfig {
    pub backend: BackendKind,
    /// Used when `backend = "ros2_control"`: a forward velocity controller.
    pub ros2_control: Ros2ControlConfig,
}

impl Default for ArmBackendConfig {
    fn default() -> Self {
        Self {
            backend: BackendKind::Sim,
            ros2_control: Ros2ControlConfig::default(),
        }
    }
}

/// The hand's backend, behind the same safety layer and endpoint either way.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandBackendConfig {
    pub backend: BackendKind,
    /// Used when `backend = "ros2_control"`: an effort or a position controller.
    pub ros2_control: Ros2ControlHandConfig,
}

impl Default for HandBackendConfig {
    fn default() -> Self {
        Self {
            backend: BackendKind::Sim,
            ros2_control: Ros2ControlHandConfig::default(),
        }
    }
}

/// The hand's backend as the safety layer sees it.
#[derive(Debug)]
enum HandBackend {
    Sim(SimHand<dyn RobotWorld>),
    Ros2Control(Box<Ros2ControlHand>),
}

impl HandHardware for HandBackend {
    fn read(&mut self, now_s: f64) -> Result<HandState, HardwareError> {
        match self {
            HandBackend::Sim(h) => h.read(now_s),
            HandBackend::Ros2Control(h) => h.read(now_s),
        }
    }

    fn write(&mut self, now_s: f64, command: &HandCommand) -> Result<(), HardwareError> {
        match self {
            HandBackend::Sim(h) => h.write(now_s, command),
            HandBackend::Ros2Control(h) => h.write(now_s, command),
        }
    }
}

/// The PR2 arm's backend as the safety layer sees it.
#[derive(Debug)]
enum ArmBackend {
    Sim(SimArm<dyn RobotWorld>),
    Ros2Control(Box<Ros2ControlArm<7>>),
}

impl ArmHardware<7> for ArmBackend {
    fn read(&mut self, now_s: f64) -> Result<ArmState<7>, HardwareError> {
        match self {
            ArmBackend::Sim(a) => a.read(now_s),
            ArmBackend::Ros2Control(a) => a.read(now_s),
        }
    }

    fn write(&mut self, now_s: f64, command: &ArmCommand<7>) -> Result<(), HardwareError> {
        match self {
            ArmBackend::Sim(a) => a.write(now_s, command),
            ArmBackend::Ros2Control(a) => a.write(now_s, command),
        }
    }
}

/// Configuration of the `remote_sim` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimNodeConfig {
    pub node_name: String,
    pub scene: SceneKind,
    /// The simulator: `mujoco` (default) or `joint_space` (the previous model, kept
    /// until the ch. 8 hand scenarios are measured in MuJoCo).
    pub engine: Engine,
    /// Rate of the state messages (and of the world's catching up with the clock), Hz.
    pub state_rate_hz: f64,
    /// World settings for `scene = "free"`.
    pub world: WorldConfig,
    pub touching: TouchingTaskConfig,
    pub cup_grasp: CupGraspConfig,
    /// The scene of `scene = "pick"` (and the table and postures of `scene = "tower"`).
    pub pick: PickSceneConfig,
    /// The blocks and the job of `scene = "tower"`.
    pub tower: TowerJobConfig,
    /// The physical world's settings (`engine = "mujoco"`): robot parameters, model
    /// mismatch, object variation, noise. The scene's objects and postures come from
    /// the scene's own section.
    pub mujoco: MujocoWorldConfig,
    /// The top and side camera views, rendered from the world and published on
    /// `teleop/hw/camera/{top,side}/image` as a camera driver would.
    pub cameras: CameraViewsConfig,
    /// The safety layer around the arm and the hand.
    pub safety: SimSafetyConfig,
    /// What runs the PR2 arm: the simulated world's (default) or a ROS 2 robot's
    /// ros2_control.
    pub pr2_arm: ArmBackendConfig,
    /// What runs the hand: the simulated world's (default) or ros2_control.
    pub shadow_hand: HandBackendConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    pub bus: BusConfig,
}

impl Default for SimNodeConfig {
    fn default() -> Self {
        Self {
            node_name: "remote_sim".into(),
            scene: SceneKind::Pick,
            engine: Engine::Mujoco,
            state_rate_hz: topics::HW_PR2_ARM_STATE.spec.rate_hz,
            world: WorldConfig::default(),
            touching: TouchingTaskConfig {
                arm_posture_rad: WORKING_POSTURE_RAD,
                ..TouchingTaskConfig::default()
            },
            cup_grasp: CupGraspConfig::default(),
            pick: PickSceneConfig::default(),
            tower: TowerJobConfig::default(),
            mujoco: MujocoWorldConfig::default(),
            cameras: CameraViewsConfig::default(),
            safety: SimSafetyConfig::default(),
            pr2_arm: ArmBackendConfig::default(),
            shadow_hand: HandBackendConfig::default(),
            scheduling: SchedulingConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for SimNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        if !(self.state_rate_hz.is_finite()
            && self.state_rate_hz > 0.0
            && self.state_rate_hz <= 1000.0)
        {
            return Err(format!(
                "state_rate_hz must be in (0, 1000], got {}",
                self.state_rate_hz
            ));
        }
        self.cameras
            .validate()
            .map_err(|e| format!("cameras: {e}"))?;
        self.safety
            .arm
            .validate()
            .map_err(|e| format!("safety.arm: {e}"))?;
        self.safety
            .hand
            .validate()
            .map_err(|e| format!("safety.hand: {e}"))?;
        for (field, node) in [
            ("arm_controller_node", &self.safety.arm_controller_node),
            ("hand_controller_node", &self.safety.hand_controller_node),
        ] {
            if node.is_empty() {
                return Err(format!("safety.{field} must name a node"));
            }
        }
        match self.scene {
            SceneKind::Pick => {
                self.pick.job_config().map_err(|e| e.to_string())?;
            }
            SceneKind::Tower => {
                self.pick
                    .tower_job_config(&self.tower)
                    .map_err(|e| format!("tower: {e}"))?;
            }
            _ => {}
        }
        if self.pr2_arm.backend == BackendKind::Ros2Control {
            self.pr2_arm
                .ros2_control
                .validate_arm(&PR2_ARM)
                .map_err(|e| format!("pr2_arm.{e}"))?;
        }
        if self.shadow_hand.backend == BackendKind::Ros2Control {
            self.shadow_hand
                .ros2_control
                .validate(&SHADOW_HAND)
                .map_err(|e| format!("shadow_hand.{e}"))?;
        }
        Ok(())
    }
}

/// The objects' poses as one `tf2_msgs/TFMessage`: world -> each object, stamped
/// `now_s`. Objects with a non-finite pose are left out.
#[must_use]
pub fn object_poses_msg(now_s: f64, poses: &[(String, nalgebra::Isometry3<f64>)]) -> TFMessage {
    let stamp = teleop_msgs::Time::from_secs_f64(now_s);
    TFMessage {
        transforms: poses
            .iter()
            .filter_map(|(name, pose)| {
                let p = teleop_hardware::wire::pose_msg(pose)?;
                Some(TransformStamped {
                    header: Header::new(stamp, "world"),
                    child_frame_id: name.clone(),
                    transform: Transform {
                        translation: teleop_msgs::Vector3 {
                            x: p.position.x,
                            y: p.position.y,
                            z: p.position.z,
                        },
                        rotation: p.orientation,
                    },
                })
            })
            .collect(),
    }
}

/// Builds the configured world.
///
/// # Errors
/// The simulator's configuration errors; a scene the engine lacks.
pub fn build_world(cfg: &SimNodeConfig) -> anyhow::Result<SimWorld> {
    let joint_world = || -> anyhow::Result<Option<World>> {
        Ok(match cfg.scene {
            SceneKind::Free => Some(World::new(cfg.world.clone())?),
            SceneKind::Touching => Some(World::touching_task(&cfg.touching)?),
            SceneKind::CupGrasp => Some(World::cup_grasp(&cfg.cup_grasp)?),
            SceneKind::Pick | SceneKind::Tower => None,
        })
    };
    Ok(match cfg.engine {
        Engine::JointSpace => {
            let Some(world) = joint_world()? else {
                anyhow::bail!(
                    "scene {:?} needs engine = \"mujoco\" (its objects are free)",
                    cfg.scene
                );
            };
            Arc::new(Mutex::new(world))
        }
        Engine::Mujoco => {
            let world = match joint_world()? {
                Some(world) => MujocoWorld::from_joint_world(&world, cfg.mujoco.clone())?,
                None => {
                    let scene = if cfg.scene == SceneKind::Tower {
                        cfg.pick.tower_scene(&cfg.tower)?
                    } else {
                        cfg.pick.scene()?
                    };
                    MujocoWorld::new(&scene, cfg.pick.world_config(&cfg.mujoco))?
                }
            };
            Arc::new(Mutex::new(world))
        }
    })
}

/// The simulator node: the world, the robots behind their safety layers, the bus
/// endpoints, the camera views.
#[derive(Debug)]
pub struct SimNode {
    period: Duration,
    world: SimWorld,
    arm: SafeArm<7, ArmBackend>,
    hand: SafeHand<HandBackend>,
    arm_endpoint: ArmEndpoint<7>,
    hand_endpoint: HandEndpoint,
    cameras: Option<CameraViews>,
    camera_due: Periodic,
    /// The objects' true poses, published with each camera view (same stamp) for the
    /// operator model (simulation only).
    objects_pub: Publisher<TFMessage>,
    /// Node-clock time matching sim time `sim_start_s`.
    start_s: Option<f64>,
    sim_start_s: f64,
    hardware_errors: u64,
    errors: NodeErrors,
    /// The last tick stepped the world and published both robots' states.
    serving: bool,
    /// The scene's job judged from ground truth (the pick and tower scenes), and the observations
    /// it refused.
    job: Option<teleop_physics::JobJudge>,
    job_errors: u64,
}

impl SimNode {
    /// Builds the world and declares the endpoints on `bus`.
    ///
    /// # Errors
    /// World, safety or camera configuration errors; bus declarations.
    pub async fn new(cfg: &SimNodeConfig, bus: &Bus) -> anyhow::Result<Self> {
        let world = build_world(cfg)?;
        let (scene_cameras, sim_start_s) = {
            let w = world
                .lock()
                .map_err(|_| anyhow::anyhow!("world lock poisoned"))?;
            let cameras = if cfg.cameras.enabled {
                Some(SceneCameras::new(&*w, &cfg.cameras)?)
            } else {
                None
            };
            (cameras, w.time_s())
        };
        let cameras = CameraViews::open(bus, scene_cameras).await?;
        let hand_backend = match cfg.shadow_hand.backend {
            BackendKind::Sim => HandBackend::Sim(SimHand::new(world.clone())),
            BackendKind::Ros2Control => HandBackend::Ros2Control(Box::new(
                Ros2ControlHand::new(bus, &SHADOW_HAND, &cfg.shadow_hand.ros2_control).await?,
            )),
        };
        let arm_backend = match cfg.pr2_arm.backend {
            BackendKind::Sim => ArmBackend::Sim(SimArm::new(world.clone())),
            BackendKind::Ros2Control => ArmBackend::Ros2Control(Box::new(
                Ros2ControlArm::new(bus, &PR2_ARM, &cfg.pr2_arm.ros2_control).await?,
            )),
        };
        let arm_safety = ArmSafety::new(
            teleop_kinematics::robots::pr2_arm_chain()?,
            cfg.safety.arm.clone(),
        )?;
        let hand_safety = HandSafety::new(HandLimits::shadow()?, cfg.safety.hand)?;
        let job = match cfg.scene {
            SceneKind::Pick => Some(teleop_physics::JobJudge::PickPlace(
                teleop_physics::PickPlaceJudge::new(cfg.pick.job_config()?)?,
            )),
            SceneKind::Tower => Some(teleop_physics::JobJudge::Tower(
                teleop_physics::TowerJudge::new(cfg.pick.tower_job_config(&cfg.tower)?)?,
            )),
            _ => None,
        };
        tracing::info!(scene = ?cfg.scene, engine = ?cfg.engine, arm_from = %cfg.safety.arm_controller_node,
            hand_from = %cfg.safety.hand_controller_node, "simulator running in real time");
        Ok(Self {
            period: Duration::from_secs_f64(1.0 / cfg.state_rate_hz),
            world,
            arm: SafeArm::new(arm_backend, arm_safety),
            hand: SafeHand::new(hand_backend, hand_safety),
            arm_endpoint: ArmEndpoint::new(bus, &PR2_ARM, &cfg.safety.arm_controller_node).await?,
            hand_endpoint: HandEndpoint::new(bus, &SHADOW_HAND, &cfg.safety.hand_controller_node)
                .await?,
            cameras,
            camera_due: Periodic::at_rate(cfg.cameras.rate_hz),
            objects_pub: bus.publisher(&topics::SIM_ROBOT_OBJECT_POSES).await?,
            start_s: None,
            sim_start_s,
            hardware_errors: 0,
            errors: NodeErrors::new(),
            serving: false,
            job,
            job_errors: 0,
        })
    }

    /// The world (ground truth).
    pub fn world(&self) -> &SimWorld {
        &self.world
    }

    /// An error of the part `what` at `now_s` (a condition: it holds until that part
    /// works again, see [`Self::works`]).
    fn fail(&mut self, what: &'static str, e: impl std::fmt::Display, now_s: f64) {
        self.hardware_errors += 1;
        self.errors.condition(what, format!("{what}: {e}"), now_s);
    }

    fn works(&mut self, what: &'static str, now_s: f64) {
        self.errors.resolved(what, now_s);
    }
}

impl Node for SimNode {
    fn period(&self) -> Duration {
        self.period
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        // Commands from the controllers, through the safety layer (a period without a
        // command is filtered too: the command timeout).
        let arm = match self.arm_endpoint.take_command() {
            Some(c) => self.arm.write(now_s, &c),
            None => self.arm.idle(now_s),
        };
        if let Some(text) = self.arm_endpoint.take_refusal() {
            self.errors.event("arm command", text, now_s);
        }
        match arm {
            Ok(()) => self.works("arm", now_s),
            Err(e) => self.fail("arm", e, now_s),
        }
        let hand = match self.hand_endpoint.take_command() {
            Some(c) => self.hand.write(now_s, &c),
            None => self.hand.idle(now_s),
        };
        if let Some(text) = self.hand_endpoint.take_refusal() {
            self.errors.event("hand command", text, now_s);
        }
        match hand {
            Ok(()) => self.works("hand", now_s),
            Err(e) => self.fail("hand", e, now_s),
        }
        // Catch up with the clock (at most 0.1 s per tick after a stall).
        let start = *self.start_s.get_or_insert(now_s);
        let Ok(mut world) = self.world.lock() else {
            self.serving = false;
            self.fail("world", "lock poisoned", now_s);
            return;
        };
        let lag = (now_s - start) - (world.time_s() - self.sim_start_s);
        let stepped = if lag > 0.0 {
            world.advance(lag.min(0.1))
        } else {
            Ok(())
        };
        // Stamped with the node clock at the measurement, as a driver would (the
        // world's own time starts at zero).
        let (mut arm_state, mut hand_state) = (world.arm_state(), world.hand_state());
        arm_state.time_s = now_s;
        hand_state.time_s = now_s;
        let judged = self.job.as_mut().map(|judge| {
            let was_final = judge.verdict().is_final();
            let verdict = judge
                .step(
                    world.time_s(),
                    arm_state.position_rad.as_slice(),
                    &world.object_poses(),
                )
                .cloned();
            (was_final, verdict)
        });
        let render = self.cameras.is_some() && self.camera_due.due(now_s);
        let (camera, objects) = if render {
            (
                self.cameras.as_mut().map(|c| c.render(&*world, now_s)),
                Some(object_poses_msg(now_s, &world.object_poses())),
            )
        } else {
            (None, None)
        };
        drop(world);
        if let Some(msg) = objects
            && let Err(e) = self.objects_pub.put(&msg)
        {
            self.errors
                .event("object poses", format!("object poses: {e}"), now_s);
        }
        let mut serving = stepped.is_ok();
        match stepped {
            Ok(()) => self.works("world", now_s),
            Err(e) => self.fail("world", e, now_s),
        }
        match judged {
            Some((false, Ok(verdict))) if verdict.is_final() => {
                tracing::info!(?verdict, "the scene's job is judged");
            }
            Some((_, Err(e))) => {
                self.job_errors += 1;
                self.errors
                    .event("job judge", format!("job judge: {e}"), now_s);
            }
            _ => {}
        }
        // A robot of its own (ros2_control): its measured state, not the world's arm.
        let arm_state = match self.arm.backend() {
            ArmBackend::Sim(_) => Ok(arm_state),
            ArmBackend::Ros2Control(_) => self.arm.read(now_s),
        };
        if let ArmBackend::Ros2Control(r) = self.arm.backend()
            && let Some(text) = r.take_refusal()
        {
            self.errors.event("arm joint state", text, now_s);
        }
        match arm_state.and_then(|s| {
            self.arm_endpoint
                .publish_state(&s)
                .map_err(|e| HardwareError::Fault(e.to_string()))
        }) {
            Ok(()) => self.works("arm state", now_s),
            Err(e) => {
                serving = false;
                self.fail("arm state", e, now_s);
            }
        }
        let hand_state = match self.hand.backend() {
            HandBackend::Sim(_) => Ok(hand_state),
            HandBackend::Ros2Control(_) => self.hand.read(now_s),
        };
        if let HandBackend::Ros2Control(r) = self.hand.backend()
            && let Some(text) = r.take_refusal()
        {
            self.errors.event("hand joint state", text, now_s);
        }
        match hand_state.and_then(|s| {
            self.hand_endpoint
                .publish_state(&s)
                .map_err(|e| HardwareError::Fault(e.to_string()))
        }) {
            Ok(()) => self.works("hand state", now_s),
            Err(e) => {
                serving = false;
                self.fail("hand state", e, now_s);
            }
        }
        match camera {
            Some(Ok(_)) => self.works("cameras", now_s),
            Some(Err(e)) => self.fail("cameras", e, now_s),
            None => {}
        }
        self.serving = serving;
    }

    /// Inactive until the world first steps and both robots' states go out; Active
    /// while they do; Fault while the world cannot step or a robot's state cannot be
    /// published (the controllers then see no hardware).
    fn state(&self) -> Lifecycle {
        crate::serving_state(self.serving, self.start_s.is_some())
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let sim_time_ms = self
            .world
            .lock()
            // Non-negative and far below 2^64 ms.
            .map(|w| {
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let ms = (w.time_s() * 1e3) as u64;
                ms
            })
            .unwrap_or(0);
        let mut out = vec![
            ("sim.time_ms".to_owned(), sim_time_ms),
            ("sim.hardware_errors".to_owned(), self.hardware_errors),
            (
                "sim.camera_frames".to_owned(),
                self.cameras.as_ref().map_or(0, |c| c.frames),
            ),
        ];
        if let Some(judge) = &self.job {
            out.extend(job_counters(judge, self.job_errors));
        }
        out.extend(self.arm_endpoint.counters());
        out.extend(self.hand_endpoint.counters());
        out.extend(self.arm.safety().counters().named("safety.arm"));
        if let ArmBackend::Ros2Control(r) = self.arm.backend() {
            out.extend(r.counters("pr2_arm.ros2_control"));
        }
        if let HandBackend::Ros2Control(r) = self.hand.backend() {
            out.extend(r.counters("shadow_hand.ros2_control"));
        }
        out.extend(self.hand.safety().counters().named("safety.hand"));
        out
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    /// The robots stop: the arm brakes (zero velocity), the hand holds its posture.
    fn shutdown(&mut self, now_s: f64) {
        let stop = teleop_hardware::ArmCommand::stop();
        if let Err(e) = self.arm.write(now_s, &stop) {
            tracing::warn!("stopping the arm: {e}");
        }
    }
}

/// The job's standing as status counters: `job.lifted` (0/1), `job.succeeded` (0/1),
/// `job.completion_ms`, `job.failed.fell_off_table` / `job.failed.timed_out` (0/1),
/// `job.judge_errors` (observations it refused).
fn job_counters(judge: &teleop_physics::JobJudge, errors: u64) -> Vec<(String, u64)> {
    use teleop_physics::{Failure, Verdict};
    let (succeeded, completion_ms, fell, timed_out) = match judge.verdict() {
        Verdict::Running => (0, 0, 0, 0),
        Verdict::Succeeded { completion_s } => {
            // Non-negative and far below 2^64 ms.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let ms = (completion_s * 1e3).round().max(0.0) as u64;
            (1, ms, 0, 0)
        }
        Verdict::Failed { failure, .. } => match failure {
            Failure::FellOffTable { .. } => (0, 0, 1, 0),
            Failure::TimedOut => (0, 0, 0, 1),
        },
    };
    use teleop_interfaces::status::job;
    let [fell_off_table, timed_out_name] = job::FAILURES;
    let mut out: Vec<(String, u64)> = [
        (job::LIFTED, u64::from(judge.lifted())),
        (job::SUCCEEDED, succeeded),
        (job::COMPLETION_MS, completion_ms),
        (job::JUDGE_ERRORS, errors),
    ]
    .into_iter()
    .map(|(n, v)| (n.to_owned(), v))
    .collect();
    out.push((format!("{}{fell_off_table}", job::FAILED_PREFIX), fell));
    out.push((format!("{}{timed_out_name}", job::FAILED_PREFIX), timed_out));
    out
}

/// Runs the simulator on the system clock until `duration` elapses (forever if `None`)
/// or SIGINT/SIGTERM.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: SimNodeConfig, duration: Option<Duration>) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = SimNode::new(&cfg, &bus).await?;
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}

/// The two camera views as the simulator publishes them: rendered from the world at the
/// camera rate, newest only (a slow subscriber misses frames, never delays them).
#[derive(Debug)]
struct CameraViews {
    cameras: SceneCameras,
    publishers: [Publisher<Image>; 2],
    /// One message per view, reused between frames.
    images: [Image; 2],
    frames: u64,
}

impl CameraViews {
    /// `None` when the cameras are disabled (`cameras` is `None`).
    async fn open(bus: &Bus, cameras: Option<SceneCameras>) -> anyhow::Result<Option<Self>> {
        let Some(cameras) = cameras else {
            return Ok(None);
        };
        Ok(Some(Self {
            cameras,
            publishers: [
                bus.publisher(&topics::HW_CAMERA_TOP).await?,
                bus.publisher(&topics::HW_CAMERA_SIDE).await?,
            ],
            images: Default::default(),
            frames: 0,
        }))
    }

    /// Renders both views and publishes them, stamped `now_s` (node clock).
    fn render(&mut self, world: &dyn RobotWorld, now_s: f64) -> anyhow::Result<()> {
        self.cameras.render(world)?;
        let stamp = teleop_msgs::Time::from_secs_f64(now_s);
        for ((view, publisher), image) in View::ALL
            .into_iter()
            .zip(&self.publishers)
            .zip(&mut self.images)
        {
            self.cameras.write_image(view, stamp, image);
            publisher.put(image)?;
        }
        self.frames += 1;
        Ok(())
    }
}
