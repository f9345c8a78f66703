//! What every node binary shares: the command line (`--config`, Zenoh overrides,
//! `--show-default-config`), config loading, and periodic status reports.

use std::path::PathBuf;

use serde::Serialize;
use serde::de::DeserializeOwned;
use teleop_msgs::{Header, Lifecycle, NodeStatus, Time};

use crate::config::{self, BusConfig, ConfigError, ZenohArgs};
use crate::session::{Bus, BusError, Publisher};
use crate::topics;

/// A node's configuration: serde with `deny_unknown_fields`, defaults for everything.
pub trait NodeConfig: Serialize + DeserializeOwned + Default {
    /// The bus section, so command-line overrides can be applied.
    fn bus_mut(&mut self) -> &mut BusConfig;
    /// Checks values serde cannot (ranges, consistency).
    ///
    /// # Errors
    /// A text naming the offending field.
    fn validate(&self) -> Result<(), String> {
        Ok(())
    }
}

/// Command-line options of every node binary (flatten into its clap parser).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct NodeArgs {
    /// TOML configuration file (unknown fields are rejected).
    #[arg(long, short = 'c')]
    pub config: Option<PathBuf>,
    /// Print the default configuration as TOML and exit.
    #[arg(long)]
    pub show_default_config: bool,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long)]
    pub duration_s: Option<f64>,
}

impl NodeArgs {
    /// The `--duration-s` limit, if any.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] for a value that is not a positive number of seconds.
    pub fn duration(&self) -> Result<Option<std::time::Duration>, ConfigError> {
        match self.duration_s {
            None => Ok(None),
            Some(s) if s.is_finite() && s > 0.0 => Ok(Some(std::time::Duration::from_secs_f64(s))),
            Some(s) => Err(ConfigError::Invalid(format!(
                "--duration-s must be a positive number of seconds, got {s}"
            ))),
        }
    }

    /// Loads the configuration (defaults when no file is given), applies the
    /// command-line overrides and validates. Returns `None` after printing the default
    /// configuration for `--show-default-config`.
    ///
    /// # Errors
    /// [`ConfigError`] naming the file, field or value at fault.
    pub fn load<C: NodeConfig>(&self) -> Result<Option<C>, ConfigError> {
        if self.show_default_config {
            print!("{}", config::to_toml(&C::default())?);
            return Ok(None);
        }
        let mut cfg: C = match &self.config {
            Some(path) => config::load_toml(path)?,
            None => C::default(),
        };
        self.zenoh.apply(cfg.bus_mut());
        cfg.validate().map_err(ConfigError::Invalid)?;
        Ok(Some(cfg))
    }

    /// A node binary's whole `main` after parsing: loads the configuration
    /// ([`load`](Self::load)) and calls `run` with it and the `--duration-s` limit;
    /// returns at once after `--show-default-config`. What `run` returns on success
    /// (e.g. final counters) is dropped.
    ///
    /// # Errors
    /// The configuration's [`ConfigError`], or what `run` returns.
    pub async fn run<C, F, Fut, T, E>(&self, run: F) -> Result<(), E>
    where
        C: NodeConfig,
        F: FnOnce(C, Option<std::time::Duration>) -> Fut,
        Fut: std::future::Future<Output = Result<T, E>>,
        E: From<ConfigError>,
    {
        let Some(cfg) = self.load::<C>()? else {
            return Ok(());
        };
        let duration = self.duration()?;
        run(cfg, duration).await.map(drop)
    }
}

/// Publishes this node's [`NodeStatus`] on [`topics::NODE_STATUS`].
#[derive(Debug)]
pub struct StatusReporter {
    publisher: Publisher<NodeStatus>,
    node_name: String,
}

impl StatusReporter {
    /// # Errors
    /// [`BusError`] if the publisher cannot be declared.
    pub async fn new(bus: &Bus) -> Result<Self, BusError> {
        Ok(Self {
            publisher: bus.publisher(&topics::NODE_STATUS).await?,
            node_name: bus.node_name().to_owned(),
        })
    }

    /// Publishes one status report.
    ///
    /// # Errors
    /// [`BusError`] if publishing fails.
    pub fn report(
        &self,
        state: Lifecycle,
        counters: &[(String, u64)],
        last_error: &str,
    ) -> Result<(), BusError> {
        let msg = NodeStatus {
            header: Header::new(Time::now(), ""),
            node_name: self.node_name.clone(),
            lifecycle_state: state as u8,
            counter_names: counters.iter().map(|(n, _)| n.clone()).collect(),
            counter_values: counters.iter().map(|(_, v)| *v).collect(),
            last_error: last_error.to_owned(),
        };
        self.publisher.put(&msg)
    }
}

/// Completes after `duration`, or on Ctrl-C when `duration` is `None`: the stop
/// condition of every node's run loop.
pub async fn stop_signal(duration: Option<std::time::Duration>) {
    match duration {
        Some(d) => tokio::time::sleep(d).await,
        None => {
            let _ = tokio::signal::ctrl_c().await;
        }
    }
}
