//! When a node stops: after a set duration, or on Ctrl-C (SIGINT) or SIGTERM (what
//! `teleop launch`, `docker stop` and service managers send).

use std::future::Future;
use std::time::Duration;

/// Completes after `duration`, or on SIGINT/SIGTERM when `duration` is `None` (a
/// signal also ends a timed run early).
///
/// The signal handlers are installed when this is called, not when the future is first
/// polled: a process that calls it before it starts serving is stopped gracefully by
/// a signal that arrives at any time after (a client that has been served may
/// interrupt it at once). Call it within the async runtime. The timer starts at the
/// first poll.
pub fn stop_signal(duration: Option<Duration>) -> impl Future<Output = ()> {
    let signals = Signals::install();
    async move {
        let timer = async {
            match duration {
                Some(d) => tokio::time::sleep(d).await,
                None => std::future::pending::<()>().await,
            }
        };
        tokio::select! {
            () = timer => {}
            () = signals.recv() => {}
        }
    }
}

/// SIGINT and SIGTERM, watched from the moment they are installed.
#[cfg(unix)]
struct Signals {
    interrupt: Option<tokio::signal::unix::Signal>,
    terminate: Option<tokio::signal::unix::Signal>,
}

#[cfg(unix)]
impl Signals {
    fn install() -> Self {
        use tokio::signal::unix::{SignalKind, signal};
        let watch = |kind: SignalKind, name: &str| match signal(kind) {
            Ok(s) => Some(s),
            Err(e) => {
                tracing::warn!("cannot watch {name} ({e})");
                None
            }
        };
        Self {
            interrupt: watch(SignalKind::interrupt(), "SIGINT"),
            terminate: watch(SignalKind::terminate(), "SIGTERM"),
        }
    }

    async fn recv(self) {
        async fn one(s: Option<tokio::signal::unix::Signal>) {
            match s {
                Some(mut s) => {
                    s.recv().await;
                }
                None => std::future::pending::<()>().await,
            }
        }
        tokio::select! {
            () = one(self.interrupt) => {}
            () = one(self.terminate) => {}
        }
    }
}

#[cfg(not(unix))]
struct Signals;

#[cfg(not(unix))]
impl Signals {
    fn install() -> Self {
        Self
    }

    async fn recv(self) {
        let _ = tokio::signal::ctrl_c().await;
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    /// A duration ends it without a signal; a signal sent after `stop_signal` is called
    /// and before its future is first polled stops it (the handler was installed at the
    /// call) and does not kill the process. One test: a signal reaches every watcher
    /// of the process.
    #[tokio::test]
    async fn a_duration_ends_it_and_a_signal_before_the_first_poll_is_not_lost() {
        let started = std::time::Instant::now();
        stop_signal(Some(Duration::from_millis(50))).await;
        assert!(started.elapsed() >= Duration::from_millis(50));

        let stop = stop_signal(None);
        nix::sys::signal::raise(nix::sys::signal::Signal::SIGTERM).expect("raise");
        tokio::time::timeout(Duration::from_secs(5), stop)
            .await
            .expect("stopped by the signal sent before the first poll");
    }
}
