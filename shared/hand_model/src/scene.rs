//! Depth-render scenes of the human hand and of the Shadow hand, and the viewpoints of
//! the paired dataset ("Dataset2" of the thesis): both hands are seen from the same
//! camera-to-palm-frame transform, the robot's palm frame placed where the human's is.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use teleop_kinematics::model::Shape;
use teleop_kinematics::robots::{self, shadow};
use teleop_kinematics::{LinkId, Robot};
use teleop_render::{Camera, Primitive, Scene};

use crate::HandModelError;
use crate::human::{HandCapsule, HumanHand, PosedHand};
use crate::retarget::SHADOW_FINGER_DOF;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;

/// The hand centre the crop is taken around, in the hand frame of thesis Fig. 3.6
/// ([`crate::hand_frame`]): 80 mm from the wrist along the fingers' mean direction,
/// the middle of the palm. At run time the same point comes from the wrist tracker's
/// pose; the dataset jitters it to train for tracking error.
pub const HAND_CENTRE_IN_HAND_FRAME: [f64; 3] = [0.0, 0.0, 0.08];

/// Forearm of the human: direction relative to the hand (wrist flexion and ulnar /
/// radial deviation, rad).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Forearm {
    pub flexion: f64,
    pub deviation: f64,
}

impl Forearm {
    /// A random forearm direction: flexion ~ U(-0.6, 0.6), deviation ~ U(-0.3, 0.3).
    pub fn sample<R: Rng + ?Sized>(rng: &mut R) -> Self {
        Self {
            flexion: rng.random_range(-0.6..0.6),
            deviation: rng.random_range(-0.3..0.3),
        }
    }
}

/// Adds the human hand `posed` (capsules of `hand`) and its forearm to `scene`, the
/// hand's canonical frame at `world_from_hand`. `capsules` is scratch space.
///
/// # Errors
/// [`HandModelError::Render`] for a non-finite pose.
pub fn push_human(
    scene: &mut Scene,
    hand: &HumanHand,
    posed: &PosedHand,
    forearm: Forearm,
    world_from_hand: &Isometry3<f64>,
    capsules: &mut Vec<HandCapsule>,
) -> Result<(), HandModelError> {
    capsules.clear();
    hand.capsules(posed, capsules);
    for c in capsules.iter() {
        scene.push(Primitive::capsule(&c.a, &c.b, c.radius), *world_from_hand)?;
    }
    // Forearm: two side-by-side capsules (a flattened cross-section ~ 60 x 40 mm)
    // from just inside the wrist back 0.25 m, bent by the wrist angles.
    let s = hand.shape().scale;
    let bend = UnitQuaternion::from_euler_angles(-forearm.flexion, forearm.deviation, 0.0);
    let back = bend * Vector3::new(0.0, 0.0, -0.25);
    for x in [-0.011, 0.011] {
        let a = Point3::new(x * s, 0.0, 0.012 * s);
        let b = Point3::new(x * s, 0.0, 0.0) + back;
        scene.push(Primitive::capsule(&a, &b, 0.02 * s), *world_from_hand)?;
    }
    Ok(())
}

/// The Shadow hand's collision shapes posed by forward kinematics, for rendering.
#[derive(Debug, Clone)]
pub struct ShadowScene {
    robot: Robot,
    shapes: Vec<(LinkId, Primitive, Isometry3<f64>)>,
    palm: LinkId,
    dof_of: [usize; SHADOW_FINGER_DOF],
}

impl ShadowScene {
    /// Loads the project's Shadow hand and turns its collision shapes into render
    /// primitives (a forearm cylinder is added below the wrist mount, as the real
    /// hand has one).
    ///
    /// # Errors
    /// [`HandModelError::Kinematics`] only if the embedded URDF were broken.
    pub fn new() -> Result<Self, HandModelError> {
        let robot = robots::shadow_hand()?;
        let mut shapes = Vec::new();
        for (i, link) in robot.links().iter().enumerate() {
            let id = robot.link_id(&link.name)?;
            debug_assert_eq!(id.index(), i);
            for c in &link.collisions {
                let (primitive, local) = match &c.shape {
                    Shape::Box { size } => {
                        (Primitive::cuboid(&(size / 2.0)), Isometry3::identity())
                    }
                    Shape::Sphere { radius } => (Primitive::ball(*radius), Isometry3::identity()),
                    Shape::Capsule { radius, length } => (
                        Primitive::capsule_z(length / 2.0, *radius),
                        Isometry3::identity(),
                    ),
                    Shape::Cylinder { radius, length } => (
                        Primitive::cylinder_y(length / 2.0, *radius),
                        // The renderer's cylinder is along y, URDF's along z.
                        Isometry3::rotation(Vector3::x() * (PI / 2.0)),
                    ),
                    _ => continue,
                };
                shapes.push((id, primitive, c.origin * local));
            }
        }
        let mount = robot.link_id(shadow::MOUNT)?;
        shapes.push((
            mount,
            Primitive::cylinder_y(0.1, 0.045),
            Isometry3::from_parts(
                Translation3::new(0.0, 0.0, -0.11),
                UnitQuaternion::from_scaled_axis(Vector3::x() * (PI / 2.0)),
            ),
        ));
        let mut dof_of = [0; SHADOW_FINGER_DOF];
        for (i, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            dof_of[i] = robot.dof_index(name)?;
        }
        let palm = robot.link_id(shadow::PALM)?;
        Ok(Self {
            robot,
            shapes,
            palm,
            dof_of,
        })
    }

