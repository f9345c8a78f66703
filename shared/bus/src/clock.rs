//! The clock a node reads: wall time in production, scripted time in tests. The bus
//! stamps what it publishes (source timestamp) and what it receives (receive time) with
//! the node's clock, so a test that drives every node of a scenario from one
//! [`ManualClock`] sees consistent ages, deadlines and timeouts end to end.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};

/// Nanoseconds since the Unix epoch, as a node sees them.
pub trait Clock: Send + Sync + std::fmt::Debug {
    /// Now, ns since the Unix epoch.
    fn now_ns(&self) -> i64;

    /// Now, s since the Unix epoch.
    fn now_s(&self) -> f64 {
        // Nanoseconds since 1970 stay far below 2^63 and lose < 1 us as f64.
        #[allow(clippy::cast_precision_loss)]
        let ns = self.now_ns() as f64;
        ns * 1e-9
    }

    /// How many of this clock's seconds pass per second of the wall clock: what the node
    /// runner divides its periods by. 1 for the system clock.
    fn rate(&self) -> f64 {
        1.0
    }
}

/// The system's wall clock (`CLOCK_REALTIME`): what every node runs on, and what makes
/// source timestamps comparable between machines with synchronized clocks.
#[derive(Debug, Clone, Copy, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now_ns(&self) -> i64 {
        teleop_msgs::unix_nanos_now()
    }
}

/// Simulated time that runs `scale` times as fast as the wall clock and agrees with it
/// at `origin_ns` (`teleop launch --time-scale`): every process of one run is given the
/// same origin and scale, so their stamps stay comparable. A scale below 1 runs the
/// system in slow motion (a machine too slow for the real-time rates keeps every
/// period in simulated time), above 1 faster than real time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledClock {
    /// One segment for the whole run: from the origin on at `scale`.
    segment: ClockSegment,
}

/// The scales a [`ScaledClock`] accepts, `[min, max]`.
pub const TIME_SCALE_RANGE: (f64, f64) = (0.05, 20.0);

impl ScaledClock {
    /// # Errors
    /// A text naming the scale when it is not within [`TIME_SCALE_RANGE`].
    pub fn new(origin_ns: i64, scale: f64) -> Result<Self, String> {
        check_rate(scale)?;
        Ok(Self {
            segment: ClockSegment {
                wall_ns: origin_ns,
                sim_ns: origin_ns,
                rate: scale,
            },
        })
    }

    /// The time at wall-clock time `wall_ns`, ns since the epoch.
    pub fn at(&self, wall_ns: i64) -> i64 {
        self.segment.at(wall_ns)
    }
}

/// `Err` naming `rate` unless it is within [`TIME_SCALE_RANGE`].
fn check_rate(rate: f64) -> Result<(), String> {
    if rate.is_finite() && (TIME_SCALE_RANGE.0..=TIME_SCALE_RANGE.1).contains(&rate) {
        Ok(())
    } else {
        Err(format!(
            "time scale must be in [{}, {}], got {rate}",
            TIME_SCALE_RANGE.0, TIME_SCALE_RANGE.1
        ))
    }
}

impl Clock for ScaledClock {
    fn now_ns(&self) -> i64 {
        self.at(teleop_msgs::unix_nanos_now())
    }

    fn rate(&self) -> f64 {
        self.segment.rate
    }
}

/// One piece of a [`PacedClock`]'s time: from wall-clock time `wall_ns` on, simulated
/// time is `sim_ns + (wall - wall_ns) x rate`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockSegment {
    pub wall_ns: i64,
    pub sim_ns: i64,
    pub rate: f64,
}

impl ClockSegment {
    /// Simulated time at wall-clock time `wall_ns`.
    pub fn at(&self, wall_ns: i64) -> i64 {
        // Differences of ns timestamps within a run lose nothing that matters as f64
        // (< 1 ns per 100 days).
        #[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
        let d = ((wall_ns - self.wall_ns) as f64 * self.rate).round() as i64;
        self.sim_ns + d
    }
}

/// What is wrong with a clock file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ClockFileError {
    #[error("clock file {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("clock file {path}, line {line}: {what}")]
    Malformed {
        path: String,
        line: usize,
        what: String,
    },
}

/// First line of a clock file.
const CLOCK_FILE_HEADER: &str = "teleop-clock 1";

/// How long a [`PacedClock`] uses what it read before reading its file again (wall
/// time). A [`PacedClockWriter`] announces every change at least
/// [`PACED_CLOCK_LEAD`] ahead, ten times this, so every reader has the new segment
/// before it takes effect and all processes switch at the same wall-clock instant.
pub const PACED_CLOCK_REFRESH: std::time::Duration = std::time::Duration::from_millis(2);
/// How far ahead of its wall-clock time a rate change is written.
pub const PACED_CLOCK_LEAD: std::time::Duration = std::time::Duration::from_millis(20);

