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
    /// Send large messages to peers on this host through sockets, not Zenoh shared
    /// memory (overrides the config's `shared_memory`).
    #[arg(long)]
    pub no_shared_memory: bool,
    /// ROS 2 domain id (overrides the config file).
    #[arg(long)]
    pub domain_id: Option<u32>,
    /// Interface (name, or IPv4 subnet a.b.c.d/n) on which hardware topics may travel
    /// (repeatable; replaces the config's `hardware_interfaces`; `*` for all).
    #[arg(long)]
    pub hardware_interface: Vec<String>,
    /// Run on simulated time that passes this many times as fast as the wall clock
    /// (0.05-20; below 1 is slow motion). Every process of one system must be given the
    /// same scale and origin (`teleop launch --time-scale` does that).
    #[arg(long, value_parser = parse_time_scale)]
    pub time_scale: Option<f64>,
    /// Where simulated time agrees with the wall clock, ns since the epoch (default:
    /// when the process starts; a launcher passes its own to every node).
    #[arg(long, requires = "time_scale")]
    pub time_origin_ns: Option<i64>,
    /// Run on the simulated time of this clock file, whose rate a launcher changes
    /// during the run (`teleop launch --as-fast-as-possible` writes it and passes it to
    /// every node; not with --time-scale).
    #[arg(long, conflicts_with = "time_scale")]
    pub time_file: Option<PathBuf>,
    /// Mutual TLS: the certificate authority (PEM) every peer must be signed by (with
    /// --tls-cert and --tls-key; every endpoint must then be a tls/ one).
    #[arg(long, requires_all = ["tls_cert", "tls_key"])]
    pub tls_ca: Option<PathBuf>,
    /// Mutual TLS: this process's certificate (PEM); its common name is its identity.
    #[arg(long, requires_all = ["tls_ca", "tls_key"])]
    pub tls_cert: Option<PathBuf>,
    /// Mutual TLS: the private key of --tls-cert (PEM).
    #[arg(long, requires_all = ["tls_ca", "tls_cert"])]
    pub tls_key: Option<PathBuf>,
}

