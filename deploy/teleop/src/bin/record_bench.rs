//! `record_bench`: the recorder's overhead at the full system rate, camera images
//! included, against a baseline measured in the same run.
//!
//! It starts the whole system once (`teleop --domain-id N launch --quiet
//! --no-report-files --display off`, the `teleop` next to this binary), lets it settle,
//! then runs `teleop record` beside it, one mode after the other, for `--rounds` rounds:
//!
//! * `discard`: `teleop record --discard`, the baseline: the same taps, queue and writer
//!   thread, every message received and counted, nothing written;
//! * `zstd`, `lz4`, `none`: `teleop record -o DIR --compression C`, a bag written;
//!
//! each once with the default topics (those crossing between the sites, the two JPEG
//! camera views among them) and once with `--all` (every topic of the table: the raw
//! depth frames and the raw camera images too, the heavy case).
//!
//! Each run is measured over a window of `--seconds` that starts `--warmup-s` after the
//! recorder said it had opened its taps and ends just before its SIGINT: its CPU time
//! (utime + stime of /proc/PID/stat) over the window's wall time, in % of one core; its
//! peak resident memory (VmHWM of /proc/PID/status, at the window's end); the bag
//! directory's growth over the window (bytes written per second); and, from the line
//! the recorder prints when it stops, the messages and CDR bytes it received (per
//! second, from the taps' opening to the SIGINT) and how many it dropped. The whole
//! machine's busy share over each window is recorded beside it (the system runs on the
//! same cores). The table gives the medians over the rounds per mode, and the median of
//! the per-round ratios of each mode's CPU to the baseline's.
//!
//! `cargo build --release --workspace --bins && $CARGO_TARGET_DIR/release/record_bench --out record_bench.json`

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};
use clap::Parser;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use serde::Serialize;
use teleop_interfaces::nodes::NODES;
use teleop_node::stats::{loadavg, median};

// /proc CPU times, shared with the `teleop` binary (the crate has no library); the
// launcher's resource sampler is not used here.
#[path = "../proc_stat.rs"]
#[allow(dead_code)]
mod proc_stat;

/// The recorder's overhead at the full system rate (CPU, memory, MB/s written, drops),
/// against `teleop record --discard` in the same run.
#[derive(Debug, Parser)]
#[command(name = "record_bench", version)]
struct Cli {
    /// Rounds; each runs every mode once with the default topics and once with `--all`.
    #[arg(long, default_value_t = 3)]
    rounds: usize,
    /// Length of each run's measured window, s.
    #[arg(long, default_value_t = 15.0)]
    seconds: f64,
    /// Time between the recorder's taps opening and the window's start, s.
    #[arg(long, default_value_t = 2.0)]
    warmup_s: f64,
    /// Time the system runs before the first recording, s.
    #[arg(long, default_value_t = 8.0)]
    settle_s: f64,
    /// ROS 2 domain id of the system and the recorders.
    #[arg(long, default_value_t = 97)]
    domain_id: u32,
    /// Directory for the bags (each removed once measured) and the system's log;
    /// default: a new directory in the system's temporary directory.
    #[arg(long)]
    work_dir: Option<PathBuf>,
    /// Also write the settings, the machine, every run and the medians as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
enum Mode {
    Discard,
    Zstd,
    Lz4,
    None,
}

impl Mode {
    const ALL: [Mode; 4] = [Mode::Discard, Mode::Zstd, Mode::Lz4, Mode::None];

    fn name(self) -> &'static str {
        match self {
            Mode::Discard => "discard",
            Mode::Zstd => "zstd",
            Mode::Lz4 => "lz4",
            Mode::None => "none",
        }
    }

