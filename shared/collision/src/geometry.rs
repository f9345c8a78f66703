//! Convex primitives, and the **only** place where this crate touches parry3d.
//!
//! Everything outside this module is nalgebra `f64` (metres, radians). parry3d 0.31 is
//! built on glam `f32`; the conversion happens here and nowhere else:
//!
//! * shape dimensions are cast to `f32` once, when a [`PlacedShape`] is built;
//! * per query, the **relative** pose of the two shapes, `(pose_a)⁻¹ · pose_b`, is
//!   composed in `f64` and only then cast to `f32` (`to_parry_pose`). Its translation
//!   is the offset between two nearby shapes (centimetres to decimetres), not a
//!   position in the robot frame, so the cast loses ~1e-8 m instead of the ~1e-7 m an
//!   absolute pose a metre from the base would lose;
//! * the `f32` distance parry returns is widened back to `f64`.
//!
//! Accuracy. Capsules are queried as their axis segment grown by the radius, so
//! sphere–anything, capsule–capsule (segment–segment), capsule–box (GJK on polytopes,
//! which terminates on the exact features) and box–box (SAT) distances are exact to
//! `f32` rounding, ~1e-7 m. Pairs with a cylinder go through GJK on a curved support
//! map, which may stop once its bounds agree to a relative `sqrt(10 ε_f32) ≈ 1.1e-3`
//! (an upper bound); measured on cylinder–box pairs it was within 5e-7 m at 0.2 m.
//! Sweeping a shape in 1 µm steps, separated or penetrating, the distance stayed
//! within ~4e-8 m of a straight line, so finite differences with steps of 1e-6 rad
//! on a 0.5 m lever (5e-7 m) are good to a few per cent. Penetration depths of
//! non-rounded cores come from EPA, which can jump by ~1e-5 m where the deepest
//! feature changes in deep penetrations.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use parry3d::math::{Pose, Rotation, Vector};
use parry3d::query::{ClosestPoints, DefaultQueryDispatcher, QueryDispatcher};
use parry3d::shape::{Ball, Cuboid, Cylinder, Segment, Shape as ParryShape};
use teleop_kinematics::Shape;

use crate::error::CollisionError;

/// A convex primitive in its own frame, centred on the frame origin. Units: metres.
/// Axially symmetric shapes lie along their **z** axis, as in URDF.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Primitive {
    /// Ball.
    Sphere {
        /// Radius (m), > 0.
        radius_m: f64,
    },
    /// Box with half side lengths along x, y, z.
    Box {
        /// Half extents (m), each >= 0.
        half_extents_m: Vector3<f64>,
    },
    /// Segment from `(0, 0, -half_length_m)` to `(0, 0, +half_length_m)` swept by a ball.
    Capsule {
        /// Half length of the segment (m), >= 0 (caps excluded).
        half_length_m: f64,
        /// Radius (m), > 0.
        radius_m: f64,
    },
    /// Solid cylinder along z, from `z = -half_length_m` to `+half_length_m`.
    Cylinder {
        /// Half length (m), >= 0.
        half_length_m: f64,
        /// Radius (m), > 0.
        radius_m: f64,
    },
}

impl Primitive {
    /// Radius of the smallest ball about the frame origin that contains the primitive.
    pub fn bounding_radius_m(&self) -> f64 {
        match *self {
            Primitive::Sphere { radius_m } => radius_m,
            Primitive::Box { half_extents_m } => half_extents_m.norm(),
            Primitive::Capsule {
                half_length_m,
                radius_m,
            } => half_length_m + radius_m,
            Primitive::Cylinder {
                half_length_m,
                radius_m,
            } => half_length_m.hypot(radius_m),
        }
    }

