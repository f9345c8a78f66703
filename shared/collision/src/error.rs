//! Errors of the collision layer.

use teleop_kinematics::KinematicsError;

/// Why a collision model, volume or constraint could not be built or queried.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CollisionError {
    /// A link's collision geometry is not a primitive (a mesh); only spheres, boxes,
    /// cylinders and capsules are supported.
    #[error("link `{link}`: collision geometry {shape} is not supported (use primitives)")]
    UnsupportedShape {
        /// The link carrying the geometry.
        link: String,
        /// What it is (for meshes: the file as written in the URDF).
        shape: String,
    },
    /// A primitive has a non-finite, negative or (for radii) zero dimension.
    #[error("{owner}: invalid {shape} dimension {value} m")]
    InvalidShape {
        /// Link name, or `volume` for external volumes.
        owner: String,
        /// The primitive kind.
        shape: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A pose or margin is not finite, or a margin is negative.
    #[error("{what} is not finite (or a margin is negative)")]
    NonFinite {
        /// What was given.
        what: &'static str,
    },
    /// A link name unknown to the robot.
    #[error("unknown link `{link}`")]
    UnknownLink {
        /// The name asked for.
        link: String,
    },
    /// A link that exists but carries no collision geometry (nothing to allow).
    #[error("link `{link}` has no collision geometry")]
    NoGeometry {
        /// The link.
        link: String,
    },
    /// The link-pose slice does not hold one pose per robot link.
    #[error("expected {expected} link poses (one per robot link), got {actual}")]
    PoseCount {
        /// `robot.links().len()` of the model's robot.
        expected: usize,
        /// Length given.
        actual: usize,
    },
    /// Fewer chain frames than the chain has moving joints.
    #[error("expected at least {expected} chain frames (one per moving joint), got {actual}")]
    FrameCount {
        /// The chain's DoF.
        expected: usize,
        /// Length given.
        actual: usize,
    },
    /// A chain or robot that is not the one the collision model was built from.
    #[error("{what} does not belong to robot `{robot}` the collision model was built from")]
    RobotMismatch {
        /// The model's robot name.
        robot: String,
        /// What did not match.
        what: String,
    },
    /// ACM generation settings out of range.
    #[error("invalid ACM settings: {reason}")]
    InvalidSettings {
        /// What is wrong.
        reason: &'static str,
    },
    /// Forward kinematics failed (wrong joint count for the rest configuration, ...).
    #[error(transparent)]
    Kinematics(#[from] KinematicsError),
}
