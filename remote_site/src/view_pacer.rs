//! Pacing of the camera views toward the operator site by their receiver's receipts,
//! so that on a slow WAN the views give way to the feedback (docs/network.md).
//!
//! Why at the source: between the sites every topic shares one router link, and below
//! Zenoh's priority queues sit byte queues Zenoh cannot reorder (the TLS session's
//! 64 KiB of records, the kernel's send buffer, the WAN's bottleneck buffer). Views that
//! exceed a capped link fill them, and the feedback behind them waits seconds (1.4 s at
//! 1 Mbit/s, measured). So the sender must not put more views in flight than the link
//! carries without a queue: the operator's display answers each view it receives with a
//! receipt (the view's header, `teleop/remote_camera/receipts`), and this core keeps a
//! window of bytes in flight that it sizes by the round trip of the views, as LEDBAT
//! (RFC 6817) sizes its window by one-way delay:
//!
//! * the base round trip is the smallest seen in the last [`BASE_HISTORY_S`]; the
//!   queueing delay of a view is its round trip minus the base (the smallest of the
//!   last [`CURRENT_FILTER`] round trips, so jitter alone is not taken for a queue);
//! * below `target_queue_s` the window grows by up to the bytes each receipt
//!   acknowledges (only while the window is being used: an idle window does not grow);
//!   above it, the window shrinks by a quarter, at most once per round trip; a view
//!   not acknowledged within `receipt_timeout_s` is taken as lost and halves it;
//! * a view may go when the bytes in flight plus its size fit in the window, or when
//!   nothing is in flight (so at least one view per round trip crosses).
//!
//! Without receipts (no display on the operator's site reports, or pacing is off) the
//! views go unpaced, at the camera's rate limit only. A receipt changes nothing but
//! this window: receipts cannot command anything, and the routers admit them only from
//! the operator site's display (docs/security.md).

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

/// How long the smallest round trip is remembered, s.
pub const BASE_HISTORY_S: f64 = 5.0;
/// How many of the latest round trips the current one is the smallest of.
pub const CURRENT_FILTER: usize = 4;
/// The window never shrinks below this, bytes (a small view).
pub const MIN_WINDOW_BYTES: f64 = 4096.0;
/// Nor grows above this, bytes.
pub const MAX_WINDOW_BYTES: f64 = 4.0 * 1024.0 * 1024.0;
/// The window at the start and after the receiver was silent, bytes.
pub const INITIAL_WINDOW_BYTES: f64 = 64.0 * 1024.0;
/// Views remembered in flight at most (older ones are taken as lost).
const MAX_IN_FLIGHT: usize = 256;
/// Buckets of the base-round-trip history.
const BASE_BUCKETS: usize = 10;

/// Settings of the pacing (`[camera_pacing]` in the feedback publisher's config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PacingConfig {
    /// Pace the views by their receipts (off: views go at the camera rate limit only).
    pub enabled: bool,
    /// Queueing delay the views may build up on the way to the operator, s, in
    /// [0.005, 1].
    pub target_queue_s: f64,
    /// A view not acknowledged within this long is taken as lost, s, in [0.1, 10].
    pub receipt_timeout_s: f64,
    /// Without any receipt for this long the views go unpaced, s, in [1, 60] and above
    /// `receipt_timeout_s`.
    pub receiver_timeout_s: f64,
}

impl Default for PacingConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            target_queue_s: 0.05,
            receipt_timeout_s: 1.0,
            receiver_timeout_s: 5.0,
        }
    }
}

impl PacingConfig {
    /// Checks the ranges.
    ///
    /// # Errors
    /// The first setting out of range, named.
    pub fn validate(&self) -> Result<(), String> {
        let check = |name: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(format!(
                    "camera_pacing.{name} must be in [{lo}, {hi}], got {v}"
                ))
            }
        };
        check("target_queue_s", self.target_queue_s, 0.005, 1.0)?;
        check("receipt_timeout_s", self.receipt_timeout_s, 0.1, 10.0)?;
        check("receiver_timeout_s", self.receiver_timeout_s, 1.0, 60.0)?;
        if self.receiver_timeout_s <= self.receipt_timeout_s {
            return Err(format!(
                "camera_pacing.receiver_timeout_s ({}) must be above receipt_timeout_s ({})",
                self.receiver_timeout_s, self.receipt_timeout_s
            ));
        }
        Ok(())
    }
}

