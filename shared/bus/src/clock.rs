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

    /// How many of this clock's seconds pass per second of the wall clock: what the node
    /// runner divides its periods by. 1 for the system clock.
    fn rate(&self) -> f64 {
        1.0
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

/// Simulated time that runs `scale` times as fast as the wall clock and agrees with it
/// at `origin_ns` (`teleop launch --time-scale`): every process of one run is given the
/// same origin and scale, so their stamps stay comparable. A scale below 1 runs the
/// system in slow motion (a machine too slow for the real-time rates keeps every
/// period in simulated time), above 1 faster than real time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledClock {
    origin_ns: i64,
    scale: f64,
}

/// The scales a [`ScaledClock`] accepts, `[min, max]`.
pub const TIME_SCALE_RANGE: (f64, f64) = (0.05, 20.0);

impl ScaledClock {
    /// # Errors
    /// A text naming the scale when it is not within [`TIME_SCALE_RANGE`].
    pub fn new(origin_ns: i64, scale: f64) -> Result<Self, String> {
        if scale.is_finite() && (TIME_SCALE_RANGE.0..=TIME_SCALE_RANGE.1).contains(&scale) {
            Ok(Self { origin_ns, scale })
        } else {
            Err(format!(
                "time scale must be in [{}, {}], got {scale}",
                TIME_SCALE_RANGE.0, TIME_SCALE_RANGE.1
            ))
        }
    }

    /// The time at wall-clock time `wall_ns`, ns since the epoch.
    pub fn at(&self, wall_ns: i64) -> i64 {
        // Differences of ns timestamps within a run lose nothing that matters as f64
        // (< 1 ns per 100 days).
        #[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
        let scaled = ((wall_ns - self.origin_ns) as f64 * self.scale).round() as i64;
        self.origin_ns + scaled
    }
}

impl Clock for ScaledClock {
    fn now_ns(&self) -> i64 {
        self.at(teleop_msgs::unix_nanos_now())
    }

    fn rate(&self) -> f64 {
        self.scale
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
    fn scaled_clock_runs_at_its_scale_from_its_origin() {
        let c = ScaledClock::new(1_000_000_000_000, 2.0).expect("valid");
        assert_eq!(c.at(1_000_000_000_000), 1_000_000_000_000);
        assert_eq!(c.at(1_000_500_000_000), 1_001_000_000_000);
        assert_eq!(c.rate(), 2.0);
        let slow = ScaledClock::new(0, 0.5).expect("valid");
        assert_eq!(slow.at(10_000), 5_000);
        for bad in [0.0, -1.0, 0.01, 25.0, f64::NAN, f64::INFINITY] {
            let e = ScaledClock::new(0, bad).expect_err("out of range");
            assert!(e.contains("time scale"), "{e}");
        }
        assert_eq!(SystemClock.rate(), 1.0);
    }

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
