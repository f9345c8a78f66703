//! `teleop topic ...`, `teleop node ...`, `teleop monitor`.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use teleop_bus::guard::GuardSettings;
use teleop_bus::keys::{EntityKind, GraphEntity};
use teleop_bus::{Bus, BusConfig, SourcePolicy, StatsSnapshot, Subscriber};
use teleop_interfaces::topics::{self, Topic, TopicSpec};
use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, Image, JointCommand, JointState, Message,
    NodeStatus, OperatorInput, PoseStamped, TFMessage,
};

/// Output format of `topic echo`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    Yaml,
    Json,
}

async fn open(cfg: &BusConfig) -> anyhow::Result<Bus> {
    let name = format!("teleop_cli_{}", std::process::id());
    Bus::open(&name, cfg)
        .await
        .context("opening the Zenoh session")
}

fn spec_or_bail(name: &str) -> anyhow::Result<&'static TopicSpec> {
    topics::find(name).with_context(|| {
        let known: Vec<String> = topics::ALL.iter().map(|t| format!("/{}", t.name)).collect();
        format!("unknown topic `{name}`; known topics: {}", known.join(", "))
    })
}

/// Calls `$f::<T>($args)` with `T` the message type of `$spec`.
macro_rules! dispatch {
    ($spec:expr, $f:ident ( $($args:expr),* )) => {{
        let spec: &TopicSpec = $spec;
        match spec.type_name {
            t if t == PoseStamped::TYPE_NAME => $f::<PoseStamped>($($args),*).await,
            t if t == JointState::TYPE_NAME => $f::<JointState>($($args),*).await,
            t if t == OperatorInput::TYPE_NAME => $f::<OperatorInput>($($args),*).await,
            t if t == FingertipPressures::TYPE_NAME => $f::<FingertipPressures>($($args),*).await,
            t if t == Image::TYPE_NAME => $f::<Image>($($args),*).await,
            t if t == CompressedImage::TYPE_NAME => $f::<CompressedImage>($($args),*).await,
            t if t == JointCommand::TYPE_NAME => $f::<JointCommand>($($args),*).await,
            t if t == NodeStatus::TYPE_NAME => $f::<NodeStatus>($($args),*).await,
            t if t == Header::TYPE_NAME => $f::<Header>($($args),*).await,
            t if t == TFMessage::TYPE_NAME => $f::<TFMessage>($($args),*).await,
            other => bail!("no decoder for type {other}"),
        }
    }};
}

pub fn print_table(markdown: bool) {
    if markdown {
        print!("{}", topics::markdown_table());
        return;
    }
    println!(
        "{:<36} {:<36} {:<16} {:>8} {:<12} {:>9}",
        "TOPIC", "TYPE", "DIRECTION", "RATE", "QOS", "DEADLINE"
    );
    for t in topics::ALL {
        let deadline = t.deadline_ms.map_or("-".into(), |d| format!("{d} ms"));
        println!(
            "{:<36} {:<36} {:<16} {:>5} Hz {:<12} {:>9}",
            format!("/{}", t.name),
            t.type_name,
            t.direction.label(),
            t.rate_hz,
            t.qos.label(),
            deadline
        );
    }
}

async fn graph(cfg: &BusConfig, wait_s: f64) -> anyhow::Result<(Bus, Vec<GraphEntity>)> {
    let bus = open(cfg).await?;
    let wait = Duration::from_secs_f64(wait_s.clamp(0.05, 60.0));
    // Give scouting a moment to find peers before asking.
    tokio::time::sleep(wait / 2).await;
    let g = bus.graph(wait).await?;
    Ok((bus, g))
}

