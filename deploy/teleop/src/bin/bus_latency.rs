//! `bus_latency`: latency of the bus between two processes on loopback, with raw-socket
//! baselines measured in the same run.
//!
//! The driver (this binary without `--role`) opens a listening Zenoh session on
//! `tcp/127.0.0.1:<free port>` (no multicast scouting), binds a UDP socket and a TCP
//! listener on 127.0.0.1, and re-spawns itself (`std::env::current_exe()`) with the hidden
//! `--role echo`. The echo process connects to all three and echoes every ping back at
//! once, each transport on its own thread. The driver then runs, one after the other:
//!
//! 1. `zenoh wrist pose`: `PoseStamped` pings on [`topics::WRIST_POSE`], echoed on a bench
//!    topic with the same QoS (control: express, real-time priority, drop, depth 1).
//! 2. `zenoh raw pose`: diagnostic floor of the transport: the same bytes and attachment
//!    through bare Zenoh publishers (same QoS) on keys outside the rmw_zenoh key space,
//!    echoed inside the echo process's Zenoh callback and timed inside the driver's: no
//!    typed layer, no application thread.
//! 3. `udp wrist pose`: raw UDP datagrams of the same size as (1) on the wire
//!    (CDR-encoded `PoseStamped` + the 33-byte rmw_zenoh attachment).
//! 4. `zenoh depth image`: 640x480 `16UC1` `Image` pings on [`topics::HW_HAND_DEPTH`], echoed on
//!    a bench topic with the same QoS (image: data-low priority, drop, depth 1).
//! 5. `tcp depth image`: the same number of bytes, length-prefixed, over a raw
//!    `TcpStream` (`TCP_NODELAY`). UDP cannot carry a 614 KB datagram (64 KB limit), so
//!    TCP is the raw baseline for images.
//!
//! Every case is stop-and-wait: send ping `k`, wait for its echo (or a timeout, counted as
//! lost), then wait for the next tick. Two latencies per sample:
//!
//! * `RTT/2`: round trip measured by the driver on the monotonic clock, halved.
//! * `one-way`: measured by the echo process as its wall clock when `recv` returns minus
//!   the source timestamp the driver put in the sample (attachment for Zenoh, first bytes
//!   for raw sockets) -- both processes read the same clock. The raw Zenoh case takes it
//!   inside the callback. The typed Zenoh cases also report `callback` (`cb`): the bus's
//!   own receive timestamp, taken in the Zenoh callback before decoding.
//!
//! Pacing: ticks at absolute deadlines `start + k * period`; the driver sleeps until
//! ~100 us before a deadline, then spins on `Instant::now()`. A tick whose deadline has
//! already passed when the driver gets to it fires at once and whole periods missed are
//! skipped (the semantics of tokio's `MissedTickBehavior::Skip`); such ticks are counted.
//!
//! The benchmark's subscribers keep the topics' order check but not their deadline, so a
//! late sample is measured instead of dropped as stale.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Condvar, Mutex, mpsc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::Parser;
use serde::{Deserialize, Serialize};
use teleop_bus::attachment::{ATTACHMENT_LEN, Attachment};
use teleop_bus::{Bus, BusConfig, Publisher, Subscriber, ZenohSettings};
use teleop_interfaces::topics::{self, Topic};
use teleop_msgs::{
    Header, Image, Message, Point, Pose, PoseStamped, Quaternion, Time, unix_nanos_now,
};
use teleop_node::stats::loadavg;
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Priority};

/// Pings of case 1: the real wrist-pose topic.
const POSE_PING: Topic<PoseStamped> = topics::WRIST_POSE;
/// Echoes of case 1: a bench topic with the wrist pose's type and QoS.
const POSE_PONG: Topic<PoseStamped> = topics::WRIST_POSE.renamed(
    "teleop/bench/wrist_pose_echo",
    "benchmark echo of wrist poses",
);
/// Pings of case 3: the real hand depth topic.
const IMAGE_PING: Topic<Image> = topics::HW_HAND_DEPTH;
/// Echoes of case 3: a bench topic with the depth image's type and QoS.
const IMAGE_PONG: Topic<Image> =
    topics::HW_HAND_DEPTH.renamed("teleop/bench/depth_echo", "benchmark echo of depth images");

/// The driver sleeps until this long before a tick, then spins.
const SPIN: Duration = Duration::from_micros(100);
/// Largest length prefix the TCP echo accepts.
const MAX_TCP_MESSAGE: usize = 64 << 20;
/// Bytes at the start of raw-socket payloads: ping index, then source timestamp (ns).
const RAW_HEADER: usize = 16;

