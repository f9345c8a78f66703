//! The hardware of both sites as the software sees it, in ros2_control's shape: a
//! controller reads the state, computes, then writes a command, once per period, with
//! the time passed in. Backends — in-process simulation (`teleop-sim`), hardware reached
//! over the bus (`teleop-hardware-bus`), a real driver — implement the same traits, so
//! a controller cannot tell them apart.
//!
//! * [`ArmHardware<N>`]: a velocity-commanded arm of `N` joints (the PR2 chain has 7,
//!   the UR5 6);
//! * [`HandHardware`]: the Shadow hand's 17 finger joints and 5 fingertip sensors;
//! * [`Camera`]: a colour or depth image stream, newest frame only;
//! * [`WristTracker`]: a 6D wrist pose source (motion capture, IMU suit);
//! * [`OperatorPanel`]: the operator's pedals and switches.
//!
//! [`wire`] converts between these types and bus messages (joints matched by name).
//! [`safety`] is the last safety layer: [`SafeArm`] and [`SafeHand`] wrap a backend in
//! the process that owns it and filter every command (limits, end-effector speed,
//! command timeout), so no caller reaches the hardware unfiltered.

mod impedance;
pub mod safety;
pub mod velocity_driver;
pub mod wire;

use nalgebra::{Isometry3, SVector};
use teleop_msgs::Image;

pub use impedance::JointImpedance;
pub use safety::{ArmSafety, ArmSafetyConfig, HandSafety, HandSafetyConfig, SafeArm, SafeHand};

/// Number of actuated finger joints of the Shadow hand with BioTacs.
pub const FINGER_DOF: usize = 17;
/// Number of fingertip sensors.
pub const FINGERTIP_COUNT: usize = 5;

/// Measured state of an arm of `N` joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmState<const N: usize> {
    /// Time of the measurement, s (the hardware's clock).
    pub time_s: f64,
    pub position_rad: SVector<f64, N>,
    pub velocity_rad_s: SVector<f64, N>,
}

/// Joint velocity command for an arm. Zero means stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmCommand<const N: usize> {
    pub velocity_rad_s: SVector<f64, N>,
}

impl<const N: usize> ArmCommand<N> {
    /// Zero velocity.
    pub fn stop() -> Self {
        Self {
            velocity_rad_s: SVector::zeros(),
        }
    }

    /// True when every value is finite.
    pub fn is_finite(&self) -> bool {
        self.velocity_rad_s.iter().all(|v| v.is_finite())
    }
}

/// Measured state of the hand (17 finger joints) and its tactile sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandState {
    pub time_s: f64,
    pub position_rad: SVector<f64, FINGER_DOF>,
    pub velocity_rad_s: SVector<f64, FINGER_DOF>,
    /// Effort actually applied per joint, N m.
    pub effort_nm: SVector<f64, FINGER_DOF>,
    /// Normal contact force at each fingertip (ff, mf, rf, lf, th), N.
    pub fingertip_force_n: [f64; FINGERTIP_COUNT],
}

/// Command for the hand.
#[derive(Debug, Clone, Copy, PartialEq)]
// Copied every control period without allocating: the impedance stays inline.
#[allow(clippy::large_enum_variant)]
pub enum HandCommand {
    /// Joint torques, N m.
    Effort(SVector<f64, FINGER_DOF>),
    /// Position targets for the hand's own servo loop (like the real hand's position
    /// controllers), rad.
    Position(SVector<f64, FINGER_DOF>),
    /// A joint impedance the hardware evaluates in its own loop; see [`HandImpedance`].
    Impedance(HandImpedance),
}

/// A joint impedance for the hand's own real-time loop: every period until the next
/// command, with its newest measurement `q`, `q̇`, the hardware applies
///
/// ```text
/// τ_i = feedforward_i + stiffness_i (position_i - q_i) + damping_i (velocity_i - q̇_i)
/// τ_i ← clamp(τ_i, -max_effort_i, max_effort_i)
/// ```
///
/// ([`JointImpedance::effort_at`]), so the stiff part of a finger's loop (stiffness,
/// damping) never waits for the network: a controller across a bus sends gains and set
/// points, as with the joint impedance interfaces of torque-controlled arms. A real
/// Shadow hand driver evaluates it in its 1 kHz control loop, where the thesis's
/// controller ran. The same type the control laws produce (`teleop-control` builds it).
pub type HandImpedance = JointImpedance<FINGER_DOF>;

