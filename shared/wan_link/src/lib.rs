//! The WAN link emulator between the two sites' Zenoh routers.
//!
//! The kernel of the development machines has no `netem` qdisc, so the WAN goes through
//! this forwarder: the local router connects to it as if it were the remote router, and
//! it forwards each connection's bytes to the remote router and back, in both
//! directions, with
//!
//! * **delay** and **jitter**: each chunk of bytes read is delivered `delay + U(-jitter,
//!   +jitter)` after it was read (never before `delay - jitter`, never before 0), in
//!   order, as TCP delivers;
//! * **bandwidth caps**: the chunks leave one after the other at `rate_mbit`, so a
//!   burst queues; one capped wire each way, shared by all connections (a router
//!   that opens two, one per priority class, gets the rate once, not twice), each
//!   connection holding at most an equal share of its buffer, so connections with
//!   bytes to send share the rate about equally (per-flow fair queueing); the queue
//!   is bounded in time (`queue_ms`: the bytes waiting for the capped link take at
//!   most this long to leave, as in a bottleneck router's buffer), and a full queue stops the forwarder reading from the sender, whose
//!   TCP send buffer then fills: the backpressure a slow link gives, which Zenoh
//!   answers by dropping what its congestion control allows (camera images) before it
//!   blocks what must arrive. The forwarder's own sockets have small kernel buffers
//!   ([`DEFAULT_SOCKET_KB`]), so the kernel adds no queue of its own in front of the
//!   modelled one;
//! * **loss** as a TCP connection experiences it: a lost segment is retransmitted, so
//!   each of a chunk's 1448-byte segments is lost with probability `loss`, and a chunk
//!   with a lost segment (and everything behind it: in order) arrives
//!   `retransmit_ms` later (default 200 ms, Linux's minimum retransmission timeout);
//!   the bytes are never dropped, since the routers' link is TCP;
//! * **partitions**: nothing is forwarded either way while partitioned; what was
//!   sent waits, as in the senders' retransmission queues, and flows when the link
//!   returns (unless the routers' sessions have timed out by then).
//!
//! Seeded (`seed`; each direction of each connection draws from its own stream), and
//! changed at run time over a line-based control port ([`Command`]). The pure part,
//! [`Link`] (when does a chunk arrive), is separate from the forwarding ([`proxy`]).

pub mod measure;
pub mod proxy;

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// TCP's maximum segment size on an Ethernet path (1500 - 20 - 20 - 12 bytes).
pub const SEGMENT_BYTES: usize = 1448;

/// The most bytes in flight in one direction (read, not yet delivered: on the wire,
/// delayed, or held by a partition or a retransmission), the stand-in for the TCP
/// window of a real path (Linux's largest default receive buffer is 6 MiB). Only the
/// bytes waiting for a capped link are bounded tighter, by `queue_ms`.
pub const IN_FLIGHT_BYTES: usize = 8 << 20;

/// The kernel buffers (`SO_RCVBUF`, `SO_SNDBUF`) the forwarder asks for on its
/// sockets, KiB (the kernel doubles it for its bookkeeping). Left to the kernel's
/// autotuning, the receive buffer grows to megabytes, and a slow link's backlog would
/// wait there, in front of the modelled queue, where no congestion control sees it.
pub const DEFAULT_SOCKET_KB: u32 = 16;

/// The impairment of the link, the same in both directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impairment {
    /// One-way delay, ms.
    pub delay_ms: f64,
    /// Uniform jitter around the delay, +- ms (<= `delay_ms`: nothing arrives early).
    pub jitter_ms: f64,
    /// Probability that one TCP segment is lost, [0, 1).
    pub loss: f64,
    /// What a loss costs the chunk it hits (and those behind it), ms.
    pub retransmit_ms: f64,
    /// Bandwidth cap, Mbit/s; `None`: uncapped.
    pub rate_mbit: Option<f64>,
    /// The capped link's buffer, ms: the sender is held while the bytes waiting for
    /// the link would take longer than this to leave at `rate_mbit`.
    pub queue_ms: f64,
    /// Nothing flows while true.
    pub partitioned: bool,
}

