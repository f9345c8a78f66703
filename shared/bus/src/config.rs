//! Bus settings of a node: the Zenoh session and the receive-side protections. Serde
//! types with unknown fields rejected; loading files and command-line overrides are the
//! node runner's (`teleop-node`).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Zenoh session mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Talks to other peers directly (default; no router needed on one LAN).
    Peer,
    /// Talks only through a router (WAN setups, rmw_zenoh routers).
    Client,
    /// Is a router: routes between its clients and to other routers (a site's
    /// `teleop router`; no node runs in this mode).
    Router,
}

impl Mode {
    /// `"peer"` / `"client"`, as Zenoh names it.
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Peer => "peer",
            Mode::Client => "client",
            Mode::Router => "router",
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
    /// Network interfaces on which hardware topics (`teleop/hw/...`: a robot's
    /// commands and states) may travel. On every other interface of this host this
    /// node neither sends nor accepts them (Zenoh access control on the node's own
    /// session), so hardware traffic does not leave the robot's site. Default `["lo"]`:
    /// it stays on this machine. A site whose drivers and controllers sit on several
    /// machines names its site LAN interface here, by name (`eth1`) or by an IPv4
    /// subnet one of the interface's addresses is in (`172.30.2.0/24`: robust where
    /// interface names are not, as in containers); `["*"]` lifts the restriction.
    pub hardware_interfaces: Vec<String>,
    /// Mutual TLS: this process's certificate and key, and the certificate authority
    /// every peer's certificate must be signed by. With it, every endpoint must be a
    /// `tls/` one (a plain `tcp/` endpoint beside TLS ones is refused), the peer must
    /// present a certificate of the same authority, and a router's access control
    /// knows the peer by the certificate's common name (docs/security.md).
    pub tls: Option<TlsSettings>,
    /// Zenoh's batch size on this session's links, bytes: its largest frame, the
    /// smaller of the two ends' values on each link. A large message (a camera view)
    /// goes in fragments of this size, and a message of a higher priority can go
    /// between two of them, so on a slow link a smaller batch lets the feedback
    /// overtake the views sooner. `None`: Zenoh's default, 65535. The robot site's
    /// router, which sends the views across the WAN, sets it (docs/network.md).
    pub batch_bytes: Option<u16>,
    /// How soon a lost connection (to the site router, or a router's to the other
    /// site) is dialled again.
    pub reconnect: ReconnectSettings,
    /// Zenoh shared memory with peers on the same host: a message of 3 KB or more (a
    /// depth frame, a camera view) goes to a peer process on this machine as a
    /// reference to a buffer in `/dev/shm` instead of in fragments through a socket
    /// (docs/benchmarks.md, bus section). Each end must allow it; a peer on another
    /// host, or in another container (its own `/dev/shm`), fails Zenoh's probe and gets
    /// the bytes over the network as before. Costs a 16 MiB pool in `/dev/shm` per
    /// process that sends such messages.
    pub shared_memory: bool,
}

/// The redial schedule after a connection is lost or refused: the first attempt
/// `first_ms` after, then twice as long each time, at most `max_ms` apart (Zenoh's
/// `connect/retry`; its own default, 1 s to 4 s, finds a restarted router up to 4 s
/// late).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReconnectSettings {
    pub first_ms: u64,
    pub max_ms: u64,
}

impl Default for ReconnectSettings {
    fn default() -> Self {
        Self {
            first_ms: 100,
            max_ms: 500,
        }
    }
}

/// Certificate files (PEM) of a mutually authenticated TLS session.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsSettings {
    /// The certificate authority that signs every certificate of the deployment.
    pub ca_certificate: PathBuf,
    /// This process's certificate; its common name is its identity (a node's is the
    /// node's name, a router's its site's router name).
    pub certificate: PathBuf,
    /// The private key of `certificate`.
    pub private_key: PathBuf,
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
            hardware_interfaces: vec!["lo".into()],
            tls: None,
            batch_bytes: None,
            reconnect: ReconnectSettings::default(),
            shared_memory: true,
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
    /// Simulated time for this run (`--time-scale`, `--time-origin-ns` on the command
    /// line; never from a file): `None`, the default, is the system clock.
    #[serde(skip)]
    pub time: Option<TimeScale>,
    /// Simulated time whose rate a launcher changes during the run
    /// ([`crate::clock::PacedClock`], `--time-file`; never from a file): exclusive with
    /// `time`.
    #[serde(skip)]
    pub time_file: Option<std::path::PathBuf>,
}

