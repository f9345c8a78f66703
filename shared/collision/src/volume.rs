//! External volumes: posed primitives that are not part of the robot, such as the
//! space the operator's hand occupies in front of the UR5's camera.
//!
//! An [`ExternalVolume`] has a frame, posed in the frame the robot's link poses are
//! given in (the robot root frame for [`crate::CollisionModel`] queries, the chain
//! base frame for the IK constraints; for the robots here both are `base_link`), and
//! primitives placed in that frame. Moving the volume ([`ExternalVolume::set_pose`])
//! moves all its primitives: for the hand volume, pass each new tracked wrist pose.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::body::{Group, PosedGroup, bounding_ball};
use crate::error::CollisionError;
use crate::geometry::{PlacedShape, Posed, Primitive, isometry_is_finite};

/// Size of an adult operator's hand, as the box the hand volume is built from.
///
/// The defaults are a large adult hand, rounded up: hand length (wrist crease to the
/// middle fingertip) 0.19 m and hand breadth (across the knuckles) 0.09 m, about the
/// 50th-percentile adult male (ANSUR II: ~0.194 m and ~0.090 m); thickness 0.05 m,
/// more than a flat hand's ~0.03 m to leave room for slightly bent fingers. An open,
/// spread hand or a fist changes the shape: cover that with the margin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandDimensions {
    /// Wrist to middle fingertip, along the hand's +z (m).
    pub length_m: f64,
    /// Across the palm, along the hand's x (m).
    pub width_m: f64,
    /// Palm thickness, along the hand's y (m).
    pub thickness_m: f64,
}

impl HandDimensions {
    /// The adult hand described on the type.
    pub const ADULT: Self = Self {
        length_m: 0.19,
        width_m: 0.09,
        thickness_m: 0.05,
    };
}

impl Default for HandDimensions {
    fn default() -> Self {
        Self::ADULT
    }
}

/// A set of primitives posed together (see the module docs for frames).
#[derive(Debug, Clone)]
pub struct ExternalVolume {
    pose: Isometry3<f64>,
    shapes: Vec<PlacedShape>,
    /// `shapes` at `pose`.
    posed: Vec<Posed>,
    local_center: Vector3<f64>,
    radius_m: f64,
    world_center: Vector3<f64>,
}

impl ExternalVolume {
    /// An empty volume with its frame at `pose`.
    ///
    /// # Errors
    /// [`CollisionError::NonFinite`] for a non-finite pose.
    pub fn new(pose: Isometry3<f64>) -> Result<Self, CollisionError> {
        if !isometry_is_finite(&pose) {
            return Err(CollisionError::NonFinite {
                what: "volume pose",
            });
        }
        Ok(Self {
            pose,
            shapes: Vec::new(),
            posed: Vec::new(),
            local_center: Vector3::zeros(),
            radius_m: 0.0,
            world_center: pose.translation.vector,
        })
    }

    /// Adds `primitive` at `origin` (in the volume frame), grown by `margin_m` in every
    /// direction: distances to it are `margin_m` smaller than to the bare primitive.
    ///
    /// # Errors
    /// [`CollisionError::InvalidShape`] for bad dimensions,
    /// [`CollisionError::NonFinite`] for a non-finite origin or a bad margin.
    pub fn push(
        &mut self,
        primitive: Primitive,
        origin: Isometry3<f64>,
        margin_m: f64,
    ) -> Result<(), CollisionError> {
        let shape = PlacedShape::new(primitive, origin, margin_m, "volume")?;
        self.posed.push(shape.posed(&self.pose));
        self.shapes.push(shape);
        let (c, r) = bounding_ball(&self.shapes);
        self.local_center = c;
        self.radius_m = r;
        self.world_center = self.pose * c;
        Ok(())
    }

    /// Builder form of [`ExternalVolume::push`].
    ///
    /// # Errors
    /// As [`ExternalVolume::push`].
    pub fn with(
        mut self,
        primitive: Primitive,
        origin: Isometry3<f64>,
        margin_m: f64,
    ) -> Result<Self, CollisionError> {
        self.push(primitive, origin, margin_m)?;
        Ok(self)
    }

