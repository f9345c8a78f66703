//! Errors of building or driving the simulated world.

use teleop_kinematics::KinematicsError;

/// Why a world could not be built or changed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The robot description did not load or lacks a link/joint the simulator needs.
    #[error("robot model: {0}")]
    Kinematics(#[from] KinematicsError),
    /// A configuration number is out of range.
    #[error("invalid config {field} = {value}: {reason}")]
    InvalidConfig {
        /// Dotted field path, e.g. `hand.substeps`.
        field: &'static str,
        /// The offending value.
        value: f64,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// A joint name is not one of [`SHADOW_FINGER_JOINTS`](teleop_interfaces::joints::SHADOW_FINGER_JOINTS).
    #[error("unknown finger joint {0:?}")]
    UnknownFingerJoint(String),
    /// An object's size or pose is not finite or not positive.
    #[error("invalid object {name:?}: {reason}")]
    InvalidObject {
        /// The object's name.
        name: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// Something the joint-space world has that the MuJoCo world does not yet.
    #[error("not supported by the MuJoCo world yet: {0}")]
    Unsupported(&'static str),
    /// A job's judge refused its settings.
    #[error("job judge: {0}")]
    Job(#[from] teleop_physics::JudgeError),
    /// The physical world (MuJoCo) refused a model or a command, or became unstable.
    #[error("physics: {0}")]
    Physics(#[from] teleop_physics::PhysicsError),
}
