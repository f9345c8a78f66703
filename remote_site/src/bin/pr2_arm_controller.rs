//! Robot-site node: PR2 arm relative control (clutch, IK, velocity law, watchdog).
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
    let duration = cli.node.duration()?;
    arm_node::run(cfg, duration).await
}
