//! [`ArmHardware`] / [`HandHardware`] over a shared in-process simulated world: the
//! joint-space [`World`] or the physical [`MujocoWorld`](crate::MujocoWorld), both seen
//! through [`RobotWorld`].
//!
//! The handles only move data: `read` returns the state the world measured at its last
//! step, `write` stores a command that the next step applies. Whoever owns the loop (a
//! test, or a single-process simulator) steps the world; a controller holding a handle
//! cannot tell it from a real driver.

use std::sync::{Arc, Mutex, MutexGuard};

use nalgebra::{Isometry3, SVector};

use super::camera::CameraScene;
use super::error::SimError;
use super::world::World;
use teleop_hardware::{
    ArmCommand, ArmHardware, ArmState, HandCommand, HandHardware, HandState, HardwareError,
};

/// What the simulator process needs of a robot-site world: time, stepping, the drivers'
/// states and commands, ground truth of the objects, and the cameras' scene.
pub trait RobotWorld: CameraScene + Send + std::fmt::Debug {
    /// Simulation time, s.
    fn time_s(&self) -> f64;
    /// Advances by `duration_s` in the world's fixed steps (durations accumulate).
    ///
    /// # Errors
    /// [`SimError::Physics`] when the physics became unstable.
    fn advance(&mut self, duration_s: f64) -> Result<(), SimError>;
    /// The arm state as its driver reports it.
    fn arm_state(&self) -> ArmState<7>;
    /// The hand state as its driver reports it.
    fn hand_state(&self) -> HandState;
    /// Stores an arm velocity command (finite: the handles check), applied from the next
    /// step.
    fn command_arm(&mut self, velocity_rad_s: &SVector<f64, 7>);
    /// Stores a hand command, applied from the next step until replaced.
    fn command_hand(&mut self, command: &HandCommand);
    /// Ground truth: every object's name and world pose.
    fn object_poses(&self) -> Vec<(String, Isometry3<f64>)>;
}

impl RobotWorld for World {
    fn time_s(&self) -> f64 {
        World::time_s(self)
    }
    fn advance(&mut self, duration_s: f64) -> Result<(), SimError> {
        self.step(duration_s);
        Ok(())
    }
    fn arm_state(&self) -> ArmState<7> {
        World::arm_state(self)
    }
    fn hand_state(&self) -> HandState {
        World::hand_state(self)
    }
    fn command_arm(&mut self, velocity_rad_s: &SVector<f64, 7>) {
        World::command_arm(self, velocity_rad_s);
    }
    fn command_hand(&mut self, command: &HandCommand) {
        World::command_hand(self, command);
    }
    fn object_poses(&self) -> Vec<(String, Isometry3<f64>)> {
        self.objects()
            .iter()
            .map(|o| (o.name.clone(), o.pose))
            .collect()
    }
}

/// A world shared between the stepping loop and the hardware handles.
pub type SharedWorld<W = World> = Arc<Mutex<W>>;

fn lock<W: ?Sized>(world: &Arc<Mutex<W>>) -> Result<MutexGuard<'_, W>, HardwareError> {
    world
        .lock()
        .map_err(|_| HardwareError::Fault("simulated world lock poisoned".to_owned()))
}

/// The simulated arm seen through [`ArmHardware`].
#[derive(Debug)]
pub struct SimArm<W: ?Sized = World> {
    world: Arc<Mutex<W>>,
}

impl<W: ?Sized> Clone for SimArm<W> {
    fn clone(&self) -> Self {
        Self {
            world: self.world.clone(),
        }
    }
}

impl<W: ?Sized> SimArm<W> {
    /// A handle on `world`'s arm.
    pub fn new(world: Arc<Mutex<W>>) -> Self {
        Self { world }
    }
}

impl<W: RobotWorld + ?Sized> ArmHardware<7> for SimArm<W> {
    fn read(&mut self, _now_s: f64) -> Result<ArmState<7>, HardwareError> {
        Ok(lock(&self.world)?.arm_state())
    }

    /// Stores the command, time-stamped with the sim time; a non-finite command is
    /// refused (as a real driver would) and leaves the previous one in force.
    fn write(&mut self, _now_s: f64, command: &ArmCommand<7>) -> Result<(), HardwareError> {
        if !command.velocity_rad_s.iter().all(|v| v.is_finite()) {
            return Err(HardwareError::Fault(
                "non-finite arm velocity command".to_owned(),
            ));
        }
        lock(&self.world)?.command_arm(&command.velocity_rad_s);
        Ok(())
    }
}

/// The simulated hand seen through [`HandHardware`].
#[derive(Debug)]
pub struct SimHand<W: ?Sized = World> {
    world: Arc<Mutex<W>>,
}

impl<W: ?Sized> Clone for SimHand<W> {
    fn clone(&self) -> Self {
        Self {
            world: self.world.clone(),
        }
    }
}

impl<W: ?Sized> SimHand<W> {
    /// A handle on `world`'s hand.
    pub fn new(world: Arc<Mutex<W>>) -> Self {
        Self { world }
    }
}

impl<W: RobotWorld + ?Sized> HandHardware for SimHand<W> {
    fn read(&mut self, _now_s: f64) -> Result<HandState, HardwareError> {
        Ok(lock(&self.world)?.hand_state())
    }

    /// Stores the command; a non-finite command is refused and leaves the previous one
    /// in force.
    fn write(&mut self, _now_s: f64, command: &HandCommand) -> Result<(), HardwareError> {
        if !command.is_finite() {
            return Err(HardwareError::Fault("non-finite hand command".to_owned()));
        }
        lock(&self.world)?.command_hand(command);
        Ok(())
    }
}

/// Wraps a world for sharing and returns the two hardware handles with it.
pub fn share<W>(world: W) -> (SharedWorld<W>, SimArm<W>, SimHand<W>) {
    let shared = Arc::new(Mutex::new(world));
    (
        shared.clone(),
        SimArm::new(shared.clone()),
        SimHand::new(shared),
    )
}
