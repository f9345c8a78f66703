//! Hardware clients over the bus: the arm, the hand and the cameras as a driver process
//! (the simulator today, a real driver later) exposes them on the `teleop/hw/...`
//! topics. They implement the same [`ArmHardware`] / [`HandHardware`] /
//! [`CameraHardware`] traits as in-process backends, so the controllers cannot tell
//! where the hardware is.

use teleop_bus::{Bus, BusError, Publisher, Subscriber, Topic, topics};
use teleop_msgs::{FingertipPressures, Image, JointState, unix_seconds_now as now_s};

use crate::hardware::{
    ArmCommand, ArmHardware, ArmState, CameraHardware, HandCommand, HandHardware, HandState,
    HardwareError,
};
use crate::wire;

/// Checks the settings every controller node has: the operator-site nodes it watches
/// (at least one) and how old the hardware state may get (finite, > 0).
///
/// # Errors
/// A message naming the field.
pub fn check_controller_links(
    operator_site_nodes: &[String],
    hardware_timeout_s: f64,
) -> Result<(), String> {
    if operator_site_nodes.is_empty() {
        return Err("operator_site_nodes must name at least one node".into());
    }
    if !(hardware_timeout_s.is_finite() && hardware_timeout_s > 0.0) {
        return Err(format!(
            "hardware_timeout_s must be positive, got {hardware_timeout_s}"
        ));
    }
    Ok(())
}

/// The arm hardware reached over the bus.
#[derive(Debug)]
pub struct BusArm {
    state: Subscriber<JointState>,
    /// `None` for a read-only handle (monitoring: it never commands the arm).
    command: Option<Publisher<JointState>>,
    latest: Option<(ArmState, f64)>,
    stale_after_s: f64,
    bad_states: u64,
}

impl BusArm {
    /// # Errors
    /// [`BusError`] if the subscriptions cannot be declared.
    pub async fn new(bus: &Bus, stale_after_s: f64) -> Result<Self, BusError> {
        let mut arm = Self::monitor(bus, stale_after_s).await?;
        arm.command = Some(bus.publisher(&topics::SIM_ARM_COMMAND).await?);
        Ok(arm)
    }

    /// A read-only handle: reads the state, refuses to write.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn monitor(bus: &Bus, stale_after_s: f64) -> Result<Self, BusError> {
        Ok(Self {
            state: bus.subscriber(&topics::SIM_ARM_STATE).await?,
            command: None,
            latest: None,
            stale_after_s,
            bad_states: 0,
        })
    }

    /// State messages that failed to convert (missing joints, NaN).
    pub fn bad_states(&self) -> u64 {
        self.bad_states
    }
}

impl ArmHardware for BusArm {
    fn read(&mut self) -> Result<ArmState, HardwareError> {
        while let Some(r) = self.state.try_recv() {
            match wire::arm_state(&r.msg) {
                Ok(s) => self.latest = Some((s, r.receive_time_s())),
                Err(e) => {
                    self.bad_states += 1;
                    tracing::warn!("arm state refused: {e}");
                }
            }
        }
        let (state, at) = self
            .latest
            .ok_or_else(|| HardwareError::NotConnected("no arm state received yet".into()))?;
        let age_s = now_s() - at;
        if age_s > self.stale_after_s {
            return Err(HardwareError::StaleState { age_s });
        }
        Ok(state)
    }

    fn write(&mut self, command: &ArmCommand) -> Result<(), HardwareError> {
        let publisher = self
            .command
            .as_ref()
            .ok_or_else(|| HardwareError::NotConnected("read-only arm handle".into()))?;
        publisher
            .put(&wire::arm_command_msg(command, now_s()))
            .map_err(|e| HardwareError::Fault(e.to_string()))
    }
}

/// The hand hardware reached over the bus.
#[derive(Debug)]
pub struct BusHand {
    state: Subscriber<JointState>,
    tactile: Subscriber<FingertipPressures>,
    /// `None` for a read-only handle.
    command: Option<Publisher<JointState>>,
    latest: Option<(HandState, f64)>,
    latest_tactile: Option<FingertipPressures>,
    stale_after_s: f64,
    bad_states: u64,
}

