//! Robots run by ros2_control on ROS 2 (rmw_zenoh), through its standard interfaces:
//! commands to a forward command controller (`std_msgs/msg/Float64MultiArray` on the
//! controller's `commands` topic, one value per controller joint in the controller's
//! order), the measured state from the joint state broadcaster
//! (`sensor_msgs/msg/JointState` on `joint_states`, matched by joint name, in any
//! order, extra joints ignored).
//!
//! * [`Ros2ControlArm`]: joint velocities;
//! * [`Ros2ControlHand`]: joint efforts (a joint impedance is evaluated here, with the
//!   newest state, at every write) or joint positions, as the hand's controllers offer.
//!
//! ros2_control's forward command controllers hold the last command forever. So where
//! a held command keeps moving the robot (velocities, efforts) this side stops it
//! itself: a watchdog thread sends zeros when no command has been written for
//! `command_timeout_s` (the owning process stalled, or stopped calling `write`), again
//! every `command_timeout_s` while that lasts, and once more when the backend is
//! dropped. A held position command holds the fingers still and needs none. It cannot
//! help when the owning process dies: a real deployment also needs a controller-side
//! timeout (see `docs/ros2-control.md`).
//!
//! Like every backend, each is wrapped by the safety layer (`SafeArm`, `SafeHand`) in
//! the process that owns it; what they add is the mapping and the zero-on-silence.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use nalgebra::SVector;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusError, Publisher, SourcePolicy, Subscriber};
use teleop_hardware::wire::{self, Field};
use teleop_hardware::{
    ArmCommand, ArmHardware, ArmState, FINGER_DOF, HandCommand, HandHardware, HandImpedance,
    HandState, HardwareError,
};
use teleop_interfaces::{ArmInterface, Direction, HandInterface, Publishers, QosClass, Topic};
use teleop_msgs::{FingertipPressures, Float64MultiArray, JointState};

/// How a robot's ros2_control setup is reached (the robot site's configuration).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2ControlConfig {
    /// The forward command controller's command topic.
    pub command_topic: String,
    /// The controller's joints in its order (its `joints` parameter), by the robot's
    /// joint names; every command carries one value for each. Empty: the interface's
    /// joints (after `joint_names`) in the interface's order.
    pub command_joints: Vec<String>,
    /// The joint state broadcaster's topic.
    pub state_topic: String,
    /// The only node whose joint states are taken (the broadcaster's node name, matched
    /// by its publisher's GID as rmw_zenoh computes it); empty: any publisher.
    pub state_node: String,
    /// The robot's name for an interface joint where the two differ
    /// (`interface joint -> robot joint`).
    pub joint_names: BTreeMap<String, String>,
    /// A state older than this is stale (the arm stops), s.
    pub stale_after_s: f64,
    /// Zero velocity is sent when no command was written for this long, s.
    pub command_timeout_s: f64,
}

impl Default for Ros2ControlConfig {
    fn default() -> Self {
        Self {
            command_topic: "/forward_velocity_controller/commands".into(),
            command_joints: Vec::new(),
            state_topic: "/joint_states".into(),
            state_node: "joint_state_broadcaster".into(),
            joint_names: BTreeMap::new(),
            stale_after_s: 0.1,
            command_timeout_s: 0.1,
        }
    }
}

/// Why a configuration cannot drive the arm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Ros2ControlConfigError {
    #[error("ros2_control.{field}: must be a ROS 2 topic name, got {value:?}")]
    Topic { field: &'static str, value: String },
    #[error("ros2_control.joint_names: `{0}` is no joint of the {1} interface")]
    UnknownJoint(String, &'static str),
    #[error(
        "ros2_control.command_joints: the {interface} joint `{joint}` (robot name `{robot}`) \
         is not among the controller's joints {joints:?}"
    )]
    JointNotCommanded {
        interface: &'static str,
        joint: &'static str,
        robot: String,
        joints: Vec<String>,
    },
    #[error("ros2_control.command_joints: `{0}` is listed twice")]
    DuplicateJoint(String),
    #[error("ros2_control.{field}: must be finite and > 0, got {value}")]
    Duration { field: &'static str, value: f64 },
    #[error("finger_inertia_kg_m2: must be in [1e-7, 1], got {0}")]
    FingerInertia(f64),
}

