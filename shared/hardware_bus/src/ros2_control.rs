//! An arm run by ros2_control on ROS 2 (rmw_zenoh), through its standard interfaces:
//! joint velocities to a forward command controller (`std_msgs/msg/Float64MultiArray`
//! on the controller's `commands` topic, one value per controller joint in the
//! controller's order), the measured state from the joint state broadcaster
//! (`sensor_msgs/msg/JointState` on `joint_states`, matched by joint name, in any
//! order, extra joints ignored).
//!
//! ros2_control's forward command controllers hold the last command forever. So this
//! side stops the arm itself: a watchdog thread sends zero velocity when no command has
//! been written for `command_timeout_s` (the owning process stalled, or stopped
//! calling [`ArmHardware::write`]), again every `command_timeout_s` while that lasts,
//! and once more when the backend is dropped. It cannot help when the owning process
//! dies: a real deployment also needs a controller-side timeout (see
//! `docs/ros2-control.md`).
//!
//! Like every backend, it is wrapped by the safety layer (`SafeArm`) in the process
//! that owns it; what it adds is the mapping and the zero-on-silence above.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use nalgebra::SVector;
use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusError, Publisher, SourcePolicy, Subscriber};
use teleop_hardware::wire::{self, Field};
use teleop_hardware::{ArmCommand, ArmHardware, ArmState, HardwareError};
use teleop_interfaces::{ArmInterface, Direction, Publishers, QosClass, Topic};
use teleop_msgs::{Float64MultiArray, JointState};

/// How the arm's ros2_control setup is reached (the robot site's configuration).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2ControlArmConfig {
    /// The forward velocity controller's command topic.
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

impl Default for Ros2ControlArmConfig {
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
}

