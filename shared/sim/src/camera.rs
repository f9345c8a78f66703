//! The remote site's camera views: the simulated world drawn by [`teleop_render`] from
//! two fixed cameras, **top** (above the workspace, looking down) and **side**, as the
//! images a camera driver would publish.
//!
//! # What is drawn
//!
//! * the finger links: the simulator's own contact capsules
//!   ([`World::link_capsules_world`]), so what the operator sees touching is what the
//!   contact model touches;
//! * every other robot link with collision geometry, from the URDF's collision
//!   primitives as [`teleop_collision::CollisionModel`] reads them (capsules merged):
//!   the PR2 base, torso and arm, the Shadow forearm mount, wrist and palm box, and
//!   the boxes the contact model leaves out (LF metacarpal);
//! * the objects ([`Object::world_capsule`](super::Object::world_capsule)).
//!
//! Colours: PR2 links grey, the Shadow hand skin-coloured, objects from
//! [`OBJECT_COLORS`]; shaded by `teleop_render`'s Lambert model with the light at the
//! camera; the background is black. (A floor was left out: a box behind every pixel
//! doubled the rendering time and, without shadows, says little about height.)
//!
//! # Cameras
//!
//! Pinhole cameras with square pixels, posed by a position, a look-at point and an up
//! direction in the world (PR2 `base_link`) frame ([`CameraViewsConfig`]); the image's
//! optical frames are `remote_camera_top_optical_frame` and
//! `remote_camera_side_optical_frame` (ROS optical convention: +Z forward, +X right,
//! +Y down). The defaults frame the hand and the task object of the touching scene
//! with the arm at [`WORKING_POSTURE_RAD`](crate::WORKING_POSTURE_RAD).
//!
//! # Cost
//!
//! The scene is built once; [`SceneCameras::render`] only moves its shapes
//! ([`Scene::set_pose`]) and renders into frames kept between calls, so after the first
//! frame it does not allocate. Both 320x240 views take about 1.3 ms
//! (`cargo bench --workspace --bench sim`). Deterministic: the same world gives
//! the same bytes.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_collision::{CollisionError, CollisionModel, ModelSettings};
use teleop_kinematics::LinkId;
use teleop_msgs::{Header, Image, Time, encodings};
use teleop_render::{
    Camera, Channels, DepthRange, Frame, Intrinsics, Primitive, RenderError, Renderer, Rgb8, Scene,
    ShapeId,
};

use super::error::SimError;
use super::geometry::Capsule;
use super::world::World;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_kinematics::{KinematicState, Robot};

/// Smallest accepted image side, px.
pub const MIN_IMAGE_SIDE_PX: u32 = 16;
/// Largest accepted image side, px.
pub const MAX_IMAGE_SIDE_PX: u32 = 1920;
/// Highest accepted frame rate, Hz.
pub const MAX_RATE_HZ: f64 = 60.0;

/// Colour of the PR2's links.
pub const ARM_COLOR: Rgb8 = Rgb8([165, 168, 175]);
/// Colour of the Shadow hand's links.
pub const HAND_COLOR: Rgb8 = Rgb8([232, 184, 150]);
/// Colours of the objects, by index in [`World::objects`] (cycled).
pub const OBJECT_COLORS: [Rgb8; 4] = [
    Rgb8([40, 110, 230]),
    Rgb8([220, 60, 50]),
    Rgb8([60, 180, 80]),
    Rgb8([240, 200, 40]),
];

/// Depth interval of the views (what lies outside is background), m.
const NEAR_M: f64 = 0.02;
const FAR_M: f64 = 20.0;
/// Capsule segments shorter than this are drawn as balls, m.
const BALL_BELOW_M: f64 = 1e-9;

/// One of the two views.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum View {
    /// Above the workspace, looking down.
    Top,
    /// Beside the workspace.
    Side,
}

impl View {
    /// Both views, in the order of [`SceneCameras`]' frames.
    pub const ALL: [View; 2] = [View::Top, View::Side];

    /// `"top"` or `"side"`.
    pub fn name(self) -> &'static str {
        match self {
            View::Top => "top",
            View::Side => "side",
        }
    }

    /// The optical frame the images are stamped with.
    pub fn frame_id(self) -> &'static str {
        match self {
            View::Top => "remote_camera_top_optical_frame",
            View::Side => "remote_camera_side_optical_frame",
        }
    }

    fn index(self) -> usize {
        match self {
            View::Top => 0,
            View::Side => 1,
        }
    }
}