    /// The primitive of a URDF collision element.
    ///
    /// # Errors
    /// [`CollisionError::UnsupportedShape`] for meshes, [`CollisionError::InvalidShape`]
    /// for bad dimensions.
    pub fn from_urdf(shape: &Shape, link: &str) -> Result<Self, CollisionError> {
        let p = match shape {
            Shape::Box { size } => Primitive::Box {
                half_extents_m: size / 2.0,
            },
            Shape::Cylinder { radius, length } => Primitive::Cylinder {
                half_length_m: length / 2.0,
                radius_m: *radius,
            },
            Shape::Capsule { radius, length } => Primitive::Capsule {
                half_length_m: length / 2.0,
                radius_m: *radius,
            },
            Shape::Sphere { radius } => Primitive::Sphere { radius_m: *radius },
            Shape::Mesh { filename, .. } => {
                return Err(CollisionError::UnsupportedShape {
                    link: link.to_owned(),
                    shape: format!("mesh `{filename}`"),
                });
            }
            other => {
                return Err(CollisionError::UnsupportedShape {
                    link: link.to_owned(),
                    shape: format!("{other:?}"),
                });
            }
        };
        p.validate(link)?;
        Ok(p)
    }

    fn validate(&self, owner: &str) -> Result<(), CollisionError> {
        let bad = |shape: &'static str, value: f64| {
            Err(CollisionError::InvalidShape {
                owner: owner.to_owned(),
                shape,
                value,
            })
        };
        let radius_ok = |r: f64| r.is_finite() && r > 0.0;
        let length_ok = |l: f64| l.is_finite() && l >= 0.0;
        match *self {
            Primitive::Sphere { radius_m } if !radius_ok(radius_m) => bad("sphere", radius_m),
            Primitive::Box { half_extents_m } => {
                match half_extents_m.iter().find(|v| !length_ok(**v)) {
                    Some(v) => bad("box", *v),
                    None => Ok(()),
                }
            }
            Primitive::Capsule {
                half_length_m,
                radius_m,
            } if !(radius_ok(radius_m) && length_ok(half_length_m)) => bad(
                "capsule",
                if radius_ok(radius_m) {
                    half_length_m
                } else {
                    radius_m
                },
            ),
            Primitive::Cylinder {
                half_length_m,
                radius_m,
            } if !(radius_ok(radius_m) && length_ok(half_length_m)) => bad(
                "cylinder",
                if radius_ok(radius_m) {
                    half_length_m
                } else {
                    radius_m
                },
            ),
            _ => Ok(()),
        }
    }
}

/// The parry shape of a primitive (f32).
#[derive(Debug, Clone, Copy)]
enum Compiled {
    Ball(Ball),
    Cuboid(Cuboid),
    /// A capsule's axis; its radius is added as rounding.
    Segment(Segment),
    Cylinder(Cylinder),
}

impl Compiled {
    fn as_dyn(&self) -> &dyn ParryShape {
        match self {
            Compiled::Ball(s) => s,
            Compiled::Cuboid(s) => s,
            Compiled::Segment(s) => s,
            Compiled::Cylinder(s) => s,
        }
    }
}

/// A primitive placed in an owner frame (a link, or an external volume's frame), with
/// an optional inflation: the shape queried is the primitive grown by `inflation_m` in
/// every direction (its Minkowski sum with a ball), so every signed distance to it is
/// `inflation_m` smaller.
#[derive(Debug, Clone)]
pub struct PlacedShape {
    primitive: Primitive,
    origin: Isometry3<f64>,
    inflation_m: f64,
    bounding_radius_m: f64,
    compiled: Compiled,
    /// Radius added around `compiled`: the capsule radius plus the inflation.
    rounding_m: f64,
    /// Frame of the parry shape in the owner frame: `origin`, turned for parry's
    /// y-axis cylinders.
    parry_offset: Isometry3<f64>,
}

