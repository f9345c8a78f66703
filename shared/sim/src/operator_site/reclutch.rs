//! The operator's foot on the clutch after a safety stop.
//!
//! A safety stop of the PR2 arm (a stale wrist pose, the operator site lost, ...)
//! latches until the clutch is released (`teleop_remote_site::arm_controller`): the
//! arm stays still while the operator goes on holding the pedal. A person at the
//! display sees the arm controller's status turn to Fault, lets go of the pedal and
//! presses it again, and the arm takes new references from where both now are. This
//! core is that reflex for the simulated operators: it filters the clutch they intend
//! by what has reached the operator site (the arm controller's status, at its arrival
//! time), never by the robot's state.
//!
//! * A Fault report that arrives while the clutch is held starts a reaction
//!   (`reaction_s`); then the pedal is up for `release_s` and pressed again.
//! * A press while the last report was a Fault (the fault that press answers, or one
//!   the operator knew of) is not reacted to again until a report that is not a Fault
//!   arrives (the release reached the arm and cleared the latch) or `settle_s` passes
//!   (the release may not have reached it).
//! * At most `max_tries` re-presses per held clutch: an arm that faults again at once
//!   (a node down, a hardware fault) is left alone, as a person would after a few
//!   tries; counted as given up.

use serde::{Deserialize, Serialize};

/// Settings of the clutch reflex.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReclutchConfig {
    /// Whether the operator presses the clutch again after seeing a safety stop.
    pub enabled: bool,
    /// From the Fault report's arrival to the foot lifting, s (a choice reaction to a
    /// change on the display).
    pub reaction_s: f64,
    /// How long the pedal stays up, s.
    pub release_s: f64,
    /// After a press made while the arm showed a Fault: how long a further Fault report
    /// is taken as the old one, unless a report without a fault comes first, s.
    pub settle_s: f64,
    /// Re-presses per held clutch before the operator leaves the arm stopped.
    pub max_tries: u32,
}

impl Default for ReclutchConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            reaction_s: 0.3,
            release_s: 0.4,
            settle_s: 3.0,
            max_tries: 3,
        }
    }
}

impl ReclutchConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        teleop_control::check_ranges(
            "operator_site.reclutch",
            &[
                ("reaction_s", self.reaction_s, 0.0, 10.0),
                ("release_s", self.release_s, 0.02, 10.0),
                ("settle_s", self.settle_s, 0.0, 60.0),
            ],
        )
    }
}

/// What the reflex has done so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReclutchCounts {
    /// Releases of the pedal in answer to a Fault report.
    pub reclutches: u64,
    /// Fault reports left unanswered after `max_tries` re-presses of one held clutch.
    pub gave_up: u64,
    /// Arm status reports taken in.
    pub reports: u64,
}

/// The clutch reflex (a pure core: arrival times and intentions in, the pedal out).
#[derive(Debug, Clone)]
pub struct Reclutch {
    cfg: ReclutchConfig,
    /// The last arm report said Fault.
    arm_faulted: bool,
    /// Arrival of the Fault report being reacted to.
    fault_at_s: Option<f64>,
    /// The pedal is up until then.
    up_until_s: Option<f64>,
    /// Fault reports before then are the fault the last press answered.
    settle_until_s: Option<f64>,
    /// The pedal was down at the last step.
    pressed: bool,
    /// Re-presses during the current held clutch.
    tries: u32,
    /// The current held clutch was given up on.
    given_up: bool,
    counts: ReclutchCounts,
}

