//! Controller-side clients.

use nalgebra::Isometry3;
use teleop_bus::{Bus, BusError, Publisher, Subscriber};
use teleop_hardware::wire::{PoseError, checked_isometry};
use teleop_hardware::{
    ArmCommand, ArmHardware, ArmState, Camera, CameraKind, HandCommand, HandHardware, HandState,
    HardwareError, OperatorPanel, PedalState, WristTracker, wire,
};
use teleop_interfaces::{ArmInterface, HandInterface, Topic, topics};
use teleop_msgs::{
    FingertipPressures, Image, JointCommand, JointState, OperatorInput, PoseStamped, Time,
};

/// The newest valid state of a subscription, with its receive time; `missing` says why
/// there is none yet.
fn freshest<S: Copy>(
    latest: Option<(S, f64)>,
    now_s: f64,
    stale_after_s: f64,
    missing: impl FnOnce() -> HardwareError,
) -> Result<S, HardwareError> {
    let (state, at) = latest.ok_or_else(missing)?;
    let age_s = now_s - at;
    if age_s > stale_after_s {
        return Err(HardwareError::StaleState { age_s });
    }
    Ok(state)
}

/// How long a publisher must have announced a hardware state without one sample
/// arriving before the error says its samples are being dropped (a driver declares its
/// publisher a moment before it first publishes), s.
pub const SILENT_PUBLISHER_AFTER_S: f64 = 2.0;

/// Why no state of `what` has arrived on `state`: nothing published yet, or (named in
/// the error, and once in the log) a publisher that has announced the topic for
/// [`SILENT_PUBLISHER_AFTER_S`] but whose samples never arrive, which for a hardware
/// topic is most often the hardware access rule: hardware topics travel only on the
/// node's `hardware_interfaces`.
#[derive(Debug)]
struct NoStateYet {
    what: &'static str,
    hardware_interfaces: Vec<String>,
    /// When a publisher was first seen announced with no state received.
    announced_since_s: Option<f64>,
    warned: bool,
}

impl NoStateYet {
    fn new(bus: &Bus, what: &'static str) -> Self {
        Self {
            what,
            hardware_interfaces: bus.config().zenoh.hardware_interfaces.clone(),
            announced_since_s: None,
            warned: false,
        }
    }

    fn error<T: teleop_msgs::Message>(
        &mut self,
        now_s: f64,
        state: &Subscriber<T>,
    ) -> HardwareError {
        let what = self.what;
        let announced = state.announced_publishers();
        let plain = || HardwareError::NotConnected(format!("no {what} state received yet"));
        if announced.is_empty() {
            self.announced_since_s = None;
            return plain();
        }
        let since = *self.announced_since_s.get_or_insert(now_s);
        let waited_s = now_s - since;
        if waited_s.is_nan() || waited_s < SILENT_PUBLISHER_AFTER_S {
            return plain();
        }
        let names: Vec<String> = announced.iter().map(|p| p.label()).collect();
        let text = format!(
            "no {what} state received yet, though {} publishes /{}: its samples do not \
             arrive here. Hardware topics travel only on this node's hardware_interfaces \
             ({}); is the link to it on another interface (see --hardware-interface)?",
            names.join(", "),
            state.spec().name,
            self.hardware_interfaces.join(", ")
        );
        if !self.warned {
            self.warned = true;
            tracing::warn!("{text}");
        }
        HardwareError::NotConnected(text)
    }
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
    no_state: NoStateYet,
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
            no_state: NoStateYet::new(bus, interface.name),
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
        let (no_state, state) = (&mut self.no_state, &self.state);
        freshest(self.latest, now_s, self.stale_after_s, || {
            no_state.error(now_s, state)
        })
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
    command: Option<Publisher<JointCommand>>,
    latest: Option<(HandState, f64)>,
    latest_tactile: Option<FingertipPressures>,
    stale_after_s: f64,
    bad_states: u64,
    no_state: NoStateYet,
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
            no_state: NoStateYet::new(bus, "hand"),
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
        let (no_state, state) = (&mut self.no_state, &self.state);
        freshest(self.latest, now_s, self.stale_after_s, || {
            no_state.error(now_s, state)
        })
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
    /// When the last image read was put on the bus (its publisher's clock, ns).
    last_sent_ns: Option<i64>,
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
            last_sent_ns: None,
        })
    }

    /// Wakes `wake` whenever an image arrives (see
    /// [`teleop_bus::Subscriber::wake_on_sample`]): a node processes each frame as it
    /// comes instead of at its next period.
    pub fn wake_on_frame(&self, wake: Option<std::sync::Arc<teleop_bus::Notify>>) {
        self.images.wake_on_sample(wake);
    }

    /// Whether an image arrived that `read` has not returned yet.
    pub fn has_new(&self) -> bool {
        self.images.has_sample()
    }

    /// When the image last returned by `read` was put on the bus (ns since the Unix
    /// epoch, the publisher's clock): the camera driver's send time.
    pub fn last_sent_ns(&self) -> Option<i64> {
        self.last_sent_ns
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
            self.last_sent_ns = Some(r.source_timestamp_ns);
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

/// Largest accepted deviation of a tracker sample's quaternion norm from 1 (a driver
/// sends unit quaternions in `f64`; anything further off is a corrupt sample).
pub const MARKER_QUATERNION_TOLERANCE: f64 = 1e-6;

/// One motion-capture sample: the marker's pose and when it was captured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerSample {
    /// The marker's pose in the tracker's own frame (quaternion re-normalized).
    pub pose: Isometry3<f64>,
    /// Capture time: the message's `header.stamp`, exactly as the driver wrote it.
    pub capture: Time,
    /// Receive time on this node's clock, s since the Unix epoch.
    pub received_s: f64,
}

