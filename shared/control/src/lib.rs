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

/// A rigid transform in config form: translation (m) and roll/pitch/yaw (deg, applied
/// about fixed x, y, z), as robotics configs write poses (URDF `xyz`/`rpy`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct TransformConfig {
    /// Translation, m.
    pub translation_m: [f64; 3],
    /// Roll, pitch, yaw, deg.
    pub rpy_deg: [f64; 3],
}

impl TransformConfig {
    /// As an isometry.
    pub fn isometry(&self) -> nalgebra::Isometry3<f64> {
        let [r, p, y] = self.rpy_deg.map(f64::to_radians);
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::from(nalgebra::Vector3::from(self.translation_m)),
            nalgebra::UnitQuaternion::from_euler_angles(r, p, y),
        )
    }

    /// The config form of `pose` (inverse of [`TransformConfig::isometry`]).
    pub fn from_isometry(pose: &nalgebra::Isometry3<f64>) -> Self {
        let (r, p, y) = pose.rotation.euler_angles();
        Self {
            translation_m: pose.translation.vector.into(),
            rpy_deg: [r, p, y].map(f64::to_degrees),
        }
    }

    /// # Errors
    /// `"{name} must be finite"` (within 1000 m / deg).
    pub fn validate(&self, name: &str) -> Result<(), String> {
        if self
            .translation_m
            .iter()
            .chain(&self.rpy_deg)
            .all(|v| v.is_finite() && v.abs() <= 1e3)
        {
            Ok(())
        } else {
            Err(format!("{name} must be finite"))
        }
    }
}

/// Largest accepted deviation of a rotation quaternion's norm from 1. Rotations are
/// `UnitQuaternion`s, but one built with `new_unchecked` (e.g. straight from a wire
/// message) may not be unit; every filter rejects it rather than compute with a
/// scaled rotation. 1e-6 passes any quaternion normalized in `f32` or `f64`.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-6;