    /// Adds the hand at `joints` (wrist joints at zero) with `rh_palm` at
    /// `world_from_palm`.
    ///
    /// # Errors
    /// [`HandModelError::Render`] for a non-finite pose or joint.
    pub fn push(
        &self,
        scene: &mut Scene,
        joints: &[f64; SHADOW_FINGER_DOF],
        world_from_palm: &Isometry3<f64>,
    ) -> Result<(), HandModelError> {
        let mut positions = vec![0.0; self.robot.dof()];
        for (i, d) in self.dof_of.iter().enumerate() {
            positions[*d] = joints[i];
        }
        let mut state = self.robot.new_state();
        self.robot.update(&mut state, &positions)?;
        let world_from_root = world_from_palm * self.robot.link_pose(&state, self.palm).inverse();
        for (link, primitive, local) in &self.shapes {
            let pose = world_from_root * self.robot.link_pose(&state, *link) * local;
            scene.push(*primitive, pose)?;
        }
        Ok(())
    }
}

/// Where the dataset's cameras look from, relative to the hand (thesis 5.4.4: the
/// palm-side views, the hand's Y axis of Fig. 3.6 pointing at the camera, predict best,
/// and the active camera arm keeps itself there).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewSampler {
    /// Camera distance from the hand centre (m).
    pub distance_m: (f64, f64),
    /// Largest angle (rad) between the viewing direction and the hand's palm normal
    /// (Fig. 3.6 Y); 30 deg = the thesis's beta of 150-180 deg.
    pub max_off_axis_rad: f64,
    /// Smallest off-axis angle (rad), for out-of-distribution sets.
    pub min_off_axis_rad: f64,
    /// Standard deviation (m) of the error of the hand-centre estimate the crop uses.
    pub centre_sd_m: f64,
    /// Roll (rad) of the camera about its optical axis away from the nominal one, in
    /// which the hand's fingers (Fig. 3.6 Z) point up in the image: a magnitude drawn
    /// from `[min, max]`, either sign. The active camera arm holds a full 6D pose
    /// relative to the hand, so only its tracking lag rolls the view; `(0, PI)` gives
    /// every roll.
    pub roll_rad: (f64, f64),
}

impl Default for ViewSampler {
    /// 0.3-0.8 m, up to 30 deg off the palm normal, 5 mm centre error, rolls up to
    /// 30 deg.
    fn default() -> Self {
        Self {
            distance_m: (0.3, 0.8),
            max_off_axis_rad: 30f64.to_radians(),
            min_off_axis_rad: 0.0,
            centre_sd_m: 0.005,
            roll_rad: (0.0, 30f64.to_radians()),
        }
    }
}

/// One sampled view: the camera's pose relative to the hand frame, and the crop
/// centre (with its estimation error) in the camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Camera optical frame in the hand frame (Fig. 3.6).
    pub hand_from_camera: Isometry3<f64>,
    /// The hand-centre estimate in the hand frame (true centre + error).
    pub centre_estimate_in_hand: Point3<f64>,
}

