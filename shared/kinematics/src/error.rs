//! Typed errors of this crate.
//!
//! Every variant that concerns one element of a robot description names it, so a
//! caller can report "joint `rh_FFJ3`: lower limit above upper limit" instead of a
//! string from the XML parser.

use std::path::PathBuf;

/// Errors from loading a robot description or evaluating its kinematics.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KinematicsError {
    /// The URDF file could not be read.
    #[error("cannot read URDF file {}: {source}", path.display())]
    Io {
        /// The file that was asked for.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The text is not well-formed URDF XML (urdf-rs rejected it).
    #[error("malformed URDF: {message}")]
    Parse {
        /// The parser's message. The parser's own error type stays private so a
        /// parser update is not a breaking change here.
        message: String,
    },
    /// The description has no links.
    #[error("robot `{robot}` has no links")]
    NoLinks {
        /// `<robot name=...>`.
        robot: String,
    },
    /// Two links share a name.
    #[error("link `{link}` is defined twice")]
    DuplicateLink {
        /// The repeated name.
        link: String,
    },
    /// Two joints share a name.
    #[error("joint `{joint}` is defined twice")]
    DuplicateJoint {
        /// The repeated name.
        joint: String,
    },
    /// A joint names a parent or child link that is not defined.
    #[error("joint `{joint}` refers to undefined link `{link}`")]
    UndefinedLink {
        /// The joint.
        joint: String,
        /// The missing link.
        link: String,
    },
    /// A link is the child of more than one joint (not a tree).
    #[error("link `{link}` is the child of both `{first}` and `{second}`")]
    MultipleParents {
        /// The link.
        link: String,
        /// First joint naming it as child.
        first: String,
        /// Second joint naming it as child.
        second: String,
    },
    /// The description does not have exactly one root link.
    #[error("expected exactly one root link, found {roots:?}")]
    RootCount {
        /// All links that are nobody's child.
        roots: Vec<String>,
    },
    /// A link cannot be reached from the root (it sits on a kinematic loop).
    #[error("link `{link}` is not reachable from the root (kinematic loop)")]
    Unreachable {
        /// The link.
        link: String,
    },
    /// The joint type is not one this crate models (floating, planar, spherical).
    #[error("joint `{joint}`: type `{kind}` is not supported")]
    UnsupportedJointType {
        /// The joint.
        joint: String,
        /// The URDF type attribute.
        kind: String,
    },
    /// The joint mimics another joint; coupled joints are not modelled yet.
    #[error("joint `{joint}`: <mimic> is not supported")]
    UnsupportedMimic {
        /// The joint.
        joint: String,
    },
    /// A moving joint has a zero or non-finite axis.
    #[error("joint `{joint}`: axis {axis:?} is zero or not finite")]
    BadAxis {
        /// The joint.
        joint: String,
        /// The axis as written.
        axis: [f64; 3],
    },
    /// A joint origin holds a non-finite number.
    #[error("joint `{joint}`: origin is not finite")]
    NonFiniteOrigin {
        /// The joint.
        joint: String,
    },
    /// A limited joint has `lower > upper` or a non-finite bound.
    #[error("joint `{joint}`: limits [{lower}, {upper}] are invalid")]
    BadLimits {
        /// The joint.
        joint: String,
        /// Lower bound as written.
        lower: f64,
        /// Upper bound as written.
        upper: f64,
    },
    /// A link name was asked for that the robot does not have.
    #[error("robot has no link `{link}`")]
    UnknownLink {
        /// The name asked for.
        link: String,
    },
    /// A joint name was asked for that the robot does not have.
    #[error("robot has no joint `{joint}`")]
    UnknownJoint {
        /// The name asked for.
        joint: String,
    },
    /// A chain was asked for between links where the base is not an ancestor of the tip.
    #[error("link `{base}` is not an ancestor of link `{tip}`")]
    NotAncestor {
        /// Requested base link.
        base: String,
        /// Requested tip link.
        tip: String,
    },
    /// A fixed-size chain was asked for with the wrong number of joints.
    #[error("chain `{base}` -> `{tip}` has {actual} moving joints, expected {expected}")]
    ChainDof {
        /// Base link.
        base: String,
        /// Tip link.
        tip: String,
        /// The const generic asked for.
        expected: usize,
        /// What the chain has.
        actual: usize,
    },
    /// A joint-position slice has the wrong length.
    #[error("expected {expected} joint positions, got {actual}")]
    JointCount {
        /// Degrees of freedom of the robot or chain.
        expected: usize,
        /// Length of the slice passed.
        actual: usize,
    },
    /// An output matrix has the wrong number of columns.
    #[error("Jacobian buffer has {actual} columns, expected {expected}")]
    JacobianColumns {
        /// Degrees of freedom.
        expected: usize,
        /// Columns of the buffer passed.
        actual: usize,
    },
}