/// One view sent and not yet acknowledged.
#[derive(Debug, Clone)]
struct Sent {
    view: usize,
    stamp_ns: i64,
    bytes: usize,
    sent_s: f64,
    /// Bytes in flight just after it was sent (itself included).
    in_flight_after: usize,
}

/// What became of a receipt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReceiptOutcome {
    /// It acknowledged a view in flight: the round trip and the queueing delay, s.
    Acknowledged { rtt_s: f64, queue_s: f64 },
    /// No view in flight has this header (late after its timeout, or not ours).
    Unmatched,
}

/// Counters of the pacing.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct PacerCounters {
    /// Views acknowledged by a receipt.
    pub acknowledged: u64,
    /// Views taken as lost (no receipt in time).
    pub lost: u64,
    /// Views held back because the window was full.
    pub held: u64,
    /// Receipts that matched no view in flight.
    pub unmatched: u64,
}

/// The pacing core: pure, driven by the caller's clock.
#[derive(Debug, Clone)]
pub struct ViewPacer {
    cfg: PacingConfig,
    window_bytes: f64,
    in_flight: VecDeque<Sent>,
    /// Smallest round trip per bucket of `BASE_HISTORY_S / BASE_BUCKETS`: (bucket, s).
    base: VecDeque<(i64, f64)>,
    /// The latest round trips.
    recent: VecDeque<f64>,
    last_receipt_s: Option<f64>,
    last_decrease_s: f64,
    counters: PacerCounters,
}

impl ViewPacer {
    pub fn new(cfg: PacingConfig) -> Self {
        Self {
            cfg,
            window_bytes: INITIAL_WINDOW_BYTES,
            in_flight: VecDeque::new(),
            base: VecDeque::new(),
            recent: VecDeque::new(),
            last_receipt_s: None,
            last_decrease_s: f64::NEG_INFINITY,
            counters: PacerCounters::default(),
        }
    }

    /// Whether views are paced now: pacing on and a receipt within
    /// `receiver_timeout_s`.
    pub fn paced(&self, now_s: f64) -> bool {
        self.cfg.enabled
            && self
                .last_receipt_s
                .is_some_and(|t| now_s - t <= self.cfg.receiver_timeout_s)
    }

    /// The window, bytes.
    pub fn window_bytes(&self) -> f64 {
        self.window_bytes
    }

    /// Bytes in flight (sent, neither acknowledged nor lost).
    pub fn in_flight_bytes(&self) -> usize {
        self.in_flight.iter().map(|s| s.bytes).sum()
    }

    /// The smallest round trip remembered, s.
    pub fn base_rtt_s(&self) -> Option<f64> {
        self.base.iter().map(|b| b.1).reduce(f64::min)
    }

    pub fn counters(&self) -> PacerCounters {
        self.counters
    }

    /// Whether a view of about `bytes` may be sent now. Counts it as held if not.
    pub fn may_send(&mut self, now_s: f64, bytes: usize) -> bool {
        self.expire(now_s);
        if !self.paced(now_s) {
            return true;
        }
        let in_flight = self.in_flight_bytes();
        #[allow(clippy::cast_precision_loss)]
        let fits = (in_flight + bytes) as f64 <= self.window_bytes;
        if in_flight == 0 || fits {
            true
        } else {
            self.counters.held += 1;
            false
        }
    }

