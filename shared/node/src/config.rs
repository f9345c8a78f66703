//! Typed node configuration: TOML files with unknown fields rejected by name, defaults
//! for everything, and a validation step for what serde cannot check.

use std::path::{Path, PathBuf};

use serde::Serialize;
use serde::de::DeserializeOwned;
use teleop_bus::BusConfig;

/// A node's configuration: serde with `deny_unknown_fields`, defaults for everything.
pub trait NodeConfig: Serialize + DeserializeOwned + Default {
    /// The bus section, so command-line overrides can be applied.
    fn bus_mut(&mut self) -> &mut BusConfig;
    /// The process's scheduling (the `[scheduling]` section), applied before the node's
    /// runtime starts ([`crate::NodeArgs::main`]).
    fn scheduling(&self) -> crate::SchedulingConfig;
    /// Checks values serde cannot (ranges, consistency).
    ///
    /// # Errors
    /// A text naming the offending field.
    fn validate(&self) -> Result<(), String> {
        Ok(())
    }
    /// True for the router's config (`teleop router`), the one config whose
    /// `bus.zenoh.mode` may be `router`.
    const IS_ROUTER: bool = false;
}

/// [`NodeConfig::validate`], and what every config's bus must satisfy: a node's Zenoh
/// mode is `peer` or `client`, with TLS every endpoint is a `tls/` one, and each
/// `hardware_interfaces` entry is an interface name or a well-formed subnet (subnets are resolved to this host's interfaces when
/// the session opens: a site's config is checked on machines that are not on that
/// site).
///
/// # Errors
/// A text naming the offending field.
pub fn validate_all<C: NodeConfig>(cfg: &mut C) -> Result<(), String> {
    let zenoh = &cfg.bus_mut().zenoh;
    if !C::IS_ROUTER && zenoh.mode == teleop_bus::Mode::Router {
        return Err(
            "bus.zenoh.mode = \"router\" is for `teleop router`, not a node: use \"peer\" or \"client\""
                .into(),
        );
    }
    for entry in &zenoh.hardware_interfaces {
        teleop_bus::config::parse_subnet(entry).map_err(|e| format!("bus.zenoh.{e}"))?;
    }
    if let Some(tls) = &zenoh.tls {
        tls.check_endpoints(&zenoh.connect, zenoh.listened())
            .map_err(|e| format!("bus.zenoh.{e}"))?;
    }
    // A deadline for a topic the table does not have would never apply: a typo, named.
    for topic in cfg.bus_mut().deadlines_ms.keys() {
        if !teleop_interfaces::topics::ALL
            .iter()
            .any(|t| t.name == topic.as_str())
        {
            return Err(format!(
                "bus.deadlines_ms: no topic {topic:?} in the topic table (names as in \
                 docs/topics.md, e.g. \"teleop/wrist_pose\")"
            ));
        }
    }
    cfg.scheduling().validate()?;
    cfg.validate()
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

/// Applies `--set KEY=VALUE` overrides to a config: `KEY` is a dotted path into the
/// config's TOML form (`engine`, `mujoco.perturbation.seed`), `VALUE` a TOML value
/// (`0.5`, `true`, `[1, 2]`, `"text"`; a bare word is taken as a string). The result
/// goes through the config's own deserialization, so an unknown field or a wrong type
/// is refused by name, as in a file.
///
/// # Errors
/// [`ConfigError::Invalid`] naming the override at fault.
pub fn apply_overrides<T: Serialize + DeserializeOwned>(
    cfg: &T,
    overrides: &[String],
) -> Result<T, ConfigError> {
    let mut root = toml::Value::try_from(cfg).map_err(|e| ConfigError::Serialize(e.to_string()))?;
    for o in overrides {
        let bad = |why: &str| ConfigError::Invalid(format!("--set {o}: {why}"));
        let (key, value) = o.split_once('=').ok_or_else(|| bad("expected KEY=VALUE"))?;
        let (key, value) = (key.trim(), value.trim());
        let path: Vec<&str> = key.split('.').collect();
        if path.iter().any(|p| p.is_empty()) {
            return Err(bad("empty key"));
        }
        let value = match toml::from_str::<toml::Table>(&format!("v = {value}")) {
            Ok(mut t) => t.remove("v").ok_or_else(|| bad("no value"))?,
            Err(_) => toml::Value::String(value.to_owned()),
        };
        let (last, parents) = path.split_last().ok_or_else(|| bad("empty key"))?;
        let mut table = root
            .as_table_mut()
            .ok_or_else(|| bad("the config is not a table"))?;
        for (depth, p) in parents.iter().enumerate() {
            table = table
                .get_mut(*p)
                .and_then(toml::Value::as_table_mut)
                .ok_or_else(|| {
                    bad(&format!(
                        "no section {:?} in this node's config",
                        path[..=depth].join(".")
                    ))
                })?;
        }
        table.insert((*last).to_owned(), value);
    }
    root.try_into().map_err(|e: toml::de::Error| {
        ConfigError::Invalid(format!("--set: {}", e.to_string().trim_end()))
    })
}

/// Renders a config as TOML (for `--show-default-config`).
///
/// # Errors
/// [`ConfigError::Serialize`] if the value cannot be expressed in TOML.
pub fn to_toml<T: Serialize>(value: &T) -> Result<String, ConfigError> {
    toml::to_string_pretty(value).map_err(|e| ConfigError::Serialize(e.to_string()))
}

/// Loads and validates a config file: what `--config` does.
///
/// # Errors
/// As [`load_toml`], or [`ConfigError::Invalid`] from [`NodeConfig::validate`].
pub fn load_checked<C: NodeConfig>(path: &Path) -> Result<C, ConfigError> {
    let mut cfg: C = load_toml(path)?;
    validate_all(&mut cfg).map_err(|e| ConfigError::Invalid(format!("{}: {e}", path.display())))?;
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_set_nested_fields_and_refuse_unknown_ones() {
        let cfg = BusConfig::default();
        let out = apply_overrides(&cfg, &["domain_id=7".into(), "zenoh.mode=client".into()])
            .expect("valid overrides");
        assert_eq!(out.domain_id, 7);
        assert_eq!(out.zenoh.mode, teleop_bus::Mode::Client);
        let err = apply_overrides(&cfg, &["domain_idd=7".into()]).expect_err("unknown field");
        assert!(err.to_string().contains("domain_idd"), "{err}");
        let err = apply_overrides(&cfg, &["nope.x=1".into()]).expect_err("unknown section");
        assert!(err.to_string().contains("nope"), "{err}");
        let err = apply_overrides(&cfg, &["domain_id=many".into()]).expect_err("wrong type");
        assert!(err.to_string().contains("--set"), "{err}");
        let err = apply_overrides(&cfg, &["domain_id".into()]).expect_err("no value");
        assert!(err.to_string().contains("KEY=VALUE"), "{err}");
    }

    #[test]
    fn unknown_field_is_named() {
        let err = parse_toml::<BusConfig>("domain_id = 1\nclock_tolerance = 3\n")
            .expect_err("unknown field must be rejected");
        assert!(err.contains("clock_tolerance"), "{err}");
        let err = parse_toml::<BusConfig>("[zenoh]\nmod = \"peer\"\n").expect_err("rejected");
        assert!(err.contains("mod"), "{err}");
    }

    #[test]
    fn default_round_trips() {
        let d = BusConfig::default();
        let text = to_toml(&d).expect("serializes");
        let back: BusConfig = parse_toml(&text).expect("parses");
        assert_eq!(back, d);
    }

    #[test]
    fn missing_file_is_named() {
        let e = load_toml::<BusConfig>(Path::new("/nonexistent/x.toml")).expect_err("missing");
        assert!(e.to_string().contains("/nonexistent/x.toml"), "{e}");
    }
}
