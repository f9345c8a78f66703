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
