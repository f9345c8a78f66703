//! Robot-site nodes and their hardware interfaces.

pub mod arm_controller;
pub mod hardware;
pub mod wire;
