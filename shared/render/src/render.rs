//! Z-buffer rasteriser: screen-space rectangles, analytic ray casts inside them.

use nalgebra::{Isometry3, Point3};
use parry3d::math::Pose;
use parry3d::math::Vector as Vec3;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::{Shape, TriMesh};

use crate::camera::Camera;
use crate::convert::to_parry_pose;
use crate::intersect::{self, Analytic};
use crate::scene::{Primitive, Scene};

/// Grey level of a surface seen edge-on, as a fraction of full white; a surface facing
/// the camera is 1.0. Keeps grazing surfaces distinguishable from the black background.
pub const AMBIENT: f32 = 0.1;

/// Which optional images a [`Frame`] carries besides depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Channels {
    /// Lambert-shaded greyscale (`mono8`).
    pub grey: bool,
    /// Per-shape colours, shaded (`rgb8`).
    pub rgb: bool,
    /// Shape id per pixel (`u16`, 0 = none).
    pub ids: bool,
}

impl Channels {
    /// Depth only: the fastest, what the hand network consumes.
    pub const DEPTH_ONLY: Self = Self {
        grey: false,
        rgb: false,
        ids: false,
    };
    /// Every image.
    pub const ALL: Self = Self {
        grey: true,
        rgb: true,
        ids: true,
    };
}

impl Default for Channels {
    /// Depth and greyscale.
    fn default() -> Self {
        Self {
            grey: true,
            rgb: false,
            ids: false,
        }
    }
}

/// A rendered frame: row-major images, `width * height` pixels, row 0 at the top.
///
/// * `depth_mm`: `16UC1`, Z along the optical axis in millimetres (rounded),
///   0 = no return (nothing hit, or the nearest surface outside the depth range).
/// * `grey`: `mono8`, `255 * (AMBIENT + (1 - AMBIENT) * cos(angle))` between the surface
///   normal and the ray back to the camera (a point light at the camera), 0 = no return.
/// * `rgb`: `rgb8`, each shape's colour times the same shading factor, 0 = no return.
/// * `ids`: the [`ShapeId`](crate::ShapeId) value of the visible shape, 0 = no return.
///
/// Optional images are empty when not requested in [`Channels`].
#[derive(Debug, Clone, Default)]
pub struct Frame {
    width: u32,
    height: u32,
    channels: Channels,
    depth_mm: Vec<u16>,
    grey: Vec<u8>,
    rgb: Vec<u8>,
    ids: Vec<u16>,
}

impl Frame {
    /// An empty frame that will carry `channels` once rendered into.
    #[must_use]
    pub fn new(channels: Channels) -> Self {
        Self {
            channels,
            ..Self::default()
        }
    }

    /// Image width (px).
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Image height (px).
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }
    /// The images this frame carries.
    #[must_use]
    pub fn channels(&self) -> Channels {
        self.channels
    }
    /// Depth image (mm, 0 = no return).
    #[must_use]
    pub fn depth_mm(&self) -> &[u16] {
        &self.depth_mm
    }
    /// Mutable depth image, e.g. for a noise model.
    pub fn depth_mm_mut(&mut self) -> &mut [u16] {
        &mut self.depth_mm
    }
    /// Depth at a pixel (mm); `None` outside the image.
    #[must_use]
    pub fn depth_mm_at(&self, u: u32, v: u32) -> Option<u16> {
        (u < self.width && v < self.height)
            .then(|| self.depth_mm[v as usize * self.width as usize + u as usize])
    }
    /// Greyscale image, if requested.
    #[must_use]
    pub fn grey(&self) -> Option<&[u8]> {
        self.channels.grey.then_some(self.grey.as_slice())
    }
    /// Colour image, 3 bytes per pixel, if requested.
    #[must_use]
    pub fn rgb(&self) -> Option<&[u8]> {
        self.channels.rgb.then_some(self.rgb.as_slice())
    }
    /// Shape-id image, if requested.
    #[must_use]
    pub fn ids(&self) -> Option<&[u16]> {
        self.channels.ids.then_some(self.ids.as_slice())
    }

    fn resize(&mut self, width: u32, height: u32) {
        let n = width as usize * height as usize;
        self.width = width;
        self.height = height;
        let sized = |on: bool, per_pixel: usize| if on { n * per_pixel } else { 0 };
        self.depth_mm.resize(n, 0);
        self.grey.resize(sized(self.channels.grey, 1), 0);
        self.rgb.resize(sized(self.channels.rgb, 3), 0);
        self.ids.resize(sized(self.channels.ids, 1), 0);
    }
}

