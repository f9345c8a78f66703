//! Operator display: the remote camera views (acknowledged, so the robot site paces them to the WAN) and the feedback, received and accounted for.
use clap::Parser;
use teleop_local_site::operator_display;
use teleop_node::NodeArgs;

/// Receives what the robot site sends the operator.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(operator_display::run)
}
