//! Node configuration shared by every binary: the Zenoh session settings and the bus
//! protections, loaded from TOML with unknown fields rejected, plus the common
//! command-line overrides.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// Zenoh session mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Talks to other peers directly (default; no router needed on one LAN).
    Peer,
    /// Talks only through a router (WAN setups, rmw_zenoh routers).
    Client,
}

impl Mode {
    fn as_str(self) -> &'static str {
        match self {
            Mode::Peer => "peer",
            Mode::Client => "client",
        }
    }
}

/// How a node's Zenoh session is set up.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohSettings {
    pub mode: Mode,
    /// Endpoints to connect to, e.g. `tcp/192.0.2.10:7447`.
    pub connect: Vec<String>,
    /// Endpoints to listen on. The default listens on loopback only, so a node on one
    /// machine needs no network setup; multi-host deployments set real addresses.
    pub listen: Vec<String>,
    /// Find peers by UDP multicast scouting.
    pub multicast_scouting: bool,
    /// Network interface for multicast scouting (`auto` or a name such as `lo`).
    pub multicast_interface: String,
    /// A full Zenoh JSON5 configuration file, applied first; the fields above override
    /// it where set.
    pub config_file: Option<PathBuf>,
}

impl Default for ZenohSettings {
    fn default() -> Self {
        Self {
            mode: Mode::Peer,
            connect: Vec::new(),
            listen: vec!["tcp/127.0.0.1:0".into()],
            multicast_scouting: true,
            multicast_interface: "lo".into(),
            config_file: None,
        }
    }
}

/// Bus settings of a node: which ROS 2 domain, and the receive-side protections.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BusConfig {
    /// ROS 2 domain id: first element of every data key.
    pub domain_id: u32,
    /// Tolerated clock offset between the machines, in milliseconds (added to every
    /// deadline; also how far in the future a source timestamp may lie).
    pub clock_tolerance_ms: u64,
    /// Per-topic deadline overrides in milliseconds, by topic name.
    pub deadlines_ms: std::collections::BTreeMap<String, u64>,
    pub zenoh: ZenohSettings,
}

impl Default for BusConfig {
    fn default() -> Self {
        Self {
            domain_id: 0,
            clock_tolerance_ms: 20,
            deadlines_ms: Default::default(),
            zenoh: ZenohSettings::default(),
        }
    }
}

/// Errors of configuration handling.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("invalid config file {path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("invalid config value: {0}")]
    Invalid(String),
    #[error("cannot serialize config: {0}")]
    Serialize(String),
    #[error("zenoh configuration rejected `{key}`: {message}")]
    Zenoh { key: String, message: String },
}

/// Reads a TOML config file into `T` (whose serde attributes reject unknown fields).
///
/// # Errors
/// [`ConfigError::Read`] for a missing/unreadable file, [`ConfigError::Parse`] naming the
/// offending field and line for bad content.
pub fn load_toml<T: DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
        path: path.to_owned(),
        source,
    })?;
    parse_toml(&text).map_err(|message| ConfigError::Parse {
        path: path.to_owned(),
        message,
    })
}

/// Parses TOML text into `T`; the error text names the field and position.
///
/// # Errors
/// The parser's message.
pub fn parse_toml<T: DeserializeOwned>(text: &str) -> Result<T, String> {
    toml::from_str(text).map_err(|e| e.to_string().trim_end().to_owned())
}

/// Renders a config as TOML (for `--show-default-config`).
///
/// # Errors
/// [`ConfigError::Serialize`] if the value cannot be expressed in TOML.
pub fn to_toml<T: Serialize>(value: &T) -> Result<String, ConfigError> {
    toml::to_string_pretty(value).map_err(|e| ConfigError::Serialize(e.to_string()))
}

/// Command-line options every binary takes (flatten into its clap parser).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ZenohArgs {
    /// Zenoh mode (overrides the config file).
    #[arg(long, value_enum)]
    pub mode: Option<Mode>,
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
            cfg.zenoh.mode = m;
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
}