/// How rays meet shapes. Every backend produces the same image up to rounding on
/// silhouette pixels; only [`RayBackend::Analytic`] is meant for real use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum RayBackend {
    /// Own closed-form intersections, pixels inside each shape's projected rectangle.
    #[default]
    Analytic,
    /// parry3d's `RayCast` in the shape frame, pixels inside each projected rectangle.
    /// Note parry3d's `Cylinder` cast is GJK-based and approximate (see above).
    ParryInRect,
    /// parry3d's `RayCast` on world-frame rays, every pixel against every shape: slow,
    /// shares no geometry code with the other two; the reference for tests and benches.
    /// Cylinders are cast against a 1024-segment parry3d `TriMesh`, because parry3d's
    /// GJK-based `Cylinder` cast is off by up to millimetres near the cap rims.
    ParryBruteForce,
}

/// A shape expressed in the camera's optical frame, ready to rasterise.
#[derive(Debug, Clone, Copy)]
struct Prepared {
    /// Index in the scene.
    index: usize,
    /// Camera origin in the shape frame.
    origin: Vec3,
    /// Columns of `shape_from_camera`'s rotation: `dir = c0 * x + c1 * y + c2`.
    c0: Vec3,
    c1: Vec3,
    c2: Vec3,
    /// Pixel rectangle, inclusive.
    rect: Rect,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Rect {
    u0: usize,
    v0: usize,
    u1: usize,
    v1: usize,
}

/// Renders [`Scene`]s into [`Frame`]s; keeps scratch buffers between frames, so one
/// renderer per camera stream avoids allocations after the first frame.
///
/// Single-threaded and deterministic: the same scene and camera give the same bytes.
#[derive(Debug, Clone, Default)]
pub struct Renderer {
    backend: RayBackend,
    /// Nearest `t` (= depth Z in m) per pixel.
    z: Vec<f32>,
    /// Scene index + 1 of the nearest shape, 0 = none.
    hit: Vec<u16>,
    /// Shading factor of the nearest hit.
    shade: Vec<f32>,
    /// Ray X/Z per column and Y/Z per row.
    xs: Vec<f32>,
    ys: Vec<f32>,
    prepared: Vec<Prepared>,
}

impl Renderer {
    /// A renderer with the [`RayBackend::Analytic`] backend.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// A renderer with the given backend.
    #[must_use]
    pub fn with_backend(backend: RayBackend) -> Self {
        Self {
            backend,
            ..Self::default()
        }
    }

    /// The backend in use.
    #[must_use]
    pub fn backend(&self) -> RayBackend {
        self.backend
    }

    /// Renders `scene` seen by `camera` into `frame`, resizing it to the camera's image.
    pub fn render(&mut self, scene: &Scene, camera: &Camera, frame: &mut Frame) {
        let k = &camera.intrinsics;
        let (w, h) = (k.width() as usize, k.height() as usize);
        let n = w * h;
        // Stale values are fine: only `region` is read, and it is cleared below.
        self.z.resize(n, f32::INFINITY);
        self.hit.resize(n, 0);
        self.shade.resize(n, 0.0);
        self.xs.clear();
        self.xs
            .extend((0..w).map(|u| ((u as f64 - k.cx()) / k.fx()) as f32));
        self.ys.clear();
        self.ys
            .extend((0..h).map(|v| ((v as f64 - k.cy()) / k.fy()) as f32));

        // The part of the image any shape can touch this frame.
        let region = match self.backend {
            RayBackend::Analytic | RayBackend::ParryInRect => self.prepare_all(scene, camera),
            RayBackend::ParryBruteForce => Some(full_rect(k.width(), k.height())),
        };
        if let Some(region) = region {
            for v in region.v0..=region.v1 {
                let row = v * w;
                self.z[row + region.u0..=row + region.u1].fill(f32::INFINITY);
                self.hit[row + region.u0..=row + region.u1].fill(0);
            }
            match self.backend {
                RayBackend::Analytic | RayBackend::ParryInRect => {
                    let shaded = frame.channels.grey || frame.channels.rgb;
                    self.rasterise(scene, shaded);
                }
                RayBackend::ParryBruteForce => self.brute_force(scene, camera),
            }
        }
        self.resolve(scene, camera, region, frame);
    }

