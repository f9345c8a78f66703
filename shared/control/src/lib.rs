#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod error;
pub mod filters;
pub mod gate;
pub mod hand;

pub use error::{Axis, ConfigError, Rejection, RejectionCounts, RejectionKind};
pub use filters::{
    CartesianLimiter, CartesianLimits, InterventionCounts, JointLimiterConfig, JointLimits,
    JointVelocityLimiter, JumpFilter, JumpFilterConfig, UR5_MAX_JOINT_VELOCITY_RAD_S,
    VelocityLimitStrategy,
};
pub use gate::{Closed, GateMode, OperatorGate, OperatorSample};

/// Checks config values against closed ranges: each `(name, value, lo, hi)` must be
/// finite and in `[lo, hi]`.
///
/// # Errors
/// `"{prefix}.{name} must be in [{lo}, {hi}], got {value}"` for the first one that
/// is not.
pub fn check_ranges(prefix: &str, checks: &[(&str, f64, f64, f64)]) -> Result<(), String> {
    for &(name, v, lo, hi) in checks {
        if !(v.is_finite() && v >= lo && v <= hi) {
            return Err(format!("{prefix}.{name} must be in [{lo}, {hi}], got {v}"));
        }
    }
    Ok(())
}
pub use hand::{
    AdaptiveImpedance, CompliantProfiles, HandController, HandControllerConfig, HandMode,
    HandOutput, JointInput, PerJoint, ShadowHandController,
};
pub use nalgebra;

pub use teleop_interfaces::calibration::TransformConfig;

/// Largest accepted deviation of a rotation quaternion's norm from 1. Rotations are
/// `UnitQuaternion`s, but one built with `new_unchecked` (e.g. straight from a wire
/// message) may not be unit; every filter rejects it rather than compute with a
/// scaled rotation. 1e-6 passes any quaternion normalized in `f32` or `f64`.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-6;