impl HandCommand {
    /// True when every value (every field of an impedance) is finite.
    pub fn is_finite(&self) -> bool {
        match self {
            HandCommand::Effort(v) | HandCommand::Position(v) => v.iter().all(|x| x.is_finite()),
            HandCommand::Impedance(z) => z.is_finite(),
        }
    }
}

/// The operator's pedals and switches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PedalState {
    /// Right pedal: the clutch of relative arm control.
    pub clutch: bool,
    /// Deadman switch held.
    pub enable: bool,
    /// Left pedal: stops the camera arm.
    pub camera_stop: bool,
    /// Scale of the operator's motion on the robot, (0, 1].
    pub motion_scale: f64,
}

/// Errors of a hardware backend.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HardwareError {
    #[error("hardware not connected: {0}")]
    NotConnected(String),
    #[error("no state received for {age_s:.3} s")]
    StaleState { age_s: f64 },
    #[error("hardware fault: {0}")]
    Fault(String),
    #[error("read-only handle: {0} takes no commands here")]
    ReadOnly(&'static str),
}

/// A velocity-commanded arm with `N` joints, joint order of its interface table
/// (`teleop_interfaces::joints`).
pub trait ArmHardware<const N: usize>: Send {
    /// Latest measured state at `now_s`.
    ///
    /// # Errors
    /// [`HardwareError`] when no fresh state is available.
    fn read(&mut self, now_s: f64) -> Result<ArmState<N>, HardwareError>;
    /// Sends a velocity command (applied until the next one, or until the hardware's
    /// own command timeout stops the arm).
    ///
    /// # Errors
    /// [`HardwareError`] if the command cannot be delivered.
    fn write(&mut self, now_s: f64, command: &ArmCommand<N>) -> Result<(), HardwareError>;
}

/// The Shadow hand's fingers.
pub trait HandHardware: Send {
    /// Latest measured state at `now_s`.
    ///
    /// # Errors
    /// [`HardwareError`] when no fresh state is available.
    fn read(&mut self, now_s: f64) -> Result<HandState, HardwareError>;
    /// Sends a command.
    ///
    /// # Errors
    /// [`HardwareError`] if the command cannot be delivered.
    fn write(&mut self, now_s: f64, command: &HandCommand) -> Result<(), HardwareError>;
}

/// What a camera delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraKind {
    /// `rgb8`, `bgr8` or `mono8`.
    Color,
    /// `16UC1` (mm) or `32FC1` (m).
    Depth,
}

impl CameraKind {
    /// Whether an image encoding fits this kind.
    pub fn accepts(self, encoding: &str) -> bool {
        match self {
            CameraKind::Color => matches!(encoding, "rgb8" | "bgr8" | "mono8"),
            CameraKind::Depth => matches!(encoding, "16UC1" | "32FC1"),
        }
    }
}

/// A camera: a stream of images of which only the newest matters (a consumer slower
/// than the camera skips frames, it never falls behind).
pub trait Camera: Send {
    /// Colour or depth.
    fn kind(&self) -> CameraKind;
    /// The newest image that arrived since the last call, `None` if none did. Older
    /// images that arrived in between are dropped and counted in [`Camera::dropped`].
    ///
    /// # Errors
    /// [`HardwareError::Fault`] when the newest image is malformed (its layout does not
    /// match its size and encoding, or its encoding not the camera's kind).
    fn read(&mut self, now_s: f64) -> Result<Option<Image>, HardwareError>;
    /// Images that arrived but were replaced by a newer one before [`Camera::read`]
    /// took them.
    fn dropped(&self) -> u64;
}

/// A 6D wrist tracker (motion capture, IMU suit).
pub trait WristTracker: Send {
    /// The wrist pose at `now_s` in the tracker's frame; `Ok(None)` when the tracker
    /// has no valid measurement (markers occluded).
    ///
    /// # Errors
    /// [`HardwareError`] when the tracker is lost.
    fn read(&mut self, now_s: f64) -> Result<Option<Isometry3<f64>>, HardwareError>;
}

/// The operator's pedals and switches.
pub trait OperatorPanel: Send {
    /// Their state at `now_s`.
    ///
    /// # Errors
    /// [`HardwareError`] when the device is lost (a robot must then stop).
    fn read(&mut self, now_s: f64) -> Result<PedalState, HardwareError>;
}