/// Latency of the bus between two processes on loopback (Zenoh vs raw UDP/TCP).
#[derive(Debug, Parser)]
#[command(name = "bus_latency", version)]
struct Cli {
    /// Wrist-pose round trips measured per transport [default: 10000; 500 with --quick]
    #[arg(long, value_name = "N")]
    pose_samples: Option<usize>,
    /// Wrist-pose send rate, Hz.
    #[arg(long, value_name = "HZ", default_value_t = 1000.0)]
    pose_rate_hz: f64,
    /// Unmeasured wrist-pose round trips before each pose case [default: 500; 50 with --quick]
    #[arg(long, value_name = "N")]
    pose_warmup: Option<usize>,
    /// Depth frames measured per transport [default: 300; 30 with --quick]
    #[arg(long, value_name = "N")]
    image_frames: Option<usize>,
    /// Depth frame rate, Hz.
    #[arg(long, value_name = "HZ", default_value_t = 30.0)]
    image_rate_hz: f64,
    /// Unmeasured depth frames before each image case [default: 10; 3 with --quick]
    #[arg(long, value_name = "N")]
    image_warmup: Option<usize>,
    /// Depth image width, pixels.
    #[arg(long, default_value_t = 640)]
    image_width: u32,
    /// Depth image height, pixels.
    #[arg(long, default_value_t = 480)]
    image_height: u32,
    /// Skip the depth-image cases (e.g. with Zenoh's lowlatency transport, which cannot
    /// fragment a 614 KB sample).
    #[arg(long)]
    no_images: bool,
    /// Short smoke run (500 poses, 30 frames) unless counts are given explicitly.
    #[arg(long)]
    quick: bool,
    /// Also write the results (with the settings and machine) as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Zenoh JSON5 configuration applied to both sessions before the benchmark's own
    /// settings (endpoints, no multicast scouting), to try transport options such as
    /// `transport/unicast/lowlatency`.
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// Both sessions without Zenoh shared memory (the images go through the socket in
    /// fragments, as between hosts): the baseline of the bus's default.
    #[arg(long)]
    no_shared_memory: bool,
    /// ROS 2 domain id of the benchmark's keys.
    #[arg(long, default_value_t = 142)]
    domain_id: u32,
    /// Internal: the role of this process.
    #[arg(long, hide = true, value_enum)]
    role: Option<Role>,
    /// Internal (echo role): Zenoh endpoint of the driver.
    #[arg(long, hide = true)]
    connect: Option<String>,
    /// Internal (echo role): the driver's UDP socket.
    #[arg(long, hide = true)]
    udp_peer: Option<SocketAddr>,
    /// Internal (echo role): the driver's TCP listener.
    #[arg(long, hide = true)]
    tcp_peer: Option<SocketAddr>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Role {
    Echo,
}

fn main() -> Result<()> {
    teleop_node::init_tracing();
    run(&Cli::parse())
}

fn run(cli: &Cli) -> Result<()> {
    match cli.role {
        Some(Role::Echo) => echo::run(cli),
        None => driver(cli),
    }
}

// ------------------------------------------------------------------------- settings

/// The resolved run settings.
#[derive(Debug, Clone, Serialize)]
struct Settings {
    pose_samples: usize,
    pose_rate_hz: f64,
    pose_warmup: usize,
    image_frames: usize,
    image_rate_hz: f64,
    image_warmup: usize,
    image_width: u32,
    image_height: u32,
    no_images: bool,
    quick: bool,
    zenoh_config: Option<PathBuf>,
    /// Zenoh shared memory between the two processes (the bus's default).
    shared_memory: bool,
    domain_id: u32,
}

impl Settings {
    fn from_cli(cli: &Cli) -> Result<Self> {
        let pick = |v: Option<usize>, full: usize, quick: usize| {
            v.unwrap_or(if cli.quick { quick } else { full })
        };
        let s = Self {
            pose_samples: pick(cli.pose_samples, 10_000, 500),
            pose_rate_hz: cli.pose_rate_hz,
            pose_warmup: pick(cli.pose_warmup, 500, 50),
            image_frames: pick(cli.image_frames, 300, 30),
            image_rate_hz: cli.image_rate_hz,
            image_warmup: pick(cli.image_warmup, 10, 3),
            image_width: cli.image_width,
            image_height: cli.image_height,
            no_images: cli.no_images,
            quick: cli.quick,
            zenoh_config: cli.zenoh_config.clone(),
            shared_memory: !cli.no_shared_memory,
            domain_id: cli.domain_id,
        };
        if s.pose_samples == 0 || s.image_frames == 0 {
            bail!("sample counts must be positive");
        }
        for rate in [s.pose_rate_hz, s.image_rate_hz] {
            if !(rate.is_finite() && rate > 0.0 && rate <= 100_000.0) {
                bail!("rates must be in (0, 100000] Hz, got {rate}");
            }
        }
        if s.image_width == 0 || s.image_height == 0 {
            bail!("image size must be positive");
        }
        Ok(s)
    }
}

fn bus_config(listen: Vec<String>, connect: Vec<String>, cli: &Cli) -> BusConfig {
    BusConfig {
        domain_id: cli.domain_id,
        zenoh: ZenohSettings {
            listen,
            connect,
            multicast_scouting: false,
            config_file: cli.zenoh_config.clone(),
            shared_memory: !cli.no_shared_memory,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn runtime() -> Result<tokio::runtime::Runtime> {
    // Zenoh refuses tokio's current-thread scheduler.
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .context("tokio runtime")
}

/// A subscriber with the topic's order check but no deadline: late samples are measured,
/// not dropped.
async fn bench_subscriber<T: Message>(bus: &Bus, topic: &Topic<T>) -> Result<Subscriber<T>> {
    let mut guard = bus.guard_settings(&topic.spec);
    guard.deadline_ns = None;
    Ok(bus
        .subscriber_with(topic, guard, teleop_bus::SourcePolicy::Any)
        .await?)
}

fn pose_index(m: &PoseStamped) -> i64 {
    m.header.stamp.as_nanos()
}
fn set_pose_index(m: &mut PoseStamped, i: i64) {
    m.header.stamp = Time::from_nanos(i);
}
fn image_index(m: &Image) -> i64 {
    m.header.stamp.as_nanos()
}
fn set_image_index(m: &mut Image, i: i64) {
    m.header.stamp = Time::from_nanos(i);
}

fn ns(d: Duration) -> i64 {
    i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)
}

// ------------------------------------------------------------------------- results

/// Percentiles of one latency series.
#[derive(Debug, Clone, Copy, Default, Serialize)]
struct Summary {
    n: usize,
    p50_us: f64,
    p99_us: f64,
    max_us: f64,
    mean_us: f64,
}

impl Summary {
    /// Nearest-rank percentiles of `samples_ns` (sorted in place).
    fn of(samples_ns: &mut [i64]) -> Self {
        if samples_ns.is_empty() {
            return Self::default();
        }
        samples_ns.sort_unstable();
        let n = samples_ns.len();
        let at = |p: f64| {
            let rank = ((p / 100.0) * n as f64).ceil() as usize;
            samples_ns[rank.clamp(1, n) - 1] as f64 / 1e3
        };
        let sum: f64 = samples_ns.iter().map(|&v| v as f64).sum();
        Self {
            n,
            p50_us: at(50.0),
            p99_us: at(99.0),
            max_us: samples_ns[n - 1] as f64 / 1e3,
            mean_us: sum / n as f64 / 1e3,
        }
    }
}

/// Counters of a bus subscriber.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
struct SubStats {
    received: u64,
    accepted: u64,
    rejected: u64,
    overwritten: u64,
}

impl SubStats {
    fn of<T: Message>(sub: &Subscriber<T>) -> Self {
        let s = sub.stats();
        Self {
            received: s.received,
            accepted: s.accepted,
            rejected: s.rejected(),
            overwritten: s.overwritten,
        }
    }
}

/// What the echo process saw of one case.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct EchoCase {
    /// Measured pings echoed (index >= 0).
    echoed: u64,
    /// Echo failures (send errors).
    errors: u64,
    /// One-way latency per measured ping, ns (wall clock on `recv` return minus source).
    one_way_ns: Vec<i64>,
    /// Zenoh only: the bus callback's receive timestamp minus source, ns.
    callback_ns: Vec<i64>,
    /// Zenoh only: the echo side's ping subscriber counters.
    subscriber: Option<SubStats>,
}

/// The echo process's report, one JSON line on its stdout.
#[derive(Debug, Default, Serialize, Deserialize)]
struct EchoReport {
    zenoh_pose: EchoCase,
    zenoh_raw: EchoCase,
    udp_pose: EchoCase,
    zenoh_image: EchoCase,
    tcp_image: EchoCase,
}

/// What the driver measured of one case.
#[derive(Debug, Default)]
struct DriverCase {
    sent: usize,
    returned: usize,
    lost: usize,
    rtt_half_ns: Vec<i64>,
    pacing: PacingStats,
}

#[derive(Debug, Clone, Copy, Default, Serialize)]
struct PacingStats {
    /// Ticks reached after their deadline (previous round trip overran the period).
    late_ticks: u64,
    /// Whole periods skipped because of late ticks.
    skipped_ticks: u64,
    /// 99th percentile of send time minus deadline, microseconds.
    send_delay_p99_us: f64,
}

/// One row of the result table.
#[derive(Debug, Serialize)]
struct CaseReport {
    name: &'static str,
    transport: &'static str,
    message: String,
    /// Bytes per sample as the application hands them over (payload + attachment).
    payload_bytes: usize,
    rate_hz: f64,
    sent: usize,
    returned: usize,
    lost: usize,
    echoed: u64,
    echo_errors: u64,
    rtt_half: Summary,
    one_way: Summary,
    one_way_callback: Option<Summary>,
    echo_subscriber: Option<SubStats>,
    driver_subscriber: Option<SubStats>,
    pacing: PacingStats,
}

#[derive(Debug, Serialize)]
struct Ratios {
    pose_zenoh_over_udp_rtt_half_p50: f64,
    pose_zenoh_over_udp_one_way_p50: f64,
    /// Zenoh transport floor (echo inside the callback) over UDP.
    pose_zenoh_raw_over_udp_rtt_half_p50: f64,
    image_zenoh_over_tcp_rtt_half_p50: Option<f64>,
    image_zenoh_over_tcp_one_way_p50: Option<f64>,
    pose_goal_max_ratio: f64,
    pose_goal_met: bool,
    image_goal_max_p50_us: f64,
    image_goal_met: Option<bool>,
}

#[derive(Debug, Serialize)]
struct CodecCost {
    image_encode: Summary,
    image_decode: Summary,
    pose_encode: Summary,
    pose_decode: Summary,
}

#[derive(Debug, Serialize)]
struct Machine {
    cpus: usize,
    kernel: String,
    loadavg_start: String,
    loadavg_end: String,
}

#[derive(Debug, Serialize)]
struct Report {
    unix_time_s: u64,
    settings: Settings,
    machine: Machine,
    cases: Vec<CaseReport>,
    ratios: Ratios,
    in_process_codec: CodecCost,
}

// ------------------------------------------------------------------------- pacing

/// Absolute-deadline ticker: sleep, then spin the last [`SPIN`]; missed ticks skipped.
#[derive(Debug)]
struct Pacer {
    period: Duration,
    next: Instant,
    stats: PacingStats,
    delays_ns: Vec<i64>,
}

impl Pacer {
    fn new(rate_hz: f64, ticks: usize) -> Self {
        let period = Duration::from_secs_f64(1.0 / rate_hz);
        Self {
            period,
            next: Instant::now() + period,
            stats: PacingStats::default(),
            delays_ns: Vec::with_capacity(ticks),
        }
    }

    /// Waits for the next tick.
    fn wait(&mut self) {
        let now = Instant::now();
        if now < self.next {
            let left = self.next - now;
            if left > SPIN {
                std::thread::sleep(left - SPIN);
            }
            while Instant::now() < self.next {
                std::hint::spin_loop();
            }
        } else {
            self.stats.late_ticks += 1;
            let missed = (now - self.next).as_nanos() / self.period.as_nanos().max(1);
            let missed = u32::try_from(missed).unwrap_or(u32::MAX);
            self.stats.skipped_ticks += u64::from(missed);
            self.next += self.period * missed;
        }
        self.delays_ns
            .push(ns(Instant::now().saturating_duration_since(self.next)));
        self.next += self.period;
    }

    fn finish(mut self) -> PacingStats {
        self.stats.send_delay_p99_us = Summary::of(&mut self.delays_ns).p99_us;
        self.stats
    }
}

/// Repeats `recv` until it yields `index` (true), nothing within `timeout` (false).
/// Older echoes (after an earlier timeout) are skipped.
fn await_echo(
    mut recv: impl FnMut(Duration) -> Option<i64>,
    index: i64,
    timeout: Duration,
) -> bool {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return false;
        }
        match recv(left) {
            Some(i) if i == index => return true,
            Some(_) => {}
            None => return false,
        }
    }
}

