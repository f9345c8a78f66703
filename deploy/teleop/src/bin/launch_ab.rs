//! `launch_ab`: the whole system, two ways, in alternating pairs: the end-of-run
//! reports' figures side by side (medians, each run's value, the ratio of the medians).
//!
//! Each run is `teleop --domain-id N <A or B> --quiet --display off --task T
//! --report-dir DIR/<name>-<i>` (the `teleop` next to this binary), where A and B are
//! argument lists that contain `launch` and whatever the two cases differ by, before
//! it (options of every binary, `--no-shared-memory`) or after it (`--no-realtime`).
//! The runs alternate A, B, A, B, ... so that a machine that slows down during the
//! benchmark slows both alike. Figures: the latency stages of the report (p50 / p99),
//! hand inference's own processing time, the camera, PR2 and hand errors, the goals met.
//!
//! With `--background-load N`, N threads of this process spin at normal priority
//! during every run (a machine doing something else besides).
//!
//! `launch_ab --pairs 3 --a launch --b "launch --no-realtime" --out /tmp/ab`

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, bail};
use clap::Parser;
use serde_json::Value;

/// The whole system two ways, alternating; the reports' figures side by side.
#[derive(Debug, Parser)]
#[command(name = "launch_ab", version)]
struct Cli {
    /// Pairs of runs.
    #[arg(long, default_value_t = 3)]
    pairs: usize,
    /// The operator task each run does once.
    #[arg(long, default_value = "fader")]
    task: String,
    /// Case A's arguments to `teleop` (whitespace-separated, containing `launch`).
    #[arg(long)]
    a: String,
    /// Case B's arguments.
    #[arg(long)]
    b: String,
    /// Case A's name in the table (default: its arguments).
    #[arg(long)]
    a_name: Option<String>,
    /// Case B's name in the table.
    #[arg(long)]
    b_name: Option<String>,
    /// ROS 2 domain of the runs (one system at a time).
    #[arg(long, default_value_t = 84)]
    domain_id: u32,
    /// Busy threads at normal priority beside each run, from this process: the same
    /// system on a machine that is doing something else too.
    #[arg(long, default_value_t = 0)]
    background_load: usize,
    /// Where the runs' reports go (`<name>-<i>/report.json`); the table is also written
    /// there as `ab.md`, every run's figures as `ab.json`.
    #[arg(long)]
    out: PathBuf,
}

/// One figure of a report: its name in the table and where it is in `report.json`.
struct Figure {
    name: &'static str,
    get: fn(&Value) -> Option<f64>,
}

fn stage(r: &Value, name: &str, field: &str) -> Option<f64> {
    r["latency"]
        .as_array()?
        .iter()
        .find(|s| s["stage"] == name)?[field]
        .as_f64()
}

fn micros_as_ms(r: &Value, group: &str, key: &str) -> Option<f64> {
    r[group][key].as_f64().map(|us| us / 1000.0)
}

fn resources_sum(r: &Value, field: &str) -> Option<f64> {
    let nodes = r["resources"].as_object()?;
    if nodes.is_empty() {
        return None;
    }
    nodes.values().map(|u| u[field].as_f64()).sum()
}

fn node_resource(r: &Value, node: &str, field: &str) -> Option<f64> {
    r["resources"][node][field].as_f64()
}

