//! `teleop launch`: starts every node of the node table on this machine, as separate
//! processes talking Zenoh peer-to-peer over loopback, shows the live monitor, and on
//! Ctrl-C / SIGTERM / SIGHUP / `--duration-s` stops them gracefully: each gets SIGINT (the
//! controllers first, the robots' owner last, so the controllers' stop commands still
//! reach the hardware), a grace period to shut down, then SIGKILL. Every node's final status
//! (its lifecycle state at the stop, its counters, its last error) is collected from
//! the bus and printed as a summary.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Stdio;
use std::time::Duration;

use anyhow::{Context, bail};
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use teleop_bus::{Bus, BusConfig, Subscriber};
use teleop_interfaces::nodes::CAMERA_ARM;
use teleop_interfaces::nodes::{NODES, NodeSpec, Site};
use teleop_interfaces::topics;
use teleop_local_site::camera_arm_node::CameraArmNodeConfig;
use teleop_local_site::keyboard_panel::{KeyboardPanelConfig, TerminalMode};
use teleop_local_site::operator_display::OperatorDisplayConfig;
use teleop_local_site::wrist_tracker::{PanelSource, WristTrackerConfig};
use teleop_msgs::{Lifecycle, NodeStatus};
use teleop_node::ZenohArgs;
use teleop_sim::operator_site::{OperatorModel, TaskKind};
use teleop_sim_nodes::local_sim::LocalSimConfig;
use tokio::process::{Child, Command};

use crate::report::Recorder;
use crate::tasks::{PICK_JOB, TOWER_JOB, WATCHED_JOBS};

use crate::record::{reports_job_failed, reports_task_done};

#[derive(Debug, Clone, clap::Args)]
pub struct LaunchArgs {
    /// Directory with `<node>.toml` files (default: built-in defaults).
    #[arg(long)]
    pub config_dir: Option<PathBuf>,
    /// Stop everything after this many seconds of (simulated, with `--time-scale`)
    /// time (default: until Ctrl-C / SIGTERM).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Do not print the monitor table.
    #[arg(long)]
    pub quiet: bool,
    /// Seconds each node gets to shut down after SIGINT before it is killed.
    #[arg(long, default_value_t = 5.0)]
    pub grace_s: f64,
    /// Run this operator task once and stop when it is done: `pick` (the operator who
    /// watches the display moves the robot world's can onto its target, judged by the
    /// robot-site simulator), `tower` (the same operator stacks two blocks on a third)
    /// or a scripted motion (pick_and_place, pouring, sweeping,
    /// fader, precision). Default: the simulator's configured task, repeated
    /// until Ctrl-C or `--duration-s`.
    #[arg(long)]
    pub task: Option<String>,
    /// Where the end-of-run report is written (`report.json`, `report.png`).
    #[arg(long, default_value = "teleop-report")]
    pub report_dir: PathBuf,
    /// Write no report files (the report is still printed).
    #[arg(long)]
    pub no_report_files: bool,
    /// The pedals from this terminal's keyboard instead of the simulated operator's
    /// feet: hold space = enable, c = clutch, s = camera-arm stop, 1-4 = motion scale,
    /// x / Esc = release (the wrist tracker's keyboard panel; the launcher reads the
    /// keys and forwards them to it).
    #[arg(long)]
    pub keyboard: bool,
    /// Start only this site's nodes, `local` (the operator's) or `remote` (the
    /// robot's): one site per machine, or the robot site driven by `teleop play`.
    #[arg(long, value_parser = ["local", "remote"])]
    pub site: Option<String>,
    /// Serve the operator display's browser page on this address (host:port), or `off`
    /// for no page. Default: the display's config (127.0.0.1:8088).
    #[arg(long)]
    pub display: Option<String>,
    /// Run on simulated time as fast as this machine can carry the whole system: the
    /// launcher sets the time's rate every half second from how busy the machine and
    /// each node's process are (faster while there is room, slower when there is not;
    /// not with --time-scale). The report gives the rates the run went through.
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// Every node at normal time sharing, none in the real-time class (by default the
    /// depth frame's path to the hand runs real-time where this user may:
    /// `scheduling.realtime_priority` in the node configs).
    #[arg(long)]
    pub no_realtime: bool,
    /// Override a field of one node's config, NODE.KEY=VALUE (repeatable): passed to
    /// that node as `--set KEY=VALUE`, e.g. `remote_sim.engine=mujoco` (the robots in
    /// the MuJoCo world) or `remote_sim.mujoco.perturbation.seed=7`.
    #[arg(long = "set", value_name = "NODE.KEY=VALUE")]
    pub set: Vec<String>,
    /// Run the `--task` this many times, each on a seed of its own (the robot world's
    /// objects and model mismatch, the operator site's world, the WAN's draws:
    /// `--seed-base`, `--seed-base` + 1, ...), and sum the runs up as the thesis does:
    /// success rate and completion time (mean, p90) beside the thesis's figures
    /// (`summary.json`, `summary.png` in `--report-dir`, each run's report in
    /// `seed-S/` there).
    #[arg(long, requires = "task", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub seeds: Option<u32>,
    /// The first seed of `--seeds` (default 1000: the defaults were tuned on seeds
    /// below 100, so these are held out).
    #[arg(long, default_value_t = 1000, requires = "seeds")]
    pub seed_base: u64,
    /// Put an emulated WAN between the sites: each site's nodes are clients of a Zenoh
    /// router of their own, and the routers are joined through the WAN link emulator
    /// (as `deploy/compose` runs them, without TLS), with these settings:
    /// `delay_ms` (one way), `jitter_ms`, `loss_pct`, `retransmit_ms`, `rate_mbit`,
    /// `queue_ms`, e.g. `--wan delay_ms=25` for a 50 ms round trip.
    #[arg(long, value_name = "SETTINGS", conflicts_with = "site")]
    pub wan: Option<String>,
}

