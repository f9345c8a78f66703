//! Operator-site simulator: the simulated operator, motion capture, pedals, the UR5 and its depth camera, offered to the operator-site nodes over the hardware topics.
use clap::Parser;
use teleop_node::NodeArgs;
use teleop_sim_nodes::local_sim;

/// Simulates the operator site's hardware in real time.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(local_sim::run)
}
