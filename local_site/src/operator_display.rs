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
//! * The operator's pedals ([`topics::OPERATOR_INPUT`]) and every node's status
//!   ([`topics::NODE_STATUS`]): clutch and enable, each node's state and last error.
//!
//! It serves all of it as a page in the browser ([`crate::display_web`], `http_listen`,
//! default <http://127.0.0.1:8088/>): the two views, the five fingertip forces as bars
//! with a scale, the hand's and the arm's joints, clutch and enable, each node's health,
//! and the rate and latency of every topic it receives. The page updates at the camera
//! rate; a slow browser gets fewer frames, never the node slower.
//!
//! Its status counters say what the operator has been seeing: views and feedback
//! received, their bytes and ages, refused views, what the page sent. Active while the
//! PR2's state comes in (within `feedback_timeout_s`), Inactive otherwise. It commands
//! nothing.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use teleop_bus::{Bus, BusConfig, Publisher, StatsSnapshot, Subscriber};
use teleop_interfaces::joints::FINGERTIPS;
use teleop_interfaces::topics::{self, Topic, TopicSpec};
use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, JointState, Lifecycle, NodeStatus, OperatorInput,
};
use teleop_node::{FinalReport, Node, NodeConfig, NodeErrors, SchedulingConfig};

use crate::display_web::{self, CAMERAS, ViewFrame, WebHub};

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
    /// Where the browser page is served (host:port); empty: no page. The default
    /// answers this machine only; `0.0.0.0:8088` answers the operator's LAN (the page
    /// commands nothing, but shows everything).
    pub http_listen: String,
    /// How often the page's state (forces, joints, nodes, topics) is sent, Hz; the views
    /// go as they arrive.
    pub state_hz: f64,
    /// Browsers served at once; more are refused (HTTP 503).
    pub web_max_clients: u64,
    /// A browser whose socket takes no message for this long is dropped, s.
    pub web_send_timeout_s: f64,
    /// Full scale of the fingertip force bars, N.
    pub force_scale_n: f64,
    /// A node whose newest status is older than this shows as silent, s.
    pub node_silent_s: f64,
    /// The process's scheduling (normal, or real-time FIFO at a priority).
    pub scheduling: SchedulingConfig,
    pub bus: BusConfig,
}

impl Default for OperatorDisplayConfig {
    fn default() -> Self {
        Self {
            node_name: "operator_display".into(),
            rate_hz: 20.0,
            acknowledge_views: true,
            feedback_timeout_s: 1.0,
            http_listen: "127.0.0.1:8088".into(),
            state_hz: 10.0,
            web_max_clients: 8,
            web_send_timeout_s: 5.0,
            force_scale_n: 50.0,
            node_silent_s: 3.0,
            scheduling: SchedulingConfig::default(),
            bus: BusConfig::default(),
        }
    }
}

impl NodeConfig for OperatorDisplayConfig {
    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }
    fn scheduling(&self) -> SchedulingConfig {
        self.scheduling
    }
    fn validate(&self) -> Result<(), String> {
        teleop_control::check_ranges(
            "operator_display",
            &[
                ("rate_hz", self.rate_hz, 1.0, 1000.0),
                ("feedback_timeout_s", self.feedback_timeout_s, 0.01, 60.0),
                ("state_hz", self.state_hz, 0.5, 100.0),
                ("web_max_clients", self.web_max_clients as f64, 1.0, 1000.0),
                ("web_send_timeout_s", self.web_send_timeout_s, 0.1, 600.0),
                ("force_scale_n", self.force_scale_n, 0.1, 10_000.0),
                ("node_silent_s", self.node_silent_s, 0.1, 600.0),
            ],
        )?;
        if !self.http_listen.is_empty() {
            display_web::parse_listen(&self.http_listen)
                .map_err(|e| format!("operator_display.http_listen: {e}"))?;
        }
        Ok(())
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
    spec: &'static TopicSpec,
    sub: Subscriber<CompressedImage>,
    received: u64,
    bytes: u64,
    refused: u64,
    /// Source stamp to receipt of the last view, µs.
    last_age_us: u64,
    /// The newest view received (what a display would show).
    newest: Option<CompressedImage>,
}

/// One stream the display receives, keeping its newest message.
#[derive(Debug)]
struct Feed<T> {
    name: &'static str,
    spec: &'static TopicSpec,
    sub: Subscriber<T>,
    received: u64,
    last_age_us: u64,
    last_received_s: Option<f64>,
    newest: Option<T>,
}

