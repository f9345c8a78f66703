//! `teleop record` and `teleop bag info|recover`: recordings as rosbag2 writes them
//! (a directory of MCAP files and metadata.yaml, `teleop-bag`).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{Context, bail};
use teleop_bag::{BagOptions, BagWriter, Compression, TopicId, mcap_files, read_bag, recover};
use teleop_bus::{Bus, BusConfig, RawPublisher, RawSample};
use teleop_interfaces::{TopicSpec, topics};

/// How many samples may wait for the writer; beyond, new ones are dropped and counted
/// (the bus is never held up by the disk).
const QUEUE: usize = 8192;

#[derive(Debug, Clone, clap::Args)]
pub struct RecordArgs {
    /// Topics to record (default: every topic that crosses between the sites).
    pub topics: Vec<String>,
    /// Every topic of the table, the robot site's hardware topics and camera images
    /// included (on the LAN where they travel).
    #[arg(long, short = 'a', conflicts_with = "topics")]
    pub all: bool,
    /// The bag's directory (must not exist); default `teleop_YYYY_MM_DD-HH_MM_SS`.
    #[arg(long, short = 'o')]
    pub output: Option<PathBuf>,
    /// Chunk compression: zstd, lz4 or none.
    #[arg(long, default_value = "zstd", value_parser = parse_compression)]
    pub compression: Compression,
    /// Start a new file when the current one reaches this size, MB.
    #[arg(long)]
    pub max_file_mb: Option<f64>,
    /// Start a new file when the current one spans this long, s.
    #[arg(long)]
    pub max_file_duration_s: Option<f64>,
    /// Stop after this many seconds (default: at Ctrl-C / SIGTERM).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Receive and count every message as the recording would, write nothing: the
    /// baseline of the recorder's overhead benchmark (`record_bench`).
    #[arg(long, conflicts_with_all = ["output", "max_file_mb", "max_file_duration_s"])]
    pub discard: bool,
}

fn parse_compression(s: &str) -> Result<Compression, String> {
    s.parse().map_err(|e: teleop_bag::BagError| e.to_string())
}

#[derive(Debug, Clone, clap::Args)]
pub struct PlayArgs {
    /// The bag (a directory, or one MCAP file).
    pub path: PathBuf,
    /// Only these topics (default: every topic of the bag that the topic table knows).
    #[arg(long, num_args = 1..)]
    pub topics: Vec<String>,
    /// Speed: 2 plays twice as fast, 0.5 at half speed.
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Start this many seconds into the bag.
    #[arg(long, default_value_t = 0.0)]
    pub start_s: f64,
    /// Stop this many seconds into the bag.
    #[arg(long)]
    pub end_s: Option<f64>,
    /// The node name the replay announces (default `teleop_play_<pid>`).
    #[arg(long, conflicts_with = "as_publishers")]
    pub node_name: Option<String>,
    /// Publish each topic under the name of the node the topic table names as its
    /// publisher (the wrist pose and the pedals as `wrist_tracker`, the finger targets
    /// as `hand_inference`, ...): the robot site follows commands only while those
    /// nodes are alive, so this lets a recorded operator drive it (alone: one
    /// commanding site at a time).
    #[arg(long)]
    pub as_publishers: bool,
    /// Wait this long after declaring the publishers before the first message, s (the
    /// subscribers must hear of them, or the first messages go nowhere).
    #[arg(long, default_value_t = 1.0)]
    pub delay_s: f64,
}

#[derive(Debug, clap::Subcommand)]
pub enum BagCommand {
    /// What a bag (a directory, or one MCAP file) holds: topics, types, counts, rates,
    /// duration; files cut short are named.
    Info { path: PathBuf },
    /// Rewrites a bag's files that were cut short (a crash) as whole files, and its
    /// metadata.yaml from what they hold.
    Recover { path: PathBuf },
}

pub fn bag(cmd: &BagCommand) -> anyhow::Result<()> {
    match cmd {
        BagCommand::Info { path } => {
            let report = read_bag(path)?;
            print!("{report}");
            Ok(())
        }
        BagCommand::Recover { path } => {
            let report = recover(path)?;
            println!(
                "recovered: {} messages in {} file(s)",
                report.messages(),
                report.files.len()
            );
            print!("{report}");
            Ok(())
        }
    }
}

