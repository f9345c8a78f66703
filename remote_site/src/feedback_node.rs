//! The feedback publisher: what the operator site sees of the robot site. Reads the
//! arm and hand hardware (read-only handles: it never commands them) and publishes the
//! joint states of both robots and the five fingertip pressures, rate-limited, plus its
//! status. Forwards the two camera views (`teleop/hw/camera/{top,side}/image`) to the
//! operator site as JPEG (`teleop/remote_camera/{top,side}/image/compressed`), each at
//! most `camera_rate_hz`, newest frame only: frames that arrive faster are dropped and
//! counted, never queued. On a WAN they give way to the feedback: the operator's
//! display acknowledges each view it receives (`teleop/remote_camera/receipts`), and
//! the views are paced by the round trip of those receipts ([`crate::view_pacer`]).

use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher, Subscriber};
use teleop_hardware::{ArmHardware, Camera, CameraKind, HandHardware, wire};
use teleop_hardware_bus::{BusArm, BusCamera, BusHand};
use teleop_interfaces::hardware::{PR2_ARM, SHADOW_HAND};
use teleop_interfaces::topics;
use teleop_msgs::{FingertipPressures, Header, JointState, Lifecycle};
use teleop_node::{FinalReport, Node, NodeConfig, NodeErrors, SchedulingConfig};

use crate::view_pacer::{PacingConfig, ReceiptOutcome, ViewPacer};

/// Configuration of the `feedback_publisher` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FeedbackConfig {
    pub node_name: String,
    /// Rate of the joint states and pressures sent to the operator site, Hz.
    pub rate_hz: f64,
    /// Hardware state older than this is not forwarded, s.
    pub hardware_timeout_s: f64,
    /// Highest rate at which each camera view is forwarded, Hz, in [0, 60]; 0 forwards
    /// no camera images. New frames are looked for at `rate_hz` and forwarded on
    /// arrival within this limit.
    pub camera_rate_hz: f64,
    /// JPEG quality of the forwarded camera views, 1-100 (libjpeg's scale; 80 keeps a
    /// 320 x 240 view near 1/31 of its raw size: docs/network.md).
    pub camera_jpeg_quality: u8,
    /// Pacing of the views by the operator display's receipts.
    pub camera_pacing: PacingConfig,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    pub bus: BusConfig,
}

impl Default for FeedbackConfig {
    fn default() -> Self {
        Self {
            node_name: "feedback_publisher".into(),
            rate_hz: topics::PR2_JOINT_STATES.spec.rate_hz,
            hardware_timeout_s: 0.1,
            camera_rate_hz: topics::REMOTE_CAMERA_TOP.spec.rate_hz,
            camera_jpeg_quality: 80,
            camera_pacing: PacingConfig::default(),
            scheduling: SchedulingConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for FeedbackConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= 1000.0) {
            return Err(format!(
                "rate_hz must be in (0, 1000], got {}",
                self.rate_hz
            ));
        }
        if !(self.hardware_timeout_s.is_finite() && self.hardware_timeout_s > 0.0) {
            return Err(format!(
                "hardware_timeout_s must be positive, got {}",
                self.hardware_timeout_s
            ));
        }
        if !(self.camera_rate_hz.is_finite()
            && self.camera_rate_hz >= 0.0
            && self.camera_rate_hz <= 60.0)
        {
            return Err(format!(
                "camera_rate_hz must be in [0, 60], got {}",
                self.camera_rate_hz
            ));
        }
        if !(1..=100).contains(&self.camera_jpeg_quality) {
            return Err(format!(
                "camera_jpeg_quality must be in [1, 100], got {}",
                self.camera_jpeg_quality
            ));
        }
        self.camera_pacing.validate()
    }
}

/// The node: read-only hardware handles, the publishers toward the operator site.
#[derive(Debug)]
pub struct FeedbackNode {
    rate_hz: f64,
    arm: BusArm<7>,
    hand: BusHand,
    arm_pub: Publisher<JointState>,
    hand_pub: Publisher<JointState>,
    pressure_pub: Publisher<FingertipPressures>,
    cameras: Vec<CameraForward>,
    /// Receipts of the views from the operator's display.
    receipts: Option<Subscriber<Header>>,
    pacer: ViewPacer,
    arm_sent: u64,
    hand_sent: u64,
    missing: u64,
    hardware_ok: bool,
    errors: NodeErrors,
}

