//! File replay of a recorded wrist trajectory: a CSV of timestamped poses, played back
//! behind the [`WristTracker`] trait so everything downstream runs as with a live tracker.
//!
//! # Format
//!
//! UTF-8 text, one pose per line, comma-separated:
//!
//! ```text
//! # comments and blank lines are skipped
//! t_s,x_m,y_m,z_m,qx,qy,qz,qw
//! 0.000,0.40,-0.10,0.90,0,0,0,1
//! 0.003125,0.40,-0.10,0.90,0,0,0,1
//! ```
//!
//! * the header line is required and must name exactly these eight columns, in this
//!   order (a file with other columns is refused rather than guessed at);
//! * `t_s`: seconds, strictly increasing; the first row is played at replay start;
//! * `x_m, y_m, z_m`: position in metres, tracker frame;
//! * `qx, qy, qz, qw`: orientation quaternion (Hamilton, scalar last, as in ROS
//!   `geometry_msgs/Quaternion`); it must have a norm within 1 % of 1 and is
//!   normalized on load;
//! * an empty position field (`t,,,,,,,`) marks a dropout: the tracker had no
//!   measurement then, and the replay reports none until the next valid row.
//!
//! Between two rows the pose is interpolated (linear position, spherical orientation)
//! unless the rows are more than [`ReplayConfig::max_gap_s`] apart, which is played as
//! a dropout. After the last row the replay ends ([`ReplayEnd::Stop`]: no measurement)
//! or starts again ([`ReplayEnd::Loop`]).

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_hardware::{HardwareError, WristTracker};

/// The header the format requires.
pub const CSV_HEADER: [&str; 8] = ["t_s", "x_m", "y_m", "z_m", "qx", "qy", "qz", "qw"];

/// Errors reading a replay file, each naming the file and line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    #[error("cannot read pose replay {path}: {reason}")]
    Io { path: PathBuf, reason: String },
    #[error("{path}: no header line; expected `{}`", CSV_HEADER.join(","))]
    MissingHeader { path: PathBuf },
    #[error("{path}:{line}: header `{found}` is not `{}`", CSV_HEADER.join(","))]
    BadHeader {
        path: PathBuf,
        line: usize,
        found: String,
    },
    #[error("{path}:{line}: {reason}")]
    BadRow {
        path: PathBuf,
        line: usize,
        reason: String,
    },
    #[error("{path}: no pose rows")]
    Empty { path: PathBuf },
}

/// What the replay does after its last row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReplayEnd {
    /// No measurement from then on (a downstream watchdog stops the robots).
    Stop,
    /// Starts again from the first row.
    Loop,
}

/// Configuration of a replay source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayConfig {
    /// The CSV file.
    pub path: PathBuf,
    /// After the last row.
    #[serde(default = "default_end")]
    pub end: ReplayEnd,
    /// Rows further apart than this (s) are not interpolated: the gap is a dropout.
    #[serde(default = "default_max_gap_s")]
    pub max_gap_s: f64,
}

fn default_end() -> ReplayEnd {
    ReplayEnd::Stop
}

fn default_max_gap_s() -> f64 {
    0.1
}

impl ReplayConfig {
    /// Checks the values.
    ///
    /// # Errors
    /// A message naming the bad field.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.max_gap_s.is_finite() && self.max_gap_s > 0.0) {
            return Err(format!(
                "replay.max_gap_s must be a positive number of seconds, got {}",
                self.max_gap_s
            ));
        }
        Ok(())
    }
}

/// One row: a time and a pose, or a dropout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayRow {
    pub t_s: f64,
    pub pose: Option<Isometry3<f64>>,
}

/// A loaded trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseTrajectory {
    rows: Vec<ReplayRow>,
}