pub async fn topic_list(cfg: &BusConfig, wait_s: f64) -> anyhow::Result<()> {
    let (bus, g) = graph(cfg, wait_s).await?;
    let mut by_topic: BTreeMap<String, (String, Vec<String>, Vec<String>)> = BTreeMap::new();
    for e in g.iter().filter(|e| e.node_name != bus.node_name()) {
        let Some(topic) = &e.topic else { continue };
        let entry = by_topic.entry(topic.clone()).or_insert_with(|| {
            (
                e.ros_type_name().unwrap_or_default(),
                Vec::new(),
                Vec::new(),
            )
        });
        match e.kind {
            EntityKind::Publisher => entry.1.push(e.node_name.clone()),
            EntityKind::Subscriber => entry.2.push(e.node_name.clone()),
            EntityKind::Node => {}
        }
    }
    if by_topic.is_empty() {
        println!(
            "no live topics (is anything running on domain {}?)",
            bus.domain_id()
        );
    } else {
        println!(
            "{:<36} {:<36} {:<28} SUBSCRIBERS",
            "TOPIC", "TYPE", "PUBLISHERS"
        );
        for (topic, (ty, pubs, subs)) in by_topic {
            println!(
                "{topic:<36} {ty:<36} {:<28} {}",
                pubs.join(","),
                subs.join(",")
            );
        }
    }
    bus.close().await?;
    Ok(())
}

pub async fn node_list(cfg: &BusConfig, wait_s: f64) -> anyhow::Result<()> {
    let (bus, g) = graph(cfg, wait_s).await?;
    // By name and Zenoh id: two sessions announcing one name (a node whose hardware
    // topics have their own session, or an impostor) are two lines.
    let mut nodes: BTreeMap<(String, String), (Vec<String>, Vec<String>)> = BTreeMap::new();
    for e in g.iter().filter(|e| e.node_name != bus.node_name()) {
        let entry = nodes.entry((e.fq_node_name(), e.zid.clone())).or_default();
        match (&e.kind, &e.topic) {
            (EntityKind::Publisher, Some(t)) => entry.0.push(t.clone()),
            (EntityKind::Subscriber, Some(t)) => entry.1.push(t.clone()),
            _ => {}
        }
    }
    if nodes.is_empty() {
        println!(
            "no live nodes (is anything running on domain {}?)",
            bus.domain_id()
        );
    } else {
        println!(
            "{:<28} {:<34} {:>4} {:>4}",
            "NODE", "ZENOH ID", "PUBS", "SUBS"
        );
        for ((name, zid), (pubs, subs)) in &nodes {
            println!("{name:<28} {zid:<34} {:>4} {:>4}", pubs.len(), subs.len());
            for p in pubs {
                println!("    publishes  {p}");
            }
            for s in subs {
                println!("    subscribes {s}");
            }
        }
    }
    bus.close().await?;
    Ok(())
}

/// `teleop query`.
#[derive(Debug, clap::Args)]
pub struct QueryArgs {
    /// The key expression (a selector: parameters after `?` are passed on).
    pub key_expr: String,
    /// How long to wait for replies, seconds.
    #[arg(long, default_value_t = 2.0)]
    pub timeout_s: f64,
    /// Print at most this many characters of each value.
    #[arg(long, default_value_t = 160)]
    pub max_chars: usize,
}

/// Queries `args.key_expr` and prints each reply, then the number of replies and of
/// error replies (`N replies, M errors`). Replies about this command's own session
/// (`@/<its zid>/...`: a Zenoh session answers admin-space queries about its own
/// links) are left out.
pub async fn query(cfg: &BusConfig, args: &QueryArgs) -> anyhow::Result<()> {
    if !(args.timeout_s.is_finite() && args.timeout_s > 0.0) {
        bail!(
            "--timeout-s must be a positive number, got {}",
            args.timeout_s
        );
    }
    let selector = zenoh::query::Selector::try_from(args.key_expr.as_str())
        .map_err(|e| anyhow::anyhow!("`{}` is not a key expression: {e}", args.key_expr))?;
    let bus = open(cfg).await?;
    let replies = bus
        .session()
        .get(selector)
        .timeout(Duration::from_secs_f64(args.timeout_s))
        .await
        .map_err(|e| anyhow::anyhow!("query {}: {e}", args.key_expr))?;
    let cut = |text: String| -> String {
        match text.char_indices().nth(args.max_chars) {
            Some((i, _)) => format!("{}...", &text[..i]),
            None => text,
        }
    };
    let own = format!("@/{}/", bus.zid());
    let (mut ok, mut errors) = (0usize, 0usize);
    while let Ok(reply) = replies.recv_async().await {
        match reply.result() {
            Ok(sample) if sample.key_expr().as_str().starts_with(&own) => {}
            Ok(sample) => {
                ok += 1;
                let text = sample
                    .payload()
                    .try_to_string()
                    .map(|t| t.into_owned())
                    .unwrap_or_else(|_| format!("<{} bytes>", sample.payload().len()));
                println!("{} {}", sample.key_expr(), cut(text));
            }
            Err(e) => {
                errors += 1;
                let text = e
                    .payload()
                    .try_to_string()
                    .map(|t| t.into_owned())
                    .unwrap_or_default();
                println!("error reply: {}", cut(text));
            }
        }
    }
    println!("{ok} replies, {errors} errors");
    bus.close().await?;
    Ok(())
}

