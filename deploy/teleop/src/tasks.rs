//! The tasks `teleop launch --task` runs as judged jobs, and the thesis's figures for
//! each (what `--seeds` sums its runs up against).

use serde::Serialize;

/// The task of the operator who watches the display and does the robot world's pick
/// job (`[pick.job]` of `remote_sim`), judged by the robot-site simulator.
pub const PICK_JOB: &str = "pick";

/// The task of the operator who watches the display and builds the robot world's tower
/// (`scene = "tower"`, `[tower]` of `remote_sim`): two blocks stacked on a third.
pub const TOWER_JOB: &str = "tower";

/// The judged jobs of the operator who watches the display.
pub const WATCHED_JOBS: [&str; 2] = [PICK_JOB, TOWER_JOB];

/// A task's figures in the thesis: its tables' success rate and average completion
/// time ("calculated when the robot started to move until it went back to the
/// starting pose", ch. 6.4, Table 6.1).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct ThesisFigure {
    /// Where the thesis gives it.
    pub source: &'static str,
    pub success_pct: f64,
    pub time_s: f64,
}

/// The thesis's figures for the task launched as `task`.
#[must_use]
pub fn thesis_figures(task: &str) -> &'static [ThesisFigure] {
    match task {
        PICK_JOB => &[
            ThesisFigure {
                source: "Table 6.1, pick1 (the Pringles can; 5 trials by one demonstrator)",
                success_pct: 100.0,
                time_s: 18.5,
            },
            ThesisFigure {
                source: "Table 7.1, pick",
                success_pct: 90.0,
                time_s: 52.5,
            },
        ],
        TOWER_JOB => &[ThesisFigure {
            source: "Table 7.1, tower (three different objects stacked)",
            success_pct: 60.0,
            time_s: 102.8,
        }],
        _ => &[],
    }
}
