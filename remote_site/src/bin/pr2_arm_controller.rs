//! Robot-site node: PR2 arm relative control (clutch, IK, velocity law, watchdog).
use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use teleop_bus::NodeArgs;
use teleop_remote_site::arm_node::{self, ArmNodeConfig};

/// Drives the PR2 arm from the operator's relative wrist motion while the clutch is held.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    duration_s: Option<f64>,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    teleop_bus::init_tracing();
    let cli = Cli::parse();
    let Some(cfg) = cli
        .node
        .load::<ArmNodeConfig>()
        .context("loading configuration")?
    else {
        return Ok(());
    };
    let duration = match cli.duration_s {
        Some(s) if s.is_finite() && s > 0.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => anyhow::bail!("--duration-s must be a positive number of seconds, got {s}"),
        None => None,
    };
    arm_node::run(cfg, duration).await
}
