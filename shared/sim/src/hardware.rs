//! [`ArmHardware`] / [`HandHardware`] over a shared in-process [`World`].
//!
//! The handles only move data: `read` returns the state the world measured at its last
//! step, `write` stores a command that the next [`World::step`] applies. Whoever owns
//! the loop (a test, or a single-process simulator) steps the world; a controller holding
//! a handle cannot tell it from a real driver.

use std::sync::{Arc, Mutex, MutexGuard};

use super::world::World;
use teleop_hardware::{
    ArmCommand, ArmHardware, ArmState, HandCommand, HandHardware, HandState, HardwareError,
};

/// A world shared between the stepping loop and the hardware handles.
pub type SharedWorld = Arc<Mutex<World>>;

fn lock(world: &SharedWorld) -> Result<MutexGuard<'_, World>, HardwareError> {
    world
        .lock()
        .map_err(|_| HardwareError::Fault("simulated world lock poisoned".to_owned()))
}

/// The simulated arm seen through [`ArmHardware`].
#[derive(Debug, Clone)]
pub struct SimArm {
    world: SharedWorld,
}

impl SimArm {
    /// A handle on `world`'s arm.
    pub fn new(world: SharedWorld) -> Self {
        Self { world }
    }
}

impl ArmHardware<7> for SimArm {
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
#[derive(Debug, Clone)]
pub struct SimHand {
    world: SharedWorld,
}

impl SimHand {
    /// A handle on `world`'s hand.
    pub fn new(world: SharedWorld) -> Self {
        Self { world }
    }
}

impl HandHardware for SimHand {
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
pub fn share(world: World) -> (SharedWorld, SimArm, SimHand) {
    let shared = Arc::new(Mutex::new(world));
    (
        shared.clone(),
        SimArm::new(shared.clone()),
        SimHand::new(shared),
    )
}