fn parse_time_scale(s: &str) -> Result<f64, String> {
    let scale: f64 = s
        .parse()
        .map_err(|e| format!("not a number: {s:?} ({e})"))?;
    teleop_bus::ScaledClock::new(0, scale).map(|_| scale)
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
        if self.no_shared_memory {
            cfg.zenoh.shared_memory = false;
        }
        if let Some(d) = self.domain_id {
            cfg.domain_id = d;
        }
        if !self.hardware_interface.is_empty() {
            cfg.zenoh.hardware_interfaces = self.hardware_interface.clone();
        }
        if let (Some(ca), Some(cert), Some(key)) = (&self.tls_ca, &self.tls_cert, &self.tls_key) {
            cfg.zenoh.tls = Some(teleop_bus::TlsSettings {
                ca_certificate: ca.clone(),
                certificate: cert.clone(),
                private_key: key.clone(),
            });
        }
        if let Some(p) = &self.time_file {
            cfg.time_file = Some(p.clone());
        }
        if let Some(scale) = self.time_scale {
            cfg.time = Some(teleop_bus::TimeScale {
                origin_ns: self
                    .time_origin_ns
                    .unwrap_or_else(teleop_msgs::unix_nanos_now),
                scale,
            });
        }
    }

    /// Fixes the simulated time's origin at now, if a scale is given without one (a
    /// launcher does this before passing [`to_args`](Self::to_args) to its nodes).
    pub fn pin_time_origin(&mut self) {
        if self.time_scale.is_some() && self.time_origin_ns.is_none() {
            self.time_origin_ns = Some(teleop_msgs::unix_nanos_now());
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
        if self.no_shared_memory {
            out.push("--no-shared-memory".into());
        }
        if let Some(d) = self.domain_id {
            out.extend(["--domain-id".into(), d.to_string()]);
        }
        for i in &self.hardware_interface {
            out.extend(["--hardware-interface".into(), i.clone()]);
        }
        if let Some(scale) = self.time_scale {
            out.extend(["--time-scale".into(), scale.to_string()]);
        }
        if let Some(origin) = self.time_origin_ns {
            out.extend(["--time-origin-ns".into(), origin.to_string()]);
        }
        if let Some(p) = &self.time_file {
            out.extend(["--time-file".into(), p.display().to_string()]);
        }
        for (flag, path) in [
            ("--tls-ca", &self.tls_ca),
            ("--tls-cert", &self.tls_cert),
            ("--tls-key", &self.tls_key),
        ] {
            if let Some(p) = path {
                out.extend([flag.into(), p.display().to_string()]);
            }
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
    /// Real-time FIFO priority of every thread of the process, 1-98, or 0 for normal
    /// time sharing (overrides the config's `scheduling.realtime_priority`).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=crate::sched::MAX_REALTIME_PRIORITY as i64))]
    pub realtime_priority: Option<u8>,
    /// Override one config field, KEY=VALUE with KEY a dotted path (`engine=mujoco`,
    /// `mujoco.perturbation.seed=7`) and VALUE a TOML value (a bare word is a string);
    /// repeatable, applied after `--config` and before validation.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
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
        if !self.set.is_empty() {
            cfg = config::apply_overrides(&cfg, &self.set)?;
        }
        self.zenoh.apply(cfg.bus_mut());
        config::validate_all(&mut cfg).map_err(ConfigError::Invalid)?;
        crate::tls_runtime::ensure_safe_runtime(cfg.bus_mut()).map_err(|e| {
            ConfigError::Invalid(format!(
                "TLS: starting again with a safe zenoh runtime: {e}"
            ))
        })?;
        Ok(Some(cfg))
    }

    /// A node binary's whole `main` after parsing, the async runtime included: loads
    /// the configuration ([`load`](Self::load)), gives the process the configured
    /// scheduling ([`crate::sched::apply`]) while it has one thread, so that every
    /// thread started afterwards inherits it, then starts the runtime and runs `run`
    /// with the configuration and the `--duration-s` limit.
    ///
    /// # Errors
    /// The configuration's [`ConfigError`], the runtime's start, or what `run` returns.
    pub fn main<C, F, Fut, T, E>(&self, run: F) -> anyhow::Result<()>
    where
        C: NodeConfig,
        F: FnOnce(C, Option<std::time::Duration>) -> Fut,
        Fut: std::future::Future<Output = Result<T, E>>,
        E: Into<anyhow::Error>,
    {
        let Some(cfg) = self.load::<C>()? else {
            return Ok(());
        };
        let duration = self.duration()?;
        let scheduling = self
            .realtime_priority
            .map_or_else(|| cfg.scheduling(), crate::SchedulingConfig::realtime);
        crate::sched::apply(&scheduling);
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
            .map_err(|e| anyhow::anyhow!("cannot start the async runtime: {e}"))?;
        runtime
            .block_on(run(cfg, duration))
            .map(drop)
            .map_err(Into::into)
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
            no_shared_memory: true,
            domain_id: Some(7),
            hardware_interface: vec!["127.0.0.0/8".into()],
            time_scale: Some(0.5),
            time_origin_ns: Some(1_700_000_000_000_000_000),
            ..Default::default()
        };
        let mut cfg = BusConfig::default();
        args.apply(&mut cfg);
        assert_eq!(cfg.zenoh.mode, Mode::Client);
        assert_eq!(cfg.domain_id, 7);
        assert!(!cfg.zenoh.multicast_scouting);
        assert!(!cfg.zenoh.shared_memory);
        assert_eq!(cfg.zenoh.hardware_interfaces, ["127.0.0.0/8"]);
        assert_eq!(
            cfg.time,
            Some(teleop_bus::TimeScale {
                origin_ns: 1_700_000_000_000_000_000,
                scale: 0.5
            })
        );
        cfg.zenoh.to_zenoh().expect("valid");
        assert_eq!(
            args.to_args(),
            [
                "--mode",
                "client",
                "--connect",
                "tcp/127.0.0.1:7447",
                "--no-multicast-scouting",
                "--no-shared-memory",
                "--domain-id",
                "7",
                "--hardware-interface",
                "127.0.0.0/8",
                "--time-scale",
                "0.5",
                "--time-origin-ns",
                "1700000000000000000"
            ]
        );
    }

    #[test]
    fn time_scale_out_of_range_is_refused_and_origin_pinned_once() {
        for bad in ["0", "-2", "100", "nan", "fast"] {
            assert!(parse_time_scale(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_time_scale("0.5"), Ok(0.5));
        let mut a = ZenohArgs {
            time_scale: Some(2.0),
            ..Default::default()
        };
        a.pin_time_origin();
        let origin = a.time_origin_ns.expect("pinned");
        a.pin_time_origin();
        assert_eq!(a.time_origin_ns, Some(origin));
        let mut cfg = BusConfig::default();
        a.apply(&mut cfg);
        assert_eq!(
            cfg.time,
            Some(teleop_bus::TimeScale {
                origin_ns: origin,
                scale: 2.0
            })
        );
        // No scale, no simulated time.
        let mut cfg = BusConfig::default();
        ZenohArgs::default().apply(&mut cfg);
        assert_eq!(cfg.time, None);
        assert_eq!(cfg.time_file, None);
    }

    #[test]
    fn a_clock_file_is_passed_on_and_excludes_a_time_scale() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            z: ZenohArgs,
        }
        let cli = Cli::try_parse_from(["x", "--time-file", "/tmp/clock"]).expect("parses");
        let mut cfg = BusConfig::default();
        cli.z.apply(&mut cfg);
        assert_eq!(cfg.time_file, Some(PathBuf::from("/tmp/clock")));
        assert_eq!(cfg.time, None);
        assert_eq!(cli.z.to_args(), ["--time-file", "/tmp/clock"]);
        let e = Cli::try_parse_from(["x", "--time-file", "/tmp/c", "--time-scale", "2"])
            .err()
            .expect("refused");
        assert!(e.to_string().contains("--time-scale"), "{e}");
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
