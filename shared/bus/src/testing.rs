//! Bus configurations for tests: sessions on loopback in a private domain, without
//! multicast scouting, so tests running in parallel cannot see each other.

use crate::{BusConfig, ZenohSettings};

/// A free TCP port on loopback (racy by nature; fine for tests).
///
/// # Errors
/// The port could not be found (no loopback).
pub fn free_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Two bus configurations in the private domain `domain_id`: the first listens on
/// `port`, the second connects to it (several sessions may share the second; they also
/// listen on a port of their own, so they reach each other directly once gossip tells
/// them about one another).
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
            listen: vec!["tcp/127.0.0.1:0".into()],
            connect: vec![format!("tcp/127.0.0.1:{port}")],
            multicast_scouting: false,
            ..Default::default()
        },
        ..Default::default()
    };
    (listen, connect)
}

/// [`isolated_pair`] on a free port.
///
/// # Panics
/// If no free port can be found on loopback (a test cannot run then).
#[allow(clippy::expect_used)]
pub fn loopback_pair(domain_id: u32) -> (BusConfig, BusConfig) {
    isolated_pair(domain_id, free_port().expect("a free port on loopback"))
}
