//! `wan_link`: the WAN link emulator between the sites' routers (`serve`), and its
//! control client (`ctl`).

use anyhow::Context;
use clap::{Parser, Subcommand};
use teleop_wan_link::Impairment;
use teleop_wan_link::proxy::{self, Emulator};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, TcpStream};

#[derive(Debug, Parser)]
#[command(version, about = "WAN link emulator between the sites' Zenoh routers")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Forward connections from --listen to --upstream, impaired.
    Serve {
        /// Where the local router connects, e.g. 0.0.0.0:7447.
        #[arg(long)]
        listen: String,
        /// The remote router, e.g. 172.30.9.2:7447.
        #[arg(long)]
        upstream: String,
        /// The control port, e.g. 0.0.0.0:7500.
        #[arg(long)]
        control: String,
        /// Seed of the jitter and loss draws.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Kernel buffers (SO_RCVBUF, SO_SNDBUF) of the forwarded connections' sockets,
        /// KiB; 0 leaves them to the kernel's autotuning (megabytes: a hidden queue in
        /// front of the modelled one, docs/network.md).
        #[arg(long, default_value_t = teleop_wan_link::DEFAULT_SOCKET_KB)]
        socket_kb: u32,
        /// Initial settings, as `set` takes them (e.g. delay_ms=20 loss_pct=1).
        settings: Vec<String>,
    },
    /// Measure the emulator itself on loopback (configured vs measured delay, loss,
    /// throughput) and print a Markdown table.
    Measure {
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Send one command to a running emulator's control port and print the reply:
    /// `set delay_ms=50 jitter_ms=5 loss_pct=1 rate_mbit=10`, `partition on|off`,
    /// `reset`, `show`.
    Ctl {
        /// The control port, e.g. 172.30.8.3:7500.
        #[arg(long)]
        control: String,
        command: Vec<String>,
    },
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    teleop_node::init_tracing();
    match Cli::parse().command {
        Cmd::Serve {
            listen,
            upstream,
            control,
            seed,
            socket_kb,
            settings,
        } => {
            let words: Vec<&str> = settings.iter().map(String::as_str).collect();
            let initial = Impairment::default()
                .with(&words)
                .context("initial settings")?;
            let emulator = Emulator::new(initial, seed, socket_kb);
            let data = emulator
                .listen(&listen)
                .await
                .with_context(|| format!("listening on {listen}"))?;
            let ctl = TcpListener::bind(&control)
                .await
                .with_context(|| format!("control port {control}"))?;
            tracing::info!(
                listen = proxy::bound(&data),
                upstream,
                control = proxy::bound(&ctl),
                seed,
                socket_kb,
                settings = initial.describe(),
                "wan link running"
            );
            tokio::select! {
                () = proxy::forward(emulator.clone(), data, upstream) => {}
                () = proxy::control(emulator.clone(), ctl) => {}
                () = teleop_node::stop_signal(None) => {}
            }
            tracing::info!(stats = emulator.stats.describe(), "wan link stopped");
            Ok(())
        }
        Cmd::Measure { seed } => measure(seed).await,
        Cmd::Ctl { control, command } => {
            let stream = TcpStream::connect(&control)
                .await
                .with_context(|| format!("connecting to the control port {control}"))?;
            let (rd, mut wr) = stream.into_split();
            wr.write_all(format!("{}\n", command.join(" ")).as_bytes())
                .await?;
            let mut lines = BufReader::new(rd).lines();
            let reply = lines
                .next_line()
                .await?
                .context("the emulator closed the control connection")?;
            println!("{reply}");
            if reply.starts_with("error") {
                std::process::exit(1);
            }
            Ok(())
        }
    }
}

/// `wan_link measure`: each condition on a fresh loopback rig.
async fn measure(seed: u64) -> anyhow::Result<()> {
    use teleop_node::stats::quantile;
    use teleop_wan_link::measure::{Rig, delays, throughput};
    println!(
        "| configured | messages | delay min / p50 / p99 / max (ms) | chunks hit by a loss (of chunks) |"
    );
    println!("|---|---|---|---|");
    for settings in [
        "delay_ms=0",
        "delay_ms=20",
        "delay_ms=50 jitter_ms=10",
        "delay_ms=100",
        "delay_ms=200",
        "delay_ms=20 loss_pct=1",
        "delay_ms=20 loss_pct=5",
    ] {
        let words: Vec<&str> = settings.split_whitespace().collect();
        let imp = Impairment::default().with(&words)?;
        let mut rig = Rig::new(imp, seed).await?;
        let n = 1000;
        let mut d = delays(&mut rig, n, std::time::Duration::from_millis(2)).await?;
        let st = &rig.emulator.stats.dir[0];
        let hit = st.losses.load(std::sync::atomic::Ordering::Relaxed);
        let chunks = st.chunks.load(std::sync::atomic::Ordering::Relaxed);
        println!(
            "| {settings} | {n} x 64 B every 2 ms | {:.2} / {:.2} / {:.2} / {:.2} | {hit} of {chunks} |",
            quantile(&mut d, 0.0),
            quantile(&mut d, 0.5),
            quantile(&mut d, 0.99),
            quantile(&mut d, 1.0)
        );
    }
    println!();
    println!(
        "| configured | transfer | measured throughput (Mbit/s) | ratio to the cap | most bytes written and not yet received |"
    );
    println!("|---|---|---|---|---|");
    for (settings, bytes) in [
        ("rate_mbit=0", 64 << 20),
        ("rate_mbit=10", 4 << 20),
        ("rate_mbit=2", 1 << 20),
    ] {
        let words: Vec<&str> = settings.split_whitespace().collect();
        let imp = Impairment::default().with(&words)?;
        let mut rig = Rig::new(imp, seed).await?;
        let t = throughput(&mut rig, bytes).await?;
        let mbit = t.bytes_per_s * 8.0 / 1e6;
        let ratio = imp
            .rate_mbit
            .map_or_else(|| "-".to_owned(), |r| format!("{:.3}", mbit / r));
        println!(
            "| {settings} | {} MiB | {mbit:.2} | {ratio} | {} KiB |",
            bytes >> 20,
            t.max_lead_bytes >> 10
        );
    }
    Ok(())
}