/// Counts and rate of one case.
#[derive(Debug, Clone, Copy)]
struct Plan {
    samples: usize,
    warmup: usize,
    rate_hz: f64,
    timeout: Duration,
}

// ------------------------------------------------------------------------- driver

fn driver(cli: &Cli) -> Result<()> {
    let settings = Settings::from_cli(cli)?;
    let loadavg_start = loadavg();
    let rt = runtime()?;
    let port = teleop_bus::testing::free_port().context("a free port on loopback")?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let cfg = bus_config(vec![endpoint.clone()], Vec::new(), cli);
    let (bus, pose_ping, pose_pong, image_ping, image_pong) = rt.block_on(async {
        let bus = Bus::open("bench_driver", &cfg).await?;
        let pose_ping = bus.publisher(&POSE_PING).await?;
        let pose_pong = bench_subscriber(&bus, &POSE_PONG).await?;
        let image_ping = bus.publisher(&IMAGE_PING).await?;
        let image_pong = bench_subscriber(&bus, &IMAGE_PONG).await?;
        anyhow::Ok((bus, pose_ping, pose_pong, image_ping, image_pong))
    })?;

    let udp = UdpSocket::bind("127.0.0.1:0").context("bind UDP")?;
    let listener = TcpListener::bind("127.0.0.1:0").context("bind TCP")?;
    let mut child = EchoChild::spawn(cli, &endpoint, udp.local_addr()?, listener.local_addr()?)?;
    let ready = child.expect_line("READY ", Duration::from_secs(30))?;
    let echo_udp: SocketAddr = ready
        .trim()
        .parse()
        .with_context(|| format!("echo process sent a bad UDP address `{ready}`"))?;
    udp.connect(echo_udp)?;
    udp.set_read_timeout(Some(Duration::from_millis(50)))?;
    // The echo process connects before it reports ready, so this does not block.
    let (mut tcp, _) = listener.accept().context("accept echo TCP connection")?;
    tcp.set_nodelay(true)?;
    tcp.set_read_timeout(Some(Duration::from_secs(10)))?;
    eprintln!(
        "bus_latency: echo process {} ready; zenoh on {endpoint}",
        child.id()
    );

    let pose_plan = Plan {
        samples: settings.pose_samples,
        warmup: settings.pose_warmup,
        rate_hz: settings.pose_rate_hz,
        timeout: Duration::from_millis(500),
    };
    let image_plan = Plan {
        samples: settings.image_frames,
        warmup: settings.image_warmup,
        rate_hz: settings.image_rate_hz,
        timeout: Duration::from_secs(2),
    };

    let pose = PoseStamped {
        header: Header::new(Time::now(), "tracker"),
        pose: Pose {
            position: Point {
                x: 0.412,
                y: -0.137,
                z: 0.305,
            },
            orientation: Quaternion {
                x: 0.0,
                y: std::f64::consts::FRAC_1_SQRT_2,
                z: 0.0,
                w: std::f64::consts::FRAC_1_SQRT_2,
            },
        },
    };
    let pose_bytes = teleop_msgs::encode(&pose)?.len() + ATTACHMENT_LEN;
    let image = depth_image(settings.image_width, settings.image_height);
    let image_bytes = teleop_msgs::encode(&image)?.len() + ATTACHMENT_LEN;

    eprintln!(
        "bus_latency: zenoh wrist pose: {} samples at {} Hz",
        pose_plan.samples, pose_plan.rate_hz
    );
    let zp = zenoh_case(
        &pose_ping,
        &pose_pong,
        pose.clone(),
        set_pose_index,
        pose_index,
        pose_plan,
    )?;
    eprintln!("bus_latency: zenoh raw (echo in callback)");
    let zr = zenoh_raw_case(
        bus.session(),
        cli.domain_id,
        pose_bytes - ATTACHMENT_LEN,
        pose_plan,
    )?;
    eprintln!("bus_latency: udp wrist pose");
    let up = udp_case(&udp, pose_bytes, pose_plan)?;
    let images = if settings.no_images {
        None
    } else {
        eprintln!(
            "bus_latency: zenoh depth image: {} frames at {} Hz",
            image_plan.samples, image_plan.rate_hz
        );
        let zi = zenoh_case(
            &image_ping,
            &image_pong,
            image.clone(),
            set_image_index,
            image_index,
            image_plan,
        )?;
        eprintln!("bus_latency: tcp depth image");
        let ti = tcp_case(&mut tcp, image_bytes, image_plan)?;
        Some((zi, ti))
    };
    drop(tcp);

    let echo = child.finish()?;
    let driver_pose_sub = SubStats::of(&pose_pong);
    let driver_image_sub = SubStats::of(&image_pong);
    drop((pose_ping, pose_pong, image_ping, image_pong));
    rt.block_on(bus.close())?;

    let in_process_codec = codec_cost(&pose, &image)?;
    let mut cases = vec![
        case_report(
            "zenoh wrist pose",
            "zenoh",
            "geometry_msgs/PoseStamped".into(),
            pose_bytes,
            pose_plan.rate_hz,
            zp,
            echo.zenoh_pose,
            Some(driver_pose_sub),
        ),
        case_report(
            "zenoh raw pose",
            "zenoh",
            "raw bytes (size of PoseStamped, same attachment); echoed inside the Zenoh callback"
                .into(),
            pose_bytes,
            pose_plan.rate_hz,
            zr,
            echo.zenoh_raw,
            None,
        ),
        case_report(
            "udp wrist pose",
            "udp",
            format!("raw bytes (size of PoseStamped + {ATTACHMENT_LEN} B attachment)"),
            pose_bytes,
            pose_plan.rate_hz,
            up,
            echo.udp_pose,
            None,
        ),
    ];
    if let Some((zi, ti)) = images {
        let image_msg = format!(
            "sensor_msgs/Image {}x{} 16UC1",
            settings.image_width, settings.image_height
        );
        cases.push(case_report(
            "zenoh depth image",
            "zenoh",
            image_msg,
            image_bytes,
            image_plan.rate_hz,
            zi,
            echo.zenoh_image,
            Some(driver_image_sub),
        ));
        cases.push(case_report(
            "tcp depth image",
            "tcp",
            format!("raw bytes (size of the Image + {ATTACHMENT_LEN} B attachment)"),
            image_bytes,
            image_plan.rate_hz,
            ti,
            echo.tcp_image,
            None,
        ));
    }
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { f64::NAN };
    let case = |name: &str| cases.iter().find(|c| c.name == name);
    let (Some(zp), Some(zr), Some(up)) = (
        case("zenoh wrist pose"),
        case("zenoh raw pose"),
        case("udp wrist pose"),
    ) else {
        bail!("pose cases missing");
    };
    let pose_ratio = ratio(zp.rtt_half.p50_us, up.rtt_half.p50_us);
    let img = case("zenoh depth image").zip(case("tcp depth image"));
    let ratios = Ratios {
        pose_zenoh_over_udp_rtt_half_p50: pose_ratio,
        pose_zenoh_over_udp_one_way_p50: ratio(zp.one_way.p50_us, up.one_way.p50_us),
        pose_zenoh_raw_over_udp_rtt_half_p50: ratio(zr.rtt_half.p50_us, up.rtt_half.p50_us),
        image_zenoh_over_tcp_rtt_half_p50: img
            .map(|(zi, ti)| ratio(zi.rtt_half.p50_us, ti.rtt_half.p50_us)),
        image_zenoh_over_tcp_one_way_p50: img
            .map(|(zi, ti)| ratio(zi.one_way.p50_us, ti.one_way.p50_us)),
        pose_goal_max_ratio: 2.0,
        pose_goal_met: pose_ratio <= 2.0,
        image_goal_max_p50_us: 1000.0,
        image_goal_met: img
            .map(|(zi, _)| zi.rtt_half.p50_us <= 1000.0 && zi.one_way.p50_us <= 1000.0),
    };
    let report = Report {
        unix_time_s: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0),
        settings,
        machine: Machine {
            cpus: std::thread::available_parallelism().map_or(0, |n| n.get()),
            kernel: std::fs::read_to_string("/proc/sys/kernel/osrelease")
                .map(|s| s.trim().to_owned())
                .unwrap_or_default(),
            loadavg_start,
            loadavg_end: loadavg(),
        },
        cases,
        ratios,
        in_process_codec,
    };
    print_table(&report);
    if let Some(path) = &cli.json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, text + "\n").with_context(|| format!("write {}", path.display()))?;
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn case_report(
    name: &'static str,
    transport: &'static str,
    message: String,
    payload_bytes: usize,
    rate_hz: f64,
    mut d: DriverCase,
    mut e: EchoCase,
    driver_subscriber: Option<SubStats>,
) -> CaseReport {
    CaseReport {
        name,
        transport,
        message,
        payload_bytes,
        rate_hz,
        sent: d.sent,
        returned: d.returned,
        lost: d.lost,
        echoed: e.echoed,
        echo_errors: e.errors,
        rtt_half: Summary::of(&mut d.rtt_half_ns),
        one_way: Summary::of(&mut e.one_way_ns),
        one_way_callback: (!e.callback_ns.is_empty()).then(|| Summary::of(&mut e.callback_ns)),
        echo_subscriber: e.subscriber,
        driver_subscriber,
        pacing: d.pacing,
    }
}