    /// A view was sent: `view` (index), its header stamp and its size.
    pub fn sent(&mut self, now_s: f64, view: usize, stamp_ns: i64, bytes: usize) {
        if self.in_flight.len() >= MAX_IN_FLIGHT {
            self.in_flight.pop_front();
            self.counters.lost += 1;
        }
        let in_flight_after = self.in_flight_bytes() + bytes;
        self.in_flight.push_back(Sent {
            view,
            stamp_ns,
            bytes,
            sent_s: now_s,
            in_flight_after,
        });
    }

    /// A receipt for the view `view` with header stamp `stamp_ns`. It also acknowledges
    /// the earlier views of the same camera still in flight (the receiver keeps the
    /// newest view only, so it may never have taken them).
    pub fn receipt(&mut self, now_s: f64, view: usize, stamp_ns: i64) -> ReceiptOutcome {
        let was_paced = self.paced(now_s);
        self.last_receipt_s = Some(now_s);
        if !was_paced {
            // The receiver (re)appears: start from the initial window.
            self.window_bytes = INITIAL_WINDOW_BYTES;
        }
        let Some(acked) = self
            .in_flight
            .iter()
            .position(|s| s.view == view && s.stamp_ns == stamp_ns)
            .and_then(|i| self.in_flight.remove(i))
        else {
            self.counters.unmatched += 1;
            return ReceiptOutcome::Unmatched;
        };
        let before = self.in_flight.len();
        self.in_flight
            .retain(|s| !(s.view == view && s.sent_s <= acked.sent_s));
        self.counters.acknowledged += 1 + (before - self.in_flight.len()) as u64;

        let rtt_s = (now_s - acked.sent_s).max(0.0);
        self.remember(now_s, rtt_s);
        let base = self.base_rtt_s().unwrap_or(rtt_s);
        let current = self.recent.iter().copied().fold(f64::INFINITY, f64::min);
        let queue_s = (current - base).max(0.0);
        let target = self.cfg.target_queue_s;
        if queue_s <= target {
            // Grow only a window in use: the view went out with at least half of it
            // in flight.
            #[allow(clippy::cast_precision_loss)]
            if acked.in_flight_after as f64 >= 0.5 * self.window_bytes {
                #[allow(clippy::cast_precision_loss)]
                let gain = (target - queue_s) / target * acked.bytes as f64;
                self.window_bytes = (self.window_bytes + gain).min(MAX_WINDOW_BYTES);
            }
        } else if now_s - self.last_decrease_s >= rtt_s {
            self.window_bytes = (self.window_bytes * 0.75).max(MIN_WINDOW_BYTES);
            self.last_decrease_s = now_s;
        }
        ReceiptOutcome::Acknowledged { rtt_s, queue_s }
    }

    fn remember(&mut self, now_s: f64, rtt_s: f64) {
        #[allow(clippy::cast_possible_truncation)]
        let bucket = (now_s / (BASE_HISTORY_S / BASE_BUCKETS as f64)).floor() as i64;
        match self.base.back_mut() {
            Some((b, min)) if *b == bucket => *min = min.min(rtt_s),
            _ => self.base.push_back((bucket, rtt_s)),
        }
        while self
            .base
            .front()
            .is_some_and(|(b, _)| bucket - b >= BASE_BUCKETS as i64)
        {
            self.base.pop_front();
        }
        self.recent.push_back(rtt_s);
        while self.recent.len() > CURRENT_FILTER {
            self.recent.pop_front();
        }
    }