/// The marker pose of a message, or why it is refused.
fn marker_pose(msg: &PoseStamped) -> Result<Isometry3<f64>, PoseError> {
    checked_isometry(&msg.pose, MARKER_QUATERNION_TOLERANCE)
}

/// A motion-capture tracker reached over the bus ([`topics::HW_MOCAP_MARKER`] by
/// default): the marker's pose in the tracker's own frame, stamped with its capture
/// time.
///
/// [`read_sample`](Self::read_sample) (and [`WristTracker::read`]) return the newest
/// sample that arrived since the last read, `Ok(None)` when none did (the marker is
/// occluded, or the reader is faster than the tracker). Samples with a non-finite
/// value or a quaternion norm off 1 by more than [`MARKER_QUATERNION_TOLERANCE`] are
/// refused and counted ([`non_finite`](Self::non_finite),
/// [`not_normalized`](Self::not_normalized)); they count as no sample.
#[derive(Debug)]
pub struct BusWristTracker {
    samples: Subscriber<PoseStamped>,
    stale_after_s: f64,
    newest: Option<MarkerSample>,
    non_finite: u64,
    not_normalized: u64,
    skipped: u64,
}

impl BusWristTracker {
    /// Subscribes to the motion-capture topic [`topics::HW_MOCAP_MARKER`]; the tracker
    /// is stale after `stale_after_s` without a valid sample.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn mocap(bus: &Bus, stale_after_s: f64) -> Result<Self, BusError> {
        Self::new(bus, &topics::HW_MOCAP_MARKER, stale_after_s).await
    }

    /// Subscribes to `topic` (marker poses in the tracker's own frame).
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn new(
        bus: &Bus,
        topic: &Topic<PoseStamped>,
        stale_after_s: f64,
    ) -> Result<Self, BusError> {
        Ok(Self {
            samples: bus.subscriber(topic).await?,
            stale_after_s,
            newest: None,
            non_finite: 0,
            not_normalized: 0,
            skipped: 0,
        })
    }

    /// The newest valid sample that arrived since the last read, with its capture
    /// time; `Ok(None)` when none did.
    ///
    /// # Errors
    /// [`HardwareError::NotConnected`] before the first valid sample,
    /// [`HardwareError::StaleState`] when the newest valid sample was received more
    /// than `stale_after_s` before `now_s`.
    pub fn read_sample(&mut self, now_s: f64) -> Result<Option<MarkerSample>, HardwareError> {
        let mut fresh: Option<MarkerSample> = None;
        while let Some(r) = self.samples.try_recv() {
            match marker_pose(&r.msg) {
                Ok(pose) => {
                    if fresh.is_some() {
                        self.skipped += 1;
                    }
                    fresh = Some(MarkerSample {
                        pose,
                        capture: r.msg.header.stamp,
                        received_s: r.receive_time_s(),
                    });
                }
                Err(e) => {
                    match e {
                        PoseError::NonFinite => self.non_finite += 1,
                        PoseError::NotUnit { .. } => self.not_normalized += 1,
                    }
                    tracing::debug!("tracker sample refused: {e}");
                }
            }
        }
        if fresh.is_some() {
            self.newest = fresh;
        }
        let newest = self.newest.as_ref().ok_or_else(|| {
            HardwareError::NotConnected("no motion-capture sample received yet".into())
        })?;
        let age_s = now_s - newest.received_s;
        if age_s > self.stale_after_s {
            return Err(HardwareError::StaleState { age_s });
        }
        Ok(fresh)
    }

    /// The newest valid sample received so far (the one the last successful read
    /// returned, or an older one), whatever its age.
    pub fn newest(&self) -> Option<&MarkerSample> {
        self.newest.as_ref()
    }

    /// Samples refused for a NaN or infinite value.
    pub fn non_finite(&self) -> u64 {
        self.non_finite
    }

    /// Samples refused for a quaternion whose norm is not 1.
    pub fn not_normalized(&self) -> u64 {
        self.not_normalized
    }

    /// Valid samples that arrived but were replaced by a newer one before a read took
    /// them (by this handle or by the subscriber's newest-only queue).
    pub fn skipped(&self) -> u64 {
        self.skipped + self.samples.stats().overwritten
    }

    /// The time after which the tracker is stale, s.
    pub fn stale_after_s(&self) -> f64 {
        self.stale_after_s
    }
}