impl PlacedShape {
    /// Places `primitive` at `origin` (primitive frame in the owner frame).
    ///
    /// # Errors
    /// [`CollisionError::InvalidShape`] for bad dimensions, [`CollisionError::NonFinite`]
    /// for a non-finite origin or a negative / non-finite inflation.
    pub fn new(
        primitive: Primitive,
        origin: Isometry3<f64>,
        inflation_m: f64,
        owner: &str,
    ) -> Result<Self, CollisionError> {
        primitive.validate(owner)?;
        if !isometry_is_finite(&origin) {
            return Err(CollisionError::NonFinite {
                what: "shape origin",
            });
        }
        if !(inflation_m.is_finite() && inflation_m >= 0.0) {
            return Err(CollisionError::NonFinite { what: "inflation" });
        }
        // Shape dimensions: the f64 -> f32 cast of this crate, part 1 of 2.
        let mut core_radius_m = 0.0;
        let (compiled, parry_offset) = match primitive {
            Primitive::Sphere { radius_m } => (Compiled::Ball(Ball::new(radius_m as f32)), origin),
            Primitive::Box { half_extents_m } => (
                Compiled::Cuboid(Cuboid::new(Vector::new(
                    half_extents_m.x as f32,
                    half_extents_m.y as f32,
                    half_extents_m.z as f32,
                ))),
                origin,
            ),
            // A capsule is its axis grown by its radius. Queries on the bare segment
            // are exact (segment-segment and point-segment are closed-form, GJK on
            // polytopes terminates on the exact features), where GJK on a curved
            // capsule stops at a ~1e-3 relative tolerance.
            Primitive::Capsule {
                half_length_m,
                radius_m,
            } if half_length_m > 0.0 => {
                core_radius_m = radius_m;
                let h = half_length_m as f32;
                (
                    Compiled::Segment(Segment::new(
                        Vector::new(0.0, 0.0, -h),
                        Vector::new(0.0, 0.0, h),
                    )),
                    origin,
                )
            }
            Primitive::Capsule { radius_m, .. } => {
                (Compiled::Ball(Ball::new(radius_m as f32)), origin)
            }
            // parry's cylinders lie along y; a +90 deg turn about x takes y to z.
            Primitive::Cylinder {
                half_length_m,
                radius_m,
            } => (
                Compiled::Cylinder(Cylinder::new(half_length_m as f32, radius_m as f32)),
                origin
                    * UnitQuaternion::from_axis_angle(
                        &Vector3::x_axis(),
                        std::f64::consts::FRAC_PI_2,
                    ),
            ),
        };
        Ok(Self {
            bounding_radius_m: primitive.bounding_radius_m() + inflation_m,
            primitive,
            origin,
            inflation_m,
            compiled,
            rounding_m: core_radius_m + inflation_m,
            parry_offset,
        })
    }

    /// The primitive.
    pub fn primitive(&self) -> &Primitive {
        &self.primitive
    }

    /// Primitive frame in the owner frame.
    pub fn origin(&self) -> &Isometry3<f64> {
        &self.origin
    }

    /// Inflation (m).
    pub fn inflation_m(&self) -> f64 {
        self.inflation_m
    }

    /// Radius of a ball about `origin`'s translation containing the inflated shape.
    pub fn bounding_radius_m(&self) -> f64 {
        self.bounding_radius_m
    }

    /// Centre of the bounding ball in the owner frame.
    pub fn bounding_center(&self) -> Vector3<f64> {
        self.origin.translation.vector
    }
}

pub(crate) fn isometry_is_finite(p: &Isometry3<f64>) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.coords.iter().all(|v| v.is_finite())
}

/// Pose cast: the f64 -> f32 cast of this crate, part 2 of 2. Only ever called on a
/// relative pose of two shapes (see the module docs).
fn to_parry_pose(p: &Isometry3<f64>) -> Pose {
    let t = &p.translation.vector;
    let q = p.rotation.quaternion();
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize(),
    )
}

/// Parry shape frames of `a` and `b` relative to each other, cast to f32.
fn relative(pa: &Posed, pb: &Posed) -> Pose {
    to_parry_pose(&pa.frame.inv_mul(&pb.frame))
}

/// A [`PlacedShape`] posed for one query: computed once per shape and query, used by
/// every pair the shape is in.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Posed {
    /// The parry shape's frame in the common frame.
    pub frame: Isometry3<f64>,
    /// Centre of the bounding ball in the common frame.
    pub center: Vector3<f64>,
}