    /// Places every shape in the camera frame and bounds its image; returns the union
    /// of the pixel rectangles, `None` when nothing can be seen.
    fn prepare_all(&mut self, scene: &Scene, camera: &Camera) -> Option<Rect> {
        let camera_from_world = camera.world_from_camera.inverse();
        self.prepared.clear();
        let mut union: Option<Rect> = None;
        for (index, object) in scene.objects().iter().enumerate() {
            let camera_from_shape = camera_from_world * object.world_from_shape;
            if let Some(p) = prepare(index, &object.primitive, &camera_from_shape, camera) {
                union = Some(match union {
                    None => p.rect,
                    Some(r) => Rect {
                        u0: r.u0.min(p.rect.u0),
                        v0: r.v0.min(p.rect.v0),
                        u1: r.u1.max(p.rect.u1),
                        v1: r.v1.max(p.rect.v1),
                    },
                });
                self.prepared.push(p);
            }
        }
        union
    }

    /// Ray-casts every prepared shape inside its pixel rectangle.
    fn rasterise(&mut self, scene: &Scene, shaded: bool) {
        let mut target = Target {
            width: self.xs.len(),
            shaded,
            z: &mut self.z,
            hit: &mut self.hit,
            shade: &mut self.shade,
            xs: &self.xs,
            ys: &self.ys,
        };
        for p in &self.prepared {
            let primitive = &scene.objects()[p.index].primitive;
            // One monomorphised pixel loop per shape kind: no dispatch per pixel.
            match self.backend {
                RayBackend::Analytic => match analytic_form(primitive) {
                    Analytic::Sphere { center, r2 } => {
                        target.fill(
                            p,
                            #[inline(always)]
                            |o, d| intersect::sphere(o, d, center, r2),
                        );
                    }
                    Analytic::Capsule { a, axis, len, r2 } => {
                        target.fill(
                            p,
                            #[inline(always)]
                            |o, d| intersect::capsule(o, d, a, axis, len, r2),
                        );
                    }
                    Analytic::Cuboid { half } => {
                        target.fill(
                            p,
                            #[inline(always)]
                            |o, d| intersect::cuboid(o, d, half),
                        );
                    }
                    Analytic::Cylinder { half_height, r2 } => {
                        target.fill(
                            p,
                            #[inline(always)]
                            |o, d| intersect::cylinder(o, d, half_height, r2),
                        );
                    }
                },
                _ => match primitive {
                    Primitive::Ball(s) => target.fill(
                        p,
                        #[inline(always)]
                        |o, d| parry_local(s, o, d),
                    ),
                    Primitive::Capsule(s) => target.fill(
                        p,
                        #[inline(always)]
                        |o, d| parry_local(s, o, d),
                    ),
                    Primitive::Cuboid(s) => target.fill(
                        p,
                        #[inline(always)]
                        |o, d| parry_local(s, o, d),
                    ),
                    Primitive::Cylinder(s) => target.fill(
                        p,
                        #[inline(always)]
                        |o, d| parry_local(s, o, d),
                    ),
                },
            }
        }
    }

    /// Every pixel against every shape with parry3d in the world frame.
    fn brute_force(&mut self, scene: &Scene, camera: &Camera) {
        let cam = to_parry_pose(&camera.world_from_camera);
        // parry3d's `Cylinder` ray cast is GJK with a ~1e-3 relative tolerance (errors
        // of millimetres near the cap rims); a fine mesh is the exact reference.
        let meshes: Vec<Option<TriMesh>> = scene
            .objects()
            .iter()
            .map(|o| match o.primitive {
                Primitive::Cylinder(c) => {
                    let (vertices, indices) = c.to_trimesh(REFERENCE_CYLINDER_SEGMENTS);
                    TriMesh::new(vertices, indices).ok()
                }
                _ => None,
            })
            .collect();
        let shapes: Vec<(&dyn Shape, Pose)> = scene
            .objects()
            .iter()
            .zip(&meshes)
            .map(|(o, mesh)| {
                let shape = match mesh {
                    Some(mesh) => mesh as &dyn Shape,
                    None => o.primitive.as_shape(),
                };
                (shape, to_parry_pose(&o.world_from_shape))
            })
            .collect();
        let w = camera.intrinsics.width() as usize;
        for (v, &y) in self.ys.iter().enumerate() {
            for (u, &x) in self.xs.iter().enumerate() {
                let dir = cam.rotation * Vec3::new(x, y, 1.0);
                let ray = Ray::new(cam.translation, dir);
                let i = v * w + u;
                for (index, (shape, pose)) in shapes.iter().enumerate() {
                    if let Some(h) = shape.cast_ray_and_get_normal(pose, &ray, f32::MAX, true)
                        && h.time_of_impact < self.z[i]
                    {
                        self.z[i] = h.time_of_impact;
                        self.hit[i] = (index + 1) as u16;
                        self.shade[i] = lambert(h.normal, dir);
                    }
                }
            }
        }
    }

