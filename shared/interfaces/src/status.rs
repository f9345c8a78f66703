//! Status counters that one node publishes and others read by name (the report, the
//! recorder, the dataset export): their names, written once.
//!
//! A node's status carries its counters as (name, value) pairs (`NodeStatus`); most are
//! for people (the monitor table, `teleop node list`), these are also read by programs.

/// The PR2 arm controller (`pr2_arm_controller`).
pub mod arm {
    /// The capture stamp (ns, the wrist pose's header) of the wrist pose the newest
    /// engagement took as the operator's reference; 0 before the first. An observer
    /// measures the arm against the reference it really took (a clutch pressed while
    /// the hand moves takes the pose the controller held at that step, not the pose at
    /// the press).
    pub const ENGAGED_FROM_STAMP_NS: &str = "arm.engaged_from_stamp_ns";
}

/// The robot-site simulator's judge of the world's job (`remote_sim`).
pub mod job {
    /// 0/1: the object was lifted.
    pub const LIFTED: &str = "job.lifted";
    /// 0/1: the job succeeded.
    pub const SUCCEEDED: &str = "job.succeeded";
    /// From the robot's first motion to its return to its starting pose, ms (0 unless
    /// it succeeded).
    pub const COMPLETION_MS: &str = "job.completion_ms";
    /// Observations the judge refused (non-finite, missing object).
    pub const JUDGE_ERRORS: &str = "job.judge_errors";
    /// The prefix of the 0/1 failure counters, `job.failed.<failure>`.
    pub const FAILED_PREFIX: &str = "job.failed.";
    /// The failures, as named after [`FAILED_PREFIX`].
    pub const FAILURES: [&str; 2] = ["fell_off_table", "timed_out"];
}