    fn label(self) -> &'static str {
        match self {
            Mode::Discard => "baseline: --discard",
            Mode::Zstd => "bag, zstd",
            Mode::Lz4 => "bag, lz4",
            Mode::None => "bag, uncompressed",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
enum Topics {
    /// The topics crossing between the sites (`teleop record`'s default).
    Default,
    /// Every topic of the table (`--all`).
    All,
}

impl Topics {
    fn name(self) -> &'static str {
        match self {
            Topics::Default => "default",
            Topics::All => "all",
        }
    }
}

/// One recorder run.
#[derive(Debug, Clone, Serialize)]
struct Run {
    round: usize,
    topics: Topics,
    mode: Mode,
    command: String,
    window_s: f64,
    /// CPU time of the recorder over the window, % of one core.
    cpu_pct: f64,
    /// Peak resident memory (VmHWM) at the window's end, MB.
    peak_rss_mb: f64,
    /// Growth of the bag directory over the window, bytes/s (0 for the baseline).
    written_bytes_per_s: f64,
    /// The bag directory's size after the recorder stopped, bytes.
    bag_bytes: u64,
    /// Messages the recorder took off its queue (its summary).
    messages: u64,
    /// CDR bytes of those messages.
    received_bytes: u64,
    /// From the taps' opening to the SIGINT, s.
    tapped_s: f64,
    messages_per_s: f64,
    received_bytes_per_s: f64,
    /// Samples dropped at the full queue (its summary).
    dropped: u64,
    /// The whole machine's busy share over the window, % of all its cores.
    machine_busy_pct: f64,
    /// The recorder's summary line.
    summary: String,
}

/// Medians over the rounds of one (topics, mode).
#[derive(Debug, Clone, Serialize)]
struct Median {
    topics: Topics,
    mode: Mode,
    runs: usize,
    cpu_pct: f64,
    cpu_pct_min: f64,
    cpu_pct_max: f64,
    /// Median of the per-round ratios to the baseline's CPU (same round, same topics).
    cpu_ratio_to_baseline: Option<f64>,
    peak_rss_mb: f64,
    written_mb_per_s: f64,
    received_mb_per_s: f64,
    messages_per_s: f64,
    dropped_total: u64,
    machine_busy_pct: f64,
}

#[derive(Debug, Clone, Serialize)]
struct Machine {
    cpus: usize,
    cpu_model: String,
    kernel: String,
    loadavg_start: String,
    loadavg_end: String,
}

#[derive(Debug, Clone, Serialize)]
struct Report {
    date_utc: String,
    machine: Machine,
    rounds: usize,
    window_s: f64,
    warmup_s: f64,
    settle_s: f64,
    domain_id: u32,
    launch_command: String,
    launch_exit: String,
    runs: Vec<Run>,
    medians: Vec<Median>,
}

fn main() -> Result<()> {
    teleop_node::init_tracing();
    let cli = Cli::parse();
    if cli.rounds == 0 {
        bail!("--rounds: at least 1");
    }
    for (name, v) in [
        ("--seconds", cli.seconds),
        ("--warmup-s", cli.warmup_s),
        ("--settle-s", cli.settle_s),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{name} {v}: zero or more seconds");
        }
    }
    if cli.seconds < 1.0 {
        bail!("--seconds {}: at least 1 s", cli.seconds);
    }
    let teleop = teleop_binary()?;
    let work = match &cli.work_dir {
        Some(d) => d.clone(),
        None => std::env::temp_dir().join(format!("record_bench_{}", std::process::id())),
    };
    std::fs::create_dir_all(&work).with_context(|| format!("creating {}", work.display()))?;
    let tck = proc_stat::clock_ticks_per_s();
    let loadavg_start = loadavg();

