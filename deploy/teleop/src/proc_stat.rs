//! CPU time from Linux's `/proc`: the whole machine's (`/proc/stat`) and one process's
//! (`/proc/<pid>/stat`), in clock ticks. Used by `teleop launch --as-fast-as-possible`
//! (the clock pacer) and by `record_bench` (included there by path: the crate has
//! binaries only).

use anyhow::{Context, Result};

/// The whole machine's CPU time (`/proc/stat`'s `cpu` line), clock ticks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MachineTicks {
    pub busy: u64,
    pub total: u64,
}

impl MachineTicks {
    /// The busy fraction of all cores since `before`, [0, 1] (0 if no time passed).
    pub fn busy_fraction_since(&self, before: &MachineTicks) -> f64 {
        let total = self.total.saturating_sub(before.total);
        if total == 0 {
            return 0.0;
        }
        #[allow(clippy::cast_precision_loss)]
        let fraction = self.busy.saturating_sub(before.busy) as f64 / total as f64;
        fraction
    }
}

/// The machine's CPU time now.
///
/// # Errors
/// `/proc/stat` unreadable or without a well-formed `cpu` line.
pub fn machine_ticks() -> Result<MachineTicks> {
    let stat = std::fs::read_to_string("/proc/stat").context("reading /proc/stat")?;
    parse_machine(&stat).context("no well-formed cpu line in /proc/stat")
}

/// utime + stime of process `pid`, clock ticks.
///
/// # Errors
/// The file unreadable (the process ended) or malformed.
pub fn process_ticks(pid: u32) -> Result<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .with_context(|| format!("reading /proc/{pid}/stat (has the process ended?)"))?;
    parse_process(&stat).with_context(|| format!("/proc/{pid}/stat: no utime and stime"))
}

/// Peak resident set size of process `pid` so far (`VmHWM` of `/proc/<pid>/status`),
/// bytes.
///
/// # Errors
/// The file unreadable (the process ended) or without `VmHWM`.
pub fn process_peak_rss_bytes(pid: u32) -> Result<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .with_context(|| format!("reading /proc/{pid}/status (has the process ended?)"))?;
    parse_peak_rss(&status).with_context(|| format!("/proc/{pid}/status: no VmHWM"))
}

fn parse_peak_rss(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("VmHWM:"))?;
    let mut parts = line.split_whitespace().skip(1);
    let kb: u64 = parts.next()?.parse().ok()?;
    (parts.next()? == "kB").then_some(kb * 1024)
}

/// CPU time and peak memory of a set of processes over a run: sampled now and then
/// (each sample keeps the newest reading of a process still alive), so the figures
/// cover the run up to the last sample.
#[derive(Debug, Clone)]
pub struct ResourceSampler {
    start: std::time::Instant,
    procs: Vec<Sampled>,
    last_s: f64,
}

/// One process's readings so far.
#[derive(Debug, Clone)]
struct Sampled {
    name: String,
    pid: u32,
    first_ticks: Option<u64>,
    newest_ticks: Option<u64>,
    peak_rss_bytes: u64,
}

/// One process's use over the sampled run.
#[derive(Debug, Clone, serde::Serialize, PartialEq)]
pub struct ProcessUse {
    /// CPU time over the sampled wall time: 1.0 = one core busy throughout.
    pub cpu_cores: f64,
    /// Peak resident memory, MB (10^6 bytes).
    pub peak_rss_mb: f64,
}

impl ResourceSampler {
    /// Starts sampling `procs` (name, pid): the first sample now.
    pub fn new(procs: impl IntoIterator<Item = (String, u32)>) -> Self {
        let mut this = Self {
            start: std::time::Instant::now(),
            procs: procs
                .into_iter()
                .map(|(name, pid)| Sampled {
                    name,
                    pid,
                    first_ticks: None,
                    newest_ticks: None,
                    peak_rss_bytes: 0,
                })
                .collect(),
            last_s: 0.0,
        };
        this.sample();
        this
    }

    /// Reads every process still alive.
    pub fn sample(&mut self) {
        for p in &mut self.procs {
            if let Ok(t) = process_ticks(p.pid) {
                p.first_ticks.get_or_insert(t);
                p.newest_ticks = Some(t);
            }
            if let Ok(r) = process_peak_rss_bytes(p.pid) {
                p.peak_rss_bytes = p.peak_rss_bytes.max(r);
            }
        }
        self.last_s = self.start.elapsed().as_secs_f64();
    }

