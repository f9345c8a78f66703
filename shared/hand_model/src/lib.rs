//! The operator's hand, as the hand-inference pipeline needs it (thesis ch. 3):
//!
//! * [`keypoints`]: the 21 keypoints in BigHand2.2M order and the hand frames of
//!   thesis Fig. 3.6 computed from them.
//! * [`human`]: a parametric human hand — 22 joints with human ranges, anthropometric
//!   bone lengths with per-hand shape variation, forward kinematics to keypoints, and
//!   capsule geometry for rendering.
//! * [`sampling`]: hand poses that cover what operators do — uniform random poses and
//!   grasp synergies (power, precision, pinch, open, pointing) and their blends.
//! * [`retarget`]: human keypoints to the Shadow hand's 17 finger joints with the
//!   project's IK goals (fingertips, PIPs, phalanx directions, self-collision).
//! * [`bighand`]: BigHand2.2M-style annotation files.
//! * [`scene`]: depth-render scenes of a human hand and of the Shadow hand, and the
//!   paired camera that sees both at the same camera-to-wrist transform.
//! * [`preprocess`]: the one depth preprocessing of the hand network (noise removal,
//!   250 mm cube crop, resize, normalisation), used by the dataset generator and at
//!   run time alike.
//!
//! Units: metres and radians, except where a file format says otherwise (BigHand: mm).

pub mod bighand;
pub mod human;
pub mod keypoints;
pub mod preprocess;
pub mod retarget;
pub mod sampling;
pub mod scene;

pub use keypoints::{
    Finger, HandKeypoints, KEYPOINT_COUNT, KEYPOINT_NAMES, hand_frame, palm_frame,
};

/// Errors of the hand model, retargeting, file reading and preprocessing.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum HandModelError {
    /// Keypoints from which no hand frame can be built.
    #[error("degenerate hand: {reason}")]
    DegenerateHand { reason: &'static str },
    /// A value outside what the model accepts.
    #[error("invalid {what}: {reason}")]
    Invalid { what: &'static str, reason: String },
    /// An annotation line that does not parse.
    #[error("{path}:{line}: {reason}")]
    Annotation {
        path: String,
        line: usize,
        reason: String,
    },
    /// A file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The Shadow hand model could not be built (only if the embedded URDF were broken).
    #[error("Shadow hand kinematics: {0}")]
    Kinematics(#[from] teleop_kinematics::KinematicsError),
    /// A render call refused its input.
    #[error("render: {0}")]
    Render(#[from] teleop_render::RenderError),
}
