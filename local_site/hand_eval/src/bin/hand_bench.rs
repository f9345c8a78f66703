//! `hand_bench`: time per frame of hand inference in Rust (preprocessing + ONNX
//! Runtime through `ort`), side by side in the same run with the same model on the same
//! crops in Python onnxruntime (the baseline a user would pick). Medians and 99th
//! percentiles; also checks that both return the same joints.
//!
//! ```text
//! hand_bench [--model local_site/models/hand/model.onnx] [--frames 200] [--repeat 5]
//! ```

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use clap::Parser;
use serde::Deserialize;
use teleop_hand_dataset::{FullFrame, Generator, GeneratorConfig, npy};
use teleop_hand_eval::COMMITTED_MODEL;
use teleop_hand_inference::{HandEstimate, HandEstimator, JointModel, OnnxModel, OnnxOptions};
use teleop_hand_model::preprocess::{PreprocessConfig, Scratch, preprocess};
use teleop_node::stats::quantile;

#[derive(Debug, Parser)]
#[command(
    about = "Hand inference time per frame: Rust (ort) vs Python onnxruntime, same model, same run"
)]
struct Args {
    #[arg(long, default_value = COMMITTED_MODEL)]
    model: PathBuf,
    /// Distinct camera frames (640 x 480, rendered and noised like the dataset).
    #[arg(long, default_value_t = 200)]
    frames: usize,
    /// Passes over the frames.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// ONNX Runtime intra-op threads, both sides.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Python with onnxruntime (default: $TELEOP_PYTHON, the project venv, python3).
    #[arg(long)]
    python: Option<PathBuf>,
    /// Write the results as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
struct PythonResult {
    onnxruntime: String,
    times_ns: Vec<u64>,
    outputs: Vec<Vec<f32>>,
}

fn python(explicit: Option<PathBuf>) -> PathBuf {
    if let Some(p) = explicit {
        return p;
    }
    if let Some(p) = std::env::var_os("TELEOP_PYTHON") {
        return p.into();
    }
    let venv = std::env::var_os("TELEOP_VENV")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/teleop-venv")));
    if let Some(v) = venv {
        let p = v.join("bin/python");
        if p.is_file() {
            return p;
        }
    }
    PathBuf::from("python3")
}

fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .init();
    run(Args::parse())
}