impl Default for Impairment {
    fn default() -> Self {
        Self {
            delay_ms: 0.0,
            jitter_ms: 0.0,
            loss: 0.0,
            retransmit_ms: 200.0,
            rate_mbit: None,
            queue_ms: 50.0,
            partitioned: false,
        }
    }
}

/// A setting out of its range, or a control line that cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinkError {
    #[error("{field} must be {range}, got {value}")]
    OutOfRange {
        field: &'static str,
        range: &'static str,
        value: String,
    },
    #[error(
        "unknown setting `{0}` (delay_ms, jitter_ms, loss_pct, retransmit_ms, rate_mbit, queue_ms)"
    )]
    UnknownSetting(String),
    #[error("`{0}` is not key=value")]
    NotKeyValue(String),
    #[error("unknown command `{0}` (set, partition on|off, reset, show)")]
    UnknownCommand(String),
}

impl Impairment {
    /// # Errors
    /// [`LinkError::OutOfRange`] naming the first field out of its range.
    pub fn validate(&self) -> Result<(), LinkError> {
        let bad = |field, range, value: f64| {
            Err(LinkError::OutOfRange {
                field,
                range,
                value: value.to_string(),
            })
        };
        if !(self.delay_ms.is_finite() && (0.0..=10_000.0).contains(&self.delay_ms)) {
            return bad("delay_ms", "in [0, 10000]", self.delay_ms);
        }
        if !(self.jitter_ms.is_finite() && self.jitter_ms >= 0.0 && self.jitter_ms <= self.delay_ms)
        {
            return bad("jitter_ms", "in [0, delay_ms]", self.jitter_ms);
        }
        if !(self.loss.is_finite() && (0.0..0.5).contains(&self.loss)) {
            return bad("loss_pct", "in [0, 50)", self.loss * 100.0);
        }
        if !(self.retransmit_ms.is_finite() && (0.0..=10_000.0).contains(&self.retransmit_ms)) {
            return bad("retransmit_ms", "in [0, 10000]", self.retransmit_ms);
        }
        if let Some(r) = self.rate_mbit
            && !(r.is_finite() && (0.01..=100_000.0).contains(&r))
        {
            return bad("rate_mbit", "in [0.01, 100000] (0 for uncapped)", r);
        }
        if !(self.queue_ms.is_finite() && (1.0..=10_000.0).contains(&self.queue_ms)) {
            return bad("queue_ms", "in [1, 10000]", self.queue_ms);
        }
        Ok(())
    }

    /// The settings as one `key=value` line (what `show` prints, what `set` reads).
    pub fn describe(&self) -> String {
        format!(
            "delay_ms={} jitter_ms={} loss_pct={} retransmit_ms={} rate_mbit={} queue_ms={} partitioned={}",
            self.delay_ms,
            self.jitter_ms,
            self.loss * 100.0,
            self.retransmit_ms,
            self.rate_mbit.unwrap_or(0.0),
            self.queue_ms,
            self.partitioned
        )
    }