impl PlacedShape {
    /// This shape on an owner frame at `owner` (in the common frame).
    pub(crate) fn posed(&self, owner: &Isometry3<f64>) -> Posed {
        Posed {
            frame: owner * self.parry_offset,
            center: owner * self.origin.translation.vector,
        }
    }
}

/// Signed distance (m) between `a` posed by `owner_a` and `b` posed by `owner_b`
/// (owner frames in a common frame): the gap when separated, minus the penetration
/// depth when overlapping, less both roundings (capsule radii and inflations).
///
/// With rounding the result is exact as long as the bare cores do not overlap. When
/// they do, the depth of the cores comes from EPA; for two capsules whose axes cross,
/// EPA has no volume to work with and the axes count as touching (depth = the sum of
/// the radii, which is the true depth of crossing capsules).
#[cfg(test)]
pub(crate) fn signed_distance(
    a: &PlacedShape,
    owner_a: &Isometry3<f64>,
    b: &PlacedShape,
    owner_b: &Isometry3<f64>,
) -> f64 {
    signed_distance_below(a, &a.posed(owner_a), b, &b.posed(owner_b), f64::INFINITY)
        .unwrap_or(f64::INFINITY)
}

/// As `signed_distance`, but only when it is below `cutoff` (`None` otherwise). A
/// finite cutoff lets separated pairs be rejected by GJK's early exit (a lower bound
/// above the cutoff) instead of converging to the exact distance.
pub(crate) fn signed_distance_below(
    a: &PlacedShape,
    pa: &Posed,
    b: &PlacedShape,
    pb: &Posed,
    cutoff: f64,
) -> Option<f64> {
    let pos12 = relative(pa, pb);
    let (g1, g2) = (a.compiled.as_dyn(), b.compiled.as_dyn());
    let rounding = a.rounding_m + b.rounding_m;
    // The gap between the bare cores, `None` when they touch or overlap.
    let gap = if !cutoff.is_finite() {
        match DefaultQueryDispatcher.distance(&pos12, g1, g2) {
            Ok(d) => Some(f64::from(d.distance)),
            Err(_) => Some(unsupported_pair()),
        }
    } else if cutoff + rounding <= 0.0 {
        // Only a penetration deeper than the cutoff can beat it.
        if !cores_within(&pos12, g1, g2, 0.0) {
            return None;
        }
        None
    } else {
        // GJK stops as soon as it proves a gap above the margin; otherwise it has
        // converged to the closest points (shape 1 and shape 2 local frames).
        match DefaultQueryDispatcher.closest_points(&pos12, g1, g2, (cutoff + rounding) as f32) {
            Ok(ClosestPoints::Disjoint) => return None,
            Ok(ClosestPoints::Intersecting) => None,
            Ok(ClosestPoints::WithinMargin(p1, p2)) => {
                Some(f64::from((p1 - pos12.transform_point(p2)).length()))
            }
            Err(_) => Some(unsupported_pair()),
        }
    };
    let raw = match gap {
        Some(g) if g > 0.0 => g,
        // Touching or overlapping: the depth comes from the contact query (EPA).
        _ => match DefaultQueryDispatcher.contact(&pos12, g1, g2, 0.0) {
            Ok(Some(c)) => f64::from(c.dist).min(0.0),
            Ok(None) => 0.0,
            Err(_) => unsupported_pair(),
        },
    };
    let d = raw - rounding;
    (d < cutoff).then_some(d)
}

/// True when the bare cores are at most `margin` apart (touching counts), decided
/// without converging to the distance: an intersection test for `margin <= 0`, else
/// a closest-points query that stops as soon as GJK proves a larger gap.
fn cores_within(pos12: &Pose, g1: &dyn ParryShape, g2: &dyn ParryShape, margin: f64) -> bool {
    if margin <= 0.0 {
        DefaultQueryDispatcher
            .intersection_test(pos12, g1, g2)
            .map_or_else(|_| unsupported_pair() <= 0.0, |i| i.intersecting)
    } else {
        match DefaultQueryDispatcher.closest_points(pos12, g1, g2, margin as f32) {
            Ok(ClosestPoints::Disjoint) => false,
            Ok(_) => true,
            Err(_) => unsupported_pair() <= margin,
        }
    }
}

