//! Operator-site nodes.
//!
//! Today: the wrist tracker node ([`wrist_tracker`]), which publishes the operator's 6D
//! wrist pose and pedal/switch state from devices behind the operator-site hardware
//! traits (`teleop_hardware::{WristTracker, OperatorPanel}`). The simulated operator
//! (`teleop_sim::operator`) knows the true hand pose, so everything downstream can be
//! measured against ground truth. A real tracker (PhaseSpace, IMU suit) and a real
//! pedal box slot in behind the same traits.

pub mod camera_arm;
pub mod camera_arm_node;
pub mod local_sim;
pub mod tracking;
pub mod wrist_tracker;
