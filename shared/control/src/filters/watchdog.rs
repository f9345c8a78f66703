//! Command watchdog: is the last valid command recent enough to keep moving?
//!
//! The thesis relies on the operator's deadman switch and foot pedals (ch. 7.4-7.5);
//! across a network a remote robot also needs to stop by itself when commands stop
//! arriving. The remote site feeds this watchdog and stops (brakes) the arm whenever
//! [`Watchdog::check`] is not [`WatchdogState::Ok`].
//!
//! # Semantics
//!
//! The caller feeds `(now_s, event)` pairs from one monotonic clock, in seconds:
//!
//! * [`WatchdogEvent::ValidCommand`]: a command passed every filter; `now_s`
//!   becomes the last valid command time.
//! * [`WatchdogEvent::RejectedCommand`]: a command arrived but a filter refused it.
//!   It is counted and does **not** feed the watchdog: a stream of rejected commands
//!   expires it like silence does.
//! * [`WatchdogEvent::Disarm`]: forget the last valid command (e.g. clutch
//!   released): [`WatchdogState::NeverFed`] until the next valid one.
//!
//! [`Watchdog::check`] at `now_s`, with `age = now_s - last_valid_s`:
//! `Ok` if `0 <= age <= deadline_s` (default 0.1 s); `Expired { since_s: age }` if
//! `age > deadline_s`; `NeverFed` before any valid command (nothing to execute, so
//! nothing may move); `ClockFault` if `now_s` is not finite or lies before the last
//! valid command (the clock went backwards: fail safe). A valid command fed with a
//! non-finite time or a time before the last one is ignored and counted as a clock
//! fault.

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, positive};

/// Settings of the [`Watchdog`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WatchdogConfig {
    /// Longest accepted age of the last valid command, seconds. Default 0.1
    /// (three periods of the thesis' 30 Hz command stream).
    pub deadline_s: f64,
}

impl Default for WatchdogConfig {
    fn default() -> Self {
        Self { deadline_s: 0.1 }
    }
}

/// What happened, fed to [`Watchdog::feed`] with the time it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WatchdogEvent {
    /// A command passed every filter and is being executed.
    ValidCommand,
    /// A command arrived and was refused; does not feed the watchdog.
    RejectedCommand,
    /// Forget the last valid command (motion deliberately disabled).
    Disarm,
}

/// The verdict of [`Watchdog::check`]. Everything but `Ok` means: stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WatchdogState {
    /// The last valid command is at most `deadline_s` old: motion may continue.
    Ok,
    /// No valid command since construction or [`WatchdogEvent::Disarm`].
    NeverFed,
    /// The last valid command is older than the deadline.
    Expired {
        /// Age of the last valid command, seconds (`> deadline_s`).
        since_s: f64,
    },
    /// The time given is not finite or is before the last valid command.
    ClockFault,
}

impl WatchdogState {
    /// `true` for [`WatchdogState::Ok`] only.
    pub fn is_ok(&self) -> bool {
        matches!(self, WatchdogState::Ok)
    }
}

/// Tracks the last valid command time against a deadline; see the
/// [module docs](self).
#[derive(Debug, Clone)]
pub struct Watchdog {
    config: WatchdogConfig,
    last_valid_s: Option<f64>,
    valid_commands: u64,
    rejected_commands: u64,
    clock_faults: u64,
}

impl Watchdog {
    /// A watchdog in state [`WatchdogState::NeverFed`].
    ///
    /// # Errors
    ///
    /// [`ConfigError::NotPositive`] if `deadline_s` is not finite and positive.
    pub fn new(config: WatchdogConfig) -> Result<Self, ConfigError> {
        positive("deadline_s", config.deadline_s)?;
        Ok(Self {
            config,
            last_valid_s: None,
            valid_commands: 0,
            rejected_commands: 0,
            clock_faults: 0,
        })
    }

    /// Records `event` at `now_s`.
    pub fn feed(&mut self, now_s: f64, event: WatchdogEvent) {
        match event {
            WatchdogEvent::ValidCommand => {
                let monotonic = self.last_valid_s.is_none_or(|last| now_s >= last);
                if now_s.is_finite() && monotonic {
                    self.last_valid_s = Some(now_s);
                    self.valid_commands = self.valid_commands.saturating_add(1);
                } else {
                    self.clock_faults = self.clock_faults.saturating_add(1);
                }
            }
            WatchdogEvent::RejectedCommand => {
                self.rejected_commands = self.rejected_commands.saturating_add(1);
            }
            WatchdogEvent::Disarm => self.last_valid_s = None,
        }
    }