impl ZenohSettings {
    /// Builds the Zenoh configuration.
    ///
    /// # Errors
    /// [`ConfigError`] naming the file or key Zenoh refused.
    pub fn to_zenoh(&self) -> Result<zenoh::Config, ConfigError> {
        let mut cfg = match &self.config_file {
            Some(path) => zenoh::Config::from_file(path).map_err(|e| ConfigError::Zenoh {
                key: path.display().to_string(),
                message: e.to_string(),
            })?,
            None => zenoh::Config::default(),
        };
        let mut set = |key: &str, value: String| {
            cfg.insert_json5(key, &value)
                .map_err(|e| ConfigError::Zenoh {
                    key: key.to_owned(),
                    message: e.to_string(),
                })
        };
        set("mode", json_string(self.mode.as_str()))?;
        set("connect/endpoints", json_list(&self.connect))?;
        if self.mode == Mode::Peer || !self.listen.is_empty() {
            set("listen/endpoints", json_list(&self.listen))?;
        }
        set(
            "scouting/multicast/enabled",
            self.multicast_scouting.to_string(),
        )?;
        set(
            "scouting/multicast/interface",
            json_string(&self.multicast_interface),
        )?;
        // Depth images are ~600 KB, i.e. ~10 Zenoh fragments: a deeper queue for their
        // priority and a 1 MiB receive buffer halve their latency on loopback
        // (docs/benchmarks.md, bus section). Memory cost: up to 1 MiB per link.
        set("transport/link/tx/queue/size/data_low", "16".into())?;
        set("transport/link/rx/buffer_size", "1048576".into())?;
        Ok(cfg)
    }
}

fn json_string(s: &str) -> String {
    serde_json::Value::String(s.to_owned()).to_string()
}

fn json_list(items: &[String]) -> String {
    serde_json::Value::from(items.to_vec()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_field_is_named() {
        let err = parse_toml::<BusConfig>("domain_id = 1\nclock_tolerance = 3\n")
            .expect_err("unknown field must be rejected");
        assert!(err.contains("clock_tolerance"), "{err}");
        let err = parse_toml::<BusConfig>("[zenoh]\nmod = \"peer\"\n").expect_err("rejected");
        assert!(err.contains("mod"), "{err}");
    }

    #[test]
    fn default_round_trips_and_builds_a_zenoh_config() {
        let d = BusConfig::default();
        let text = to_toml(&d).expect("serializes");
        let back: BusConfig = parse_toml(&text).expect("parses");
        assert_eq!(back, d);
        d.zenoh.to_zenoh().expect("default zenoh config is valid");
    }

    #[test]
    fn cli_overrides() {
        let mut cfg = BusConfig::default();
        ZenohArgs {
            mode: Some(Mode::Client),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            no_multicast_scouting: true,
            domain_id: Some(7),
            ..Default::default()
        }
        .apply(&mut cfg);
        assert_eq!(cfg.zenoh.mode, Mode::Client);
        assert_eq!(cfg.domain_id, 7);
        assert!(!cfg.zenoh.multicast_scouting);
        cfg.zenoh.to_zenoh().expect("valid");
    }

    #[test]
    fn bad_endpoint_and_missing_file_are_errors() {
        let s = ZenohSettings {
            connect: vec!["nonsense".into()],
            ..Default::default()
        };
        let e = s.to_zenoh().expect_err("bad endpoint");
        assert!(e.to_string().contains("connect/endpoints"), "{e}");
        let s = ZenohSettings {
            config_file: Some("/nonexistent/zenoh.json5".into()),
            ..Default::default()
        };
        assert!(s.to_zenoh().is_err());
        let e = load_toml::<BusConfig>(Path::new("/nonexistent/x.toml")).expect_err("missing");
        assert!(e.to_string().contains("/nonexistent/x.toml"), "{e}");
    }
}
