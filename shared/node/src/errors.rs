//! What a node's status says under `last_error`: the errors that hold now, and once none
//! does, the last one marked recovered with the time its cause went away.
//!
//! Two kinds of error. A **condition** lasts until its cause is gone ("hardware not
//! connected", "safety stop latched"): the node sets it while the cause holds and
//! resolves it when the cause is gone. An **event** happens at an instant (a refused
//! message, a failed publish): it is current for [`EVENT_HOLD_S`] after it last
//! happened, then counts as recovered. Each becomes current with one warning in the log
//! (not one per occurrence or change of text, so a flood of refused messages does not
//! flood the log) and leaves with one info line saying how long it lasted.

use std::fmt::Write as _;

/// How long an event stays current after it last happened, s.
pub const EVENT_HOLD_S: f64 = 5.0;

/// The prefix of a `last_error` whose cause is gone.
pub const RECOVERED_PREFIX: &str = "recovered at ";

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Condition,
    Event,
}

#[derive(Debug, Clone)]
struct Current {
    cause: &'static str,
    text: String,
    kind: Kind,
    since_s: f64,
    last_s: f64,
}

/// A node's current errors (see the module's documentation).
#[derive(Debug, Clone, Default)]
pub struct NodeErrors {
    current: Vec<Current>,
    /// The last error that left, and when (node clock, s).
    recovered: Option<(String, f64)>,
}

impl NodeErrors {
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// A condition named `cause` holds at `now_s` with `text` (a new text replaces the
    /// old one; the time it began is kept).
    pub fn condition(&mut self, cause: &'static str, text: impl Into<String>, now_s: f64) {
        self.raise(cause, text.into(), Kind::Condition, now_s);
    }

    /// An event named `cause` happened at `now_s`.
    pub fn event(&mut self, cause: &'static str, text: impl Into<String>, now_s: f64) {
        self.raise(cause, text.into(), Kind::Event, now_s);
    }

    /// The cause of the condition (or event) `cause` is gone at `now_s`.
    pub fn resolved(&mut self, cause: &'static str, now_s: f64) {
        if let Some(i) = self.current.iter().position(|c| c.cause == cause) {
            let gone = self.current.remove(i);
            self.leave(gone, now_s);
        }
    }

    /// Events that last happened more than [`EVENT_HOLD_S`] before `now_s` leave.
    pub fn step(&mut self, now_s: f64) {
        while let Some(i) = self
            .current
            .iter()
            .position(|c| c.kind == Kind::Event && now_s - c.last_s > EVENT_HOLD_S)
        {
            let gone = self.current.remove(i);
            let at = gone.last_s + EVENT_HOLD_S;
            self.leave(gone, at);
        }
    }

    /// Whether `cause` is current.
    #[must_use]
    pub fn is_current(&self, cause: &str) -> bool {
        self.current.iter().any(|c| c.cause == cause)
    }

    /// The status's `last_error`: the newest current error (with how many more hold),
    /// else the last one that left, marked `recovered at HH:MM:SS.s UTC: `, else empty.
    #[must_use]
    pub fn text(&self) -> String {
        if let Some(newest) = self
            .current
            .iter()
            .max_by(|a, b| a.last_s.total_cmp(&b.last_s))
        {
            let mut out = newest.text.clone();
            let more = self.current.len() - 1;
            if more > 0 {
                let _ = write!(out, " (and {more} more)");
            }
            return out;
        }
        match &self.recovered {
            Some((text, at)) => format!("{RECOVERED_PREFIX}{} UTC: {text}", clock_of_day(*at)),
            None => String::new(),
        }
    }

    fn raise(&mut self, cause: &'static str, text: String, kind: Kind, now_s: f64) {
        match self.current.iter_mut().find(|c| c.cause == cause) {
            Some(c) => {
                // Quietly: a text may change on every occurrence (an age, a count).
                c.text = text;
                c.kind = kind;
                c.last_s = now_s;
            }
            None => {
                tracing::warn!("{text}");
                self.current.push(Current {
                    cause,
                    text,
                    kind,
                    since_s: now_s,
                    last_s: now_s,
                });
            }
        }
    }

    fn leave(&mut self, gone: Current, at_s: f64) {
        tracing::info!(
            "recovered after {:.1} s: {}",
            (at_s - gone.since_s).max(0.0),
            gone.text
        );
        self.recovered = Some((gone.text, at_s));
    }
}

/// `HH:MM:SS.s` of a time in seconds since the Unix epoch (UTC).
fn clock_of_day(t_s: f64) -> String {
    if !t_s.is_finite() {
        return format!("{t_s}");
    }
    let day = t_s.rem_euclid(86_400.0);
    // In [0, 86400): the casts cannot truncate or lose a sign.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let (h, m) = ((day / 3600.0) as u32, ((day % 3600.0) / 60.0) as u32);
    format!("{h:02}:{m:02}:{:04.1}", day % 60.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_condition_holds_until_resolved_then_shows_recovered_with_its_time() {
        let mut e = NodeErrors::new();
        assert_eq!(e.text(), "");
        // 1 Jan 2026, 10:00:00 UTC.
        let t0 = 1_767_261_600.0;
        e.condition("hardware", "hardware not connected: no pr2_arm state", t0);
        e.step(t0 + 60.0);
        assert_eq!(e.text(), "hardware not connected: no pr2_arm state");
        assert!(e.is_current("hardware"));
        e.resolved("hardware", t0 + 62.5);
        assert!(!e.is_current("hardware"));
        assert_eq!(
            e.text(),
            "recovered at 10:01:02.5 UTC: hardware not connected: no pr2_arm state"
        );
        // Resolving what is not current changes nothing.
        e.resolved("hardware", t0 + 70.0);
        assert!(e.text().starts_with("recovered at 10:01:02.5"));
    }

    #[test]
    fn an_event_is_current_for_its_hold_after_it_last_happened() {
        let mut e = NodeErrors::new();
        let t0 = 1000.0;
        e.event("wrist", "wrist pose refused", t0);
        e.event("wrist", "wrist pose refused", t0 + 3.0);
        e.step(t0 + 3.0 + EVENT_HOLD_S - 0.1);
        assert_eq!(e.text(), "wrist pose refused");
        e.step(t0 + 3.0 + EVENT_HOLD_S + 0.1);
        assert!(e.text().starts_with(RECOVERED_PREFIX), "{}", e.text());
        assert!(e.text().ends_with(": wrist pose refused"));
    }

    #[test]
    fn the_newest_current_error_shows_with_a_count_of_the_others() {
        let mut e = NodeErrors::new();
        e.condition("hardware", "hardware lost", 10.0);
        e.event("publish", "publishing failed", 11.0);
        assert_eq!(e.text(), "publishing failed (and 1 more)");
        e.step(11.0 + EVENT_HOLD_S + 1.0);
        // The event left; the condition still holds and is what shows.
        assert_eq!(e.text(), "hardware lost");
        // A new text for the same cause replaces the old one.
        e.condition("hardware", "hardware lost again", 20.0);
        assert_eq!(e.text(), "hardware lost again");
    }

    #[test]
    fn times_of_day_format_in_utc() {
        assert_eq!(clock_of_day(0.0), "00:00:00.0");
        assert_eq!(clock_of_day(86_399.94), "23:59:59.9");
        assert_eq!(clock_of_day(3_723.3), "01:02:03.3");
        assert_eq!(clock_of_day(f64::NAN), "NaN");
    }
}