    /// Applies the depth range and writes the requested images: background outside
    /// `region`, the z-buffer's content inside.
    fn resolve(&self, scene: &Scene, camera: &Camera, region: Option<Rect>, frame: &mut Frame) {
        let k = &camera.intrinsics;
        frame.resize(k.width(), k.height());
        frame.depth_mm.fill(0);
        frame.grey.fill(0);
        frame.rgb.fill(0);
        frame.ids.fill(0);
        let Some(region) = region else {
            return;
        };
        let w = k.width() as usize;
        let min = camera.range.min_m() as f32;
        let max = camera.range.max_m() as f32;
        let channels = frame.channels;
        for v in region.v0..=region.v1 {
            for i in v * w + region.u0..=v * w + region.u1 {
                let (z, hit) = (self.z[i], self.hit[i]);
                // z <= 65.535 m, so the depth fits a u16; a depth that rounds to 0 mm
                // (camera inside a solid with a zero near limit) is no return either.
                let depth_mm = round_to_u16(z * 1000.0);
                if hit == 0 || z < min || z > max || depth_mm == 0 {
                    continue;
                }
                frame.depth_mm[i] = depth_mm;
                let shade = self.shade[i];
                if channels.grey {
                    frame.grey[i] = round_to_u16(255.0 * shade) as u8;
                }
                if channels.ids {
                    frame.ids[i] = hit;
                }
                if channels.rgb {
                    let color = scene.objects()[usize::from(hit) - 1].color.0;
                    for (out, c) in frame.rgb[3 * i..3 * i + 3].iter_mut().zip(color) {
                        *out = round_to_u16(f32::from(c) * shade) as u8;
                    }
                }
            }
        }
    }
}

/// The per-pixel buffers one shape is drawn into.
struct Target<'a> {
    width: usize,
    /// Whether shading is needed (grey or rgb requested).
    shaded: bool,
    z: &'a mut [f32],
    hit: &'a mut [u16],
    shade: &'a mut [f32],
    xs: &'a [f32],
    ys: &'a [f32],
}

impl Target<'_> {
    /// Casts the rays of every pixel in `p.rect` with `cast(origin, dir)` (shape frame,
    /// returns `(t, outward normal)`) and keeps the nearest hits.
    #[inline(always)]
    fn fill<F>(&mut self, p: &Prepared, cast: F)
    where
        F: Fn(Vec3, Vec3) -> Option<(f32, Vec3)>,
    {
        if self.shaded {
            self.fill_with::<true, F>(p, cast);
        } else {
            self.fill_with::<false, F>(p, cast);
        }
    }

    // One out-of-line loop per shape kind and shading mode keeps each loop small.
    #[inline(never)]
    fn fill_with<const SHADE: bool, F>(&mut self, p: &Prepared, cast: F)
    where
        F: Fn(Vec3, Vec3) -> Option<(f32, Vec3)>,
    {
        let id = (p.index + 1) as u16;
        for v in p.rect.v0..=p.rect.v1 {
            let row_dir = p.c1 * self.ys[v] + p.c2;
            let row = v * self.width;
            for u in p.rect.u0..=p.rect.u1 {
                let dir = p.c0 * self.xs[u] + row_dir;
                if let Some((t, normal)) = cast(p.origin, dir) {
                    let i = row + u;
                    if t < self.z[i] {
                        self.z[i] = t;
                        self.hit[i] = id;
                        if SHADE {
                            self.shade[i] = lambert(normal, dir);
                        }
                    }
                }
            }
        }
    }
}