/// `value` must be a ROS 2 topic name (slash-separated parts of letters, digits and `_`,
/// none starting with a digit).
fn check_topic(field: &'static str, value: &str) -> Result<(), Ros2ControlConfigError> {
    let name = value.trim_matches('/');
    let valid = !name.is_empty()
        && name.split('/').all(|part| {
            !part.is_empty()
                && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                && !part.starts_with(|c: char| c.is_ascii_digit())
        });
    if valid {
        Ok(())
    } else {
        Err(Ros2ControlConfigError::Topic {
            field,
            value: value.to_owned(),
        })
    }
}

/// An interface's name and joints.
#[derive(Debug, Clone, Copy)]
struct Joints<'a, const N: usize> {
    name: &'static str,
    joints: &'a [&'static str; N],
}

impl Ros2ControlConfig {
    /// The robot's name of each interface joint, and where each interface joint goes in
    /// a command (index into the controller's joints), with the number of those.
    fn mapping<const N: usize>(
        &self,
        interface: Joints<'_, N>,
    ) -> Result<([String; N], [usize; N], usize), Ros2ControlConfigError> {
        check_topic("command_topic", &self.command_topic)?;
        check_topic("state_topic", &self.state_topic)?;
        for (field, value) in [
            ("stale_after_s", self.stale_after_s),
            ("command_timeout_s", self.command_timeout_s),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(Ros2ControlConfigError::Duration { field, value });
            }
        }
        if let Some(unknown) = self
            .joint_names
            .keys()
            .find(|k| !interface.joints.contains(&k.as_str()))
        {
            return Err(Ros2ControlConfigError::UnknownJoint(
                unknown.clone(),
                interface.name,
            ));
        }
        let robot: [String; N] = std::array::from_fn(|i| {
            let joint = interface.joints[i];
            self.joint_names
                .get(joint)
                .cloned()
                .unwrap_or_else(|| joint.to_owned())
        });
        let controller: Vec<String> = if self.command_joints.is_empty() {
            robot.to_vec()
        } else {
            self.command_joints.clone()
        };
        for (i, j) in controller.iter().enumerate() {
            if controller[..i].contains(j) {
                return Err(Ros2ControlConfigError::DuplicateJoint(j.clone()));
            }
        }
        let mut index = [0usize; N];
        for (i, name) in robot.iter().enumerate() {
            index[i] = controller.iter().position(|c| c == name).ok_or_else(|| {
                Ros2ControlConfigError::JointNotCommanded {
                    interface: interface.name,
                    joint: interface.joints[i],
                    robot: name.clone(),
                    joints: controller.clone(),
                }
            })?;
        }
        Ok((robot, index, controller.len()))
    }

    /// Checks the configuration against an arm interface without opening anything.
    ///
    /// # Errors
    /// [`Ros2ControlConfigError`] naming the field at fault.
    pub fn validate_arm<const N: usize>(
        &self,
        interface: &ArmInterface<N>,
    ) -> Result<(), Ros2ControlConfigError> {
        self.mapping(Joints {
            name: interface.name,
            joints: &interface.joints,
        })
        .map(|_| ())
    }

    /// Checks the configuration against the hand interface without opening anything.
    ///
    /// # Errors
    /// [`Ros2ControlConfigError`] naming the field at fault.
    pub fn validate_hand(&self, interface: &HandInterface) -> Result<(), Ros2ControlConfigError> {
        self.mapping(Joints {
            name: interface.name,
            joints: &interface.joints,
        })
        .map(|_| ())
    }
}

