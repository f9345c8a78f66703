//! Collision models of the three robots of the system, with the pairs allowed by hand.
//!
//! Each constructor takes the [`Robot`] loaded by [`teleop_kinematics::robots`] (the
//! caller needs it for forward kinematics anyway), generates the ACM with
//! [`ModelSettings::default`] (capsules merged; 1,000 samples, seed 0: reproducible)
//! and adds the pairs
//! below. Every hand-allowed pair says why.

use teleop_kinematics::Robot;

use crate::error::CollisionError;
use crate::model::{CollisionModel, ModelSettings};

/// Shadow hand pairs allowed by hand: `(link, link, reason)`.
pub const SHADOW_ALLOWED: [(&str, &str, &str); 1] = [(
    "rh_palm",
    "rh_lfproximal",
    "the URDF's palm box reaches z = 0.086 m over the whole palm width, but the LF \
     knuckle sits at z = 0.0865 m (lower than the others at 0.095 m), so the LF \
     proximal's base dips into the box at almost any flexion (60 % of random \
     configurations with the URDF's cylinder; with the merged capsule's cap it touches \
     already at the neutral configuration); on the hand the palm is cut away under the \
     LF knuckle",
)];

/// The UR5 with its camera mount: generated ACM only.
///
/// # Errors
/// As [`CollisionModel::with_settings`].
pub fn ur5(robot: &Robot) -> Result<CollisionModel, CollisionError> {
    CollisionModel::with_settings(robot, ModelSettings::default())
}

/// The Shadow hand alone: generated ACM plus [`SHADOW_ALLOWED`].
///
/// # Errors
/// As [`CollisionModel::with_settings`]; [`CollisionError::UnknownLink`] if `robot`
/// lacks a link of [`SHADOW_ALLOWED`].
pub fn shadow_hand(robot: &Robot) -> Result<CollisionModel, CollisionError> {
    let mut model = CollisionModel::with_settings(robot, ModelSettings::default())?;
    for (a, b, _) in SHADOW_ALLOWED {
        model.allow(a, b)?;
    }
    Ok(model)
}

/// The PR2 arm with the Shadow hand: generated ACM plus [`SHADOW_ALLOWED`].
///
/// # Errors
/// As [`shadow_hand`].
pub fn pr2_arm(robot: &Robot) -> Result<CollisionModel, CollisionError> {
    shadow_hand(robot)
}