impl Reclutch {
    /// # Errors
    /// An invalid config, naming the field.
    pub fn new(cfg: ReclutchConfig) -> Result<Self, String> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            arm_faulted: false,
            fault_at_s: None,
            up_until_s: None,
            settle_until_s: None,
            pressed: false,
            tries: 0,
            given_up: false,
            counts: ReclutchCounts::default(),
        })
    }

    /// A status report of the arm controller arrived at `received_s` (operator-site
    /// clock): `faulted` when its lifecycle state is Fault.
    pub fn arm_report(&mut self, received_s: f64, faulted: bool) {
        if !received_s.is_finite() {
            return;
        }
        self.counts.reports += 1;
        self.arm_faulted = faulted;
        if !faulted {
            self.fault_at_s = None;
            self.settle_until_s = None;
            return;
        }
        if self.settle_until_s.is_some_and(|t| received_s < t) {
            return;
        }
        self.settle_until_s = None;
        if self.pressed && self.fault_at_s.is_none() && self.up_until_s.is_none() {
            if self.tries >= self.cfg.max_tries {
                if !self.given_up {
                    self.given_up = true;
                    self.counts.gave_up += 1;
                }
                return;
            }
            self.fault_at_s = Some(received_s);
        }
    }

    /// The pedal at `now_s` when the operator means the clutch to be `intended`.
    pub fn pedal(&mut self, now_s: f64, intended: bool) -> bool {
        if !self.cfg.enabled {
            return intended;
        }
        if !intended {
            self.fault_at_s = None;
            self.up_until_s = None;
            self.tries = 0;
            self.given_up = false;
            self.pressed = false;
            return false;
        }
        if let Some(until) = self.up_until_s {
            if now_s < until {
                return false;
            }
            self.up_until_s = None;
        }
        if let Some(at) = self.fault_at_s
            && now_s >= at + self.cfg.reaction_s
        {
            self.fault_at_s = None;
            self.up_until_s = Some(now_s + self.cfg.release_s);
            self.tries += 1;
            self.counts.reclutches += 1;
            self.pressed = false;
            return false;
        }
        if !self.pressed {
            // A press: a fault shown now is the one this press answers.
            self.pressed = true;
            self.settle_until_s = self.arm_faulted.then_some(now_s + self.cfg.settle_s);
        }
        true
    }

    #[must_use]
    pub fn counts(&self) -> ReclutchCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.02;

    fn reflex() -> Reclutch {
        Reclutch::new(ReclutchConfig::default()).unwrap()
    }

    /// Steps the pedal from `t0` to `t1` with the clutch meant `intended`; the times the
    /// pedal was up.
    fn run(r: &mut Reclutch, t0: f64, t1: f64, intended: bool) -> Vec<f64> {
        let mut up = Vec::new();
        let mut t = t0;
        while t < t1 - 1e-9 {
            if !r.pedal(t, intended) {
                up.push(t);
            }
            t += DT;
        }
        up
    }

    #[test]
    fn a_fault_seen_while_holding_is_answered_by_a_release_and_a_press() {
        let mut r = reflex();
        assert!(run(&mut r, 0.0, 1.0, true).is_empty());
        r.arm_report(1.0, true);
        let up = run(&mut r, 1.0, 3.0, true);
        // Up from the reaction (0.3 s after the report) for 0.4 s, then pressed.
        assert!(!up.is_empty());
        assert!((up[0] - 1.3).abs() < DT + 1e-9, "{up:?}");
        let last = up[up.len() - 1];
        assert!((last - up[0] - 0.4).abs() < 2.0 * DT, "{up:?}");
        assert_eq!(r.counts().reclutches, 1);
        // The old Fault reported again (the status every second) is not answered twice.
        r.arm_report(2.0, true);
        assert!(run(&mut r, 2.0, 4.0, true).is_empty());
        // The release reached the arm: a report without a fault; a new fault is answered.
        r.arm_report(4.0, false);
        r.arm_report(5.0, true);
        let up = run(&mut r, 4.0, 7.0, true);
        assert!((up[0] - 5.3).abs() < DT + 1e-9, "{up:?}");
        assert_eq!(r.counts().reclutches, 2);
    }

    #[test]
    fn a_fault_that_outlasts_the_settle_time_is_answered_again_then_given_up() {
        let mut r = reflex();
        run(&mut r, 0.0, 0.5, true);
        let mut t = 0.5;
        // An arm that reports Fault every second and never anything else.
        while t < 30.0 {
            r.arm_report(t, true);
            run(&mut r, t, t + 1.0, true);
            t += 1.0;
        }
        assert_eq!(r.counts().reclutches, 3, "{:?}", r.counts());
        assert_eq!(r.counts().gave_up, 1);
        // A new hold starts the tries over.
        run(&mut r, t, t + 1.0, false);
        run(&mut r, t + 1.0, t + 1.5, true);
        r.arm_report(t + 1.5, false);
        r.arm_report(t + 2.0, true);
        let up = run(&mut r, t + 2.0, t + 3.0, true);
        assert!(!up.is_empty());
        assert_eq!(r.counts().reclutches, 4);
    }

    #[test]
    fn nothing_is_done_without_the_clutch_held_or_with_the_reflex_off() {
        let mut r = reflex();
        r.arm_report(0.5, true);
        assert!(run(&mut r, 0.0, 2.0, false).len() >= 99);
        assert_eq!(r.counts().reclutches, 0);
        // A press made while the arm shows the fault is the answer to it.
        assert!(run(&mut r, 2.0, 3.0, true).is_empty());
        r.arm_report(3.0, true);
        assert!(run(&mut r, 3.0, 4.0, true).is_empty());
        assert_eq!(r.counts().reclutches, 0);

        let mut off = Reclutch::new(ReclutchConfig {
            enabled: false,
            ..ReclutchConfig::default()
        })
        .unwrap();
        run(&mut off, 0.0, 1.0, true);
        off.arm_report(1.0, true);
        assert!(run(&mut off, 1.0, 3.0, true).is_empty());
        assert_eq!(off.counts().reclutches, 0);
    }

    #[test]
    fn bad_input_is_refused() {
        let e = Reclutch::new(ReclutchConfig {
            reaction_s: f64::NAN,
            ..ReclutchConfig::default()
        })
        .unwrap_err();
        assert!(e.contains("reaction_s"), "{e}");
        let e = Reclutch::new(ReclutchConfig {
            release_s: 0.0,
            ..ReclutchConfig::default()
        })
        .unwrap_err();
        assert!(e.contains("release_s"), "{e}");
        let mut r = reflex();
        run(&mut r, 0.0, 1.0, true);
        r.arm_report(f64::NAN, true);
        assert!(run(&mut r, 1.0, 2.0, true).is_empty());
        assert_eq!(r.counts().reports, 0);
    }
}