/// Errors opening the backend.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Ros2ControlError {
    #[error(transparent)]
    Config(#[from] Ros2ControlConfigError),
    #[error(transparent)]
    Bus(#[from] BusError),
    #[error("starting the {robot} command watchdog: {message}")]
    Watchdog {
        robot: &'static str,
        message: String,
    },
}

/// A topic named by configuration. `TopicSpec` names are `'static` (the topic table's
/// are constants); a backend is opened once per process, so the few bytes of its two
/// names are leaked on purpose.
fn configured_topic<T: teleop_msgs::Message>(
    name: &str,
    qos: QosClass,
    rate_hz: f64,
    doc: &'static str,
) -> Topic<T> {
    let name: &'static str = Box::leak(name.trim_matches('/').to_owned().into_boxed_str());
    Topic::new(
        name,
        Direction::RemoteInternal,
        rate_hz,
        qos,
        // The robot's clock is not the bus clock: staleness is judged on receipt.
        None,
        Publishers::EveryNode,
        doc,
    )
}

/// The watchdog's view of the commands: when the last one was written, and whether
/// the backend is still there.
#[derive(Debug)]
struct Watch {
    epoch: Instant,
    /// Microseconds since `epoch` of the last written command (0: none yet).
    last_write_us: AtomicU64,
    stop: AtomicBool,
    /// Zero commands the watchdog sent.
    zeros_sent: AtomicU64,
}

impl Watch {
    fn since_epoch_us(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}

/// The newest state of the robot's joints, by interface joint.
#[derive(Debug, Clone, Copy)]
struct Measured<const N: usize> {
    /// Receive time on the bus clock, s.
    received_s: f64,
    position: SVector<f64, N>,
    velocity: SVector<f64, N>,
    /// Zero when the broadcaster sends no efforts.
    effort: SVector<f64, N>,
}

/// One robot's link to its ros2_control: the command publisher (and, where a held
/// command keeps it moving, the zero-on-silence watchdog), the joint state subscriber,
/// the joint mapping.
#[derive(Debug)]
struct Link<const N: usize> {
    name: &'static str,
    robot_joints: [String; N],
    command_index: [usize; N],
    command_len: usize,
    state: Subscriber<JointState>,
    command: Arc<Publisher<Float64MultiArray>>,
    watch: Arc<Watch>,
    watchdog: Option<std::thread::JoinHandle<()>>,
    latest: Option<Measured<N>>,
    /// The previous positions with their stamp (velocities when the broadcaster sends
    /// none).
    previous: Option<(SVector<f64, N>, f64)>,
    /// The broadcaster's period, s: a moving average of its stamps' differences.
    state_period_s: Option<f64>,
    stale_after_s: f64,
    bad_states: u64,
    /// The newest refusal's text not yet taken by the owner ([`Ros2ControlArm::take_refusal`]).
    /// Behind a lock: taken through the safety layer's read-only view of the backend.
    newest_refusal: Mutex<Option<String>>,
}

impl<const N: usize> Link<N> {
    async fn open(
        bus: &Bus,
        interface: Joints<'_, N>,
        cfg: &Ros2ControlConfig,
        rate_hz: f64,
        what: &'static str,
        zero_on_silence: bool,
    ) -> Result<Self, Ros2ControlError> {
        let (robot_joints, command_index, command_len) = cfg.mapping(interface)?;
        let name = interface.name;
        let command_topic = configured_topic::<Float64MultiArray>(
            &cfg.command_topic,
            QosClass::Control,
            rate_hz,
            what,
        );
        let state_topic = configured_topic::<JointState>(
            &cfg.state_topic,
            QosClass::State,
            rate_hz,
            "ros2_control joint state broadcaster",
        );
        let policy = if cfg.state_node.is_empty() {
            SourcePolicy::Any
        } else {
            SourcePolicy::Node(cfg.state_node.clone())
        };
        let state = bus
            .subscriber_with(&state_topic, bus.guard_settings(&state_topic.spec), policy)
            .await?;
        let command = Arc::new(bus.publisher(&command_topic).await?);
        let watch = Arc::new(Watch {
            epoch: Instant::now(),
            last_write_us: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            zeros_sent: AtomicU64::new(0),
        });
        let watchdog = if zero_on_silence {
            let timeout_us = (cfg.command_timeout_s * 1e6) as u64;
            let (watch, command) = (Arc::clone(&watch), Arc::clone(&command));
            let zero = Float64MultiArray::flat(vec![0.0; command_len]);
            Some(
                std::thread::Builder::new()
                    .name(format!("{name}-ros2-control-watchdog"))
                    .spawn(move || watchdog(&watch, &command, &zero, timeout_us, name))
                    .map_err(|e| Ros2ControlError::Watchdog {
                        robot: name,
                        message: e.to_string(),
                    })?,
            )
        } else {
            None
        };
        tracing::info!(
            robot = name,
            command = %cfg.command_topic,
            state = %cfg.state_topic,
            state_from = %cfg.state_node,
            "driven through ros2_control"
        );
        Ok(Self {
            name,
            robot_joints,
            command_index,
            command_len,
            state,
            command,
            watch,
            watchdog,
            latest: None,
            previous: None,
            state_period_s: None,
            stale_after_s: cfg.stale_after_s,
            bad_states: 0,
            newest_refusal: Mutex::new(None),
        })
    }

    /// The state in `msg`, by the robot's joint names, received at `received_s`.
    fn convert(
        &mut self,
        msg: &JointState,
        received_s: f64,
    ) -> Result<Measured<N>, wire::WireError> {
        let names: [&str; N] = std::array::from_fn(|i| self.robot_joints[i].as_str());
        let position = wire::joint_vector(msg, &names, Field::Position)?;
        let stamp_s = msg.header.stamp.as_secs_f64();
        let velocity = if msg.velocity.is_empty() {
            // A broadcaster without velocity interfaces: differences of positions.
            match self.previous {
                Some((q, t)) if stamp_s > t => (position - q) / (stamp_s - t),
                _ => SVector::zeros(),
            }
        } else {
            wire::joint_vector(msg, &names, Field::Velocity)?
        };
        let effort = if msg.effort.is_empty() {
            SVector::zeros()
        } else {
            wire::joint_vector(msg, &names, Field::Effort)?
        };
        if let Some((_, t)) = self.previous
            && stamp_s > t
            && stamp_s - t < self.stale_after_s
        {
            let dt = stamp_s - t;
            self.state_period_s = Some(match self.state_period_s {
                Some(p) => p + 0.1 * (dt - p),
                None => dt,
            });
        }
        self.previous = Some((position, stamp_s));
        Ok(Measured {
            received_s,
            position,
            velocity,
            effort,
        })
    }

    /// Keeps `text` as the newest refusal.
    fn refused(&mut self, text: String) {
        *self
            .newest_refusal
            .get_mut()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(text);
    }

    fn take_refusal(&self) -> Option<String> {
        self.newest_refusal
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .take()
    }

    /// Takes the joint states that arrived; the newest fresh one.
    fn read(&mut self, now_s: f64) -> Result<Measured<N>, HardwareError> {
        while let Some(r) = self.state.try_recv() {
            match self.convert(&r.msg, r.receive_time_s()) {
                Ok(m) => self.latest = Some(m),
                Err(e) => {
                    self.bad_states += 1;
                    let text = format!("{} joint state from ros2_control refused: {e}", self.name);
                    tracing::debug!("{text}");
                    self.refused(text);
                }
            }
        }
        let m = self.latest.ok_or_else(|| {
            HardwareError::NotConnected(format!(
                "no {} joint state received yet on /{}",
                self.name,
                self.state.spec().name
            ))
        })?;
        let age_s = now_s - m.received_s;
        if age_s > self.stale_after_s {
            return Err(HardwareError::StaleState { age_s });
        }
        Ok(m)
    }

    /// Sends one value per interface joint, in the controller's order.
    fn send(&mut self, values: &SVector<f64, N>, what: &str) -> Result<(), HardwareError> {
        if !values.iter().all(|v| v.is_finite()) {
            return Err(HardwareError::Fault(format!(
                "non-finite {} {what} command",
                self.name
            )));
        }
        let mut data = vec![0.0; self.command_len];
        for (i, &at) in self.command_index.iter().enumerate() {
            data[at] = values[i];
        }
        self.command
            .put(&Float64MultiArray::flat(data))
            .map_err(|e| HardwareError::Fault(e.to_string()))?;
        self.watch
            .last_write_us
            .store(self.watch.since_epoch_us().max(1), Ordering::Relaxed);
        Ok(())
    }

    fn counters(&self, prefix: &str) -> Vec<(String, u64)> {
        let mut out = vec![
            (format!("{prefix}.bad_states"), self.bad_states),
            (
                format!("{prefix}.watchdog_stops"),
                self.watch.zeros_sent.load(Ordering::Relaxed),
            ),
        ];
        out.extend(self.state.named_counters());
        out
    }
}

impl<const N: usize> Drop for Link<N> {
    fn drop(&mut self) {
        self.watch.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.watchdog.take()
            && handle.join().is_err()
        {
            tracing::warn!(robot = self.name, "the command watchdog panicked");
        }
    }
}

fn watchdog(
    watch: &Watch,
    command: &Publisher<Float64MultiArray>,
    zero: &Float64MultiArray,
    timeout_us: u64,
    name: &str,
) {
    let tick = Duration::from_micros((timeout_us / 4).clamp(1_000, 50_000));
    let mut last_zero_us = 0u64;
    while !watch.stop.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let now = watch.since_epoch_us();
        let last = watch.last_write_us.load(Ordering::Relaxed);
        // Nothing written yet: nothing to stop (the controller holds its start-up zero).
        if last == 0 || now.saturating_sub(last) < timeout_us {
            continue;
        }
        if now.saturating_sub(last_zero_us.max(last)) >= timeout_us {
            last_zero_us = now;
            watch.zeros_sent.fetch_add(1, Ordering::Relaxed);
            if let Err(e) = command.put(zero) {
                tracing::warn!(robot = name, "watchdog zero command not sent: {e}");
            }
        }
    }
    // The backend is gone: the robot must not keep the last command.
    if let Err(e) = command.put(zero) {
        tracing::warn!(robot = name, "final zero command not sent: {e}");
    }
}

/// The arm of an interface table entry, run by ros2_control through a forward
/// velocity controller.
#[derive(Debug)]
pub struct Ros2ControlArm<const N: usize> {
    link: Link<N>,
}

impl<const N: usize> Ros2ControlArm<N> {
    /// Opens the command publisher and the state subscriber on `bus` and starts the
    /// zero-on-silence watchdog.
    ///
    /// # Errors
    /// [`Ros2ControlError`]: the configuration does not fit `interface`, or a
    /// declaration failed.
    pub async fn new(
        bus: &Bus,
        interface: &ArmInterface<N>,
        cfg: &Ros2ControlConfig,
    ) -> Result<Self, Ros2ControlError> {
        let joints = Joints {
            name: interface.name,
            joints: &interface.joints,
        };
        Ok(Self {
            link: Link::open(
                bus,
                joints,
                cfg,
                interface.state.spec.rate_hz,
                "ros2_control forward velocity controller: joint velocities, rad/s",
                true,
            )
            .await?,
        })
    }

    /// The newest refused joint state's reason since the last call, once (as the
    /// hardware endpoints hand over theirs); through the safety layer's read-only view.
    pub fn take_refusal(&self) -> Option<String> {
        self.link.take_refusal()
    }

    /// Counters for the owning node's status, under `prefix`.
    pub fn counters(&self, prefix: &str) -> Vec<(String, u64)> {
        self.link.counters(prefix)
    }
}

impl<const N: usize> ArmHardware<N> for Ros2ControlArm<N> {
    fn read(&mut self, now_s: f64) -> Result<ArmState<N>, HardwareError> {
        let m = self.link.read(now_s)?;
        // Stamped on receipt: the robot's stamps are its clock, the controllers run on
        // the bus's.
        Ok(ArmState {
            time_s: m.received_s,
            position_rad: m.position,
            velocity_rad_s: m.velocity,
        })
    }

    fn write(&mut self, _now_s: f64, command: &ArmCommand<N>) -> Result<(), HardwareError> {
        self.link.send(&command.velocity_rad_s, "velocity")
    }
}

/// Which of the hand's forward command controllers the commands go to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HandControllerMode {
    /// Joint efforts, N m (an effort controller): effort commands as they are, a joint
    /// impedance evaluated here at every write with the newest state. An effort
    /// interface has no position loop: a position command, which is what the safety
    /// layer sends to hold the hand when commands stop, goes out as zero effort (the
    /// fingers are no longer driven), counted.
    Effort,
    /// Joint positions, rad (a position controller): position commands as they are,
    /// a joint impedance's set point (the hand's own position loop does the rest).
    Position,
}