/// True when the (rounded) shapes touch or overlap: `signed_distance <= 0`, decided
/// without computing a distance.
pub(crate) fn collides(a: &PlacedShape, pa: &Posed, b: &PlacedShape, pb: &Posed) -> bool {
    let pos12 = relative(pa, pb);
    cores_within(
        &pos12,
        a.compiled.as_dyn(),
        b.compiled.as_dyn(),
        a.rounding_m + b.rounding_m,
    )
}

/// parry supports every pair of the four convex primitives used here (a unit test
/// checks all sixteen); should that ever change, report contact rather than hide one.
fn unsupported_pair() -> f64 {
    debug_assert!(false, "parry3d has no distance query for a primitive pair");
    0.0
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;
    use nalgebra::Translation3;

    fn all() -> [Primitive; 4] {
        [
            Primitive::Sphere { radius_m: 0.05 },
            Primitive::Box {
                half_extents_m: Vector3::new(0.05, 0.04, 0.03),
            },
            Primitive::Capsule {
                half_length_m: 0.05,
                radius_m: 0.02,
            },
            Primitive::Cylinder {
                half_length_m: 0.05,
                radius_m: 0.02,
            },
        ]
    }

    #[test]
    fn every_pair_is_supported_both_separated_and_overlapping() {
        for a in all() {
            for b in all() {
                let sa = PlacedShape::new(a, Isometry3::identity(), 0.0, "a").unwrap();
                let sb = PlacedShape::new(b, Isometry3::identity(), 0.0, "b").unwrap();
                for (x, sign) in [(1.0, 1.0), (0.01, -1.0)] {
                    let pb = Isometry3::translation(x, 0.0, 0.0);
                    let pos12 = relative(&sa.posed(&Isometry3::identity()), &sb.posed(&pb));
                    let (g1, g2) = (sa.compiled.as_dyn(), sb.compiled.as_dyn());
                    assert!(DefaultQueryDispatcher.distance(&pos12, g1, g2).is_ok());
                    assert!(DefaultQueryDispatcher.contact(&pos12, g1, g2, 0.0).is_ok());
                    let d = signed_distance(&sa, &Isometry3::identity(), &sb, &pb);
                    assert!(d * sign > 0.0, "{a:?} {b:?} at {x}: {d}");
                    let hit = collides(&sa, &sa.posed(&Isometry3::identity()), &sb, &sb.posed(&pb));
                    assert_eq!(hit, sign < 0.0);
                }
            }
        }
    }

    #[test]
    fn the_cutoff_path_agrees_with_the_plain_distance() {
        let id = Isometry3::identity();
        for a in all() {
            for b in all() {
                let sa = PlacedShape::new(a, id, 0.0, "a").unwrap();
                let sb = PlacedShape::new(b, id, 0.001, "b").unwrap();
                for k in 0..20 {
                    let t = f64::from(k);
                    let pb = Isometry3::from_parts(
                        Translation3::new(0.02 + 0.01 * t, 0.03 * (t * 0.7).sin(), 0.01 * t.cos()),
                        UnitQuaternion::from_euler_angles(0.3 * t, 0.2, -0.1 * t),
                    );
                    let (qa, qb) = (sa.posed(&id), sb.posed(&pb));
                    let exact = signed_distance_below(&sa, &qa, &sb, &qb, f64::INFINITY).unwrap();
                    for cutoff in [exact + 0.01, exact + 1e-4, exact - 1e-4, 0.0] {
                        let got = signed_distance_below(&sa, &qa, &sb, &qb, cutoff);
                        if exact < cutoff - 1e-6 {
                            let got = got.unwrap();
                            assert!(
                                (got - exact).abs() < 1e-6,
                                "{a:?} {b:?} {k}: {got} vs {exact}"
                            );
                        } else if exact > cutoff + 1e-6 {
                            assert!(got.is_none(), "{a:?} {b:?} {k}: {got:?} vs {exact}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn cylinders_lie_along_z_like_urdf() {
        let cyl = PlacedShape::new(
            Primitive::Cylinder {
                half_length_m: 0.5,
                radius_m: 0.1,
            },
            Isometry3::identity(),
            0.0,
            "c",
        )
        .unwrap();
        let ball = PlacedShape::new(
            Primitive::Sphere { radius_m: 0.1 },
            Isometry3::identity(),
            0.0,
            "b",
        )
        .unwrap();
        let above = Isometry3::from_parts(Translation3::new(0.0, 0.0, 1.0), Default::default());
        let side = Isometry3::from_parts(Translation3::new(1.0, 0.0, 0.0), Default::default());
        let d_above = signed_distance(&cyl, &Isometry3::identity(), &ball, &above);
        let d_side = signed_distance(&cyl, &Isometry3::identity(), &ball, &side);
        assert!((d_above - 0.4).abs() < 1e-6, "{d_above}");
        assert!((d_side - 0.8).abs() < 1e-6, "{d_side}");
    }

    #[test]
    fn inflation_shifts_the_distance_and_penetration_is_negative() {
        let a = PlacedShape::new(
            Primitive::Sphere { radius_m: 0.1 },
            Isometry3::identity(),
            0.02,
            "a",
        )
        .unwrap();
        let b = a.clone();
        let far = Isometry3::translation(0.5, 0.0, 0.0);
        assert!((signed_distance(&a, &Isometry3::identity(), &b, &far) - 0.26).abs() < 1e-6);
        let near = Isometry3::translation(0.15, 0.0, 0.0);
        let d = signed_distance(&a, &Isometry3::identity(), &b, &near);
        assert!((d + 0.09).abs() < 1e-6, "{d}");
    }

    #[test]
    fn crossing_capsules_are_as_deep_as_their_radii() {
        let cap = |axis: Vector3<f64>| {
            let turn = UnitQuaternion::rotation_between(&Vector3::z(), &axis).unwrap();
            PlacedShape::new(
                Primitive::Capsule {
                    half_length_m: 0.1,
                    radius_m: 0.02,
                },
                Isometry3::from_parts(Translation3::identity(), turn),
                0.0,
                "c",
            )
            .unwrap()
        };
        let (a, b) = (cap(Vector3::z()), cap(Vector3::x()));
        let id = Isometry3::identity();
        assert!((signed_distance(&a, &id, &b, &id) + 0.04).abs() < 1e-6);
        // Collinear, overlapping axes.
        assert!(
            (signed_distance(&a, &id, &a, &Isometry3::translation(0.0, 0.0, 0.05)) + 0.04).abs()
                < 1e-6
        );
        // Skew axes 3 cm apart: 0.03 - 0.04.
        let d = signed_distance(&a, &id, &b, &Isometry3::translation(0.0, 0.03, 0.02));
        assert!((d + 0.01).abs() < 1e-6, "{d}");
        // Parallel axes 5 cm apart, separated: 0.05 - 0.04.
        let d = signed_distance(&a, &id, &a, &Isometry3::translation(0.05, 0.0, 0.02));
        assert!((d - 0.01).abs() < 1e-6, "{d}");
    }

    #[test]
    fn bad_dimensions_are_refused() {
        for p in [
            Primitive::Sphere { radius_m: 0.0 },
            Primitive::Sphere { radius_m: f64::NAN },
            Primitive::Box {
                half_extents_m: Vector3::new(0.1, -0.1, 0.1),
            },
            Primitive::Capsule {
                half_length_m: 0.1,
                radius_m: -1.0,
            },
            Primitive::Cylinder {
                half_length_m: f64::INFINITY,
                radius_m: 0.1,
            },
        ] {
            assert!(matches!(
                PlacedShape::new(p, Isometry3::identity(), 0.0, "x"),
                Err(CollisionError::InvalidShape { .. })
            ));
        }
        assert!(
            PlacedShape::new(all()[0], Isometry3::identity(), -0.1, "x").is_err(),
            "negative inflation"
        );
    }
}
