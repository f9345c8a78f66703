//! The operator-site simulator process (`local_sim`), the counterpart of the robot
//! site's `remote_sim`: it owns the simulated operator world
//! ([`teleop_sim::operator_site`]) and offers it to the site's nodes over the hardware
//! topics, as the devices' drivers would:
//!
//! | device | topic | rate |
//! |---|---|---|
//! | motion capture (marker on the back of the hand, capture frame) | [`topics::HW_MOCAP_MARKER`] | 320 Hz, none while occluded |
//! | pedal box and enable switch | [`topics::HW_PEDALS`] | 50 Hz |
//! | UR5 state / velocity commands | [`UR5_ARM`] (`teleop/hw/ur5/...`) | every tick / from `camera_arm` only |
//! | SR300 depth camera on the UR5 | [`topics::HW_HAND_DEPTH`] | 30 Hz |
//!
//! plus the simulation's ground truth for the end-of-run metrics:
//! [`topics::SIM_OPERATOR_HAND_POSE`] (the true hand frame) and
//! [`topics::SIM_OPERATOR_SHADOW_JOINTS`] (the true fingers retargeted to the Shadow
//! hand), the latter stamped with the capture time of the depth frame it belongs to, so
//! an inferred posture can be paired with its truth by stamp.
//!
//! Every sample is stamped with the node clock at the moment it was measured (the
//! capture time), so every later stage measures its latency from there.
//!
//! It owns the UR5, so the last safety layer of the camera arm lives here: the UR5 is
//! wrapped in a [`SafeArm`] (joint speed and acceleration, position margins, camera
//! speed <= 0.25 m/s, brake after 0.1 s without a command) and its endpoint takes
//! commands only from the `camera_arm` node.

use std::time::Duration;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher, Subscriber};
use teleop_hardware::safety::{ArmSafety, ArmSafetyConfig};
use teleop_hardware::{ArmCommand, ArmHardware, SafeArm};
use teleop_hardware_bus::ArmEndpoint;
use teleop_interfaces::hardware::{PR2_ARM, UR5_ARM};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{
    CompressedImage, Header, Image, JointState, Lifecycle, NodeStatus, OperatorInput, PoseStamped,
    TFMessage, Time,
};
use teleop_node::{FinalReport, Node, NodeConfig, NodeErrors, Periodic, SchedulingConfig};
use teleop_sim::operator_site::watching::{
    Phase, RobotEye, ScenePercept, ViewGate, WatchingCounters,
};
use teleop_sim::operator_site::{
    MocapReading, OperatorModel, OperatorSiteConfig, OperatorWorld, Reclutch, SharedOperatorWorld,
    SimUr5, UR5_DOF, WatchingOperator,
};

use teleop_hardware::wire::pose_msg;

/// The hardware safety layer of the simulated UR5.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LocalSimSafetyConfig {
    /// The only node whose UR5 commands are taken.
    pub ur5_controller_node: String,
    pub ur5: ArmSafetyConfig,
}

impl Default for LocalSimSafetyConfig {
    fn default() -> Self {
        Self {
            ur5_controller_node: UR5_ARM.controller_node.into(),
            ur5: ArmSafetyConfig {
                // The camera's optical centre and a point 10 cm ahead of the flange
                // side (the camera body).
                tool_points_m: vec![[0.0, 0.0, 0.0], [0.0, 0.0, -0.1]],
                ..ArmSafetyConfig::default()
            },
        }
    }
}

/// Configuration of the `local_sim` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LocalSimConfig {
    pub node_name: String,
    /// Pedal publishing rate, Hz.
    pub pedal_rate_hz: f64,
    /// Ground-truth hand pose publishing rate, Hz.
    pub truth_rate_hz: f64,
    /// The simulated operator world (task, hand, motion capture, UR5, camera). The
    /// node ticks at the motion capture's rate.
    pub operator_site: OperatorSiteConfig,
    pub safety: LocalSimSafetyConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    pub bus: BusConfig,
}

