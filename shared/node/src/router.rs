//! A site's Zenoh router, `teleop router`: the one process per site that the site's
//! nodes connect to as clients and that talks to the other site's router across the
//! WAN. It is a plain Zenoh router built from the same zenoh crate as the nodes (one
//! version on both ends of every link, no second toolchain to build `zenohd`), with the
//! same typed, validated settings as a node's bus: its `hardware_interfaces` keep the
//! robot's hardware topics on the site LAN, by interface name or by subnet.

use serde::{Deserialize, Serialize};
use teleop_bus::{BusConfig, Mode};

use crate::NodeConfig;
use crate::access::AccessConfig;

/// The router's configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RouterConfig {
    /// Only `bus.zenoh` matters to a router (mode `router`, what it listens on, which
    /// routers it connects to, where hardware topics may go, its TLS identity); the
    /// rest is ignored.
    pub bus: BusConfig,
    /// Who may publish what through this router (off by default; needs TLS).
    pub access: AccessConfig,
    /// Answer queries on Zenoh's admin space (`@/<zid>/router/**`: its links,
    /// sessions, routes and configuration), read-only, as `zenohd` does by default;
    /// with `access.enabled` only the observer identities may query it
    /// (`teleop query '@/*/router/**'`).
    pub admin_space: bool,
}

impl RouterConfig {
    /// The router's Zenoh configuration: the bus settings, and with `access.enabled`
    /// the access control generated from the topic and node tables in place of the
    /// bus's interface-only hardware rule.
    ///
    /// # Errors
    /// What Zenoh or the bus settings refuse.
    pub fn to_zenoh(&self) -> Result<zenoh::Config, teleop_bus::config::ConfigError> {
        let z = &self.bus.zenoh;
        let mut cfg = z.to_zenoh()?;
        let set = teleop_bus::config::set_json5;
        set(
            &mut cfg,
            "adminspace/enabled",
            &self.admin_space.to_string(),
        )?;
        set(&mut cfg, "adminspace/permissions/read", "true")?;
        set(&mut cfg, "adminspace/permissions/write", "false")?;
        if self.access.enabled {
            let hw = teleop_bus::config::resolve_interfaces(
                &z.hardware_interfaces,
                &teleop_bus::config::host_addresses(),
            )?;
            set(
                &mut cfg,
                "access_control",
                &self.access.zenoh_acl(&hw).to_string(),
            )?;
        }
        Ok(cfg)
    }
}

impl Default for RouterConfig {
    fn default() -> Self {
        let mut bus = BusConfig::default();
        bus.zenoh.mode = Mode::Router;
        bus.zenoh.listen = vec!["tcp/0.0.0.0:7447".into()];
        bus.zenoh.multicast_scouting = false;
        Self {
            bus,
            access: AccessConfig::default(),
            admin_space: true,
        }
    }
}

impl NodeConfig for RouterConfig {
    const IS_ROUTER: bool = true;

    fn bus_mut(&mut self) -> &mut BusConfig {
        &mut self.bus
    }

    /// Normal time sharing: the router runs inside `teleop`, whose runtime has started
    /// before its configuration is read.
    fn scheduling(&self) -> crate::SchedulingConfig {
        crate::SchedulingConfig::default()
    }

    fn validate(&self) -> Result<(), String> {
        let z = &self.bus.zenoh;
        if z.mode != Mode::Router {
            return Err(format!(
                "bus.zenoh.mode must be \"router\" for a router, got \"{}\"",
                z.mode.as_str()
            ));
        }
        if z.listen.is_empty() {
            return Err("bus.zenoh.listen must name at least one endpoint".into());
        }
        if self.access.enabled && z.tls.is_none() {
            return Err(
                "access.enabled needs [bus.zenoh.tls]: the router knows its peers by their certificates"
                    .into(),
            );
        }
        self.access.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn router_config_checks_mode_and_listen() {
        RouterConfig::default().validate().expect("default valid");
        let mut c = RouterConfig::default();
        c.bus.zenoh.mode = Mode::Peer;
        assert!(c.validate().unwrap_err().contains("mode"));
        let mut c = RouterConfig::default();
        c.bus.zenoh.listen.clear();
        assert!(c.validate().unwrap_err().contains("listen"));
        let mut c = RouterConfig::default();
        c.bus.zenoh.hardware_interfaces = vec!["10.0.0.0/40".into()];
        let e = crate::config::validate_all(&mut c).unwrap_err();
        assert!(
            e.contains("hardware_interfaces") && e.contains("10.0.0.0/40"),
            "{e}"
        );
        let e = crate::config::parse_toml::<RouterConfig>("[bus.zenoh]\nmodee = \"router\"\n")
            .unwrap_err();
        assert!(e.contains("modee"), "{e}");
        let mut c = RouterConfig::default();
        c.access.enabled = true;
        let e = c.validate().unwrap_err();
        assert!(e.contains("access.enabled") && e.contains("tls"), "{e}");
        let e =
            crate::config::parse_toml::<RouterConfig>("[access]\nsite = \"moon\"\n").unwrap_err();
        assert!(e.contains("moon"), "{e}");
    }
}
