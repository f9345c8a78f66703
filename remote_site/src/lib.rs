//! Robot-site nodes and their hardware interfaces.

pub mod arm_controller;
pub mod arm_node;
pub mod bus_hardware;
pub mod feedback_node;
pub mod hardware;
pub mod sim;
pub mod sim_node;
pub mod wire;
