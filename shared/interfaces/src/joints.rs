//! Joint and fingertip tables of the robots. Joint order everywhere (state and command
//! vectors, wire messages built by this project, controller gains) is the order of
//! these arrays; messages from elsewhere are matched by name.
//!
//! The names are those of the URDFs in `shared/kinematics/urdf/`; a test
//! (`shared/kinematics/tests/descriptions.rs`, `interface_tables_match_the_models`)
//! checks every name against the models.

/// The 7 joints of the PR2 arm chain the arm controller drives: the PR2 right arm's 5
/// joints, then the Shadow hand's 2 wrist joints (the hand replaces the PR2 wrist
/// roll and gripper; thesis ch. 6.2.3).
pub const PR2_ARM_JOINTS: [&str; 7] = [
    "r_shoulder_pan_joint",
    "r_shoulder_lift_joint",
    "r_upper_arm_roll_joint",
    "r_elbow_flex_joint",
    "r_forearm_roll_joint",
    "rh_WRJ2",
    "rh_WRJ1",
];

/// The 6 joints of the UR5 camera arm, base to flange.
pub const UR5_JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];

/// The fingers, in the one order of every per-finger array (fingertip forces, tip
/// frames, flexion joints): first, middle, ring, little, thumb.
pub const FINGERTIPS: [&str; 5] = ["ff", "mf", "rf", "lf", "th"];

/// The 17 actuated finger joints of the Shadow hand with BioTacs (the five J1 are fixed
/// at 20 deg by the sensors; the two wrist joints belong to the arm chain), finger by
/// finger in [`FINGERTIPS`] order, proximal to distal.
pub const SHADOW_FINGER_JOINTS: [&str; 17] = [
    "rh_FFJ4", "rh_FFJ3", "rh_FFJ2", "rh_MFJ4", "rh_MFJ3", "rh_MFJ2", "rh_RFJ4", "rh_RFJ3",
    "rh_RFJ2", "rh_LFJ5", "rh_LFJ4", "rh_LFJ3", "rh_LFJ2", "rh_THJ5", "rh_THJ4", "rh_THJ3",
    "rh_THJ2",
];

/// The two flexion joints of each finger ([`FINGERTIPS`] order) that curl it toward the
/// palm: J3 and J2; for the thumb THJ4 and THJ2.
pub const FLEXION_JOINTS: [[&str; 2]; 5] = [
    ["rh_FFJ3", "rh_FFJ2"],
    ["rh_MFJ3", "rh_MFJ2"],
    ["rh_RFJ3", "rh_RFJ2"],
    ["rh_LFJ3", "rh_LFJ2"],
    ["rh_THJ4", "rh_THJ2"],
];

/// Index of `name` in `table`.
pub fn index_of<const N: usize>(table: &[&str; N], name: &str) -> Option<usize> {
    table.iter().position(|j| *j == name)
}

/// Index of a finger joint in [`SHADOW_FINGER_JOINTS`].
pub fn finger_joint_index(name: &str) -> Option<usize> {
    index_of(&SHADOW_FINGER_JOINTS, name)
}

/// Index of a finger in [`FINGERTIPS`] (`"ff"`, ..., `"th"`).
pub fn fingertip_index(name: &str) -> Option<usize> {
    index_of(&FINGERTIPS, name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_have_unique_names() {
        fn unique<const N: usize>(t: &[&str; N]) {
            for (i, a) in t.iter().enumerate() {
                assert!(!t[i + 1..].contains(a), "{a} twice");
            }
        }
        unique(&PR2_ARM_JOINTS);
        unique(&UR5_JOINTS);
        unique(&SHADOW_FINGER_JOINTS);
        unique(&FINGERTIPS);
    }

    #[test]
    fn finger_joints_follow_the_finger_order() {
        // Each finger's joints are contiguous, in FINGERTIPS order.
        let order: Vec<usize> = SHADOW_FINGER_JOINTS
            .iter()
            .map(|j| {
                let f = j[3..5].to_ascii_lowercase();
                fingertip_index(&f).expect("finger prefix")
            })
            .collect();
        assert!(order.windows(2).all(|w| w[0] <= w[1]), "{order:?}");
        for (f, [j3, j2]) in FLEXION_JOINTS.iter().enumerate() {
            for j in [j3, j2] {
                let i = finger_joint_index(j).expect("flexion joint is a finger joint");
                assert_eq!(order[i], f, "{j}");
            }
        }
        assert_eq!(finger_joint_index("rh_THJ2"), Some(16));
        assert_eq!(finger_joint_index("rh_FFJ1"), None);
    }
}