/// Where a camera is: world (PR2 `base_link`) frame, metres. All three fields are
/// needed when a view is configured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewPose {
    /// Centre of projection, m.
    pub position_m: [f64; 3],
    /// A point on the optical axis (it appears at the image centre), m.
    pub look_at_m: [f64; 3],
    /// World direction that points up in the image; not parallel to the viewing
    /// direction.
    pub up: [f64; 3],
}

impl ViewPose {
    /// The optical frame's pose in the world.
    ///
    /// # Errors
    /// [`RenderError::InvalidPose`] for non-finite numbers, `position == look_at`, or
    /// `up` parallel to the viewing direction.
    pub fn world_from_camera(&self) -> Result<Isometry3<f64>, RenderError> {
        Camera::look_at(
            &Point3::from(self.position_m),
            &Point3::from(self.look_at_m),
            &Vector3::from(self.up),
        )
    }
}

/// Settings of the two camera views.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraViewsConfig {
    /// Render and publish the views. Default true.
    pub enabled: bool,
    /// Frames per second of each view, in (0, 60]. Default 15 (the topics' nominal
    /// rate).
    pub rate_hz: f64,
    /// Image width, px, in [16, 1920]. Default 320.
    pub width_px: u32,
    /// Image height, px, in [16, 1920]. Default 240.
    pub height_px: u32,
    /// Horizontal field of view, deg, in [10, 150] (square pixels). Default 60.
    pub horizontal_fov_deg: f64,
    /// The top view. Default: 0.42 m above the hand and a little behind it to its
    /// right, looking down at it, the robot's forward (+x) up in the image.
    pub top: ViewPose,
    /// The side view. Default: 0.4 m to the hand's right (-y), a little above and in
    /// front, world up (+z) up in the image.
    pub side: ViewPose,
}

/// Centre of the default views: between the palm and the "mouse" of the touching scene
/// at [`WORKING_POSTURE_RAD`](crate::WORKING_POSTURE_RAD) (PR2 `base_link` frame, m).
const DEFAULT_TARGET_M: [f64; 3] = [0.70, -0.19, 0.78];

impl Default for CameraViewsConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            rate_hz: 15.0,
            width_px: 320,
            height_px: 240,
            horizontal_fov_deg: 60.0,
            top: ViewPose {
                position_m: [0.62, -0.29, 1.2],
                look_at_m: DEFAULT_TARGET_M,
                up: [1.0, 0.0, 0.0],
            },
            side: ViewPose {
                position_m: [0.78, -0.59, 0.88],
                look_at_m: DEFAULT_TARGET_M,
                up: [0.0, 0.0, 1.0],
            },
        }
    }
}

impl CameraViewsConfig {
    /// Checks every number and both poses.
    ///
    /// # Errors
    /// [`CameraError::InvalidConfig`] naming the first bad field, or
    /// [`CameraError::InvalidView`] for a degenerate pose.
    pub fn validate(&self) -> Result<(), CameraError> {
        let bad = |field, value: f64, reason| {
            Err(CameraError::InvalidConfig {
                field,
                value,
                reason,
            })
        };
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= MAX_RATE_HZ) {
            return bad("rate_hz", self.rate_hz, "must be in (0, 60]");
        }
        for (field, side) in [("width_px", self.width_px), ("height_px", self.height_px)] {
            if !(MIN_IMAGE_SIDE_PX..=MAX_IMAGE_SIDE_PX).contains(&side) {
                return bad(field, f64::from(side), "must be in [16, 1920]");
            }
        }
        let fov = self.horizontal_fov_deg;
        if !(fov.is_finite() && (10.0..=150.0).contains(&fov)) {
            return bad("horizontal_fov_deg", fov, "must be in [10, 150]");
        }
        for view in View::ALL {
            self.pose(view)
                .world_from_camera()
                .map_err(|source| CameraError::InvalidView {
                    view: view.name(),
                    source,
                })?;
        }
        Ok(())
    }

    /// The pose settings of `view`.
    pub fn pose(&self, view: View) -> &ViewPose {
        match view {
            View::Top => &self.top,
            View::Side => &self.side,
        }
    }

    /// The camera of `view`.
    ///
    /// # Errors
    /// As [`CameraViewsConfig::validate`].
    pub fn camera(&self, view: View) -> Result<Camera, CameraError> {
        self.validate()?;
        let invalid = |source| CameraError::InvalidView {
            view: view.name(),
            source,
        };
        let (w, h) = (self.width_px, self.height_px);
        let f = (f64::from(w) / 2.0) / (self.horizontal_fov_deg.to_radians() / 2.0).tan();
        let intrinsics = Intrinsics::new(
            f,
            f,
            (f64::from(w) - 1.0) / 2.0,
            (f64::from(h) - 1.0) / 2.0,
            w,
            h,
        )
        .map_err(invalid)?;
        let range = DepthRange::new(NEAR_M, FAR_M).map_err(invalid)?;
        let pose = self.pose(view).world_from_camera().map_err(invalid)?;
        Ok(Camera::new(intrinsics, range, pose))
    }
}