impl BusHand {
    /// # Errors
    /// [`BusError`] if the subscriptions cannot be declared.
    pub async fn new(bus: &Bus, stale_after_s: f64) -> Result<Self, BusError> {
        let mut hand = Self::monitor(bus, stale_after_s).await?;
        hand.command = Some(bus.publisher(&topics::SIM_HAND_COMMAND).await?);
        Ok(hand)
    }

    /// A read-only handle: reads the state, refuses to write.
    ///
    /// # Errors
    /// [`BusError`] if the subscriptions cannot be declared.
    pub async fn monitor(bus: &Bus, stale_after_s: f64) -> Result<Self, BusError> {
        Ok(Self {
            state: bus.subscriber(&topics::SIM_HAND_STATE).await?,
            tactile: bus.subscriber(&topics::SIM_HAND_TACTILE).await?,
            command: None,
            latest: None,
            latest_tactile: None,
            stale_after_s,
            bad_states: 0,
        })
    }

    pub fn bad_states(&self) -> u64 {
        self.bad_states
    }
}

impl HandHardware for BusHand {
    fn read(&mut self) -> Result<HandState, HardwareError> {
        while let Some(t) = self.tactile.try_recv() {
            self.latest_tactile = Some(t.msg);
        }
        while let Some(r) = self.state.try_recv() {
            match wire::hand_state(&r.msg, self.latest_tactile.as_ref()) {
                Ok(s) => self.latest = Some((s, r.receive_time_s())),
                Err(e) => {
                    self.bad_states += 1;
                    tracing::warn!("hand state refused: {e}");
                }
            }
        }
        let (state, at) = self
            .latest
            .ok_or_else(|| HardwareError::NotConnected("no hand state received yet".into()))?;
        let age_s = now_s() - at;
        if age_s > self.stale_after_s {
            return Err(HardwareError::StaleState { age_s });
        }
        Ok(state)
    }

    fn write(&mut self, command: &HandCommand) -> Result<(), HardwareError> {
        let publisher = self
            .command
            .as_ref()
            .ok_or_else(|| HardwareError::NotConnected("read-only hand handle".into()))?;
        publisher
            .put(&wire::hand_command_msg(command, now_s()))
            .map_err(|e| HardwareError::Fault(e.to_string()))
    }
}

/// A camera reached over the bus (read-only: cameras take no commands), e.g. one of
/// [`topics::SIM_CAMERA_TOP`] / [`topics::SIM_CAMERA_SIDE`].
#[derive(Debug)]
pub struct BusCamera {
    images: Subscriber<Image>,
    /// Images this handle itself skipped (besides those the subscriber overwrote).
    skipped: u64,
    bad_images: u64,
}

impl BusCamera {
    /// Subscribes to `topic`.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn monitor(bus: &Bus, topic: &Topic<Image>) -> Result<Self, BusError> {
        Ok(Self {
            images: bus.subscriber(topic).await?,
            skipped: 0,
            bad_images: 0,
        })
    }

    /// Images refused because their layout did not match their size and encoding.
    pub fn bad_images(&self) -> u64 {
        self.bad_images
    }
}

impl CameraHardware for BusCamera {
    fn latest(&mut self) -> Result<Option<Image>, HardwareError> {
        let mut newest = None;
        while let Some(r) = self.images.try_recv() {
            if newest.is_some() {
                self.skipped += 1;
            }
            newest = Some(r.msg);
        }
        match newest {
            Some(image) => match image.check_layout() {
                Ok(()) => Ok(Some(image)),
                Err(e) => {
                    self.bad_images += 1;
                    Err(HardwareError::Fault(format!("camera image refused: {e}")))
                }
            },
            None => Ok(None),
        }
    }

    fn dropped(&self) -> u64 {
        self.skipped + self.images.stats().overwritten
    }
}