impl Default for LocalSimConfig {
    fn default() -> Self {
        Self {
            node_name: "local_sim".into(),
            pedal_rate_hz: topics::HW_PEDALS.spec.rate_hz,
            truth_rate_hz: topics::SIM_OPERATOR_HAND_POSE.spec.rate_hz,
            operator_site: OperatorSiteConfig::default(),
            safety: LocalSimSafetyConfig::default(),
            // On the depth frame's path to the hand (docs/local-site.md).
            scheduling: SchedulingConfig::realtime(teleop_node::sched::LATENCY_PATH_PRIORITY),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for LocalSimConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        teleop_control::check_ranges(
            "local_sim",
            &[
                ("pedal_rate_hz", self.pedal_rate_hz, 1.0, 1000.0),
                ("truth_rate_hz", self.truth_rate_hz, 1.0, 1000.0),
            ],
        )?;
        self.operator_site.validate()?;
        self.safety
            .ur5
            .validate()
            .map_err(|e| format!("safety.ur5: {e}"))?;
        if self.safety.ur5_controller_node.is_empty() {
            return Err("safety.ur5_controller_node must name a node".into());
        }
        Ok(())
    }
}

/// Counters of the simulator node.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct LocalSimCounters {
    pub marker_samples: u64,
    pub marker_dropouts: u64,
    pub marker_glitches: u64,
    pub depth_frames: u64,
    /// Depth frames in which every keypoint of the hand was inside the image.
    pub frames_hand_fully_in_view: u64,
    /// Depth frames with no keypoint of the hand in the image.
    pub frames_hand_out_of_view: u64,
    pub hardware_errors: u64,
    /// Ticks that took more than 50 ms (each logged with where the time went).
    pub slow_ticks: u64,
}

/// The simulator node.
pub struct LocalSimNode {
    period: Duration,
    world: SharedOperatorWorld,
    ur5: SafeArm<UR5_DOF, SimUr5>,
    ur5_endpoint: ArmEndpoint<UR5_DOF>,
    marker_pub: Publisher<PoseStamped>,
    pedals_pub: Publisher<OperatorInput>,
    depth_pub: Option<Publisher<Image>>,
    truth_pose_pub: Publisher<PoseStamped>,
    truth_joints_pub: Publisher<JointState>,
    pedals_due: Periodic,
    camera_due: Periodic,
    truth_due: Periodic,
    /// Node-clock time of sim time 0.
    start_s: Option<f64>,
    /// Sim time of the next motion-capture sample.
    next_marker_s: Option<f64>,
    counters: LocalSimCounters,
    /// Wall time of the last depth render, µs.
    last_render_us: u64,
    errors: NodeErrors,
    /// The last tick stepped the world and published the UR5's state.
    serving: bool,
    /// The operator who watches the display (`operator = "watching"`).
    watcher: Option<Watcher>,
    /// Either operator's foot on the clutch after a safety stop of the arm, and the
    /// arm controller's status as it arrives here (what the display shows).
    reclutch: Reclutch,
    statuses: Subscriber<NodeStatus>,
}

/// The watching operator and what it watches: the feedback joint states, the camera
/// views' stamps and the objects' poses up to the newest view.
struct Watcher {
    operator: WatchingOperator,
    gate: ViewGate,
    eye: RobotEye,
    arm_states: Subscriber<JointState>,
    hand_states: Subscriber<JointState>,
    views: [Subscriber<CompressedImage>; 2],
    objects: Subscriber<TFMessage>,
    /// The newest ground truth received (not limited by the views), for the log of
    /// perceived vs true.
    newest_truth: Option<ScenePercept>,
    views_received: u64,
    bad_input: u64,
    /// Largest distance between the object as perceived and as last received, mm.
    max_perceived_error_mm: f64,
}

fn scene_of(msg: &TFMessage) -> Option<ScenePercept> {
    let stamp_s = msg.transforms.first()?.header.stamp.as_secs_f64();
    let objects = msg
        .transforms
        .iter()
        .map(|t| {
            let v = &t.transform.translation;
            let pose = teleop_msgs::Pose {
                position: teleop_msgs::Point {
                    x: v.x,
                    y: v.y,
                    z: v.z,
                },
                orientation: t.transform.rotation,
            };
            (
                t.child_frame_id.clone(),
                teleop_hardware::wire::isometry(&pose),
            )
        })
        .collect();
    Some(ScenePercept { stamp_s, objects })
}

