//! Robot-site nodes and their hardware interfaces.

pub mod arm_controller;
pub mod arm_node;
pub mod bus_hardware;
pub mod feedback_node;
pub mod hand_controller;
pub mod hand_gravity;
pub mod hand_node;
pub mod hand_scenarios;
pub mod hardware;
pub mod sim;
pub mod sim_node;
pub mod wire;