    /// The operator's hand as a box of [`HandDimensions::ADULT`] grown by `margin_m`,
    /// following the tracked wrist: see [`ExternalVolume::hand_volume_with`].
    ///
    /// # Errors
    /// [`CollisionError::NonFinite`] for a non-finite pose or a negative margin.
    pub fn hand_volume(wrist_pose: Isometry3<f64>, margin_m: f64) -> Result<Self, CollisionError> {
        Self::hand_volume_with(wrist_pose, HandDimensions::ADULT, margin_m)
    }

    /// The operator's hand as a box grown by `margin_m` (a rounded box: every point
    /// within `margin_m` of the box is inside).
    ///
    /// Frame: the volume frame is the wrist frame in the thesis' hand convention
    /// (ch. 3.4): origin at the wrist, **+z towards the fingertips**, y along the palm
    /// normal, x across the palm. The box spans `z ∈ [0, length]`,
    /// `x ∈ ±width/2`, `y ∈ ±thickness/2`. `wrist_pose` places it in the robot frame
    /// (the tracked wrist pose registered into the UR5 base frame). The forearm behind
    /// the wrist is not included; add a capsule with [`ExternalVolume::push`] if the
    /// robot can reach it.
    ///
    /// # Errors
    /// [`CollisionError::NonFinite`] for a non-finite pose or a negative margin,
    /// [`CollisionError::InvalidShape`] for negative dimensions.
    pub fn hand_volume_with(
        wrist_pose: Isometry3<f64>,
        hand: HandDimensions,
        margin_m: f64,
    ) -> Result<Self, CollisionError> {
        let half = Vector3::new(hand.width_m, hand.thickness_m, hand.length_m) / 2.0;
        let origin = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, half.z),
            UnitQuaternion::identity(),
        );
        Self::new(wrist_pose)?.with(
            Primitive::Box {
                half_extents_m: half,
            },
            origin,
            margin_m,
        )
    }

    /// Moves the volume frame (and every primitive with it) to `pose`.
    ///
    /// # Errors
    /// [`CollisionError::NonFinite`] for a non-finite pose (the volume is unchanged).
    pub fn set_pose(&mut self, pose: Isometry3<f64>) -> Result<(), CollisionError> {
        if !isometry_is_finite(&pose) {
            return Err(CollisionError::NonFinite {
                what: "volume pose",
            });
        }
        self.pose = pose;
        self.world_center = pose * self.local_center;
        for (p, s) in self.posed.iter_mut().zip(&self.shapes) {
            *p = s.posed(&pose);
        }
        Ok(())
    }

    /// The same volume at another pose.
    ///
    /// # Errors
    /// As [`ExternalVolume::set_pose`].
    pub fn at(&self, pose: Isometry3<f64>) -> Result<Self, CollisionError> {
        let mut v = self.clone();
        v.set_pose(pose)?;
        Ok(v)
    }

    /// Pose of the volume frame in the robot frame.
    pub fn pose(&self) -> &Isometry3<f64> {
        &self.pose
    }

    /// The primitives, placed in the volume frame.
    pub fn shapes(&self) -> &[PlacedShape] {
        &self.shapes
    }

    /// True when the volume has no primitive (nothing can collide with it).
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    pub(crate) fn group(&self) -> PosedGroup<'_> {
        PosedGroup {
            group: Group {
                shapes: &self.shapes,
                posed: &self.posed,
            },
            center: self.world_center,
            radius_m: self.radius_m,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn hand_box_spans_the_documented_extents() {
        let v = ExternalVolume::hand_volume(Isometry3::identity(), 0.01).unwrap();
        assert_eq!(v.shapes().len(), 1);
        let s = &v.shapes()[0];
        assert_eq!(
            *s.primitive(),
            Primitive::Box {
                half_extents_m: Vector3::new(0.045, 0.025, 0.095)
            }
        );
        assert!((s.origin().translation.vector - Vector3::new(0.0, 0.0, 0.095)).norm() < 1e-12);
        assert_eq!(s.inflation_m(), 0.01);
    }

    #[test]
    fn bad_inputs_are_refused() {
        let nan = Isometry3::translation(f64::NAN, 0.0, 0.0);
        assert!(ExternalVolume::hand_volume(nan, 0.0).is_err());
        assert!(ExternalVolume::hand_volume(Isometry3::identity(), -0.01).is_err());
        let mut v = ExternalVolume::hand_volume(Isometry3::identity(), 0.0).unwrap();
        assert!(v.set_pose(nan).is_err());
        assert_eq!(*v.pose(), Isometry3::identity());
    }
}
