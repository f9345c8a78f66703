//! Wrist-tracking sources beyond the simulated motion capture: file replay of recorded
//! poses ([`replay`]) and the Perception Neuron suit's BVH broadcast ([`bvh`]). Each is a
//! [`teleop_hardware::WristTracker`], so the wrist tracker node runs on any of them.

pub mod bvh;
pub mod imu_arm;
pub mod replay;
