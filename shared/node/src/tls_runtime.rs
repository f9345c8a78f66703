//! Zenoh's TLS link (zenoh-link-tls 1.10.2) reads and writes one TLS stream from its
//! receive and transmit tasks without a lock between them (eclipse-zenoh/zenoh#2557,
//! open upstream); when the two run on different threads at once the stream's state is
//! corrupted, and a process under load aborts (seen here: a router and the hand
//! controller, "memory allocation of 140... bytes failed" inside rustls, within 40 s of
//! a compose run). Zenoh's runtime settings (the `ZENOH_RUNTIME` environment variable,
//! read once when the process starts) can hand the receive tasks over to the one-thread
//! transmit runtime, so the two never run at the same time: the same system ran 6 x 40 s
//! without an abort, against 3 aborts in 2 x 40 s without (docs/security.md).
//!
//! A process configured for TLS therefore starts itself again with that setting when the
//! environment does not name one; nobody has to set it by hand.

use teleop_bus::BusConfig;

/// The environment variable zenoh reads its runtime settings from.
pub const ZENOH_RUNTIME_ENV: &str = "ZENOH_RUNTIME";

/// Receive tasks run on the transmit runtime, which has one worker thread.
pub const TLS_SAFE_RUNTIME: &str = "(rx: (handover: tx), tx: (worker_threads: 1))";

/// Whether a process with `cfg` must be started again with [`TLS_SAFE_RUNTIME`]: it uses
/// TLS, and the environment (`runtime_env`, the variable's value) sets no runtime.
pub fn needs_safe_runtime(cfg: &BusConfig, runtime_env: Option<&std::ffi::OsStr>) -> bool {
    cfg.zenoh.tls.is_some() && runtime_env.is_none()
}

/// With TLS configured and no `ZENOH_RUNTIME` set, replaces this process by the same
/// program with the same arguments and [`TLS_SAFE_RUNTIME`] (same process id: `docker
/// stop` and launchers still reach it). Returns `Ok` when nothing is to be done.
///
/// # Errors
/// The program could not be started again.
pub fn ensure_safe_runtime(cfg: &BusConfig) -> std::io::Result<()> {
    if !needs_safe_runtime(cfg, std::env::var_os(ZENOH_RUNTIME_ENV).as_deref()) {
        return Ok(());
    }
    use std::os::unix::process::CommandExt;
    let exe = std::env::current_exe()?;
    tracing::debug!("TLS: starting again with {ZENOH_RUNTIME_ENV}={TLS_SAFE_RUNTIME}");
    // `exec` returns only on failure.
    Err(std::process::Command::new(exe)
        .args(std::env::args_os().skip(1))
        .env(ZENOH_RUNTIME_ENV, TLS_SAFE_RUNTIME)
        .exec())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_tls_without_a_runtime_setting_starts_again() {
        let mut cfg = BusConfig::default();
        assert!(!needs_safe_runtime(&cfg, None));
        cfg.zenoh.tls = Some(teleop_bus::TlsSettings {
            ca_certificate: "ca.pem".into(),
            certificate: "n.pem".into(),
            private_key: "n.key".into(),
        });
        assert!(needs_safe_runtime(&cfg, None));
        assert!(!needs_safe_runtime(
            &cfg,
            Some(std::ffi::OsStr::new(TLS_SAFE_RUNTIME))
        ));
    }
}
