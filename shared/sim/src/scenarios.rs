//! The thesis' hand experiments (ch. 8.3) as ready-made worlds. Objects are placed from
//! the forward kinematics of the hand at a reference posture, so they sit where flexing
//! the fingers meets them whatever the arm posture or hand model.

use nalgebra::{Isometry3, Point3, SVector, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::config::WorldConfig;
use super::error::SimError;
use super::geometry::{Capsule, capsule_distance};
use super::objects::{ExternalLoad, Object, ObjectShape};
use super::world::World;
use teleop_interfaces::joints::{FINGERTIPS, FLEXION_JOINTS, SHADOW_FINGER_JOINTS};

/// Arm posture the robot-site simulator starts in: elbow bent, away from the
/// straight-arm singularity, so relative motion is possible in every direction.
pub const WORKING_POSTURE_RAD: [f64; 7] = [-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1];

/// Finger posture helper: `(joint name, rad)` pairs on a zero posture.
fn posture(pairs: &[(&str, f64)]) -> [f64; 17] {
    let mut q = [0.0; 17];
    for (name, value) in pairs {
        if let Some(i) = SHADOW_FINGER_JOINTS.iter().position(|j| j == name) {
            q[i] = *value;
        }
    }
    q
}

/// The "mouse touching" task (thesis Fig. 8.6-8.7): the hand, palm down, hovers over a
/// fixed curved surface; the fingers flex onto it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TouchingTaskConfig {
    /// World settings (the arm's and hand's initial positions are overridden by
    /// `arm_posture_rad` / `hand_posture_rad`).
    pub world: WorldConfig,
    /// Arm posture, rad ([`PR2_ARM_JOINTS`](teleop_interfaces::joints::PR2_ARM_JOINTS) order). Default zero: arm
    /// straight forward, palm facing down.
    pub arm_posture_rad: [f64; 7],
    /// Reference finger posture, rad ([`SHADOW_FINGER_JOINTS`] order), held by the position
    /// servo at start. Default: FF..LF J3 = J2 = 0.35 rad, THJ4 = 0.3 rad.
    pub hand_posture_rad: [f64; 17],
    /// Radius of the sphere whose cap is "the mouse", m. Default 0.04.
    pub surface_radius_m: f64,
    /// The finger ([`FINGERTIPS`] name) the surface is centred under. Default `"ff"`.
    pub finger: String,
    /// Gap between that finger and the surface at the reference posture, m.
    /// Default 0.005.
    pub clearance_m: f64,
}

impl Default for TouchingTaskConfig {
    fn default() -> Self {
        let mut pairs = vec![("rh_THJ4", 0.3)];
        for f in ["FF", "MF", "RF", "LF"] {
            pairs.push((
                match f {
                    "FF" => "rh_FFJ3",
                    "MF" => "rh_MFJ3",
                    "RF" => "rh_RFJ3",
                    _ => "rh_LFJ3",
                },
                0.35,
            ));
            pairs.push((
                match f {
                    "FF" => "rh_FFJ2",
                    "MF" => "rh_MFJ2",
                    "RF" => "rh_RFJ2",
                    _ => "rh_LFJ2",
                },
                0.35,
            ));
        }
        Self {
            world: WorldConfig::default(),
            arm_posture_rad: [0.0; 7],
            hand_posture_rad: posture(&pairs),
            surface_radius_m: 0.04,
            finger: "ff".to_owned(),
            clearance_m: 0.005,
        }
    }
}

/// The cup grasp (thesis Fig. 8.8) and, with a load, the screw pouring (Fig. 8.10-8.11):
/// an upright cup held fixed in front of the palm (the human partner held it); the
/// fingers wrap around it from one side, the thumb from the other.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CupGraspConfig {
    /// World settings (initial positions overridden as in [`TouchingTaskConfig`]).
    pub world: WorldConfig,
    /// Arm posture, rad. Default: forearm rolled by +pi/2, so the palm faces sideways
    /// and the thumb points up (the cup axis, along the palm's x, is vertical).
    pub arm_posture_rad: [f64; 7],
    /// Open pre-grasp posture, rad, held at start; the cup is placed to fit inside it.
    /// Default: FF..LF J3 = J2 = 0.3 rad, THJ5 = 0.6, THJ4 = 0.7 rad.
    pub hand_posture_rad: [f64; 17],
    /// Closed grasp posture, rad: what a position command "close the hand" sends. The cup
    /// is placed so that every BioTac would reach into it at this posture. Default:
    /// FF..LF J3 = J2 = 1.0 rad; thumb THJ5 = 0.8, THJ4 = 1.0, THJ2 = -0.1 rad.
    pub closed_posture_rad: [f64; 17],
    /// Cup radius, m. Default 0.035.
    pub cup_radius_m: f64,
    /// Cup height (straight part), m. Default 0.12.
    pub cup_height_m: f64,
    /// Smallest gap between any finger link and the cup at the pre-grasp posture, m.
    /// Default 0.003.
    pub clearance_m: f64,
    /// External loads (e.g. [`ExternalLoad::screw_pouring`]). Default none.
    pub loads: Vec<ExternalLoad>,
}

