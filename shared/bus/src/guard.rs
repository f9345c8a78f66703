//! Receive-side protections, as a pure state machine: sequence order per publisher and
//! a deadline on the source timestamp. The subscriber feeds it every sample with the
//! receive time; tests drive it with scripted times.

use std::collections::HashMap;

use crate::attachment::Attachment;

/// Settings of a [`ReceiveGuard`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardSettings {
    /// Drop samples whose sequence number is not above the last accepted one from the
    /// same publisher.
    pub enforce_order: bool,
    /// Maximum age of a sample at receipt (receive time minus source timestamp), ns.
    pub deadline_ns: Option<i64>,
    /// Tolerated clock offset between machines, ns: added to the deadline, and the
    /// largest amount a source timestamp may lie in the future.
    pub clock_tolerance_ns: i64,
}

impl GuardSettings {
    /// The oldest a sample may be and still be taken: the deadline plus the clock
    /// tolerance, ns (`None`: no deadline). The guard judges receipt by it; a
    /// consumer that acts on a sample later re-checks its age against the same limit.
    #[must_use]
    pub fn max_age_ns(&self) -> Option<i64> {
        self.deadline_ns
            .map(|d| d.saturating_add(self.clock_tolerance_ns))
    }
}

/// What the guard decided about one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    Accept,
    /// Sequence number not newer than `last` from this publisher.
    OutOfOrder {
        sequence: i64,
        last: i64,
    },
    /// Older than the deadline.
    Stale {
        age_ns: i64,
    },
    /// Source timestamp further in the future than the clock tolerance.
    FromFuture {
        ahead_ns: i64,
    },
}

/// Most publishers remembered per topic; beyond this the guard forgets the publisher
/// seen longest ago, so a flood of made-up GIDs cannot grow memory without bound.
const MAX_PUBLISHERS: usize = 64;

/// Per-topic receive guard.
#[derive(Debug)]
pub struct ReceiveGuard {
    settings: GuardSettings,
    /// GID -> (last accepted sequence, receive time of it).
    last: HashMap<[u8; 16], (i64, i64)>,
}

impl ReceiveGuard {
    pub fn new(settings: GuardSettings) -> Self {
        Self {
            settings,
            last: HashMap::new(),
        }
    }

    pub fn settings(&self) -> &GuardSettings {
        &self.settings
    }

    /// Judges one sample received at `now_ns` (ns since Unix epoch, receiver clock).
    pub fn check(&mut self, att: &Attachment, now_ns: i64) -> Verdict {
        let age_ns = now_ns.saturating_sub(att.source_timestamp_ns);
        if -age_ns > self.settings.clock_tolerance_ns {
            return Verdict::FromFuture { ahead_ns: -age_ns };
        }
        if let Some(max_age) = self.settings.max_age_ns()
            && age_ns > max_age
        {
            return Verdict::Stale { age_ns };
        }
        if self.settings.enforce_order {
            if let Some(&(last, _)) = self.last.get(&att.gid)
                && att.sequence <= last
            {
                return Verdict::OutOfOrder {
                    sequence: att.sequence,
                    last,
                };
            }
            if self.last.len() >= MAX_PUBLISHERS && !self.last.contains_key(&att.gid) {
                let oldest = self
                    .last
                    .iter()
                    .min_by_key(|(_, (_, t))| *t)
                    .map(|(gid, _)| *gid);
                if let Some(gid) = oldest {
                    self.last.remove(&gid);
                }
            }
            self.last.insert(att.gid, (att.sequence, now_ns));
        }
        Verdict::Accept
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn att(gid: u8, sequence: i64, ts: i64) -> Attachment {
        Attachment {
            sequence,
            source_timestamp_ns: ts,
            gid: [gid; 16],
        }
    }

    fn guard() -> ReceiveGuard {
        ReceiveGuard::new(GuardSettings {
            enforce_order: true,
            deadline_ns: Some(100 * MS),
            clock_tolerance_ns: 5 * MS,
        })
    }

    #[test]
    fn order_is_per_publisher() {
        let mut g = guard();
        let t = 1_000 * MS;
        assert_eq!(g.check(&att(1, 5, t), t), Verdict::Accept);
        assert_eq!(
            g.check(&att(1, 5, t), t),
            Verdict::OutOfOrder {
                sequence: 5,
                last: 5
            }
        );
        assert_eq!(
            g.check(&att(1, 4, t), t),
            Verdict::OutOfOrder {
                sequence: 4,
                last: 5
            }
        );
        // Another publisher has its own sequence.
        assert_eq!(g.check(&att(2, 1, t), t), Verdict::Accept);
        assert_eq!(g.check(&att(1, 6, t), t), Verdict::Accept);
    }

    #[test]
    fn deadline_with_clock_tolerance() {
        let mut g = guard();
        let now = 10_000 * MS;
        assert_eq!(g.check(&att(1, 1, now - 104 * MS), now), Verdict::Accept);
        assert_eq!(
            g.check(&att(1, 2, now - 106 * MS), now),
            Verdict::Stale { age_ns: 106 * MS }
        );
        assert_eq!(g.check(&att(1, 3, now + 4 * MS), now), Verdict::Accept);
        assert_eq!(
            g.check(&att(1, 4, now + 6 * MS), now),
            Verdict::FromFuture { ahead_ns: 6 * MS }
        );
        // Extreme timestamps do not overflow.
        assert!(matches!(
            g.check(&att(1, 5, i64::MIN), now),
            Verdict::Stale { .. }
        ));
        assert!(matches!(
            g.check(&att(1, 6, i64::MAX), now),
            Verdict::FromFuture { .. }
        ));
    }

    #[test]
    fn stale_sample_does_not_advance_sequence() {
        let mut g = guard();
        let now = 10_000 * MS;
        assert!(matches!(
            g.check(&att(1, 9, now - 500 * MS), now),
            Verdict::Stale { .. }
        ));
        assert_eq!(g.check(&att(1, 2, now), now), Verdict::Accept);
    }

    #[test]
    fn publisher_memory_is_bounded() {
        let mut g = guard();
        let now = 10_000 * MS;
        for i in 0..1000u32 {
            let mut a = att(0, 1, now);
            a.gid[..4].copy_from_slice(&i.to_le_bytes());
            assert_eq!(g.check(&a, now + i64::from(i)), Verdict::Accept);
        }
        assert!(g.last.len() <= MAX_PUBLISHERS);
    }

    #[test]
    fn no_order_no_deadline_accepts_repeats() {
        let mut g = ReceiveGuard::new(GuardSettings {
            enforce_order: false,
            deadline_ns: None,
            clock_tolerance_ns: MS,
        });
        assert_eq!(g.check(&att(1, 1, 0), 10_000 * MS), Verdict::Accept);
        assert_eq!(g.check(&att(1, 1, 0), 10_000 * MS), Verdict::Accept);
    }
}