/// A synthetic depth image: a tilted plane with a "hand" blob nearer the camera.
fn depth_image(width: u32, height: u32) -> Image {
    let mut depth = Vec::with_capacity(width as usize * height as usize);
    let (cx, cy) = (f64::from(width) / 2.0, f64::from(height) / 2.0);
    for v in 0..height {
        for u in 0..width {
            let (du, dv) = (f64::from(u) - cx, f64::from(v) - cy);
            let hand = du * du + dv * dv < (f64::from(height) / 4.0).powi(2);
            let mm = if hand {
                450.0 + 0.05 * du
            } else {
                900.0 + 0.3 * f64::from(v)
            };
            depth.push(mm as u16);
        }
    }
    Image::depth_mm(
        Header::new(Time::now(), "hand_depth_optical_frame"),
        width,
        height,
        &depth,
    )
}

/// Pings until the first echo comes back: Zenoh discovery takes a moment.
fn zenoh_connect<T: Message>(
    ping: &Publisher<T>,
    pong: &Subscriber<T>,
    msg: &mut T,
    set_index: fn(&mut T, i64),
    index_of: fn(&T) -> i64,
) -> Result<()> {
    let start = Instant::now();
    let mut k: i64 = 0;
    while start.elapsed() < Duration::from_secs(20) {
        let index = -1_000_000 - k;
        k += 1;
        set_index(msg, index);
        ping.put(msg)?;
        if await_echo(
            |left| pong.recv_blocking(left).map(|r| index_of(&r.msg)),
            index,
            Duration::from_millis(50),
        ) {
            return Ok(());
        }
    }
    bail!("no echo on {} within 20 s", pong.spec().name)
}

