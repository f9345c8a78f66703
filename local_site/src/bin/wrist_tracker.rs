//! Operator-site wrist tracker node (simulated operator today).
use clap::Parser;
use teleop_local_site::wrist_tracker;
use teleop_node::NodeArgs;

/// Publishes the operator's wrist pose and pedal state.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(wrist_tracker::run)
}