impl<T: teleop_msgs::Message> Feed<T> {
    async fn new(bus: &Bus, name: &'static str, topic: &'static Topic<T>) -> anyhow::Result<Self> {
        Ok(Self {
            name,
            spec: &topic.spec,
            sub: bus.subscriber(topic).await?,
            received: 0,
            last_age_us: 0,
            last_received_s: None,
            newest: None,
        })
    }

    /// Takes what came; `each` sees every message (in order) before the newest is kept.
    fn take_each(&mut self, now_s: f64, mut each: impl FnMut(&T)) {
        while let Some(r) = self.sub.try_recv() {
            self.received += 1;
            self.last_age_us = age_us(r.latency_ns());
            self.last_received_s = Some(now_s);
            each(&r.msg);
            self.newest = Some(r.msg);
        }
    }

    fn take(&mut self, now_s: f64) {
        self.take_each(now_s, |_| {});
    }

    fn age_ms(&self, now_s: f64) -> Option<f64> {
        self.last_received_s.map(|t| (now_s - t).max(0.0) * 1000.0)
    }
}

fn age_us(latency_ns: i64) -> u64 {
    u64::try_from(latency_ns / 1000).unwrap_or(0)
}

/// A node's newest status as the display heard it.
#[derive(Debug)]
struct Heard {
    status: NodeStatus,
    received_s: f64,
}

/// The rate of a topic over the last window.
#[derive(Debug, Default, Clone, Copy)]
struct RateWindow {
    accepted: u64,
    t_s: f64,
    rate_hz: f64,
}

impl RateWindow {
    /// Moves the window on once a second has passed.
    fn update(&mut self, accepted: u64, now_s: f64) {
        let dt = now_s - self.t_s;
        if self.t_s == 0.0 {
            *self = Self {
                accepted,
                t_s: now_s,
                rate_hz: 0.0,
            };
        } else if dt >= 1.0 {
            self.rate_hz = accepted.saturating_sub(self.accepted) as f64 / dt;
            self.accepted = accepted;
            self.t_s = now_s;
        }
    }
}

/// The page's state: what the browser draws (serialised as JSON at `state_hz`).
#[derive(Debug, Serialize)]
pub struct PageState {
    pub t_s: f64,
    pub node: String,
    pub views: Vec<PageView>,
    pub forces: PageForces,
    pub pr2: Option<PageJoints>,
    pub shadow: Option<PageJoints>,
    pub operator: Option<PageOperator>,
    pub nodes: Vec<PageNode>,
    pub topics: Vec<PageTopic>,
    pub web: PageWeb,
}

#[derive(Debug, Serialize)]
pub struct PageView {
    pub name: &'static str,
    pub topic: String,
    pub received: u64,
    pub refused: u64,
    pub age_ms: f64,
    pub rate_hz: f64,
}

