//! `teleop launch --as-fast-as-possible`: the run's simulated time goes as fast as the
//! machine can carry every process of the system. The launcher writes a
//! [`PacedClock`](teleop_bus::PacedClock) file that every node reads, measures how busy
//! the machine and each node's process are every half second, and sets the clock's
//! rate so that they stay below a target load: faster when there is room, slower when a
//! process or the machine runs out of it (down to slow motion on a machine that cannot
//! hold real time).
//!
//! Not a lockstep clock (one that advances only when every node finished its step, as
//! ROS's `/clock` with a stepping simulator): nine processes exchanging samples over
//! Zenoh, whose delivery is not ordered with any barrier, would need every sample
//! acknowledged per step. Pacing on load keeps the system's own timing (periods,
//! latencies, watchdogs) what it is at real time, in simulated seconds; the report
//! says what rates the run went through.

use std::path::Path;

use serde::Serialize;
use teleop_bus::PacedClockWriter;

use crate::proc_stat::{self, MachineTicks};

/// How the pacer decides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PacerConfig {
    /// The machine's busy fraction (all cores) to run at.
    pub machine_target: f64,
    /// The most one process may use, in cores (a node's loop is one thread).
    pub process_target: f64,
    /// The slowest and fastest rate.
    pub min_rate: f64,
    pub max_rate: f64,
    /// The most the rate changes in one step, as a factor (down: `1 / max_step`).
    pub max_step: f64,
    /// Changes smaller than this fraction of the rate are not made.
    pub dead_band: f64,
}

impl Default for PacerConfig {
    fn default() -> Self {
        Self {
            machine_target: 0.8,
            process_target: 0.8,
            min_rate: 0.25,
            max_rate: teleop_bus::clock::TIME_SCALE_RANGE.1,
            max_step: 1.5,
            dead_band: 0.05,
        }
    }
}

/// How busy the machine was over the last interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Load {
    /// Busy fraction of all cores, [0, 1].
    pub machine: f64,
    /// The busiest process of the run, in cores.
    pub busiest_process: f64,
}

/// The pacer's pure core: the next rate from the load at the current one.
#[derive(Debug, Clone, PartialEq)]
pub struct Pacer {
    cfg: PacerConfig,
    rate: f64,
    summary: PacingSummary,
}

/// What the pacer did during a run (in the report).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PacingSummary {
    /// Load measurements taken.
    pub samples: u64,
    /// Rate changes made.
    pub changes: u64,
    pub min_rate: f64,
    pub max_rate: f64,
    /// The rate at the end.
    pub last_rate: f64,
    /// Mean machine busy fraction and the busiest process's mean load (cores).
    pub mean_machine_load: f64,
    pub mean_busiest_process: f64,
}

impl Pacer {
    pub fn new(cfg: PacerConfig, start_rate: f64) -> Self {
        let rate = start_rate.clamp(cfg.min_rate, cfg.max_rate);
        Self {
            cfg,
            rate,
            summary: PacingSummary {
                min_rate: rate,
                max_rate: rate,
                last_rate: rate,
                ..PacingSummary::default()
            },
        }
    }

    pub fn summary(&self) -> &PacingSummary {
        &self.summary
    }

    /// One decision: the new rate if it changes. The load of a process grows about in
    /// proportion to the rate (its work per simulated second is fixed), so the rate is
    /// scaled by target / load of whichever of the machine and the busiest process is
    /// nearer its limit, at most by `max_step` per step. A load that is not a number
    /// changes nothing.
    pub fn step(&mut self, load: Load) -> Option<f64> {
        if !(load.machine.is_finite() && load.busiest_process.is_finite()) {
            return None;
        }
        let s = &mut self.summary;
        let n = s.samples as f64;
        s.mean_machine_load = (s.mean_machine_load * n + load.machine) / (n + 1.0);
        s.mean_busiest_process = (s.mean_busiest_process * n + load.busiest_process) / (n + 1.0);
        s.samples += 1;
        let pressure = (load.machine / self.cfg.machine_target)
            .max(load.busiest_process / self.cfg.process_target)
            .max(1e-3);
        let factor = (1.0 / pressure).clamp(1.0 / self.cfg.max_step, self.cfg.max_step);
        let next = (self.rate * factor).clamp(self.cfg.min_rate, self.cfg.max_rate);
        if (next - self.rate).abs() <= self.cfg.dead_band * self.rate {
            return None;
        }
        self.rate = next;
        s.changes += 1;
        s.min_rate = s.min_rate.min(next);
        s.max_rate = s.max_rate.max(next);
        s.last_rate = next;
        Some(next)
    }
}

/// The load of the machine and of the run's processes between two calls, from
/// `/proc` ([`crate::proc_stat`]).
#[derive(Debug)]
pub struct CpuSampler {
    ticks_per_s: f64,
    last: Option<Sample>,
}

#[derive(Debug, Clone)]
struct Sample {
    at: std::time::Instant,
    machine: MachineTicks,
    /// utime + stime of each process that could be read.
    processes: Vec<(u32, u64)>,
}