    // The whole system, long enough for every run (it is stopped at the end).
    let per_run_s = cli.warmup_s + cli.seconds + 20.0;
    #[allow(clippy::cast_precision_loss)]
    let runs_total = (cli.rounds * 2 * Mode::ALL.len()) as f64;
    let duration_s = (cli.settle_s + runs_total * per_run_s + 120.0).ceil();
    let mut launch_args = vec![
        "--domain-id".to_owned(),
        cli.domain_id.to_string(),
        "launch".to_owned(),
        "--quiet".to_owned(),
        "--no-report-files".to_owned(),
    ];
    if launch_knows_display(&teleop)? {
        launch_args.extend(["--display".to_owned(), "off".to_owned()]);
    } else {
        eprintln!("record_bench: this `teleop launch` has no --display option: left out");
    }
    launch_args.extend(["--duration-s".to_owned(), format!("{duration_s}")]);
    let launch_command = format!("teleop {}", launch_args.join(" "));
    let log_path = work.join("launch.log");
    let log = std::fs::File::create(&log_path)
        .with_context(|| format!("creating {}", log_path.display()))?;
    eprintln!(
        "record_bench: starting the system: {launch_command} (log: {})",
        log_path.display()
    );
    let child = Command::new(&teleop)
        .args(&launch_args)
        .stdin(Stdio::null())
        .stdout(log.try_clone().context("the launch log")?)
        .stderr(log)
        .spawn()
        .with_context(|| format!("starting {}", teleop.display()))?;
    let mut system = System {
        child: Some(child),
        log: log_path.clone(),
    };
    std::thread::sleep(Duration::from_secs_f64(cli.settle_s));
    system.check_alive()?;

    let mut runs = Vec::new();
    for round in 1..=cli.rounds {
        for topics in [Topics::Default, Topics::All] {
            for mode in Mode::ALL {
                let run =
                    measure(&cli, &teleop, &work, tck, round, topics, mode).with_context(|| {
                        format!("round {round}, {} topics, {}", topics.name(), mode.name())
                    })?;
                eprintln!(
                    "record_bench: round {round}/{}: {:7} {:8} CPU {:5.1} %, RSS {:5.1} MB, \
                     written {:6.2} MB/s, received {:6.2} MB/s, {:6.0} msg/s, dropped {}, \
                     machine {:3.0} % busy",
                    cli.rounds,
                    topics.name(),
                    mode.name(),
                    run.cpu_pct,
                    run.peak_rss_mb,
                    run.written_bytes_per_s / 1e6,
                    run.received_bytes_per_s / 1e6,
                    run.messages_per_s,
                    run.dropped,
                    run.machine_busy_pct,
                );
                runs.push(run);
                system.check_alive()?;
            }
        }
    }
    let launch_exit = system.stop();
    eprintln!("record_bench: the system stopped: {launch_exit}");

    let medians = medians(&runs);
    let report = Report {
        date_utc: date_utc(),
        machine: Machine {
            cpus: std::thread::available_parallelism().map_or(0, std::num::NonZero::get),
            cpu_model: cpu_model(),
            kernel: std::fs::read_to_string("/proc/sys/kernel/osrelease")
                .map(|s| s.trim().to_owned())
                .unwrap_or_default(),
            loadavg_start,
            loadavg_end: loadavg(),
        },
        rounds: cli.rounds,
        window_s: cli.seconds,
        warmup_s: cli.warmup_s,
        settle_s: cli.settle_s,
        domain_id: cli.domain_id,
        launch_command,
        launch_exit,
        runs,
        medians,
    };
    print_report(&report);
    if let Some(path) = &cli.out {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
        println!("\nJSON: {}", path.display());
    }
    // The system's log stays when it did not stop gracefully.
    if cli.work_dir.is_none() && report.launch_exit.starts_with("graceful, exit status: 0") {
        std::fs::remove_dir_all(&work).ok();
    } else {
        println!("the system's log: {}", log_path.display());
    }
    Ok(())
}

/// `teleop` next to this binary, and the node binaries next to it.
fn teleop_binary() -> Result<PathBuf> {
    let exe = std::env::current_exe().context("locating this binary")?;
    let dir = exe
        .parent()
        .context("this binary's directory")?
        .to_path_buf();
    let teleop = dir.join("teleop");
    if !teleop.is_file() {
        bail!(
            "{} not found: record_bench runs the `teleop` next to itself; build it first \
             (cargo build --release --workspace --bins)",
            teleop.display()
        );
    }
    let missing: Vec<&str> = NODES
        .iter()
        .map(|n| n.name)
        .filter(|n| !dir.join(n).is_file())
        .collect();
    if !missing.is_empty() {
        bail!(
            "node binaries missing next to {}: {}; build them first (cargo build --release \
             --workspace --bins)",
            teleop.display(),
            missing.join(", ")
        );
    }
    Ok(teleop)
}