/// The hand's ros2_control setup.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2ControlHandConfig {
    pub mode: HandControllerMode,
    /// The smallest joint inertia of the fingers, armature included, kg m^2 (default:
    /// the project's Shadow hand model). In effort mode the joint impedance is a loop
    /// closed here, sampled at the joint state broadcaster's period `T`: its gains are
    /// held to `damping <= 0.5 I / T` and `stiffness <= 0.09 I / T^2` (natural
    /// frequency times `T` at most 0.3), below which it stays stable; higher gains are
    /// lowered to those, counted (`impedance_gains_limited`). docs/ros2-control.md.
    pub finger_inertia_kg_m2: f64,
    /// The hand driver's fingertip forces (`teleop_msgs/msg/FingertipPressures`, N);
    /// empty: none, the forces read zero.
    pub tactile_topic: String,
    pub ros2_control: Ros2ControlConfig,
}

impl Default for Ros2ControlHandConfig {
    fn default() -> Self {
        Self {
            mode: HandControllerMode::Effort,
            finger_inertia_kg_m2: 2e-4,
            tactile_topic: String::new(),
            ros2_control: Ros2ControlConfig {
                command_topic: "/hand_effort_controller/commands".into(),
                ..Ros2ControlConfig::default()
            },
        }
    }
}

