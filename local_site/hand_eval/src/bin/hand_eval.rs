//! `hand_eval`: the thesis's metrics for hand networks on generated test sets.
//!
//! ```text
//! hand_eval --model transteleop=runs/transteleop/model.onnx --model baseline=... \
//!     --data test=DATA/test --data ood-views=DATA/ood-views \
//!     --report local_site/models/hand/report.json --markdown report.md --plot curve.png
//! ```
//! The first model is the one the CI thresholds are measured for (on a freshly
//! generated seeded set of `--ci-frames` pairs, like the CI test).

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use clap::Parser;
use teleop_hand_dataset::{GeneratorConfig, load};
use teleop_hand_eval::{
    CiThresholds, Report, Row, evaluate_generated, evaluate_loaded, markdown_table,
    per_joint_table, plot_curves,
};
use teleop_hand_inference::{HandEstimator, OnnxModel, OnnxOptions};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;

#[derive(Debug, Parser)]
#[command(about = "Evaluate hand networks (ONNX) on hand_dataset test sets")]
struct Args {
    /// NAME=PATH of an ONNX model; repeat. The first is the shipped one.
    #[arg(long = "model", required = true)]
    models: Vec<String>,
    /// NAME=DIR of a dataset; repeat. The first is the in-distribution test set.
    #[arg(long = "data", required = true)]
    datasets: Vec<String>,
    /// Write the JSON report here.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Write the markdown tables here.
    #[arg(long)]
    markdown: Option<PathBuf>,
    /// Draw the fraction-of-frames curves (first dataset, every model) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Draw a few pairs of the first dataset here.
    #[arg(long)]
    pairs: Option<PathBuf>,
    /// Pairs and seed of the CI check; its thresholds are the first model's measured
    /// values on that set, less `--ci-margin` (fractions) and plus a tenth of it (mean).
    #[arg(long, default_value_t = 300)]
    ci_frames: usize,
    #[arg(long, default_value_t = 11)]
    ci_seed: u64,
    #[arg(long, default_value_t = 0.05)]
    ci_margin: f64,
}

fn split(s: &str) -> anyhow::Result<(String, PathBuf)> {
    let Some((name, path)) = s.split_once('=') else {
        bail!("{s:?} is not NAME=PATH");
    };
    Ok((name.to_owned(), PathBuf::from(path)))
}

fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    run(Args::parse())
}

fn run(args: Args) -> anyhow::Result<()> {
    let models = args
        .models
        .iter()
        .map(|s| split(s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let datasets = args
        .datasets
        .iter()
        .map(|s| split(s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut loaded = Vec::new();
    for (name, dir) in &datasets {
        loaded.push((
            name.clone(),
            load(dir).with_context(|| format!("dataset {}", dir.display()))?,
        ));
    }
    let mut rows = Vec::new();
    let mut curves = Vec::new();
    let mut ci = None;
    for (mi, (name, path)) in models.iter().enumerate() {
        let model = OnnxModel::load(
            path,
            &OnnxOptions {
                threads: Some(2),
                ..OnnxOptions::default()
            },
        )?;
        let mut estimator = HandEstimator::new(model)?;
        for (di, (dname, data)) in loaded.iter().enumerate() {
            let acc = evaluate_loaded(&mut estimator, data)?;
            let s = acc.summary();
            tracing::info!(model = %name, dataset = %dname, within_0_1 = s.fraction_within[0], mean = s.mean_error_rad, "evaluated");
            if di == 0 {
                curves.push((name.clone(), acc.curve(0.4, 80)));
            }
            rows.push(Row::new(name, dname, &s));
        }
        if mi == 0 {
            let config = GeneratorConfig::training(args.ci_seed, args.ci_frames);
            let s = evaluate_generated(&mut estimator, config, args.ci_frames)?.summary();
            tracing::info!(
                within_0_1 = s.fraction_within[0],
                mean = s.mean_error_rad,
                "CI set measured"
            );
            ci = Some(CiThresholds {
                frames: args.ci_frames,
                seed: args.ci_seed,
                min_fraction_within_0_1: (s.fraction_within[0] - args.ci_margin).max(0.0),
                min_fraction_within_0_2: (s.fraction_within[2] - args.ci_margin).max(0.0),
                max_mean_error_rad: s.mean_error_rad + args.ci_margin / 10.0,
            });
        }
    }
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let report = Report {
        command,
        thresholds_rad: teleop_hand_eval::thresholds(),
        joint_names: SHADOW_FINGER_JOINTS
            .iter()
            .map(|s| (*s).to_owned())
            .collect(),
        rows: rows.clone(),
        ci: ci.context("no model evaluated")?,
    };
    let table = markdown_table(&rows);
    let first: Vec<Row> = rows
        .iter()
        .filter(|r| r.dataset == datasets[0].0)
        .cloned()
        .collect();
    let md = format!(
        "{table}\nMean error per joint (rad), {}:\n\n{}",
        datasets[0].0,
        per_joint_table(&first)
    );
    println!("{md}");
    if let Some(p) = &args.report {
        std::fs::write(p, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &args.markdown {
        std::fs::write(p, &md).with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &args.pairs {
        let (_, data) = &loaded[0];
        let picks: Vec<usize> = (0..data.count)
            .step_by((data.count / 5).max(1))
            .take(5)
            .collect();
        teleop_hand_eval::plot_pairs(p, data, &picks)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("drawing {}", p.display()))?;
    }
    if let Some(p) = &args.plot {
        plot_curves(
            p,
            &format!(
                "Hand networks on the {} set: frames within a max joint error",
                datasets[0].0
            ),
            &curves,
        )
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("drawing {}", p.display()))?;
    }
    Ok(())
}