impl PoseTrajectory {
    /// Reads and checks a replay file.
    ///
    /// # Errors
    /// [`ReplayError`] naming the file, the line and what was wrong.
    pub fn load(path: &Path) -> Result<Self, ReplayError> {
        let text = std::fs::read_to_string(path).map_err(|e| ReplayError::Io {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Self::parse(&text, path)
    }

    /// Parses replay text; `path` only names the source in errors.
    ///
    /// # Errors
    /// [`ReplayError`] naming the line and what was wrong.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ReplayError> {
        let bad = |line: usize, reason: String| ReplayError::BadRow {
            path: path.to_path_buf(),
            line,
            reason,
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((header_line, header)) = lines.next() else {
            return Err(ReplayError::MissingHeader {
                path: path.to_path_buf(),
            });
        };
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        if names != CSV_HEADER {
            return Err(ReplayError::BadHeader {
                path: path.to_path_buf(),
                line: header_line,
                found: header.to_string(),
            });
        }
        let mut rows: Vec<ReplayRow> = Vec::new();
        for (line, text) in lines {
            let fields: Vec<&str> = text.split(',').map(str::trim).collect();
            if fields.len() != CSV_HEADER.len() {
                return Err(bad(
                    line,
                    format!("{} fields, expected {}", fields.len(), CSV_HEADER.len()),
                ));
            }
            let t_s = parse_number(fields[0], "t_s").map_err(|r| bad(line, r))?;
            if let Some(prev) = rows.last()
                && t_s <= prev.t_s
            {
                return Err(bad(
                    line,
                    format!(
                        "t_s {t_s} is not after the previous row's {} (times must increase)",
                        prev.t_s
                    ),
                ));
            }
            let pose = if fields[1..].iter().all(|f| f.is_empty()) {
                None
            } else {
                let mut v = [0.0; 7];
                for (k, slot) in v.iter_mut().enumerate() {
                    *slot =
                        parse_number(fields[k + 1], CSV_HEADER[k + 1]).map_err(|r| bad(line, r))?;
                }
                let q = Quaternion::new(v[6], v[3], v[4], v[5]);
                let norm = q.norm();
                if (norm - 1.0).abs() > 0.01 {
                    return Err(bad(
                        line,
                        format!("quaternion norm {norm:.4} is not 1 (within 1 %)"),
                    ));
                }
                Some(Isometry3::from_parts(
                    Translation3::new(v[0], v[1], v[2]),
                    UnitQuaternion::from_quaternion(q),
                ))
            };
            rows.push(ReplayRow { t_s, pose });
        }
        if rows.is_empty() {
            return Err(ReplayError::Empty {
                path: path.to_path_buf(),
            });
        }
        Ok(Self { rows })
    }

    /// The rows.
    pub fn rows(&self) -> &[ReplayRow] {
        &self.rows
    }

    /// Duration from the first to the last row, s.
    pub fn duration_s(&self) -> f64 {
        match (self.rows.first(), self.rows.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        }
    }

    /// The pose `t` seconds after the first row: interpolated between the rows around
    /// it, `None` in a dropout, in a gap longer than `max_gap_s`, or outside the rows.
    pub fn sample(&self, t: f64, max_gap_s: f64) -> Option<Isometry3<f64>> {
        let t0 = self.rows.first()?.t_s;
        let t = t0 + t;
        let i = self.rows.partition_point(|r| r.t_s <= t);
        if i == 0 {
            return None;
        }
        let a = self.rows[i - 1];
        let Some(b) = self.rows.get(i) else {
            // At or after the last row: its pose only exactly at its time.
            return if t == a.t_s { a.pose } else { None };
        };
        let (pa, pb) = (a.pose?, b.pose);
        if t == a.t_s {
            return Some(pa);
        }
        let pb = pb?;
        if b.t_s - a.t_s > max_gap_s {
            return None;
        }
        let s = (t - a.t_s) / (b.t_s - a.t_s);
        Some(pa.lerp_slerp(&pb, s))
    }
}

fn parse_number(field: &str, name: &str) -> Result<f64, String> {
    let v: f64 = field
        .parse()
        .map_err(|_| format!("{name} `{field}` is not a number"))?;
    if !v.is_finite() {
        return Err(format!("{name} is {v}, not a finite number"));
    }
    Ok(v)
}

/// A [`WristTracker`] playing a [`PoseTrajectory`]: the first `read` starts the replay.
#[derive(Debug, Clone)]
pub struct ReplayTracker {
    trajectory: PoseTrajectory,
    end: ReplayEnd,
    max_gap_s: f64,
    start_s: Option<f64>,
}

impl ReplayTracker {
    /// Loads the file the config names.
    ///
    /// # Errors
    /// [`ReplayError`] for a missing or malformed file.
    pub fn open(config: &ReplayConfig) -> Result<Self, ReplayError> {
        Ok(Self::new(
            PoseTrajectory::load(&config.path)?,
            config.end,
            config.max_gap_s,
        ))
    }

    /// Plays `trajectory`.
    pub fn new(trajectory: PoseTrajectory, end: ReplayEnd, max_gap_s: f64) -> Self {
        Self {
            trajectory,
            end,
            max_gap_s,
            start_s: None,
        }
    }

    /// True once a non-looping replay has played its last row.
    pub fn finished(&self, now_s: f64) -> bool {
        self.end == ReplayEnd::Stop
            && self
                .start_s
                .is_some_and(|s| now_s - s > self.trajectory.duration_s())
    }
}

impl WristTracker for ReplayTracker {
    fn read(&mut self, now_s: f64) -> Result<Option<Isometry3<f64>>, HardwareError> {
        if !now_s.is_finite() {
            return Err(HardwareError::Fault(format!(
                "replay read at a non-finite time {now_s}"
            )));
        }
        let start = *self.start_s.get_or_insert(now_s);
        let mut t = now_s - start;
        let duration = self.trajectory.duration_s();
        if self.end == ReplayEnd::Loop && duration > 0.0 {
            t = t.rem_euclid(duration);
        }
        Ok(self.trajectory.sample(t, self.max_gap_s))
    }
}

/// Writes poses in the replay format (for recording a session, and for tests).
pub fn write_csv(rows: &[ReplayRow]) -> String {
    let mut out = CSV_HEADER.join(",");
    out.push('\n');
    for r in rows {
        match r.pose {
            Some(p) => {
                let t: Vector3<f64> = p.translation.vector;
                let q = p.rotation.quaternion();
                out.push_str(&format!(
                    "{},{},{},{},{},{},{},{}\n",
                    r.t_s, t.x, t.y, t.z, q.i, q.j, q.k, q.w
                ));
            }
            None => out.push_str(&format!("{},,,,,,,\n", r.t_s)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path() -> &'static Path {
        Path::new("test.csv")
    }

    fn pose(x: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::new(Vector3::new(x, 0.2, 0.9), Vector3::new(0.0, 0.0, yaw))
    }

    #[test]
    fn round_trip_and_interpolation() {
        let rows = vec![
            ReplayRow {
                t_s: 10.0,
                pose: Some(pose(0.0, 0.0)),
            },
            ReplayRow {
                t_s: 10.05,
                pose: Some(pose(0.1, 0.4)),
            },
            ReplayRow {
                t_s: 10.1,
                pose: None,
            },
            ReplayRow {
                t_s: 10.15,
                pose: Some(pose(0.2, 0.0)),
            },
        ];
        let traj = PoseTrajectory::parse(&write_csv(&rows), path()).expect("parses");
        assert_eq!(traj.rows().len(), 4);
        assert!((traj.duration_s() - 0.15).abs() < 1e-12);
        let mid = traj.sample(0.025, 0.1).expect("between two poses");
        assert!((mid.translation.x - 0.05).abs() < 1e-9);
        assert!((mid.rotation.angle() - 0.2).abs() < 1e-9);
        // Into the dropout row and out of it: no measurement.
        assert_eq!(traj.sample(0.07, 0.1), None);
        assert_eq!(traj.sample(0.12, 0.1), None);
        // The last row exactly, then nothing.
        let last = traj.sample(0.15, 0.1).expect("last row");
        assert!((last.translation.x - 0.2).abs() < 1e-9);
        assert_eq!(traj.sample(0.2, 0.1), None);
        assert_eq!(traj.sample(-0.01, 0.1), None);
        // A gap longer than max_gap_s is a dropout.
        assert_eq!(traj.sample(0.025, 0.01), None);
    }

    #[test]
    fn tracker_plays_from_the_first_read_and_loops() {
        let rows: Vec<ReplayRow> = (0..=10)
            .map(|i| ReplayRow {
                t_s: f64::from(i) * 0.1,
                pose: Some(pose(f64::from(i) * 0.01, 0.0)),
            })
            .collect();
        let traj = PoseTrajectory::parse(&write_csv(&rows), path()).expect("parses");
        let mut stop = ReplayTracker::new(traj.clone(), ReplayEnd::Stop, 0.5);
        let first = stop.read(100.0).expect("reads").expect("pose");
        assert!(first.translation.x.abs() < 1e-12);
        let later = stop.read(100.55).expect("reads").expect("pose");
        assert!((later.translation.x - 0.055).abs() < 1e-9);
        assert_eq!(stop.read(101.5).expect("reads"), None);
        assert!(stop.finished(101.5));
        let mut looped = ReplayTracker::new(traj, ReplayEnd::Loop, 0.5);
        looped.read(0.0).expect("reads");
        let wrapped = looped.read(1.25).expect("reads").expect("pose");
        // 1.25 s into a 1 s loop: 0.25 s, between the rows at 0.2 and 0.3 s.
        assert!((wrapped.translation.x - 0.025).abs() < 1e-9);
        assert!(looped.read(f64::NAN).is_err());
    }

    #[test]
    fn malformed_files_are_refused_with_the_line() {
        let h = CSV_HEADER.join(",");
        let cases: [(String, &str); 7] = [
            (String::new(), "no header"),
            (
                "t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n".into(),
                "header `t,x",
            ),
            (format!("{h}\n"), "no pose rows"),
            (format!("{h}\n0,0,0,0,0,0,0\n"), ":2: 7 fields"),
            (
                format!("{h}\n0,0,0,0,0,0,0,1\n0,0,0,0,0,0,0,1\n"),
                ":3: t_s 0 is not after",
            ),
            (format!("{h}\n# c\n0,NaN,0,0,0,0,0,1\n"), ":3: x_m is NaN"),
            (
                format!("{h}\n0,0,0,0,0,0,0,2\n"),
                ":2: quaternion norm 2.0000",
            ),
        ];
        for (text, want) in cases {
            let err = PoseTrajectory::parse(&text, path())
                .expect_err(want)
                .to_string();
            assert!(err.contains(want), "`{err}` should contain `{want}`");
        }
        let missing = PoseTrajectory::load(Path::new("/nonexistent/poses.csv"))
            .expect_err("missing file")
            .to_string();
        assert!(missing.contains("/nonexistent/poses.csv"), "{missing}");
    }
}