impl Ros2ControlHandConfig {
    /// Checks the configuration against `interface` without opening anything.
    ///
    /// # Errors
    /// [`Ros2ControlConfigError`] naming the field at fault.
    pub fn validate(&self, interface: &HandInterface) -> Result<(), Ros2ControlConfigError> {
        self.ros2_control.validate_hand(interface)?;
        if !self.tactile_topic.is_empty() {
            check_topic("tactile_topic", &self.tactile_topic)?;
        }
        if !(1e-7..=1.0).contains(&self.finger_inertia_kg_m2) {
            return Err(Ros2ControlConfigError::FingerInertia(
                self.finger_inertia_kg_m2,
            ));
        }
        Ok(())
    }
}

/// The Shadow hand run by ros2_control through an effort or a position controller.
#[derive(Debug)]
pub struct Ros2ControlHand {
    link: Link<FINGER_DOF>,
    mode: HandControllerMode,
    tactile: Option<Subscriber<FingertipPressures>>,
    forces: [f64; 5],
    /// The newest state read, for the impedance evaluated at the next write.
    last: Option<Measured<FINGER_DOF>>,
    /// Position commands (the safety layer's hold) sent as zero effort in effort mode.
    positions_as_zero_effort: u64,
    finger_inertia_kg_m2: f64,
    /// Writes whose impedance gains were lowered to what the sampled loop holds.
    impedance_gains_limited: u64,
}

