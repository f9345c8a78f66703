//! Robot-site nodes and their supervisors:
//!
//! * `pr2_arm_controller` ([`arm_node`], core [`arm_controller`]): clutched relative
//!   control of the PR2 arm;
//! * `shadow_hand_controller` ([`hand_node`], core [`hand_controller`], gravity model
//!   [`gravity`]): the Shadow hand's force control with its hold watchdog;
//! * `feedback_publisher` ([`feedback_node`]): what the operator site sees of the robots,
//!   the camera views paced by the operator display's receipts ([`view_pacer`]).
//!
//! The hardware interfaces are `teleop-hardware` (traits, safety layer) and
//! `teleop-hardware-bus` (over the bus). The simulator that stands in for the robots
//! (`remote_sim`, crate `teleop-sim-nodes`) is not linked here: a driver serving the
//! same hardware topics takes its place.

pub mod arm_controller;
pub mod arm_node;
pub mod command_age;
pub mod feedback_node;
pub mod gravity;
pub mod hand_controller;
pub mod hand_node;
pub mod view_pacer;
