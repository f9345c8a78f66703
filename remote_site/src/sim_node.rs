//! The simulator process: owns the simulated world (PR2 arm, Shadow hand, objects) and
//! offers it to the controllers over the `teleop/hw/...` topics, as a robot driver
//! would (the way Gazebo stands in for hardware). Steps in real time; commands that fail
//! to convert are counted and ignored (the previous command stays in force, and the arm
//! stops on its own when commands stop arriving).

use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeConfig, StatusReporter, topics};
use teleop_msgs::Lifecycle;
use tokio::time::MissedTickBehavior;

use crate::sim::{
    CameraViewsConfig, CupGraspConfig, SceneCameras, TouchingTaskConfig, View, World, WorldConfig,
};
use crate::wire;

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
}

/// Arm posture the node starts in: elbow bent, away from the straight-arm singularity,
/// so relative motion is possible in every direction.
pub const WORKING_POSTURE_RAD: [f64; 7] = [-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1];

/// Configuration of the `remote_sim` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimNodeConfig {
    pub node_name: String,
    pub scene: SceneKind,
    /// Rate of the state messages, Hz.
    pub state_rate_hz: f64,
    /// World settings for `scene = "free"`.
    pub world: WorldConfig,
    pub touching: TouchingTaskConfig,
    pub cup_grasp: CupGraspConfig,
    /// The top and side camera views, rendered from the world and published on
    /// `teleop/hw/camera/{top,side}/image` as a camera driver would.
    pub cameras: CameraViewsConfig,
    pub bus: BusConfig,
}

impl Default for SimNodeConfig {
    fn default() -> Self {
        Self {
            node_name: "remote_sim".into(),
            scene: SceneKind::Touching,
            state_rate_hz: topics::SIM_ARM_STATE.spec.rate_hz,
            world: WorldConfig::default(),
            touching: TouchingTaskConfig {
                arm_posture_rad: WORKING_POSTURE_RAD,
                ..TouchingTaskConfig::default()
            },
            cup_grasp: CupGraspConfig::default(),
            cameras: CameraViewsConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for SimNodeConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
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
        Ok(())
    }
}

/// Builds the configured world.
///
/// # Errors
/// The simulator's configuration errors.
pub fn build_world(cfg: &SimNodeConfig) -> anyhow::Result<World> {
    Ok(match cfg.scene {
        SceneKind::Free => World::new(cfg.world.clone())?,
        SceneKind::Touching => World::touching_task(&cfg.touching)?,
        SceneKind::CupGrasp => World::cup_grasp(&cfg.cup_grasp)?,
    })
}

/// Runs the simulator until `duration` elapses (forever if `None`) or Ctrl-C.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: SimNodeConfig, duration: Option<Duration>) -> anyhow::Result<()> {
    let mut world = build_world(&cfg)?;
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let arm_cmd = bus.subscriber(&topics::SIM_ARM_COMMAND).await?;
    let hand_cmd = bus.subscriber(&topics::SIM_HAND_COMMAND).await?;
    let arm_state = bus.publisher(&topics::SIM_ARM_STATE).await?;
    let hand_state = bus.publisher(&topics::SIM_HAND_STATE).await?;
    let tactile = bus.publisher(&topics::SIM_HAND_TACTILE).await?;
    let status = StatusReporter::new(&bus).await?;
    let mut cameras = CameraViews::open(&bus, &cfg.cameras, &world).await?;
    tracing::info!(node = %cfg.node_name, scene = ?cfg.scene, "simulator running in real time");

    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.state_rate_hz));
    tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut status_tick = tokio::time::interval(Duration::from_secs(1));
    // Disabled cameras never tick; the fallback only keeps an invalid rate from panicking.
    let camera_period =
        Duration::try_from_secs_f64(1.0 / cfg.cameras.rate_hz).unwrap_or(Duration::from_secs(1));
    let mut camera_tick = tokio::time::interval(camera_period);
    camera_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let stop = teleop_bus::node::stop_signal(duration);
    tokio::pin!(stop);
    let start = Instant::now();
    let sim_start = world.time_s();
    let mut bad_commands = 0u64;
    let mut last_error = String::new();
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = status_tick.tick() => {
                let counters = vec![
                    ("sim.time_ms".to_owned(), (world.time_s() * 1e3) as u64),
                    ("sim.bad_commands".to_owned(), bad_commands),
                    ("sim.camera_frames".to_owned(), cameras.as_ref().map_or(0, |c| c.frames)),
                ];
                let _ = status.report(Lifecycle::Active, &counters, &last_error);
            }
            _ = tick.tick() => {
                while let Some(r) = arm_cmd.try_recv() {
                    match wire::arm_command(&r.msg) {
                        Ok(c) => world.command_arm(&c.velocity_rad_s),
                        Err(e) => { bad_commands += 1; last_error = format!("arm command: {e}"); }
                    }
                }
                while let Some(r) = hand_cmd.try_recv() {
                    match wire::hand_command(&r.msg) {
                        Ok(c) => world.command_hand(&c),
                        Err(e) => { bad_commands += 1; last_error = format!("hand command: {e}"); }
                    }
                }
                // Catch up with the wall clock.
                let lag = start.elapsed().as_secs_f64() - (world.time_s() - sim_start);
                if lag > 0.0 {
                    world.step(lag.min(0.1));
                }
                let hs = world.hand_state();
                for r in [
                    arm_state.put(&wire::arm_state_msg(&world.arm_state())),
                    hand_state.put(&wire::hand_state_msg(&hs)),
                ] {
                    if let Err(e) = r { last_error = e.to_string(); }
                }
                if let Err(e) = tactile.put(&wire::tactile_msg(&hs)) { last_error = e.to_string(); }
            }
            _ = camera_tick.tick(), if cameras.is_some() => {
                if let Some(c) = cameras.as_mut()
                    && let Err(e) = c.publish(&world)
                {
                    last_error = format!("cameras: {e}");
                }
            }
        }
    }
    drop((
        arm_cmd, hand_cmd, arm_state, hand_state, tactile, status, cameras,
    ));
    bus.close().await?;
    Ok(())
}

/// The two camera views as the simulator publishes them: rendered from the world at the
/// camera rate, newest only (a slow subscriber misses frames, never delays them).
#[derive(Debug)]
struct CameraViews {
    cameras: SceneCameras,
    publishers: [teleop_bus::Publisher<teleop_msgs::Image>; 2],
    /// One message per view, reused between frames.
    images: [teleop_msgs::Image; 2],
    frames: u64,
}

impl CameraViews {
    /// `None` when the cameras are disabled.
    async fn open(
        bus: &Bus,
        config: &CameraViewsConfig,
        world: &World,
    ) -> anyhow::Result<Option<Self>> {
        if !config.enabled {
            return Ok(None);
        }
        Ok(Some(Self {
            cameras: SceneCameras::new(world, config)?,
            publishers: [
                bus.publisher(&topics::SIM_CAMERA_TOP).await?,
                bus.publisher(&topics::SIM_CAMERA_SIDE).await?,
            ],
            images: Default::default(),
            frames: 0,
        }))
    }

    fn publish(&mut self, world: &World) -> anyhow::Result<()> {
        self.cameras.render(world)?;
        let stamp = teleop_msgs::Time::now();
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