impl Ros2ControlHand {
    /// Opens the links on `bus` (the zero-effort watchdog in effort mode).
    ///
    /// # Errors
    /// [`Ros2ControlError`]: the configuration does not fit `interface`, or a
    /// declaration failed.
    pub async fn new(
        bus: &Bus,
        interface: &HandInterface,
        cfg: &Ros2ControlHandConfig,
    ) -> Result<Self, Ros2ControlError> {
        cfg.validate(interface)?;
        let joints = Joints {
            name: interface.name,
            joints: &interface.joints,
        };
        let (what, zero_on_silence) = match cfg.mode {
            HandControllerMode::Effort => ("ros2_control hand effort controller: N m", true),
            HandControllerMode::Position => ("ros2_control hand position controller: rad", false),
        };
        let rate_hz = interface.state.spec.rate_hz;
        let link = Link::open(
            bus,
            joints,
            &cfg.ros2_control,
            rate_hz,
            what,
            zero_on_silence,
        )
        .await?;
        let tactile = if cfg.tactile_topic.is_empty() {
            None
        } else {
            let topic = configured_topic::<FingertipPressures>(
                &cfg.tactile_topic,
                QosClass::State,
                rate_hz,
                "the hand driver's fingertip forces",
            );
            Some(bus.subscriber(&topic).await?)
        };
        Ok(Self {
            link,
            mode: cfg.mode,
            tactile,
            forces: [0.0; 5],
            last: None,
            positions_as_zero_effort: 0,
            finger_inertia_kg_m2: cfg.finger_inertia_kg_m2,
            impedance_gains_limited: 0,
        })
    }

    /// The newest refused joint state's (or fingertip forces') reason since the last
    /// call, once.
    pub fn take_refusal(&self) -> Option<String> {
        self.link.take_refusal()
    }

    /// Counters for the owning node's status, under `prefix`.
    pub fn counters(&self, prefix: &str) -> Vec<(String, u64)> {
        let mut out = self.link.counters(prefix);
        out.push((
            format!("{prefix}.positions_as_zero_effort"),
            self.positions_as_zero_effort,
        ));
        out.push((
            format!("{prefix}.impedance_gains_limited"),
            self.impedance_gains_limited,
        ));
        out
    }
}

impl HandHardware for Ros2ControlHand {
    fn read(&mut self, now_s: f64) -> Result<HandState, HardwareError> {
        if let Some(tactile) = &self.tactile {
            while let Some(r) = tactile.try_recv() {
                let v = r.msg.values();
                if v.iter().all(|f| f.is_finite()) {
                    self.forces = v;
                } else {
                    self.link.bad_states += 1;
                    let text = format!("{} fingertip forces refused: not finite", self.link.name);
                    self.link.refused(text);
                }
            }
        }
        let m = self.link.read(now_s)?;
        self.last = Some(m);
        Ok(HandState {
            time_s: m.received_s,
            position_rad: m.position,
            velocity_rad_s: m.velocity,
            effort_nm: m.effort,
            fingertip_force_n: self.forces,
        })
    }