const FIGURES: &[Figure] = &[
    Figure {
        name: "CPU of all nodes, cores",
        get: |r| resources_sum(r, "cpu_cores"),
    },
    Figure {
        name: "peak memory of all nodes (sum), MB",
        get: |r| resources_sum(r, "peak_rss_mb"),
    },
    Figure {
        name: "CPU of remote_sim, cores",
        get: |r| node_resource(r, "remote_sim", "cpu_cores"),
    },
    Figure {
        name: "peak memory of remote_sim, MB",
        get: |r| node_resource(r, "remote_sim", "peak_rss_mb"),
    },
    Figure {
        name: "depth frame on the bus -> finger targets p50, ms",
        get: |r| stage(r, "depth frame on the bus -> finger targets", "p50_ms"),
    },
    Figure {
        name: "depth frame on the bus -> finger targets p99, ms",
        get: |r| stage(r, "depth frame on the bus -> finger targets", "p99_ms"),
    },
    Figure {
        name: "depth frame (capture) -> finger targets p99, ms",
        get: |r| stage(r, "depth frame -> finger targets", "p99_ms"),
    },
    Figure {
        name: "capture -> targets received by the hand controller p99, ms",
        get: |r| {
            micros_as_ms(
                r,
                "hand_controller_stages_us",
                "latency.targets.capture_to_received_us.p99",
            )
        },
    },
    Figure {
        name: "hand inference processing p50, ms",
        get: |r| micros_as_ms(r, "hand_inference_stages_us", "latency.processing_us.p50"),
    },
    Figure {
        name: "hand inference processing p99, ms",
        get: |r| micros_as_ms(r, "hand_inference_stages_us", "latency.processing_us.p99"),
    },
    Figure {
        name: "motion capture -> wrist pose p99, ms",
        get: |r| stage(r, "motion capture -> wrist pose", "p99_ms"),
    },
    Figure {
        name: "UR5 joints -> camera pose p99, ms",
        get: |r| stage(r, "UR5 joints -> camera pose", "p99_ms"),
    },
    Figure {
        name: "PR2 joints -> feedback p99, ms",
        get: |r| stage(r, "PR2 joints -> feedback", "p99_ms"),
    },
    Figure {
        name: "UR5 camera position error mean, cm",
        get: |r| {
            r["camera_position_error_m"]["mean"]
                .as_f64()
                .map(|m| m * 100.0)
        },
    },
    Figure {
        name: "PR2 end-effector error mean, mm",
        get: |r| {
            r["pr2_position_error_m"]["mean"]
                .as_f64()
                .map(|m| m * 1000.0)
        },
    },
    Figure {
        name: "hand joint error mean, rad",
        get: |r| r["hand_joint_mean_error_rad"]["mean"].as_f64(),
    },
    Figure {
        name: "goals met (of 5)",
        get: |r| {
            r["goals"]
                .as_array()
                .map(|g| g.iter().filter(|g| g["met"] == true).count() as f64)
        },
    },
];

