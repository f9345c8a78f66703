//! The one run loop of every node: open the session, build the node, tick it at its
//! period on the node's clock, publish its status (every second, and at once when its
//! lifecycle state changes), stop on the stop signal, shut down gracefully (the node
//! commands its hardware to stop), publish a final `FINALIZED` status, close the
//! session.
//!
//! The loop itself has no logic to test; what a node does per period is its
//! [`Node::tick`], which tests drive with scripted time.

use std::future::Future;
use std::time::Duration;

use teleop_bus::Bus;
use teleop_msgs::Lifecycle;
use tokio::time::MissedTickBehavior;

use crate::status::StatusReporter;

/// What the run loop needs of a node.
///
/// Lifecycle states mean what `NodeStatus.msg` says: [`Lifecycle::Active`] — a robot
/// under this node may move (or the node does its job); [`Lifecycle::Inactive`] — its
/// outputs are held (the robot under it does not move); [`Lifecycle::Fault`] — stopped
/// on an error that needs operator action.
pub trait Node: Send {
    /// The control period.
    fn period(&self) -> Duration;
    /// One period at `now_s` (node clock, s since the Unix epoch).
    fn tick(&mut self, now_s: f64);
    /// The node's lifecycle state now.
    fn state(&self) -> Lifecycle;
    /// Counters for the status (cheap enough to call every second).
    fn counters(&self) -> Vec<(String, u64)>;
    /// The last error, empty if none.
    fn last_error(&self) -> String;
    /// Called once when the node stops, before the final status: command the hardware
    /// to stop (or hold). Default: nothing to stop.
    fn shutdown(&mut self, _now_s: f64) {}
    /// A signal that the node has work before its next period (a camera frame arrived;
    /// see `teleop_bus::Subscriber::wake_on_sample`): the runner then ticks at once,
    /// besides the periodic ticks. Default: none, the node ticks on its period only.
    fn wake(&self) -> Option<std::sync::Arc<tokio::sync::Notify>> {
        None
    }
}

/// What a node reported when it stopped.
#[derive(Debug, Clone, PartialEq)]
pub struct FinalReport {
    pub node_name: String,
    /// Lifecycle state just before the stop.
    pub state_at_stop: Lifecycle,
    pub counters: Vec<(String, u64)>,
    pub last_error: String,
}

impl FinalReport {
    /// A counter by name.
    pub fn counter(&self, name: &str) -> Option<u64> {
        self.counters
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}

/// How often the status is published when nothing changes.
pub const STATUS_PERIOD: Duration = Duration::from_secs(1);

/// Runs `node` on `bus` (the node's session, opened with the node's clock) until
/// `stop` completes, then shuts it down gracefully and closes the session. Returns the
/// node's final report.
///
/// # Errors
/// Declaring the status publisher or closing the session; publishing errors are
/// logged, not fatal.
pub async fn run<N, S>(bus: Bus, mut node: N, stop: S) -> anyhow::Result<FinalReport>
where
    N: Node,
    S: Future<Output = ()>,
{
    let node_name = bus.node_name().to_owned();
    let status = StatusReporter::new(&bus).await?;
    // On a run's simulated time (`--time-scale`, `--time-file`) the period is in
    // simulated seconds; a paced clock's rate changes during the run, and the period in
    // wall time with it.
    let mut rate = bus.clock().rate();
    let mut tick = wall_interval(node.period().div_f64(rate), tokio::time::Instant::now());
    let mut status_tick = tokio::time::interval(STATUS_PERIOD);
    status_tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    tokio::pin!(stop);
    let report = |node: &N, state: Lifecycle| {
        let mut counters = node.counters();
        if let Some(scheduling) = crate::sched::process() {
            counters.extend(scheduling.counters());
        }
        if let Err(e) = status.report(bus.clock().now_ns(), state, &counters, &node.last_error()) {
            tracing::warn!("status: {e}");
        }
    };
    let mut reported = node.state();
    tracing::info!(node = %node_name, zid = bus.zid(), state = ?reported, "running");
    let wake = node.wake();
    let woken = || async {
        match &wake {
            Some(w) => w.notified().await,
            None => std::future::pending().await,
        }
    };
    loop {
        // A tick on the period or on a wake-up (a frame arrived), alike.
        tokio::select! {
            () = &mut stop => break,
            _ = status_tick.tick() => {
                reported = node.state();
                report(&node, reported);
                continue;
            }
            () = woken() => {}
            _ = tick.tick() => {}
        }
        node.tick(bus.now_s());
        let now_rate = bus.clock().rate();
        if (now_rate - rate).abs() > 1e-3 * rate {
            rate = now_rate;
            let wall = node.period().div_f64(rate);
            tick = wall_interval(wall, tokio::time::Instant::now() + wall);
        }
        let state = node.state();
        if state != reported {
            tracing::info!(node = %node_name, from = ?reported, to = ?state, "lifecycle");
            reported = state;
            report(&node, state);
        }
    }
    let state_at_stop = node.state();
    node.shutdown(bus.now_s());
    let final_report = FinalReport {
        node_name: node_name.clone(),
        state_at_stop,
        counters: node.counters(),
        last_error: node.last_error(),
    };
    report(&node, Lifecycle::Finalized);
    tracing::info!(node = %node_name, state = ?state_at_stop, "stopped");
    drop((node, status));
    bus.close().await?;
    Ok(final_report)
}

/// A tick every `period` of wall time (a node's period over its clock's rate), the
/// first one at `first`; missed ticks are skipped.
fn wall_interval(period: Duration, first: tokio::time::Instant) -> tokio::time::Interval {
    let mut tick = tokio::time::interval_at(first, period);
    tick.set_missed_tick_behavior(MissedTickBehavior::Skip);
    tick
}

/// Something to do every `period_s` on the node's clock, inside a faster tick (a
/// second publishing rate, camera frames in a physics loop). The first call is due at
/// once; after that, due times advance by whole periods (no drift), skipping those
/// missed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Periodic {
    period_s: f64,
    next_s: Option<f64>,
}

impl Periodic {
    /// Every `period_s` seconds (> 0).
    pub fn every(period_s: f64) -> Self {
        Self {
            period_s,
            next_s: None,
        }
    }

    /// Every `1 / rate_hz` seconds.
    pub fn at_rate(rate_hz: f64) -> Self {
        Self::every(1.0 / rate_hz)
    }

    /// True if the thing is due at `now_s` (and books the next time).
    pub fn due(&mut self, now_s: f64) -> bool {
        match self.next_s {
            Some(next) if now_s < next => false,
            Some(next) => {
                let missed = ((now_s - next) / self.period_s).floor();
                self.next_s = Some(next + (missed + 1.0) * self.period_s);
                true
            }
            None => {
                self.next_s = Some(now_s + self.period_s);
                true
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodic_keeps_its_rate_inside_a_faster_tick() {
        let mut p = Periodic::at_rate(50.0);
        let mut fired = 0;
        // 120 Hz tick for 10 s: 50 Hz on average, no drift.
        for k in 0..1200 {
            if p.due(1000.0 + f64::from(k) / 120.0) {
                fired += 1;
            }
        }
        assert!((499..=501).contains(&fired), "{fired}");
        // A long gap fires once, not in a burst.
        let mut p = Periodic::every(0.1);
        assert!(p.due(0.0));
        assert!(p.due(5.0));
        assert!(!p.due(5.05));
        assert!(p.due(5.1));
    }
}