    fn write(&mut self, now_s: f64, command: &HandCommand) -> Result<(), HardwareError> {
        let name = self.link.name;
        match (self.mode, command) {
            (HandControllerMode::Effort, HandCommand::Effort(tau)) => self.link.send(tau, "effort"),
            (HandControllerMode::Position, HandCommand::Position(q)) => {
                self.link.send(q, "position")
            }
            (HandControllerMode::Position, HandCommand::Impedance(z)) => {
                self.link.send(&z.position_rad, "position")
            }
            (HandControllerMode::Effort, HandCommand::Impedance(z)) => {
                // Our side closes the impedance loop, with the newest measurement.
                let m = match self.last {
                    Some(m) if now_s - m.received_s <= self.link.stale_after_s => m,
                    _ => {
                        return Err(HardwareError::NotConnected(format!(
                            "{name}: no fresh joint state to evaluate the impedance at"
                        )));
                    }
                };
                let period_s = self.link.state_period_s.unwrap_or(self.link.stale_after_s);
                let (held, limited) = sampled_loop_gains(z, self.finger_inertia_kg_m2, period_s);
                if limited {
                    if self.impedance_gains_limited == 0 {
                        tracing::warn!(
                            hand = name,
                            period_ms = period_s * 1e3,
                            max_stiffness = held.stiffness_nm_rad.max(),
                            max_damping = held.damping_nm_s_rad.max(),
                            "impedance gains lowered to what a loop sampled at the joint \
                             states' period holds (counted: impedance_gains_limited)"
                        );
                    }
                    self.impedance_gains_limited += 1;
                }
                let tau = held.effort_at(&m.position, &m.velocity);
                self.link.send(&tau, "effort")
            }
            (HandControllerMode::Effort, HandCommand::Position(_)) => {
                // The safety layer's hold (or a position command) on an effort
                // interface, which has no position loop: the fingers are no longer
                // driven (zero effort), counted.
                self.positions_as_zero_effort += 1;
                self.link.send(&SVector::zeros(), "effort")
            }
            (HandControllerMode::Position, HandCommand::Effort(_)) => {
                Err(HardwareError::Fault(format!(
                    "{name}: an effort command, but the ros2_control controller takes positions"
                )))
            }
        }
    }
}