/// The topics a command that taps the bus takes (`teleop record`, `teleop foxglove`):
/// every topic of the table with `all`, the ones named, or by default every topic that
/// crosses between the sites. An unknown name is an error naming it; a topic named
/// twice is taken once.
pub fn chosen_topics(names: &[String], all: bool) -> anyhow::Result<Vec<&'static TopicSpec>> {
    if all {
        return Ok(topics::ALL.iter().collect());
    }
    if names.is_empty() {
        return Ok(topics::ALL
            .iter()
            .filter(|t| t.direction.crosses_sites())
            .collect());
    }
    let mut chosen: Vec<&'static TopicSpec> = Vec::new();
    for name in names {
        let spec = topics::find(name)
            .with_context(|| format!("unknown topic `{name}` (`teleop topics` lists them)"))?;
        if !chosen.iter().any(|c| c.name == spec.name) {
            chosen.push(spec);
        }
    }
    Ok(chosen)
}

/// `teleop_YYYY_MM_DD-HH_MM_SS` (UTC), as rosbag2 names its bags.
fn default_name(unix_s: i64) -> String {
    let days = unix_s.div_euclid(86_400);
    let secs = unix_s.rem_euclid(86_400);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "teleop_{year:04}_{month:02}_{day:02}-{:02}_{:02}_{:02}",
        secs / 3600,
        secs % 3600 / 60,
        secs % 60
    )
}

fn options(args: &RecordArgs) -> anyhow::Result<BagOptions> {
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let max_file_bytes = match args.max_file_mb {
        Some(mb) if mb.is_finite() && mb > 0.0 => Some((mb * 1e6) as u64),
        Some(mb) => bail!("--max-file-mb {mb}: a positive number of MB"),
        None => None,
    };
    let opts = BagOptions {
        compression: args.compression,
        max_file_bytes,
        max_file_duration_s: args.max_file_duration_s,
        ..BagOptions::default()
    };
    opts.validate()?;
    Ok(opts)
}

pub async fn record(args: &RecordArgs, cfg: &BusConfig) -> anyhow::Result<()> {
    let specs = chosen_topics(&args.topics, args.all)?;
    let opts = options(args)?;
    let dir = match &args.output {
        Some(d) => d.clone(),
        None => PathBuf::from(default_name(teleop_msgs::unix_nanos_now() / 1_000_000_000)),
    };
    // With `--discard` the samples take the same way (taps, queue, thread) and end there.
    let writer = if args.discard {
        None
    } else {
        let mut writer = BagWriter::create(&dir, opts)?;
        let ids = specs
            .iter()
            .map(|s| writer.add_topic(s))
            .collect::<Result<Vec<TopicId>, _>>()?;
        Some((writer, ids))
    };

    let bus = Bus::open(&format!("teleop_record_{}", std::process::id()), cfg)
        .await
        .context("opening the Zenoh session")?;
    // Samples travel with their topic's index in `specs`.
    let (tx, rx) = mpsc::sync_channel::<(usize, RawSample)>(QUEUE);
    let dropped = Arc::new(AtomicU64::new(0));
    let counts = Arc::new(Counts::default());
    let writer_thread = {
        let counts = Arc::clone(&counts);
        std::thread::Builder::new()
            .name("bag-writer".into())
            .spawn(move || write_all(writer, &rx, &counts))
            .context("starting the bag writer")?
    };
    let mut taps = Vec::new();
    for (id, spec) in specs.iter().enumerate() {
        let (tx, dropped) = (tx.clone(), Arc::clone(&dropped));
        taps.push(
            bus.tap(spec, move |s| {
                if tx.try_send((id, s)).is_err() {
                    dropped.fetch_add(1, Ordering::Relaxed);
                }
            })
            .await?,
        );
    }
    drop(tx);
    if args.discard {
        eprintln!(
            "receiving {} topic(s), writing nothing (--discard; Ctrl-C stops)",
            specs.len()
        );
    } else {
        eprintln!(
            "recording {} topic(s) into {} (Ctrl-C stops)",
            specs.len(),
            dir.display()
        );
    }
    let stop =
        teleop_node::stop_signal(args.duration_s.map(|s| Duration::from_secs_f64(s.max(0.0))));
    tokio::pin!(stop);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    let mut progress = crate::progress::Progress::stderr();
    let started = std::time::Instant::now();
    loop {
        tokio::select! {
            () = &mut stop => break,
            _ = tick.tick() => progress.show(|| {
                #[allow(clippy::cast_precision_loss)]
                let mb = counts.bytes.load(Ordering::Relaxed) as f64 / 1e6;
                format!(
                    "{} {:.0} s: {} messages, {mb:.1} MB, {} dropped",
                    if args.discard { "receiving" } else { "recording" },
                    started.elapsed().as_secs_f64(),
                    counts.messages.load(Ordering::Relaxed),
                    dropped.load(Ordering::Relaxed),
                )
            }),
        }
    }
    progress.finish();
    // Undeclaring the taps drops their senders: the writer drains what is queued,
    // closes the files and writes metadata.yaml.
    drop(taps);
    let summary = tokio::task::spawn_blocking(move || writer_thread.join())
        .await?
        .map_err(|_| anyhow::anyhow!("the bag writer panicked"))??;
    bus.close().await.ok();
    let lost = dropped.load(Ordering::Relaxed);
    let messages = counts.messages.load(Ordering::Relaxed);
    let bytes = counts.bytes.load(Ordering::Relaxed);
    // One line for people and for `record_bench`, which parses it.
    match &summary {
        Some(s) => eprintln!(
            "recorded {} messages, {lost} dropped, {bytes} bytes received; {} file(s) ({})",
            s.messages,
            s.files.len(),
            format!("{:?}", args.compression).to_lowercase()
        ),
        None => eprintln!(
            "discarded {messages} messages, {lost} dropped, {bytes} bytes received; nothing written"
        ),
    }
    if messages == 0 {
        bail!(
            "nothing was received: no publisher of the chosen topics was heard (is the system \
             running, on this domain and network?)"
        );
    }
    if summary.is_some() {
        print!("{}", read_bag(&dir)?);
    }
    if lost > 0 {
        tracing::warn!(
            dropped = lost,
            "samples dropped: the writer could not keep up"
        );
    }
    Ok(())
}