fn zenoh_case<T: Message>(
    ping: &Publisher<T>,
    pong: &Subscriber<T>,
    mut msg: T,
    set_index: fn(&mut T, i64),
    index_of: fn(&T) -> i64,
    plan: Plan,
) -> Result<DriverCase> {
    zenoh_connect(ping, pong, &mut msg, set_index, index_of)?;
    let mut out = DriverCase {
        rtt_half_ns: Vec::with_capacity(plan.samples),
        ..Default::default()
    };
    let mut pacer = Pacer::new(plan.rate_hz, plan.warmup + plan.samples);
    for k in 0..plan.warmup + plan.samples {
        let index = k as i64 - plan.warmup as i64;
        set_index(&mut msg, index);
        pacer.wait();
        let t0 = Instant::now();
        ping.put(&msg)?;
        let ok = await_echo(
            |left| pong.recv_blocking(left).map(|r| index_of(&r.msg)),
            index,
            plan.timeout,
        );
        let rtt = t0.elapsed();
        if index >= 0 {
            out.sent += 1;
            if ok {
                out.returned += 1;
                out.rtt_half_ns.push(ns(rtt) / 2);
            } else {
                out.lost += 1;
            }
        }
    }
    out.pacing = pacer.finish();
    Ok(out)
}

/// Keys of the raw Zenoh case (outside the rmw_zenoh key space of the typed topics).
fn raw_keys(domain_id: u32) -> (String, String) {
    (
        format!("{domain_id}/teleop_bench/raw_ping"),
        format!("{domain_id}/teleop_bench/raw_pong"),
    )
}

/// A raw publisher with the control topics' QoS.
fn raw_publisher(
    session: &zenoh::Session,
    key: String,
) -> Result<zenoh::pubsub::Publisher<'static>> {
    session
        .declare_publisher(key)
        .congestion_control(CongestionControl::Drop)
        .priority(Priority::RealTime)
        .express(true)
        .wait()
        .map_err(|e| anyhow::anyhow!("declare raw publisher: {e}"))
}

/// Driver side of the raw case: the echo's arrival is timed inside the callback.
#[derive(Debug)]
struct RawState {
    base: Instant,
    /// Send time of the current ping, ns since `base`.
    t0_ns: AtomicI64,
    /// (index, round trip ns) of the last echo.
    slot: Mutex<Option<(i64, i64)>>,
    cv: Condvar,
}

impl RawState {
    fn wait(&self, index: i64, timeout: Duration) -> Option<i64> {
        let deadline = Instant::now() + timeout;
        let mut slot = self.slot.lock().ok()?;
        loop {
            if let Some((i, rtt)) = slot.take()
                && i == index
            {
                return Some(rtt);
            }
            let left = deadline.checked_duration_since(Instant::now())?;
            slot = self.cv.wait_timeout(slot, left).ok()?.0;
        }
    }
}