/// A sample as JSON; image pixel data is summarised, not dumped.
fn to_json<T: Message>(msg: &T) -> anyhow::Result<serde_json::Value> {
    let mut v = serde_json::to_value(msg)?;
    if let Some(data) = v.get_mut("data")
        && let Some(arr) = data.as_array()
    {
        *data = serde_json::Value::String(format!("<{} bytes>", arr.len()));
    }
    Ok(v)
}

/// Echo shows everything in order; no deadline, so a slow link is still visible.
fn echo_guard(bus: &Bus, spec: &TopicSpec) -> GuardSettings {
    GuardSettings {
        deadline_ns: None,
        ..bus.guard_settings(spec)
    }
}

async fn echo_typed<T: Message>(
    bus: &Bus,
    spec: &TopicSpec,
    format: Format,
    count: Option<u64>,
    until: Option<Instant>,
) -> anyhow::Result<()> {
    let topic = Topic::<T>::from_spec(spec).context("topic type mismatch")?;
    let sub = bus
        .subscriber_with(&topic, echo_guard(bus, spec), SourcePolicy::Any)
        .await?;
    let mut n = 0u64;
    loop {
        if count.is_some_and(|c| n >= c) || until.is_some_and(|u| Instant::now() >= u) {
            break;
        }
        let Some(r) = sub.recv_timeout(Duration::from_millis(200)).await else {
            continue;
        };
        n += 1;
        let mut v = to_json(&r.msg)?;
        if let Some(obj) = v.as_object_mut() {
            let gid: String = r.publisher_gid.iter().map(|b| format!("{b:02x}")).collect();
            // The node that announced this publisher (liveliness), if any did.
            let node = sub.publisher_info(&r.publisher_gid).map(|p| p.node_name);
            obj.insert(
                "_meta".into(),
                serde_json::json!({
                    "publisher_gid": gid,
                    "publisher_node": node,
                    "sequence": r.sequence,
                    "latency_ms": r.latency_ns() as f64 / 1e6,
                    // When it was sent (the publisher's clock) and received (ours), s
                    // since the epoch: a timeline to compare with other topics.
                    "sent_s": r.source_timestamp_ns as f64 * 1e-9,
                    "received_s": r.receive_time_s(),
                }),
            );
        }
        match format {
            Format::Json => println!("{}", serde_json::to_string(&v)?),
            Format::Yaml => print!("---\n{}", serde_yaml::to_string(&v)?),
        }
    }
    let s = sub.stats();
    if s.rejected() > 0 {
        eprintln!(
            "dropped: {} out-of-order, {} undecodable, {} without attachment",
            s.dropped_out_of_order, s.decode_errors, s.bad_attachment
        );
    }
    Ok(())
}

fn deadline(duration_s: Option<f64>) -> anyhow::Result<Option<Instant>> {
    match duration_s {
        None => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 => {
            Ok(Some(Instant::now() + Duration::from_secs_f64(s)))
        }
        Some(s) => bail!("--duration-s must be a positive number, got {s}"),
    }
}