impl Watcher {
    async fn new(cfg: &OperatorSiteConfig, bus: &Bus) -> anyhow::Result<Self> {
        Ok(Self {
            operator: WatchingOperator::new(
                cfg.watching.clone(),
                cfg.motion_scale,
                cfg.start_delay_s,
            )
            .map_err(anyhow::Error::msg)?,
            gate: ViewGate::new(),
            eye: RobotEye::new()?,
            arm_states: bus.subscriber(&topics::PR2_JOINT_STATES).await?,
            hand_states: bus.subscriber(&topics::SHADOW_JOINT_STATES).await?,
            views: [
                bus.subscriber(&topics::REMOTE_CAMERA_TOP).await?,
                bus.subscriber(&topics::REMOTE_CAMERA_SIDE).await?,
            ],
            objects: bus.subscriber(&topics::SIM_ROBOT_OBJECT_POSES).await?,
            newest_truth: None,
            views_received: 0,
            bad_input: 0,
            max_perceived_error_mm: 0.0,
        })
    }

    /// Takes in what arrived and returns the operator's sample for `now_s`.
    fn step(&mut self, now_s: f64) -> (teleop_sim::operator_site::TaskSample, Option<String>) {
        let mut error = None;
        while let Some(r) = self.objects.try_recv() {
            match scene_of(&r.msg) {
                Some(scene) => {
                    self.newest_truth = Some(scene.clone());
                    self.gate.object_poses(scene);
                }
                None => self.bad_input += 1,
            }
        }
        for sub in &self.views {
            while let Some(r) = sub.try_recv() {
                self.views_received += 1;
                self.gate.view_received(r.msg.header.stamp.as_secs_f64());
            }
        }
        while let Some(scene) = self.gate.take_visible() {
            self.operator.perceive_scene(now_s, scene);
        }
        while let Some(r) = self.hand_states.try_recv() {
            if let Err(e) = self.eye.hand_joints(&r.msg.name, &r.msg.position) {
                self.bad_input += 1;
                error = Some(e);
            }
        }
        while let Some(r) = self.arm_states.try_recv() {
            match self.eye.arm_joints(
                r.msg.header.stamp.as_secs_f64(),
                &r.msg.name,
                &r.msg.position,
            ) {
                Ok(p) => self.operator.perceive_robot(r.receive_time_s(), p),
                Err(e) => {
                    self.bad_input += 1;
                    error = Some(e);
                }
            }
        }
        let sample = self.operator.step(now_s);
        // The object as perceived against the newest ground truth received.
        let object = self.operator.object_name();
        let off_mm = match (self.operator.perceived_scene(), &self.newest_truth) {
            (Some(seen), Some(truth)) => match (seen.object(object), truth.object(object)) {
                (Some(a), Some(b)) => (a.translation.vector - b.translation.vector).norm() * 1e3,
                _ => f64::NAN,
            },
            _ => f64::NAN,
        };
        if off_mm.is_finite() {
            self.max_perceived_error_mm = self.max_perceived_error_mm.max(off_mm);
        }
        for d in self.operator.take_decisions() {
            tracing::info!(
                phase = d.phase.name(),
                t_s = d.t_s,
                perceived_vs_true_mm = off_mm,
                "operator: {}",
                d.what
            );
        }
        (sample, error)
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let WatchingCounters {
            robot_percepts,
            scene_percepts,
            submovements,
            grasp_attempts,
            goals_not_reached,
        } = self.operator.counters();
        let phase = self.operator.phase();
        vec![
            ("operator.phase".to_owned(), phase.index()),
            ("operator.done".to_owned(), u64::from(phase == Phase::Done)),
            (
                "operator.gave_up".to_owned(),
                u64::from(phase == Phase::GaveUp),
            ),
            ("operator.robot_percepts".to_owned(), robot_percepts),
            ("operator.scene_percepts".to_owned(), scene_percepts),
            ("operator.views_received".to_owned(), self.views_received),
            ("operator.submovements".to_owned(), submovements),
            ("operator.grasp_attempts".to_owned(), grasp_attempts),
            (
                "operator.placement".to_owned(),
                self.operator.placement() as u64,
            ),
            ("operator.goals_not_reached".to_owned(), goals_not_reached),
            ("operator.bad_input".to_owned(), self.bad_input),
            (
                "operator.max_perceived_error_mm".to_owned(),
                // Non-negative, a few hundred at most.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                {
                    self.max_perceived_error_mm.round() as u64
                },
            ),
        ]
    }
}

impl std::fmt::Debug for LocalSimNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LocalSimNode")
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