/// parry3d's ray cast in the shape frame.
#[inline(always)]
fn parry_local<S: RayCast>(shape: &S, origin: Vec3, dir: Vec3) -> Option<(f32, Vec3)> {
    shape
        .cast_local_ray_and_get_normal(&Ray::new(origin, dir), f32::MAX, true)
        .map(|hit| (hit.time_of_impact, hit.normal))
}

/// Rounds a value in `[0, 65535]` to the nearest integer. `f32::round` and `trunc` are
/// libm calls on the x86-64 baseline (no SSE4.1); this is an add and a converting
/// truncation (`as` saturates).
#[inline(always)]
fn round_to_u16(x: f32) -> u16 {
    (x + 0.5) as u16
}

/// Shading factor for a surface with (unnormalised) `normal` seen along `dir`.
#[inline(always)]
fn lambert(normal: Vec3, dir: Vec3) -> f32 {
    let denom = (normal.length_squared() * dir.length_squared()).sqrt();
    let cos = if denom > 0.0 {
        (normal.dot(dir).abs() / denom).min(1.0)
    } else {
        1.0
    };
    AMBIENT + (1.0 - AMBIENT) * cos
}

/// The closed-form description of a primitive.
#[inline(always)]
fn analytic_form(primitive: &Primitive) -> Analytic {
    match primitive {
        Primitive::Ball(b) => Analytic::Sphere {
            center: Vec3::ZERO,
            r2: b.radius * b.radius,
        },
        Primitive::Capsule(c) => {
            let ab = c.segment.b - c.segment.a;
            let len = ab.length();
            if len > 0.0 {
                Analytic::Capsule {
                    a: c.segment.a,
                    axis: ab / len,
                    len,
                    r2: c.radius * c.radius,
                }
            } else {
                Analytic::Sphere {
                    center: c.segment.a,
                    r2: c.radius * c.radius,
                }
            }
        }
        Primitive::Cuboid(b) => Analytic::Cuboid {
            half: b.half_extents,
        },
        Primitive::Cylinder(c) => Analytic::Cylinder {
            half_height: c.half_height,
            r2: c.radius * c.radius,
        },
    }
}

/// Segments of the mesh standing in for a cylinder in [`RayBackend::ParryBruteForce`]:
/// the mesh is inscribed, at most `r (1 - cos(pi / 1024))` = 0.5 um inside at r = 0.1 m.
const REFERENCE_CYLINDER_SEGMENTS: u32 = 1024;

/// Below this Z (m) a bounding volume counts as reaching behind the camera and the whole
/// image is searched.
const NEAR_EPS_M: f64 = 1e-3;

/// Places a shape in the camera frame and bounds its image; `None` when it cannot
/// appear (behind the camera, beyond the far limit, or outside the image).
fn prepare(
    index: usize,
    primitive: &Primitive,
    camera_from_shape: &Isometry3<f64>,
    camera: &Camera,
) -> Option<Prepared> {
    let k = &camera.intrinsics;
    let far = camera.range.max_m();
    let mut spheres = [(Point3::origin(), 0.0); 2];
    let mut corners = [Point3::origin(); 8];
    let bounds = match primitive {
        Primitive::Ball(b) => {
            spheres[0] = (camera_from_shape * Point3::origin(), f64::from(b.radius));
            Bounds::Spheres(&spheres[..1])
        }
        Primitive::Capsule(c) => {
            let r = f64::from(c.radius);
            for (out, p) in spheres.iter_mut().zip([c.segment.a, c.segment.b]) {
                let p = Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
                *out = (camera_from_shape * p, r);
            }
            Bounds::Spheres(&spheres)
        }
        Primitive::Cuboid(b) => {
            let h = b.half_extents;
            box_corners(&mut corners, [h.x, h.y, h.z], camera_from_shape);
            Bounds::Points(&corners)
        }
        Primitive::Cylinder(c) => {
            box_corners(
                &mut corners,
                [c.radius, c.half_height, c.radius],
                camera_from_shape,
            );
            Bounds::Points(&corners)
        }
    };
    let (min_z, max_z) = bounds.z_extent();
    if max_z <= 0.0 || min_z > far || !min_z.is_finite() || !max_z.is_finite() {
        return None;
    }
    let rect = if min_z < NEAR_EPS_M {
        Some(full_rect(k.width(), k.height()))
    } else {
        bounds.pixel_rect(camera)
    }?;
    let shape_from_camera = camera_from_shape.inverse();
    let r = shape_from_camera.rotation.to_rotation_matrix();
    let m = r.matrix();
    let col = |j: usize| Vec3::new(m[(0, j)] as f32, m[(1, j)] as f32, m[(2, j)] as f32);
    let t = &shape_from_camera.translation.vector;
    Some(Prepared {
        index,
        origin: Vec3::new(t.x as f32, t.y as f32, t.z as f32),
        c0: col(0),
        c1: col(1),
        c2: col(2),
        rect,
    })
}

