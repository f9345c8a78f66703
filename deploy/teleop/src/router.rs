//! `teleop router`: runs a site's Zenoh router ([`teleop_node::router`]) until
//! SIGINT/SIGTERM (`docker stop`) or `--duration-s`.

use std::path::PathBuf;

use anyhow::Context;
use teleop_node::ZenohArgs;
use teleop_node::router::RouterConfig;

#[derive(Debug, Clone, clap::Args)]
pub struct RouterArgs {
    /// TOML configuration file (unknown fields are rejected).
    #[arg(long, short = 'c')]
    pub config: Option<PathBuf>,
    /// Print the default configuration as TOML and exit.
    #[arg(long)]
    pub show_default_config: bool,
    /// Stop after this many seconds (default: until Ctrl-C or SIGTERM).
    #[arg(long)]
    pub duration_s: Option<f64>,
}

pub async fn run(args: RouterArgs, zenoh: &ZenohArgs) -> anyhow::Result<()> {
    let node_args = teleop_node::NodeArgs {
        config: args.config,
        show_default_config: args.show_default_config,
        zenoh: zenoh.clone(),
        duration_s: args.duration_s,
        realtime_priority: None,
        set: Vec::new(),
    };
    let Some(cfg) = node_args.load::<RouterConfig>()? else {
        return Ok(());
    };
    let duration = node_args.duration()?;
    let z = &cfg.bus.zenoh;
    let session = zenoh::open(cfg.to_zenoh()?)
        .await
        .map_err(|e| anyhow::anyhow!("zenoh: opening the router session: {e}"))?;
    tracing::info!(
        zid = %session.zid(),
        listen = ?z.listen,
        connect = ?z.connect,
        hardware_interfaces = ?z.hardware_interfaces,
        tls = z.tls.is_some(),
        access_control = cfg.access.enabled,
        "router running"
    );
    teleop_node::stop_signal(duration).await;
    session
        .close()
        .await
        .map_err(|e| anyhow::anyhow!("zenoh: closing the router session: {e}"))
        .context("router stop")?;
    tracing::info!("router stopped");
    Ok(())
}