/// The `--set` overrides per node: `(node, KEY=VALUE)`.
///
/// # Errors
/// An override without a node name, or naming a node the system does not have.
fn node_overrides(sets: &[String]) -> anyhow::Result<Vec<(&'static str, String)>> {
    sets.iter()
        .map(|s| {
            let (node, rest) = s
                .split_once('.')
                .with_context(|| format!("--set {s}: expected NODE.KEY=VALUE"))?;
            let spec = NODES.iter().find(|n| n.name == node).with_context(|| {
                format!(
                    "--set {s}: no node {node:?}; the nodes are: {}",
                    NODES.iter().map(|n| n.name).collect::<Vec<_>>().join(", ")
                )
            })?;
            Ok((spec.name, rest.to_owned()))
        })
        .collect()
}

/// The `--set` overrides of node `name` (`KEY=VALUE`, its own config's keys).
fn sets_for(overrides: &[(&'static str, String)], name: &str) -> Vec<String> {
    overrides
        .iter()
        .filter(|(n, _)| *n == name)
        .map(|(_, s)| s.clone())
        .collect()
}

/// This run's directory for the configs the launcher writes.
fn run_dir() -> anyhow::Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("teleop-launch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

/// Writes `cfg` as `<name>.toml` into this run's directory.
fn write_run_config<T: serde::Serialize>(name: &str, cfg: &T) -> anyhow::Result<PathBuf> {
    let path = run_dir()?.join(format!("{name}.toml"));
    std::fs::write(&path, teleop_node::config::to_toml(cfg)?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// Node `name`'s config for this run: `<name>.toml` of `--config-dir`, or its defaults.
fn shipped_or_default<C: teleop_node::NodeConfig + Default>(
    args: &LaunchArgs,
    name: &str,
) -> anyhow::Result<C> {
    Ok(match &args.config_dir {
        Some(dir) => teleop_node::config::load_checked(&dir.join(format!("{name}.toml")))?,
        None => C::default(),
    })
}

/// The wrist tracker's config for `--keyboard`: the shipped file or the defaults, its
/// panel the keyboard.
fn keyboard_wrist_tracker_config(args: &LaunchArgs) -> anyhow::Result<PathBuf> {
    let name = teleop_interfaces::nodes::WRIST_TRACKER;
    let mut cfg: WristTrackerConfig = shipped_or_default(args, name)?;
    let keyboard = match cfg.panel {
        PanelSource::Keyboard(k) => k,
        _ => KeyboardPanelConfig::default(),
    };
    cfg.panel = PanelSource::Keyboard(keyboard);
    write_run_config(name, &cfg)
}

/// The operator display's config for `--display` (the shipped file or the defaults,
/// its page on the address given), and the address its page is served on (empty: none).
fn display_config(args: &LaunchArgs) -> anyhow::Result<(Option<PathBuf>, String)> {
    let name = teleop_interfaces::nodes::OPERATOR_DISPLAY;
    let mut cfg: OperatorDisplayConfig = shipped_or_default(args, name)?;
    let Some(listen) = &args.display else {
        return Ok((None, cfg.http_listen));
    };
    cfg.http_listen = if listen == "off" {
        String::new()
    } else {
        teleop_local_site::display_web::parse_listen(listen)
            .with_context(|| "--display".to_owned())?;
        listen.clone()
    };
    Ok((Some(write_run_config(name, &cfg)?), cfg.http_listen))
}

/// Forwards this process's stdin to the wrist tracker's keyboard panel, byte by byte
/// as the keys arrive, on a thread of its own (a blocking read cannot be cancelled; the
/// thread ends with the process or when the tracker's end of the pipe closes). A
/// terminal is switched to key-by-key, no-echo mode (Ctrl-C still reaches the
/// launcher) until the returned guard is dropped.
fn forward_keys(
    mut to_tracker: std::io::PipeWriter,
) -> anyhow::Result<Option<std::sync::Arc<TerminalMode>>> {
    use std::io::{IsTerminal, Read, Write};
    let mode = if std::io::stdin().is_terminal() {
        Some(TerminalMode::enter(Box::new(std::io::stdin()))?)
    } else {
        None
    };
    std::thread::Builder::new()
        .name("launch-keys".into())
        .spawn(move || {
            let mut stdin = std::io::stdin();
            let mut buf = [0u8; 64];
            loop {
                match stdin.read(&mut buf) {
                    Ok(0) => {
                        tracing::warn!("keyboard: input ended; the panel is lost (robots stop)");
                        return;
                    }
                    Ok(n) => {
                        if to_tracker.write_all(&buf[..n]).is_err() {
                            return;
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => {
                        tracing::warn!("keyboard: reading the keys failed: {e}");
                        return;
                    }
                }
            }
        })
        .context("starting the key forwarding thread")?;
    Ok(mode)
}

/// Settings a task needs on other nodes, before the command line's own `--set` (which
/// win): the pick and tower jobs start the PR2 at the top grasp's posture with the
/// table under it (`teleop_sim::PICK_TOP_GRASP_POSTURE_RAD`); the tower job's scene.
fn task_sets(task: Option<&str>) -> Vec<String> {
    let Some(task) = task.filter(|t| WATCHED_JOBS.contains(t)) else {
        return Vec::new();
    };
    let posture = teleop_sim::PICK_TOP_GRASP_POSTURE_RAD
        .map(|v| v.to_string())
        .join(", ");
    let mut sets = vec![
        format!("remote_sim.pick.arm_posture_rad=[{posture}]"),
        format!(
            "remote_sim.pick.table_below_palm_m={}",
            teleop_sim::PICK_TOP_GRASP_TABLE_BELOW_PALM_M
        ),
    ];
    if task == TOWER_JOB {
        sets.push("remote_sim.scene=\"tower\"".to_owned());
    }
    sets
}

/// The simulator's config for this run: the shipped file or the defaults, with the
/// task chosen on the command line (run once).
fn local_sim_config(args: &LaunchArgs) -> anyhow::Result<Option<(PathBuf, String)>> {
    let mut cfg: LocalSimConfig = shipped_or_default(args, "local_sim")?;
    let Some(task) = &args.task else {
        return Ok(None);
    };
    if task == PICK_JOB {
        cfg.operator_site.operator = OperatorModel::Watching;
    } else if task == TOWER_JOB {
        // The operator is told the tower's blocks (the robot world's default ones).
        cfg.operator_site.operator = OperatorModel::Watching;
        cfg.operator_site.watching.placements = teleop_sim::TowerJobConfig::default().placements();
        cfg.operator_site.watching.clear_tall_objects = true;
        // Pressed 1 cm onto the block below: a block carried tilted stands flat before
        // it is let go (5 mm above, as the can is, it was let go on an edge and fell).
        cfg.operator_site.watching.release_above_m = -0.01;
    } else {
        cfg.operator_site.operator = OperatorModel::Scripted;
        cfg.operator_site.task = TaskKind::ALL
            .into_iter()
            .find(|k| k.name() == task)
            .with_context(|| {
                format!(
                    "unknown task {task:?}; the tasks are: {PICK_JOB}, {TOWER_JOB}, {}",
                    TaskKind::ALL.map(TaskKind::name).join(", ")
                )
            })?;
    }
    cfg.operator_site.repeat = false;
    let path = write_run_config("local_sim", &cfg)?;
    Ok(Some((path, task.clone())))
}

/// Where the node binaries are: next to this one.
fn node_binary(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("locating the teleop binary")?;
    let dir = exe.parent().context("teleop binary has no directory")?;
    let path = dir.join(name);
    if !path.exists() {
        bail!(
            "node binary {} not found next to teleop; build the workspace first: cargo build --release --workspace",
            path.display()
        );
    }
    Ok(path)
}

/// Hand inference needs ONNX Runtime: its binary finds the library, or installs the
/// pinned PyPI wheel into the project's Python environment (once; later runs find it).
async fn ensure_onnx_runtime(args: &LaunchArgs) -> anyhow::Result<()> {
    let name = teleop_interfaces::nodes::HAND_INFERENCE;
    let mut cmd = Command::new(node_binary(name)?);
    cmd.arg("--ensure-runtime");
    if let Some(dir) = &args.config_dir {
        cmd.arg("--config").arg(dir.join(format!("{name}.toml")));
    }
    let out = cmd
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .await
        .with_context(|| format!("running {name} --ensure-runtime"))?;
    if !out.status.success() {
        bail!(
            "hand inference has no ONNX Runtime (see the message above); the system was not started"
        );
    }
    tracing::info!(
        library = String::from_utf8_lossy(&out.stdout).trim(),
        "ONNX Runtime for hand inference"
    );
    Ok(())
}

/// How one node ended.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeOutcome {
    pub name: &'static str,
    /// Exit status, or how it was stopped.
    pub exit: String,
    /// Whether it exited on its own after SIGINT (not killed, exit code 0).
    pub graceful: bool,
    /// Its lifecycle state just before it finalized (from its status reports).
    pub state_at_stop: Option<Lifecycle>,
    /// Its final (`FINALIZED`) status, if it reached the bus.
    pub final_status: Option<NodeStatus>,
}

/// What every node reported, collected from `/teleop/status`.
#[derive(Debug, Default)]
struct StatusLog {
    last_state: BTreeMap<String, Lifecycle>,
    finals: BTreeMap<String, NodeStatus>,
}

impl StatusLog {
    fn record(&mut self, s: NodeStatus) {
        match s.lifecycle() {
            Some(Lifecycle::Finalized) => {
                self.finals.insert(s.node_name.clone(), s);
            }
            Some(state) => {
                self.last_state.insert(s.node_name.clone(), state);
            }
            None => {}
        }
    }

    fn drain(&mut self, sub: &Subscriber<NodeStatus>) {
        while let Some(r) = sub.try_recv() {
            self.record(r.msg);
        }
    }
}

/// The `--set` overrides that give one run of `--seeds` its seed: the robot world's
/// objects and model mismatch, and the operator site's world (hand shape, noise, the
/// UR5's perturbation).
fn seed_sets(seed: u64) -> Vec<String> {
    vec![
        format!("remote_sim.mujoco.seed={seed}"),
        format!("remote_sim.mujoco.perturbation.seed={seed}"),
        format!("local_sim.operator_site.seed={seed}"),
    ]
}

pub async fn launch(args: LaunchArgs, zenoh: &ZenohArgs) -> anyhow::Result<()> {
    let wan = args
        .wan
        .as_deref()
        .map(crate::site_link::parse_wan)
        .transpose()?;
    let Some(n) = args.seeds else {
        let (_, problem) = launch_once(&args, zenoh, wan, Vec::new(), 1, &args.report_dir).await?;
        return problem.map_or(Ok(()), |p| Err(anyhow::anyhow!(p)));
    };
    let task = args.task.clone().context("--seeds needs --task")?;
    // Ctrl-C / SIGTERM ends the run in progress (its nodes stop as usual) and the
    // series: no further seeds.
    let stopped = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watcher = {
        let stopped = stopped.clone();
        tokio::spawn(async move {
            teleop_node::stop_signal(None).await;
            stopped.store(true, std::sync::atomic::Ordering::SeqCst);
        })
    };
    let mut runs = Vec::new();
    for seed in args.seed_base..args.seed_base + u64::from(n) {
        if stopped.load(std::sync::atomic::Ordering::SeqCst) {
            println!("stopped: {} of {n} runs done", runs.len());
            break;
        }
        let dir = args.report_dir.join(format!("seed-{seed}"));
        println!("\n== run {} of {n}: seed {seed}", runs.len() + 1);
        let (report, error) = launch_once(&args, zenoh, wan, seed_sets(seed), seed, &dir).await?;
        runs.push(crate::seeds::SeedRun {
            seed,
            job: report.job,
            operator: report.operator,
            error,
            report_dir: dir,
        });
    }
    watcher.abort();
    let summary = crate::seeds::SeedsSummary::new(&task, wan.as_ref(), runs);
    println!();
    print!("{}", summary.text());
    if !args.no_report_files {
        summary.write_files(&args.report_dir)?;
    }
    // A job that failed is a result; a run that went wrong is not.
    let broken: Vec<String> = summary
        .runs
        .iter()
        .filter_map(|r| Some(format!("seed {}: {}", r.seed, r.error.as_ref()?)))
        .collect();
    if !broken.is_empty() {
        bail!("runs that went wrong: {}", broken.join("; "));
    }
    Ok(())
}

/// One run of the system: started, run until `--duration-s`, the task's end or
/// Ctrl-C, stopped; its report printed and written into `report_dir`. `extra_sets`
/// come after the task's own and before the command line's; `wan_seed` seeds the
/// emulated WAN's draws. Returns the report and, when the run itself went wrong (a
/// node exited early or did not stop gracefully), what did.
///
/// # Errors
/// What kept the system from starting, or the report from being written.
async fn launch_once(
    args: &LaunchArgs,
    zenoh: &ZenohArgs,
    wan: Option<teleop_wan_link::Impairment>,
    extra_sets: Vec<String>,
    wan_seed: u64,
    report_dir: &std::path::Path,
) -> anyhow::Result<(crate::report::RunReport, Option<String>)> {
    // One simulated time for every process of the run (`--time-scale`).
    let mut zenoh = zenoh.clone();
    let paced_clock = if args.as_fast_as_possible {
        if zenoh.time_scale.is_some() || zenoh.time_file.is_some() {
            bail!(
                "--as-fast-as-possible sets the run's time itself: give it without --time-scale or --time-file"
            );
        }
        let (path, writer) = crate::clock_pacer::create_clock(&run_dir()?)?;
        zenoh.time_file = Some(path);
        Some(writer)
    } else {
        None
    };
    zenoh.pin_time_origin();
    let zenoh = &zenoh;
    let link = match wan {
        Some(w) => Some(crate::site_link::SiteLink::start(w, wan_seed, zenoh).await?),
        None => None,
    };
    // Each process's bus arguments: with the emulated WAN, a client of its site's
    // router (the launcher at the operator's site, where the report is taken).
    let site_args = |site: Site| {
        link.as_ref()
            .map_or_else(|| zenoh.clone(), |l| l.site_args(zenoh, site))
    };
    let mut cfg = BusConfig::default();
    site_args(Site::Local).apply(&mut cfg);
    let bus = Bus::open(&format!("teleop_launch_{}", std::process::id()), &cfg).await?;
    let status = bus.subscriber(&topics::NODE_STATUS).await?;
    let mut log = StatusLog::default();

    let mut sets = task_sets(args.task.as_deref());
    sets.extend(extra_sets);
    sets.extend(args.set.iter().cloned());
    let overrides = node_overrides(&sets)?;
    ensure_onnx_runtime(args).await?;
    let sim_config = local_sim_config(args)?;
    let (display_config, display_listen) = display_config(args)?;
    let task_name = match &sim_config {
        Some((_, t)) => t.clone(),
        None => match &args.config_dir {
            Some(dir) => {
                let c: LocalSimConfig =
                    teleop_node::config::load_checked(&dir.join("local_sim.toml"))?;
                c.operator_site.task.name().to_owned()
            }
            None => LocalSimConfig::default()
                .operator_site
                .task
                .name()
                .to_owned(),
        },
    };
    let keyboard_config = if args.keyboard {
        Some(keyboard_wrist_tracker_config(args)?)
    } else {
        None
    };
    // The camera is judged against the goal of the camera arm's settings as this run
    // starts it (its --config-dir file or defaults, with its --set overrides).
    let camera: CameraArmNodeConfig = shipped_or_default(args, CAMERA_ARM)?;
    let camera = teleop_node::config::apply_overrides(&camera, &sets_for(&overrides, CAMERA_ARM))?;
    let mut recorder = Recorder::new(&bus, &task_name, "teleop launch", camera.camera_arm).await?;
    let mut children: Vec<(&'static NodeSpec, Child)> = Vec::new();
    let mut _terminal = None;
    for spec in NODES.iter().filter(|n| {
        args.site
            .as_deref()
            .is_none_or(|site| n.site.label() == site)
    }) {
        let mut cmd = Command::new(node_binary(spec.name)?);
        let mut stdin = Stdio::null();
        if let (Some((path, _)), "local_sim") = (&sim_config, spec.name) {
            cmd.arg("--config").arg(path);
        } else if let (Some(path), teleop_interfaces::nodes::WRIST_TRACKER) =
            (&keyboard_config, spec.name)
        {
            cmd.arg("--config").arg(path);
            let (keys_in, keys_out) = std::io::pipe().context("a pipe for the keys")?;
            _terminal = forward_keys(keys_out)?;
            stdin = Stdio::from(keys_in);
        } else if let (Some(path), teleop_interfaces::nodes::OPERATOR_DISPLAY) =
            (&display_config, spec.name)
        {
            cmd.arg("--config").arg(path);
        } else if let Some(dir) = &args.config_dir {
            cmd.arg("--config")
                .arg(dir.join(format!("{}.toml", spec.name)));
        }
        for set in sets_for(&overrides, spec.name) {
            cmd.arg("--set").arg(set);
        }
        cmd.args(site_args(spec.site).to_args());
        if args.no_realtime {
            cmd.args(["--realtime-priority", "0"]);
        }
        // Each node in a process group of its own: a terminal's Ctrl-C (SIGINT to the
        // whole foreground group) reaches only the launcher, which stops the nodes in
        // the node table's order (controllers first, the robots' owner last) instead of
        // all at once.
        cmd.stdin(stdin).kill_on_drop(true).process_group(0);
        let child = cmd
            .spawn()
            .with_context(|| format!("starting {}", spec.name))?;
        tracing::info!(node = spec.name, pid = child.id(), "started");
        children.push((spec, child));
    }
    let mut banner = vec![format!(
        "teleop launch: {} nodes{}{}",
        children.len(),
        args.task
            .as_deref()
            .map(|t| format!(", task {t}"))
            .unwrap_or_default(),
        link.as_ref()
            .map(|l| format!("; {}", crate::site_link::describe(&l.link())))
            .unwrap_or_default()
    )];
    if !display_listen.is_empty()
        && children
            .iter()
            .any(|(s, _)| s.name == teleop_interfaces::nodes::OPERATOR_DISPLAY)
    {
        let line = format!("operator display: open http://{display_listen}/ in a browser");
        println!("{line}");
        banner.push(line);
    }
    let pacing = std::sync::Arc::new(std::sync::Mutex::new(
        crate::clock_pacer::PacingSummary::default(),
    ));
    let wall_start = std::time::Instant::now();
    let sim_start_s = bus.now_s();
    let pacer = paced_clock.map(|writer| {
        let mut pids: Vec<u32> = children.iter().filter_map(|(_, c)| c.id()).collect();
        pids.push(std::process::id());
        tokio::spawn(crate::clock_pacer::run(
            writer,
            pids,
            crate::clock_pacer::PacerConfig::default(),
            pacing.clone(),
        ))
    });
    // `--duration-s` is simulated time.
    let stop = until_simulated(
        bus.clock().clone(),
        args.duration_s.map(|s| sim_start_s + s.max(0.0)),
    );
    let monitor = async {
        if args.quiet {
            stop.await;
            Ok(())
        } else {
            // Behind the emulated WAN the launcher is at the operator's site: it
            // watches what reaches that site, not the robot site's internal topics.
            let at_site = link.as_ref().map(|_| Site::Local);
            crate::inspect::monitor_until(&cfg, None, at_site, stop, &banner).await
        }
    };
    let run_once = sim_config.is_some();
    // CPU and peak memory of every node's process, for the report.
    let mut resources = crate::proc_stat::ResourceSampler::new(
        children
            .iter()
            .filter_map(|(spec, c)| c.id().map(|pid| (spec.name.to_owned(), pid))),
    );
    let resources_ref = &mut resources;
    let collect = async {
        let mut sampled = std::time::Instant::now();
        // Simulated time, as the task's.
        let mut done_since: Option<f64> = None;
        loop {
            while let Some(r) = status.try_recv() {
                // With a task run once: stop 1 s after the operator's simulator reports
                // it done, or the robot's simulator reports its job failed for good.
                if run_once && (reports_task_done(&r.msg) || reports_job_failed(&r.msg)) {
                    done_since.get_or_insert_with(|| bus.now_s());
                }
                recorder.on_status(&r.msg);
                log.record(r.msg);
            }
            recorder.poll();
            if sampled.elapsed() >= Duration::from_secs(1) {
                resources_ref.sample();
                sampled = std::time::Instant::now();
            }
            if done_since.is_some_and(|t| bus.now_s() - t > 1.0) {
                return;
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    };
    // A closed terminal (SIGHUP) stops the system the same way: the nodes, in groups of
    // their own, would not get the hangup.
    let hangup = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::hangup()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    let early = tokio::select! {
        r = monitor => { r?; None }
        () = hangup => None,
        (name, exit) = wait_any(&mut children) => Some((name, exit)),
        () = collect => None,
    };
    log.drain(&status);
    resources.sample();
    // Who publishes what, as the running nodes announce it, against the topic table
    // (which the sites' routers enforce across machines).
    let publishers = match bus.graph(Duration::from_millis(500)).await {
        Ok(g) => publisher_check(&g),
        Err(e) => format!("publishers vs the topic table: not checked ({e})"),
    };
    let outcomes = stop_all(&mut children, args.grace_s, &status, &mut log).await;
    print_summary(&outcomes);
    println!("{publishers}");
    let mut report = recorder.finish(bus.now_s(), &log.finals);
    report.resources = resources.summary();
    if let Some(task) = pacer {
        task.abort();
        // The mean rate: simulated over wall seconds of the run.
        let wall_s = wall_start.elapsed().as_secs_f64();
        if wall_s > 0.0 {
            report.time_scale = (bus.now_s() - sim_start_s) / wall_s;
        }
        report.pacing = pacing.lock().ok().map(|p| p.clone());
        // Judged again now that the report says the run was paced (the latency goal
        // is judged in real time only).
        report.goals = report.judge_goals();
    }
    report.wan = link.as_ref().map(|l| crate::site_link::describe(&l.link()));
    println!();
    print!("{}", report.text());
    if !args.no_report_files {
        report.write_files(report_dir)?;
    }
    drop(status);
    bus.close().await?;
    if let Some(l) = link {
        l.stop().await;
    }
    let bad: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.graceful || o.final_status.is_none())
        .map(|o| o.name)
        .collect();
    let problem = match early {
        Some((name, exit)) => Some(format!("node {name} exited early: {exit}")),
        None if !bad.is_empty() => Some(format!("not stopped gracefully: {}", bad.join(", "))),
        None => None,
    };
    Ok((report, problem))
}

/// Completes at simulated time `end_s` on `clock` (never without one), or on Ctrl-C /
/// SIGTERM.
async fn until_simulated(clock: std::sync::Arc<dyn teleop_bus::Clock>, end_s: Option<f64>) {
    let timer = async {
        match end_s {
            Some(end) => {
                while clock.now_s() < end {
                    // A fraction of the time left in wall seconds at the current rate,
                    // at most 50 ms: the rate may change meanwhile.
                    let left = ((end - clock.now_s()) / clock.rate()).clamp(0.001, 0.05);
                    tokio::time::sleep(Duration::from_secs_f64(left)).await;
                }
            }
            None => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        () = timer => {}
        () = teleop_node::stop_signal(None) => {}
    }
}

/// The topics the running nodes of the node table publish, against the topic table's
/// publishers: one line saying they agree, or what differs (a publisher the table does
/// not name would be refused by the sites' routers; a table entry no node published is
/// stale).
pub fn publisher_check(graph: &[teleop_bus::keys::GraphEntity]) -> String {
    use std::collections::BTreeSet;
    use teleop_bus::keys::EntityKind;
    let running: BTreeSet<&str> = graph
        .iter()
        .filter(|e| e.kind == EntityKind::Node)
        .map(|e| e.node_name.as_str())
        .filter(|n| NODES.iter().any(|s| s.name == *n))
        .collect();
    let seen: BTreeSet<(String, String)> = graph
        .iter()
        .filter(|e| e.kind == EntityKind::Publisher && running.contains(e.node_name.as_str()))
        .filter_map(|e| {
            Some((
                e.topic.as_deref()?.trim_matches('/').to_owned(),
                e.node_name.clone(),
            ))
        })
        .collect();
    let unlisted: Vec<String> = seen
        .iter()
        .filter(|(t, n)| !topics::find(t).is_some_and(|spec| spec.publishers.includes(n)))
        .map(|(t, n)| format!("{n} -> /{t}"))
        .collect();
    let mut missing = Vec::new();
    for t in topics::ALL {
        if let topics::Publishers::Nodes(names) = t.publishers {
            for n in names.iter().filter(|n| running.contains(*n)) {
                if !seen.contains(&(t.name.to_owned(), (*n).to_owned())) {
                    missing.push(format!("{n} -> /{}", t.name));
                }
            }
        }
    }
    if unlisted.is_empty() && missing.is_empty() {
        format!(
            "publishers vs the topic table: all {} publications of the {} running nodes are in the table, and every one the table names for them was seen",
            seen.len(),
            running.len()
        )
    } else {
        format!(
            "publishers vs the topic table: DIFFER: not in the table (routers would refuse): [{}]; in the table but not published: [{}]",
            unlisted.join(", "),
            missing.join(", ")
        )
    }
}

/// SIGINT to each node in the node table's stop order, wait up to `grace_s`, then
/// SIGKILL.
async fn stop_all(
    children: &mut [(&'static NodeSpec, Child)],
    grace_s: f64,
    status: &Subscriber<NodeStatus>,
    log: &mut StatusLog,
) -> Vec<NodeOutcome> {
    let grace = Duration::from_secs_f64(grace_s.clamp(0.1, 120.0));
    let mut outcomes = Vec::new();
    for stop in teleop_interfaces::nodes::stop_order() {
        let Some((spec, child)) = children.iter_mut().find(|(s, _)| s.name == stop.name) else {
            continue;
        };
        let (exit, graceful) = match child.try_wait() {
            Ok(Some(s)) => (format!("exited before the stop: {s}"), false),
            _ => {
                let signalled = child
                    .id()
                    .and_then(|pid| i32::try_from(pid).ok())
                    .is_some_and(|pid| kill(Pid::from_raw(pid), Signal::SIGINT).is_ok());
                match tokio::time::timeout(grace, child.wait()).await {
                    Ok(Ok(s)) if signalled => (s.to_string(), s.success()),
                    Ok(Ok(s)) => (s.to_string(), false),
                    Ok(Err(e)) => (format!("wait failed: {e}"), false),
                    Err(_) => {
                        let _ = child.start_kill();
                        let _ = child.wait().await;
                        (format!("killed after {grace_s} s"), false)
                    }
                }
            }
        };
        // The final status is published just before the session closes.
        let until = tokio::time::Instant::now() + Duration::from_millis(500);
        while !log.finals.contains_key(spec.name) && tokio::time::Instant::now() < until {
            if let Some(r) = status.recv_timeout(Duration::from_millis(50)).await {
                log.record(r.msg);
            }
        }
        log.drain(status);
        outcomes.push(NodeOutcome {
            name: spec.name,
            exit,
            graceful,
            state_at_stop: log.last_state.get(spec.name).copied(),
            final_status: log.finals.get(spec.name).cloned(),
        });
    }
    // Summarize in start order.
    outcomes.sort_by_key(|o| NODES.iter().position(|n| n.name == o.name));
    outcomes
}

/// Counters worth a line in the summary: everything that counts something going wrong
/// or a safety action, when nonzero.
fn notable(name: &str) -> bool {
    [
        "rejected",
        "refused",
        "limited",
        "stop.",
        "hold.",
        "error",
        "missing",
        "safety",
        "conflict",
        "foreign",
        "bad",
        "engagements",
    ]
    .iter()
    .any(|k| name.contains(k))
        && !name.ends_with(".received")
        && !name.ends_with(".accepted")
}

fn print_summary(outcomes: &[NodeOutcome]) {
    println!();
    println!("== teleop launch: summary");
    println!(
        "{:<24} {:<10} {:<14} {:<10} EXIT",
        "NODE", "STOPPED", "STATE AT STOP", "FINAL"
    );
    for o in outcomes {
        println!(
            "{:<24} {:<10} {:<14} {:<10} {}",
            o.name,
            if o.graceful { "graceful" } else { "NOT" },
            o.state_at_stop
                .map_or_else(|| "-".to_owned(), |s| format!("{s:?}")),
            if o.final_status.is_some() {
                "reported"
            } else {
                "MISSING"
            },
            o.exit
        );
    }
    for o in outcomes {
        let Some(s) = &o.final_status else { continue };
        let lines: Vec<String> = s
            .counter_names
            .iter()
            .zip(&s.counter_values)
            .filter(|(n, v)| **v > 0 && notable(n))
            .map(|(n, v)| format!("{n}={v}"))
            .collect();
        if !lines.is_empty() {
            println!("  {}: {}", o.name, lines.join(" "));
        }
        if !s.last_error.is_empty() {
            println!("  {} last error: {}", o.name, s.last_error);
        }
    }
}

async fn wait_any(children: &mut [(&'static NodeSpec, Child)]) -> (&'static str, String) {
    loop {
        for (spec, child) in children.iter_mut() {
            if let Ok(Some(status)) = child.try_wait() {
                return (spec.name, status.to_string());
            }
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_go_to_the_node_they_name() {
        let out = node_overrides(&[
            "remote_sim.engine=mujoco".into(),
            "remote_sim.mujoco.perturbation.seed=7".into(),
        ])
        .expect("valid");
        assert_eq!(
            out,
            [
                ("remote_sim", "engine=mujoco".to_owned()),
                ("remote_sim", "mujoco.perturbation.seed=7".to_owned())
            ]
        );
        let err = node_overrides(&["remote_simm.engine=mujoco".into()]).expect_err("no node");
        assert!(err.to_string().contains("remote_simm"), "{err}");
        assert!(node_overrides(&["engine".into()]).is_err());
    }

    #[test]
    fn the_pick_job_starts_the_robot_at_the_top_grasp_posture() {
        assert!(task_sets(Some("fader")).is_empty());
        assert!(task_sets(None).is_empty());
        let sets = node_overrides(&task_sets(Some(PICK_JOB))).expect("valid");
        // The keys and values are the robot-site simulator's pick scene's own (its
        // config holds the scene under `pick`; unknown fields are refused).
        #[derive(serde::Serialize, serde::Deserialize, Default)]
        #[serde(deny_unknown_fields)]
        struct Sim {
            pick: teleop_sim::PickSceneConfig,
        }
        let scene =
            teleop_node::config::apply_overrides(&Sim::default(), &sets_for(&sets, "remote_sim"))
                .expect("its fields")
                .pick;
        assert_eq!(
            scene.arm_posture_rad,
            teleop_sim::PICK_TOP_GRASP_POSTURE_RAD
        );
        assert_eq!(
            scene.table_below_palm_m,
            teleop_sim::PICK_TOP_GRASP_TABLE_BELOW_PALM_M
        );
        assert_eq!(sets.len(), 2, "{sets:?}");
    }

    #[test]
    fn the_tower_job_gets_its_scene_the_top_grasp_posture_and_the_operator_its_blocks() {
        use teleop_node::NodeConfig as _;
        use teleop_sim_nodes::remote_sim::{SceneKind, SimNodeConfig};
        let sets = node_overrides(&task_sets(Some(TOWER_JOB))).expect("valid");
        let sim = teleop_node::config::apply_overrides(
            &SimNodeConfig::default(),
            &sets_for(&sets, "remote_sim"),
        )
        .expect("the simulator's own fields");
        assert_eq!(sim.scene, SceneKind::Tower);
        assert_eq!(
            sim.pick.arm_posture_rad,
            teleop_sim::PICK_TOP_GRASP_POSTURE_RAD
        );
        sim.validate().expect("a valid tower scene");
        // The operator stacks each block on the one below, bottom up.
        let placements = teleop_sim::TowerJobConfig::default().placements();
        let names: Vec<(&str, &str)> = placements
            .iter()
            .map(|p| match &p.onto {
                teleop_sim::operator_site::Onto::Object { name, .. } => {
                    (p.object.as_str(), name.as_str())
                }
                teleop_sim::operator_site::Onto::Table { .. } => (p.object.as_str(), "table"),
            })
            .collect();
        assert_eq!(names, [("middle", "base"), ("top", "middle")]);
    }
}