impl Default for CupGraspConfig {
    fn default() -> Self {
        let mut pairs = vec![("rh_THJ5", 0.6), ("rh_THJ4", 0.7)];
        for j in [
            "rh_FFJ3", "rh_FFJ2", "rh_MFJ3", "rh_MFJ2", "rh_RFJ3", "rh_RFJ2", "rh_LFJ3", "rh_LFJ2",
        ] {
            pairs.push((j, 0.3));
        }
        Self {
            world: WorldConfig::default(),
            arm_posture_rad: [0.0, 0.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2, 0.0, 0.0],
            hand_posture_rad: posture(&pairs),
            closed_posture_rad: posture(&[
                ("rh_FFJ3", 1.0),
                ("rh_FFJ2", 1.0),
                ("rh_MFJ3", 1.0),
                ("rh_MFJ2", 1.0),
                ("rh_RFJ3", 1.0),
                ("rh_RFJ2", 1.0),
                ("rh_LFJ3", 1.0),
                ("rh_LFJ2", 1.0),
                ("rh_THJ5", 0.8),
                ("rh_THJ4", 1.0),
                ("rh_THJ2", -0.1),
            ]),
            cup_radius_m: 0.035,
            cup_height_m: 0.12,
            clearance_m: 0.003,
            loads: Vec::new(),
        }
    }
}

fn positive(field: &'static str, value: f64) -> Result<(), SimError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SimError::InvalidConfig {
            field,
            value,
            reason: "must be finite and > 0",
        })
    }
}

fn posed_world(world: &WorldConfig, arm: &[f64; 7], hand: &[f64; 17]) -> Result<World, SimError> {
    let mut config = world.clone();
    config.arm.initial_position_rad = *arm;
    config.hand.initial_position_rad = *hand;
    World::new(config)
}

impl World {
    /// The mouse-touching world: a sphere of `surface_radius_m` placed along the
    /// chosen fingertip's flexion direction (J3 + J2 motion of its tip at the reference
    /// posture) so that finger's links clear it by exactly `clearance_m`.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for bad sizes or an unknown finger; as
    /// [`World::new`].
    pub fn touching_task(config: &TouchingTaskConfig) -> Result<Self, SimError> {
        positive("surface_radius_m", config.surface_radius_m)?;
        positive("clearance_m", config.clearance_m)?;
        let finger = FINGERTIPS
            .iter()
            .position(|f| *f == config.finger)
            .ok_or_else(|| SimError::UnknownFingerJoint(config.finger.clone()))?;
        let mut world = posed_world(
            &config.world,
            &config.arm_posture_rad,
            &config.hand_posture_rad,
        )?;

        // Direction the tip moves when the finger flexes (its two flexion joints).
        let flexion = world.flexion_direction(finger)?;
        let tip = world.fingertip_positions_m()[finger];
        let mut centre = tip + flexion * (config.surface_radius_m + config.clearance_m);
        // Slide the centre along the flexion direction until the finger's closest link
        // clears the surface by `clearance_m` (distance changes ~1:1 with the slide).
        for _ in 0..20 {
            let ball = Capsule::ball(centre, config.surface_radius_m);
            let gap = world.finger_clearance(finger, &ball);
            let err = gap - config.clearance_m;
            if err.abs() < 1e-9 {
                break;
            }
            centre -= flexion * err;
        }
        world.add_object(Object {
            name: "mouse".to_owned(),
            shape: ObjectShape::Sphere {
                radius_m: config.surface_radius_m,
            },
            pose: Isometry3::from_parts(
                Translation3::from(centre.coords),
                UnitQuaternion::identity(),
            ),
        })?;
        Ok(world)
    }

