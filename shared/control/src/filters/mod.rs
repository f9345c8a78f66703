//! Robot-side motion filters: pure structs with a `step`/`filter` that takes the
//! input and the time step and returns an output or a typed [`Rejection`].
//!
//! * [`jump`]: [`JumpFilter`] drops poses that jump away from the last accepted one.
//! * [`cartesian`]: [`CartesianLimiter`] moves a pose toward a target stream within
//!   linear/angular velocity and acceleration limits, stopping without overshoot.
//! * [`joint`]: [`JointVelocityLimiter`] brings joint velocity commands within
//!   velocity, acceleration and position limits.
//!
//! [`Rejection`]: crate::Rejection

mod approach;
pub mod cartesian;
pub mod joint;
pub mod jump;

pub use cartesian::{CartesianLimiter, CartesianLimits};
pub use joint::{
    InterventionCounts, JointLimiterConfig, JointLimits, JointVelocityLimiter,
    UR5_MAX_JOINT_VELOCITY_RAD_S, VelocityLimitStrategy,
};
pub use jump::{JumpFilter, JumpFilterConfig};