/// Whether `teleop launch` has the `--display` option (added with the browser page).
fn launch_knows_display(teleop: &Path) -> Result<bool> {
    let out = Command::new(teleop)
        .args(["launch", "--help"])
        .output()
        .with_context(|| format!("running {} launch --help", teleop.display()))?;
    if !out.status.success() {
        bail!(
            "{} launch --help failed ({}): {}",
            teleop.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).contains("--display"))
}

/// The running system; stopped (SIGINT, then killed) when dropped.
#[derive(Debug)]
struct System {
    child: Option<Child>,
    log: PathBuf,
}

impl System {
    fn check_alive(&mut self) -> Result<()> {
        let Some(child) = &mut self.child else {
            bail!("the system is not running");
        };
        if let Some(status) = child.try_wait()? {
            self.child = None;
            bail!(
                "the system (teleop launch) ended early ({status}); its log, {}:\n{}",
                self.log.display(),
                tail(&std::fs::read_to_string(&self.log).unwrap_or_default(), 40)
            );
        }
        Ok(())
    }

    /// SIGINT, up to 60 s for the graceful stop, then the launcher's nodes and the
    /// launcher killed. Returns how it ended.
    fn stop(&mut self) -> String {
        let Some(mut child) = self.child.take() else {
            return "not running".to_owned();
        };
        // The nodes run in process groups of their own: killed by id if the launcher
        // has to be.
        let nodes = children_of(child.id());
        interrupt(&child);
        match wait_timeout(&mut child, Duration::from_secs(60)) {
            Some(status) => format!("graceful, {status}"),
            None => {
                for pid in nodes {
                    if let Ok(pid) = i32::try_from(pid) {
                        kill(Pid::from_raw(pid), Signal::SIGKILL).ok();
                    }
                }
                child.kill().ok();
                let status = child
                    .wait()
                    .map_or_else(|e| e.to_string(), |s| s.to_string());
                format!("killed after 60 s without stopping ({status})")
            }
        }
    }
}

impl Drop for System {
    fn drop(&mut self) {
        if self.child.is_some() {
            let how = self.stop();
            eprintln!("record_bench: the system stopped: {how}");
        }
    }
}

/// The pids of a process's children (/proc/PID/task/*/children).
fn children_of(pid: u32) -> Vec<u32> {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    tasks
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("children")).ok())
        .flat_map(|s| {
            s.split_whitespace()
                .filter_map(|p| p.parse().ok())
                .collect::<Vec<u32>>()
        })
        .collect()
}

fn interrupt(child: &Child) {
    if let Ok(pid) = i32::try_from(child.id()) {
        kill(Pid::from_raw(pid), Signal::SIGINT).ok();
    }
}

fn wait_timeout(child: &mut Child, timeout: Duration) -> Option<ExitStatus> {
    let end = Instant::now() + timeout;
    while Instant::now() < end {
        match child.try_wait() {
            Ok(Some(s)) => return Some(s),
            Ok(None) => std::thread::sleep(Duration::from_millis(50)),
            Err(_) => return None,
        }
    }
    None
}

/// A recorder process; SIGINT and killed when dropped before it ended.
struct Recorder {
    child: Child,
    lines: mpsc::Receiver<(Instant, String)>,
    reader: Option<JoinHandle<()>>,
    stderr: Vec<String>,
}

impl Drop for Recorder {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            interrupt(&self.child);
            if wait_timeout(&mut self.child, Duration::from_secs(10)).is_none() {
                self.child.kill().ok();
                self.child.wait().ok();
            }
        }
    }
}

