//! The operator site's default calibrations and the config form of a rigid transform
//! they are written in. A real installation measures its own (the wrist tracker's
//! `[registration]`); these are what the simulated installation is built with, so the
//! site's nodes and the simulator that stands in for the hardware agree without either
//! depending on the other.

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

/// Where the motion-capture system's own frame sits in the UR5 base frame, as the
/// simulated PhaseSpace is installed (the registration `rT_c` of eq. 7.1 folded into
/// one transform). Not the identity, so a missing registration shows.
pub fn default_base_from_mocap() -> TransformConfig {
    TransformConfig {
        translation_m: [1.2, -0.4, -0.8],
        rpy_deg: [0.0, 0.0, 90.0],
    }
}

/// The LED marker's pose in the operator's hand frame (Fig. 3.6: origin at the wrist,
/// z along the fingers, y the palm normal): on the back of the hand (-y), 5 cm toward
/// the knuckles, rotated as the rigid body was glued on.
pub fn default_hand_from_marker() -> TransformConfig {
    TransformConfig {
        translation_m: [0.0, -0.03, 0.05],
        rpy_deg: [90.0, 0.0, 0.0],
    }
}