fn parse_clock_file(
    path: &std::path::Path,
    text: &str,
) -> Result<Vec<ClockSegment>, ClockFileError> {
    let bad = |line: usize, what: String| ClockFileError::Malformed {
        path: path.display().to_string(),
        line,
        what,
    };
    let mut lines = text.lines();
    if lines.next() != Some(CLOCK_FILE_HEADER) {
        return Err(bad(1, format!("expected the header {CLOCK_FILE_HEADER:?}")));
    }
    let mut segments: Vec<ClockSegment> = Vec::new();
    for (k, line) in lines.enumerate() {
        let n = k + 2;
        let f: Vec<&str> = line.split_whitespace().collect();
        let [wall, sim, rate] = f.as_slice() else {
            return Err(bad(
                n,
                format!("expected `wall_ns sim_ns rate`, got {line:?}"),
            ));
        };
        let wall_ns = wall
            .parse()
            .map_err(|e| bad(n, format!("wall_ns {wall:?}: {e}")))?;
        let sim_ns = sim
            .parse()
            .map_err(|e| bad(n, format!("sim_ns {sim:?}: {e}")))?;
        let rate: f64 = rate
            .parse()
            .map_err(|e| bad(n, format!("rate {rate:?}: {e}")))?;
        check_rate(rate).map_err(|e| bad(n, format!("rate {rate} outside the range: {e}")))?;
        if segments.last().is_some_and(|p| p.wall_ns >= wall_ns) {
            return Err(bad(n, "segments must be in increasing wall_ns".into()));
        }
        segments.push(ClockSegment {
            wall_ns,
            sim_ns,
            rate,
        });
    }
    if segments.is_empty() {
        return Err(bad(2, "no segment".into()));
    }
    Ok(segments)
}

/// The segment in force at `wall_ns` (the first one before it starts).
fn segment_at(segments: &[ClockSegment], wall_ns: i64) -> ClockSegment {
    segments
        .iter()
        .rev()
        .find(|s| s.wall_ns <= wall_ns)
        .or(segments.first())
        .copied()
        .unwrap_or(ClockSegment {
            wall_ns,
            sim_ns: wall_ns,
            rate: 1.0,
        })
}

#[derive(Debug)]
struct PacedCache {
    read_at_ns: i64,
    segments: Vec<ClockSegment>,
    read_errors: u64,
}

/// Simulated time whose rate may change during a run (`teleop launch
/// --as-fast-as-possible`): piecewise linear in the wall clock, continuous and
/// increasing, its segments in a small file the launcher rewrites (atomically, by
/// rename) and every process of the run reads (at most every
/// [`PACED_CLOCK_REFRESH`]). All processes on one machine read one file, so they agree
/// on the time to within the wall clock's own reading.
#[derive(Debug)]
pub struct PacedClock {
    path: std::path::PathBuf,
    cache: std::sync::Mutex<PacedCache>,
}

impl PacedClock {
    /// The clock of `path`, read once now.
    ///
    /// # Errors
    /// The file cannot be read or is malformed (the error names the path and line).
    pub fn open(path: &std::path::Path) -> Result<Self, ClockFileError> {
        let read_at_ns = teleop_msgs::unix_nanos_now();
        let segments = read_clock_file(path)?;
        Ok(Self {
            path: path.to_path_buf(),
            cache: std::sync::Mutex::new(PacedCache {
                read_at_ns,
                segments,
                read_errors: 0,
            }),
        })
    }

    /// Times the file could not be read again since [`open`](Self::open) (the clock
    /// goes on with the segments it has: a launcher that ended leaves the rate as it
    /// was).
    pub fn read_errors(&self) -> u64 {
        self.cache.lock().map(|c| c.read_errors).unwrap_or(0)
    }

    fn segment_now(&self) -> (ClockSegment, i64) {
        // The wall time first: segments read after it are valid at it (a change is
        // written PACED_CLOCK_LEAD ahead).
        let wall = teleop_msgs::unix_nanos_now();
        let mut cache = match self.cache.lock() {
            Ok(c) => c,
            Err(p) => p.into_inner(),
        };
        #[allow(clippy::cast_possible_truncation)]
        let refresh = PACED_CLOCK_REFRESH.as_nanos() as i64;
        if wall - cache.read_at_ns > refresh {
            match read_clock_file(&self.path) {
                Ok(s) => {
                    cache.segments = s;
                    cache.read_at_ns = wall;
                }
                Err(e) => {
                    cache.read_errors += 1;
                    // Once, and then only every 1000th time: the run goes on.
                    if cache.read_errors % 1000 == 1 {
                        tracing::warn!("paced clock: {e}; keeping the last rate");
                    }
                    cache.read_at_ns = wall;
                }
            }
        }
        (segment_at(&cache.segments, wall), wall)
    }
}

