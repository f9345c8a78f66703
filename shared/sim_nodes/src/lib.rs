//! The simulator processes, one per site, that stand in for the hardware and serve it on
//! the bus as the drivers would (the way Gazebo stands in for a robot):
//!
//! * [`remote_sim`]: the robot site's world (PR2 arm, Shadow hand, objects, camera
//!   views), with the last safety layer of the robots it owns;
//! * [`local_sim`]: the operator site's world (the operator, the motion capture, the
//!   pedals, the UR5 and its depth camera), with the UR5's last safety layer.
//!
//! The sites' node crates do not depend on this crate or on the simulators behind it:
//! a node cannot tell a simulated device from a real one (`tests/layout.rs` checks the
//! dependency graph).

pub mod local_sim;
pub mod remote_sim;

/// A simulator's lifecycle: Inactive until its world first steps (`started`), Active
/// while it steps and its robots' states go out (`serving`), Fault while they cannot.
pub(crate) fn serving_state(serving: bool, started: bool) -> teleop_msgs::Lifecycle {
    use teleop_msgs::Lifecycle;
    if serving {
        Lifecycle::Active
    } else if started {
        Lifecycle::Fault
    } else {
        Lifecycle::Inactive
    }
}