/// Why the camera views could not be set up.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CameraError {
    /// A number of [`CameraViewsConfig`] is out of range.
    #[error("invalid camera config {field} = {value}: {reason}")]
    InvalidConfig {
        /// Field name, e.g. `width_px`.
        field: &'static str,
        /// The offending value.
        value: f64,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// A view's pose is not finite or degenerate.
    #[error("camera view `{view}`: {source}")]
    InvalidView {
        /// `top` or `side`.
        view: &'static str,
        /// What the renderer refused.
        source: RenderError,
    },
    /// A shape could not be added to or moved in the scene.
    #[error("camera scene: {0}")]
    Scene(#[from] RenderError),
    /// The robot's collision geometry could not be read.
    #[error("robot collision geometry: {0}")]
    Collision(#[from] CollisionError),
    /// An object's geometry is invalid.
    #[error("object: {0}")]
    Object(#[from] SimError),
}

/// What a shape of the scene shows (look it up with [`SceneCameras::part`] from a
/// value of a frame's id image).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Part {
    /// A PR2 link (base, torso, arm).
    Arm,
    /// A Shadow hand link (forearm mount, wrist, palm, fingers).
    Hand,
    /// An object, by index in the world's list of objects.
    Object(usize),
    /// The table the objects stand on.
    Table,
}

/// An object or fixture of the scene as the cameras draw it.
#[derive(Debug, Clone, Copy)]
pub struct SceneObject {
    pub primitive: Primitive,
    /// The render shape's pose in the world.
    pub pose: Isometry3<f64>,
    pub color: Rgb8,
    pub part: Part,
}

/// What the cameras need from a simulated world: the robot and its configuration, and
/// the environment's shapes with their current poses.
pub trait CameraScene {
    /// The robot description (PR2 arm with the Shadow hand).
    fn scene_robot(&self) -> &Robot;
    /// The robot's current configuration (ground truth).
    fn scene_kinematics(&self) -> &KinematicState;
    /// The finger links as the world's contact model has them (world frame), drawn in
    /// place of their URDF collision primitives; `None`: the world collides with those
    /// primitives, so they are drawn as the other links are.
    fn finger_capsules(&self) -> Option<Vec<Capsule>>;
    /// The objects and fixtures, posed, into `out` (cleared first).
    ///
    /// # Errors
    /// [`CameraError::Object`] for an object whose geometry is invalid.
    fn scene_objects(&self, out: &mut Vec<SceneObject>) -> Result<(), CameraError>;
}

impl CameraScene for World {
    fn scene_robot(&self) -> &Robot {
        self.robot()
    }

    fn scene_kinematics(&self) -> &KinematicState {
        self.kinematic_state()
    }

    fn finger_capsules(&self) -> Option<Vec<Capsule>> {
        Some(self.link_capsules_world(None).collect())
    }

    fn scene_objects(&self, out: &mut Vec<SceneObject>) -> Result<(), CameraError> {
        out.clear();
        for (index, object) in self.objects().iter().enumerate() {
            let capsule = object.world_capsule()?;
            let (primitive, ball) = capsule_primitive(&capsule);
            let pose = if ball {
                Isometry3::translation(capsule.a.x, capsule.a.y, capsule.a.z)
            } else {
                segment_pose(&capsule.a, &capsule.b)
            };
            out.push(SceneObject {
                primitive,
                pose,
                color: OBJECT_COLORS[index % OBJECT_COLORS.len()],
                part: Part::Object(index),
            });
        }
        Ok(())
    }
}

/// A shape that follows a robot link.
#[derive(Debug, Clone, Copy)]
struct LinkShape {
    id: ShapeId,
    link: LinkId,
    /// Shape frame in the link frame.
    offset: Isometry3<f64>,
}

/// A shape drawn from a capsule the simulator gives in world coordinates.
#[derive(Debug, Clone, Copy)]
struct CapsuleShape {
    id: ShapeId,
    /// Drawn as a ball (zero-length segment).
    ball: bool,
}

/// The two views of a [`World`]: the scene (built once), the cameras, a renderer and a
/// frame per view.
#[derive(Debug, Clone)]
pub struct SceneCameras {
    config: CameraViewsConfig,
    cameras: [Camera; 2],
    scene: Scene,
    parts: Vec<Part>,
    links: Vec<LinkShape>,
    fingers: Vec<CapsuleShape>,
    objects: Vec<ShapeId>,
    /// The world's objects at the last update (reused).
    object_buf: Vec<SceneObject>,
    renderer: Renderer,
    frames: [Frame; 2],
}

impl SceneCameras {
    /// The views of `world` (its current robot geometry and objects).
    ///
    /// # Errors
    /// [`CameraError`] for a bad config or geometry the renderer refuses.
    pub fn new(
        world: &(impl CameraScene + ?Sized),
        config: &CameraViewsConfig,
    ) -> Result<Self, CameraError> {
        let cameras = [config.camera(View::Top)?, config.camera(View::Side)?];
        let channels = Channels {
            grey: false,
            rgb: true,
            ids: true,
        };
        let mut this = Self {
            config: config.clone(),
            cameras,
            scene: Scene::new(),
            parts: Vec::new(),
            links: Vec::new(),
            fingers: Vec::new(),
            objects: Vec::new(),
            object_buf: Vec::new(),
            renderer: Renderer::new(),
            frames: [Frame::new(channels), Frame::new(channels)],
        };
        this.build(world)?;
        Ok(this)
    }

    /// The settings in use.
    pub fn config(&self) -> &CameraViewsConfig {
        &self.config
    }

    /// The camera of `view`.
    pub fn camera(&self, view: View) -> &Camera {
        &self.cameras[view.index()]
    }

    /// The scene as last posed.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// What the shape with id-image value `id` shows; `None` for 0 (background) or an
    /// unknown id.
    pub fn part(&self, id: u16) -> Option<Part> {
        usize::from(id)
            .checked_sub(1)
            .and_then(|i| self.parts.get(i))
            .copied()
    }

    /// The last rendered frame of `view` (rgb8 colour, depth, shape ids).
    pub fn frame(&self, view: View) -> &Frame {
        &self.frames[view.index()]
    }

    /// Poses the scene from `world` and renders both views.
    ///
    /// # Errors
    /// [`CameraError`] if a shape's pose is not finite or the world's objects are
    /// invalid.
    pub fn render(&mut self, world: &(impl CameraScene + ?Sized)) -> Result<(), CameraError> {
        self.update(world)?;
        for (camera, frame) in self.cameras.iter().zip(self.frames.iter_mut()) {
            self.renderer.render(&self.scene, camera, frame);
        }
        Ok(())
    }

    /// Poses the scene from `world` and renders one view.
    ///
    /// # Errors
    /// As [`SceneCameras::render`].
    pub fn render_view(
        &mut self,
        world: &(impl CameraScene + ?Sized),
        view: View,
    ) -> Result<(), CameraError> {
        self.update(world)?;
        let i = view.index();
        self.renderer
            .render(&self.scene, &self.cameras[i], &mut self.frames[i]);
        Ok(())
    }

    /// Writes the last frame of `view` into `image` as `rgb8`, stamped `stamp` in the
    /// view's optical frame. Reuses `image`'s buffers.
    pub fn write_image(&self, view: View, stamp: Time, image: &mut Image) {
        let frame = self.frame(view);
        image.header.stamp = stamp;
        set_string(&mut image.header.frame_id, view.frame_id());
        set_string(&mut image.encoding, encodings::RGB8);
        image.width = frame.width();
        image.height = frame.height();
        image.is_bigendian = 0;
        image.step = frame.width() * 3;
        image.data.clear();
        image
            .data
            .extend_from_slice(frame.rgb().unwrap_or_default());
    }

    /// The last frame of `view` as a new `rgb8` [`Image`] stamped `stamp`.
    pub fn image(&self, view: View, stamp: Time) -> Image {
        let mut image = Image {
            header: Header::new(stamp, view.frame_id()),
            ..Image::default()
        };
        self.write_image(view, stamp, &mut image);
        image
    }

    /// (Re)builds the scene from `world`.
    fn build(&mut self, world: &(impl CameraScene + ?Sized)) -> Result<(), CameraError> {
        self.scene.clear();
        self.parts.clear();
        self.links.clear();
        self.fingers.clear();
        self.objects.clear();

        // Robot links from the URDF collision primitives, except the finger capsules
        // and balls where the world's contact model has its own.
        let robot = world.scene_robot();
        let kin = world.scene_kinematics();
        let finger_capsules = world.finger_capsules();
        let finger_dofs: Vec<usize> = SHADOW_FINGER_JOINTS
            .iter()
            .filter_map(|j| robot.dof_index(j).ok())
            .collect();
        let model = CollisionModel::with_settings(
            robot,
            ModelSettings {
                random_samples: 0,
                ..ModelSettings::default()
            },
        )?;
        for body in model.bodies() {
            let link = body.link();
            let moved_by_finger = robot
                .dofs_moving(link)
                .iter()
                .any(|d| finger_dofs.contains(d));
            let hand = body.name().starts_with("rh_");
            let (part, color) = if hand {
                (Part::Hand, HAND_COLOR)
            } else {
                (Part::Arm, ARM_COLOR)
            };
            for shape in body.shapes() {
                let is_box = matches!(shape.primitive(), teleop_collision::Primitive::Box { .. });
                if moved_by_finger && !is_box && finger_capsules.is_some() {
                    continue;
                }
                let Some((primitive, in_shape)) = render_primitive(shape.primitive()) else {
                    continue;
                };
                let offset = shape.origin() * in_shape;
                let pose = robot.link_pose(kin, link) * offset;
                let id = self.scene.push_colored(primitive, pose, color)?;
                self.parts.push(part);
                self.links.push(LinkShape { id, link, offset });
            }
        }

        // Finger links: the contact model's capsules.
        for capsule in finger_capsules.unwrap_or_default() {
            let (primitive, ball) = capsule_primitive(&capsule);
            let id = self.scene.push_colored(
                primitive,
                segment_pose(&capsule.a, &capsule.b),
                HAND_COLOR,
            )?;
            self.parts.push(Part::Hand);
            self.fingers.push(CapsuleShape { id, ball });
        }

        // Objects and fixtures.
        world.scene_objects(&mut self.object_buf)?;
        for o in &self.object_buf {
            let id = self.scene.push_colored(o.primitive, o.pose, o.color)?;
            self.parts.push(o.part);
            self.objects.push(id);
        }
        Ok(())
    }

    /// Moves every shape to where `world` has it; rebuilds the scene if the world's
    /// finger capsules or objects are not the ones it was built from.
    fn update(&mut self, world: &(impl CameraScene + ?Sized)) -> Result<(), CameraError> {
        let fingers = world.finger_capsules().unwrap_or_default();
        world.scene_objects(&mut self.object_buf)?;
        if fingers.len() != self.fingers.len() || self.object_buf.len() != self.objects.len() {
            tracing::debug!("camera scene rebuilt: the world's shapes changed");
            return self.build(world);
        }
        let robot = world.scene_robot();
        let kin = world.scene_kinematics();
        for s in &self.links {
            self.scene
                .set_pose(s.id, robot.link_pose(kin, s.link) * s.offset)?;
        }
        for (s, capsule) in self.fingers.iter().zip(&fingers) {
            self.scene.set_pose(s.id, capsule_pose(s, capsule))?;
        }
        for (id, o) in self.objects.iter().zip(&self.object_buf) {
            self.scene.set_pose(*id, o.pose)?;
        }
        Ok(())
    }
}

fn set_string(s: &mut String, value: &str) {
    if s != value {
        s.clear();
        s.push_str(value);
    }
}

fn capsule_pose(shape: &CapsuleShape, capsule: &Capsule) -> Isometry3<f64> {
    if shape.ball {
        Isometry3::translation(capsule.a.x, capsule.a.y, capsule.a.z)
    } else {
        segment_pose(&capsule.a, &capsule.b)
    }
}

/// A frame at the segment's midpoint with its z axis along `a -> b` (a render capsule
/// along local z).
/// The render primitive of a contact capsule (a ball when its segment is shorter than
/// [`BALL_BELOW_M`]), and whether it is a ball.
fn capsule_primitive(capsule: &Capsule) -> (Primitive, bool) {
    let length = (capsule.b - capsule.a).norm();
    if length < BALL_BELOW_M {
        (Primitive::ball(capsule.radius_m), true)
    } else {
        (Primitive::capsule_z(length / 2.0, capsule.radius_m), false)
    }
}

fn segment_pose(a: &Point3<f64>, b: &Point3<f64>) -> Isometry3<f64> {
    let mid = nalgebra::center(a, b);
    let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &(b - a))
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI));
    Isometry3::from_parts(Translation3::from(mid.coords), rotation)
}

