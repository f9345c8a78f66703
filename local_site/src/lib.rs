//! Operator-site nodes (the hand-inference node lives in `teleop-hand-inference`, so
//! ONNX Runtime stays out of this crate's build):
//!
//! * [`wrist_tracker`]: the marker pose registered into the operator's hand frame in
//!   the UR5 base, jump-filtered, and the pedals, through the operator-site hardware
//!   traits (`teleop_hardware::{WristTracker, OperatorPanel}`);
//! * [`camera_arm_node`]: the active-vision camera arm on the UR5, around the pure
//!   control core [`camera_arm`];
//! * [`operator_display`]: what the operator sees of the robot site (the camera views,
//!   acknowledged so the robot site paces them to the WAN; the feedback's ages);
//! * [`keyboard_panel`]: the operator panel (deadman, clutch, camera stop, motion
//!   scale) on the keys of the wrist tracker's terminal.
//!
//! Real devices (PhaseSpace, an IMU suit, a pedal box, a UR5 driver, an SR300 driver)
//! slot in behind the same traits and topics; the simulator that stands in for them
//! (`local_sim`, crate `teleop-sim-nodes`) is not linked here.

pub mod camera_arm;
pub mod camera_arm_node;
pub mod display_web;
pub mod keyboard_panel;
pub mod operator_display;
pub mod tracking;
pub mod wrist_tracker;
