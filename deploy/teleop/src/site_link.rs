//! `teleop launch --wan SETTINGS`: the two sites on this machine as the compose setup
//! runs them on two, each site's nodes clients of a Zenoh router of their own, and the
//! sites' routers joined through the WAN link emulator (`teleop_wan_link`, the same
//! forwarder the compose setup's `wan-link` host runs) with delay, jitter, loss or a
//! bandwidth cap. Everything crossing between the sites (commands one way, feedback and
//! camera views the other) then takes the emulated WAN, so a task's success and time
//! can be measured against the round trip on one machine, without Docker.
//!
//! Unlike the compose setup the links are plain TCP on loopback: no TLS, no access
//! control (docs/security.md covers those; `deploy/compose/test.sh` tests them).

use std::path::Path;
use std::time::Duration;

use anyhow::{Context, bail};
use teleop_interfaces::nodes::Site;
use teleop_node::ZenohArgs;
use teleop_node::args::ModeArg;
use teleop_wan_link::Impairment;
use teleop_wan_link::proxy::{self, Emulator};
use tokio::process::{Child, Command};
use tokio::task::JoinHandle;

/// The emulator's settings from `--wan`: `key=value` words as `wan_link ctl set` takes
/// them (`delay_ms`, one way; `jitter_ms`, `loss_pct`, `retransmit_ms`, `rate_mbit`,
/// `queue_ms`), separated by spaces or commas.
///
/// # Errors
/// A word that is not `key=value`, an unknown key, or a value out of range, named.
pub fn parse_wan(settings: &str) -> anyhow::Result<Impairment> {
    let words: Vec<&str> = settings
        .split([' ', ','])
        .filter(|w| !w.is_empty())
        .collect();
    if words.is_empty() {
        bail!("--wan: no settings; give e.g. --wan delay_ms=25 (one way: 50 ms round trip)");
    }
    Impairment::default()
        .with(&words)
        .with_context(|| format!("--wan {settings:?}"))
}

/// One line for reports: the link as configured, with the round trip it adds.
#[must_use]
pub fn describe(link: &Impairment) -> String {
    format!(
        "emulated WAN between the sites' routers: {} (round trip {:.0} ms)",
        link.describe(),
        2.0 * link.delay_ms
    )
}

/// The two routers and the emulator between them.
pub struct SiteLink {
    /// Killed when dropped (`kill_on_drop`).
    routers: Vec<(Site, Child)>,
    /// Held for its drop: the emulator's task ends with the link.
    _forward: AbortOnDrop,
    ports: [u16; 2],
    link: Impairment,
}

impl SiteLink {
    /// Starts the robot site's router, the emulator in front of it, and the operator
    /// site's router connected through the emulator (in that order, each listening
    /// before the next starts), in domain `base.domain_id`; `seed` seeds the jitter and
    /// loss draws.
    ///
    /// # Errors
    /// `base` already choosing the sessions' mode or endpoints (the link sets those), a
    /// router that does not start or listen within 10 s, the emulator's socket.
    pub async fn start(link: Impairment, seed: u64, base: &ZenohArgs) -> anyhow::Result<Self> {
        if base.mode.is_some()
            || !base.connect.is_empty()
            || !base.listen.is_empty()
            || base.zenoh_config.is_some()
            || base.tls_ca.is_some()
        {
            bail!(
                "--wan runs the sites' routers and connects the nodes to them itself: give it without --mode, --connect, --listen, --zenoh-config or --tls-*"
            );
        }
        let exe = std::env::current_exe().context("locating the teleop binary")?;
        let remote_port = teleop_bus::testing::free_port().context("a port for a router")?;
        let local_port = teleop_bus::testing::free_port().context("a port for a router")?;
        let remote = start_router(&exe, base, remote_port, None).await?;
        let emulator = Emulator::new(link, seed, teleop_wan_link::DEFAULT_SOCKET_KB);
        let listener = emulator
            .listen("127.0.0.1:0")
            .await
            .context("the WAN emulator's socket")?;
        let wan = proxy::bound(&listener);
        // Aborted if the operator site's router fails to start, or with the link.
        let forward = AbortOnDrop(tokio::spawn(proxy::forward(
            emulator,
            listener,
            format!("127.0.0.1:{remote_port}"),
        )));
        // Small kernel buffers on the WAN link, as the compose routers have them: what a
        // site sends across waits in Zenoh's priority queues, not in the kernel's.
        let local = start_router(
            &exe,
            base,
            local_port,
            Some(format!("tcp/{wan}#so_sndbuf=16384;so_rcvbuf=16384")),
        )
        .await?;
        tracing::info!(link = %link.describe(), local_port, remote_port, %wan, "sites joined through the WAN emulator");
        Ok(Self {
            routers: vec![(Site::Remote, remote), (Site::Local, local)],
            _forward: forward,
            ports: [local_port, remote_port],
            link,
        })
    }