/// Zenoh without the typed layer: raw bytes of the pose's size with the same attachment,
/// echoed by the other process inside its subscriber callback, timed by the driver inside
/// its callback. No application thread wakes up on either side: the transport's floor.
fn zenoh_raw_case(
    session: &zenoh::Session,
    domain_id: u32,
    size: usize,
    plan: Plan,
) -> Result<DriverCase> {
    let (ping_key, pong_key) = raw_keys(domain_id);
    let publisher = raw_publisher(session, ping_key)?;
    let state = Arc::new(RawState {
        base: Instant::now(),
        t0_ns: AtomicI64::new(0),
        slot: Mutex::new(None),
        cv: Condvar::new(),
    });
    let cb = Arc::clone(&state);
    let _sub = session
        .declare_subscriber(pong_key)
        .callback(move |sample: zenoh::sample::Sample| {
            let rtt = ns(cb.base.elapsed()) - cb.t0_ns.load(Ordering::Acquire);
            if let Some(index) = raw_index(&sample.payload().to_bytes()) {
                if let Ok(mut slot) = cb.slot.lock() {
                    *slot = Some((index, rtt));
                }
                cb.cv.notify_all();
            }
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("declare raw subscriber: {e}"))?;
    let mut gid = [0_u8; 16];
    gid[0] = 0xbe;
    let mut buf = vec![0x5a_u8; size.max(RAW_HEADER)];
    let mut sequence = 0;
    let mut send = |index: i64| -> Result<()> {
        sequence += 1;
        raw_header(&mut buf, index);
        let att = Attachment {
            sequence,
            source_timestamp_ns: unix_nanos_now(),
            gid,
        };
        if let Ok(mut slot) = state.slot.lock() {
            *slot = None;
        }
        state
            .t0_ns
            .store(ns(state.base.elapsed()), Ordering::Release);
        publisher
            .put(buf.clone())
            .attachment(att.to_bytes().to_vec())
            .wait()
            .map_err(|e| anyhow::anyhow!("raw put: {e}"))
    };
    let start = Instant::now();
    let mut connected = false;
    while !connected {
        if start.elapsed() > Duration::from_secs(20) {
            bail!("no raw Zenoh echo within 20 s");
        }
        send(-1_000_000)?;
        connected = state.wait(-1_000_000, Duration::from_millis(50)).is_some();
    }
    let mut out = DriverCase {
        rtt_half_ns: Vec::with_capacity(plan.samples),
        ..Default::default()
    };
    let mut pacer = Pacer::new(plan.rate_hz, plan.warmup + plan.samples);
    for k in 0..plan.warmup + plan.samples {
        let index = k as i64 - plan.warmup as i64;
        pacer.wait();
        send(index)?;
        let rtt = state.wait(index, plan.timeout);
        if index >= 0 {
            out.sent += 1;
            match rtt {
                Some(rtt) => {
                    out.returned += 1;
                    out.rtt_half_ns.push(rtt / 2);
                }
                None => out.lost += 1,
            }
        }
    }
    out.pacing = pacer.finish();
    Ok(out)
}

fn raw_header(buf: &mut [u8], index: i64) {
    buf[..8].copy_from_slice(&index.to_le_bytes());
    buf[8..16].copy_from_slice(&unix_nanos_now().to_le_bytes());
}

fn raw_index(buf: &[u8]) -> Option<i64> {
    Some(i64::from_le_bytes(buf.get(..8)?.try_into().ok()?))
}

fn udp_case(udp: &UdpSocket, size: usize, plan: Plan) -> Result<DriverCase> {
    let mut buf = vec![0x5a_u8; size.max(RAW_HEADER)];
    let mut rx = vec![0_u8; 65_536];
    let mut out = DriverCase {
        rtt_half_ns: Vec::with_capacity(plan.samples),
        ..Default::default()
    };
    // Connect: the echo thread is up once it answers.
    let start = Instant::now();
    let mut connected = false;
    while !connected && start.elapsed() < Duration::from_secs(10) {
        raw_header(&mut buf, -1_000_000);
        udp.send(&buf)?;
        connected = await_echo(
            |_| udp.recv(&mut rx).ok().and_then(|n| raw_index(&rx[..n])),
            -1_000_000,
            Duration::from_millis(50),
        );
    }
    if !connected {
        bail!("no UDP echo within 10 s");
    }
    let mut pacer = Pacer::new(plan.rate_hz, plan.warmup + plan.samples);
    for k in 0..plan.warmup + plan.samples {
        let index = k as i64 - plan.warmup as i64;
        pacer.wait();
        let t0 = Instant::now();
        raw_header(&mut buf, index);
        udp.send(&buf)?;
        let ok = await_echo(
            |_| udp.recv(&mut rx).ok().and_then(|n| raw_index(&rx[..n])),
            index,
            plan.timeout,
        );
        let rtt = t0.elapsed();
        if index >= 0 {
            out.sent += 1;
            if ok {
                out.returned += 1;
                out.rtt_half_ns.push(ns(rtt) / 2);
            } else {
                out.lost += 1;
            }
        }
    }
    out.pacing = pacer.finish();
    Ok(out)
}

fn tcp_case(tcp: &mut TcpStream, size: usize, plan: Plan) -> Result<DriverCase> {
    let size = size.max(RAW_HEADER);
    let len = u32::try_from(size).context("TCP message too large")?;
    // One buffer with the length prefix, written in one call.
    let mut buf = vec![0_u8; 4 + size];
    buf[..4].copy_from_slice(&len.to_le_bytes());
    for (i, b) in buf[4 + RAW_HEADER..].iter_mut().enumerate() {
        *b = (i % 251) as u8;
    }
    let mut rx = vec![0_u8; 4 + size];
    let mut out = DriverCase {
        rtt_half_ns: Vec::with_capacity(plan.samples),
        ..Default::default()
    };
    let mut pacer = Pacer::new(plan.rate_hz, plan.warmup + plan.samples);
    for k in 0..plan.warmup + plan.samples {
        let index = k as i64 - plan.warmup as i64;
        pacer.wait();
        let t0 = Instant::now();
        raw_header(&mut buf[4..], index);
        tcp.write_all(&buf).context("TCP send")?;
        tcp.read_exact(&mut rx).context("TCP echo")?;
        let rtt = t0.elapsed();
        if rx[..4] != buf[..4] || raw_index(&rx[4..]) != Some(index) {
            bail!("TCP echo of frame {index} is corrupt");
        }
        if index >= 0 {
            out.sent += 1;
            out.returned += 1;
            out.rtt_half_ns.push(ns(rtt) / 2);
        }
    }
    out.pacing = pacer.finish();
    Ok(out)
}

/// In-process CDR cost, to attribute part of the Zenoh latency to serialization.
fn codec_cost(pose: &PoseStamped, image: &Image) -> Result<CodecCost> {
    fn time<R>(n: usize, mut f: impl FnMut() -> Result<R>) -> Result<Summary> {
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            let t = Instant::now();
            std::hint::black_box(f()?);
            v.push(ns(t.elapsed()));
        }
        Ok(Summary::of(&mut v))
    }
    let image_bytes = teleop_msgs::encode(image)?;
    let pose_bytes = teleop_msgs::encode(pose)?;
    Ok(CodecCost {
        image_encode: time(100, || Ok(teleop_msgs::encode(image)?))?,
        image_decode: time(100, || Ok(teleop_msgs::decode::<Image>(&image_bytes)?))?,
        pose_encode: time(10_000, || Ok(teleop_msgs::encode(pose)?))?,
        pose_decode: time(10_000, || {
            Ok(teleop_msgs::decode::<PoseStamped>(&pose_bytes)?)
        })?,
    })
}

