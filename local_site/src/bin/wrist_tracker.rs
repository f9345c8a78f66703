//! Operator-site wrist tracker node (simulated operator today).
use clap::Parser;
use teleop_bus::NodeArgs;
use teleop_local_site::wrist_tracker::{self, WristTrackerConfig};

/// Publishes the operator's wrist pose and pedal state.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    teleop_bus::init_tracing();
    Cli::parse()
        .node
        .run(|cfg: WristTrackerConfig, duration| async move {
            let counters = wrist_tracker::run(cfg, duration).await?;
            tracing::info!(?counters, "wrist tracker stopped");
            anyhow::Ok(())
        })
        .await
}