impl CpuSampler {
    pub fn new() -> Self {
        Self {
            ticks_per_s: proc_stat::clock_ticks_per_s(),
            last: None,
        }
    }

    /// The load since the last call (`None` on the first call, or without `/proc`).
    pub fn sample(&mut self, pids: &[u32]) -> Option<Load> {
        let now = Sample {
            at: std::time::Instant::now(),
            machine: proc_stat::machine_ticks().ok()?,
            processes: pids
                .iter()
                .filter_map(|&pid| Some((pid, proc_stat::process_ticks(pid).ok()?)))
                .collect(),
        };
        let before = self.last.replace(now.clone())?;
        let wall_s = now.at.duration_since(before.at).as_secs_f64();
        if now.machine.total == before.machine.total || wall_s <= 0.0 {
            return None;
        }
        let busiest_process = now
            .processes
            .iter()
            .filter_map(|(pid, t)| {
                let (_, b) = before.processes.iter().find(|(p, _)| p == pid)?;
                Some(t.saturating_sub(*b) as f64 / self.ticks_per_s / wall_s)
            })
            .fold(0.0, f64::max);
        Some(Load {
            machine: now.machine.busy_fraction_since(&before.machine),
            busiest_process,
        })
    }
}

/// Paces `writer`'s clock on the load of the processes `pids` until the future is
/// dropped; the pacer's state goes into `out` after every step.
pub async fn run(
    mut writer: PacedClockWriter,
    pids: Vec<u32>,
    cfg: PacerConfig,
    out: std::sync::Arc<std::sync::Mutex<PacingSummary>>,
) {
    let mut pacer = Pacer::new(cfg, writer.rate_at(teleop_msgs::unix_nanos_now()));
    let mut sampler = CpuSampler::new();
    let mut tick = tokio::time::interval(std::time::Duration::from_millis(500));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tick.tick().await;
        let Some(load) = sampler.sample(&pids) else {
            continue;
        };
        if let Some(rate) = pacer.step(load) {
            tracing::debug!(rate, ?load, "pacing");
            if let Err(e) = writer.set_rate(rate) {
                tracing::warn!("pacing: {e}");
            }
        }
        if let Ok(mut o) = out.lock() {
            *o = pacer.summary().clone();
        }
    }
}

/// The clock file of this launcher's run, created at rate 1.
///
/// # Errors
/// The file cannot be written.
pub fn create_clock(dir: &Path) -> anyhow::Result<(std::path::PathBuf, PacedClockWriter)> {
    let path = dir.join("clock");
    let writer = PacedClockWriter::create(&path, 1.0)?;
    Ok((path, writer))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(machine: f64, busiest_process: f64) -> Load {
        Load {
            machine,
            busiest_process,
        }
    }

    #[test]
    fn the_rate_rises_with_room_and_falls_under_load_within_its_bounds() {
        let mut p = Pacer::new(PacerConfig::default(), 1.0);
        // An idle machine: up by at most 1.5x a step, to the maximum and no further.
        assert_eq!(p.step(load(0.1, 0.05)), Some(1.5));
        for _ in 0..20 {
            p.step(load(0.1, 0.05));
        }
        assert_eq!(p.summary().last_rate, 20.0);
        assert_eq!(p.step(load(0.1, 0.05)), None);
        // The machine at 96 % for a target of 80 %: down by 1/1.2.
        let r = p.step(load(0.96, 0.3)).expect("slower");
        assert!((r - 20.0 / 1.2).abs() < 1e-9, "{r}");
        // One process at a full core while the machine has room: that process decides.
        let before = p.summary().last_rate;
        let r = p.step(load(0.5, 1.0)).expect("slower");
        assert!((r - before * 0.8).abs() < 1e-9, "{r}");
        // Near the target: no change.
        let before = p.summary().last_rate;
        assert_eq!(p.step(load(0.79, 0.5)), None);
        assert_eq!(p.summary().last_rate, before);
        // Overloaded: down by at most 1/1.5 a step, to the minimum and no further.
        for _ in 0..30 {
            p.step(load(1.0, 2.0));
        }
        assert_eq!(p.summary().last_rate, 0.25);
        // A load that is not a number changes nothing.
        assert_eq!(p.step(load(f64::NAN, 0.1)), None);
        let s = p.summary();
        assert_eq!(s.min_rate, 0.25);
        assert_eq!(s.max_rate, 20.0);
        assert_eq!(s.last_rate, 0.25);
        assert!(s.changes >= 10 && s.samples > s.changes, "{s:?}");
    }

    #[test]
    fn the_sampler_measures_a_busy_process() {
        let mut s = CpuSampler::new();
        let me = std::process::id();
        assert!(
            s.sample(&[me]).is_none(),
            "first sample has nothing to compare"
        );
        let t = std::time::Instant::now();
        let mut x = 0u64;
        while t.elapsed() < std::time::Duration::from_millis(300) {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        let l = s.sample(&[me]).expect("a load");
        assert!((0.0..=1.0).contains(&l.machine), "{l:?}");
        // This thread spun for the whole interval.
        assert!(l.busiest_process > 0.1, "{l:?}");
    }
}