    /// Applies `key=value` settings (a `set` line's arguments) to a copy and validates
    /// it.
    ///
    /// # Errors
    /// [`LinkError`] naming the setting.
    pub fn with(&self, settings: &[&str]) -> Result<Self, LinkError> {
        let mut out = *self;
        for kv in settings {
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| LinkError::NotKeyValue((*kv).to_owned()))?;
            let num = |field: &'static str| {
                v.parse::<f64>().map_err(|_| LinkError::OutOfRange {
                    field,
                    range: "a number",
                    value: v.to_owned(),
                })
            };
            match k {
                "delay_ms" => out.delay_ms = num("delay_ms")?,
                "jitter_ms" => out.jitter_ms = num("jitter_ms")?,
                "loss_pct" => out.loss = num("loss_pct")? / 100.0,
                "retransmit_ms" => out.retransmit_ms = num("retransmit_ms")?,
                "rate_mbit" => {
                    let r = num("rate_mbit")?;
                    out.rate_mbit = if r == 0.0 { None } else { Some(r) };
                }
                "queue_ms" => out.queue_ms = num("queue_ms")?,
                other => return Err(LinkError::UnknownSetting(other.to_owned())),
            }
        }
        out.validate()?;
        Ok(out)
    }

    /// How long a reader must wait before it takes more from the sender, s, when the
    /// capped link needs `backlog_s` to send what already waits for it: until the
    /// backlog is back within `queue_ms`. Zero when uncapped.
    pub fn hold_s(&self, backlog_s: f64) -> f64 {
        if self.rate_mbit.is_none() {
            return 0.0;
        }
        (backlog_s - self.queue_ms * 1e-3).max(0.0)
    }

    /// The same for one of `connections` sharing the capped link, whose own bytes
    /// need `own_backlog_s` of it: also until its own share is back within
    /// `queue_ms / connections`. So no connection holds more than its share of the
    /// buffer, and the link's rate is shared about equally among the connections that
    /// have bytes to send (as per-flow fair queueing does on a router, and TCP's
    /// congestion control on average behind a drop-tail one), whatever the size of
    /// the reads; a connection that needs less than its share gets all it needs,
    /// waiting behind at most the others' shares.
    pub fn hold_shared_s(&self, backlog_s: f64, own_backlog_s: f64, connections: u64) -> f64 {
        if self.rate_mbit.is_none() {
            return 0.0;
        }
        #[allow(clippy::cast_precision_loss)]
        let share_s = self.queue_ms * 1e-3 / connections.max(1) as f64;
        self.hold_s(backlog_s).max(own_backlog_s - share_s)
    }
}

/// A control-port command, one per line.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// `set delay_ms=50 jitter_ms=5 loss_pct=1 rate_mbit=10 ...`: the named settings
    /// change, the others stay.
    Set(Impairment),
    /// `partition on` / `partition off`.
    Partition(bool),
    /// `reset`: no impairment, no partition.
    Reset,
    /// `show`: the settings and the counters.
    Show,
}

impl Command {
    /// Parses one control line against the current settings.
    ///
    /// # Errors
    /// [`LinkError`] naming what was wrong.
    pub fn parse(line: &str, current: &Impairment) -> Result<Self, LinkError> {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["set", settings @ ..] => Ok(Self::Set(current.with(settings)?)),
            ["partition", "on"] => Ok(Self::Partition(true)),
            ["partition", "off"] => Ok(Self::Partition(false)),
            ["reset"] => Ok(Self::Reset),
            ["show"] => Ok(Self::Show),
            _ => Err(LinkError::UnknownCommand(line.trim().to_owned())),
        }
    }
}

/// The capped wire of one direction, shared by every connection that crosses the link
/// that way (one bottleneck, as on a real WAN: two TCP connections between the same
/// sites share its rate and its buffer, they do not get one each): when it is free
/// for the next chunk, s.
#[derive(Debug, Clone)]
pub struct Wire(Arc<Mutex<f64>>);

impl Default for Wire {
    fn default() -> Self {
        Self(Arc::new(Mutex::new(f64::NEG_INFINITY)))
    }
}

impl Wire {
    fn free_s(&self) -> f64 {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Books the wire for `on_wire_s` from `t_s` or when it is free, whichever is
    /// later; when the chunk has left, s.
    fn book(&self, t_s: f64, on_wire_s: f64) -> f64 {
        let mut free = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        *free = t_s.max(*free) + on_wire_s;
        *free
    }
}

/// One direction of one connection: when each chunk read from the sender is delivered.
/// The delay, jitter and losses are the connection's own; the capped wire it is sent
/// on may be shared with other connections ([`Link::on`]).
#[derive(Debug)]
pub struct Link {
    rng: ChaCha8Rng,
    wire: Wire,
    /// When the previous chunk is delivered (TCP is in order), s.
    last_s: f64,
    /// This connection's chunks on the wire not yet sent: when each has left, and how
    /// long it takes to send, s.
    mine: VecDeque<(f64, f64)>,
    /// Chunks delayed by a loss so far.
    pub losses: u64,
    /// Chunks scheduled so far.
    pub chunks: u64,
}

impl Link {
    /// A direction drawing from stream `stream` of seed `seed`, on a wire of its own.
    pub fn new(seed: u64, stream: u64) -> Self {
        Self::on(Wire::default(), seed, stream)
    }

