//! Typed publish/subscribe over Zenoh 1.x, wire-compatible with ROS 2's rmw_zenoh.
//!
//! * [`topics`]: the one table naming every topic (key, type, direction, rate, QoS).
//! * [`Bus`]: a node's Zenoh session with its liveliness token; typed
//!   [`Publisher`]/[`Subscriber`] on rmw_zenoh data keys, every sample carrying the
//!   33-byte rmw_zenoh attachment ([`attachment`]).
//! * Receive-side protections ([`guard`]): out-of-order and stale samples are dropped
//!   and counted; undecodable payloads are counted, logged (rate-limited) and never reach
//!   the application.
//! * [`stats`]: per-topic counters and latency percentiles.
//! * [`config`]: typed node configuration and the common command-line overrides.

pub mod attachment;
pub mod config;
pub mod guard;
pub mod keys;
pub mod node;
mod session;
pub mod stats;
pub mod topics;

pub use attachment::Attachment;
pub use config::{BusConfig, ZenohArgs, ZenohSettings};
pub use node::{NodeArgs, NodeConfig, StatusReporter};
pub use session::{Bus, BusError, NodeEvent, NodeWatch, Publisher, Received, Subscriber};
pub use stats::StatsSnapshot;
pub use topics::{Direction, QosClass, Topic, TopicSpec};

/// Sets up `tracing` output on stderr; the level comes from `RUST_LOG` (default `info`).
pub fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}
