//! Per-topic receive statistics: counters and a latency histogram.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use hdrhistogram::Histogram;

/// Counters and latency histogram of one subscriber. Shared between the receive
/// callback and readers; every method takes `&self`.
#[derive(Debug)]
pub struct TopicStats {
    received: AtomicU64,
    accepted: AtomicU64,
    dropped_stale: AtomicU64,
    dropped_out_of_order: AtomicU64,
    dropped_from_future: AtomicU64,
    decode_errors: AtomicU64,
    bad_attachment: AtomicU64,
    foreign: AtomicU64,
    overwritten: AtomicU64,
    /// Microseconds from source timestamp to receipt, accepted samples only.
    latency_us: Mutex<Histogram<u64>>,
}

/// A copy of the statistics at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StatsSnapshot {
    /// Every sample that reached the subscriber.
    pub received: u64,
    /// Samples handed to the application.
    pub accepted: u64,
    pub dropped_stale: u64,
    pub dropped_out_of_order: u64,
    pub dropped_from_future: u64,
    /// Payloads that failed to decode.
    pub decode_errors: u64,
    /// Samples without a valid rmw_zenoh attachment.
    pub bad_attachment: u64,
    /// Samples from a publisher the source policy or lock refuses.
    pub foreign: u64,
    /// Accepted samples replaced by a newer one before the application took them.
    pub overwritten: u64,
    pub latency_p50_us: u64,
    pub latency_p99_us: u64,
    pub latency_max_us: u64,
}

impl StatsSnapshot {
    /// All samples refused for any reason.
    pub fn rejected(&self) -> u64 {
        self.dropped_stale
            + self.dropped_out_of_order
            + self.dropped_from_future
            + self.decode_errors
            + self.bad_attachment
            + self.foreign
    }
}

/// Kinds of counted events.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    Received,
    Accepted,
    Stale,
    OutOfOrder,
    FromFuture,
    DecodeError,
    BadAttachment,
    Foreign,
    Overwritten,
}

impl Default for TopicStats {
    fn default() -> Self {
        Self::new()
    }
}

impl TopicStats {
    pub fn new() -> Self {
        // 1 us .. 100 s at 3 significant digits.
        #[allow(clippy::expect_used)]
        let hist = Histogram::new_with_bounds(1, 100_000_000, 3)
            .expect("constant histogram bounds are valid");
        Self {
            received: AtomicU64::new(0),
            accepted: AtomicU64::new(0),
            dropped_stale: AtomicU64::new(0),
            dropped_out_of_order: AtomicU64::new(0),
            dropped_from_future: AtomicU64::new(0),
            decode_errors: AtomicU64::new(0),
            bad_attachment: AtomicU64::new(0),
            foreign: AtomicU64::new(0),
            overwritten: AtomicU64::new(0),
            latency_us: Mutex::new(hist),
        }
    }

    pub fn count(&self, event: Event) {
        let c = match event {
            Event::Received => &self.received,
            Event::Accepted => &self.accepted,
            Event::Stale => &self.dropped_stale,
            Event::OutOfOrder => &self.dropped_out_of_order,
            Event::FromFuture => &self.dropped_from_future,
            Event::DecodeError => &self.decode_errors,
            Event::BadAttachment => &self.bad_attachment,
            Event::Foreign => &self.foreign,
            Event::Overwritten => &self.overwritten,
        };
        c.fetch_add(1, Ordering::Relaxed);
    }

    /// Records one latency (negative values, from clock offset, count as 0).
    pub fn record_latency_ns(&self, latency_ns: i64) {
        let us = u64::try_from(latency_ns.max(0) / 1_000).unwrap_or(0).max(1);
        if let Ok(mut h) = self.latency_us.lock() {
            h.saturating_record(us);
        }
    }

    pub fn snapshot(&self) -> StatsSnapshot {
        let (p50, p99, max) = self
            .latency_us
            .lock()
            .map(|h| {
                if h.is_empty() {
                    (0, 0, 0)
                } else {
                    (h.value_at_quantile(0.5), h.value_at_quantile(0.99), h.max())
                }
            })
            .unwrap_or_default();
        StatsSnapshot {
            received: self.received.load(Ordering::Relaxed),
            accepted: self.accepted.load(Ordering::Relaxed),
            dropped_stale: self.dropped_stale.load(Ordering::Relaxed),
            dropped_out_of_order: self.dropped_out_of_order.load(Ordering::Relaxed),
            dropped_from_future: self.dropped_from_future.load(Ordering::Relaxed),
            decode_errors: self.decode_errors.load(Ordering::Relaxed),
            bad_attachment: self.bad_attachment.load(Ordering::Relaxed),
            foreign: self.foreign.load(Ordering::Relaxed),
            overwritten: self.overwritten.load(Ordering::Relaxed),
            latency_p50_us: p50,
            latency_p99_us: p99,
            latency_max_us: max,
        }
    }

    /// Named counters, for [`teleop_msgs::NodeStatus`]: `<prefix>.received`, ...
    pub fn named_counters(&self, prefix: &str) -> Vec<(String, u64)> {
        let s = self.snapshot();
        [
            ("received", s.received),
            ("accepted", s.accepted),
            ("rejected_stale", s.dropped_stale),
            ("rejected_out_of_order", s.dropped_out_of_order),
            ("rejected_from_future", s.dropped_from_future),
            ("rejected_decode", s.decode_errors),
            ("rejected_attachment", s.bad_attachment),
            ("rejected_foreign", s.foreign),
        ]
        .into_iter()
        .map(|(n, v)| (format!("{prefix}.{n}"), v))
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_percentiles() {
        let s = TopicStats::new();
        for i in 1..=100 {
            s.count(Event::Received);
            s.count(Event::Accepted);
            s.record_latency_ns(i * 1_000_000);
        }
        s.count(Event::Stale);
        s.count(Event::DecodeError);
        s.record_latency_ns(-5);
        let snap = s.snapshot();
        assert_eq!(snap.received, 100);
        assert_eq!(snap.rejected(), 2);
        assert!((49_000..=51_000).contains(&snap.latency_p50_us), "{snap:?}");
        assert!(
            (98_000..=100_100).contains(&snap.latency_p99_us),
            "{snap:?}"
        );
        let named = s.named_counters("wrist_pose");
        assert!(named.contains(&("wrist_pose.rejected_stale".into(), 1)));
    }
}
