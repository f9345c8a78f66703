//! What every node binary shares, so each binary is a few lines: `main` parses
//! ([`NodeArgs`]), loads its typed configuration ([`config`]), and hands a node to the
//! one run loop ([`runner::run`]): tick at the node's period on the node's clock,
//! status every second and on every lifecycle change, stop on a duration or
//! SIGINT/SIGTERM, graceful shutdown that commands the hardware to stop, a final
//! status, session closed.

pub mod args;
pub mod config;
#[cfg(feature = "plot")]
pub mod plot;
pub mod runner;
pub mod source;
pub mod status;
pub mod stop;

pub use args::{NodeArgs, ZenohArgs};
pub use config::{ConfigError, NodeConfig};
pub use runner::{FinalReport, Node, Periodic, run};
pub use source::SourceLock;
pub use status::StatusReporter;
pub use stop::stop_signal;
pub use teleop_bus::clock::{self, Clock, ManualClock, SystemClock};

/// Sets up `tracing` output on stderr; the level comes from `RUST_LOG` (default `info`).
pub fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}