#[derive(Debug, Serialize)]
pub struct PageForces {
    /// Finger names in the message's order ([`FINGERTIPS`]: ff, mf, rf, lf, th).
    pub fingers: [&'static str; 5],
    /// Newest forces, N; empty before the first message.
    pub newton: Vec<f64>,
    /// Highest force of each finger since the start, N.
    pub peak_newton: [f64; 5],
    pub scale_n: f64,
    pub age_ms: Option<f64>,
    pub received: u64,
}

#[derive(Debug, Serialize)]
pub struct PageJoints {
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
    pub age_ms: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct PageOperator {
    pub clutch: bool,
    pub enable: bool,
    pub camera_stop: bool,
    pub motion_scale: f64,
    pub age_ms: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct PageNode {
    pub name: String,
    pub site: &'static str,
    pub machine: &'static str,
    /// Lifecycle state, `silent` when its status is older than `node_silent_s`, `unseen`
    /// before its first status.
    pub state: &'static str,
    pub age_s: Option<f64>,
    pub last_error: String,
    /// Its counters whose name says it stopped, refused or limited something, non-zero.
    pub alerts: Vec<(String, u64)>,
}

#[derive(Debug, Serialize)]
pub struct PageTopic {
    pub name: String,
    pub rate_hz: f64,
    pub nominal_hz: f64,
    pub latency_p50_ms: f64,
    pub latency_p99_ms: f64,
    pub refused: u64,
    pub accepted: u64,
}

#[derive(Debug, Default, Serialize)]
pub struct PageWeb {
    pub clients: u64,
    pub frames_sent: u64,
    pub frames_skipped: u64,
}

/// Whether a counter's name says something was stopped, refused, held or limited.
fn is_alert(counter: &str) -> bool {
    [
        ".stop.", "rejected", "refused", "dropped", "limited", "clamped", "fault", "expired",
    ]
    .iter()
    .any(|w| counter.contains(w))
}

/// The node.
#[derive(Debug)]
pub struct OperatorDisplayNode {
    node_name: String,
    rate_hz: f64,
    feedback_timeout_s: f64,
    state_period_s: f64,
    force_scale_n: f64,
    node_silent_s: f64,
    views: Vec<View>,
    receipts: Option<Publisher<Header>>,
    receipts_sent: u64,
    pr2: Feed<JointState>,
    shadow: Feed<JointState>,
    pressures: Feed<FingertipPressures>,
    peak_newton: [f64; 5],
    operator: Feed<OperatorInput>,
    status: Feed<NodeStatus>,
    heard: BTreeMap<String, Heard>,
    rates: BTreeMap<&'static str, RateWindow>,
    next_rates_s: f64,
    web: Option<Arc<WebHub>>,
    next_state_s: f64,
    wake: Arc<tokio::sync::Notify>,
    now_s: f64,
    errors: NodeErrors,
}

impl OperatorDisplayNode {
    /// Declares the subscriptions and the receipts' publisher on `bus`; the page's state
    /// and views go to `web` when given.
    ///
    /// # Errors
    /// Bus declarations.
    pub async fn new(
        cfg: &OperatorDisplayConfig,
        bus: &Bus,
        web: Option<Arc<WebHub>>,
    ) -> anyhow::Result<Self> {
        let wake = Arc::new(tokio::sync::Notify::new());
        let mut views = Vec::new();
        for (name, topic) in [
            (CAMERAS[0], &topics::REMOTE_CAMERA_TOP),
            (CAMERAS[1], &topics::REMOTE_CAMERA_SIDE),
        ] {
            let sub = bus.subscriber(topic).await?;
            // A view is acknowledged as it arrives, not at the next period: its
            // receipt's round trip is what the sender paces by.
            sub.wake_on_sample(Some(wake.clone()));
            views.push(View {
                name,
                spec: &topic.spec,
                sub,
                received: 0,
                bytes: 0,
                refused: 0,
                last_age_us: 0,
                newest: None,
            });
        }
        Ok(Self {
            node_name: cfg.node_name.clone(),
            rate_hz: cfg.rate_hz,
            feedback_timeout_s: cfg.feedback_timeout_s,
            state_period_s: 1.0 / cfg.state_hz,
            force_scale_n: cfg.force_scale_n,
            node_silent_s: cfg.node_silent_s,
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
            peak_newton: [0.0; 5],
            operator: Feed::new(bus, "operator_input", &topics::OPERATOR_INPUT).await?,
            status: Feed::new(bus, "status", &topics::NODE_STATUS).await?,
            heard: BTreeMap::new(),
            rates: BTreeMap::new(),
            next_rates_s: 0.0,
            web,
            next_state_s: 0.0,
            wake,
            now_s: 0.0,
            errors: NodeErrors::new(),
        })
    }

    /// Every topic the display receives, with its statistics now.
    fn topic_stats(&self) -> Vec<(&'static TopicSpec, StatsSnapshot)> {
        let mut out: Vec<(&'static TopicSpec, StatsSnapshot)> =
            self.views.iter().map(|v| (v.spec, v.sub.stats())).collect();
        out.push((self.pr2.spec, self.pr2.sub.stats()));
        out.push((self.shadow.spec, self.shadow.sub.stats()));
        out.push((self.pressures.spec, self.pressures.sub.stats()));
        out.push((self.operator.spec, self.operator.sub.stats()));
        out.push((self.status.spec, self.status.sub.stats()));
        out
    }

    /// What the page shows now.
    pub fn page_state(&self) -> PageState {
        let now_s = self.now_s;
        let rate = |name: &str| self.rates.get(name).map_or(0.0, |r| r.rate_hz);
        let views = self
            .views
            .iter()
            .map(|v| PageView {
                name: v.name,
                topic: format!("/{}", v.spec.name),
                received: v.received,
                refused: v.refused,
                age_ms: v.last_age_us as f64 / 1000.0,
                rate_hz: rate(v.spec.name),
            })
            .collect();
        let joints = |f: &Feed<JointState>| {
            f.newest.as_ref().map(|m| PageJoints {
                name: m.name.clone(),
                position: m.position.clone(),
                velocity: m.velocity.clone(),
                effort: m.effort.clone(),
                age_ms: f.age_ms(now_s),
            })
        };
        let nodes = self.page_nodes();
        let topics = self
            .topic_stats()
            .into_iter()
            .map(|(spec, s)| PageTopic {
                name: format!("/{}", spec.name),
                rate_hz: rate(spec.name),
                nominal_hz: spec.rate_hz,
                latency_p50_ms: s.latency_p50_us as f64 / 1000.0,
                latency_p99_ms: s.latency_p99_us as f64 / 1000.0,
                refused: s.rejected(),
                accepted: s.accepted,
            })
            .collect();
        let web = self
            .web
            .as_ref()
            .map_or_else(PageWeb::default, |w| PageWeb {
                clients: w.stats.clients.load(Ordering::Relaxed),
                frames_sent: w.stats.frames_sent.load(Ordering::Relaxed),
                frames_skipped: w.stats.frames_skipped.load(Ordering::Relaxed),
            });
        PageState {
            t_s: now_s,
            node: self.node_name.clone(),
            views,
            forces: PageForces {
                fingers: FINGERTIPS,
                newton: self
                    .pressures
                    .newest
                    .as_ref()
                    .map(|p| p.values().to_vec())
                    .unwrap_or_default(),
                peak_newton: self.peak_newton,
                scale_n: self.force_scale_n,
                age_ms: self.pressures.age_ms(now_s),
                received: self.pressures.received,
            },
            pr2: joints(&self.pr2),
            shadow: joints(&self.shadow),
            operator: self.operator.newest.as_ref().map(|o| PageOperator {
                clutch: o.clutch,
                enable: o.enable,
                camera_stop: o.camera_stop,
                motion_scale: o.motion_scale,
                age_ms: self.operator.age_ms(now_s),
            }),
            nodes,
            topics,
            web,
        }
    }

    /// Every node of the node table, then any other node heard.
    fn page_nodes(&self) -> Vec<PageNode> {
        let now_s = self.now_s;
        let entry = |name: &str, site: &'static str, machine: &'static str| {
            let heard = self.heard.get(name);
            let age_s = heard.map(|h| (now_s - h.received_s).max(0.0));
            let state = match (heard, age_s) {
                (None, _) => "unseen",
                (Some(_), Some(a)) if a > self.node_silent_s => "silent",
                (Some(h), _) => h.status.lifecycle().map_or("unknown", Lifecycle::name),
            };
            PageNode {
                name: name.to_owned(),
                site,
                machine,
                state,
                age_s,
                last_error: heard
                    .map(|h| h.status.last_error.clone())
                    .unwrap_or_default(),
                alerts: heard
                    .map(|h| {
                        h.status
                            .counter_names
                            .iter()
                            .zip(&h.status.counter_values)
                            .filter(|(n, v)| **v > 0 && is_alert(n))
                            .map(|(n, v)| (n.clone(), *v))
                            .collect()
                    })
                    .unwrap_or_default(),
            }
        };
        let table = teleop_interfaces::nodes::NODES;
        let mut out: Vec<PageNode> = table
            .iter()
            .map(|n| entry(n.name, n.site.label(), n.machine))
            .collect();
        for name in self.heard.keys() {
            if !table.iter().any(|n| n.name == name.as_str()) {
                out.push(entry(name, "", ""));
            }
        }
        out
    }

    fn publish_page(&mut self, now_s: f64) {
        let Some(web) = &self.web else {
            return;
        };
        if now_s < self.next_state_s {
            return;
        }
        self.next_state_s = now_s + self.state_period_s;
        match serde_json::to_string(&self.page_state()) {
            Ok(json) => web.set_state(json),
            Err(e) => self.errors.event("page", format!("page state: {e}"), now_s),
        }
    }
}

impl Node for OperatorDisplayNode {
    fn period(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.rate_hz)
    }

    fn tick(&mut self, now_s: f64) {
        self.now_s = now_s;
        self.errors.step(now_s);
        for (camera, v) in self.views.iter_mut().enumerate() {
            while let Some(r) = v.sub.try_recv() {
                if let Err(e) = check_view(&r.msg) {
                    v.refused += 1;
                    let text = format!("camera view {}: {e}", v.name);
                    self.errors.event("camera view", text, now_s);
                    continue;
                }
                v.received += 1;
                v.bytes += r.msg.data.len() as u64;
                v.last_age_us = age_us(r.latency_ns());
                if let Some(receipts) = &self.receipts {
                    match receipts.put(&r.msg.header) {
                        Ok(()) => self.receipts_sent += 1,
                        Err(e) => self.errors.event("receipt", format!("receipt: {e}"), now_s),
                    }
                }
                if let (Some(web), Ok(index)) = (&self.web, u8::try_from(camera)) {
                    web.set_view(
                        camera,
                        ViewFrame::new(index, v.received, r.source_timestamp_ns, &r.msg.data),
                    );
                }
                v.newest = Some(r.msg);
            }
        }
        self.pr2.take(now_s);
        self.shadow.take(now_s);
        let peak = &mut self.peak_newton;
        self.pressures.take_each(now_s, |p| {
            for (m, f) in peak.iter_mut().zip(p.values()) {
                if f.is_finite() {
                    *m = m.max(f);
                }
            }
        });
        self.operator.take(now_s);
        let heard = &mut self.heard;
        self.status.take_each(now_s, |s| {
            heard.insert(
                s.node_name.clone(),
                Heard {
                    status: s.clone(),
                    received_s: now_s,
                },
            );
        });
        // The rates move once a second: the statistics' snapshots (two quantiles under
        // each subscription's lock) are not taken on every view's wake-up.
        if now_s >= self.next_rates_s {
            self.next_rates_s = now_s + 1.0;
            for (spec, s) in self.topic_stats() {
                self.rates
                    .entry(spec.name)
                    .or_default()
                    .update(s.accepted, now_s);
            }
        }
        self.publish_page(now_s);
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
        out.push((
            "display.web.serving".to_owned(),
            u64::from(self.web.is_some()),
        ));
        if let Some(web) = &self.web {
            let s = &web.stats;
            for (name, counter) in [
                ("clients", &s.clients),
                ("connections", &s.connections),
                ("refused", &s.refused),
                ("frames_sent", &s.frames_sent),
                ("frames_skipped", &s.frames_skipped),
                ("states_sent", &s.states_sent),
                ("bytes_sent", &s.bytes_sent),
                ("send_timeouts", &s.send_timeouts),
                ("http_requests", &s.http_requests),
            ] {
                out.push((
                    format!("display.web.{name}"),
                    counter.load(Ordering::Relaxed),
                ));
            }
        }
        out
    }

    fn last_error(&self) -> String {
        self.errors.text()
    }

    fn wake(&self) -> Option<Arc<tokio::sync::Notify>> {
        Some(self.wake.clone())
    }
}

/// Runs the node on the system clock until `duration` elapses (forever if `None`) or
/// SIGINT/SIGTERM, serving the page on `http_listen` (if that address cannot be bound,
/// in use or not this machine's, the node runs without its page, the reason in its
/// status's last error and `display.web.serving` 0).
///
/// # Errors
/// Bus errors; `http_listen` is not an address.
pub async fn run(
    cfg: OperatorDisplayConfig,
    duration: Option<Duration>,
) -> anyhow::Result<FinalReport> {
    run_until(cfg, teleop_node::stop_signal(duration)).await
}

/// Runs the display until `stop` completes (what [`run`] does with a timer and the
/// process's signals; a test stops it when the peer it watches has stopped).
pub async fn run_until(
    cfg: OperatorDisplayConfig,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<FinalReport> {
    let bus = Bus::open(&cfg.node_name, &cfg.bus).await?;
    let mut page_error = String::new();
    let (web, server) = if cfg.http_listen.is_empty() {
        (None, None)
    } else {
        let addr = display_web::parse_listen(&cfg.http_listen)?;
        let hub = WebHub::new(
            cfg.web_max_clients,
            Duration::from_secs_f64(cfg.web_send_timeout_s),
        );
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        match display_web::serve(addr, Arc::clone(&hub), async {
            let _ = stop_rx.await;
        })
        .await
        {
            Ok((bound, task)) => {
                tracing::info!("operator display: http://{bound}/");
                (Some(hub), Some((stop_tx, task)))
            }
            // The views are still received and acknowledged (their pacing across the
            // WAN depends on it): the node runs on without its page, and says why.
            Err(e) => {
                page_error = format!(
                    "no browser page: {e} (set http_listen to a free address, or \"\" for none)"
                );
                tracing::error!("operator display: {page_error}");
                (None, None)
            }
        }
    };
    let now_s = bus.now_s();
    let mut node = OperatorDisplayNode::new(&cfg, &bus, web).await?;
    if !page_error.is_empty() {
        // For the whole run: the page is not served again.
        node.errors.condition("page", page_error, now_s);
    }
    let report = teleop_node::run(bus, node, stop).await;
    if let Some((stop_tx, task)) = server {
        let _ = stop_tx.send(());
        // Open sockets do not hold the stop up.
        let _ = tokio::time::timeout(Duration::from_secs(1), task).await;
    }
    report
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