impl Recorder {
    /// Waits for a line for which `pred` holds; the time it arrived.
    fn wait_for(&mut self, timeout: Duration, pred: impl Fn(&str) -> bool) -> Result<Instant> {
        let end = Instant::now() + timeout;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok((t, line)) => {
                    let hit = pred(&line);
                    self.stderr.push(line);
                    if hit {
                        return Ok(t);
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => bail!(
                    "the recorder did not start within {} s; it printed:\n{}",
                    timeout.as_secs(),
                    self.stderr.join("\n")
                ),
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let status = self.child.wait()?;
                    bail!(
                        "the recorder ended ({status}); it printed:\n{}",
                        self.stderr.join("\n")
                    )
                }
            }
        }
    }

    /// SIGINT, then its exit (killed after `timeout`) and everything it printed.
    fn stop(&mut self, timeout: Duration) -> Result<ExitStatus> {
        interrupt(&self.child);
        let status = match wait_timeout(&mut self.child, timeout) {
            Some(s) => s,
            None => {
                self.child.kill().ok();
                self.child.wait().ok();
                bail!(
                    "the recorder did not stop within {} s of SIGINT; it printed:\n{}",
                    timeout.as_secs(),
                    self.stderr.join("\n")
                );
            }
        };
        if let Some(reader) = self.reader.take() {
            reader.join().ok();
        }
        self.stderr.extend(self.lines.try_iter().map(|(_, l)| l));
        Ok(status)
    }
}

fn spawn_recorder(teleop: &Path, args: &[String]) -> Result<Recorder> {
    let mut child = Command::new(teleop)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting {}", teleop.display()))?;
    let stderr = child.stderr.take().context("the recorder's stderr")?;
    let (tx, lines) = mpsc::channel();
    let reader = std::thread::Builder::new()
        .name("recorder-stderr".into())
        .spawn(move || {
            for line in BufReader::new(stderr).lines() {
                let Ok(line) = line else { break };
                if tx.send((Instant::now(), line)).is_err() {
                    break;
                }
            }
        })
        .context("starting the recorder's reader")?;
    Ok(Recorder {
        child,
        lines,
        reader: Some(reader),
        stderr: Vec::new(),
    })
}

