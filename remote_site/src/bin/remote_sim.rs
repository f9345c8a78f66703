//! Robot-site simulator: the PR2 arm, the Shadow hand and the task objects, offered to the controllers over the hardware topics.
use anyhow::Context;
use clap::Parser;
use teleop_bus::NodeArgs;
use teleop_remote_site::sim_node::{self, SimNodeConfig};

/// Simulates the robot site's hardware in real time.
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
        .load::<SimNodeConfig>()
        .context("loading configuration")?
    else {
        return Ok(());
    };
    let duration = cli.node.duration()?;
    sim_node::run(cfg, duration).await
}