impl LocalSimNode {
    /// Builds the world and declares the devices on `bus`.
    ///
    /// # Errors
    /// World or safety configuration errors; bus declarations.
    pub async fn new(cfg: &LocalSimConfig, bus: &Bus) -> anyhow::Result<Self> {
        let world = OperatorWorld::new(cfg.operator_site.clone())?;
        let chain = world.ur5_chain().clone();
        let world = std::sync::Arc::new(std::sync::Mutex::new(world));
        let safety = ArmSafety::new(chain, cfg.safety.ur5.clone())?;
        let camera = &cfg.operator_site.camera;
        let watcher = match cfg.operator_site.operator {
            OperatorModel::Scripted => None,
            OperatorModel::Watching => Some(Watcher::new(&cfg.operator_site, bus).await?),
        };
        tracing::info!(task = cfg.operator_site.task.name(), operator = ?cfg.operator_site.operator,
            ur5_from = %cfg.safety.ur5_controller_node, "operator-site simulator running in real time");
        Ok(Self {
            period: Duration::from_secs_f64(1.0 / cfg.operator_site.mocap.rate_hz),
            ur5: SafeArm::new(SimUr5::new(world.clone()), safety),
            world,
            ur5_endpoint: ArmEndpoint::new(bus, &UR5_ARM, &cfg.safety.ur5_controller_node).await?,
            marker_pub: bus.publisher(&topics::HW_MOCAP_MARKER).await?,
            pedals_pub: bus.publisher(&topics::HW_PEDALS).await?,
            depth_pub: if camera.enabled {
                Some(bus.publisher(&topics::HW_HAND_DEPTH).await?)
            } else {
                None
            },
            truth_pose_pub: bus.publisher(&topics::SIM_OPERATOR_HAND_POSE).await?,
            truth_joints_pub: bus.publisher(&topics::SIM_OPERATOR_SHADOW_JOINTS).await?,
            pedals_due: Periodic::at_rate(cfg.pedal_rate_hz),
            camera_due: Periodic::at_rate(camera.rate_hz),
            truth_due: Periodic::at_rate(cfg.truth_rate_hz),
            start_s: None,
            next_marker_s: None,
            counters: LocalSimCounters::default(),
            last_render_us: 0,
            errors: NodeErrors::new(),
            serving: false,
            watcher,
            reclutch: Reclutch::new(cfg.operator_site.reclutch.clone())
                .map_err(anyhow::Error::msg)?,
            statuses: bus.subscriber(&topics::NODE_STATUS).await?,
        })
    }

    /// The world (ground truth).
    pub fn world(&self) -> &SharedOperatorWorld {
        &self.world
    }

    /// A failure of the part `what` at `now_s` (current while it keeps failing).
    fn fail(&mut self, what: &'static str, e: impl std::fmt::Display, now_s: f64) {
        self.counters.hardware_errors += 1;
        self.errors.event(what, format!("{what}: {e}"), now_s);
    }

    fn pose_stamped(now_s: f64, frame: &str, pose: &Isometry3<f64>) -> Option<PoseStamped> {
        pose_msg(pose).map(|pose| PoseStamped {
            header: Header::new(Time::from_secs_f64(now_s), frame),
            pose,
        })
    }

    fn publish_depth(&mut self, world: &mut OperatorWorld, now_s: f64) -> anyhow::Result<()> {
        let Some(publisher) = &self.depth_pub else {
            return Ok(());
        };
        let started = std::time::Instant::now();
        let view = world.hand_in_view()?;
        let k = world.intrinsics();
        let depth = world.render_depth()?;
        let image = Image::depth_mm(
            Header::new(Time::from_secs_f64(now_s), "camera_optical_frame"),
            k.width(),
            k.height(),
            depth,
        );
        self.last_render_us = u64::try_from(started.elapsed().as_micros()).unwrap_or(u64::MAX);
        // The frame goes on the bus as soon as it exists; the true fingers at its
        // capture time (retargeting them takes about a millisecond) follow, with the
        // frame's send time as their source timestamp, so the report measures "frame on
        // the bus -> targets" from the frame's own send time.
        let sent_ns = publisher.now_ns();
        publisher.put_at(&image, sent_ns)?;
        let joints = world.shadow_joints()?;
        self.truth_joints_pub.put_at(
            &JointState::positions(
                Header::new(Time::from_secs_f64(now_s), ""),
                &SHADOW_FINGER_JOINTS,
                &joints,
            ),
            sent_ns,
        )?;
        self.counters.depth_frames += 1;
        if view.fully {
            self.counters.frames_hand_fully_in_view += 1;
        }
        if view.keypoints == 0 {
            self.counters.frames_hand_out_of_view += 1;
        }
        Ok(())
    }
}

