//! The chapter-6 registration of the operator's arm to the PR2's (thesis ch. 6.2, Fig.
//! 6.5): from one frame of the IMU suit's skeleton, the target pose of the PR2's palm
//! in its torso frame, for the arm controller's absolute mode.
//!
//! # The mapping
//!
//! The thesis matches the human spine frame to the PR2's `torso_lift_link` and takes the
//! palm's pose relative to the spine as the robot wrist's pose relative to the torso,
//! "updated by the link lengths of the robot upper arm and forearm". Here that update is
//! made explicit, about the shoulders, so that a straight human arm pointing forward
//! maps onto the PR2's straight arm at zero, whatever the operator's size:
//!
//! * **rotation**: `R_ts`, the spine's axes in the torso's (`torso_from_spine_rpy_deg`;
//!   the default `[90, 0, 90]` turns a BVH body's y-up, z-forward axes into the torso's
//!   z-up, x-forward ones);
//! * **wrist position**: `p_w = s_r + k R_ts (p_hand - p_shoulder)`, with `p_hand`,
//!   `p_shoulder` the human wrist and shoulder joints in the spine frame, `s_r` the
//!   PR2's shoulder (the shoulder-lift joint at zero pan, `(0.1, -0.188, 0)` m in the
//!   torso) and `k` the ratio of the robot's upper arm + forearm (0.4 + 0.321 m) to the
//!   human's, measured in each frame from the skeleton (or `arm_length_ratio`);
//! * **palm orientation**: `R_ts R_hand C`, where `C` is fixed so that the BVH rest
//!   pose (the T-pose: arm out to the side, every joint frame aligned with the spine)
//!   maps onto the PR2 arm stretched out to its right with the palm down (shoulder pan
//!   -90 deg, every other joint 0), then turned by `palm_rpy_deg` (default none);
//! * **palm position**: the wrist plus the robot's wrist-to-palm offset, in the palm
//!   frame.
//!
//! The PR2's shoulder lift sits 0.1 m out from its pan axis and pans with the arm; the
//! scaling centre is fixed where it is at zero pan, so a target well to the side lies
//! up to 0.1 m off the point a rigid copy of the human arm would give (the T-pose maps
//! 0.1 m forward and inward of the PR2's stretched-out palm). The arm follows the
//! target, not the human arm's shape.
//!
//! The robot's numbers come from the project's PR2 URDF (`teleop_kinematics`), so a
//! change there moves them too. The mapping knows nothing of limits: the target goes
//! through the arm controller's jump filter, Cartesian limiter, IK and watchdogs like
//! every other.

use nalgebra::{Isometry3, Point3, SVector, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_kinematics::robots::{self, pr2};

/// Frame of the absolute targets: the PR2 torso (the arm controller's absolute mode
/// expects it).
pub const TORSO_FRAME: &str = pr2::TORSO;

/// The PR2's shoulder-lift link: the point the arm's reach is scaled about.
const SHOULDER_LINK: &str = "r_shoulder_lift_link";
/// The PR2's elbow (the elbow-flex joint's link).
const ELBOW_LINK: &str = "r_elbow_flex_link";
/// The PR2's wrist point, where the Shadow hand is mounted.
const WRIST_LINK: &str = "rh_forearm";

/// Configuration of the chapter-6 arm registration, `[source.arm]` of a BVH source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuArmConfig {
    /// The skeleton's shoulder joint (the upper arm's root; Axis Neuron: `RightArm`).
    pub shoulder_joint: String,
    /// The skeleton's elbow joint (Axis Neuron: `RightForeArm`).
    pub elbow_joint: String,
    /// The spine frame's axes in the PR2 torso frame, roll/pitch/yaw, deg.
    pub torso_from_spine_rpy_deg: [f64; 3],
    /// Robot-to-human arm-length ratio; unset: measured from the skeleton in each frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub arm_length_ratio: Option<f64>,
    /// A further turn of the palm target in its own frame (calibration), rpy, deg.
    pub palm_rpy_deg: [f64; 3],
}

impl Default for ImuArmConfig {
    fn default() -> Self {
        Self {
            shoulder_joint: "RightArm".into(),
            elbow_joint: "RightForeArm".into(),
            torso_from_spine_rpy_deg: [90.0, 0.0, 90.0],
            arm_length_ratio: None,
            palm_rpy_deg: [0.0; 3],
        }
    }
}

impl ImuArmConfig {
    /// # Errors
    /// A message naming the bad field.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [
            ("torso_from_spine_rpy_deg", self.torso_from_spine_rpy_deg),
            ("palm_rpy_deg", self.palm_rpy_deg),
        ] {
            if v.iter().any(|a| !a.is_finite() || a.abs() > 360.0) {
                return Err(format!(
                    "bvh.arm.{name} must be three angles within +-360 deg, got {v:?}"
                ));
            }
        }
        if let Some(k) = self.arm_length_ratio
            && !(k.is_finite() && (0.2..=5.0).contains(&k))
        {
            return Err(format!(
                "bvh.arm.arm_length_ratio must be within 0.2..5, got {k}"
            ));
        }
        if self.shoulder_joint.trim().is_empty() || self.elbow_joint.trim().is_empty() {
            return Err("bvh.arm.shoulder_joint and elbow_joint must name joints".into());
        }
        Ok(())
    }
}