/// `teleop play`: the bag's messages published again at their recorded pace (times
/// `--rate`), each with a fresh attachment (this replay's GID, its own sequence
/// numbers, the time it is sent), so every receiver's guard takes them as new.
pub async fn play(args: &PlayArgs, cfg: &BusConfig) -> anyhow::Result<()> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate {}: a positive number", args.rate);
    }
    if !(args.start_s.is_finite() && args.start_s >= 0.0) {
        bail!("--start-s {}: zero or more seconds", args.start_s);
    }
    if let Some(end) = args.end_s
        && !(end.is_finite() && end > args.start_s)
    {
        bail!("--end-s {end}: after --start-s ({})", args.start_s);
    }
    let report = read_bag(&args.path)?;
    for f in &report.files {
        if let Some(why) = &f.truncated {
            tracing::warn!(file = %f.path.display(), "cut short ({why}): played up to the cut");
        }
    }
    let first = report.first_ns().context("the bag holds no message")?;
    let in_bag = report.topics();
    let wanted: Vec<String> = if args.topics.is_empty() {
        in_bag.keys().cloned().collect()
    } else {
        args.topics
            .iter()
            .map(|t| format!("/{}", t.trim_start_matches('/')))
            .collect()
    };
    let own_name = args
        .node_name
        .clone()
        .unwrap_or_else(|| format!("teleop_play_{}", std::process::id()));
    // One session per node name the replay speaks as.
    let mut sessions: std::collections::BTreeMap<String, Bus> = std::collections::BTreeMap::new();
    let mut publishers: std::collections::BTreeMap<String, RawPublisher> =
        std::collections::BTreeMap::new();
    for name in &wanted {
        let Some(t) = in_bag.get(name) else {
            bail!(
                "{name} is not in the bag; it holds: {}",
                in_bag.keys().cloned().collect::<Vec<_>>().join(", ")
            );
        };
        let Some(spec) = topics::find(name) else {
            tracing::warn!(topic = %name, "not in the topic table: not played");
            continue;
        };
        if spec.type_name != t.type_name {
            bail!(
                "{name}: the bag holds {}, the topic table says {}",
                t.type_name,
                spec.type_name
            );
        }
        let node = match spec.publishers {
            topics::Publishers::Nodes([first, ..]) if args.as_publishers => (*first).to_owned(),
            _ => own_name.clone(),
        };
        if !sessions.contains_key(&node) {
            let bus = Bus::open(&node, cfg)
                .await
                .with_context(|| format!("opening the Zenoh session as {node}"))?;
            sessions.insert(node.clone(), bus);
        }
        let bus = &sessions[&node];
        publishers.insert(name.clone(), bus.raw_publisher(spec).await?);
    }
    if publishers.is_empty() {
        bail!("nothing to play");
    }
    eprintln!(
        "playing {} topic(s) of {} ({:.1} s) at {}x",
        publishers.len(),
        args.path.display(),
        report.duration_s(),
        args.rate
    );
    tokio::time::sleep(Duration::from_secs_f64(args.delay_s.clamp(0.0, 60.0))).await;
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let (from, to) = (
        first + (args.start_s * 1e9) as u64,
        args.end_s.map_or(u64::MAX, |e| first + (e * 1e9) as u64),
    );
    let start = tokio::time::Instant::now();
    let stop = teleop_node::stop_signal(None);
    tokio::pin!(stop);
    let (mut sent, mut failed) = (0u64, 0u64);
    let mut progress = crate::progress::Progress::stderr();
    'files: for path in mcap_files(&args.path)? {
        let buf = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        let stream =
            teleop_bag::messages(&buf).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        for m in stream {
            let Ok(m) = m else { break };
            if m.log_time < from {
                continue;
            }
            if m.log_time > to {
                break 'files;
            }
            let Some(p) = publishers.get(&m.channel.topic) else {
                continue;
            };
            #[allow(clippy::cast_precision_loss)]
            let due =
                start + Duration::from_secs_f64((m.log_time - from) as f64 * 1e-9 / args.rate);
            tokio::select! {
                () = &mut stop => break 'files,
                () = tokio::time::sleep_until(due) => {}
            }
            match p.put(m.data) {
                Ok(()) => sent += 1,
                Err(e) => {
                    failed += 1;
                    tracing::warn!(topic = %m.channel.topic, "not sent: {e}");
                }
            }
            progress.show(|| {
                #[allow(clippy::cast_precision_loss)]
                let at = (m.log_time - from) as f64 * 1e-9;
                let whole = (report.duration_s() - args.start_s).max(1e-9);
                let whole = args.end_s.map_or(whole, |e| whole.min(e - args.start_s));
                format!(
                    "playing {at:.1} / {whole:.1} s of the bag ({:.0} %): {sent} messages",
                    100.0 * (at / whole).min(1.0)
                )
            });
        }
    }
    progress.finish();
    eprintln!(
        "played {sent} messages in {:.1} s{}",
        start.elapsed().as_secs_f64(),
        if failed > 0 {
            format!(", {failed} not sent")
        } else {
            String::new()
        }
    );
    drop(publishers);
    for (_, bus) in sessions {
        bus.close().await.ok();
    }
    Ok(())
}