fn print_table(r: &Report) {
    let s = &r.settings;
    println!();
    println!(
        "bus_latency: 2 processes on 127.0.0.1; zenoh peer-to-peer over TCP vs raw sockets (stop-and-wait ping-pong)"
    );
    println!(
        "machine: {} CPUs, kernel {}, load {} -> {}; {} pose samples @ {} Hz, {} depth frames @ {} Hz, zenoh shared memory {}{}",
        r.machine.cpus,
        r.machine.kernel,
        r.machine.loadavg_start,
        r.machine.loadavg_end,
        s.pose_samples,
        s.pose_rate_hz,
        s.image_frames,
        s.image_rate_hz,
        if s.shared_memory { "on" } else { "off" },
        s.zenoh_config
            .as_ref()
            .map(|p| format!(", zenoh config {}", p.display()))
            .unwrap_or_default()
    );
    println!();
    println!(
        "{:<18} {:>8} {:>6} {:>6} {:>5} | {:>9} {:>9} {:>9} | {:>9} {:>9} {:>9} | {:>9}",
        "case",
        "bytes",
        "sent",
        "back",
        "lost",
        "RTT/2 p50",
        "p99",
        "max",
        "1-way p50",
        "p99",
        "max",
        "cb p50"
    );
    for c in &r.cases {
        println!(
            "{:<18} {:>8} {:>6} {:>6} {:>5} | {:>9.1} {:>9.1} {:>9.1} | {:>9.1} {:>9.1} {:>9.1} | {:>9}",
            c.name,
            c.payload_bytes,
            c.sent,
            c.returned,
            c.lost,
            c.rtt_half.p50_us,
            c.rtt_half.p99_us,
            c.rtt_half.max_us,
            c.one_way.p50_us,
            c.one_way.p99_us,
            c.one_way.max_us,
            c.one_way_callback
                .map_or_else(|| "-".to_owned(), |cb| format!("{:.1}", cb.p50_us))
        );
    }
    println!(
        "(microseconds; RTT/2 from the driver's monotonic clock, 1-way = echo's wall clock at recv return - source timestamp,"
    );
    println!("  cb = bus callback receive timestamp - source timestamp, before decoding)");
    println!();
    let q = &r.ratios;
    let verdict = |met: bool| if met { "met" } else { "NOT met" };
    println!(
        "ratio zenoh/udp  wrist pose  p50: RTT/2 {:.2}x, one-way {:.2}x   (goal <= {:.0}x on RTT/2: {})",
        q.pose_zenoh_over_udp_rtt_half_p50,
        q.pose_zenoh_over_udp_one_way_p50,
        q.pose_goal_max_ratio,
        verdict(q.pose_goal_met)
    );
    println!(
        "ratio zenoh raw (callback echo, no teleop-bus layer)/udp wrist pose p50: RTT/2 {:.2}x",
        q.pose_zenoh_raw_over_udp_rtt_half_p50
    );
    if let (Some(zi), Some(rtt), Some(one_way), Some(met)) = (
        r.cases.iter().find(|c| c.name == "zenoh depth image"),
        q.image_zenoh_over_tcp_rtt_half_p50,
        q.image_zenoh_over_tcp_one_way_p50,
        q.image_goal_met,
    ) {
        println!(
            "ratio zenoh/tcp  depth image p50: RTT/2 {rtt:.2}x, one-way {one_way:.2}x   (goal zenoh p50 <= 1 ms: RTT/2 {:.0} us, one-way {:.0} us: {})",
            zi.rtt_half.p50_us,
            zi.one_way.p50_us,
            verdict(met)
        );
        println!(
            "  (raw UDP cannot carry a 614 KB frame in one datagram; TCP is the image baseline)"
        );
    }
    let c = &r.in_process_codec;
    println!(
        "in-process CDR p50: depth image encode {:.0} us, decode {:.0} us; pose encode {:.2} us, decode {:.2} us",
        c.image_encode.p50_us, c.image_decode.p50_us, c.pose_encode.p50_us, c.pose_decode.p50_us
    );
    for c in &r.cases {
        let subs = [("echo", c.echo_subscriber), ("driver", c.driver_subscriber)]
            .iter()
            .filter_map(|(who, s)| {
                s.map(|s| {
                    format!(
                        " {who} sub: received {} accepted {} rejected {} overwritten {};",
                        s.received, s.accepted, s.rejected, s.overwritten
                    )
                })
            })
            .collect::<String>();
        println!(
            "{:<18} echoed {} errors {}; pacing: late ticks {} skipped {} send delay p99 {:.1} us;{}",
            c.name,
            c.echoed,
            c.echo_errors,
            c.pacing.late_ticks,
            c.pacing.skipped_ticks,
            c.pacing.send_delay_p99_us,
            subs
        );
    }
}

// ------------------------------------------------------------------------- child

/// The echo process, killed if the driver fails before [`EchoChild::finish`].
#[derive(Debug)]
struct EchoChild {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<String>,
    finished: bool,
}

impl EchoChild {
    fn spawn(cli: &Cli, endpoint: &str, udp: SocketAddr, tcp: SocketAddr) -> Result<Self> {
        let exe = std::env::current_exe().context("locate own executable")?;
        let mut cmd = Command::new(exe);
        cmd.args(["--role", "echo", "--connect", endpoint])
            .args([
                "--udp-peer",
                &udp.to_string(),
                "--tcp-peer",
                &tcp.to_string(),
            ])
            .args(["--domain-id", &cli.domain_id.to_string()]);
        if let Some(p) = &cli.zenoh_config {
            cmd.arg("--zenoh-config").arg(p);
        }
        if cli.no_shared_memory {
            cmd.arg("--no-shared-memory");
        }
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .context("spawn echo process")?;
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().context("echo stdout")?;
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Ok(Self {
            child,
            stdin,
            lines,
            finished: false,
        })
    }

    fn id(&self) -> u32 {
        self.child.id()
    }

    /// The rest of the next line starting with `prefix`.
    fn expect_line(&mut self, prefix: &str, timeout: Duration) -> Result<String> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    if let Some(rest) = line.strip_prefix(prefix) {
                        return Ok(rest.to_owned());
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    bail!("echo process: no `{prefix}` line within {timeout:?}")
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let status = self.child.wait().ok();
                    bail!("echo process ended before `{prefix}` ({status:?})")
                }
            }
        }
    }

    /// Closes the echo's stdin (its signal to stop), reads its report, waits for it.
    fn finish(&mut self) -> Result<EchoReport> {
        drop(self.stdin.take());
        let line = self.expect_line("RESULT ", Duration::from_secs(30))?;
        let report = serde_json::from_str(&line).context("parse echo report")?;
        let status = self.child.wait()?;
        self.finished = true;
        if !status.success() {
            bail!("echo process failed: {status}");
        }
        Ok(report)
    }
}