/// One run of the recorder in `mode`, measured.
#[allow(clippy::too_many_arguments)]
fn measure(
    cli: &Cli,
    teleop: &Path,
    work: &Path,
    tck: f64,
    round: usize,
    topics: Topics,
    mode: Mode,
) -> Result<Run> {
    let bag = work.join(format!("r{round}_{}_{}", topics.name(), mode.name()));
    if bag.exists() {
        std::fs::remove_dir_all(&bag).with_context(|| format!("removing {}", bag.display()))?;
    }
    let mut args = vec![
        "--domain-id".to_owned(),
        cli.domain_id.to_string(),
        "record".to_owned(),
    ];
    if topics == Topics::All {
        args.push("--all".to_owned());
    }
    match mode {
        Mode::Discard => args.push("--discard".to_owned()),
        _ => {
            args.push("-o".to_owned());
            args.push(bag.display().to_string());
            args.extend(["--compression".to_owned(), mode.name().to_owned()]);
        }
    }
    let command = format!("teleop {}", args.join(" "));
    let mut rec = spawn_recorder(teleop, &args)?;
    let pid = rec.child.id();
    let tapped = rec.wait_for(Duration::from_secs(30), |l| {
        l.starts_with("recording ") || l.starts_with("receiving ")
    })?;
    std::thread::sleep(Duration::from_secs_f64(cli.warmup_s));

    let (cpu0, wall0, size0, machine0) = (
        proc_stat::process_ticks(pid)?,
        Instant::now(),
        dir_bytes(&bag),
        proc_stat::machine_ticks()?,
    );
    std::thread::sleep(Duration::from_secs_f64(cli.seconds));
    let (cpu1, wall1, size1, machine1) = (
        proc_stat::process_ticks(pid)?,
        Instant::now(),
        dir_bytes(&bag),
        proc_stat::machine_ticks()?,
    );
    let peak_rss_kb = vm_hwm_kb(pid)?;
    let stopped_at = Instant::now();
    let status = rec.stop(Duration::from_secs(180))?;
    if !status.success() {
        bail!("`{command}` failed ({status}):\n{}", rec.stderr.join("\n"));
    }
    let summary = rec
        .stderr
        .iter()
        .find(|l| l.starts_with("recorded ") || l.starts_with("discarded "))
        .cloned()
        .with_context(|| {
            format!(
                "no summary line from `{command}`:\n{}",
                rec.stderr.join("\n")
            )
        })?;
    let s = parse_summary(&summary).with_context(|| format!("reading `{summary}`"))?;
    let bag_bytes = dir_bytes(&bag);
    if mode != Mode::Discard {
        std::fs::remove_dir_all(&bag).with_context(|| format!("removing {}", bag.display()))?;
    }

    let window_s = (wall1 - wall0).as_secs_f64();
    let tapped_s = (stopped_at - tapped).as_secs_f64();
    #[allow(clippy::cast_precision_loss)]
    let run = Run {
        round,
        topics,
        mode,
        command,
        window_s,
        cpu_pct: (cpu1 - cpu0) as f64 / tck / window_s * 100.0,
        peak_rss_mb: peak_rss_kb as f64 * 1024.0 / 1e6,
        written_bytes_per_s: size1.saturating_sub(size0) as f64 / window_s,
        bag_bytes,
        messages: s.messages,
        received_bytes: s.bytes,
        tapped_s,
        messages_per_s: s.messages as f64 / tapped_s,
        received_bytes_per_s: s.bytes as f64 / tapped_s,
        dropped: s.dropped,
        machine_busy_pct: machine1.busy_fraction_since(&machine0) * 100.0,
        summary,
    };
    Ok(run)
}

/// What the recorder's summary line says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Summary {
    messages: u64,
    dropped: u64,
    bytes: u64,
}

/// `recorded N messages, D dropped, B bytes received; ...` (or `discarded ...`).
fn parse_summary(line: &str) -> Result<Summary> {
    let head = line.split(';').next().unwrap_or_default();
    let mut parts = head.split(", ");
    let mut number = |what: &str, at: usize| -> Result<u64> {
        let part = parts.next().with_context(|| format!("no {what}"))?;
        let word = part
            .split_whitespace()
            .nth(at)
            .with_context(|| format!("no {what} in `{part}`"))?;
        word.parse()
            .with_context(|| format!("{what}: `{word}` is not a count"))
    };
    Ok(Summary {
        messages: number("messages", 1)?,
        dropped: number("dropped", 0)?,
        bytes: number("bytes", 0)?,
    })
}

/// VmHWM of a process, kB.
fn vm_hwm_kb(pid: u32) -> Result<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .with_context(|| format!("reading /proc/{pid}/status"))?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .context("no VmHWM in /proc/PID/status")
}

/// The size of the files in a directory (and below), bytes; 0 if it does not exist.
fn dir_bytes(dir: &Path) -> u64 {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| match e.metadata() {
            Ok(m) if m.is_dir() => dir_bytes(&e.path()),
            Ok(m) => m.len(),
            Err(_) => 0,
        })
        .sum()
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, m)| m.trim().to_owned())
        })
        .unwrap_or_default()
}

