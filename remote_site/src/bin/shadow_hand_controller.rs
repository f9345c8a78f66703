//! Robot-site node: Shadow hand control (position, fixed-gain or adaptive impedance),
//! with the hold watchdog.
use clap::Parser;
use teleop_node::NodeArgs;
use teleop_remote_site::hand_node;

/// Drives the Shadow hand's 17 finger joints toward the operator's inferred hand posture.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    Cli::parse().node.main(hand_node::run)
}