impl FeedbackNode {
    /// Declares the handles and publishers on `bus`.
    ///
    /// # Errors
    /// Bus declarations.
    pub async fn new(cfg: &FeedbackConfig, bus: &Bus) -> anyhow::Result<Self> {
        let mut cameras = Vec::new();
        if cfg.camera_rate_hz > 0.0 {
            for (name, from, to) in [
                ("top", topics::HW_CAMERA_TOP, topics::REMOTE_CAMERA_TOP),
                ("side", topics::HW_CAMERA_SIDE, topics::REMOTE_CAMERA_SIDE),
            ] {
                cameras.push(CameraForward {
                    name,
                    camera: BusCamera::monitor(bus, &from, CameraKind::Color).await?,
                    publisher: bus.publisher(&to).await?,
                    frame_id: None,
                    last_bytes: 0,
                    quality: cfg.camera_jpeg_quality,
                    forwarded: 0,
                    bytes: 0,
                    // 10 % below the period: frames arriving at exactly the limit's rate
                    // (with jitter) all pass.
                    min_interval_s: 0.9 / cfg.camera_rate_hz,
                    last_sent_s: None,
                });
            }
        }
        Ok(Self {
            rate_hz: cfg.rate_hz,
            arm: BusArm::monitor(bus, &PR2_ARM, cfg.hardware_timeout_s).await?,
            hand: BusHand::monitor(bus, &SHADOW_HAND, cfg.hardware_timeout_s).await?,
            arm_pub: bus.publisher(&topics::PR2_JOINT_STATES).await?,
            hand_pub: bus.publisher(&topics::SHADOW_JOINT_STATES).await?,
            pressure_pub: bus.publisher(&topics::FINGERTIP_PRESSURES).await?,
            receipts: if cameras.is_empty() {
                None
            } else {
                Some(bus.subscriber(&topics::REMOTE_CAMERA_RECEIPTS).await?)
            },
            cameras,
            pacer: ViewPacer::new(cfg.camera_pacing.clone()),
            arm_sent: 0,
            hand_sent: 0,
            missing: 0,
            hardware_ok: false,
            errors: NodeErrors::new(),
        })
    }
}

impl Node for FeedbackNode {
    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.rate_hz)
    }

    fn tick(&mut self, now_s: f64) {
        self.errors.step(now_s);
        let mut ok = true;
        match self.arm.read(now_s) {
            Ok(s) => {
                self.errors.resolved("arm hardware", now_s);
                match self.arm_pub.put(&wire::arm_state_msg(&PR2_ARM.joints, &s)) {
                    Ok(()) => self.arm_sent += 1,
                    Err(e) => self.errors.event("publish", e.to_string(), now_s),
                }
            }
            Err(e) => {
                ok = false;
                self.missing += 1;
                self.errors.condition("arm hardware", e.to_string(), now_s);
            }
        }
        match self.hand.read(now_s) {
            Ok(s) => {
                self.errors.resolved("hand hardware", now_s);
                match self.hand_pub.put(&wire::hand_state_msg(&s)) {
                    Ok(()) => self.hand_sent += 1,
                    Err(e) => self.errors.event("publish", e.to_string(), now_s),
                }
                if let Err(e) = self.pressure_pub.put(&wire::tactile_msg(&s)) {
                    self.errors.event("publish", e.to_string(), now_s);
                }
            }
            Err(e) => {
                ok = false;
                self.missing += 1;
                self.errors.condition("hand hardware", e.to_string(), now_s);
            }
        }
        self.hardware_ok = ok;
        self.take_receipts(now_s);
        // Cameras are checked at this (faster) rate and forwarded on arrival,
        // rate-limited and paced, so a 15 Hz camera is not aliased by a 15 Hz poll.
        // The view sent longest ago goes first, so a window with room for one view
        // serves both in turn.
        let mut order: Vec<usize> = (0..self.cameras.len()).collect();
        order.sort_by(|a, b| {
            let t = |i: &usize| self.cameras[*i].last_sent_s.unwrap_or(f64::NEG_INFINITY);
            t(a).total_cmp(&t(b))
        });
        for i in order {
            let c = &mut self.cameras[i];
            if let Err(e) = c.forward(now_s, i, &mut self.pacer) {
                self.errors
                    .event("camera", format!("camera {}: {e}", c.name), now_s);
            }
        }
    }

    /// Active while both robots' states come in; Fault when one is missing (the
    /// operator site then sees no feedback). It commands nothing.
    fn state(&self) -> Lifecycle {
        if self.hardware_ok {
            Lifecycle::Active
        } else {
            Lifecycle::Fault
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let mut counters = vec![
            ("feedback.arm_states".to_owned(), self.arm_sent),
            ("feedback.hand_states".to_owned(), self.hand_sent),
            ("feedback.hardware_missing".to_owned(), self.missing),
        ];
        for c in &self.cameras {
            let name = |what| format!("feedback.camera_{}.{what}", c.name);
            counters.push((name("forwarded"), c.forwarded));
            counters.push((name("bytes"), c.bytes));
            counters.push((name("dropped"), c.camera.dropped()));
            counters.push((name("bad"), c.camera.bad_images()));
        }
        if !self.cameras.is_empty() {
            let p = self.pacer.counters();
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let window = self.pacer.window_bytes() as u64;
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let base_rtt_us = self.pacer.base_rtt_s().map_or(0, |s| (s * 1e6) as u64);
            counters.extend([
                (
                    "feedback.camera_pacing.acknowledged".to_owned(),
                    p.acknowledged,
                ),
                ("feedback.camera_pacing.lost".to_owned(), p.lost),
                ("feedback.camera_pacing.held".to_owned(), p.held),
                ("feedback.camera_pacing.unmatched".to_owned(), p.unmatched),
                ("feedback.camera_pacing.window_bytes".to_owned(), window),
                ("feedback.camera_pacing.base_rtt_us".to_owned(), base_rtt_us),
            ]);
        }
        counters
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }
}

