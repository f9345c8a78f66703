//! Robot-site node: PR2 arm relative control (clutch, IK, velocity law, watchdog).
use clap::Parser;
use teleop_node::NodeArgs;
use teleop_remote_site::arm_node;

/// Drives the PR2 arm from the operator's relative wrist motion while the clutch is held.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(arm_node::run)
}