fn main() -> Result<()> {
    let cli = Cli::parse();
    if cli.pairs == 0 {
        bail!("--pairs must be at least 1");
    }
    let teleop = std::env::current_exe()
        .context("locating this binary")?
        .with_file_name("teleop");
    if !teleop.is_file() {
        bail!(
            "{} not found: build the workspace first (cargo build --release --workspace --bins)",
            teleop.display()
        );
    }
    let cases = [
        (cli.a_name.clone().unwrap_or_else(|| cli.a.clone()), &cli.a),
        (cli.b_name.clone().unwrap_or_else(|| cli.b.clone()), &cli.b),
    ];
    for (_, args) in &cases {
        if !args.split_whitespace().any(|a| a == "launch") {
            bail!("each case's arguments must contain `launch`, got {args:?}");
        }
    }
    std::fs::create_dir_all(&cli.out).with_context(|| format!("creating {}", cli.out.display()))?;
    let mut reports: [Vec<Value>; 2] = [Vec::new(), Vec::new()];
    for i in 1..=cli.pairs {
        for (k, (name, args)) in cases.iter().enumerate() {
            let dir = cli
                .out
                .join(format!("{}-{i}", if k == 0 { "a" } else { "b" }));
            let report =
                run(&teleop, &cli, args, &dir).with_context(|| format!("run {i} of {name}"))?;
            eprintln!("{name} run {i}: {}", one_line(&report));
            reports[k].push(report);
        }
    }
    let table = table(&cases[0].0, &cases[1].0, &reports);
    println!("{table}");
    std::fs::write(cli.out.join("ab.md"), &table)?;
    let json = serde_json::json!({
        "task": cli.task,
        "a": {"name": cases[0].0, "args": cli.a, "runs": figures_of(&reports[0])},
        "b": {"name": cases[1].0, "args": cli.b, "runs": figures_of(&reports[1])},
    });
    std::fs::write(
        cli.out.join("ab.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    Ok(())
}

/// `n` threads spinning until the returned guard is dropped.
struct BackgroundLoad {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl BackgroundLoad {
    fn start(n: usize) -> Self {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let threads = (0..n)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        for _ in 0..10_000 {
                            x = std::hint::black_box(
                                x.wrapping_mul(6364136223846793005).wrapping_add(1),
                            );
                        }
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for BackgroundLoad {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// One run to its end; its report.
fn run(teleop: &Path, cli: &Cli, args: &str, dir: &Path) -> Result<Value> {
    let _load = BackgroundLoad::start(cli.background_load);
    let out = Command::new(teleop)
        .args(["--domain-id", &cli.domain_id.to_string()])
        .args(args.split_whitespace())
        .args([
            "--quiet",
            "--display",
            "off",
            "--task",
            &cli.task,
            "--report-dir",
        ])
        .arg(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .context("running teleop")?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(20).collect();
        bail!(
            "teleop exited with {}: {}",
            out.status,
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        );
    }
    let path = dir.join("report.json");
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
}

fn one_line(report: &Value) -> String {
    FIGURES[..3]
        .iter()
        .map(|f| format!("{} {}", f.name, fmt((f.get)(report))))
        .collect::<Vec<_>>()
        .join(", ")
}

fn figures_of(reports: &[Value]) -> Vec<serde_json::Map<String, Value>> {
    reports
        .iter()
        .map(|r| {
            FIGURES
                .iter()
                .map(|f| {
                    (
                        f.name.to_owned(),
                        (f.get)(r).map_or(Value::Null, Value::from),
                    )
                })
                .collect()
        })
        .collect()
}

fn fmt(v: Option<f64>) -> String {
    match v {
        None => "-".into(),
        Some(v) if v.abs() >= 10.0 => format!("{v:.1}"),
        Some(v) if v.abs() >= 0.1 => format!("{v:.2}"),
        Some(v) => format!("{v:.3}"),
    }
}

/// The median of the finite values, None without any.
fn median(values: &[f64]) -> Option<f64> {
    let finite: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    (!finite.is_empty()).then(|| teleop_node::stats::median(&finite))
}

/// The markdown table: per figure, each case's median with its runs in brackets, and
/// the ratio of the medians (B / A).
fn table(a: &str, b: &str, reports: &[Vec<Value>; 2]) -> String {
    let mut s = format!("| figure | {a} | {b} | {b} / {a} |\n|---|---:|---:|---:|\n");
    for f in FIGURES {
        let cells: Vec<(Option<f64>, String)> = reports
            .iter()
            .map(|runs| {
                let values: Vec<f64> = runs.iter().filter_map(|r| (f.get)(r)).collect();
                let runs = values.iter().map(|v| fmt(Some(*v))).collect::<Vec<_>>();
                let m = median(&values);
                (m, format!("{} ({})", fmt(m), runs.join(", ")))
            })
            .collect();
        let ratio = match (cells[0].0, cells[1].0) {
            (Some(x), Some(y)) if x != 0.0 => format!("{:.2}x", y / x),
            _ => "-".into(),
        };
        s.push_str(&format!(
            "| {} | {} | {} | {} |\n",
            f.name, cells[0].1, cells[1].1, ratio
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(frame_p99: f64, processing_p99_us: u64, met: usize) -> Value {
        let goals: Vec<Value> = (0..5)
            .map(|i| serde_json::json!({"met": i < met}))
            .collect();
        serde_json::json!({
            "latency": [
                {"stage": "depth frame on the bus -> finger targets", "p50_ms": 3.0, "p99_ms": frame_p99},
            ],
            "hand_inference_stages_us": {"latency.processing_us.p99": processing_p99_us},
            "pr2_position_error_m": {"mean": 0.0031},
            "goals": goals,
        })
    }

    #[test]
    fn the_table_gives_medians_runs_and_ratios_and_dashes_for_what_is_missing() {
        let reports = [
            vec![
                report(4.0, 2000, 5),
                report(5.0, 3000, 5),
                report(4.5, 2500, 5),
            ],
            vec![
                report(8.0, 4000, 4),
                report(6.0, 5000, 5),
                report(7.0, 6000, 5),
            ],
        ];
        let t = table("rt", "normal", &reports);
        assert!(
            t.contains(
                "| depth frame on the bus -> finger targets p99, ms | 4.50 (4.00, 5.00, 4.50) | 7.00 (8.00, 6.00, 7.00) | 1.56x |"
            ),
            "{t}"
        );
        assert!(
            t.contains("| hand inference processing p99, ms | 2.50 (2.00, 3.00, 2.50) | 5.00 (4.00, 5.00, 6.00) | 2.00x |"),
            "{t}"
        );
        assert!(
            t.contains("| PR2 end-effector error mean, mm | 3.10 (3.10, 3.10, 3.10) |"),
            "{t}"
        );
        assert!(
            t.contains(
                "| goals met (of 5) | 5.00 (5.00, 5.00, 5.00) | 5.00 (4.00, 5.00, 5.00) | 1.00x |"
            ),
            "{t}"
        );
        // Not in these reports: a dash, no ratio.
        assert!(
            t.contains("| UR5 camera position error mean, cm | - () | - () | - |"),
            "{t}"
        );
        assert_eq!(median(&[]), None);
        assert_eq!(median(&[1.0, 3.0]), Some(2.0));
    }
}