impl Node for LocalSimNode {
    fn period(&self) -> Duration {
        self.period
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        // The camera arm's command, through the safety layer (a period without one is
        // filtered too: the command timeout).
        let ur5 = match self.ur5_endpoint.take_command() {
            Some(c) => self.ur5.write(now_s, &c),
            None => self.ur5.idle(now_s),
        };
        if let Some(text) = self.ur5_endpoint.take_refusal() {
            self.errors.event("ur5 command", text, now_s);
        }
        if let Err(e) = ur5 {
            self.fail("ur5", e, now_s);
        }
        let start = *self.start_s.get_or_insert(now_s);
        let world = self.world.clone();
        let Ok(mut world) = world.lock() else {
            self.serving = false;
            self.fail("world", "lock poisoned", now_s);
            return;
        };
        let tick_started = std::time::Instant::now();
        // Catch up with the clock (at most 0.1 s per tick after a stall).
        let lag = (now_s - start) - world.time_s();
        if lag > 0.0 {
            world.step(lag.min(0.1));
        }
        let world_ms = tick_started.elapsed().as_secs_f64() * 1e3;
        // The watching operator acts on what has reached the site so far.
        if let Some(watcher) = &mut self.watcher {
            let (sample, error) = watcher.step(now_s);
            world.drive(sample);
            if let Some(e) = error {
                let text = format!("operator's view: {e}");
                self.errors.event("operator's view", text, now_s);
            }
        }
        let operator_ms = tick_started.elapsed().as_secs_f64() * 1e3 - world_ms;
        // Motion capture: every sample due since the last tick, each stamped with its
        // own capture time (a late tick does not change the capture rate).
        let period = world.mocap_period_s();
        let sim_now = world.time_s();
        let next = self.next_marker_s.get_or_insert(sim_now);
        let mut due = Vec::new();
        while *next <= sim_now + 1e-9 {
            due.push(*next);
            *next += period;
        }
        // After a long stall, only the last 0.1 s of samples are sent.
        let skip = due.len().saturating_sub((0.1 / period).ceil() as usize);
        for t in due.into_iter().skip(skip) {
            let capture_s = start + t;
            match world.measure_marker_at(t) {
                MocapReading::Marker { pose, glitch } => {
                    self.counters.marker_samples += 1;
                    if glitch {
                        self.counters.marker_glitches += 1;
                    }
                    if let Some(msg) = Self::pose_stamped(capture_s, "mocap", &pose)
                        && let Err(e) = self.marker_pub.put(&msg)
                    {
                        self.fail("mocap", e, now_s);
                    }
                }
                MocapReading::Dropout => self.counters.marker_dropouts += 1,
            }
        }
        // The UR5's encoders, stamped with the node clock as a driver would.
        let mut state = world.ur5_state();
        state.time_s = now_s;
        self.serving = match self.ur5_endpoint.publish_state(&state) {
            Ok(()) => true,
            Err(e) => {
                self.fail("ur5 state", e, now_s);
                false
            }
        };
        // The arm controller's status as the display shows it: a safety stop is
        // answered by letting go of the clutch and pressing it again.
        while let Some(r) = self.statuses.try_recv() {
            if r.msg.node_name == PR2_ARM.controller_node {
                let faulted = r.msg.lifecycle() == Some(Lifecycle::Fault);
                self.reclutch.arm_report(r.receive_time_s(), faulted);
            }
        }
        let intended = world.pedals();
        let reclutches = self.reclutch.counts().reclutches;
        let clutch = self.reclutch.pedal(now_s, intended.clutch);
        if self.reclutch.counts().reclutches > reclutches {
            tracing::info!(
                reclutches = self.reclutch.counts().reclutches,
                "operator: the display shows the arm stopped (its controller in Fault); \
                 letting go of the clutch to press it again"
            );
        }
        if self.pedals_due.due(now_s) {
            let msg = OperatorInput {
                header: Header::new(Time::from_secs_f64(now_s), ""),
                clutch,
                enable: intended.enable,
                camera_stop: intended.camera_stop,
                motion_scale: intended.motion_scale,
            };
            if let Err(e) = self.pedals_pub.put(&msg) {
                self.fail("pedals", e, now_s);
            }
        }
        if self.truth_due.due(now_s)
            && let Some(msg) = Self::pose_stamped(now_s, "ur5_base_link", &world.hand_pose())
            && let Err(e) = self.truth_pose_pub.put(&msg)
        {
            self.fail("ground truth", e, now_s);
        }
        let depth_started = std::time::Instant::now();
        if self.camera_due.due(now_s)
            && let Err(e) = self.publish_depth(&mut world, now_s)
        {
            self.fail("depth camera", e, now_s);
        }
        let tick_ms = tick_started.elapsed().as_secs_f64() * 1e3;
        if tick_ms > 50.0 {
            self.counters.slow_ticks += 1;
            tracing::warn!(
                tick_ms,
                world_ms,
                operator_ms,
                depth_ms = depth_started.elapsed().as_secs_f64() * 1e3,
                "slow tick"
            );
        }
    }

