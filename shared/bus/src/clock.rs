//! The clock a node reads: wall time in production, scripted time in tests. The bus
//! stamps what it publishes (source timestamp) and what it receives (receive time) with
//! the node's clock, so a test that drives every node of a scenario from one
//! [`ManualClock`] sees consistent ages, deadlines and timeouts end to end.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};

/// Nanoseconds since the Unix epoch, as a node sees them.
pub trait Clock: Send + Sync + std::fmt::Debug {
    /// Now, ns since the Unix epoch.
    fn now_ns(&self) -> i64;

    /// Now, s since the Unix epoch.
    fn now_s(&self) -> f64 {
        // Nanoseconds since 1970 stay far below 2^63 and lose < 1 us as f64.
        #[allow(clippy::cast_precision_loss)]
        let ns = self.now_ns() as f64;
        ns * 1e-9
    }
}

/// The system's wall clock (`CLOCK_REALTIME`): what every node runs on, and what makes
/// source timestamps comparable between machines with synchronized clocks.
#[derive(Debug, Clone, Copy, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now_ns(&self) -> i64 {
        teleop_msgs::unix_nanos_now()
    }
}

/// A clock that moves only when told to: for tests that script time.
#[derive(Debug, Default)]
pub struct ManualClock {
    now_ns: AtomicI64,
}

impl ManualClock {
    /// A clock at `start_s` seconds since the epoch.
    pub fn starting_at(start_s: f64) -> Arc<Self> {
        let clock = Arc::new(Self::default());
        clock.set_s(start_s);
        clock
    }

    /// Jumps to `t_s` (may go backwards: the nodes must cope).
    pub fn set_s(&self, t_s: f64) {
        // Test times are far below the i64 range of nanoseconds.
        #[allow(clippy::cast_possible_truncation)]
        self.now_ns
            .store((t_s * 1e9).round() as i64, Ordering::SeqCst);
    }

    /// Moves forward by `dt_s`.
    pub fn advance_s(&self, dt_s: f64) {
        #[allow(clippy::cast_possible_truncation)]
        self.now_ns
            .fetch_add((dt_s * 1e9).round() as i64, Ordering::SeqCst);
    }
}

impl Clock for ManualClock {
    fn now_ns(&self) -> i64 {
        self.now_ns.load(Ordering::SeqCst)
    }
}

/// The clock every node uses unless a test passes another.
pub fn system() -> Arc<dyn Clock> {
    Arc::new(SystemClock)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_clock_moves_only_when_told() {
        let c = ManualClock::starting_at(100.0);
        assert_eq!(c.now_ns(), 100_000_000_000);
        c.advance_s(0.25);
        assert!((c.now_s() - 100.25).abs() < 1e-9);
        c.set_s(1.0);
        assert_eq!(c.now_ns(), 1_000_000_000);
        let sys = SystemClock.now_s();
        assert!(sys > 1.7e9, "system clock reads Unix time, got {sys}");
    }
}
