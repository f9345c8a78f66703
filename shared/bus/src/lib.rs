//! Typed publish/subscribe over Zenoh 1.x, wire-compatible with ROS 2's rmw_zenoh. The
//! transport only: the topics themselves are named in `teleop-interfaces`, the node
//! runner (command line, config files, status, shutdown) is `teleop-node`.
//!
//! * [`Bus`]: a node's Zenoh session with its liveliness token and its [`Clock`];
//!   typed [`Publisher`]/[`Subscriber`] on rmw_zenoh data keys, every sample carrying
//!   the 33-byte rmw_zenoh attachment ([`attachment`]). QoS classes map to Zenoh
//!   priorities, express delivery and queue depths ([`priority`]).
//! * Receive-side protections ([`guard`]): out-of-order and stale samples are dropped
//!   and counted; undecodable payloads are counted, logged (rate-limited) and never reach
//!   the application. A [`SourcePolicy`] or a source lock
//!   ([`Subscriber::lock_source`]) also drops samples of publishers that may not
//!   deliver ([`directory`]: which node announced which publisher).
//! * [`stats`]: per-topic counters and latency percentiles.
//! * [`config`]: the bus section of every node's configuration.

pub mod attachment;
pub mod clock;
pub mod config;
pub mod directory;
pub mod guard;
pub mod keys;
mod session;
pub mod stats;
pub mod testing;

pub use attachment::Attachment;
pub use clock::{Clock, ManualClock, PacedClock, PacedClockWriter, ScaledClock, SystemClock};
pub use config::{BusConfig, Mode, TimeScale, TlsSettings, ZenohSettings};
pub use directory::{PublisherDirectory, PublisherInfo};
pub use session::{
    Bus, BusError, NodeEvent, NodeWatch, Publisher, RawPublisher, RawSample, Received,
    SeenPublisher, SourcePolicy, Subscriber, Tap, priority,
};
pub use stats::StatsSnapshot;
/// Wakes a node when a sample arrives ([`Subscriber::wake_on_sample`]).
pub use tokio::sync::Notify;
