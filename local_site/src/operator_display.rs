//! The `operator_display` node (the thesis's PC3 showed the operator the two remote
//! camera views and the fingertip forces): what reaches the operator's site from the
//! robot site, received, checked and accounted for.
//!
//! * The two camera views ([`topics::REMOTE_CAMERA_TOP`], [`topics::REMOTE_CAMERA_SIDE`],
//!   JPEG): each view received is checked (its format names JPEG, its data starts
//!   with JPEG's start-of-image marker; the pixels are not decoded) and answered
//!   at once with a receipt, the view's header ([`topics::REMOTE_CAMERA_RECEIPTS`]): the
//!   feedback publisher paces the views by the receipts' round trip, so on a slow WAN
//!   they give way to the feedback (`teleop_remote_site::view_pacer`).
//! * The feedback ([`topics::PR2_JOINT_STATES`], [`topics::SHADOW_JOINT_STATES`],
//!   [`topics::FINGERTIP_PRESSURES`]): counted, with the age of the newest sample (source
//!   stamp to receipt).
//!
//! Its status counters say what the operator has been seeing: views and feedback
//! received, their bytes and ages, refused views. Active while the PR2's state comes in
//! (within `feedback_timeout_s`), Inactive otherwise. It commands nothing.

use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher, Subscriber};
use teleop_interfaces::topics::{self, Topic};
use teleop_msgs::{CompressedImage, FingertipPressures, Header, JointState, Lifecycle};
use teleop_node::{FinalReport, Node, NodeConfig};

/// Configuration of the `operator_display` node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OperatorDisplayConfig {
    pub node_name: String,
    /// How often the feedback is looked at, Hz (views are taken as they arrive).
    pub rate_hz: f64,
    /// Acknowledge each view received (the feedback publisher paces the views by the
    /// receipts; off, they cross at the camera rate whatever the WAN carries).
    pub acknowledge_views: bool,
    /// The display counts as without feedback (Inactive) when the newest PR2 state is
    /// older than this, s.
    pub feedback_timeout_s: f64,
    pub bus: BusConfig,
}

impl Default for OperatorDisplayConfig {
    fn default() -> Self {
        Self {
            node_name: "operator_display".into(),
            rate_hz: 20.0,
            acknowledge_views: true,
            feedback_timeout_s: 1.0,
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for OperatorDisplayConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn validate(&self) -> Result<(), String> {
        teleop_control::check_ranges(
            "operator_display",
            &[
                ("rate_hz", self.rate_hz, 1.0, 1000.0),
                ("feedback_timeout_s", self.feedback_timeout_s, 0.01, 60.0),
            ],
        )
    }
}

/// Why a view was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ViewError {
    #[error("format `{0}` is not JPEG")]
    NotJpeg(String),
    #[error("data ({0} bytes) is not a JPEG stream (no start-of-image marker)")]
    NoJpegMarker(usize),
}

/// Checks that a view is a JPEG (its format names JPEG, its data starts with the
/// start-of-image marker). The pixels are the browser's business: it decodes them.
///
/// # Errors
/// What is wrong with it.
pub fn check_view(view: &CompressedImage) -> Result<(), ViewError> {
    if view.codec() != Some("jpeg") {
        return Err(ViewError::NotJpeg(view.format.clone()));
    }
    if !view.data.starts_with(&[0xFF, 0xD8]) {
        return Err(ViewError::NoJpegMarker(view.data.len()));
    }
    Ok(())
}

/// One camera view as the operator sees it.
#[derive(Debug)]
struct View {
    name: &'static str,
    sub: Subscriber<CompressedImage>,
    received: u64,
    bytes: u64,
    refused: u64,
    /// Source stamp to receipt of the last view, µs.
    last_age_us: u64,
    /// The newest view received (what a display would show).
    newest: Option<CompressedImage>,
}

/// One feedback stream.
#[derive(Debug)]
struct Feed<T> {
    name: &'static str,
    sub: Subscriber<T>,
    received: u64,
    last_age_us: u64,
    last_received_s: Option<f64>,
}

impl<T: teleop_msgs::Message> Feed<T> {
    async fn new(bus: &Bus, name: &'static str, topic: &Topic<T>) -> anyhow::Result<Self> {
        Ok(Self {
            name,
            sub: bus.subscriber(topic).await?,
            received: 0,
            last_age_us: 0,
            last_received_s: None,
        })
    }

