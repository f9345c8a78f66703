//! `teleop foxglove`: a live view of the bus in Foxglove. Each chosen topic is tapped
//! raw (the CDR bytes as they travelled) and logged to a channel of the Foxglove SDK's
//! WebSocket server: topic `/teleop/...`, message encoding `cdr`, schema the ROS 2 type
//! with its full `ros2msg` definition (the one `teleop record` writes into bags), so
//! Foxglove decodes and shows the messages as it does a ROS 2 system's.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use foxglove::{PartialMetadata, RawChannel, Schema};
use teleop_bus::{Bus, BusConfig, RawSample};
use teleop_interfaces::TopicSpec;

use crate::foxglove_front::{self, FrontCounts};

/// How long the server may take to close its clients' connections when it stops.
const SHUTDOWN_WAIT: Duration = Duration::from_secs(3);

#[derive(Debug, Clone, clap::Args)]
pub struct FoxgloveArgs {
    /// Topics to show (default: every topic that crosses between the sites, as
    /// `teleop record` takes them).
    pub topics: Vec<String>,
    /// Every topic of the table, the robot site's hardware topics and camera images
    /// included (on the LAN where they travel).
    #[arg(long, short = 'a', conflicts_with = "topics")]
    pub all: bool,
    /// The address the WebSocket server listens on (0.0.0.0: every interface; the
    /// server has no authentication, anyone who reaches it sees the bus).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// The WebSocket server's port (Foxglove's default 8765; 0 picks a free one).
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
    /// Stop after this many seconds (default: at Ctrl-C / SIGTERM).
    #[arg(long)]
    pub duration_s: Option<f64>,
}

/// A Foxglove channel for a topic of the table: raw CDR, the ROS 2 type's full
/// definition as its `ros2msg` schema, the topic's type hash as metadata.
fn channel(ctx: &Arc<foxglove::Context>, spec: &TopicSpec) -> anyhow::Result<Arc<RawChannel>> {
    let description = teleop_msgs::description_of(spec.type_name)
        .with_context(|| format!("/{}: no description of {}", spec.name, spec.type_name))?;
    let schema = Schema::new(
        spec.type_name,
        "ros2msg",
        description.full_definition().into_bytes(),
    );
    ctx.channel_builder(format!("/{}", spec.name.trim_start_matches('/')))
        .message_encoding("cdr")
        .schema(schema)
        .add_metadata("topic_type_hash", spec.type_hash)
        .build_raw()
        .with_context(|| format!("the Foxglove channel of /{}", spec.name))
}

/// A clear message for a listening address that could not be taken.
fn bind_error(io: &std::io::Error, host: &str, port: u16) -> anyhow::Error {
    if io.kind() == std::io::ErrorKind::AddrInUse {
        anyhow::anyhow!(
            "port {port} on {host} is in use (another `teleop foxglove` or a \
             foxglove_bridge?): choose another with --port"
        )
    } else {
        anyhow::anyhow!("cannot listen on {host}:{port} for Foxglove: {io}")
    }
}

/// Logs a tapped sample to its channel, stamped with the time it was received.
fn forward(channel: &RawChannel, count: &AtomicU64, sample: &RawSample) {
    count.fetch_add(1, Ordering::Relaxed);
    let log_time = u64::try_from(sample.received_ns).unwrap_or(0);
    channel.log_with_meta(&sample.payload, PartialMetadata::with_log_time(log_time));
}

pub async fn run(args: &FoxgloveArgs, cfg: &BusConfig) -> anyhow::Result<()> {
    let duration = match args.duration_s {
        Some(s) if s.is_finite() && s > 0.0 => Some(Duration::from_secs_f64(s)),
        Some(s) => bail!("--duration-s {s}: a positive number of seconds"),
        None => None,
    };
    // Signals are watched from here on: a client served as soon as the server starts
    // may interrupt it at once.
    let stop = teleop_node::stop_signal(duration);
    let specs = crate::bag::chosen_topics(&args.topics, args.all)?;
    // A context of its own: only this command's channels reach this server.
    let ctx = foxglove::Context::new();
    let channels = specs
        .iter()
        .map(|s| channel(&ctx, s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    // The address clients reach is the front's (which also lets clients of the older
    // subprotocol name in); the SDK's server listens on loopback behind it.
    let listener = tokio::net::TcpListener::bind((args.host.as_str(), args.port))
        .await
        .map_err(|e| bind_error(&e, &args.host, args.port))?;
    let port = listener
        .local_addr()
        .context("the Foxglove listener's address")?
        .port();
    let server = ctx
        .websocket_server()
        .name("teleop")
        .bind("127.0.0.1", 0)
        .start()
        .await
        .context("starting the Foxglove SDK's WebSocket server on loopback")?;
    let upstream = std::net::SocketAddr::from(([127, 0, 0, 1], server.port()));
    let front_counts = Arc::new(FrontCounts::default());
    let front = tokio::spawn(foxglove_front::serve(
        listener,
        upstream,
        Arc::clone(&front_counts),
    ));

    let bus = Bus::open(&format!("teleop_foxglove_{}", std::process::id()), cfg)
        .await
        .context("opening the Zenoh session")?;
    let counts: Vec<Arc<AtomicU64>> = specs.iter().map(|_| Arc::default()).collect();
    let mut taps = Vec::new();
    for ((spec, channel), count) in specs.iter().zip(&channels).zip(&counts) {
        let (channel, count) = (Arc::clone(channel), Arc::clone(count));
        taps.push(
            bus.tap(spec, move |s| forward(&channel, &count, &s))
                .await
                .with_context(|| format!("tapping /{}", spec.name))?,
        );
    }
    println!(
        "Foxglove: open ws://{}:{port} in Foxglove (Open connection)",
        args.host
    );
    eprintln!(
        "bridging {} topic(s) (Ctrl-C stops); layout: deploy/foxglove/teleop-layout.json",
        specs.len()
    );

    let started = Instant::now();
    tokio::pin!(stop);
    let mut tick = tokio::time::interval(Duration::from_secs(5));
    tick.tick().await;
    loop {
        tokio::select! {
            () = &mut stop => break,
            _ = tick.tick() => tracing::info!(
                clients = server.client_count(),
                messages = counts.iter().map(|c| c.load(Ordering::Relaxed)).sum::<u64>(),
                "bridging"
            ),
        }
    }

    // No more samples, then the clients told the server is going away (through the
    // front, which then stops).
    drop(taps);
    let clients = server.client_count();
    if tokio::time::timeout(SHUTDOWN_WAIT, server.stop().wait())
        .await
        .is_err()
    {
        tracing::warn!("the Foxglove server did not stop within {SHUTDOWN_WAIT:?}");
    }
    front.abort();
    for c in &channels {
        c.close();
    }
    bus.close().await.ok();

    println!(
        "bridged for {:.1} s ({clients} client(s) connected at the end); messages per topic:",
        started.elapsed().as_secs_f64()
    );
    println!(
        "handshakes: {} passed as offered, {} renamed from {}, {} refused at the front",
        front_counts.passed.load(Ordering::Relaxed),
        front_counts.renamed.load(Ordering::Relaxed),
        foxglove_front::LEGACY_V1,
        front_counts.refused.load(Ordering::Relaxed),
    );
    let width = specs.iter().map(|s| s.name.len() + 1).max().unwrap_or(0);
    for (spec, count) in specs.iter().zip(&counts) {
        println!(
            "  {:<width$}  {:>8}",
            format!("/{}", spec.name),
            count.load(Ordering::Relaxed)
        );
    }
    Ok(())
}