pub async fn echo(
    cfg: &BusConfig,
    name: &str,
    format: Format,
    count: Option<u64>,
    duration_s: Option<f64>,
) -> anyhow::Result<()> {
    let spec = spec_or_bail(name)?;
    let until = deadline(duration_s)?;
    let bus = open(cfg).await?;
    dispatch!(spec, echo_typed(&bus, spec, format, count, until))?;
    bus.close().await?;
    Ok(())
}

/// Type-erased view of a subscriber's statistics.
trait Watched {
    fn spec(&self) -> &TopicSpec;
    fn stats(&self) -> StatsSnapshot;
}

impl<T: Message> Watched for Subscriber<T> {
    fn spec(&self) -> &TopicSpec {
        Subscriber::spec(self)
    }
    fn stats(&self) -> StatsSnapshot {
        Subscriber::stats(self)
    }
}

async fn watch_typed<T: Message>(bus: &Bus, spec: &TopicSpec) -> anyhow::Result<Box<dyn Watched>> {
    let topic = Topic::<T>::from_spec(spec).context("topic type mismatch")?;
    Ok(Box::new(bus.subscriber(&topic).await?))
}

/// One line of the monitor table.
pub fn monitor_line(
    spec: &TopicSpec,
    now: &StatsSnapshot,
    before: &StatsSnapshot,
    dt_s: f64,
) -> String {
    let rate = (now.accepted - before.accepted) as f64 / dt_s.max(1e-9);
    format!(
        "{:<36} {:>8.1} {:>8.1} {:>9.2} {:>9.2} {:>7} {:>7} {:>7} {:>7}",
        format!("/{}", spec.name),
        rate,
        spec.rate_hz,
        now.latency_p50_us as f64 / 1000.0,
        now.latency_p99_us as f64 / 1000.0,
        now.dropped_stale + now.dropped_from_future,
        now.dropped_out_of_order,
        now.decode_errors + now.bad_attachment,
        now.accepted,
    )
}

pub async fn monitor(
    cfg: &BusConfig,
    only: Option<&str>,
    duration_s: Option<f64>,
) -> anyhow::Result<()> {
    let duration = deadline(duration_s)?.map(|u| u.saturating_duration_since(Instant::now()));
    monitor_until(cfg, only, None, teleop_node::stop_signal(duration), &[]).await
}

/// How the monitor's table reaches the screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TableOutput {
    /// One table redrawn in place, like `top` (a terminal).
    Redraw,
    /// A new table every second, plain lines (a pipe, a file, a log).
    Lines,
}

impl TableOutput {
    /// [`TableOutput::Redraw`] on a terminal, [`TableOutput::Lines`] otherwise.
    pub fn for_stdout() -> Self {
        use std::io::IsTerminal;
        if std::io::stdout().is_terminal() {
            Self::Redraw
        } else {
            Self::Lines
        }
    }

    /// `lines` as this output shows them: in place (cursor home, each line cleared to
    /// its end, the rest of the screen cleared; the whole screen cleared the first
    /// time) or as they are, followed by an empty line.
    pub fn frame(self, lines: &[String], first: bool) -> String {
        match self {
            Self::Lines => {
                let mut out = lines.join("\n");
                out.push_str("\n\n");
                out
            }
            Self::Redraw => {
                let mut out = String::from(if first { "\x1b[2J\x1b[H" } else { "\x1b[H" });
                for l in lines {
                    out.push_str(l);
                    out.push_str("\x1b[K\n");
                }
                out.push_str("\x1b[J");
                out
            }
        }
    }
}