/// A run's simulated time: `scale` x the wall clock, agreeing with it at `origin_ns`
/// (see [`crate::clock::ScaledClock`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeScale {
    pub origin_ns: i64,
    pub scale: f64,
}

impl Default for BusConfig {
    fn default() -> Self {
        Self {
            domain_id: 0,
            clock_tolerance_ms: 20,
            deadlines_ms: Default::default(),
            zenoh: ZenohSettings::default(),
            time: None,
            time_file: None,
        }
    }
}

/// A Zenoh setting the session refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    #[error("zenoh configuration rejected `{key}`: {message}")]
    Zenoh { key: String, message: String },
    #[error("hardware_interfaces: {0}")]
    HardwareInterfaces(String),
    #[error("tls.{field}: {message}")]
    Tls {
        field: &'static str,
        message: String,
    },
    #[error("{field} {message}")]
    OutOfRange {
        field: &'static str,
        message: String,
    },
}

impl ZenohSettings {
    /// The endpoints this session listens on: none for a client (it only connects to
    /// its router), `listen` otherwise.
    pub fn listened(&self) -> &[String] {
        if self.mode == Mode::Client {
            &[]
        } else {
            &self.listen
        }
    }

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
        let mut set = |key: &str, value: String| set_json5(&mut cfg, key, &value);
        set("mode", json_string(self.mode.as_str()))?;
        set("connect/endpoints", json_list(&self.connect))?;
        if self.mode != Mode::Client {
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
        set(
            "transport/shared_memory/enabled",
            self.shared_memory.to_string(),
        )?;
        if let Some(b) = self.batch_bytes {
            if b < 1024 {
                return Err(ConfigError::OutOfRange {
                    field: "batch_bytes",
                    message: format!("must be in [1024, 65535], got {b}"),
                });
            }
            set("transport/link/tx/batch_size", b.to_string())?;
        }
        let r = self.reconnect;
        if !(10..=60_000).contains(&r.first_ms) || !(r.first_ms..=60_000).contains(&r.max_ms) {
            return Err(ConfigError::OutOfRange {
                field: "reconnect",
                message: format!(
                    "first_ms must be in [10, 60000] and max_ms in [first_ms, 60000], got {} and {}",
                    r.first_ms, r.max_ms
                ),
            });
        }
        set(
            "connect/retry",
            format!(
                "{{period_init_ms: {}, period_max_ms: {}, period_increase_factor: 2.0}}",
                r.first_ms, r.max_ms
            ),
        )?;
        if let Some(tls) = &self.tls {
            tls.check_endpoints(&self.connect, self.listened())?;
            let ca = tls.file("ca_certificate", &tls.ca_certificate)?;
            let cert = tls.file("certificate", &tls.certificate)?;
            let key = tls.file("private_key", &tls.private_key)?;
            set("transport/link/tls/root_ca_certificate", json_string(&ca))?;
            set("transport/link/tls/listen_certificate", json_string(&cert))?;
            set("transport/link/tls/listen_private_key", json_string(&key))?;
            set("transport/link/tls/connect_certificate", json_string(&cert))?;
            set("transport/link/tls/connect_private_key", json_string(&key))?;
            set("transport/link/tls/enable_mtls", "true".into())?;
            set("transport/link/tls/verify_name_on_connect", "true".into())?;
        }
        let allowed = resolve_interfaces(&self.hardware_interfaces, &host_addresses())?;
        if let Some(acl) = hardware_acl(&allowed, &host_interfaces()) {
            set("access_control", acl.to_string())?;
        }
        Ok(cfg)
    }
}

impl TlsSettings {
    /// `path` as Zenoh takes it, after checking that it is a readable PEM file.
    fn file(&self, field: &'static str, path: &std::path::Path) -> Result<String, ConfigError> {
        let bad = |message: String| ConfigError::Tls { field, message };
        let text = std::fs::read_to_string(path)
            .map_err(|e| bad(format!("cannot read {}: {e}", path.display())))?;
        if !text.contains("-----BEGIN ") {
            return Err(bad(format!("{} is not a PEM file", path.display())));
        }
        path.to_str()
            .map(str::to_owned)
            .ok_or_else(|| bad(format!("{} is not valid UTF-8", path.display())))
    }

