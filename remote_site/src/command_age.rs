//! The last check before a command from the operator site is executed: how old it is
//! when the controller takes it, and in which order commands were taken.
//!
//! The bus's receive guard already refuses a sample older than its topic's deadline at
//! receipt, and one not newer than the last from the same publisher. A controller takes
//! the newest sample at its next step, a little later; [`CommandAges::admit`] measures
//! the age again at that moment (against the same limit: the deadline plus the clock
//! tolerance between machines) and refuses what has expired meanwhile, so no command
//! older than its deadline is executed. It also records every taken command's age and
//! counts any taken out of order (a sequence not above the last taken from the same
//! publisher), independently of the guard: the network tests assert both from these
//! counters (`<prefix>.executed_max_age_us`, `<prefix>.executed_out_of_order`).

use std::collections::HashMap;

use teleop_bus::guard::GuardSettings;
use teleop_node::LatencyHistogram;

/// Most publishers remembered; beyond this the one taken from longest ago is forgotten.
const MAX_PUBLISHERS: usize = 16;

/// Ages and order of the commands of one topic that a controller took.
#[derive(Debug)]
pub struct CommandAges {
    prefix: &'static str,
    /// Oldest a command may be when taken (deadline + clock tolerance), s.
    limit_s: f64,
    taken: u64,
    expired: u64,
    out_of_order: u64,
    max_age_s: f64,
    ages: LatencyHistogram,
    /// publisher -> (last taken sequence, when).
    last: HashMap<[u8; 16], (i64, f64)>,
}

impl CommandAges {
    /// Ages of the commands counted as `<prefix>.*`, against the guard's deadline plus
    /// its clock tolerance (no limit when the topic has no deadline).
    #[must_use]
    pub fn new(prefix: &'static str, latency_name: &'static str, guard: &GuardSettings) -> Self {
        let limit_s = guard
            .max_age_ns()
            .map_or(f64::INFINITY, |a| a as f64 * 1e-9);
        Self {
            prefix,
            limit_s,
            taken: 0,
            expired: 0,
            out_of_order: 0,
            max_age_s: 0.0,
            ages: LatencyHistogram::new(latency_name),
            last: HashMap::new(),
        }
    }

    /// The oldest a command may be when taken, s.
    #[must_use]
    pub fn limit_s(&self) -> f64 {
        self.limit_s
    }

    /// Whether a command sent at `sent_s` (its source timestamp, s) by publisher `gid`
    /// with `sequence` may be taken at `now_s`: not when older than the limit (counted
    /// as expired) or with a non-finite time. A taken command's age is recorded, and a
    /// sequence not above the last taken from the same publisher is counted.
    pub fn admit(&mut self, now_s: f64, sent_s: f64, gid: [u8; 16], sequence: i64) -> bool {
        let age_s = now_s - sent_s;
        if !age_s.is_finite() || age_s > self.limit_s {
            self.expired += 1;
            return false;
        }
        self.taken += 1;
        self.max_age_s = self.max_age_s.max(age_s);
        self.ages.record_s(age_s);
        if let Some(&(last, _)) = self.last.get(&gid)
            && sequence <= last
        {
            self.out_of_order += 1;
        }
        if self.last.len() >= MAX_PUBLISHERS && !self.last.contains_key(&gid) {
            let oldest = self
                .last
                .iter()
                .min_by(|a, b| a.1.1.total_cmp(&b.1.1))
                .map(|(g, _)| *g);
            if let Some(g) = oldest {
                self.last.remove(&g);
            }
        }
        let entry = self.last.entry(gid).or_insert((sequence, now_s));
        *entry = (entry.0.max(sequence), now_s);
        true
    }

    /// Commands taken so far.
    #[must_use]
    pub fn taken(&self) -> u64 {
        self.taken
    }

    /// Commands refused as expired so far.
    #[must_use]
    pub fn expired(&self) -> u64 {
        self.expired
    }

