//! Operator-site node: the UR5 keeps the depth camera on the operator's hand (ch. 7.4).
use clap::Parser;
use teleop_local_site::camera_arm_node;
use teleop_node::NodeArgs;

/// Drives the UR5 camera arm so that the depth camera looks at the operator's palm.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(camera_arm_node::run)
}