    /// Inactive until the world first steps and the UR5's state goes out; Active while
    /// it does; Fault while the world cannot step or the UR5's state cannot be published
    /// (the camera arm's controller then sees no hardware).
    fn state(&self) -> Lifecycle {
        crate::serving_state(self.serving, self.start_s.is_some())
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let (sim_ms, reps) = self
            .world
            .lock()
            .map(|w| {
                // Non-negative and far below 2^64 ms.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let ms = (w.time_s() * 1e3) as u64;
                (ms, w.repetitions_done())
            })
            .unwrap_or((0, 0));
        let c = &self.counters;
        let mut out = vec![
            ("sim.time_ms".to_owned(), sim_ms),
            // The watching operator's one job counts as a repetition once it is over.
            (
                "sim.task_repetitions".to_owned(),
                self.watcher.as_ref().map_or(reps, |w| {
                    u64::from(matches!(w.operator.phase(), Phase::Done | Phase::GaveUp))
                }),
            ),
            ("sim.hardware_errors".to_owned(), c.hardware_errors),
            ("sim.slow_ticks".to_owned(), c.slow_ticks),
            ("mocap.samples".to_owned(), c.marker_samples),
            ("mocap.dropouts".to_owned(), c.marker_dropouts),
            ("mocap.glitches".to_owned(), c.marker_glitches),
            ("camera.frames".to_owned(), c.depth_frames),
            (
                "camera.frames_hand_fully_in_view".to_owned(),
                c.frames_hand_fully_in_view,
            ),
            (
                "camera.frames_hand_out_of_view".to_owned(),
                c.frames_hand_out_of_view,
            ),
            ("camera.render_us".to_owned(), self.last_render_us),
        ];
        if let Some(w) = &self.watcher {
            out.extend(w.counters());
        }
        let r = self.reclutch.counts();
        out.push(("operator.reclutches".to_owned(), r.reclutches));
        out.push(("operator.reclutch_gave_up".to_owned(), r.gave_up));
        out.extend(self.ur5_endpoint.counters());
        out.extend(self.ur5.safety().counters().named("safety.ur5"));
        out
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    /// The UR5 brakes (zero velocity).
    fn shutdown(&mut self, now_s: f64) {
        if let Err(e) = self.ur5.write(now_s, &ArmCommand::stop()) {
            tracing::warn!("stopping the UR5: {e}");
        }
    }
}

/// Runs the simulator on the system clock until `duration` elapses (forever if `None`)
/// or SIGINT/SIGTERM.
///
/// # Errors
/// Bus or configuration errors.
pub async fn run(cfg: LocalSimConfig, duration: Option<Duration>) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = LocalSimNode::new(&cfg, &bus).await?;
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_is_valid_and_fields_are_named() {
        LocalSimConfig::default().validate().expect("valid");
        let mut bad = LocalSimConfig::default();
        bad.operator_site.mocap.rate_hz = 0.0;
        assert!(bad.validate().unwrap_err().contains("mocap.rate_hz"));
        let typo = toml::from_str::<LocalSimConfig>("[operator_site]\ntaks = \"pouring\"\n")
            .expect_err("unknown field");
        assert!(typo.to_string().contains("taks"), "{typo}");
        let cfg: LocalSimConfig =
            toml::from_str("[operator_site]\ntask = \"pouring\"\n").expect("parses");
        assert_eq!(cfg.operator_site.task.name(), "pouring");
    }
}