    /// Every endpoint must be a TLS one: a plain TCP endpoint beside them would accept
    /// peers without a certificate.
    ///
    /// # Errors
    /// [`ConfigError::Tls`] naming the first endpoint that is not `tls/...`.
    pub fn check_endpoints(
        &self,
        connect: &[String],
        listen: &[String],
    ) -> Result<(), ConfigError> {
        for (field, list) in [("connect", connect), ("listen", listen)] {
            if let Some(e) = list.iter().find(|e| !e.starts_with("tls/")) {
                return Err(ConfigError::Tls {
                    field: "endpoints",
                    message: format!(
                        "`{e}` in {field} is not a tls/ endpoint; with TLS set every endpoint must be one"
                    ),
                });
            }
        }
        Ok(())
    }
}

impl ZenohSettings {
    /// The settings of this node's hardware session, when it needs one.
    ///
    /// Zenoh's access control knows a link by the interface of the link's local
    /// address, and a peer on this host that dials one of this node's addresses on
    /// another interface (one it listens on for the operator site, say) makes a link
    /// that never leaves the host but counts as that interface's, where hardware
    /// topics are dropped; which of a node's addresses a peer dials is Zenoh's choice
    /// (the order of its listeners is a hash map's). So a peer node that listens on
    /// any address outside its hardware interfaces carries its hardware topics on a
    /// second session that listens on the hardware interfaces' addresses alone (port
    /// chosen by the system), dials only configured endpoints inside them, and scouts
    /// like the first: every link it has is on a hardware interface whoever dials.
    /// `None` when every listened address is on a hardware interface (the default:
    /// loopback only), for a client, or when `hardware_interfaces` is `["*"]`.
    ///
    /// # Errors
    /// [`ConfigError::HardwareInterfaces`] as [`resolve_interfaces`].
    pub fn hardware_session(&self) -> Result<Option<ZenohSettings>, ConfigError> {
        self.hardware_session_on(&host_networks())
    }

    /// [`ZenohSettings::hardware_session`] on a host with the interfaces `nets`
    /// (name, IPv4 address, network mask), as [`host_networks`] gives them.
    ///
    /// # Errors
    /// As [`ZenohSettings::hardware_session`].
    pub fn hardware_session_on(
        &self,
        nets: &[(String, std::net::Ipv4Addr, u32)],
    ) -> Result<Option<ZenohSettings>, ConfigError> {
        if self.mode != Mode::Peer {
            return Ok(None);
        }
        let host: Vec<(String, std::net::Ipv4Addr)> =
            nets.iter().map(|(n, ip, _)| (n.clone(), *ip)).collect();
        let allowed = resolve_interfaces(&self.hardware_interfaces, &host)?;
        if allowed.iter().any(|a| a == "*") {
            return Ok(None);
        }
        let inside = |endpoint: &str| {
            endpoint_interfaces(endpoint, nets)
                .is_some_and(|ifaces| ifaces.iter().all(|i| allowed.contains(i)))
        };
        if self.listen.iter().all(|e| inside(e)) {
            return Ok(None);
        }
        let protocol = if self.tls.is_some() { "tls" } else { "tcp" };
        let mut listen: Vec<String> = Vec::new();
        for (name, ip, _) in nets {
            let endpoint = format!("{protocol}/{ip}:0");
            if allowed.contains(name) && !listen.contains(&endpoint) {
                listen.push(endpoint);
            }
        }
        Ok(Some(ZenohSettings {
            listen,
            connect: self.connect.iter().filter(|e| inside(e)).cloned().collect(),
            ..self.clone()
        }))
    }
}

/// The interfaces of this host a link to or from `endpoint` would be on (`None` when
/// that cannot be told: a host name, IPv6 other than loopback). A Unix socket is on
/// none (Zenoh's access control gives its links no interface), an unspecified
/// address on all.
fn endpoint_interfaces(
    endpoint: &str,
    nets: &[(String, std::net::Ipv4Addr, u32)],
) -> Option<Vec<String>> {
    let (protocol, rest) = endpoint.split_once('/')?;
    if protocol.starts_with("unixsock") {
        return Some(Vec::new());
    }
    let address = rest.split(['?', '#']).next()?;
    let ip = match address.parse::<std::net::SocketAddr>().ok()?.ip() {
        std::net::IpAddr::V4(ip) => ip,
        std::net::IpAddr::V6(ip) if ip.is_loopback() => std::net::Ipv4Addr::LOCALHOST,
        std::net::IpAddr::V6(ip) if ip.is_unspecified() => std::net::Ipv4Addr::UNSPECIFIED,
        std::net::IpAddr::V6(_) => return None,
    };
    let mut out: Vec<String> = Vec::new();
    for (name, addr, mask) in nets {
        let on = ip.is_unspecified() || u32::from(ip) & mask == u32::from(*addr) & mask;
        if on && !out.contains(name) {
            out.push(name.clone());
        }
    }
    (!out.is_empty()).then_some(out)
}