impl FeedbackNode {
    /// Feeds the receipts that came in to the pacer. A receipt for a frame no camera
    /// has is counted as unmatched, nothing else.
    fn take_receipts(&mut self, now_s: f64) {
        let Some(receipts) = &self.receipts else {
            return;
        };
        while let Some(r) = receipts.try_recv() {
            let view = self
                .cameras
                .iter()
                .position(|c| c.frame_id.as_deref() == Some(r.msg.frame_id.as_str()));
            // A receipt for no camera of ours matches no view in flight: counted.
            let view = view.unwrap_or(usize::MAX);
            let outcome = self.pacer.receipt(now_s, view, r.msg.stamp.as_nanos());
            if let ReceiptOutcome::Acknowledged { rtt_s, queue_s } = outcome {
                tracing::trace!(rtt_s, queue_s, "view acknowledged");
            }
        }
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus errors.
pub async fn run(cfg: FeedbackConfig, duration: Option<Duration>) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = FeedbackNode::new(&cfg, &bus).await?;
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}

/// One camera view on its way to the operator site.
#[derive(Debug)]
struct CameraForward {
    name: &'static str,
    camera: BusCamera,
    publisher: teleop_bus::Publisher<teleop_msgs::CompressedImage>,
    /// The camera's frame, as its images name it (receipts are matched by it).
    frame_id: Option<String>,
    /// Size of the last JPEG sent, bytes (the next one's size for the pacer).
    last_bytes: usize,
    /// JPEG quality, 1-100.
    quality: u8,
    forwarded: u64,
    /// JPEG bytes forwarded.
    bytes: u64,
    /// Shortest time between two forwarded frames, s.
    min_interval_s: f64,
    last_sent_s: Option<f64>,
}

impl CameraForward {
    /// Sends the newest image since the last forwarded one, if any and if the rate
    /// limit and the pacer allow, as JPEG with the camera's stamp and frame. While
    /// they hold frames back the frames wait in the newest-only subscription (older
    /// ones are dropped and counted there). An image that cannot be compressed (not
    /// `rgb8`) is not sent and the error names it.
    fn forward(&mut self, now_s: f64, view: usize, pacer: &mut ViewPacer) -> anyhow::Result<()> {
        if self
            .last_sent_s
            .is_some_and(|t| now_s - t < self.min_interval_s)
        {
            return Ok(());
        }
        if !self.camera.has_new() || !pacer.may_send(now_s, self.last_bytes) {
            return Ok(());
        }
        if let Some(image) = self.camera.read(now_s)? {
            let jpeg = teleop_msgs::image_codec::jpeg_from_rgb8(&image, self.quality)?;
            self.publisher.put(&jpeg)?;
            let bytes = jpeg.data.len();
            pacer.sent(now_s, view, jpeg.header.stamp.as_nanos(), bytes);
            if self.frame_id.as_deref() != Some(jpeg.header.frame_id.as_str()) {
                self.frame_id = Some(jpeg.header.frame_id.clone());
            }
            self.forwarded += 1;
            self.bytes += bytes as u64;
            self.last_bytes = bytes;
            self.last_sent_s = Some(now_s);
        }
        Ok(())
    }
}