/// The render primitive of a collision primitive and the render shape's frame in the
/// collision primitive's frame (URDF cylinders are along z, the renderer's along y).
/// `None` for shapes with a zero dimension (invisible) or kinds the renderer lacks.
fn render_primitive(p: &teleop_collision::Primitive) -> Option<(Primitive, Isometry3<f64>)> {
    use teleop_collision::Primitive as C;
    let positive = |v: f64| v.is_finite() && v > 0.0;
    match *p {
        C::Sphere { radius_m } if positive(radius_m) => {
            Some((Primitive::ball(radius_m), Isometry3::identity()))
        }
        C::Box { half_extents_m } if half_extents_m.iter().all(|v| positive(*v)) => {
            Some((Primitive::cuboid(&half_extents_m), Isometry3::identity()))
        }
        C::Capsule {
            half_length_m,
            radius_m,
        } if positive(radius_m) && half_length_m.is_finite() && half_length_m >= 0.0 => Some((
            Primitive::capsule_z(half_length_m, radius_m),
            Isometry3::identity(),
        )),
        C::Cylinder {
            half_length_m,
            radius_m,
        } if positive(radius_m) && positive(half_length_m) => Some((
            Primitive::cylinder_y(half_length_m, radius_m),
            // Local y of the render cylinder onto the URDF cylinder's z.
            Isometry3::rotation(Vector3::x() * FRAC_PI_2),
        )),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TouchingTaskConfig;
    use crate::WORKING_POSTURE_RAD;

    fn touching_world() -> World {
        let config = TouchingTaskConfig {
            arm_posture_rad: WORKING_POSTURE_RAD,
            ..TouchingTaskConfig::default()
        };
        World::touching_task(&config).expect("touching world")
    }

    /// Pixels per part in the id image of `view`.
    fn census(cams: &SceneCameras, view: View) -> (usize, usize, usize) {
        let ids = cams.frame(view).ids().expect("ids rendered");
        let (mut hand, mut arm, mut object) = (0, 0, 0);
        for &id in ids {
            match cams.part(id) {
                Some(Part::Hand) => hand += 1,
                Some(Part::Arm) => arm += 1,
                Some(Part::Object(_)) => object += 1,
                Some(Part::Table) | None => {}
            }
        }
        (hand, arm, object)
    }

    #[test]
    fn rotated_cylinder_runs_along_urdf_z() {
        let (_, in_shape) = render_primitive(&teleop_collision::Primitive::Cylinder {
            half_length_m: 0.1,
            radius_m: 0.01,
        })
        .expect("cylinder");
        let axis = in_shape * Vector3::y();
        assert!((axis - Vector3::z()).norm() < 1e-12, "{axis}");
    }

    #[test]
    fn segment_pose_puts_local_z_along_the_segment() {
        let a = Point3::new(0.1, 0.2, 0.3);
        for b in [
            Point3::new(0.1, 0.2, 0.5),
            Point3::new(0.1, 0.2, 0.1),
            Point3::new(0.4, -0.2, 0.3),
        ] {
            let pose = segment_pose(&a, &b);
            let half = (b - a).norm() / 2.0;
            assert!((pose * Point3::new(0.0, 0.0, -half) - a).norm() < 1e-12);
            assert!((pose * Point3::new(0.0, 0.0, half) - b).norm() < 1e-12);
        }
    }

    #[test]
    fn both_views_show_the_hand_and_the_mouse() {
        let world = touching_world();
        let mut cams = SceneCameras::new(&world, &CameraViewsConfig::default()).expect("cameras");
        cams.render(&world).expect("render");
        eprintln!("{} shapes", cams.scene().len());
        for view in View::ALL {
            let frame = cams.frame(view);
            assert_eq!((frame.width(), frame.height()), (320, 240));
            let (hand, arm, object) = census(&cams, view);
            let n = 320 * 240;
            eprintln!(
                "{}: hand {:.1} %, arm {:.1} %, object {:.1} %",
                view.name(),
                100.0 * hand as f64 / n as f64,
                100.0 * arm as f64 / n as f64,
                100.0 * object as f64 / n as f64,
            );
            assert!(hand > n / 20, "{}: hand covers {hand} px", view.name());
            assert!(
                object > n / 200,
                "{}: mouse covers {object} px",
                view.name()
            );
            // The hand is roughly centred: its pixels' mean lies in the middle half.
            let ids = frame.ids().expect("ids");
            let (mut su, mut sv) = (0.0, 0.0);
            for (i, &id) in ids.iter().enumerate() {
                if cams.part(id) == Some(Part::Hand) {
                    su += (i % 320) as f64;
                    sv += (i / 320) as f64;
                }
            }
            let (mu, mv) = (su / hand as f64, sv / hand as f64);
            assert!(
                (80.0..240.0).contains(&mu) && (60.0..180.0).contains(&mv),
                "{}: hand centred at ({mu:.0}, {mv:.0})",
                view.name()
            );
        }
    }

    #[test]
    fn the_same_world_gives_the_same_bytes() {
        let config = CameraViewsConfig::default();
        let world = touching_world();
        let mut a = SceneCameras::new(&world, &config).expect("cameras");
        a.render(&world).expect("render");
        let mut b = SceneCameras::new(&touching_world(), &config).expect("cameras");
        b.render(&touching_world()).expect("render");
        for view in View::ALL {
            let (ia, ib) = (
                a.image(view, Time::default()),
                b.image(view, Time::default()),
            );
            assert_eq!(ia, ib, "{}", view.name());
            assert_eq!(ia.encoding, "rgb8");
            assert_eq!(ia.data.len(), 320 * 240 * 3);
            ia.check_layout().expect("layout");
            assert!(ia.data.iter().any(|&v| v > 0));
        }
        // Rendering again after the world moved changes the image, and moving back
        // gives the first bytes again: the reused scene follows the world.
        let first = a.image(View::Side, Time::default());
        let mut moved = touching_world();
        let mut q = moved.hand_position_rad();
        q[1] += 0.6;
        moved.set_hand_position(&q);
        a.render(&moved).expect("render");
        assert_ne!(a.image(View::Side, Time::default()), first);
        a.render(&world).expect("render");
        assert_eq!(a.image(View::Side, Time::default()), first);
    }

    #[test]
    fn a_world_with_other_objects_rebuilds_the_scene() {
        let config = CameraViewsConfig::default();
        let empty = World::new(crate::WorldConfig::default()).expect("world");
        let mut cams = SceneCameras::new(&empty, &config).expect("cameras");
        cams.render(&empty).expect("render");
        assert!(!cams.parts.contains(&Part::Object(0)));
        let touching = touching_world();
        cams.render(&touching).expect("render");
        assert!(cams.parts.contains(&Part::Object(0)));
    }

    #[test]
    fn bad_settings_are_named() {
        let base = CameraViewsConfig::default();
        let cases: Vec<(CameraViewsConfig, &str)> = vec![
            (
                CameraViewsConfig {
                    rate_hz: 0.0,
                    ..base.clone()
                },
                "rate_hz",
            ),
            (
                CameraViewsConfig {
                    width_px: 4000,
                    ..base.clone()
                },
                "width_px",
            ),
            (
                CameraViewsConfig {
                    height_px: 0,
                    ..base.clone()
                },
                "height_px",
            ),
            (
                CameraViewsConfig {
                    horizontal_fov_deg: f64::NAN,
                    ..base.clone()
                },
                "horizontal_fov_deg",
            ),
            (
                CameraViewsConfig {
                    top: ViewPose {
                        up: [
                            base.top.look_at_m[0] - base.top.position_m[0],
                            base.top.look_at_m[1] - base.top.position_m[1],
                            base.top.look_at_m[2] - base.top.position_m[2],
                        ],
                        ..base.top
                    },
                    ..base.clone()
                },
                "top",
            ),
            (
                CameraViewsConfig {
                    side: ViewPose {
                        look_at_m: base.side.position_m,
                        ..base.side
                    },
                    ..base.clone()
                },
                "side",
            ),
        ];
        for (config, name) in cases {
            let err = config.validate().expect_err(name).to_string();
            assert!(err.contains(name), "{err}");
        }
        assert!(base.validate().is_ok());
    }
}
