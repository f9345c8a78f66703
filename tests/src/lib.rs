//! Helpers for the cross-crate tests.

use std::path::PathBuf;

use teleop_bus::{BusConfig, ZenohSettings};

pub mod scenarios;

/// The repository root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .unwrap_or_default()
}

/// A free TCP port on loopback (racy by nature; fine for tests).
pub fn free_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Two bus configurations in a private domain: the first listens on `port`, the second
/// connects to it (several nodes may share the second); no multicast scouting, so
/// parallel tests cannot see each other.
pub fn isolated_pair(domain_id: u32, port: u16) -> (BusConfig, BusConfig) {
    let listen = BusConfig {
        domain_id,
        zenoh: ZenohSettings {
            listen: vec![format!("tcp/127.0.0.1:{port}")],
            multicast_scouting: false,
            ..Default::default()
        },
        ..Default::default()
    };
    let connect = BusConfig {
        domain_id,
        zenoh: ZenohSettings {
            // Listening too lets the connecting nodes reach each other directly once
            // gossip tells them about one another.
            listen: vec!["tcp/127.0.0.1:0".into()],
            connect: vec![format!("tcp/127.0.0.1:{port}")],
            multicast_scouting: false,
            ..Default::default()
        },
        ..Default::default()
    };
    (listen, connect)
}