/// This host's interfaces with their IPv4 addresses and network masks.
pub fn host_networks() -> Vec<(String, std::net::Ipv4Addr, u32)> {
    let Ok(addrs) = nix::ifaddrs::getifaddrs() else {
        return Vec::new();
    };
    addrs
        .filter_map(|a| {
            let ip = a.address?.as_sockaddr_in()?.ip();
            let mask = a
                .netmask
                .and_then(|m| m.as_sockaddr_in().map(|m| u32::from(m.ip())));
            Some((a.interface_name, ip, mask.unwrap_or(u32::MAX)))
        })
        .collect()
}

/// Key expression of every hardware topic's data, in any domain.
pub const HARDWARE_KEYS: &str = "*/teleop/hw/**";

/// The network interfaces of this host (Linux: `/sys/class/net`); empty elsewhere.
pub fn host_interfaces() -> Vec<String> {
    let mut out: Vec<String> = std::fs::read_dir("/sys/class/net")
        .map(|dir| {
            dir.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

/// This host's interfaces with their IPv4 addresses.
pub fn host_addresses() -> Vec<(String, std::net::Ipv4Addr)> {
    host_networks()
        .into_iter()
        .map(|(name, ip, _)| (name, ip))
        .collect()
}

/// `allowed` with each subnet entry (`a.b.c.d/n`) replaced by the names of the
/// interfaces in `host` with an address in it; names and `*` kept as they are.
///
/// # Errors
/// [`ConfigError::HardwareInterfaces`] for a malformed subnet, or one no interface of
/// this host is in (a site LAN that is not there: refusing beats guessing).
pub fn resolve_interfaces(
    allowed: &[String],
    host: &[(String, std::net::Ipv4Addr)],
) -> Result<Vec<String>, ConfigError> {
    let mut out = Vec::new();
    for entry in allowed {
        let Some((net, mask)) = parse_subnet(entry)? else {
            out.push(entry.clone());
            continue;
        };
        let mut found = false;
        for (name, ip) in host {
            if u32::from(*ip) & mask == u32::from(net) & mask {
                found = true;
                if !out.contains(name) {
                    out.push(name.clone());
                }
            }
        }
        if !found {
            return Err(ConfigError::HardwareInterfaces(format!(
                "`{entry}`: no interface of this host has an address in it"
            )));
        }
    }
    Ok(out)
}

/// `Some((network, mask))` for a subnet entry `a.b.c.d/n`, `None` for an interface
/// name.
///
/// # Errors
/// [`ConfigError::HardwareInterfaces`] for a malformed subnet.
pub fn parse_subnet(entry: &str) -> Result<Option<(std::net::Ipv4Addr, u32)>, ConfigError> {
    let Some((net, len)) = entry.split_once('/') else {
        return Ok(None);
    };
    let bad = |why: &str| ConfigError::HardwareInterfaces(format!("`{entry}`: {why}"));
    let net: std::net::Ipv4Addr = net
        .parse()
        .map_err(|_| bad("not an IPv4 subnet a.b.c.d/n"))?;
    let len: u32 = len
        .parse()
        .ok()
        .filter(|l| *l <= 32)
        .ok_or_else(|| bad("prefix length must be 0-32"))?;
    Ok(Some((net, u32::MAX.checked_shl(32 - len).unwrap_or(0))))
}

/// The Zenoh access-control block that keeps hardware topics off every interface of
/// `host` not in `allowed`; `None` when nothing is to be denied (`"*"` allowed, or no
/// other interface).
pub fn hardware_acl(allowed: &[String], host: &[String]) -> Option<serde_json::Value> {
    if allowed.iter().any(|a| a == "*") {
        return None;
    }
    let denied: Vec<&String> = host.iter().filter(|i| !allowed.contains(i)).collect();
    if denied.is_empty() {
        return None;
    }
    Some(serde_json::json!({
        "enabled": true,
        "default_permission": "allow",
        "rules": [{
            "id": "hardware_topics",
            "permission": "deny",
            "flows": ["egress", "ingress"],
            "messages": ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable"],
            "key_exprs": [HARDWARE_KEYS],
        }],
        "subjects": [{ "id": "off_site", "interfaces": denied }],
        "policies": [{ "rules": ["hardware_topics"], "subjects": ["off_site"] }],
    }))
}

/// Sets `key` of a Zenoh configuration to the JSON5 `value`.
///
/// # Errors
/// [`ConfigError::Zenoh`] naming the key Zenoh refused.
pub fn set_json5(cfg: &mut zenoh::Config, key: &str, value: &str) -> Result<(), ConfigError> {
    cfg.insert_json5(key, value)
        .map_err(|e| ConfigError::Zenoh {
            key: key.to_owned(),
            message: e.to_string(),
        })
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

    fn site_host() -> Vec<(String, std::net::Ipv4Addr, u32)> {
        vec![
            (
                "lo".into(),
                std::net::Ipv4Addr::new(127, 0, 0, 1),
                0xff00_0000,
            ),
            (
                "eth0".into(),
                std::net::Ipv4Addr::new(192, 0, 2, 2),
                0xffff_ff00,
            ),
            (
                "eth1".into(),
                std::net::Ipv4Addr::new(172, 30, 2, 5),
                0xffff_ff00,
            ),
        ]
    }

    #[test]
    fn a_node_listening_outside_its_hardware_interfaces_gets_a_hardware_session() {
        let host = site_host();
        // The default (loopback only) and any listener inside needs none.
        let mut z = ZenohSettings::default();
        assert_eq!(z.hardware_session_on(&host).expect("ok"), None);
        z.listen = vec![
            "tcp/127.0.0.1:0".into(),
            "unixsock-stream//tmp/a.sock".into(),
        ];
        assert_eq!(z.hardware_session_on(&host).expect("ok"), None);
        z.hardware_interfaces = vec!["lo".into(), "172.30.2.0/24".into()];
        z.listen = vec!["tcp/127.0.0.1:0".into(), "tcp/172.30.2.5:7447".into()];
        assert_eq!(z.hardware_session_on(&host).expect("ok"), None);
        // A listener for the operator site on eth0: hardware goes on a second session
        // listening on the hardware interfaces' addresses alone, dialling only
        // configured endpoints inside them.
        z.listen.push("tcp/192.0.2.2:7447#iface=eth0".into());
        z.connect = vec![
            "tcp/172.30.2.9:7447".into(),
            "tcp/192.0.2.10:7447".into(),
            "tcp/robot-router:7447".into(),
        ];
        let hw = z.hardware_session_on(&host).expect("ok").expect("needed");
        assert_eq!(hw.listen, ["tcp/127.0.0.1:0", "tcp/172.30.2.5:0"]);
        assert_eq!(hw.connect, ["tcp/172.30.2.9:7447"]);
        assert_eq!(hw.hardware_interfaces, z.hardware_interfaces);
        assert!(hw.hardware_session_on(&host).expect("ok").is_none());
        // An unspecified address is on every interface; TLS keeps TLS.
        z.listen = vec!["tls/0.0.0.0:7447".into()];
        z.tls = Some(TlsSettings {
            ca_certificate: "ca.pem".into(),
            certificate: "c.pem".into(),
            private_key: "k.pem".into(),
        });
        let hw = z.hardware_session_on(&host).expect("ok").expect("needed");
        assert_eq!(hw.listen, ["tls/127.0.0.1:0", "tls/172.30.2.5:0"]);
        // No restriction, or a client: none.
        z.hardware_interfaces = vec!["*".into()];
        assert_eq!(z.hardware_session_on(&host).expect("ok"), None);
        z.hardware_interfaces = vec!["lo".into()];
        z.mode = Mode::Client;
        assert_eq!(z.hardware_session_on(&host).expect("ok"), None);
        // A subnet the host is not on is refused as before.
        z.mode = Mode::Peer;
        z.hardware_interfaces = vec!["10.9.0.0/16".into()];
        assert!(z.hardware_session_on(&host).is_err());
    }

    #[test]
    fn default_builds_a_zenoh_config() {
        BusConfig::default()
            .zenoh
            .to_zenoh()
            .expect("default zenoh config is valid");
    }

    #[test]
    fn hardware_topics_are_denied_on_other_interfaces_only() {
        let host: Vec<String> = ["eth0", "lo", "wlan0"].map(String::from).to_vec();
        let acl = hardware_acl(&["lo".into()], &host).expect("eth0 and wlan0 denied");
        assert_eq!(
            acl["subjects"][0]["interfaces"],
            serde_json::json!(["eth0", "wlan0"])
        );
        assert_eq!(acl["rules"][0]["key_exprs"][0], HARDWARE_KEYS);
        assert!(hardware_acl(&["*".into()], &host).is_none());
        assert!(hardware_acl(&host, &host).is_none());
        // The default builds a valid Zenoh config with the block.
        BusConfig::default().zenoh.to_zenoh().expect("valid");
        assert!(host_interfaces().contains(&"lo".to_owned()));
    }

    #[test]
    fn hardware_interfaces_by_subnet_resolve_to_interface_names() {
        let ip = |s: &str| s.parse::<std::net::Ipv4Addr>().expect("ip");
        let host = vec![
            ("lo".to_owned(), ip("127.0.0.1")),
            ("eth0".to_owned(), ip("172.30.2.5")),
            ("eth1".to_owned(), ip("172.30.9.2")),
        ];
        let names = |v: &[&str]| v.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
        assert_eq!(
            resolve_interfaces(&names(&["lo", "172.30.2.0/24"]), &host).expect("resolves"),
            names(&["lo", "eth0"])
        );
        assert_eq!(
            resolve_interfaces(&names(&["172.30.0.0/16"]), &host).expect("resolves"),
            names(&["eth0", "eth1"])
        );
        assert_eq!(
            resolve_interfaces(&names(&["*"]), &host).expect("kept"),
            names(&["*"])
        );
        for (bad, why) in [
            ("10.0.0.0/8", "no interface"),
            ("172.30.2.0/33", "prefix length"),
            ("eth0/24", "not an IPv4 subnet"),
        ] {
            let e = resolve_interfaces(&names(&[bad]), &host).expect_err(bad);
            assert!(e.to_string().contains(why), "{e}");
            assert!(e.to_string().contains(bad), "{e}");
        }
        // This host's loopback by subnet.
        assert_eq!(
            resolve_interfaces(&names(&["127.0.0.0/8"]), &host_addresses()).expect("lo"),
            names(&["lo"])
        );
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
        let e = s.to_zenoh().expect_err("missing file");
        assert!(e.to_string().contains("/nonexistent/zenoh.json5"), "{e}");
    }

    #[test]
    fn batch_size_and_redial_schedule_reach_zenoh_and_bad_ones_are_named() {
        let s = ZenohSettings {
            batch_bytes: Some(16_384),
            reconnect: ReconnectSettings {
                first_ms: 50,
                max_ms: 400,
            },
            ..Default::default()
        };
        let cfg = s.to_zenoh().expect("valid");
        let json = |key: &str| cfg.get_json(key).expect(key);
        assert_eq!(json("transport/link/tx/batch_size"), "16384");
        let retry: serde_json::Value = serde_json::from_str(&json("connect/retry")).expect("json");
        assert_eq!(retry["period_init_ms"], 50);
        assert_eq!(retry["period_max_ms"], 400);
        // The default redials within half a second.
        let cfg = ZenohSettings::default().to_zenoh().expect("valid");
        let retry: serde_json::Value =
            serde_json::from_str(&cfg.get_json("connect/retry").expect("retry")).expect("json");
        assert_eq!(retry["period_max_ms"], 500);
        // Shared memory with same-host peers is on unless a node turns it off.
        assert_eq!(
            cfg.get_json("transport/shared_memory/enabled")
                .expect("shm"),
            "true"
        );
        let off = ZenohSettings {
            shared_memory: false,
            ..Default::default()
        };
        let cfg = off.to_zenoh().expect("valid");
        assert_eq!(
            cfg.get_json("transport/shared_memory/enabled")
                .expect("shm"),
            "false"
        );
        for (bad, named) in [
            (
                ZenohSettings {
                    batch_bytes: Some(100),
                    ..Default::default()
                },
                "batch_bytes",
            ),
            (
                ZenohSettings {
                    reconnect: ReconnectSettings {
                        first_ms: 500,
                        max_ms: 100,
                    },
                    ..Default::default()
                },
                "reconnect",
            ),
        ] {
            let e = bad.to_zenoh().expect_err(named).to_string();
            assert!(e.contains(named), "{e}");
        }
        // Unknown fields in the file are refused.
        let e = serde_json::from_str::<ZenohSettings>(
            r#"{"reconnect": {"first_ms": 10, "soon": true}}"#,
        )
        .expect_err("unknown field");
        assert!(e.to_string().contains("soon"), "{e}");
    }
}