/// Now, `YYYY-MM-DD HH:MM UTC`.
fn date_utc() -> String {
    // The system's `date` names the day; without it, the Unix time does.
    Command::new("date")
        .args(["-u", "+%Y-%m-%d %H:%M UTC"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_else(|| {
            let secs = SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            format!("unix time {secs}")
        })
}

fn medians(runs: &[Run]) -> Vec<Median> {
    let mut groups: BTreeMap<(Topics, Mode), Vec<&Run>> = BTreeMap::new();
    for r in runs {
        groups.entry((r.topics, r.mode)).or_default().push(r);
    }
    let baseline_cpu = |topics: Topics, round: usize| {
        runs.iter()
            .find(|r| r.topics == topics && r.round == round && r.mode == Mode::Discard)
            .map(|r| r.cpu_pct)
    };
    groups
        .into_iter()
        .map(|((topics, mode), rs)| {
            let of = |f: fn(&Run) -> f64| median(&rs.iter().map(|r| f(r)).collect::<Vec<_>>());
            let ratios: Vec<f64> = rs
                .iter()
                .filter_map(|r| {
                    baseline_cpu(topics, r.round)
                        .filter(|b| *b > 0.0)
                        .map(|b| r.cpu_pct / b)
                })
                .collect();
            Median {
                topics,
                mode,
                runs: rs.len(),
                cpu_pct: of(|r| r.cpu_pct),
                cpu_pct_min: rs.iter().map(|r| r.cpu_pct).fold(f64::INFINITY, f64::min),
                cpu_pct_max: rs
                    .iter()
                    .map(|r| r.cpu_pct)
                    .fold(f64::NEG_INFINITY, f64::max),
                cpu_ratio_to_baseline: (!ratios.is_empty()).then(|| median(&ratios)),
                peak_rss_mb: of(|r| r.peak_rss_mb),
                written_mb_per_s: of(|r| r.written_bytes_per_s / 1e6),
                received_mb_per_s: of(|r| r.received_bytes_per_s / 1e6),
                messages_per_s: of(|r| r.messages_per_s),
                dropped_total: rs.iter().map(|r| r.dropped).sum(),
                machine_busy_pct: of(|r| r.machine_busy_pct),
            }
        })
        .collect()
}

fn print_report(r: &Report) {
    println!(
        "\nrecord_bench, {}: {} CPUs ({}), kernel {}, load {} -> {}; {} rounds, {} s windows \
         ({} s after the taps opened); system: {} ({})\n",
        r.date_utc,
        r.machine.cpus,
        r.machine.cpu_model,
        r.machine.kernel,
        r.machine.loadavg_start,
        r.machine.loadavg_end,
        r.rounds,
        r.window_s,
        r.warmup_s,
        r.launch_command,
        r.launch_exit
    );
    println!(
        "| topics | mode | CPU, % of one core (min-max) | CPU / baseline | peak RSS, MB | \
         received, MB/s | written, MB/s | messages/s | dropped | machine busy |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for m in &r.medians {
        println!(
            "| {} | {} | {:.1} ({:.1}-{:.1}) | {} | {:.1} | {:.2} | {} | {:.0} | {} | {:.0} % |",
            match m.topics {
                Topics::Default => "default (crossing)",
                Topics::All => "`--all`",
            },
            m.mode.label(),
            m.cpu_pct,
            m.cpu_pct_min,
            m.cpu_pct_max,
            m.cpu_ratio_to_baseline
                .map_or_else(|| "-".to_owned(), |x| format!("{x:.2}x")),
            m.peak_rss_mb,
            m.received_mb_per_s,
            if m.mode == Mode::Discard {
                "-".to_owned()
            } else {
                format!("{:.2}", m.written_mb_per_s)
            },
            m.messages_per_s,
            m.dropped_total,
            m.machine_busy_pct,
        );
    }
}

fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_lines_of_both_modes_parse() {
        let want = Summary {
            messages: 5650,
            dropped: 3,
            bytes: 1_234_567,
        };
        assert_eq!(
            parse_summary(
                "recorded 5650 messages, 3 dropped, 1234567 bytes received; 1 file(s) (zstd)"
            )
            .ok(),
            Some(want)
        );
        assert_eq!(
            parse_summary(
                "discarded 5650 messages, 3 dropped, 1234567 bytes received; nothing written"
            )
            .ok(),
            Some(want)
        );
        assert!(parse_summary("recorded many messages").is_err());
    }
}
