//! `teleop`: the command-line tool to inspect a running system, in the spirit of
//! `ros2 topic` / `ros2 node`, and to launch the whole system on one machine.

mod bag;
mod certs;
mod clock_pacer;
mod export;
mod foxglove;
mod foxglove_front;
mod inspect;
mod launch;
mod proc_stat;
mod progress;
mod publish;
mod record;
mod report;
mod router;
mod seeds;
mod site_link;
mod sweep;
mod tasks;

use clap::{Parser, Subcommand};
use teleop_node::ZenohArgs;

#[derive(Debug, Parser)]
#[command(
    version,
    about = "Inspect and run the dexterous hand-arm teleoperation system"
)]
struct Cli {
    #[command(flatten)]
    zenoh: ZenohArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The topic table of the system (static, from code).
    Topics {
        /// Print as a Markdown table (as in docs/topics.md).
        #[arg(long)]
        markdown: bool,
    },
    /// Live topics.
    #[command(subcommand)]
    Topic(TopicCommand),
    /// Live nodes.
    #[command(subcommand)]
    Node(NodeCommand),
    /// A Zenoh query (get) on a key expression: every reply's key and value (as text,
    /// cut short). E.g. a site router's admin space, `teleop query '@/*/router/**'`,
    /// which the routers answer to their observer identities alone.
    Query(inspect::QueryArgs),
    /// Rates, latency and drops of every topic of the table, refreshed every second.
    Monitor {
        /// Stop after this many seconds.
        #[arg(long)]
        duration_s: Option<f64>,
    },
    /// Start every node of the system on this machine (simulated hardware).
    Launch(launch::LaunchArgs),
    /// Run a site's Zenoh router (the site's nodes connect to it as clients; it
    /// connects to the other site's router across the WAN).
    Router(router::RouterArgs),
    /// Record the end-of-run report of a running system (started by someone else:
    /// docker compose, several machines).
    Report(record::ReportArgs),
    /// Record topics into a bag as rosbag2 writes them (a directory of MCAP files and
    /// metadata.yaml), for ROS 2 tools, Foxglove and `teleop bag`.
    Record(bag::RecordArgs),
    /// Publish a bag's messages again at their recorded pace (like `ros2 bag play`):
    /// fresh sequence numbers and timestamps, so the receivers take them.
    Play(bag::PlayArgs),
    /// Bags: what they hold, recovering one cut short.
    #[command(subcommand)]
    Bag(bag::BagCommand),
    /// Bags to robot-learning datasets.
    #[command(subcommand)]
    Export(export::ExportCommand),
    /// A live view in Foxglove: topics served over Foxglove's WebSocket protocol (CDR
    /// with their ROS 2 definitions), for its "Open connection"; the layout is
    /// deploy/foxglove/teleop-layout.json.
    Foxglove(foxglove::FoxgloveArgs),
    /// Make a certificate authority and certificates for mutual TLS between the sites.
    Certs(certs::CertsArgs),
    /// The WAN-condition sweep's table, plots and checks, from what
    /// deploy/compose/sweep.sh recorded.
    SweepReport(sweep::SweepArgs),
    /// Success rate and completion time against the WAN's round trip, from the
    /// summaries of `teleop launch --task T --seeds N --wan ...` (one per condition):
    /// a Markdown table and a picture.
    SeedsPlot(seeds::SeedsPlotArgs),
}

#[derive(Debug, Subcommand)]
enum TopicCommand {
    /// Topics with at least one live publisher or subscriber.
    List {
        /// How long to collect announcements, seconds.
        #[arg(long, default_value_t = 1.0)]
        wait_s: f64,
    },
    /// Print samples of a topic, decoded.
    Echo {
        topic: String,
        /// Output format.
        #[arg(long, value_enum, default_value_t = inspect::Format::Yaml)]
        format: inspect::Format,
        /// Stop after this many samples.
        #[arg(long, short = 'n')]
        count: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long)]
        duration_s: Option<f64>,
    },
    /// Publish samples of a topic (like `ros2 topic pub`; with fault-injection options).
    Pub(publish::PubArgs),
    /// Rate, latency and drops of a topic, every second.
    Hz {
        topic: String,
        /// Stop after this many seconds.
        #[arg(long)]
        duration_s: Option<f64>,
    },
}

#[derive(Debug, Subcommand)]
enum NodeCommand {
    /// Nodes alive now, with their publishers and subscribers.
    List {
        /// How long to collect announcements, seconds.
        #[arg(long, default_value_t = 1.0)]
        wait_s: f64,
    },
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    let cli = Cli::parse();
    let mut bus_cfg = teleop_bus::BusConfig::default();
    cli.zenoh.apply(&mut bus_cfg);
    // `teleop router` checks its own configuration file.
    if !matches!(cli.command, Command::Router(_)) {
        teleop_node::tls_runtime::ensure_safe_runtime(&bus_cfg)
            .map_err(|e| anyhow::anyhow!("TLS: starting again with a safe zenoh runtime: {e}"))?;
    }
    match cli.command {
        Command::Topics { markdown } => {
            inspect::print_table(markdown);
            Ok(())
        }
        Command::Topic(TopicCommand::List { wait_s }) => {
            inspect::topic_list(&bus_cfg, wait_s).await
        }
        Command::Topic(TopicCommand::Echo {
            topic,
            format,
            count,
            duration_s,
        }) => inspect::echo(&bus_cfg, &topic, format, count, duration_s).await,
        Command::Topic(TopicCommand::Pub(args)) => publish::run(&bus_cfg, &args).await,
        Command::Topic(TopicCommand::Hz { topic, duration_s }) => {
            inspect::monitor(&bus_cfg, Some(&topic), duration_s).await
        }
        Command::Node(NodeCommand::List { wait_s }) => inspect::node_list(&bus_cfg, wait_s).await,
        Command::Query(args) => inspect::query(&bus_cfg, &args).await,
        Command::Monitor { duration_s } => inspect::monitor(&bus_cfg, None, duration_s).await,
        Command::Launch(args) => launch::launch(args, &cli.zenoh).await,
        Command::SeedsPlot(args) => seeds::plot(&args),
        Command::Router(args) => router::run(args, &cli.zenoh).await,
        Command::Report(args) => record::run(args, &cli.zenoh).await,
        Command::Certs(args) => certs::run(args),
        Command::Record(args) => bag::record(&args, &bus_cfg).await,
        Command::Play(args) => bag::play(&args, &bus_cfg).await,
        Command::Bag(cmd) => bag::bag(&cmd),
        Command::Export(cmd) => export::run(&cmd),
        Command::Foxglove(args) => foxglove::run(&args, &bus_cfg).await,
        Command::SweepReport(args) => sweep::run(&args),
    }
}
