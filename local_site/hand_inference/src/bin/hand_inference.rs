//! Hand inference (operator site): the operator's hand depth frames in, the Shadow hand's 17 finger joint targets out, through the ONNX model.
use clap::Parser;
use teleop_hand_inference::{node, runtime};
use teleop_node::NodeArgs;

/// Estimates the Shadow hand's finger joint targets from the operator's hand depth frames.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    /// Find ONNX Runtime (installing the pinned PyPI wheel into the project's Python
    /// environment if it is nowhere), print where it is, and exit.
    #[arg(long)]
    ensure_runtime: bool,
    #[command(flatten)]
    node: NodeArgs,
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    let cli = Cli::parse();
    if cli.ensure_runtime {
        let cfg: node::HandInferenceConfig = cli.node.load()?.unwrap_or_default();
        let found = runtime::find_or_install(cfg.onnxruntime_library.as_deref())?;
        println!("{} (via {})", found.path.display(), found.source);
        return Ok(());
    }
    cli.node.main(node::run)
}
