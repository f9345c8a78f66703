//! Fixed objects of the world and external loads on the hand.

use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

use super::error::SimError;
use super::geometry::Capsule;

/// Shape of a fixed object. Both are capsules for the contact model (see
/// [`super::geometry`]); a long capsule is a cylinder wherever its side is touched.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum ObjectShape {
    /// A ball centred on the object frame's origin.
    Sphere {
        /// Radius, m.
        radius_m: f64,
    },
    /// A capsule along the object frame's z axis (a cylinder with rounded ends).
    Capsule {
        /// Radius, m.
        radius_m: f64,
        /// Half length of the straight part (caps excluded), m.
        half_length_m: f64,
    },
}

/// A rigid object held fixed in the world (PR2 `base_link` frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Name for reports, e.g. `"mouse"`.
    pub name: String,
    /// Geometry in the object frame.
    pub shape: ObjectShape,
    /// Object frame in the world: `p_world = pose * p_object`.
    pub pose: Isometry3<f64>,
}

impl Object {
    /// The object's capsule in the world frame.
    ///
    /// # Errors
    /// [`SimError::InvalidObject`] for a non-positive or non-finite size or pose.
    pub fn world_capsule(&self) -> Result<Capsule, SimError> {
        let bad = |reason| SimError::InvalidObject {
            name: self.name.clone(),
            reason,
        };
        let local = match self.shape {
            ObjectShape::Sphere { radius_m } => {
                if !(radius_m.is_finite() && radius_m > 0.0) {
                    return Err(bad("radius must be finite and > 0"));
                }
                Capsule::ball(nalgebra::Point3::origin(), radius_m)
            }
            ObjectShape::Capsule {
                radius_m,
                half_length_m,
            } => {
                if !(radius_m.is_finite() && radius_m > 0.0) {
                    return Err(bad("radius must be finite and > 0"));
                }
                if !(half_length_m.is_finite() && half_length_m >= 0.0) {
                    return Err(bad("half length must be finite and >= 0"));
                }
                Capsule::along_z(half_length_m, radius_m)
            }
        };
        let c = local.transformed(&self.pose);
        if !(c.a.coords.iter().chain(c.b.coords.iter())).all(|v| v.is_finite()) {
            return Err(bad("pose must be finite"));
        }
        Ok(c)
    }
}

/// What an [`ExternalLoad`] pushes on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
pub enum LoadTarget {
    /// A torque on one finger joint (a name of [`SHADOW_FINGER_JOINTS`](teleop_interfaces::joints::SHADOW_FINGER_JOINTS)), N m,
    /// positive about the joint axis (positive = towards the joint's upper limit).
    JointTorque {
        /// Joint name, e.g. `"rh_THJ4"`.
        joint: String,
        /// Full torque, N m.
        torque_nm: f64,
    },
    /// A force at a fingertip frame's origin (`rh_<f>tip`), world frame, N.
    FingertipForce {
        /// Finger: one of [`FINGERTIPS`](teleop_interfaces::joints::FINGERTIPS) (`"ff"` .. `"th"`).
        finger: String,
        /// Full force in the world (PR2 `base_link`) frame, N.
        force_n: [f64; 3],
    },
}

/// An external disturbance on the hand: zero before `start_s`, ramped linearly to full
/// over `ramp_s`, full until `end_s` (forever if `None`). Stands in for the thesis'
/// screw pouring, where 0.6 kg of screws poured into the held cup made the thumb slip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExternalLoad {
    /// Where and how much.
    pub target: LoadTarget,
    /// Sim time at which the load starts, s.
    pub start_s: f64,
    /// Duration of the linear ramp to full load, s (0: a step).
    #[serde(default)]
    pub ramp_s: f64,
    /// Sim time at which the load is removed, s; `None`: never.
    #[serde(default)]
    pub end_s: Option<f64>,
}

impl ExternalLoad {
    /// The screw-pouring stand-in: the weight of ~0.6 kg of screws, shared by the
    /// fingers, pushes the thumb open: -0.15 N m on THJ4, ramped over 2 s from
    /// `start_s` (the pour lasted a few seconds in Fig. 8.11).
    pub fn screw_pouring(start_s: f64) -> Self {
        Self {
            target: LoadTarget::JointTorque {
                joint: "rh_THJ4".to_owned(),
                torque_nm: -0.15,
            },
            start_s,
            ramp_s: 2.0,
            end_s: None,
        }
    }

    /// Checks that every number is finite (both worlds call it before taking a load).
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] naming the field (`load.<field>`).
    pub fn validate(&self) -> Result<(), SimError> {
        let mut fields = vec![("load.start_s", self.start_s), ("load.ramp_s", self.ramp_s)];
        match &self.target {
            LoadTarget::JointTorque { torque_nm, .. } => {
                fields.push(("load.torque_nm", *torque_nm))
            }
            LoadTarget::FingertipForce { force_n, .. } => {
                fields.extend(force_n.iter().map(|f| ("load.force_n", *f)));
            }
        }
        for (field, value) in fields {
            if !value.is_finite() {
                return Err(SimError::InvalidConfig {
                    field,
                    value,
                    reason: "must be finite",
                });
            }
        }
        Ok(())
    }

    /// Fraction of the full load at sim time `time_s`, in `[0, 1]`.
    pub fn scale_at(&self, time_s: f64) -> f64 {
        if time_s < self.start_s || self.end_s.is_some_and(|e| time_s >= e) {
            0.0
        } else if self.ramp_s <= 0.0 {
            1.0
        } else {
            ((time_s - self.start_s) / self.ramp_s).min(1.0)
        }
    }
}

/// A load resolved against the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ResolvedTarget {
    Joint {
        hand_index: usize,
        torque_nm: f64,
    },
    Fingertip {
        finger: usize,
        force_n: Vector3<f64>,
    },
}