impl Drop for EchoChild {
    fn drop(&mut self) {
        if !self.finished {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

mod echo {
    //! The echo role: answers every ping at once and records one-way latencies.

    use super::*;

    pub(super) fn run(cli: &Cli) -> Result<()> {
        let connect = cli.connect.clone().context("--connect is required")?;
        let udp_peer = cli.udp_peer.context("--udp-peer is required")?;
        let tcp_peer = cli.tcp_peer.context("--tcp-peer is required")?;
        let rt = runtime()?;
        let cfg = bus_config(Vec::new(), vec![connect], cli);
        let (bus, pose_sub, pose_pub, image_sub, image_pub) = rt.block_on(async {
            let bus = Bus::open("bench_echo", &cfg).await?;
            let pose_sub = bench_subscriber(&bus, &POSE_PING).await?;
            let pose_pub = bus.publisher(&POSE_PONG).await?;
            let image_sub = bench_subscriber(&bus, &IMAGE_PING).await?;
            let image_pub = bus.publisher(&IMAGE_PONG).await?;
            anyhow::Ok((bus, pose_sub, pose_pub, image_sub, image_pub))
        })?;
        let udp = UdpSocket::bind("127.0.0.1:0").context("bind UDP")?;
        udp.connect(udp_peer)?;
        udp.set_read_timeout(Some(Duration::from_millis(100)))?;
        let udp_addr = udp.local_addr()?;
        let tcp = TcpStream::connect(tcp_peer).context("connect TCP")?;
        tcp.set_nodelay(true)?;

        let stop = Arc::new(AtomicBool::new(false));
        let zenoh_pose = zenoh_echo(pose_sub, pose_pub, pose_index, Arc::clone(&stop));
        let (raw_sub, zenoh_raw) = zenoh_raw_echo(bus.session(), cli.domain_id)?;
        let zenoh_image = zenoh_echo(image_sub, image_pub, image_index, Arc::clone(&stop));
        let udp_pose = udp_echo(udp, Arc::clone(&stop));
        let tcp_image = tcp_echo(tcp);

        let mut out = std::io::stdout().lock();
        writeln!(out, "READY {udp_addr}")?;
        out.flush()?;
        // The driver closes our stdin when it is done.
        std::io::copy(&mut std::io::stdin().lock(), &mut std::io::sink())?;
        stop.store(true, Ordering::Relaxed);
        let join = |h: JoinHandle<EchoCase>| h.join().unwrap_or_default();
        let report = EchoReport {
            zenoh_pose: join(zenoh_pose),
            zenoh_raw: {
                drop(raw_sub);
                zenoh_raw
                    .lock()
                    .map(|mut c| std::mem::take(&mut *c))
                    .unwrap_or_default()
            },
            udp_pose: join(udp_pose),
            zenoh_image: join(zenoh_image),
            tcp_image: join(tcp_image),
        };
        writeln!(out, "RESULT {}", serde_json::to_string(&report)?)?;
        out.flush()?;
        rt.block_on(bus.close())?;
        Ok(())
    }

    fn zenoh_echo<T: Message>(
        sub: Subscriber<T>,
        publisher: Publisher<T>,
        index_of: fn(&T) -> i64,
        stop: Arc<AtomicBool>,
    ) -> JoinHandle<EchoCase> {
        std::thread::spawn(move || {
            let mut out = EchoCase::default();
            while !stop.load(Ordering::Relaxed) {
                let Some(r) = sub.recv_blocking(Duration::from_millis(100)) else {
                    continue;
                };
                let now = unix_nanos_now();
                if publisher.put(&r.msg).is_err() {
                    out.errors += 1;
                }
                if index_of(&r.msg) >= 0 {
                    out.echoed += 1;
                    out.one_way_ns.push(now - r.source_timestamp_ns);
                    out.callback_ns.push(r.latency_ns());
                }
            }
            out.subscriber = Some(SubStats::of(&sub));
            out
        })
    }

    /// Echoes raw pings inside the Zenoh callback.
    fn zenoh_raw_echo(
        session: &zenoh::Session,
        domain_id: u32,
    ) -> Result<(zenoh::pubsub::Subscriber<()>, Arc<Mutex<EchoCase>>)> {
        let (ping_key, pong_key) = raw_keys(domain_id);
        let publisher = raw_publisher(session, pong_key)?;
        let record = Arc::new(Mutex::new(EchoCase::default()));
        let rec = Arc::clone(&record);
        let sub = session
            .declare_subscriber(ping_key)
            .callback(move |sample: zenoh::sample::Sample| {
                let now = unix_nanos_now();
                let mut put = publisher.put(sample.payload().clone());
                if let Some(att) = sample.attachment() {
                    put = put.attachment(att.clone());
                }
                let ok = put.wait().is_ok();
                let bytes = sample.payload().to_bytes();
                let Ok(mut rec) = rec.lock() else { return };
                if !ok {
                    rec.errors += 1;
                }
                if let (Some(index), Some(ts)) =
                    (raw_index(&bytes), bytes.get(8..).and_then(raw_index))
                    && index >= 0
                {
                    rec.echoed += 1;
                    rec.one_way_ns.push(now - ts);
                }
            })
            .wait()
            .map_err(|e| anyhow::anyhow!("declare raw subscriber: {e}"))?;
        Ok((sub, record))
    }

    fn udp_echo(udp: UdpSocket, stop: Arc<AtomicBool>) -> JoinHandle<EchoCase> {
        std::thread::spawn(move || {
            let mut out = EchoCase::default();
            let mut buf = vec![0_u8; 65_536];
            while !stop.load(Ordering::Relaxed) {
                let Ok(n) = udp.recv(&mut buf) else { continue };
                let now = unix_nanos_now();
                if udp.send(&buf[..n]).is_err() {
                    out.errors += 1;
                }
                if let (Some(index), Some(ts)) = (raw_index(&buf[..n]), raw_index(&buf[8..n]))
                    && index >= 0
                {
                    out.echoed += 1;
                    out.one_way_ns.push(now - ts);
                }
            }
            out
        })
    }

    /// Echoes length-prefixed messages until the driver closes the connection.
    fn tcp_echo(mut tcp: TcpStream) -> JoinHandle<EchoCase> {
        std::thread::spawn(move || {
            let mut out = EchoCase::default();
            let mut buf = Vec::new();
            loop {
                let mut len = [0_u8; 4];
                if tcp.read_exact(&mut len).is_err() {
                    break;
                }
                let n = u32::from_le_bytes(len) as usize;
                if !(RAW_HEADER..=MAX_TCP_MESSAGE).contains(&n) {
                    out.errors += 1;
                    break;
                }
                buf.resize(4 + n, 0);
                buf[..4].copy_from_slice(&len);
                if tcp.read_exact(&mut buf[4..]).is_err() {
                    out.errors += 1;
                    break;
                }
                let now = unix_nanos_now();
                if tcp.write_all(&buf).is_err() {
                    out.errors += 1;
                    break;
                }
                if let (Some(index), Some(ts)) = (raw_index(&buf[4..]), raw_index(&buf[12..]))
                    && index >= 0
                {
                    out.echoed += 1;
                    out.one_way_ns.push(now - ts);
                }
            }
            out
        })
    }
}