fn read_clock_file(path: &std::path::Path) -> Result<Vec<ClockSegment>, ClockFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| ClockFileError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_clock_file(path, &text)
}

impl Clock for PacedClock {
    fn now_ns(&self) -> i64 {
        let (s, wall) = self.segment_now();
        s.at(wall)
    }

    fn rate(&self) -> f64 {
        self.segment_now().0.rate
    }
}

/// Writes a [`PacedClock`]'s file: the launcher's side.
#[derive(Debug)]
pub struct PacedClockWriter {
    path: std::path::PathBuf,
    /// The newest segments, the last one possibly announced for the near future.
    segments: Vec<ClockSegment>,
}

impl PacedClockWriter {
    /// A clock at `rate` that agrees with the wall clock now, written to `path`.
    ///
    /// # Errors
    /// The rate is out of range ([`ClockFileError::Malformed`] naming it) or the file
    /// cannot be written.
    pub fn create(path: &std::path::Path, rate: f64) -> Result<Self, ClockFileError> {
        let now = teleop_msgs::unix_nanos_now();
        let w = Self {
            path: path.to_path_buf(),
            segments: vec![ClockSegment {
                wall_ns: now,
                sim_ns: now,
                rate,
            }],
        };
        w.write()?;
        Ok(w)
    }

    /// The clock's time at wall-clock time `wall_ns`.
    pub fn at(&self, wall_ns: i64) -> i64 {
        segment_at(&self.segments, wall_ns).at(wall_ns)
    }

    /// The rate in force at `wall_ns`.
    pub fn rate_at(&self, wall_ns: i64) -> f64 {
        segment_at(&self.segments, wall_ns).rate
    }

    /// Changes the rate from [`PACED_CLOCK_LEAD`] after now on (continuously: the new
    /// segment starts where the old one is then).
    ///
    /// # Errors
    /// As [`create`](Self::create).
    pub fn set_rate(&mut self, rate: f64) -> Result<(), ClockFileError> {
        #[allow(clippy::cast_possible_truncation)]
        let lead = PACED_CLOCK_LEAD.as_nanos() as i64;
        let wall_ns = teleop_msgs::unix_nanos_now() + lead;
        let current = segment_at(&self.segments, wall_ns);
        let next = ClockSegment {
            wall_ns,
            sim_ns: current.at(wall_ns),
            rate,
        };
        // Keep the segments a reader may still be in (rate changes come every few
        // hundred ms; a reader refreshes every few ms).
        self.segments.push(next);
        let keep_from = self.segments.len().saturating_sub(4);
        self.segments.drain(..keep_from);
        self.write()
    }

    fn write(&self) -> Result<(), ClockFileError> {
        let mut text = format!("{CLOCK_FILE_HEADER}\n");
        for s in &self.segments {
            text.push_str(&format!("{} {} {}\n", s.wall_ns, s.sim_ns, s.rate));
        }
        // Refuse what a reader would refuse, before it is in the file.
        parse_clock_file(&self.path, &text)?;
        let io = |source| ClockFileError::Io {
            path: self.path.display().to_string(),
            source,
        };
        let tmp = self.path.with_extension("tmp");
        std::fs::write(&tmp, text).map_err(io)?;
        std::fs::rename(&tmp, &self.path).map_err(io)
    }
}

/// A clock that moves only when told to: for tests that script time.
#[derive(Debug, Default)]
pub struct ManualClock {
    now_ns: AtomicI64,
}

impl ManualClock {
    /// A clock at `start_s` seconds since the epoch.
    pub fn starting_at(start_s: f64) -> Arc<Self> {
        let clock = Arc::new(Self::default());
        clock.set_s(start_s);
        clock
    }

    /// Jumps to `t_s` (may go backwards: the nodes must cope).
    pub fn set_s(&self, t_s: f64) {
        // Test times are far below the i64 range of nanoseconds.
        #[allow(clippy::cast_possible_truncation)]
        self.now_ns
            .store((t_s * 1e9).round() as i64, Ordering::SeqCst);
    }

    /// Moves forward by `dt_s`.
    pub fn advance_s(&self, dt_s: f64) {
        #[allow(clippy::cast_possible_truncation)]
        self.now_ns
            .fetch_add((dt_s * 1e9).round() as i64, Ordering::SeqCst);
    }
}

impl Clock for ManualClock {
    fn now_ns(&self) -> i64 {
        self.now_ns.load(Ordering::SeqCst)
    }
}

