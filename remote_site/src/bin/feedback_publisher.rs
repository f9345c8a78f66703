//! Robot-site node: publishes joint states of both robots, the fingertip pressures and the
//! remote camera views to the operator site.
use clap::Parser;
use teleop_node::NodeArgs;
use teleop_remote_site::feedback_node;

/// Forwards the robot site's state to the operator site.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(feedback_node::run)
}