    /// The bus arguments of a process of `site`: `base` as a client of that site's
    /// router, without multicast scouting.
    #[must_use]
    pub fn site_args(&self, base: &ZenohArgs, site: Site) -> ZenohArgs {
        let port = match site {
            Site::Local => self.ports[0],
            Site::Remote => self.ports[1],
        };
        ZenohArgs {
            mode: Some(ModeArg::Client),
            connect: vec![format!("tcp/127.0.0.1:{port}")],
            no_multicast_scouting: true,
            ..base.clone()
        }
    }

    /// The link's settings.
    #[must_use]
    pub fn link(&self) -> Impairment {
        self.link
    }

    /// Stops the routers (SIGINT, then SIGKILL after 5 s) and the emulator (its task
    /// is aborted as `self` drops).
    pub async fn stop(mut self) {
        for (site, child) in &mut self.routers {
            if let Some(pid) = child.id().and_then(|p| i32::try_from(p).ok()) {
                let _ = nix::sys::signal::kill(
                    nix::unistd::Pid::from_raw(pid),
                    nix::sys::signal::Signal::SIGINT,
                );
            }
            if tokio::time::timeout(Duration::from_secs(5), child.wait())
                .await
                .is_err()
            {
                tracing::warn!(site = site.label(), "router did not stop in 5 s; killed");
                let _ = child.start_kill();
                let _ = child.wait().await;
            }
        }
    }
}

/// A task aborted when its handle is dropped: a link dropped on an early return
/// (a node that did not start, Ctrl-C) leaves no emulator forwarding behind it.
struct AbortOnDrop(JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// Starts `teleop router` listening on loopback `port` (and connecting to `connect`),
/// and waits until it accepts connections.
async fn start_router(
    exe: &Path,
    base: &ZenohArgs,
    port: u16,
    connect: Option<String>,
) -> anyhow::Result<Child> {
    let args = ZenohArgs {
        listen: vec![format!("tcp/127.0.0.1:{port}")],
        connect: connect.into_iter().collect(),
        no_multicast_scouting: true,
        ..base.clone()
    };
    let mut child = Command::new(exe)
        .args(args.to_args())
        .arg("router")
        .stdin(std::process::Stdio::null())
        .kill_on_drop(true)
        .process_group(0)
        .spawn()
        .context("starting a site router (teleop router)")?;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            bail!("the site router on port {port} exited at start: {status}");
        }
        if tokio::net::TcpStream::connect(("127.0.0.1", port))
            .await
            .is_ok()
        {
            return Ok(child);
        }
        if tokio::time::Instant::now() > deadline {
            bail!("the site router did not listen on port {port} within 10 s");
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wan_settings_are_the_emulators_and_bad_ones_are_named() {
        let link = parse_wan("delay_ms=25, jitter_ms=5 loss_pct=1").expect("valid");
        assert_eq!(link.delay_ms, 25.0);
        assert_eq!(link.jitter_ms, 5.0);
        assert!((link.loss - 0.01).abs() < 1e-12);
        assert!(
            describe(&link).contains("round trip 50 ms"),
            "{}",
            describe(&link)
        );
        for (bad, names) in [
            ("", "no settings"),
            ("delay=25", "delay"),
            ("delay_ms=-3", "delay_ms"),
            ("25", "25"),
        ] {
            let err = format!("{:#}", parse_wan(bad).expect_err(bad));
            assert!(err.contains(names), "{bad}: {err}");
        }
    }

    #[tokio::test]
    async fn the_link_refuses_sessions_that_choose_their_own_endpoints() {
        let base = ZenohArgs {
            connect: vec!["tcp/127.0.0.1:7447".into()],
            ..ZenohArgs::default()
        };
        let err = SiteLink::start(Impairment::default(), 1, &base)
            .await
            .err()
            .expect("refused");
        assert!(err.to_string().contains("--connect"), "{err}");
    }
}
