//! `hand_dataset`: generates the paired human/Shadow depth dataset of the hand network.
//!
//! ```text
//! hand_dataset --out data/hand/train --preset train --count 60000 --seed 1
//! ```

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Parser;
use teleop_hand_dataset::{GeneratorConfig, generate};

#[derive(Debug, Parser)]
#[command(
    about = "Generate the paired human/Shadow hand depth dataset (NumPy shards + manifest.json)"
)]
struct Args {
    /// Output directory (created; must not hold a dataset already).
    #[arg(long)]
    out: PathBuf,
    /// Distribution: train, test, ood-views, ood-far, ood-shapes, ood-roll.
    #[arg(long, default_value = "train")]
    preset: String,
    /// Number of pairs.
    #[arg(long, default_value_t = 10_000)]
    count: usize,
    /// Seed of the set (sample i depends on the seed and i only).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Pairs per shard directory.
    #[arg(long, default_value_t = 2048)]
    shard_size: usize,
    /// Worker threads (default: every core).
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .init();
    run(Args::parse())
}

fn run(args: Args) -> anyhow::Result<()> {
    let mut config = GeneratorConfig::preset(&args.preset, args.seed, args.count)?;
    config.shard_size = args.shard_size;
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        let bar = indicatif::ProgressBar::new(config.count as u64);
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} pairs, {per_sec}, eta {eta}",
        ) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar
    };
    let start = std::time::Instant::now();
    let manifest = generate(&config, &args.out, threads, &|n| bar.set_position(n as u64))
        .with_context(|| format!("generating {}", args.out.display()))?;
    bar.finish();
    let secs = start.elapsed().as_secs_f64();
    tracing::info!(
        pairs = config.count,
        shards = manifest.shards.len(),
        seconds = format!("{secs:.1}"),
        pairs_per_second = format!("{:.0}", config.count as f64 / secs),
        out = %args.out.display(),
        "dataset written"
    );
    Ok(())
}