    /// Commands taken out of order so far.
    #[must_use]
    pub fn out_of_order(&self) -> u64 {
        self.out_of_order
    }

    /// The oldest taken command's age, s (0 before any).
    #[must_use]
    pub fn max_age_s(&self) -> f64 {
        self.max_age_s
    }

    /// Appends `<prefix>.executed`, `.rejected_expired`, `.executed_out_of_order`,
    /// `.executed_max_age_us`, `.execute_limit_us`, and the age distribution
    /// (`latency.<name>_us.p50/p99/max`).
    pub fn named(&self, out: &mut Vec<(String, u64)>) {
        let us = |s: f64| (s * 1e6).round().clamp(0.0, u64::MAX as f64) as u64;
        let p = self.prefix;
        out.push((format!("{p}.executed"), self.taken));
        out.push((format!("{p}.rejected_expired"), self.expired));
        out.push((format!("{p}.executed_out_of_order"), self.out_of_order));
        out.push((format!("{p}.executed_max_age_us"), us(self.max_age_s)));
        if self.limit_s.is_finite() {
            out.push((format!("{p}.execute_limit_us"), us(self.limit_s)));
        }
        self.ages.named(out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn ages() -> CommandAges {
        CommandAges::new(
            "wrist_pose",
            "wrist_pose.sent_to_executed",
            &GuardSettings {
                enforce_order: true,
                deadline_ns: Some(100 * MS),
                clock_tolerance_ns: 20 * MS,
            },
        )
    }

    #[test]
    fn a_command_older_than_deadline_plus_tolerance_is_refused_and_counted() {
        let mut a = ages();
        assert!((a.limit_s() - 0.12).abs() < 1e-12);
        assert!(a.admit(10.0, 9.95, [1; 16], 1));
        assert!(a.admit(10.0, 9.881, [1; 16], 2));
        assert!(!a.admit(10.0, 9.879, [1; 16], 3));
        assert!(!a.admit(10.0, f64::NAN, [1; 16], 4));
        assert_eq!((a.taken(), a.expired()), (2, 2));
        assert!((a.max_age_s() - 0.119).abs() < 1e-9);
        let mut c = Vec::new();
        a.named(&mut c);
        let get = |n: &str| c.iter().find(|(k, _)| k == n).map(|(_, v)| *v);
        assert_eq!(get("wrist_pose.executed"), Some(2));
        assert_eq!(get("wrist_pose.rejected_expired"), Some(2));
        assert_eq!(get("wrist_pose.executed_max_age_us"), Some(119_000));
        assert_eq!(get("wrist_pose.execute_limit_us"), Some(120_000));
        assert_eq!(get("wrist_pose.executed_out_of_order"), Some(0));
    }

    #[test]
    fn out_of_order_is_per_publisher() {
        let mut a = ages();
        assert!(a.admit(1.0, 1.0, [1; 16], 5));
        assert!(a.admit(1.0, 1.0, [2; 16], 1));
        assert!(a.admit(1.01, 1.0, [1; 16], 6));
        assert_eq!(a.out_of_order(), 0);
        assert!(a.admit(1.02, 1.0, [1; 16], 6));
        assert!(a.admit(1.03, 1.0, [1; 16], 3));
        assert_eq!(a.out_of_order(), 2);
        // The later sequence stays the reference.
        assert!(a.admit(1.04, 1.0, [1; 16], 6));
        assert_eq!(a.out_of_order(), 3);
    }

    #[test]
    fn no_deadline_means_no_limit() {
        let mut a = CommandAges::new(
            "targets",
            "targets.sent_to_executed",
            &GuardSettings {
                enforce_order: false,
                deadline_ns: None,
                clock_tolerance_ns: 0,
            },
        );
        assert!(a.admit(100.0, 0.0, [0; 16], 0));
        let mut c = Vec::new();
        a.named(&mut c);
        assert!(!c.iter().any(|(k, _)| k == "targets.execute_limit_us"));
    }
}
