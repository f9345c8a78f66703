//! The three robots of the system, embedded at compile time so no binary needs the
//! URDF files at run time, with the link and joint names other crates refer to.
//!
//! The URDF sources live in `shared/kinematics/urdf/`; each number in them cites
//! where it comes from.

use crate::chain::FixedChain;
use crate::error::KinematicsError;
use crate::model::Robot;

/// `urdf/ur5.urdf`: UR5 from Universal Robots' DH parameters, SR300 on the flange.
pub const UR5_URDF: &str = include_str!("../urdf/ur5.urdf");
/// `urdf/pr2_right_arm_shadow.urdf`: PR2 base + torso + right arm carrying the Shadow hand.
pub const PR2_ARM_URDF: &str = include_str!("../urdf/pr2_right_arm_shadow.urdf");
/// `urdf/shadow_hand.urdf`: the Shadow hand alone, root at the wrist mount.
pub const SHADOW_HAND_URDF: &str = include_str!("../urdf/shadow_hand.urdf");

/// The UR5 with its camera.
///
/// # Errors
/// Only if the embedded URDF were broken (a test parses it).
pub fn ur5() -> Result<Robot, KinematicsError> {
    Robot::from_urdf_str(UR5_URDF)
}

/// PR2 base, torso (fixed height) and right arm with the Shadow hand.
///
/// # Errors
/// Only if the embedded URDF were broken (a test parses it).
pub fn pr2_arm() -> Result<Robot, KinematicsError> {
    Robot::from_urdf_str(PR2_ARM_URDF)
}

/// The Shadow hand with BioTac fingertips, root `rh_forearm` at the wrist mount.
///
/// # Errors
/// Only if the embedded URDF were broken (a test parses it).
pub fn shadow_hand() -> Result<Robot, KinematicsError> {
    Robot::from_urdf_str(SHADOW_HAND_URDF)
}

/// Names in `ur5.urdf`.
pub mod ur5 {
    /// Root link; equals the DH base frame of the UR controller (ur_description
    /// calls this frame `base`; its `base_link` is this one turned by pi about z).
    pub const BASE: &str = "base_link";
    /// Tool flange (DH frame 6): z out of the flange face.
    pub const FLANGE: &str = "tool0";
    /// Depth camera optical frame: +z along the optical axis (viewing direction),
    /// +x right and +y down in the image (REP 103 optical convention).
    pub const CAMERA_OPTICAL_FRAME: &str = "camera_optical_frame";
}

/// Names in `pr2_right_arm_shadow.urdf`.
pub mod pr2 {
    /// Root link (PR2 mobile base).
    pub const BASE: &str = "base_link";
    /// Torso link; the thesis registers the operator's spine to this frame (ch. 6).
    pub const TORSO: &str = "torso_lift_link";
    /// End of the 7-joint IK chain: the Shadow palm (child of WRJ1).
    pub const WRIST: &str = "rh_palm";
}

/// Names in `shadow_hand.urdf` (and the hand part of `pr2_right_arm_shadow.urdf`).
pub mod shadow {
    /// Root link of the standalone hand: the wrist mount plane on the forearm.
    pub const MOUNT: &str = "rh_forearm";
    /// Palm link (child of WRJ1); the fingers' base frame.
    pub const PALM: &str = "rh_palm";
    /// Angle at which the BioTac fixes every J1 (rad): 20 deg (thesis Table 3.1).
    pub const J1_FIXED_RAD: f64 = 20.0 * std::f64::consts::PI / 180.0;
    // Per-finger frame arrays follow the one finger order of the whole system
    // (`teleop_interfaces::joints::FINGERTIPS`: ff, mf, rf, lf, th); a test checks it.
    /// Fingertip frames (BioTac tip).
    pub const TIPS: [&str; 5] = ["rh_fftip", "rh_mftip", "rh_rftip", "rh_lftip", "rh_thtip"];
    /// Distal links (the BioTacs).
    pub const DISTALS: [&str; 5] = [
        "rh_ffdistal",
        "rh_mfdistal",
        "rh_rfdistal",
        "rh_lfdistal",
        "rh_thdistal",
    ];
    /// Distal-joint frames (J1 axis; the human DIP / thumb IP keypoint).
    pub const DIPS: [&str; 5] = ["rh_ffdip", "rh_mfdip", "rh_rfdip", "rh_lfdip", "rh_thdip"];
    /// Middle-joint frames (J2 axis; the human PIP keypoint; thumb: THJ3/THJ2 axes,
    /// the human thumb MCP).
    pub const PIPS: [&str; 5] = ["rh_ffpip", "rh_mfpip", "rh_rfpip", "rh_lfpip", "rh_thpip"];
    /// Knuckle frames (J3/J4 axes; the human MCP keypoint; thumb: THJ5/THJ4 axes,
    /// the human thumb CMC).
    pub const MCPS: [&str; 5] = ["rh_ffmcp", "rh_mfmcp", "rh_rfmcp", "rh_lfmcp", "rh_thmcp"];
    /// All 24 joints of the hand as Shadow names them (`rh_` prefix), J1s included.
    pub const ALL_JOINTS: [&str; 24] = [
        "rh_WRJ2", "rh_WRJ1", "rh_FFJ4", "rh_FFJ3", "rh_FFJ2", "rh_FFJ1", "rh_MFJ4", "rh_MFJ3",
        "rh_MFJ2", "rh_MFJ1", "rh_RFJ4", "rh_RFJ3", "rh_RFJ2", "rh_RFJ1", "rh_LFJ5", "rh_LFJ4",
        "rh_LFJ3", "rh_LFJ2", "rh_LFJ1", "rh_THJ5", "rh_THJ4", "rh_THJ3", "rh_THJ2", "rh_THJ1",
    ];
    /// The five J1 joints, fixed at [`J1_FIXED_RAD`] by the BioTac (URDF type `fixed`).
    pub const FIXED_J1: [&str; 5] = ["rh_FFJ1", "rh_MFJ1", "rh_RFJ1", "rh_LFJ1", "rh_THJ1"];
}

/// UR5 flange chain (`base_link` -> `tool0`).
///
/// # Errors
/// Only if the embedded URDF were broken (a test builds it).
pub fn ur5_flange_chain() -> Result<FixedChain<6>, KinematicsError> {
    ur5()?.chain(ur5::BASE, ur5::FLANGE)?.fixed()
}

/// UR5 camera chain (`base_link` -> `camera_optical_frame`): what the active-vision
/// IK drives.
///
/// # Errors
/// Only if the embedded URDF were broken (a test builds it).
pub fn ur5_camera_chain() -> Result<FixedChain<6>, KinematicsError> {
    ur5()?.chain(ur5::BASE, ur5::CAMERA_OPTICAL_FRAME)?.fixed()
}

/// The PR2 7-joint arm chain (`base_link` -> `rh_palm`): 5 arm joints + WRJ2, WRJ1.
///
/// # Errors
/// Only if the embedded URDF were broken (a test builds it).
pub fn pr2_arm_chain() -> Result<FixedChain<7>, KinematicsError> {
    pr2_arm()?.chain(pr2::BASE, pr2::WRIST)?.fixed()
}