impl WristTracker for BusWristTracker {
    fn read(&mut self, now_s: f64) -> Result<Option<Isometry3<f64>>, HardwareError> {
        Ok(self.read_sample(now_s)?.map(|s| s.pose))
    }
}

/// The pedal box and the enable switch reached over the bus ([`topics::HW_PEDALS`] by
/// default): their latest state.
///
/// A message with a non-finite motion scale is refused and counted
/// ([`bad_states`](Self::bad_states)); any other value is passed on (the robot site's
/// operator gate judges the motion scale).
#[derive(Debug)]
pub struct BusPanel {
    inputs: Subscriber<OperatorInput>,
    latest: Option<(PedalState, f64)>,
    stale_after_s: f64,
    bad_states: u64,
}

impl BusPanel {
    /// Subscribes to the pedal topic [`topics::HW_PEDALS`]; the state is stale (and
    /// [`OperatorPanel::read`] fails) after `stale_after_s` without a valid message.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn pedals(bus: &Bus, stale_after_s: f64) -> Result<Self, BusError> {
        Self::new(bus, &topics::HW_PEDALS, stale_after_s).await
    }

    /// Subscribes to `topic`.
    ///
    /// # Errors
    /// [`BusError`] if the subscription cannot be declared.
    pub async fn new(
        bus: &Bus,
        topic: &Topic<OperatorInput>,
        stale_after_s: f64,
    ) -> Result<Self, BusError> {
        Ok(Self {
            inputs: bus.subscriber(topic).await?,
            latest: None,
            stale_after_s,
            bad_states: 0,
        })
    }

    /// Messages refused (non-finite motion scale).
    pub fn bad_states(&self) -> u64 {
        self.bad_states
    }
}

impl OperatorPanel for BusPanel {
    fn read(&mut self, now_s: f64) -> Result<PedalState, HardwareError> {
        while let Some(r) = self.inputs.try_recv() {
            let m = &r.msg;
            if m.motion_scale.is_finite() {
                let state = PedalState {
                    clutch: m.clutch,
                    enable: m.enable,
                    camera_stop: m.camera_stop,
                    motion_scale: m.motion_scale,
                };
                self.latest = Some((state, r.receive_time_s()));
            } else {
                self.bad_states += 1;
                tracing::warn!("pedal state refused: non-finite motion scale");
            }
        }
        freshest(self.latest, now_s, self.stale_after_s, || {
            HardwareError::NotConnected("no pedal state received yet".into())
        })
    }
}