fn run(args: Args) -> anyhow::Result<()> {
    let mut generator = Generator::new(GeneratorConfig::training(99, args.frames.max(1)))?;
    let frames: Vec<FullFrame> = (0..args.frames as u64)
        .map(|i| generator.full_frame(i))
        .collect::<Result<_, _>>()?;
    let model = OnnxModel::load(
        &args.model,
        &OnnxOptions {
            threads: Some(args.threads),
            ..OnnxOptions::default()
        },
    )?;
    let library = model.library().to_path_buf();
    let mut estimator = HandEstimator::new(model)?;
    let size = estimator.model_mut().input_size();
    let cfg = PreprocessConfig {
        size,
        ..PreprocessConfig::default()
    };

    // Preprocessed crops (also the Python side's inputs) and the Rust outputs.
    let mut crops = Vec::with_capacity(frames.len() * size * size);
    let mut rust_out = Vec::new();
    let mut scratch = Scratch::default();
    let mut crop = vec![0.0f32; size * size];
    for f in &frames {
        preprocess(
            &f.depth_mm,
            &f.intrinsics,
            &f.centre_m,
            &cfg,
            &mut scratch,
            &mut crop,
        )?;
        crops.extend_from_slice(&crop);
        let mut out = [0.0f32; 17];
        estimator.model_mut().infer(&crop, &mut out)?;
        rust_out.push(out);
    }
    for f in frames.iter().take(20) {
        estimator.estimate(&f.depth_mm, &f.intrinsics, &f.centre_m)?;
    }
    let (mut e2e, mut pre, mut inf) = (Vec::new(), Vec::new(), Vec::new());
    let mut no_hand = 0;
    // Three tight loops, each like the Python side's: end to end, preprocessing
    // alone, inference alone on the stored crops.
    for _ in 0..args.repeat {
        for f in &frames {
            let t = std::time::Instant::now();
            let r = estimator.estimate(&f.depth_mm, &f.intrinsics, &f.centre_m)?;
            e2e.push(t.elapsed().as_secs_f64() * 1e3);
            if matches!(r, HandEstimate::NoHand { .. }) {
                no_hand += 1;
            }
        }
        for f in &frames {
            let t = std::time::Instant::now();
            preprocess(
                &f.depth_mm,
                &f.intrinsics,
                &f.centre_m,
                &cfg,
                &mut scratch,
                &mut crop,
            )?;
            pre.push(t.elapsed().as_secs_f64() * 1e3);
        }
        for input in crops.chunks_exact(size * size) {
            let mut out = [0.0f32; 17];
            let t = std::time::Instant::now();
            estimator.model_mut().infer(input, &mut out)?;
            inf.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }

    // Python onnxruntime on the same crops.
    let dir = std::env::temp_dir().join(format!("hand-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let inputs = dir.join("crops.npy");
    npy::write(
        &inputs,
        npy::Dtype::F32,
        &[frames.len(), size, size],
        &crops,
    )?;
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("python/bench_onnxruntime.py");
    let py = python(args.python.clone());
    let out = std::process::Command::new(&py)
        .arg(&script)
        .arg(&args.model)
        .arg(&inputs)
        .arg(args.repeat.to_string())
        .arg(args.threads.to_string())
        .output()
        .with_context(|| format!("running {} (Python with onnxruntime)", py.display()))?;
    let _ = std::fs::remove_dir_all(&dir);
    if !out.status.success() {
        bail!(
            "{} {} failed: {}",
            py.display(),
            script.display(),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let py_result: PythonResult =
        serde_json::from_slice(&out.stdout).context("parsing the Python side's JSON")?;
    let mut py_ms: Vec<f64> = py_result.times_ns.iter().map(|t| *t as f64 / 1e6).collect();
    let mut agree = 0.0_f32;
    for (r, p) in rust_out.iter().zip(&py_result.outputs) {
        for (a, b) in r.iter().zip(p) {
            agree = agree.max((a - b).abs());
        }
    }

    let rows = [
        (
            "Rust: preprocessing (640x480 -> 96x96)",
            quantile(&mut pre, 0.5),
            quantile(&mut pre, 0.99),
        ),
        (
            "Rust: inference (ort)",
            quantile(&mut inf, 0.5),
            quantile(&mut inf, 0.99),
        ),
        (
            "Rust: end to end (HandEstimator::estimate)",
            quantile(&mut e2e, 0.5),
            quantile(&mut e2e, 0.99),
        ),
        (
            "Python onnxruntime: inference",
            quantile(&mut py_ms, 0.5),
            quantile(&mut py_ms, 0.99),
        ),
    ];
    println!(
        "model {} ({} frames x {} passes, {} intra-op thread(s)); Rust ONNX Runtime {}; Python onnxruntime {}",
        args.model.display(),
        frames.len(),
        args.repeat,
        args.threads,
        library.display(),
        py_result.onnxruntime
    );
    println!("| path | p50 (ms) | p99 (ms) |\n|---|---|---|");
    for (name, p50, p99) in rows {
        println!("| {name} | {p50:.3} | {p99:.3} |");
    }
    let ratio = rows[3].1 / rows[1].1;
    println!(
        "Python / Rust inference median: {ratio:.2}; largest joint difference Rust vs Python: {agree:.2e} rad; no-hand frames: {no_hand}"
    );
    if let Some(p) = &args.json {
        let v = serde_json::json!({
            "model": args.model.display().to_string(),
            "frames": frames.len(), "repeat": args.repeat, "threads": args.threads,
            "rows": rows.iter().map(|(n, a, b)| serde_json::json!({"path": n, "p50_ms": a, "p99_ms": b})).collect::<Vec<_>>(),
            "python_over_rust_inference": ratio,
            "max_joint_difference_rad": agree,
        });
        std::fs::write(p, serde_json::to_string_pretty(&v)?)?;
    }
    if agree > 1e-4 {
        bail!("Rust and Python disagree by {agree} rad on the same crops");
    }
    Ok(())
}
