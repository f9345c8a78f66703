//! Robot-site simulator: the PR2 arm, the Shadow hand and the task objects, offered to the controllers over the hardware topics.
use clap::Parser;
use teleop_node::NodeArgs;
use teleop_sim_nodes::remote_sim;

/// Simulates the robot site's hardware in real time.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(remote_sim::run)
}