/// [`monitor`] until `stop` completes; `banner` lines go above the table redrawn in
/// place (plain lines leave them out: the caller prints them once). With `at_site`,
/// only the topics that reach that site in a deployment: the other site's internal
/// ones (the robots' 250 Hz-1 kHz hardware states, the raw camera images) are not
/// subscribed to, so a monitor behind a WAN does not pull them across it.
pub async fn monitor_until(
    cfg: &BusConfig,
    only: Option<&str>,
    at_site: Option<teleop_interfaces::nodes::Site>,
    stop: impl std::future::Future<Output = ()>,
    banner: &[String],
) -> anyhow::Result<()> {
    use std::io::Write;
    let output = TableOutput::for_stdout();
    let started = Instant::now();
    let mut first = true;
    let specs: Vec<&'static TopicSpec> = match only {
        Some(name) => vec![spec_or_bail(name)?],
        None => topics::ALL
            .iter()
            .filter(|t| at_site.is_none_or(|site| t.direction.reaches(site)))
            .collect(),
    };
    tokio::pin!(stop);
    let bus = open(cfg).await?;
    let mut subs: Vec<Box<dyn Watched>> = Vec::new();
    for spec in &specs {
        subs.push(dispatch!(*spec, watch_typed(&bus, spec))?);
    }
    let mut before: Vec<StatsSnapshot> = subs.iter().map(|s| s.stats()).collect();
    let mut t_before = Instant::now();
    let mut ticker = tokio::time::interval(Duration::from_secs(1));
    ticker.tick().await;
    loop {
        tokio::select! {
            _ = ticker.tick() => {}
            () = &mut stop => break,
        }
        let dt = t_before.elapsed().as_secs_f64();
        t_before = Instant::now();
        // Plain lines: the caller printed the banner once already.
        let mut lines = Vec::new();
        if output == TableOutput::Redraw {
            lines.extend_from_slice(banner);
            lines.push(format!(
                "teleop monitor: {:.0} s, every second (Ctrl-C to stop)",
                started.elapsed().as_secs_f64()
            ));
        }
        lines.push(format!(
            "{:<36} {:>8} {:>8} {:>9} {:>9} {:>7} {:>7} {:>7} {:>7}",
            "TOPIC", "RATE Hz", "NOMINAL", "p50 ms", "p99 ms", "STALE", "ORDER", "BAD", "TOTAL"
        ));
        for (sub, prev) in subs.iter().zip(before.iter_mut()) {
            let now = sub.stats();
            lines.push(monitor_line(sub.spec(), &now, prev, dt));
            *prev = now;
        }
        let mut stdout = std::io::stdout().lock();
        // A closed stdout (the reader went away) ends nothing: the monitor only shows.
        let _ = stdout.write_all(output.frame(&lines, first).as_bytes());
        let _ = stdout.flush();
        first = false;
    }
    drop(subs);
    bus.close().await?;
    Ok(())
}

#[cfg(test)]
mod dispatch_tests {
    use super::*;

    #[test]
    fn a_terminal_gets_one_table_redrawn_in_place_a_pipe_plain_lines() {
        let lines = vec!["TOPIC".to_owned(), "/a 1".to_owned()];
        let plain = TableOutput::Lines.frame(&lines, true);
        assert_eq!(plain, "TOPIC\n/a 1\n\n");
        assert!(!plain.contains('\x1b'));
        let first = TableOutput::Redraw.frame(&lines, true);
        let next = TableOutput::Redraw.frame(&lines, false);
        assert!(first.starts_with("\x1b[2J\x1b[H"), "{first:?}");
        assert!(
            next.starts_with("\x1b[H") && !next.contains("\x1b[2J"),
            "{next:?}"
        );
        assert!(
            next.contains("/a 1\x1b[K\n") && next.ends_with("\x1b[J"),
            "{next:?}"
        );
    }

    async fn type_name_of<T: Message>() -> anyhow::Result<&'static str> {
        Ok(T::TYPE_NAME)
    }

    /// `topic echo`, `hz` and the other inspectors decode every topic of the table.
    #[test]
    fn every_topic_of_the_table_has_a_decoder() {
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        for spec in topics::ALL {
            let name = rt
                .block_on(async { dispatch!(spec, type_name_of()) })
                .unwrap_or_else(|e| panic!("/{}: {e}", spec.name));
            assert_eq!(name, spec.type_name);
        }
    }
}
