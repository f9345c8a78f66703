//! Scenes: posed parry3d primitives with colours.

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::math::Vector;
use parry3d::shape::{Ball, Capsule, Cuboid, Cylinder};

use crate::RenderError;

/// One renderable primitive, a parry3d shape in its own *shape frame* (metres, `f32`).
///
/// Conventions are parry3d's: a [`Ball`] is centred on the origin, a [`Cuboid`] is
/// axis-aligned and centred, a [`Cylinder`] is centred with its axis along **local Y**
/// (a URDF cylinder is along Z: put a 90 deg rotation about X into its pose), and a
/// [`Capsule`] is the set of points within `radius` of its segment `a - b`.
///
/// The `f64` constructors are the preferred way in: they keep the caller on nalgebra.
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub enum Primitive {
    /// Sphere.
    Ball(Ball),
    /// Sphere-swept segment.
    Capsule(Capsule),
    /// Box.
    Cuboid(Cuboid),
    /// Flat-capped cylinder along local Y.
    Cylinder(Cylinder),
}

impl Primitive {
    /// A sphere of radius `radius_m` centred on the shape frame's origin.
    #[must_use]
    pub fn ball(radius_m: f64) -> Self {
        Self::Ball(Ball::new(radius_m as f32))
    }

    /// A capsule around the segment `a_m - b_m` (shape frame) with radius `radius_m`.
    #[must_use]
    pub fn capsule(a_m: &Point3<f64>, b_m: &Point3<f64>, radius_m: f64) -> Self {
        Self::Capsule(Capsule::new(
            vector_f32(&a_m.coords),
            vector_f32(&b_m.coords),
            radius_m as f32,
        ))
    }

    /// A capsule along the local Z axis, segment from `-half_length_m` to
    /// `+half_length_m` (the caps extend `radius_m` further).
    #[must_use]
    pub fn capsule_z(half_length_m: f64, radius_m: f64) -> Self {
        Self::Capsule(Capsule::new_z(half_length_m as f32, radius_m as f32))
    }

    /// A box with the given half side lengths.
    #[must_use]
    pub fn cuboid(half_extents_m: &Vector3<f64>) -> Self {
        Self::Cuboid(Cuboid::new(vector_f32(half_extents_m)))
    }

    /// A cylinder along the local **Y** axis (parry3d's convention).
    #[must_use]
    pub fn cylinder_y(half_height_m: f64, radius_m: f64) -> Self {
        Self::Cylinder(Cylinder::new(half_height_m as f32, radius_m as f32))
    }

    /// The parry3d shape, e.g. for ray casting or collision queries.
    #[must_use]
    pub fn as_shape(&self) -> &dyn parry3d::shape::Shape {
        match self {
            Self::Ball(s) => s,
            Self::Capsule(s) => s,
            Self::Cuboid(s) => s,
            Self::Cylinder(s) => s,
        }
    }

    /// Checks every dimension is finite and positive (a capsule's segment may have zero
    /// length, its endpoints must be finite).
    fn validate(&self) -> Result<(), RenderError> {
        let positive = |name: &'static str, value: f32| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(RenderError::InvalidShapeDimension {
                    name,
                    value: f64::from(value),
                })
            }
        };
        match self {
            Self::Ball(s) => positive("radius", s.radius),
            Self::Capsule(s) => {
                positive("radius", s.radius)?;
                for v in s
                    .segment
                    .a
                    .to_array()
                    .into_iter()
                    .chain(s.segment.b.to_array())
                {
                    if !v.is_finite() {
                        return Err(RenderError::InvalidShapeDimension {
                            name: "segment endpoint",
                            value: f64::from(v),
                        });
                    }
                }
                Ok(())
            }
            Self::Cuboid(s) => s
                .half_extents
                .to_array()
                .into_iter()
                .try_for_each(|v| positive("half_extent", v)),
            Self::Cylinder(s) => {
                positive("radius", s.radius)?;
                positive("half_height", s.half_height)
            }
        }
    }
}

impl From<Ball> for Primitive {
    fn from(s: Ball) -> Self {
        Self::Ball(s)
    }
}
impl From<Capsule> for Primitive {
    fn from(s: Capsule) -> Self {
        Self::Capsule(s)
    }
}
impl From<Cuboid> for Primitive {
    fn from(s: Cuboid) -> Self {
        Self::Cuboid(s)
    }
}
impl From<Cylinder> for Primitive {
    fn from(s: Cylinder) -> Self {
        Self::Cylinder(s)
    }
}

/// An 8-bit sRGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Rgb8(pub [u8; 3]);