/// What the writer thread has taken off the queue: messages, and their CDR bytes.
#[derive(Debug, Default)]
struct Counts {
    messages: AtomicU64,
    bytes: AtomicU64,
}

/// The writer thread: every queued sample into the bag (the topic ids in the order of
/// the queue's indices), then the bag closed; without a bag (`--discard`) every sample
/// counted and dropped.
fn write_all(
    mut writer: Option<(BagWriter, Vec<TopicId>)>,
    rx: &mpsc::Receiver<(usize, RawSample)>,
    counts: &Counts,
) -> Result<Option<teleop_bag::BagSummary>, teleop_bag::BagError> {
    // MCAP's sequence is 32 bits; rmw_zenoh's counts from 1 in 64 (wraps after four
    // billion samples of one publisher).
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let low32 = |s: i64| s as u32;
    while let Ok((id, s)) = rx.recv() {
        if let Some((writer, ids)) = &mut writer {
            let id = ids[id];
            let log = u64::try_from(s.received_ns).unwrap_or(0);
            let (publish, sequence) = match s.attachment {
                Some(a) => (
                    u64::try_from(a.source_timestamp_ns).unwrap_or(log),
                    low32(a.sequence),
                ),
                None => (log, 0),
            };
            writer.write(id, log, publish, sequence, &s.payload)?;
        }
        counts.messages.fetch_add(1, Ordering::Relaxed);
        counts
            .bytes
            .fetch_add(s.payload.len() as u64, Ordering::Relaxed);
    }
    writer.map(|(w, _)| w.close()).transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_names_are_rosbag2_style_dates() {
        assert_eq!(default_name(0), "teleop_1970_01_01-00_00_00");
        // 2026-12-04 21:30:05 UTC
        assert_eq!(default_name(1_796_419_805), "teleop_2026_12_04-21_30_05");
        assert_eq!(default_name(951_782_400), "teleop_2000_02_29-00_00_00");
    }
}
