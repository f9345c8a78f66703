//! Robot-site nodes and their supervisors:
//!
//! * `remote_sim` ([`sim_node`]): the simulated PR2 arm, Shadow hand, objects and camera
//!   views behind the hardware safety layer (the process that owns the robots);
//! * `pr2_arm_controller` ([`arm_node`], core [`arm_controller`]): clutched relative
//!   control of the PR2 arm;
//! * `shadow_hand_controller` ([`hand_node`], core [`hand_controller`], gravity model
//!   [`gravity`]): the Shadow hand's force control with its hold watchdog;
//! * `feedback_publisher` ([`feedback_node`]): what the operator site sees of the robots,
//!   the camera views paced by the operator display's receipts ([`view_pacer`]).
//!
//! The hardware interfaces are `teleop-hardware` (traits, safety layer) and
//! `teleop-hardware-bus` (over the bus); the simulated world is `teleop-sim`.

pub mod arm_controller;
pub mod arm_node;
pub mod command_age;
pub mod feedback_node;
pub mod gravity;
pub mod hand_controller;
pub mod hand_node;
pub mod sim_node;
pub mod view_pacer;