    /// The cup-grasp world: an upright capsule "cup" with its axis along the palm's x
    /// (across the fingers), placed by a grid search in the palm's y-z plane (1 mm
    /// steps) at the spot where, at the pre-grasp posture, every finger link and the
    /// palm clear it by at least `clearance_m`, and at the closed posture the BioTac
    /// that reaches least far into it reaches farthest.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] for bad sizes or if no placement fits the
    /// pre-grasp posture; as [`World::new`] and [`World::add_load`].
    pub fn cup_grasp(config: &CupGraspConfig) -> Result<Self, SimError> {
        positive("cup_radius_m", config.cup_radius_m)?;
        positive("cup_height_m", config.cup_height_m)?;
        positive("clearance_m", config.clearance_m)?;
        let mut world = posed_world(
            &config.world,
            &config.arm_posture_rad,
            &config.hand_posture_rad,
        )?;
        let palm = world.palm_pose();
        let half = config.cup_height_m / 2.0;
        let r = config.cup_radius_m;
        // Finger geometry at the pre-grasp posture (everything must clear the cup) and
        // the BioTacs at the closed posture (they should all reach into it).
        let open: Vec<Capsule> = world.link_capsules_world(None).collect();
        let mut distal_links = [world.robot().root(); 5];
        for (f, l) in distal_links.iter_mut().enumerate() {
            *l = world.distal_link(f)?;
        }
        world.set_hand_position(&SVector::from(config.closed_posture_rad));
        let closed: Vec<Vec<Capsule>> = distal_links
            .iter()
            .map(|&l| world.link_capsules_world(Some(l)).collect())
            .collect();
        world.set_hand_position(&SVector::from(config.hand_posture_rad));
        let axis = palm.rotation * Vector3::x();
        // Palm box (URDF): y within +-0.012 m of the palm frame.
        const PALM_FRONT_Y_M: f64 = -0.012;
        let mut best: Option<(f64, Point3<f64>)> = None;
        for iy in 0..120 {
            let y = PALM_FRONT_Y_M - r - config.clearance_m - f64::from(iy) * 0.001;
            for iz in 0..200 {
                let z = f64::from(iz) * 0.001;
                let centre = palm * Point3::new(0.0, y, z);
                let cup = Capsule {
                    a: centre - axis * half,
                    b: centre + axis * half,
                    radius_m: r,
                };
                if open
                    .iter()
                    .any(|c| capsule_distance(c, &cup) < config.clearance_m)
                {
                    continue;
                }
                // The BioTac that reaches least into the cup when closed.
                let worst = closed
                    .iter()
                    .map(|caps| {
                        caps.iter()
                            .map(|c| capsule_distance(c, &cup))
                            .fold(f64::INFINITY, f64::min)
                    })
                    .fold(f64::NEG_INFINITY, f64::max);
                if best.is_none_or(|(s, _)| worst < s) {
                    best = Some((worst, centre));
                }
            }
        }
        let Some((_, centre)) = best else {
            return Err(SimError::InvalidConfig {
                field: "cup_radius_m",
                value: r,
                reason: "no cup placement fits the pre-grasp posture",
            });
        };
        // Object z along the palm's x.
        let rotation = palm.rotation
            * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2);
        world.add_object(Object {
            name: "cup".to_owned(),
            shape: ObjectShape::Capsule {
                radius_m: r,
                half_length_m: half,
            },
            pose: Isometry3::from_parts(Translation3::from(centre.coords), rotation),
        })?;
        for load in &config.loads {
            world.add_load(load.clone())?;
        }
        Ok(world)
    }

    /// The screw-pouring variant of [`World::cup_grasp`]: the default cup with
    /// [`ExternalLoad::screw_pouring`] starting at `load_start_s`.
    ///
    /// # Errors
    /// As [`World::cup_grasp`].
    pub fn screw_pouring(load_start_s: f64) -> Result<Self, SimError> {
        World::cup_grasp(&CupGraspConfig {
            loads: vec![ExternalLoad::screw_pouring(load_start_s)],
            ..CupGraspConfig::default()
        })
    }

    /// Unit direction the fingertip moves in when its finger's two flexion joints
    /// (J3 and J2; thumb: THJ4 and THJ2) turn together, at the current posture.
    fn flexion_direction(&self, finger: usize) -> Result<Vector3<f64>, SimError> {
        let last = FLEXION_JOINTS.len() - 1;
        let names = FLEXION_JOINTS[finger.min(last)];
        let robot = self.robot();
        let tip_link = robot.link_id(super::world::TIP_FRAMES[finger.min(last)])?;
        let mut jac = nalgebra::Matrix6xX::zeros(robot.dof());
        robot.link_jacobian_into(
            self.kinematic_state(),
            tip_link,
            &Point3::origin(),
            &mut jac,
        )?;
        let mut dir = Vector3::zeros();
        for name in names {
            let d = robot.dof_index(name)?;
            dir += jac.fixed_view::<3, 1>(0, d);
        }
        Ok(dir.normalize())
    }

    /// Smallest clearance between any link of `finger` (links moved by its flexion
    /// joints beyond the knuckle) and `object`.
    fn finger_clearance(&self, finger: usize, object: &Capsule) -> f64 {
        let prefix = match finger {
            0 => "rh_ff",
            1 => "rh_mf",
            2 => "rh_rf",
            3 => "rh_lf",
            _ => "rh_th",
        };
        ["proximal", "middle", "distal"]
            .iter()
            .filter_map(|part| self.robot().link_id(&format!("{prefix}{part}")).ok())
            .map(|l| self.finger_clearance_link(l, object))
            .fold(f64::INFINITY, f64::min)
    }

    fn finger_clearance_link(&self, link: teleop_kinematics::LinkId, object: &Capsule) -> f64 {
        self.clearance_to(object, Some(link))
            .unwrap_or(f64::INFINITY)
    }

    /// Smallest clearance of finger capsules (of `link` only, if given) to a capsule in
    /// the world frame; `None` if there is no such capsule.
    fn clearance_to(
        &self,
        object: &Capsule,
        link: Option<teleop_kinematics::LinkId>,
    ) -> Option<f64> {
        self.link_capsules_world(link)
            .map(|c| capsule_distance(&c, object))
            .min_by(f64::total_cmp)
    }
}
