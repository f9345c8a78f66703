//! The command line every node binary takes, and the Zenoh overrides every tool takes.

use std::path::PathBuf;

use teleop_bus::{BusConfig, Mode};

use crate::config::{self, ConfigError, NodeConfig};

/// Zenoh session mode on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeArg {
    /// Talk to other peers directly.
    Peer,
    /// Talk only through a router.
    Client,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Peer => Mode::Peer,
            ModeArg::Client => Mode::Client,
        }
    }
}

/// Command-line options every binary takes (flatten into its clap parser).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ZenohArgs {
    /// Zenoh mode (overrides the config file).
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Endpoint to connect to, e.g. tcp/192.0.2.10:7447 (repeatable; replaces the
    /// config's list).
    #[arg(long, short = 'e')]
    pub connect: Vec<String>,
    /// Endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable; replaces the config's
    /// list).
    #[arg(long, short = 'l')]
    pub listen: Vec<String>,
    /// Zenoh JSON5 configuration file.
    #[arg(long)]
    pub zenoh_config: Option<PathBuf>,
    /// Disable multicast scouting (use with --connect).
    #[arg(long)]
    pub no_multicast_scouting: bool,
    /// ROS 2 domain id (overrides the config file).
    #[arg(long)]
    pub domain_id: Option<u32>,
}

impl ZenohArgs {
    /// Applies the command-line overrides to `cfg`.
    pub fn apply(&self, cfg: &mut BusConfig) {
        if let Some(m) = self.mode {
            cfg.zenoh.mode = m.into();
        }
        if !self.connect.is_empty() {
            cfg.zenoh.connect = self.connect.clone();
        }
        if !self.listen.is_empty() {
            cfg.zenoh.listen = self.listen.clone();
        }
        if let Some(p) = &self.zenoh_config {
            cfg.zenoh.config_file = Some(p.clone());
        }
        if self.no_multicast_scouting {
            cfg.zenoh.multicast_scouting = false;
        }
        if let Some(d) = self.domain_id {
            cfg.domain_id = d;
        }
    }

    /// The arguments as a child process's command line (for launchers).
    pub fn to_args(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(m) = self.mode {
            out.push("--mode".into());
            out.push(
                match m {
                    ModeArg::Peer => "peer",
                    ModeArg::Client => "client",
                }
                .into(),
            );
        }
        for e in &self.connect {
            out.extend(["--connect".into(), e.clone()]);
        }
        for e in &self.listen {
            out.extend(["--listen".into(), e.clone()]);
        }
        if let Some(p) = &self.zenoh_config {
            out.extend(["--zenoh-config".into(), p.display().to_string()]);
        }
        if self.no_multicast_scouting {
            out.push("--no-multicast-scouting".into());
        }
        if let Some(d) = self.domain_id {
            out.extend(["--domain-id".into(), d.to_string()]);
        }
        out
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
    /// Stop after this many seconds (default: until Ctrl-C or SIGTERM).
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
    /// returns at once after `--show-default-config`.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cli_overrides_and_round_trip_to_args() {
        let args = ZenohArgs {
            mode: Some(ModeArg::Client),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            no_multicast_scouting: true,
            domain_id: Some(7),
            ..Default::default()
        };
        let mut cfg = BusConfig::default();
        args.apply(&mut cfg);
        assert_eq!(cfg.zenoh.mode, Mode::Client);
        assert_eq!(cfg.domain_id, 7);
        assert!(!cfg.zenoh.multicast_scouting);
        cfg.zenoh.to_zenoh().expect("valid");
        assert_eq!(
            args.to_args(),
            [
                "--mode",
                "client",
                "--connect",
                "tcp/127.0.0.1:7447",
                "--no-multicast-scouting",
                "--domain-id",
                "7"
            ]
        );
    }

    #[test]
    fn duration_must_be_positive() {
        let a = NodeArgs {
            duration_s: Some(-1.0),
            ..Default::default()
        };
        assert!(a.duration().is_err());
        let a = NodeArgs {
            duration_s: Some(2.5),
            ..Default::default()
        };
        assert_eq!(
            a.duration().expect("valid"),
            Some(std::time::Duration::from_secs_f64(2.5))
        );
    }
}
