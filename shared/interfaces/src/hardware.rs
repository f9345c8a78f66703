//! The hardware interfaces offered on the bus: for each robot, the joints, the state and
//! command topics, and the one node allowed to command it. The process that owns the
//! hardware (a driver, or a simulator standing in for it) serves these; the site's
//! controllers use them through `teleop-hardware-bus`.

use teleop_msgs::{FingertipPressures, JointCommand, JointState};

use crate::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS, UR5_JOINTS};
use crate::topics::{self, Topic};

/// A velocity-commanded arm with `N` joints.
#[derive(Debug, Clone, Copy)]
pub struct ArmInterface<const N: usize> {
    /// Short name for logs and counters, e.g. `pr2_arm`.
    pub name: &'static str,
    /// Joint order of state and command vectors.
    pub joints: [&'static str; N],
    /// Measured joint positions and velocities.
    pub state: Topic<JointState>,
    /// Joint velocity commands (`JointState.velocity`, rad/s).
    pub command: Topic<JointState>,
    /// The only node whose commands the hardware accepts (by default; configurable in
    /// the owning process).
    pub controller_node: &'static str,
}

/// The Shadow hand: 17 finger joints and 5 fingertip sensors.
#[derive(Debug, Clone, Copy)]
pub struct HandInterface {
    /// Short name for logs and counters.
    pub name: &'static str,
    /// Joint order of state and command vectors.
    pub joints: [&'static str; 17],
    /// Measured joint positions, velocities and efforts.
    pub state: Topic<JointState>,
    /// Fingertip forces.
    pub tactile: Topic<FingertipPressures>,
    /// Effort, position or joint-impedance commands (`teleop_msgs/msg/JointCommand`).
    pub command: Topic<JointCommand>,
    /// The only node whose commands the hardware accepts (by default).
    pub controller_node: &'static str,
}

/// The PR2 arm chain (5 arm joints + 2 Shadow wrist joints).
pub const PR2_ARM: ArmInterface<7> = ArmInterface {
    name: "pr2_arm",
    joints: PR2_ARM_JOINTS,
    state: topics::HW_PR2_ARM_STATE,
    command: topics::HW_PR2_ARM_COMMAND,
    controller_node: "pr2_arm_controller",
};

/// The UR5 camera arm.
pub const UR5_ARM: ArmInterface<6> = ArmInterface {
    name: "ur5",
    joints: UR5_JOINTS,
    state: topics::HW_UR5_STATE,
    command: topics::HW_UR5_COMMAND,
    controller_node: "camera_arm",
};

/// The Shadow hand's fingers.
pub const SHADOW_HAND: HandInterface = HandInterface {
    name: "shadow_hand",
    joints: SHADOW_FINGER_JOINTS,
    state: topics::HW_HAND_STATE,
    tactile: topics::HW_HAND_TACTILE,
    command: topics::HW_HAND_COMMAND,
    controller_node: "shadow_hand_controller",
};
