//! Hardware reached over the bus, on the `teleop/hw/...` topics of an interface table
//! entry (`teleop_interfaces::hardware`).
//!
//! * Clients — what a controller holds: [`BusArm<N>`] (any arm: the PR2 chain, the UR5),
//!   [`BusHand`], [`BusCamera`], and the operator site's [`BusWristTracker`] (motion
//!   capture, with each sample's capture time) and [`BusPanel`] (pedals). They
//!   implement the `teleop-hardware` traits, so a controller cannot tell them from an
//!   in-process backend. A `monitor` handle only reads.
//! * Endpoints — what the process that owns the hardware holds: [`ArmEndpoint<N>`] and
//!   [`HandEndpoint`] publish the state and take commands **only from the interface's
//!   controller node** (bus [`SourcePolicy::Node`](teleop_bus::SourcePolicy)): samples
//!   of any other publisher are dropped and counted before they are decoded. What they
//!   hand out must still go through the safety layer (`SafeArm` / `SafeHand`).
//! * Backends for hardware of other ecosystems: [`Ros2ControlArm`] and
//!   [`Ros2ControlHand`], robots run by ros2_control on ROS 2 (rmw_zenoh), through
//!   forward command controllers and the joint state broadcaster.

mod client;
mod endpoint;
pub mod ros2_control;

pub use client::{
    BusArm, BusCamera, BusHand, BusPanel, BusWristTracker, MARKER_QUATERNION_TOLERANCE,
    MarkerSample, SILENT_PUBLISHER_AFTER_S,
};
pub use endpoint::{ArmEndpoint, HandEndpoint};
pub use ros2_control::{
    HandControllerMode, Ros2ControlArm, Ros2ControlConfig, Ros2ControlHand, Ros2ControlHandConfig,
};