    /// The verdict at `now_s`.
    pub fn check(&self, now_s: f64) -> WatchdogState {
        let Some(last) = self.last_valid_s else {
            return WatchdogState::NeverFed;
        };
        if !now_s.is_finite() || now_s < last {
            return WatchdogState::ClockFault;
        }
        let age_s = now_s - last;
        if age_s <= self.config.deadline_s {
            WatchdogState::Ok
        } else {
            WatchdogState::Expired { since_s: age_s }
        }
    }

    /// Time of the last valid command, seconds.
    pub fn last_valid_s(&self) -> Option<f64> {
        self.last_valid_s
    }

    /// The settings in use.
    pub fn config(&self) -> &WatchdogConfig {
        &self.config
    }

    /// `(name, count)` pairs for a status report: valid and rejected commands fed,
    /// valid commands ignored for a bad time.
    pub fn counters(&self) -> [(&'static str, u64); 3] {
        [
            ("valid_commands", self.valid_commands),
            ("rejected_commands", self.rejected_commands),
            ("clock_faults", self.clock_faults),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn watchdog() -> Watchdog {
        Watchdog::new(WatchdogConfig::default()).unwrap()
    }

    #[test]
    fn never_fed_until_a_valid_command() {
        let mut w = watchdog();
        assert_eq!(w.check(0.0), WatchdogState::NeverFed);
        w.feed(1.0, WatchdogEvent::RejectedCommand);
        assert_eq!(w.check(1.0), WatchdogState::NeverFed);
        w.feed(1.0, WatchdogEvent::ValidCommand);
        assert_eq!(w.check(1.0), WatchdogState::Ok);
    }

    #[test]
    fn expires_after_the_deadline_inclusive_boundary() {
        let mut w = watchdog();
        w.feed(10.0, WatchdogEvent::ValidCommand);
        assert!(w.check(10.05).is_ok());
        assert!(w.check(10.1).is_ok());
        assert_eq!(
            w.check(10.35),
            WatchdogState::Expired {
                since_s: 10.35 - 10.0
            }
        );
        // A new valid command revives it.
        w.feed(10.4, WatchdogEvent::ValidCommand);
        assert!(w.check(10.45).is_ok());
    }

    #[test]
    fn rejected_commands_do_not_feed() {
        let mut w = watchdog();
        w.feed(0.0, WatchdogEvent::ValidCommand);
        let mut t = 0.0;
        for _ in 0..10 {
            t += 1.0 / 30.0;
            w.feed(t, WatchdogEvent::RejectedCommand);
        }
        assert!(matches!(w.check(t), WatchdogState::Expired { since_s } if since_s > 0.3));
        assert_eq!(w.counters()[1], ("rejected_commands", 10));
    }

    #[test]
    fn steady_30_hz_stream_stays_ok() {
        let mut w = watchdog();
        for k in 0..300 {
            let t = k as f64 / 30.0;
            w.feed(t, WatchdogEvent::ValidCommand);
            assert!(w.check(t + 0.09).is_ok());
        }
        assert_eq!(w.counters()[0], ("valid_commands", 300));
    }

    #[test]
    fn disarm_forgets() {
        let mut w = watchdog();
        w.feed(0.0, WatchdogEvent::ValidCommand);
        w.feed(0.01, WatchdogEvent::Disarm);
        assert_eq!(w.check(0.02), WatchdogState::NeverFed);
        assert_eq!(w.last_valid_s(), None);
    }

    #[test]
    fn clock_faults_fail_safe() {
        let mut w = watchdog();
        w.feed(5.0, WatchdogEvent::ValidCommand);
        assert_eq!(w.check(4.9), WatchdogState::ClockFault);
        assert_eq!(w.check(f64::NAN), WatchdogState::ClockFault);
        assert_eq!(w.check(f64::INFINITY), WatchdogState::ClockFault);
        // A command stamped in the past or NaN does not move the last valid time.
        w.feed(4.0, WatchdogEvent::ValidCommand);
        w.feed(f64::NAN, WatchdogEvent::ValidCommand);
        assert_eq!(w.last_valid_s(), Some(5.0));
        assert_eq!(w.counters()[2], ("clock_faults", 2));
        let mut fresh = watchdog();
        fresh.feed(f64::NEG_INFINITY, WatchdogEvent::ValidCommand);
        assert_eq!(fresh.check(0.0), WatchdogState::NeverFed);
    }

    #[test]
    fn config_parses_and_validates() {
        let c: WatchdogConfig = toml::from_str("").unwrap();
        assert_eq!(c.deadline_s, 0.1);
        let c: WatchdogConfig = toml::from_str("deadline_s = 0.25").unwrap();
        assert_eq!(c.deadline_s, 0.25);
        assert!(toml::from_str::<WatchdogConfig>("deadline = 1.0").is_err());
        for bad in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            assert!(Watchdog::new(WatchdogConfig { deadline_s: bad }).is_err());
        }
    }
}
