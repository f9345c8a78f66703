//! The feedback publisher: what the operator site sees of the robot site. Reads the
//! arm and hand hardware (read-only handles: it never commands them) and publishes the
//! joint states of both robots and the five fingertip pressures, rate-limited, plus its
//! status. Forwards the two camera views (`teleop/hw/camera/{top,side}/image`) to the
//! operator site, each at most `camera_rate_hz`, newest frame only: frames that arrive
//! faster are dropped and counted, never queued.

use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, NodeConfig, StatusReporter, topics};
use teleop_msgs::Lifecycle;
use tokio::time::MissedTickBehavior;

use crate::bus_hardware::{BusArm, BusCamera, BusHand};
use crate::hardware::{ArmHardware, CameraHardware, HandHardware};
use crate::wire;

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
    pub bus: BusConfig,
}

impl Default for FeedbackConfig {
    fn default() -> Self {
        Self {
            node_name: "feedback_publisher".into(),
            rate_hz: topics::PR2_JOINT_STATES.spec.rate_hz,
            hardware_timeout_s: 0.1,
            camera_rate_hz: topics::REMOTE_CAMERA_TOP.spec.rate_hz,
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for FeedbackConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
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
        Ok(())
    }
}

/// Runs the node until `duration` elapses (forever if `None`) or Ctrl-C.
///
/// # Errors
/// Bus errors.
pub async fn run(cfg: FeedbackConfig, duration: Option<Duration>) -> anyhow::Result<()> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let mut arm = BusArm::monitor(&bus, cfg.hardware_timeout_s).await?;
    let mut hand = BusHand::monitor(&bus, cfg.hardware_timeout_s).await?;
    let arm_pub = bus.publisher(&topics::PR2_JOINT_STATES).await?;
    let hand_pub = bus.publisher(&topics::SHADOW_JOINT_STATES).await?;
    let pressure_pub = bus.publisher(&topics::FINGERTIP_PRESSURES).await?;
    let status = StatusReporter::new(&bus).await?;
    let mut cameras = Vec::new();
    if cfg.camera_rate_hz > 0.0 {
        for (name, from, to) in [
            ("top", topics::SIM_CAMERA_TOP, topics::REMOTE_CAMERA_TOP),
            ("side", topics::SIM_CAMERA_SIDE, topics::REMOTE_CAMERA_SIDE),
        ] {
            cameras.push(CameraForward {
                name,
                camera: BusCamera::monitor(&bus, &from).await?,
                publisher: bus.publisher(&to).await?,
                forwarded: 0,
                // 10 % below the period: frames arriving at exactly the limit's rate
                // (with jitter) all pass.
                min_interval: Duration::from_secs_f64(0.9 / cfg.camera_rate_hz),
                last_sent: None,
            });
        }
    }
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / cfg.rate_hz));
    tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let mut status_tick = tokio::time::interval(Duration::from_secs(1));
    let stop = teleop_bus::node::stop_signal(duration);
    tokio::pin!(stop);
    let (mut arm_sent, mut hand_sent, mut missing) = (0u64, 0u64, 0u64);
    let mut last_error = String::new();
    loop {
        tokio::select! {
            _ = &mut stop => break,
            _ = status_tick.tick() => {
                let mut counters = vec![
                    ("feedback.arm_states".to_owned(), arm_sent),
                    ("feedback.hand_states".to_owned(), hand_sent),
                    ("feedback.hardware_missing".to_owned(), missing),
                ];
                for c in &cameras {
                    let name = |what| format!("feedback.camera_{}.{what}", c.name);
                    counters.push((name("forwarded"), c.forwarded));
                    counters.push((name("dropped"), c.camera.dropped()));
                    counters.push((name("bad"), c.camera.bad_images()));
                }
                let _ = status.report(Lifecycle::Active, &counters, &last_error);
            }
            _ = tick.tick() => {
                match arm.read() {
                    Ok(s) => match arm_pub.put(&wire::arm_state_msg(&s)) {
                        Ok(()) => arm_sent += 1,
                        Err(e) => last_error = e.to_string(),
                    },
                    Err(e) => { missing += 1; last_error = e.to_string(); }
                }
                match hand.read() {
                    Ok(s) => {
                        match hand_pub.put(&wire::hand_state_msg(&s)) {
                            Ok(()) => hand_sent += 1,
                            Err(e) => last_error = e.to_string(),
                        }
                        if let Err(e) = pressure_pub.put(&wire::tactile_msg(&s)) {
                            last_error = e.to_string();
                        }
                    }
                    Err(e) => { missing += 1; last_error = e.to_string(); }
                }
                // Cameras are checked at this (faster) rate and forwarded on arrival,
                // rate-limited, so a 15 Hz camera is not aliased by a 15 Hz poll.
                let now = Instant::now();
                for c in &mut cameras {
                    if let Err(e) = c.forward(now) {
                        last_error = format!("camera {}: {e}", c.name);
                    }
                }
            }
        }
    }
    drop((arm, hand, arm_pub, hand_pub, pressure_pub, status, cameras));
    bus.close().await?;
    Ok(())
}

/// One camera view on its way to the operator site.
#[derive(Debug)]
struct CameraForward {
    name: &'static str,
    camera: BusCamera,
    publisher: teleop_bus::Publisher<teleop_msgs::Image>,
    forwarded: u64,
    /// Shortest time between two forwarded frames.
    min_interval: Duration,
    last_sent: Option<Instant>,
}

impl CameraForward {
    /// Sends the newest image since the last forwarded one, if any and if the rate
    /// limit allows, as it came (stamp and frame of the camera). While the limit holds
    /// frames back they wait in the newest-only subscription (older ones are dropped
    /// and counted there).
    fn forward(&mut self, now: Instant) -> anyhow::Result<()> {
        if self
            .last_sent
            .is_some_and(|t| now.duration_since(t) < self.min_interval)
        {
            return Ok(());
        }
        if let Some(image) = self.camera.latest()? {
            self.publisher.put(&image)?;
            self.forwarded += 1;
            self.last_sent = Some(now);
        }
        Ok(())
    }
}