/// `z` with its gains held to what a joint impedance closed here, on joint states that
/// come every `period_s`, keeps stable on a joint of inertia `inertia_kg_m2`:
/// `damping <= 0.5 I / T`, `stiffness <= 0.09 I / T^2`; and whether any was lowered.
pub fn sampled_loop_gains(
    z: &HandImpedance,
    inertia_kg_m2: f64,
    period_s: f64,
) -> (HandImpedance, bool) {
    let max_damping = 0.5 * inertia_kg_m2 / period_s;
    let max_stiffness = 0.09 * inertia_kg_m2 / (period_s * period_s);
    let mut held = *z;
    held.damping_nm_s_rad = z.damping_nm_s_rad.map(|d| d.min(max_damping));
    held.stiffness_nm_rad = z.stiffness_nm_rad.map(|k| k.min(max_stiffness));
    let limited =
        held.damping_nm_s_rad != z.damping_nm_s_rad || held.stiffness_nm_rad != z.stiffness_nm_rad;
    (held, limited)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_effort_loop_gains_are_held_to_the_sampling_period() {
        let mut z = HandImpedance {
            position_rad: SVector::zeros(),
            velocity_rad_s: SVector::zeros(),
            stiffness_nm_rad: SVector::repeat(1.0),
            damping_nm_s_rad: SVector::repeat(0.05),
            feedforward_nm: SVector::zeros(),
            max_effort_nm: SVector::repeat(0.3),
        };
        // 500 Hz on the model's 2e-4 kg m^2: up to 0.05 N m s/rad and 4.5 N m/rad.
        let (held, limited) = sampled_loop_gains(&z, 2e-4, 0.002);
        assert!(!limited);
        assert_eq!(held, z);
        z.stiffness_nm_rad[3] = 20.0;
        z.damping_nm_s_rad[4] = 0.3;
        let (held, limited) = sampled_loop_gains(&z, 2e-4, 0.002);
        assert!(limited);
        assert!((held.stiffness_nm_rad[3] - 4.5).abs() < 1e-9);
        assert!((held.damping_nm_s_rad[4] - 0.05).abs() < 1e-9);
        assert_eq!(held.stiffness_nm_rad[0], 1.0);
        assert_eq!(held.position_rad, z.position_rad);
        // 100 Hz: the initial gains too.
        let (held, _) = sampled_loop_gains(&z, 2e-4, 0.01);
        assert!((held.damping_nm_s_rad[0] - 0.01).abs() < 1e-12);
        assert!((held.stiffness_nm_rad[0] - 0.18).abs() < 1e-12);
    }
    use teleop_interfaces::hardware::{PR2_ARM, SHADOW_HAND};

    fn arm() -> Joints<'static, 7> {
        Joints {
            name: PR2_ARM.name,
            joints: &PR2_ARM.joints,
        }
    }

    #[test]
    fn the_hand_configuration_names_its_tactile_topic() {
        assert!(
            Ros2ControlHandConfig::default()
                .validate(&SHADOW_HAND)
                .is_ok()
        );
        let bad = Ros2ControlHandConfig {
            tactile_topic: "/bio tac".into(),
            ..Ros2ControlHandConfig::default()
        };
        assert!(matches!(
            bad.validate(&SHADOW_HAND),
            Err(Ros2ControlConfigError::Topic {
                field: "tactile_topic",
                ..
            })
        ));
    }

    #[test]
    fn the_default_maps_the_interface_joints_in_order() {
        let (robot, index, len) = Ros2ControlConfig::default().mapping(arm()).expect("valid");
        assert_eq!(robot[0], PR2_ARM.joints[0]);
        assert_eq!(index, [0, 1, 2, 3, 4, 5, 6]);
        assert_eq!(len, 7);
    }

    #[test]
    fn controller_order_and_renamed_joints_are_followed() {
        let mut controller: Vec<String> = PR2_ARM
            .joints
            .iter()
            .rev()
            .map(|s| (*s).to_owned())
            .collect();
        controller[0] = "wrist_roll".into();
        controller.push("torso_lift_joint".into());
        let cfg = Ros2ControlConfig {
            command_joints: controller,
            joint_names: [(PR2_ARM.joints[6].to_owned(), "wrist_roll".to_owned())].into(),
            ..Ros2ControlConfig::default()
        };
        let (robot, index, len) = cfg.mapping(arm()).expect("valid");
        assert_eq!(robot[6], "wrist_roll");
        assert_eq!(index, [6, 5, 4, 3, 2, 1, 0]);
        assert_eq!(len, 8);
    }

    #[test]
    fn bad_configurations_are_named() {
        let missing = Ros2ControlConfig {
            command_joints: vec!["a".into()],
            ..Ros2ControlConfig::default()
        };
        let e = missing.validate_arm(&PR2_ARM).expect_err("joint missing");
        assert!(e.to_string().contains(PR2_ARM.joints[0]), "{e}");
        let unknown = Ros2ControlConfig {
            joint_names: [("elbow".to_owned(), "x".to_owned())].into(),
            ..Ros2ControlConfig::default()
        };
        assert!(matches!(
            unknown.validate_arm(&PR2_ARM),
            Err(Ros2ControlConfigError::UnknownJoint(..))
        ));
        let topic = Ros2ControlConfig {
            command_topic: "/a b/commands".into(),
            ..Ros2ControlConfig::default()
        };
        assert!(matches!(
            topic.validate_arm(&PR2_ARM),
            Err(Ros2ControlConfigError::Topic {
                field: "command_topic",
                ..
            })
        ));
        let timeout = Ros2ControlConfig {
            command_timeout_s: f64::NAN,
            ..Ros2ControlConfig::default()
        };
        assert!(matches!(
            timeout.validate_arm(&PR2_ARM),
            Err(Ros2ControlConfigError::Duration { .. })
        ));
        let twice = Ros2ControlConfig {
            command_joints: PR2_ARM
                .joints
                .iter()
                .chain(&PR2_ARM.joints[..1])
                .map(|s| (*s).to_owned())
                .collect(),
            ..Ros2ControlConfig::default()
        };
        assert!(matches!(
            twice.validate_arm(&PR2_ARM),
            Err(Ros2ControlConfigError::DuplicateJoint(_))
        ));
    }
}