    fn take(&mut self, now_s: f64) {
        while let Some(r) = self.sub.try_recv() {
            self.received += 1;
            self.last_age_us = age_us(r.latency_ns());
            self.last_received_s = Some(now_s);
        }
    }
}

fn age_us(latency_ns: i64) -> u64 {
    u64::try_from(latency_ns / 1000).unwrap_or(0)
}

/// The node.
#[derive(Debug)]
pub struct OperatorDisplayNode {
    rate_hz: f64,
    feedback_timeout_s: f64,
    views: Vec<View>,
    receipts: Option<Publisher<Header>>,
    receipts_sent: u64,
    pr2: Feed<JointState>,
    shadow: Feed<JointState>,
    pressures: Feed<FingertipPressures>,
    wake: Arc<tokio::sync::Notify>,
    now_s: f64,
    last_error: String,
}

impl OperatorDisplayNode {
    /// Declares the subscriptions and the receipts' publisher on `bus`.
    ///
    /// # Errors
    /// Bus declarations.
    pub async fn new(cfg: &OperatorDisplayConfig, bus: &Bus) -> anyhow::Result<Self> {
        let wake = Arc::new(tokio::sync::Notify::new());
        let mut views = Vec::new();
        for (name, topic) in [
            ("top", topics::REMOTE_CAMERA_TOP),
            ("side", topics::REMOTE_CAMERA_SIDE),
        ] {
            let sub = bus.subscriber(&topic).await?;
            // A view is acknowledged as it arrives, not at the next period: its
            // receipt's round trip is what the sender paces by.
            sub.wake_on_sample(Some(wake.clone()));
            views.push(View {
                name,
                sub,
                received: 0,
                bytes: 0,
                refused: 0,
                last_age_us: 0,
                newest: None,
            });
        }
        Ok(Self {
            rate_hz: cfg.rate_hz,
            feedback_timeout_s: cfg.feedback_timeout_s,
            views,
            receipts: if cfg.acknowledge_views {
                Some(bus.publisher(&topics::REMOTE_CAMERA_RECEIPTS).await?)
            } else {
                None
            },
            receipts_sent: 0,
            pr2: Feed::new(bus, "pr2_states", &topics::PR2_JOINT_STATES).await?,
            shadow: Feed::new(bus, "shadow_states", &topics::SHADOW_JOINT_STATES).await?,
            pressures: Feed::new(bus, "pressures", &topics::FINGERTIP_PRESSURES).await?,
            wake,
            now_s: 0.0,
            last_error: String::new(),
        })
    }

    /// The newest view of camera `name` (`top`, `side`), if one came.
    pub fn newest_view(&self, name: &str) -> Option<&CompressedImage> {
        self.views
            .iter()
            .find(|v| v.name == name)
            .and_then(|v| v.newest.as_ref())
    }
}

impl Node for OperatorDisplayNode {
    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.rate_hz)
    }

    fn tick(&mut self, now_s: f64) {
        self.now_s = now_s;
        for v in &mut self.views {
            while let Some(r) = v.sub.try_recv() {
                if let Err(e) = check_view(&r.msg) {
                    v.refused += 1;
                    self.last_error = format!("camera view {}: {e}", v.name);
                    continue;
                }
                v.received += 1;
                v.bytes += r.msg.data.len() as u64;
                v.last_age_us = age_us(r.latency_ns());
                if let Some(receipts) = &self.receipts {
                    match receipts.put(&r.msg.header) {
                        Ok(()) => self.receipts_sent += 1,
                        Err(e) => self.last_error = format!("receipt: {e}"),
                    }
                }
                v.newest = Some(r.msg);
            }
        }
        self.pr2.take(now_s);
        self.shadow.take(now_s);
        self.pressures.take(now_s);
    }

    /// Active while the PR2's state comes in; Inactive otherwise (the operator sees no
    /// feedback).
    fn state(&self) -> Lifecycle {
        if self
            .pr2
            .last_received_s
            .is_some_and(|t| self.now_s - t <= self.feedback_timeout_s)
        {
            Lifecycle::Active
        } else {
            Lifecycle::Inactive
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let mut out = Vec::new();
        for v in &self.views {
            let name = |what| format!("display.view_{}.{what}", v.name);
            out.push((name("received"), v.received));
            out.push((name("bytes"), v.bytes));
            out.push((name("refused"), v.refused));
            out.push((name("age_us"), v.last_age_us));
        }
        out.push(("display.receipts_sent".to_owned(), self.receipts_sent));
        let feeds = [
            (self.pr2.name, self.pr2.received, self.pr2.last_age_us),
            (
                self.shadow.name,
                self.shadow.received,
                self.shadow.last_age_us,
            ),
            (
                self.pressures.name,
                self.pressures.received,
                self.pressures.last_age_us,
            ),
        ];
        for (name, received, age) in feeds {
            out.push((format!("display.{name}.received"), received));
            out.push((format!("display.{name}.age_us"), age));
        }
        out
    }

    fn last_error(&self) -> String {
        self.last_error.clone()
    }

    fn wake(&self) -> Option<Arc<tokio::sync::Notify>> {
        Some(self.wake.clone())
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM.
///
/// # Errors
/// Bus errors.
pub async fn run(
    cfg: OperatorDisplayConfig,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let node = OperatorDisplayNode::new(&cfg, &bus).await?;
    teleop_node::run(bus, node, teleop_node::stop_signal(duration)).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_that_are_not_jpeg_are_refused_and_named() {
        let mut v = CompressedImage {
            format: "rgb8; jpeg compressed bgr8".into(),
            data: vec![0xFF, 0xD8, 0xFF, 0xE0],
            ..CompressedImage::default()
        };
        assert_eq!(check_view(&v), Ok(()));
        v.data = vec![1, 2, 3];
        assert_eq!(check_view(&v), Err(ViewError::NoJpegMarker(3)));
        v.format = "png".into();
        let e = check_view(&v).unwrap_err();
        assert!(e.to_string().contains("`png`"), "{e}");
    }
}