/// Colours handed out to shapes pushed without one (index = shape index mod 12).
pub const PALETTE: [Rgb8; 12] = [
    Rgb8([230, 159, 0]),
    Rgb8([86, 180, 233]),
    Rgb8([0, 158, 115]),
    Rgb8([240, 228, 66]),
    Rgb8([0, 114, 178]),
    Rgb8([213, 94, 0]),
    Rgb8([204, 121, 167]),
    Rgb8([200, 200, 200]),
    Rgb8([120, 200, 80]),
    Rgb8([160, 100, 220]),
    Rgb8([250, 130, 130]),
    Rgb8([90, 90, 200]),
];

/// Identifies a shape in its [`Scene`]; also the value written to the id image.
///
/// Ids are `1..=65535` in insertion order; 0 in the id image means "no shape".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ShapeId(u16);

impl ShapeId {
    /// The value written to the id image (never 0).
    #[must_use]
    pub fn get(self) -> u16 {
        self.0
    }

    /// Index into [`Scene::objects`].
    #[must_use]
    pub fn index(self) -> usize {
        usize::from(self.0) - 1
    }
}

/// A primitive placed in the world.
#[derive(Debug, Clone, Copy)]
pub struct SceneObject {
    /// The shape, in its shape frame.
    pub primitive: Primitive,
    /// Pose of the shape frame in the world frame (m).
    pub world_from_shape: Isometry3<f64>,
    /// Colour in the rgb8 view.
    pub color: Rgb8,
}

/// A list of posed primitives: the collision geometry to render.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    objects: Vec<SceneObject>,
}

impl Scene {
    /// Most shapes a scene holds (ids are `u16`, 0 is reserved for "no shape").
    pub const MAX_SHAPES: usize = u16::MAX as usize;

    /// An empty scene.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a primitive with a palette colour; returns its id.
    ///
    /// # Errors
    /// [`RenderError::InvalidShapeDimension`], [`RenderError::InvalidPose`] (non-finite
    /// pose) or [`RenderError::TooManyShapes`].
    pub fn push(
        &mut self,
        primitive: impl Into<Primitive>,
        world_from_shape: Isometry3<f64>,
    ) -> Result<ShapeId, RenderError> {
        let color = PALETTE[self.objects.len() % PALETTE.len()];
        self.push_colored(primitive, world_from_shape, color)
    }

    /// Adds a primitive with a given colour; returns its id.
    ///
    /// # Errors
    /// As [`Scene::push`].
    pub fn push_colored(
        &mut self,
        primitive: impl Into<Primitive>,
        world_from_shape: Isometry3<f64>,
        color: Rgb8,
    ) -> Result<ShapeId, RenderError> {
        let primitive = primitive.into();
        primitive.validate()?;
        check_pose(&world_from_shape)?;
        let id = u16::try_from(self.objects.len() + 1)
            .map_err(|_| RenderError::TooManyShapes {
                max: Self::MAX_SHAPES,
            })
            .map(ShapeId)?;
        self.objects.push(SceneObject {
            primitive,
            world_from_shape,
            color,
        });
        Ok(id)
    }

    /// Moves a shape (e.g. every frame, from forward kinematics).
    ///
    /// # Errors
    /// [`RenderError::UnknownShape`] or [`RenderError::InvalidPose`].
    pub fn set_pose(
        &mut self,
        id: ShapeId,
        world_from_shape: Isometry3<f64>,
    ) -> Result<(), RenderError> {
        check_pose(&world_from_shape)?;
        self.objects
            .get_mut(id.index())
            .ok_or(RenderError::UnknownShape(id))?
            .world_from_shape = world_from_shape;
        Ok(())
    }

    /// The shape with this id.
    #[must_use]
    pub fn get(&self, id: ShapeId) -> Option<&SceneObject> {
        self.objects.get(id.index())
    }

    /// All shapes; index `i` has id `i + 1`.
    #[must_use]
    pub fn objects(&self) -> &[SceneObject] {
        &self.objects
    }

    /// Ids of all shapes in insertion order.
    pub fn ids(&self) -> impl Iterator<Item = ShapeId> + '_ {
        // The push checks keep len <= u16::MAX, so the conversion cannot fail.
        (1..=self.objects.len()).filter_map(|i| u16::try_from(i).ok().map(ShapeId))
    }

    /// Number of shapes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.objects.len()
    }

    /// `true` when the scene holds no shape.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.objects.is_empty()
    }

    /// Removes every shape (ids restart at 1).
    pub fn clear(&mut self) {
        self.objects.clear();
    }
}

fn check_pose(pose: &Isometry3<f64>) -> Result<(), RenderError> {
    let finite = pose
        .translation
        .vector
        .iter()
        .chain(pose.rotation.coords.iter())
        .all(|v| v.is_finite());
    if finite {
        Ok(())
    } else {
        Err(RenderError::InvalidPose {
            what: "shape pose is not finite",
        })
    }
}

fn vector_f32(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}