    /// Each process's use from the first to the last sample, by name.
    pub fn summary(&self) -> std::collections::BTreeMap<String, ProcessUse> {
        let tck = clock_ticks_per_s();
        self.procs
            .iter()
            .map(|p| {
                let ticks = match (p.first_ticks, p.newest_ticks) {
                    (Some(a), Some(b)) => b.saturating_sub(a),
                    _ => 0,
                };
                #[allow(clippy::cast_precision_loss)]
                let cpu_cores = if self.last_s > 0.0 {
                    ticks as f64 / tck / self.last_s
                } else {
                    0.0
                };
                #[allow(clippy::cast_precision_loss)]
                let peak_rss_mb = p.peak_rss_bytes as f64 / 1e6;
                (
                    p.name.clone(),
                    ProcessUse {
                        cpu_cores,
                        peak_rss_mb,
                    },
                )
            })
            .collect()
    }
}

/// Clock ticks per second of `/proc`'s CPU times (`getconf CLK_TCK`; 100, Linux's
/// USER_HZ on every architecture it runs on, if that fails).
pub fn clock_ticks_per_s() -> f64 {
    std::process::Command::new("getconf")
        .arg("CLK_TCK")
        .output()
        .ok()
        .and_then(|o| {
            String::from_utf8_lossy(&o.stdout)
                .trim()
                .parse::<f64>()
                .ok()
        })
        .filter(|t| *t > 0.0)
        .unwrap_or_else(|| {
            eprintln!("getconf CLK_TCK failed: taking 100 ticks/s");
            100.0
        })
}

/// Busy and total ticks from `/proc/stat`'s `cpu` line (idle and iowait are not busy).
fn parse_machine(text: &str) -> Option<MachineTicks> {
    let line = text.lines().find(|l| l.starts_with("cpu "))?;
    let v: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .map(str::parse)
        .collect::<Result<_, _>>()
        .ok()?;
    // user nice system idle iowait irq softirq steal (guest time is inside user).
    let total: u64 = v.iter().take(8).sum();
    let idle = v.get(3)? + v.get(4).copied().unwrap_or(0);
    Some(MachineTicks {
        busy: total.saturating_sub(idle),
        total,
    })
}

/// utime + stime from `/proc/<pid>/stat` (fields 14 and 15; the command name in
/// parentheses may hold spaces, so count from its closing parenthesis).
fn parse_process(text: &str) -> Option<u64> {
    let rest = &text[text.rfind(')')? + 1..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    // After ")": state is field 3, so utime (14) is index 11, stime (15) index 12.
    let utime: u64 = f.get(11)?.parse().ok()?;
    let stime: u64 = f.get(12)?.parse().ok()?;
    Some(utime + stime)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_memory_is_read_and_a_busy_process_uses_cpu() {
        assert_eq!(
            parse_peak_rss("Name:\tx\nVmHWM:\t  2048 kB\nVmRSS:\t 1 kB\n"),
            Some(2 * 1024 * 1024)
        );
        assert_eq!(parse_peak_rss("VmHWM:\t2048 MB\n"), None);
        assert_eq!(parse_peak_rss("Name: x\n"), None);
        let me = std::process::id();
        let mut s = ResourceSampler::new([("me".to_owned(), me), ("gone".to_owned(), u32::MAX)]);
        // Busy for 0.3 s on this thread.
        let t0 = std::time::Instant::now();
        let mut x = 0u64;
        while t0.elapsed().as_secs_f64() < 0.3 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        s.sample();
        let out = s.summary();
        assert!(out["me"].cpu_cores > 0.3, "{:?}", out["me"]);
        assert!(out["me"].peak_rss_mb > 1.0, "{:?}", out["me"]);
        assert_eq!(out["gone"].cpu_cores, 0.0);
        assert_eq!(out["gone"].peak_rss_mb, 0.0);
    }

    #[test]
    fn proc_files_are_read_and_odd_ones_refused() {
        assert_eq!(
            parse_machine("cpu  100 5 50 800 20 3 2 0 0 0\ncpu0 1 2 3 4\n"),
            Some(MachineTicks {
                busy: 160,
                total: 980
            })
        );
        assert_eq!(parse_machine("cpu0 1 2 3\n"), None);
        assert_eq!(parse_machine("cpu  1 x 3 4\n"), None);
        let line = "4242 (a node (x)) S 1 4242 4242 0 -1 4194560 1 0 0 0 117 23 0 0 20 0 9 0";
        assert_eq!(parse_process(line), Some(140));
        assert_eq!(parse_process("4242 (x) S 1"), None);
        let a = MachineTicks {
            busy: 100,
            total: 1000,
        };
        let b = MachineTicks {
            busy: 150,
            total: 1200,
        };
        assert!((b.busy_fraction_since(&a) - 0.25).abs() < 1e-12);
        assert_eq!(a.busy_fraction_since(&a), 0.0);
        // The real files of this machine and process.
        let m = machine_ticks().expect("/proc/stat");
        assert!(m.busy <= m.total && m.total > 0, "{m:?}");
        process_ticks(std::process::id()).expect("/proc/self");
        assert!(process_ticks(u32::MAX).is_err());
        assert!(clock_ticks_per_s() > 0.0);
    }
}