impl ViewSampler {
    /// A view: camera on a cone around the palm normal at a random distance, rolled
    /// about its optical axis by `roll_rad` from the fingers-up view.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> View {
        let centre = Point3::from(HAND_CENTRE_IN_HAND_FRAME);
        let (lo, hi) = self.distance_m;
        let distance = if hi > lo {
            rng.random_range(lo..hi)
        } else {
            lo
        };
        // Uniform on the spherical cap between the two off-axis angles.
        let (c0, c1) = (self.min_off_axis_rad.cos(), self.max_off_axis_rad.cos());
        let cos_t = if c0 > c1 {
            rng.random_range(c1..c0)
        } else {
            c0
        };
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = rng.random_range(0.0..2.0 * PI);
        // The palm normal is +Y of the hand frame; x/z span the cap.
        let dir = Vector3::new(sin_t * phi.cos(), cos_t, sin_t * phi.sin());
        let eye = centre + dir * distance;
        let (lo, hi) = (
            self.roll_rad.0.clamp(0.0, PI),
            self.roll_rad.1.clamp(0.0, PI),
        );
        let magnitude = if hi > lo {
            rng.random_range(lo..=hi)
        } else {
            lo
        };
        let roll = if rng.random::<bool>() {
            magnitude
        } else {
            -magnitude
        };
        // Fingers up in the image: the hand's +Z, made perpendicular to the view.
        let z_perp = Vector3::z() - dir * dir.z;
        let nominal = z_perp
            .try_normalize(1e-9)
            .unwrap_or_else(|| any_perpendicular(&dir));
        let up =
            UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(-dir), roll) * nominal;
        let pose = Camera::look_at(&eye, &centre, &up).unwrap_or_else(|_| Isometry3::identity());
        let noise = Normal::new(0.0, self.centre_sd_m.max(0.0)).ok();
        let mut jitter = || noise.map_or(0.0, |n| n.sample(rng));
        let error = Vector3::new(jitter(), jitter(), jitter());
        View {
            hand_from_camera: pose,
            centre_estimate_in_hand: centre + error,
        }
    }
}

fn any_perpendicular(v: &Vector3<f64>) -> Vector3<f64> {
    let helper = if v.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    v.cross(&helper).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::HumanPose;
    use rand::SeedableRng;
    use teleop_render::{Channels, Frame, Renderer};

    #[test]
    fn both_hands_render_in_front_of_a_palm_side_camera() {
        let hand = HumanHand::average();
        let posed = hand.pose(&HumanPose::flat());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let view = ViewSampler::default().sample(&mut rng);
        // World = camera frame.
        let camera_from_hand = view.hand_from_camera.inverse();
        let mut scene = Scene::new();
        push_human(
            &mut scene,
            &hand,
            &posed,
            Forearm::default(),
            &camera_from_hand,
            &mut Vec::new(),
        )
        .expect("human");
        let camera = Camera::sr300(Isometry3::identity());
        let mut frame = Frame::new(Channels::DEPTH_ONLY);
        let mut renderer = Renderer::new();
        renderer.render(&scene, &camera, &mut frame);
        let hits = frame.depth_mm().iter().filter(|d| **d > 0).count();
        assert!(hits > 2000, "human pixels {hits}");

        let shadow = ShadowScene::new().expect("shadow");
        let mut scene = Scene::new();
        shadow
            .push(&mut scene, &[0.0; SHADOW_FINGER_DOF], &camera_from_hand)
            .expect("shadow");
        renderer.render(&scene, &camera, &mut frame);
        let hits = frame.depth_mm().iter().filter(|d| **d > 0).count();
        assert!(hits > 2000, "robot pixels {hits}");
    }

    #[test]
    fn views_respect_the_cone_and_distance() {
        let sampler = ViewSampler::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let centre = Point3::from(HAND_CENTRE_IN_HAND_FRAME);
        for _ in 0..500 {
            let v = sampler.sample(&mut rng);
            let eye = Point3::from(v.hand_from_camera.translation.vector);
            let d = (eye - centre).norm();
            assert!((0.3 - 1e-9..=0.8 + 1e-9).contains(&d), "distance {d}");
            let angle = ((eye - centre) / d).dot(&Vector3::y()).acos();
            assert!(angle <= 30f64.to_radians() + 1e-9, "off axis {angle}");
            // The optical axis (camera +Z) points at the centre.
            let z = v.hand_from_camera.rotation * Vector3::z();
            assert!(z.dot(&(centre - eye).normalize()) > 0.999_999);
            // The fingers (hand +Z) point up in the image, rolled by at most 30 deg:
            // image up is the optical frame's -Y.
            let fingers = v.hand_from_camera.rotation.inverse() * Vector3::z();
            let (x, y) = (fingers.x, fingers.y);
            let roll = x.atan2(-y).abs();
            assert!(roll <= 30f64.to_radians() + 1e-6, "roll {roll}");
        }
    }
}
