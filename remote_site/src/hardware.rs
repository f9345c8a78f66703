//! Hardware interfaces of the robot site, in ros2_control's shape: a controller reads the
//! state, computes, then writes a command, once per control period. Simulated backends
//! (in-process for tests, or a simulator process reached over the bus, as Gazebo stands
//! in for hardware) and real drivers implement the same traits, so a controller cannot
//! tell them apart.
//!
//! Joint order everywhere is the order of the name constants below.

use nalgebra::SVector;
use teleop_msgs::Image;

/// The 7 joints the arm controller drives: the PR2 right arm's 5 joints, then the Shadow
/// hand's 2 wrist joints (the hand replaces the PR2 wrist; thesis ch. 6.2.3).
pub const ARM_JOINTS: [&str; 7] = teleop_kinematics::robots::pr2::ARM_JOINTS;

/// The 17 finger joints the hand controller drives (the 5 J1 joints are fixed at 20 deg
/// by the BioTac sensors; the wrist joints belong to the arm chain).
pub const FINGER_JOINTS: [&str; 17] = [
    "rh_FFJ4", "rh_FFJ3", "rh_FFJ2", "rh_MFJ4", "rh_MFJ3", "rh_MFJ2", "rh_RFJ4", "rh_RFJ3",
    "rh_RFJ2", "rh_LFJ5", "rh_LFJ4", "rh_LFJ3", "rh_LFJ2", "rh_THJ5", "rh_THJ4", "rh_THJ3",
    "rh_THJ2",
];

/// Fingertip order of tactile readings.
pub const FINGERTIPS: [&str; 5] = ["ff", "mf", "rf", "lf", "th"];

/// The two flexion joints of each finger ([`FINGERTIPS`] order) that curl it toward
/// the palm: J3 and J2, for the thumb THJ4 and THJ2.
pub const FLEXION_JOINTS: [[&str; 2]; 5] = [
    ["rh_FFJ3", "rh_FFJ2"],
    ["rh_MFJ3", "rh_MFJ2"],
    ["rh_RFJ3", "rh_RFJ2"],
    ["rh_LFJ3", "rh_LFJ2"],
    ["rh_THJ4", "rh_THJ2"],
];

/// Measured state of the arm (7 joints).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmState {
    /// Time of the measurement, seconds (hardware clock).
    pub time_s: f64,
    pub position_rad: SVector<f64, 7>,
    pub velocity_rad_s: SVector<f64, 7>,
}

/// Joint velocity command for the arm. Zero means stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmCommand {
    pub velocity_rad_s: SVector<f64, 7>,
}

impl ArmCommand {
    pub fn stop() -> Self {
        Self {
            velocity_rad_s: SVector::zeros(),
        }
    }
}

/// Measured state of the hand (17 finger joints) and its tactile sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandState {
    pub time_s: f64,
    pub position_rad: SVector<f64, 17>,
    pub velocity_rad_s: SVector<f64, 17>,
    /// Effort actually applied per joint, N m.
    pub effort_nm: SVector<f64, 17>,
    /// Normal contact force at each fingertip (ff, mf, rf, lf, th), N.
    pub fingertip_force_n: [f64; 5],
}

/// Command for the hand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HandCommand {
    /// Joint torques, N m (clamped by the hardware to its maximum).
    Effort(SVector<f64, 17>),
    /// Position targets for the hand's own servo loop (like the real hand's position
    /// controllers), rad.
    Position(SVector<f64, 17>),
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
}

/// The arm as the controller sees it.
pub trait ArmHardware: Send {
    /// Latest measured state.
    ///
    /// # Errors
    /// [`HardwareError`] when no fresh state is available.
    fn read(&mut self) -> Result<ArmState, HardwareError>;
    /// Sends a velocity command (applied until the next one, or until the hardware's
    /// own command timeout stops the arm).
    ///
    /// # Errors
    /// [`HardwareError`] if the command cannot be delivered.
    fn write(&mut self, command: &ArmCommand) -> Result<(), HardwareError>;
}

/// The hand as the controller sees it.
pub trait HandHardware: Send {
    /// Latest measured state.
    ///
    /// # Errors
    /// [`HardwareError`] when no fresh state is available.
    fn read(&mut self) -> Result<HandState, HardwareError>;
    /// Sends a command.
    ///
    /// # Errors
    /// [`HardwareError`] if the command cannot be delivered.
    fn write(&mut self, command: &HandCommand) -> Result<(), HardwareError>;
}

/// A camera as its consumers see it: a stream of images of which only the newest
/// matters (a consumer that polls slower than the camera runs skips frames, it never
/// falls behind).
pub trait CameraHardware: Send {
    /// The newest image that arrived since the last call, `None` if none did. Older
    /// images that arrived in between are dropped and counted in
    /// [`CameraHardware::dropped`].
    ///
    /// # Errors
    /// [`HardwareError::Fault`] when the newest image is malformed (its layout does not
    /// match its size and encoding).
    fn latest(&mut self) -> Result<Option<Image>, HardwareError>;
    /// Images that arrived but were replaced by a newer one before [`latest`] took
    /// them.
    ///
    /// [`latest`]: CameraHardware::latest
    fn dropped(&self) -> u64;
}
