//! `teleop launch`: starts every node of the system on this machine, as separate
//! processes talking Zenoh peer-to-peer over loopback, then shows the live monitor.

use std::path::PathBuf;
use std::process::Stdio;
use std::time::Duration;

use anyhow::{Context, bail};
use teleop_bus::ZenohArgs;
use tokio::process::{Child, Command};

/// The node binaries of the system, in start order. Each runs with its default
/// configuration unless a config directory is given.
pub const NODES: &[&str] = &[
    "remote_sim",
    "pr2_arm_controller",
    "shadow_hand_controller",
    "feedback_publisher",
    "wrist_tracker",
];

#[derive(Debug, Clone, clap::Args)]
pub struct LaunchArgs {
    /// Directory with `<node>.toml` files (default: built-in defaults).
    #[arg(long)]
    pub config_dir: Option<PathBuf>,
    /// Stop everything after this many seconds (default: until Ctrl-C).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Do not print the monitor table.
    #[arg(long)]
    pub quiet: bool,
}

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

pub async fn launch(args: LaunchArgs, zenoh: &ZenohArgs) -> anyhow::Result<()> {
    let mut children: Vec<(&str, Child)> = Vec::new();
    for name in NODES {
        let mut cmd = Command::new(node_binary(name)?);
        if let Some(dir) = &args.config_dir {
            cmd.arg("--config").arg(dir.join(format!("{name}.toml")));
        }
        if let Some(d) = zenoh.domain_id {
            cmd.arg("--domain-id").arg(d.to_string());
        }
        cmd.stdin(Stdio::null()).kill_on_drop(true);
        let child = cmd.spawn().with_context(|| format!("starting {name}"))?;
        tracing::info!(node = name, pid = child.id(), "started");
        children.push((name, child));
    }
    let mut cfg = teleop_bus::BusConfig::default();
    zenoh.apply(&mut cfg);
    let monitor = async {
        if args.quiet {
            teleop_bus::node::stop_signal(
                args.duration_s.map(|s| Duration::from_secs_f64(s.max(0.0))),
            )
            .await;
            Ok(())
        } else {
            crate::inspect::monitor(&cfg, None, args.duration_s).await
        }
    };
    let result = tokio::select! {
        r = monitor => r,
        (name, status) = wait_any(&mut children) => {
            Err(anyhow::anyhow!("node {name} exited early: {status}"))
        }
    };
    for (name, child) in &mut children {
        if let Err(e) = child.start_kill() {
            tracing::warn!(node = *name, "stopping: {e}");
        }
        let _ = child.wait().await;
    }
    result
}

async fn wait_any<'a>(children: &mut [(&'a str, Child)]) -> (&'a str, String) {
    loop {
        for (name, child) in children.iter_mut() {
            if let Ok(Some(status)) = child.try_wait() {
                return (name, status.to_string());
            }
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}
