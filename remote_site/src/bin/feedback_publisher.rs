//! Robot-site node: publishes joint states of both robots and the fingertip pressures to the operator site.
use anyhow::Context;
use clap::Parser;
use teleop_bus::NodeArgs;
use teleop_remote_site::feedback_node::{self, FeedbackConfig};

/// Forwards the robot site's state to the operator site.
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
        .load::<FeedbackConfig>()
        .context("loading configuration")?
    else {
        return Ok(());
    };
    let duration = cli.node.duration()?;
    feedback_node::run(cfg, duration).await
}