/// The clock every node uses unless a test passes another.
pub fn system() -> Arc<dyn Clock> {
    Arc::new(SystemClock)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_clock_runs_at_its_scale_from_its_origin() {
        let c = ScaledClock::new(1_000_000_000_000, 2.0).expect("valid");
        assert_eq!(c.at(1_000_000_000_000), 1_000_000_000_000);
        assert_eq!(c.at(1_000_500_000_000), 1_001_000_000_000);
        assert_eq!(c.rate(), 2.0);
        let slow = ScaledClock::new(0, 0.5).expect("valid");
        assert_eq!(slow.at(10_000), 5_000);
        for bad in [0.0, -1.0, 0.01, 25.0, f64::NAN, f64::INFINITY] {
            let e = ScaledClock::new(0, bad).expect_err("out of range");
            assert!(e.contains("time scale"), "{e}");
        }
        assert_eq!(SystemClock.rate(), 1.0);
    }

    #[test]
    fn manual_clock_moves_only_when_told() {
        let c = ManualClock::starting_at(100.0);
        assert_eq!(c.now_ns(), 100_000_000_000);
        c.advance_s(0.25);
        assert!((c.now_s() - 100.25).abs() < 1e-9);
        c.set_s(1.0);
        assert_eq!(c.now_ns(), 1_000_000_000);
        let sys = SystemClock.now_s();
        assert!(sys > 1.7e9, "system clock reads Unix time, got {sys}");
    }

    fn temp_path(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("teleop-clock-test-{}-{name}", std::process::id()))
    }

    #[test]
    fn a_paced_clock_follows_its_writer_continuously_and_two_readers_agree() {
        let path = temp_path("agree");
        let mut w = PacedClockWriter::create(&path, 1.0).expect("written");
        let a = PacedClock::open(&path).expect("read");
        let b = PacedClock::open(&path).expect("read");
        assert_eq!(a.rate(), 1.0);
        w.set_rate(4.0).expect("written");
        // Before the change takes effect the rate is still 1; after it, 4.
        assert_eq!(a.rate(), 1.0);
        std::thread::sleep(PACED_CLOCK_LEAD + PACED_CLOCK_REFRESH * 2);
        assert_eq!(a.rate(), 4.0);
        assert_eq!(b.rate(), 4.0);
        // Both readers (and the writer) give the same time for the same wall instant,
        // and the time is continuous across the change.
        let t_a = a.now_ns();
        let t_b = b.now_ns();
        let t_w = w.at(teleop_msgs::unix_nanos_now());
        assert!(t_a <= t_b && t_b <= t_w, "{t_a} {t_b} {t_w}");
        // Read within a few hundred microseconds of each other at 4x: < 5 ms apart.
        assert!(t_w - t_a < 5_000_000, "{}", t_w - t_a);
        let seg = w.segments.clone();
        let (old, new) = (seg[seg.len() - 2], seg[seg.len() - 1]);
        assert_eq!(old.at(new.wall_ns), new.sim_ns, "continuous at the change");
        // Monotonic over rate changes up and down.
        let mut last = a.now_ns();
        for rate in [0.5, 8.0, 1.0] {
            w.set_rate(rate).expect("written");
            for _ in 0..15 {
                std::thread::sleep(std::time::Duration::from_millis(2));
                let t = a.now_ns();
                assert!(t >= last, "time went back at rate {rate}");
                last = t;
            }
        }
        assert_eq!(a.read_errors(), 0);
        // The file gone: the clock goes on at its last rate and counts the failures.
        std::fs::remove_file(&path).expect("removed");
        std::thread::sleep(PACED_CLOCK_REFRESH * 2);
        let t = a.now_ns();
        assert!(t >= last);
        assert!(a.read_errors() >= 1);
    }

    #[test]
    fn bad_clock_files_are_refused_naming_what_is_wrong() {
        let missing = temp_path("missing");
        let e = PacedClock::open(&missing).expect_err("missing");
        assert!(e.to_string().contains("teleop-clock-test"), "{e}");
        let path = temp_path("bad");
        for (text, want) in [
            ("", "header"),
            ("teleop-clock 1\n", "no segment"),
            ("teleop-clock 1\n1 2\n", "line 2"),
            ("teleop-clock 1\n1 2 x\n", "rate \"x\""),
            ("teleop-clock 1\n1 2 NaN\n", "outside"),
            ("teleop-clock 1\n1 2 100\n", "outside"),
            ("teleop-clock 1\n5 2 1\n4 3 1\n", "increasing"),
        ] {
            std::fs::write(&path, text).expect("written");
            let e = PacedClock::open(&path).expect_err(text);
            assert!(e.to_string().contains(want), "{text:?}: {e}");
        }
        assert!(PacedClockWriter::create(&path, 0.0).is_err());
        std::fs::remove_file(&path).ok();
    }
}