    /// A direction drawing from stream `stream` of seed `seed`, sent on `wire`.
    pub fn on(wire: Wire, seed: u64, stream: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Self {
            rng,
            wire,
            last_s: f64::NEG_INFINITY,
            mine: VecDeque::new(),
            losses: 0,
            chunks: 0,
        }
    }

    /// How long the capped link needs at `t_s` to send the chunks already waiting for
    /// it, s (zero once it is idle).
    pub fn backlog_s(&self, t_s: f64) -> f64 {
        (self.wire.free_s() - t_s).max(0.0)
    }

    /// How much of that backlog is this connection's own at `t_s`, s.
    pub fn own_backlog_s(&mut self, t_s: f64) -> f64 {
        while self.mine.front().is_some_and(|(left, _)| *left <= t_s) {
            self.mine.pop_front();
        }
        self.mine
            .iter()
            .map(|(left, on_wire)| on_wire.min(left - t_s))
            .sum()
    }

    /// When a chunk of `len` bytes read at `t_s` is delivered under `imp` (not
    /// partitioned: the forwarder holds chunks while it is).
    pub fn schedule(&mut self, imp: &Impairment, t_s: f64, len: usize) -> f64 {
        self.chunks += 1;
        // Onto the wire when it is free, for len * 8 / rate.
        #[allow(clippy::cast_precision_loss)]
        let on_wire = imp.rate_mbit.map_or(0.0, |r| (len * 8) as f64 / (r * 1e6));
        let sent = self.wire.book(t_s, on_wire);
        if on_wire > 0.0 {
            self.mine.push_back((sent, on_wire));
        }
        let jitter = if imp.jitter_ms > 0.0 {
            self.rng.random_range(-imp.jitter_ms..=imp.jitter_ms)
        } else {
            0.0
        };
        let mut arrive = sent + (imp.delay_ms + jitter) * 1e-3;
        if imp.loss > 0.0 {
            let segments = len.div_ceil(SEGMENT_BYTES).max(1);
            let p_any = 1.0 - (1.0 - imp.loss).powi(i32::try_from(segments).unwrap_or(i32::MAX));
            if self.rng.random_bool(p_any.clamp(0.0, 1.0)) {
                self.losses += 1;
                arrive += imp.retransmit_ms * 1e-3;
            }
        }
        // In order: never before the chunk ahead of it.
        let arrive = arrive.max(self.last_s);
        self.last_s = arrive;
        arrive
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delay_and_jitter_stay_in_their_band_and_in_order() {
        let imp = Impairment {
            delay_ms: 50.0,
            jitter_ms: 10.0,
            ..Impairment::default()
        };
        let mut link = Link::new(7, 0);
        let mut last = f64::NEG_INFINITY;
        let mut sum = 0.0;
        for k in 0..10_000 {
            let t = f64::from(k) * 0.001;
            let a = link.schedule(&imp, t, 100);
            assert!(a >= last, "out of order at {k}");
            last = a;
            // In order, so a chunk may wait behind a later-drawn earlier one, but
            // never arrives before delay - jitter nor after delay + jitter + the 1 ms
            // between chunks.
            let d = (a - t) * 1e3;
            assert!((40.0 - 1e-9..=60.0 + 1e-9).contains(&d), "{d} ms at {k}");
            sum += d;
        }
        let mean = sum / 10_000.0;
        assert!((50.0..56.0).contains(&mean), "mean {mean} ms");
    }

    #[test]
    fn the_same_seed_gives_the_same_schedule() {
        let imp = Impairment {
            delay_ms: 20.0,
            jitter_ms: 5.0,
            loss: 0.05,
            ..Impairment::default()
        };
        let run = |seed, stream| {
            let mut l = Link::new(seed, stream);
            (0..100)
                .map(|k| l.schedule(&imp, f64::from(k) * 0.01, 3000))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(1, 0), run(1, 0));
        assert_ne!(run(1, 0), run(1, 1));
        assert_ne!(run(1, 0), run(2, 0));
    }

    #[test]
    fn the_rate_cap_queues_a_burst() {
        let imp = Impairment {
            rate_mbit: Some(8.0),
            ..Impairment::default()
        };
        let mut link = Link::new(1, 0);
        // Ten 10 kB chunks at once on 8 Mbit/s = 1 MB/s: one every 10 ms.
        let arrivals: Vec<f64> = (0..10).map(|_| link.schedule(&imp, 0.0, 10_000)).collect();
        for (k, a) in arrivals.iter().enumerate() {
            #[allow(clippy::cast_precision_loss)]
            let expect = (k + 1) as f64 * 0.01;
            assert!((a - expect).abs() < 1e-9, "{k}: {a}");
        }
        // 100 ms of bytes wait for the link at t = 0: behind a 50 ms buffer the reader
        // holds the sender 50 ms, at t = 60 ms no longer; uncapped, never.
        assert!((link.backlog_s(0.0) - 0.1).abs() < 1e-9);
        assert!((imp.hold_s(link.backlog_s(0.0)) - 0.05).abs() < 1e-9);
        assert_eq!(imp.hold_s(link.backlog_s(0.06)), 0.0);
        assert_eq!(link.backlog_s(0.2), 0.0);
        assert_eq!(Impairment::default().hold_s(5.0), 0.0);
    }

    #[test]
    fn connections_on_one_wire_share_its_rate_and_keep_their_own_order() {
        let imp = Impairment {
            rate_mbit: Some(8.0),
            ..Impairment::default()
        };
        let wire = Wire::default();
        let mut a = Link::on(wire.clone(), 1, 0);
        let mut b = Link::on(wire, 1, 2);
        // Two connections, five 10 kB chunks each at once, on 8 Mbit/s = 1 MB/s: the
        // ten leave one every 10 ms, whichever connection sent them (twice as long
        // as on a wire each), and each connection's arrive in its own order.
        let mut arrivals = Vec::new();
        for _ in 0..5 {
            arrivals.push(a.schedule(&imp, 0.0, 10_000));
            arrivals.push(b.schedule(&imp, 0.0, 10_000));
        }
        for (k, t) in arrivals.iter().enumerate() {
            #[allow(clippy::cast_precision_loss)]
            let expect = (k + 1) as f64 * 0.01;
            assert!((t - expect).abs() < 1e-9, "{k}: {t}");
        }
        // Both see the one backlog: 100 ms at t = 0.
        assert!((a.backlog_s(0.0) - 0.1).abs() < 1e-9);
        assert!((b.backlog_s(0.0) - 0.1).abs() < 1e-9);
        // On wires of their own, each would be done in 50 ms.
        let mut c = Link::new(1, 0);
        let mut d = Link::new(1, 2);
        for _ in 0..5 {
            c.schedule(&imp, 0.0, 10_000);
            d.schedule(&imp, 0.0, 10_000);
        }
        assert!((c.backlog_s(0.0) - 0.05).abs() < 1e-9);
        assert!((d.backlog_s(0.0) - 0.05).abs() < 1e-9);
    }

    #[test]
    fn a_connection_is_held_at_its_share_of_the_buffer() {
        let imp = Impairment {
            rate_mbit: Some(8.0),
            queue_ms: 50.0,
            ..Impairment::default()
        };
        let wire = Wire::default();
        let mut bulk = Link::on(wire.clone(), 1, 0);
        let mut small = Link::on(wire, 1, 2);
        // Four 10 kB chunks of one connection (40 ms at 1 MB/s), one 1 kB of the
        // other behind them.
        for _ in 0..4 {
            bulk.schedule(&imp, 0.0, 10_000);
        }
        small.schedule(&imp, 0.0, 1_000);
        assert!((bulk.own_backlog_s(0.0) - 0.04).abs() < 1e-9);
        assert!((small.own_backlog_s(0.0) - 0.001).abs() < 1e-9);
        // The link's 41 ms are within its 50 ms; alone, the bulk connection could go
        // on, but of two it may hold only 25 ms: it waits until 40 - 25 = 15 ms, and
        // the small one, within its share, does not.
        let total = bulk.backlog_s(0.0);
        assert_eq!(imp.hold_s(total), 0.0);
        assert_eq!(imp.hold_shared_s(total, bulk.own_backlog_s(0.0), 1), 0.0);
        let hold = imp.hold_shared_s(total, bulk.own_backlog_s(0.0), 2);
        assert!((hold - 0.015).abs() < 1e-9, "{hold}");
        assert_eq!(imp.hold_shared_s(total, small.own_backlog_s(0.0), 2), 0.0);
        // Half-way through the second chunk: 25 ms of the bulk's own are left.
        assert!((bulk.own_backlog_s(0.015) - 0.025).abs() < 1e-9);
        // Uncapped, nobody is held.
        assert_eq!(Impairment::default().hold_shared_s(1.0, 1.0, 2), 0.0);
    }

    #[test]
    fn loss_costs_the_retransmission_delay_at_its_rate() {
        let imp = Impairment {
            loss: 0.01,
            ..Impairment::default()
        };
        let mut link = Link::new(3, 0);
        // One-segment chunks 1 s apart: no queueing, each lost with p = 1 %.
        let mut hit = 0;
        for k in 0..20_000 {
            let t = f64::from(k);
            let d = link.schedule(&imp, t, 1000) - t;
            assert!(d == 0.0 || (d - 0.2).abs() < 1e-9, "{d}");
            hit += u32::from(d > 0.0);
        }
        assert_eq!(u64::from(hit), link.losses);
        assert!((150..250).contains(&hit), "{hit} of 20000");
        // A chunk of ten segments is hit ~10x as often.
        let mut link = Link::new(3, 1);
        for k in 0..2000 {
            link.schedule(&imp, f64::from(k), 10 * SEGMENT_BYTES);
        }
        assert!((140..250).contains(&link.losses), "{}", link.losses);
    }

    #[test]
    fn control_lines_are_parsed_and_bad_ones_named() {
        let cur = Impairment::default();
        let Command::Set(s) =
            Command::parse("set delay_ms=50 jitter_ms=5 loss_pct=1 rate_mbit=10", &cur)
                .expect("set")
        else {
            panic!("not a set")
        };
        assert_eq!(s.delay_ms, 50.0);
        assert_eq!(s.jitter_ms, 5.0);
        assert!((s.loss - 0.01).abs() < 1e-12);
        assert_eq!(s.rate_mbit, Some(10.0));
        let Command::Set(u) = Command::parse("set rate_mbit=0", &s).expect("set") else {
            panic!("not a set")
        };
        assert_eq!(u.rate_mbit, None);
        assert_eq!(u.delay_ms, 50.0, "unnamed settings stay");
        assert_eq!(
            Command::parse("partition on", &cur),
            Ok(Command::Partition(true))
        );
        assert_eq!(
            Command::parse(" partition off ", &cur),
            Ok(Command::Partition(false))
        );
        assert_eq!(Command::parse("reset", &cur), Ok(Command::Reset));
        for (line, named) in [
            ("set delay_ms=-1", "delay_ms"),
            ("set delay_ms=10 jitter_ms=20", "jitter_ms"),
            ("set loss_pct=60", "loss_pct"),
            ("set loss_pct=nan", "loss_pct"),
            ("set rate_mbit=abc", "rate_mbit"),
            ("set queue_ms=0", "queue_ms"),
            ("set queue_kb=64", "queue_kb"),
            ("set bandwidth=3", "bandwidth"),
            ("set delay_ms", "delay_ms"),
            ("partition maybe", "partition maybe"),
            ("drop all", "drop all"),
        ] {
            let e = Command::parse(line, &cur).expect_err(line).to_string();
            assert!(e.contains(named), "{line}: {e}");
        }
    }
}