fn box_corners(out: &mut [Point3<f64>; 8], half: [f32; 3], camera_from_shape: &Isometry3<f64>) {
    let [hx, hy, hz] = half.map(f64::from);
    for (i, corner) in out.iter_mut().enumerate() {
        let sign = |bit: usize| if i & bit == 0 { -1.0 } else { 1.0 };
        *corner = camera_from_shape * Point3::new(sign(1) * hx, sign(2) * hy, sign(4) * hz);
    }
}

fn full_rect(width: u32, height: u32) -> Rect {
    Rect {
        u0: 0,
        v0: 0,
        u1: width as usize - 1,
        v1: height as usize - 1,
    }
}

/// Bounding volumes in the camera frame whose image contains the shape's image.
enum Bounds<'a> {
    /// Union of spheres `(centre, radius)`; a capsule is the convex hull of two, and the
    /// rectangle of the hull's image equals the union of the spheres' rectangles.
    Spheres(&'a [(Point3<f64>, f64)]),
    /// Convex hull of points (box corners).
    Points(&'a [Point3<f64>]),
}

impl Bounds<'_> {
    fn z_extent(&self) -> (f64, f64) {
        match self {
            Self::Spheres(s) => s
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, (c, r)| {
                    (acc.0.min(c.z - r), acc.1.max(c.z + r))
                }),
            Self::Points(p) => p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |acc, c| {
                (acc.0.min(c.z), acc.1.max(c.z))
            }),
        }
    }

    /// Pixel rectangle (inclusive, widened by one pixel against rounding) of the image,
    /// for volumes entirely in front of the camera; `None` if it misses the image.
    fn pixel_rect(&self, camera: &Camera) -> Option<Rect> {
        let k = &camera.intrinsics;
        // Ranges of X/Z and Y/Z over the volume.
        let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        match self {
            Self::Spheres(spheres) => {
                for (c, r) in *spheres {
                    let (lo, hi) = sphere_slope_range(c.x, c.z, *r);
                    x_lo = x_lo.min(lo);
                    x_hi = x_hi.max(hi);
                    let (lo, hi) = sphere_slope_range(c.y, c.z, *r);
                    y_lo = y_lo.min(lo);
                    y_hi = y_hi.max(hi);
                }
            }
            Self::Points(points) => {
                for p in *points {
                    x_lo = x_lo.min(p.x / p.z);
                    x_hi = x_hi.max(p.x / p.z);
                    y_lo = y_lo.min(p.y / p.z);
                    y_hi = y_hi.max(p.y / p.z);
                }
            }
        }
        let span = |lo: f64, hi: f64, f: f64, c: f64, size: u32| -> Option<(usize, usize)> {
            let a = (f * lo + c).floor() - 1.0;
            let b = (f * hi + c).ceil() + 1.0;
            let last = f64::from(size) - 1.0;
            if b < 0.0 || a > last {
                return None;
            }
            Some((a.max(0.0) as usize, b.min(last) as usize))
        };
        let (u0, u1) = span(x_lo, x_hi, k.fx(), k.cx(), k.width())?;
        let (v0, v1) = span(y_lo, y_hi, k.fy(), k.cy(), k.height())?;
        Some(Rect { u0, v0, u1, v1 })
    }
}

/// Range of `a / z` over a sphere whose centre has coordinates `(a, z)` in a plane
/// through the camera, radius `r`, with `z > r` (the sphere in front of the camera):
/// the slopes of the two tangents from the origin,
/// `(a z +- r sqrt(a^2 + z^2 - r^2)) / (z^2 - r^2)`.
fn sphere_slope_range(a: f64, z: f64, r: f64) -> (f64, f64) {
    let denom = z * z - r * r;
    let root = r * (a * a + z * z - r * r).max(0.0).sqrt();
    ((a * z - root) / denom, (a * z + root) / denom)
}
