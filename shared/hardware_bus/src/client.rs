//! Controller-side clients.

use teleop_bus::{Bus, BusError, Publisher, Subscriber};
use teleop_hardware::{
    ArmCommand, ArmHardware, ArmState, Camera, CameraKind, HandCommand, HandHardware, HandState,
    HardwareError, wire,
};
use teleop_interfaces::{ArmInterface, HandInterface, Topic};
use teleop_msgs::{FingertipPressures, Image, JointState};

/// The newest valid state of a subscription, with its receive time.
fn freshest<S: Copy>(
    latest: Option<(S, f64)>,
    now_s: f64,
    stale_after_s: f64,
    what: &str,
) -> Result<S, HardwareError> {
    let (state, at) = latest
        .ok_or_else(|| HardwareError::NotConnected(format!("no {what} state received yet")))?;
    let age_s = now_s - at;
    if age_s > stale_after_s {
        return Err(HardwareError::StaleState { age_s });
    }
    Ok(state)
}

/// An arm of `N` joints reached over the bus.
#[derive(Debug)]
pub struct BusArm<const N: usize> {
    interface: ArmInterface<N>,
    state: Subscriber<JointState>,
    /// `None` for a read-only handle (monitoring: it never commands the arm).
    command: Option<Publisher<JointState>>,
    latest: Option<(ArmState<N>, f64)>,
    stale_after_s: f64,
    bad_states: u64,
}

impl<const N: usize> BusArm<N> {
    /// A handle that reads the state and sends commands.
    ///
    /// # Errors
    /// [`BusError`] if the declarations fail.
    pub async fn new(
        bus: &Bus,
        interface: &ArmInterface<N>,
        stale_after_s: f64,
    ) -> Result<Self, BusError> {
        let mut arm = Self::monitor(bus, interface, stale_after_s).await?;
        arm.command = Some(bus.publisher(&interface.command).await?);
        Ok(arm)
    }

    /// A read-only handle: reads the state, refuses to write.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn monitor(
        bus: &Bus,
        interface: &ArmInterface<N>,
        stale_after_s: f64,
    ) -> Result<Self, BusError> {
        Ok(Self {
            interface: *interface,
            state: bus.subscriber(&interface.state).await?,
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

    /// The interface this handle serves.
    pub fn interface(&self) -> &ArmInterface<N> {
        &self.interface
    }
}

impl<const N: usize> ArmHardware<N> for BusArm<N> {
    fn read(&mut self, now_s: f64) -> Result<ArmState<N>, HardwareError> {
        while let Some(r) = self.state.try_recv() {
            match wire::arm_state(&self.interface.joints, &r.msg) {
                Ok(s) => self.latest = Some((s, r.receive_time_s())),
                Err(e) => {
                    self.bad_states += 1;
                    tracing::warn!(arm = self.interface.name, "state refused: {e}");
                }
            }
        }
        freshest(self.latest, now_s, self.stale_after_s, self.interface.name)
    }

    fn write(&mut self, now_s: f64, command: &ArmCommand<N>) -> Result<(), HardwareError> {
        let publisher = self
            .command
            .as_ref()
            .ok_or(HardwareError::ReadOnly(self.interface.name))?;
        publisher
            .put(&wire::arm_command_msg(
                &self.interface.joints,
                command,
                now_s,
            ))
            .map_err(|e| HardwareError::Fault(e.to_string()))
    }
}

/// The hand reached over the bus.
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
    /// A handle that reads the state and sends commands.
    ///
    /// # Errors
    /// [`BusError`] if the declarations fail.
    pub async fn new(
        bus: &Bus,
        interface: &HandInterface,
        stale_after_s: f64,
    ) -> Result<Self, BusError> {
        let mut hand = Self::monitor(bus, interface, stale_after_s).await?;
        hand.command = Some(bus.publisher(&interface.command).await?);
        Ok(hand)
    }

    /// A read-only handle: reads the state, refuses to write.
    ///
    /// # Errors
    /// [`BusError`] if the subscriptions cannot be declared.
    pub async fn monitor(
        bus: &Bus,
        interface: &HandInterface,
        stale_after_s: f64,
    ) -> Result<Self, BusError> {
        Ok(Self {
            state: bus.subscriber(&interface.state).await?,
            tactile: bus.subscriber(&interface.tactile).await?,
            command: None,
            latest: None,
            latest_tactile: None,
            stale_after_s,
            bad_states: 0,
        })
    }

    /// State messages that failed to convert.
    pub fn bad_states(&self) -> u64 {
        self.bad_states
    }
}

impl HandHardware for BusHand {
    fn read(&mut self, now_s: f64) -> Result<HandState, HardwareError> {
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
        freshest(self.latest, now_s, self.stale_after_s, "hand")
    }

    fn write(&mut self, now_s: f64, command: &HandCommand) -> Result<(), HardwareError> {
        let publisher = self
            .command
            .as_ref()
            .ok_or(HardwareError::ReadOnly("hand"))?;
        publisher
            .put(&wire::hand_command_msg(command, now_s))
            .map_err(|e| HardwareError::Fault(e.to_string()))
    }
}

/// A camera reached over the bus (read-only: cameras take no commands).
#[derive(Debug)]
pub struct BusCamera {
    kind: CameraKind,
    images: Subscriber<Image>,
    /// Images this handle itself skipped (besides those the subscriber overwrote).
    skipped: u64,
    bad_images: u64,
}

impl BusCamera {
    /// Subscribes to `topic`, a camera of `kind`.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn monitor(
        bus: &Bus,
        topic: &Topic<Image>,
        kind: CameraKind,
    ) -> Result<Self, BusError> {
        Ok(Self {
            kind,
            images: bus.subscriber(topic).await?,
            skipped: 0,
            bad_images: 0,
        })
    }

    /// Images refused because their layout did not match their size and encoding, or
    /// their encoding not the camera's kind.
    pub fn bad_images(&self) -> u64 {
        self.bad_images
    }
}

impl Camera for BusCamera {
    fn kind(&self) -> CameraKind {
        self.kind
    }

    fn read(&mut self, _now_s: f64) -> Result<Option<Image>, HardwareError> {
        let mut newest = None;
        while let Some(r) = self.images.try_recv() {
            if newest.is_some() {
                self.skipped += 1;
            }
            newest = Some(r.msg);
        }
        let Some(image) = newest else {
            return Ok(None);
        };
        let problem = if self.kind.accepts(&image.encoding) {
            image.check_layout().err().map(|e| e.to_string())
        } else {
            Some(format!(
                "encoding `{}` is not a {:?} image",
                image.encoding, self.kind
            ))
        };
        match problem {
            None => Ok(Some(image)),
            Some(e) => {
                self.bad_images += 1;
                Err(HardwareError::Fault(format!("camera image refused: {e}")))
            }
        }
    }

    fn dropped(&self) -> u64 {
        self.skipped + self.images.stats().overwritten
    }
}
