//! What every node binary shares, so each binary is a few lines: `main` parses
//! ([`NodeArgs`]), loads its typed configuration ([`config`]), and hands a node to the
//! one run loop ([`runner::run`]): tick at the node's period on the node's clock,
//! status every second and on every lifecycle change, stop on a duration or
//! SIGINT/SIGTERM, graceful shutdown that commands the hardware to stop, a final
//! status, session closed.

pub mod access;
pub mod args;
#[cfg(feature = "certs")]
pub mod certs;
pub mod config;
pub mod errors;
pub mod latency;
#[cfg(feature = "plot")]
pub mod plot;
pub mod router;
pub mod runner;
pub mod sched;
pub mod source;
pub mod stats;
pub mod status;
pub mod stop;
pub mod tls_runtime;

pub use args::{NodeArgs, ZenohArgs};
pub use config::{ConfigError, NodeConfig};
pub use errors::NodeErrors;
pub use latency::LatencyHistogram;
pub use runner::{FinalReport, Node, Periodic, run};
pub use sched::SchedulingConfig;
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

#[cfg(test)]
mod tests {
    use super::check_controller_links;

    #[test]
    fn controller_links_name_the_bad_field() {
        assert!(check_controller_links(&["wrist_tracker".into()], 0.1).is_ok());
        let none = check_controller_links(&[], 0.1).unwrap_err();
        assert!(none.contains("operator_site_nodes"), "{none}");
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = check_controller_links(&["n".into()], bad).unwrap_err();
            assert!(e.contains("hardware_timeout_s"), "{e}");
        }
    }
}