/// Errors building the mapping.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ImuArmError {
    #[error("invalid arm registration config: {0}")]
    Config(String),
    #[error("the PR2 model: {0}")]
    Model(String),
}

/// The skeleton joints one mapping needs, in the spine frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HumanArm {
    pub shoulder: Point3<f64>,
    pub elbow: Point3<f64>,
    /// The wrist joint (the palm's joint in the skeleton) with its orientation.
    pub hand: Isometry3<f64>,
}

impl HumanArm {
    /// Upper arm + forearm length, m.
    pub fn length_m(&self) -> f64 {
        (self.elbow - self.shoulder).norm()
            + (self.hand.translation.vector - self.elbow.coords).norm()
    }
}

/// The registration, with the robot's geometry taken from the PR2 model.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuArmMapping {
    torso_from_spine: UnitQuaternion<f64>,
    robot_shoulder: Vector3<f64>,
    robot_arm_length_m: f64,
    fixed_ratio: Option<f64>,
    /// `C` of the module docs, with the calibration turn.
    palm_correction: UnitQuaternion<f64>,
    /// Wrist point to palm, in the palm frame.
    wrist_to_palm: Vector3<f64>,
}

impl ImuArmMapping {
    /// # Errors
    /// An invalid config, or a PR2 model without the links named here.
    pub fn new(cfg: &ImuArmConfig) -> Result<Self, ImuArmError> {
        cfg.validate().map_err(ImuArmError::Config)?;
        let model = |e: teleop_kinematics::KinematicsError| ImuArmError::Model(e.to_string());
        let robot = robots::pr2_arm().map_err(model)?;
        let pose_at = |tip: &str, q: &[f64]| -> Result<Isometry3<f64>, ImuArmError> {
            let chain = robot.chain(pr2::TORSO, tip).map_err(model)?;
            chain.end_pose(&q[..chain.dof()]).map_err(model)
        };
        let zero = [0.0; 7];
        let shoulder = pose_at(SHOULDER_LINK, &zero)?.translation.vector;
        let elbow = pose_at(ELBOW_LINK, &zero)?.translation.vector;
        let wrist = pose_at(WRIST_LINK, &zero)?.translation.vector;
        let robot_arm_length_m = (elbow - shoulder).norm() + (wrist - elbow).norm();
        // The T-pose: shoulder pan -90 deg, the rest at zero.
        let mut q_t = SVector::<f64, 7>::zeros();
        q_t[0] = -std::f64::consts::FRAC_PI_2;
        let palm_t = pose_at(pr2::WRIST, q_t.as_slice())?;
        let wrist_t = pose_at(WRIST_LINK, q_t.as_slice())?;
        let [r, p, y] = cfg.torso_from_spine_rpy_deg.map(f64::to_radians);
        let torso_from_spine = UnitQuaternion::from_euler_angles(r, p, y);
        let [r, p, y] = cfg.palm_rpy_deg.map(f64::to_radians);
        let calibration = UnitQuaternion::from_euler_angles(r, p, y);
        Ok(Self {
            torso_from_spine,
            robot_shoulder: shoulder,
            robot_arm_length_m,
            fixed_ratio: cfg.arm_length_ratio,
            palm_correction: torso_from_spine.inverse() * palm_t.rotation * calibration,
            wrist_to_palm: palm_t.rotation.inverse()
                * (palm_t.translation.vector - wrist_t.translation.vector),
        })
    }

    /// The robot's upper arm + forearm, m (from the model).
    pub fn robot_arm_length_m(&self) -> f64 {
        self.robot_arm_length_m
    }

    /// The robot's shoulder (scaling centre) in the torso frame, m.
    pub fn robot_shoulder(&self) -> Vector3<f64> {
        self.robot_shoulder
    }

    /// The ratio used for `arm`: the configured one, or robot length / human length.
    /// `None` for a degenerate (zero-length) human arm.
    pub fn ratio(&self, arm: &HumanArm) -> Option<f64> {
        match self.fixed_ratio {
            Some(k) => Some(k),
            None => {
                let l = arm.length_m();
                (l.is_finite() && l > 1e-3).then(|| self.robot_arm_length_m / l)
            }
        }
    }

    /// The PR2 palm target in the torso frame for the human arm `arm` (spine frame).
    /// `None` for a degenerate arm.
    pub fn palm_target(&self, arm: &HumanArm) -> Option<Isometry3<f64>> {
        let k = self.ratio(arm)?;
        let reach = arm.hand.translation.vector - arm.shoulder.coords;
        let wrist = self.robot_shoulder + self.torso_from_spine * (reach * k);
        let rotation = self.torso_from_spine * arm.hand.rotation * self.palm_correction;
        let palm = wrist + rotation * self.wrist_to_palm;
        let pose = Isometry3::from_parts(Translation3::from(palm), rotation);
        (pose.translation.vector.iter().all(|v| v.is_finite())
            && pose.rotation.coords.iter().all(|v| v.is_finite()))
        .then_some(pose)
    }
}