impl Ros2ControlArmConfig {
    /// The robot's name of each interface joint, and where each interface joint goes in
    /// a command (index into the controller's joints), with the number of those.
    fn mapping<const N: usize>(
        &self,
        interface: &ArmInterface<N>,
    ) -> Result<([String; N], [usize; N], usize), Ros2ControlConfigError> {
        for (field, value) in [
            ("command_topic", &self.command_topic),
            ("state_topic", &self.state_topic),
        ] {
            let name = value.trim_matches('/');
            let valid = !name.is_empty()
                && name.split('/').all(|part| {
                    !part.is_empty()
                        && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                        && !part.starts_with(|c: char| c.is_ascii_digit())
                });
            if !valid {
                return Err(Ros2ControlConfigError::Topic {
                    field,
                    value: value.clone(),
                });
            }
        }
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

    /// Checks the configuration against `interface` without opening anything.
    ///
    /// # Errors
    /// [`Ros2ControlConfigError`] naming the field at fault.
    pub fn validate<const N: usize>(
        &self,
        interface: &ArmInterface<N>,
    ) -> Result<(), Ros2ControlConfigError> {
        self.mapping(interface).map(|_| ())
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
    #[error("starting the {arm} command watchdog: {message}")]
    Watchdog { arm: &'static str, message: String },
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
    /// Zero-velocity commands the watchdog sent.
    zeros_sent: AtomicU64,
}

impl Watch {
    fn since_epoch_us(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}

/// The arm of an interface table entry, run by ros2_control.
#[derive(Debug)]
pub struct Ros2ControlArm<const N: usize> {
    interface: ArmInterface<N>,
    robot_joints: [String; N],
    command_index: [usize; N],
    command_len: usize,
    state: Subscriber<JointState>,
    command: Arc<Publisher<Float64MultiArray>>,
    watch: Arc<Watch>,
    watchdog: Option<std::thread::JoinHandle<()>>,
    /// Newest state, its receive time, and the previous positions with their stamp
    /// (for velocities when the broadcaster sends none).
    latest: Option<(ArmState<N>, f64)>,
    previous: Option<(SVector<f64, N>, f64)>,
    stale_after_s: f64,
    bad_states: u64,
    newest_refusal: Option<String>,
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
        cfg: &Ros2ControlArmConfig,
    ) -> Result<Self, Ros2ControlError> {
        let (robot_joints, command_index, command_len) = cfg.mapping(interface)?;
        let command_topic = configured_topic::<Float64MultiArray>(
            &cfg.command_topic,
            QosClass::Control,
            interface.state.spec.rate_hz,
            "ros2_control forward command controller: joint velocities, rad/s",
        );
        let state_topic = configured_topic::<JointState>(
            &cfg.state_topic,
            QosClass::State,
            interface.state.spec.rate_hz,
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
        let timeout_us = (cfg.command_timeout_s * 1e6) as u64;
        let watchdog = {
            let (watch, command) = (Arc::clone(&watch), Arc::clone(&command));
            let zero = Float64MultiArray::flat(vec![0.0; command_len]);
            let name = interface.name;
            std::thread::Builder::new()
                .name(format!("{name}-ros2-control-watchdog"))
                .spawn(move || watchdog(&watch, &command, &zero, timeout_us, name))
                .map_err(|e| Ros2ControlError::Watchdog {
                    arm: name,
                    message: e.to_string(),
                })?
        };
        tracing::info!(
            arm = interface.name,
            command = %cfg.command_topic,
            state = %cfg.state_topic,
            state_from = %cfg.state_node,
            "arm driven through ros2_control"
        );
        Ok(Self {
            interface: *interface,
            robot_joints,
            command_index,
            command_len,
            state,
            command,
            watch,
            watchdog: Some(watchdog),
            latest: None,
            previous: None,
            stale_after_s: cfg.stale_after_s,
            bad_states: 0,
            newest_refusal: None,
        })
    }

    /// Joint states that could not be used (a joint missing, lengths, NaN).
    pub fn bad_states(&self) -> u64 {
        self.bad_states
    }

    /// Zero-velocity commands the watchdog sent because no command was written.
    pub fn watchdog_stops(&self) -> u64 {
        self.watch.zeros_sent.load(Ordering::Relaxed)
    }

    /// Why the newest refused joint state was refused.
    pub fn newest_refusal(&self) -> Option<&str> {
        self.newest_refusal.as_deref()
    }

    /// Counters for the owning node's status, under `prefix`.
    pub fn counters(&self, prefix: &str) -> Vec<(String, u64)> {
        let mut out = vec![
            (format!("{prefix}.bad_states"), self.bad_states),
            (format!("{prefix}.watchdog_stops"), self.watchdog_stops()),
        ];
        out.extend(self.state.named_counters());
        out
    }

    /// The state in `msg`, by the robot's joint names.
    fn convert(&mut self, msg: &JointState) -> Result<ArmState<N>, wire::WireError> {
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
        self.previous = Some((position, stamp_s));
        Ok(ArmState {
            time_s: stamp_s,
            position_rad: position,
            velocity_rad_s: velocity,
        })
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
                tracing::warn!(arm = name, "watchdog zero velocity not sent: {e}");
            }
        }
    }
    // The backend is gone: the arm must not keep the last command.
    if let Err(e) = command.put(zero) {
        tracing::warn!(arm = name, "final zero velocity not sent: {e}");
    }
}

impl<const N: usize> Drop for Ros2ControlArm<N> {
    fn drop(&mut self) {
        self.watch.stop.store(true, Ordering::Relaxed);
        if let Some(handle) = self.watchdog.take()
            && handle.join().is_err()
        {
            tracing::warn!(arm = self.interface.name, "the command watchdog panicked");
        }
    }
}

impl<const N: usize> ArmHardware<N> for Ros2ControlArm<N> {
    fn read(&mut self, now_s: f64) -> Result<ArmState<N>, HardwareError> {
        while let Some(r) = self.state.try_recv() {
            match self.convert(&r.msg) {
                Ok(mut s) => {
                    let received_s = r.receive_time_s();
                    // The robot's stamps are its clock; the controllers run on the bus's.
                    s.time_s = received_s;
                    self.latest = Some((s, received_s));
                }
                Err(e) => {
                    self.bad_states += 1;
                    let text = format!(
                        "{} joint state from ros2_control refused: {e}",
                        self.interface.name
                    );
                    tracing::debug!("{text}");
                    self.newest_refusal = Some(text);
                }
            }
        }
        let (state, at) = self.latest.ok_or_else(|| {
            HardwareError::NotConnected(format!(
                "no {} joint state received yet on /{}",
                self.interface.name,
                self.state.spec().name
            ))
        })?;
        let age_s = now_s - at;
        if age_s > self.stale_after_s {
            return Err(HardwareError::StaleState { age_s });
        }
        Ok(state)
    }

    fn write(&mut self, _now_s: f64, command: &ArmCommand<N>) -> Result<(), HardwareError> {
        if !command.is_finite() {
            return Err(HardwareError::Fault(format!(
                "non-finite {} velocity command",
                self.interface.name
            )));
        }
        let mut data = vec![0.0; self.command_len];
        for (i, &at) in self.command_index.iter().enumerate() {
            data[at] = command.velocity_rad_s[i];
        }
        self.command
            .put(&Float64MultiArray::flat(data))
            .map_err(|e| HardwareError::Fault(e.to_string()))?;
        self.watch
            .last_write_us
            .store(self.watch.since_epoch_us().max(1), Ordering::Relaxed);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use teleop_interfaces::hardware::PR2_ARM;

    #[test]
    fn the_default_maps_the_interface_joints_in_order() {
        let (robot, index, len) = Ros2ControlArmConfig::default()
            .mapping(&PR2_ARM)
            .expect("valid");
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
        let cfg = Ros2ControlArmConfig {
            command_joints: controller,
            joint_names: [(PR2_ARM.joints[6].to_owned(), "wrist_roll".to_owned())].into(),
            ..Ros2ControlArmConfig::default()
        };
        let (robot, index, len) = cfg.mapping(&PR2_ARM).expect("valid");
        assert_eq!(robot[6], "wrist_roll");
        assert_eq!(index, [6, 5, 4, 3, 2, 1, 0]);
        assert_eq!(len, 8);
    }

    #[test]
    fn bad_configurations_are_named() {
        let missing = Ros2ControlArmConfig {
            command_joints: vec!["a".into()],
            ..Ros2ControlArmConfig::default()
        };
        let e = missing.validate(&PR2_ARM).expect_err("joint missing");
        assert!(e.to_string().contains(PR2_ARM.joints[0]), "{e}");
        let unknown = Ros2ControlArmConfig {
            joint_names: [("elbow".to_owned(), "x".to_owned())].into(),
            ..Ros2ControlArmConfig::default()
        };
        assert!(matches!(
            unknown.validate(&PR2_ARM),
            Err(Ros2ControlConfigError::UnknownJoint(..))
        ));
        let topic = Ros2ControlArmConfig {
            command_topic: "/a b/commands".into(),
            ..Ros2ControlArmConfig::default()
        };
        assert!(matches!(
            topic.validate(&PR2_ARM),
            Err(Ros2ControlConfigError::Topic {
                field: "command_topic",
                ..
            })
        ));
        let timeout = Ros2ControlArmConfig {
            command_timeout_s: f64::NAN,
            ..Ros2ControlArmConfig::default()
        };
        assert!(matches!(
            timeout.validate(&PR2_ARM),
            Err(Ros2ControlConfigError::Duration { .. })
        ));
        let twice = Ros2ControlArmConfig {
            command_joints: PR2_ARM
                .joints
                .iter()
                .chain(&PR2_ARM.joints[..1])
                .map(|s| (*s).to_owned())
                .collect(),
            ..Ros2ControlArmConfig::default()
        };
        assert!(matches!(
            twice.validate(&PR2_ARM),
            Err(Ros2ControlConfigError::DuplicateJoint(_))
        ));
    }
}