    /// Views in flight longer than `receipt_timeout_s` are lost: the window halves
    /// (once per expiry pass).
    fn expire(&mut self, now_s: f64) {
        let before = self.in_flight.len();
        let timeout = self.cfg.receipt_timeout_s;
        self.in_flight.retain(|s| now_s - s.sent_s <= timeout);
        let lost = before - self.in_flight.len();
        if lost > 0 {
            self.counters.lost += lost as u64;
            if self.paced(now_s) {
                self.window_bytes = (self.window_bytes * 0.5).max(MIN_WINDOW_BYTES);
                self.last_decrease_s = now_s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A link of `rate_bps` with a one-way delay `delay_s` each way and a FIFO queue:
    /// views sent through it arrive after the queue drains; receipts come back after
    /// the delay. Returns (views delivered per second, mean queueing delay s).
    fn simulate(pacing: bool, rate_bps: f64, delay_s: f64, seconds: f64) -> (f64, f64, ViewPacer) {
        let mut pacer = ViewPacer::new(PacingConfig {
            enabled: pacing,
            ..PacingConfig::default()
        });
        let frame = 7300_usize; // one 320x240 JPEG view at q80
        let dt = 0.01;
        let mut link_free_s = 0.0_f64;
        // (arrival at the operator, view, stamp)
        let mut on_the_way: VecDeque<(f64, usize, i64)> = VecDeque::new();
        let mut receipts: VecDeque<(f64, usize, i64)> = VecDeque::new();
        let mut delivered = 0_u64;
        let mut queue_sum = 0.0;
        let mut next_frame_s = [0.0_f64; 2];
        let mut t = 0.0;
        // Receiver reports from the start (pacing engages on the first receipt).
        while t < seconds {
            while receipts.front().is_some_and(|r| r.0 <= t) {
                if let Some((_, v, s)) = receipts.pop_front() {
                    pacer.receipt(t, v, s);
                }
            }
            while on_the_way.front().is_some_and(|r| r.0 <= t) {
                if let Some((at, v, s)) = on_the_way.pop_front() {
                    delivered += 1;
                    receipts.push_back((at + delay_s, v, s));
                }
            }
            for (v, next) in next_frame_s.iter_mut().enumerate() {
                if t >= *next && pacer.may_send(t, frame) {
                    *next = (*next + 1.0 / 15.0).max(t);
                    #[allow(clippy::cast_possible_truncation)]
                    let stamp = (t * 1e9) as i64;
                    pacer.sent(t, v, stamp, frame);
                    let start = link_free_s.max(t);
                    queue_sum += start - t;
                    #[allow(clippy::cast_precision_loss)]
                    let wire = frame as f64 * 8.0 / rate_bps;
                    link_free_s = start + wire;
                    on_the_way.push_back((link_free_s + delay_s, v, stamp));
                }
            }
            t += dt;
        }
        #[allow(clippy::cast_precision_loss)]
        let sent = (pacer.counters().acknowledged + pacer.counters().lost) as f64;
        #[allow(clippy::cast_precision_loss)]
        (delivered as f64 / seconds, queue_sum / sent.max(1.0), pacer)
    }

    #[test]
    fn on_a_fast_link_the_views_go_at_the_camera_rate() {
        let (rate, queue, p) = simulate(true, 100e6, 0.02, 20.0);
        assert!(rate > 29.0, "{rate} views/s");
        assert!(queue < 0.005, "{queue} s");
        assert_eq!(p.counters().lost, 0);
    }

    #[test]
    fn on_a_slow_link_paced_views_keep_the_queue_short_and_unpaced_ones_do_not() {
        // 1 Mbit/s: two 15 Hz views (1.75 Mbit/s) do not fit.
        let (rate, queue, p) = simulate(true, 1e6, 0.02, 30.0);
        // The target (50 ms) plus one view on the wire (58 ms) behind the other.
        assert!(queue < 0.15, "paced: {queue} s of queue");
        assert!(rate > 5.0, "paced: {rate} views/s");
        assert!(p.counters().held > 0);
        let (_, unpaced_queue, _) = simulate(false, 1e6, 0.02, 30.0);
        assert!(unpaced_queue > 1.0, "unpaced: {unpaced_queue} s of queue");
    }

    #[test]
    fn without_receipts_the_views_are_not_paced_and_the_lost_ones_are_counted() {
        let mut p = ViewPacer::new(PacingConfig::default());
        for i in 0..100 {
            let t = f64::from(i) * 0.066;
            assert!(p.may_send(t, 100_000), "view {i}");
            p.sent(t, 0, i64::from(i), 100_000);
        }
        assert!(!p.paced(6.6));
        assert!(p.counters().lost > 80, "{:?}", p.counters());
        assert_eq!(p.counters().held, 0);
    }

    #[test]
    fn a_receiver_that_falls_silent_unpaces_the_views_after_its_timeout() {
        let mut p = ViewPacer::new(PacingConfig::default());
        p.sent(0.0, 0, 1, 1000);
        assert!(matches!(
            p.receipt(0.05, 0, 1),
            ReceiptOutcome::Acknowledged { .. }
        ));
        assert!(p.paced(1.0));
        // A full window holds views back while the receiver reports.
        p.sent(1.0, 0, 2, 60_000);
        assert!(!p.may_send(1.01, 60_000));
        assert_eq!(p.counters().held, 1);
        assert!(p.paced(5.0));
        assert!(!p.paced(5.1));
        assert!(p.may_send(5.1, 60_000));
    }

    #[test]
    fn a_receipt_acknowledges_the_earlier_views_of_its_camera_only() {
        let mut p = ViewPacer::new(PacingConfig::default());
        p.sent(0.0, 0, 10, 1000);
        p.sent(0.0, 1, 10, 1000);
        p.sent(0.07, 0, 20, 1000);
        assert!(matches!(
            p.receipt(0.1, 0, 20),
            ReceiptOutcome::Acknowledged { .. }
        ));
        assert_eq!(p.counters().acknowledged, 2);
        assert_eq!(
            p.in_flight_bytes(),
            1000,
            "camera 1's view is still in flight"
        );
        assert_eq!(p.receipt(0.1, 0, 10), ReceiptOutcome::Unmatched);
        assert_eq!(p.receipt(0.1, 7, 99), ReceiptOutcome::Unmatched);
        assert_eq!(p.counters().unmatched, 2);
    }

    #[test]
    fn a_growing_round_trip_shrinks_the_window_and_a_steady_one_grows_it() {
        let mut p = ViewPacer::new(PacingConfig::default());
        let mut t = 0.0;
        let mut stamp = 0;
        let ack = |p: &mut ViewPacer, t: f64, rtt: f64, stamp: &mut i64| {
            *stamp += 1;
            p.sent(t, 0, *stamp, 40_000);
            p.receipt(t + rtt, 0, *stamp)
        };
        for _ in 0..20 {
            ack(&mut p, t, 0.04, &mut stamp);
            t += 0.05;
        }
        let steady = p.window_bytes();
        assert!(steady > INITIAL_WINDOW_BYTES, "{steady}");
        // Within the base round trip's memory (5 s); the queue shows once the last
        // CURRENT_FILTER round trips are all long.
        for i in 0..10 {
            let out = ack(&mut p, t, 0.3, &mut stamp);
            let queue_s = match out {
                ReceiptOutcome::Acknowledged { queue_s, .. } => queue_s,
                ReceiptOutcome::Unmatched => panic!("{out:?}"),
            };
            if i + 1 >= CURRENT_FILTER {
                assert!(queue_s > 0.2, "{i}: {out:?}");
            } else {
                assert!(queue_s < 1e-9, "{i}: {out:?}");
            }
            t += 0.35;
        }
        assert!(p.window_bytes() < steady / 4.0, "{}", p.window_bytes());
        assert!(p.window_bytes() >= MIN_WINDOW_BYTES);
    }

    #[test]
    fn settings_out_of_range_are_named() {
        assert!(PacingConfig::default().validate().is_ok());
        for (cfg, name) in [
            (
                PacingConfig {
                    target_queue_s: f64::NAN,
                    ..PacingConfig::default()
                },
                "target_queue_s",
            ),
            (
                PacingConfig {
                    receipt_timeout_s: 0.0,
                    ..PacingConfig::default()
                },
                "receipt_timeout_s",
            ),
            (
                PacingConfig {
                    receiver_timeout_s: 0.5,
                    ..PacingConfig::default()
                },
                "receiver_timeout_s",
            ),
        ] {
            let e = cfg.validate().unwrap_err();
            assert!(e.contains(name), "{e}");
        }
    }
}
