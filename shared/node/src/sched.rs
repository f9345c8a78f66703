//! A node process's scheduling: normal time sharing, or the operating system's
//! real-time FIFO class for the processes on a latency path (ros2_control runs its
//! control thread this way).
//!
//! The priority is set on the main thread before the async runtime starts, so every
//! thread the process starts afterwards (runtime workers, Zenoh's own, ONNX Runtime's)
//! inherits it. Where the process may not (no root, no `CAP_SYS_NICE`, no
//! `RLIMIT_RTPRIO`: a container without `--cap-add SYS_NICE`, an ordinary user), it
//! says so and runs at normal priority: a priority is a help to the latency, never a
//! condition for running. The kernel's real-time throttling (`sched_rt_runtime_us`,
//! 95 % by default) keeps a runaway real-time thread from starving the machine.

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

/// The highest priority a node may ask for: 99 is left to the kernel's own threads.
pub const MAX_REALTIME_PRIORITY: u8 = 98;

/// The default priority of the processes on the depth frame's path to the hand (the
/// simulated camera, hand inference, the Shadow hand controller): ros2_control's
/// default for its control thread.
pub const LATENCY_PATH_PRIORITY: u8 = 50;

/// The `[scheduling]` section of every node's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SchedulingConfig {
    /// 0: normal time sharing. 1-98: every thread of the process in the real-time FIFO
    /// class at this priority (Linux `SCHED_FIFO`), where the process is permitted;
    /// otherwise a warning and normal time sharing.
    pub realtime_priority: u8,
}

impl SchedulingConfig {
    /// Real-time FIFO scheduling at `priority` (0 = normal).
    pub const fn realtime(priority: u8) -> Self {
        Self {
            realtime_priority: priority,
        }
    }

    /// # Errors
    /// A text naming the field when the priority is above [`MAX_REALTIME_PRIORITY`].
    pub fn validate(&self) -> Result<(), String> {
        if self.realtime_priority > MAX_REALTIME_PRIORITY {
            return Err(format!(
                "scheduling.realtime_priority must be 0 (normal) or 1-{MAX_REALTIME_PRIORITY}, got {}",
                self.realtime_priority
            ));
        }
        Ok(())
    }
}

/// What the process got.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Scheduling {
    /// Normal time sharing, as configured.
    Normal,
    /// Real-time FIFO at this priority.
    Realtime { priority: u8 },
    /// Real-time was asked for and refused; the process runs at normal priority.
    Refused { requested: u8, reason: String },
}

impl Scheduling {
    /// The real-time priority the process runs at (0 = normal time sharing).
    pub fn granted(&self) -> u8 {
        match self {
            Self::Realtime { priority } => *priority,
            Self::Normal | Self::Refused { .. } => 0,
        }
    }

    /// The real-time priority the configuration asked for (0 = none).
    pub fn requested(&self) -> u8 {
        match self {
            Self::Normal => 0,
            Self::Realtime { priority } => *priority,
            Self::Refused { requested, .. } => *requested,
        }
    }

    /// The counters every node's status carries about it.
    pub fn counters(&self) -> [(String, u64); 2] {
        [
            (
                "process.realtime_priority".to_owned(),
                u64::from(self.granted()),
            ),
            (
                "process.realtime_priority_requested".to_owned(),
                u64::from(self.requested()),
            ),
        ]
    }
}

static PROCESS: OnceLock<Scheduling> = OnceLock::new();

/// Sets the calling thread's scheduling from `cfg` (call it on the main thread before
/// any other thread starts: they inherit it), logs the outcome, and remembers it for
/// [`process`]. A refusal is logged as a warning, not returned as an error.
pub fn apply(cfg: &SchedulingConfig) -> Scheduling {
    let outcome = match cfg.realtime_priority {
        0 => {
            leave_realtime();
            Scheduling::Normal
        }
        p => match set_current_thread_fifo(p) {
            Ok(()) => {
                tracing::info!(
                    priority = p,
                    "real-time FIFO scheduling for every thread of this process"
                );
                Scheduling::Realtime { priority: p }
            }
            Err(reason) => {
                tracing::warn!(
                    requested = p,
                    %reason,
                    "real-time scheduling refused, running at normal priority (it needs root, \
                     CAP_SYS_NICE or an RLIMIT_RTPRIO of at least the priority; \
                     scheduling.realtime_priority = 0 turns it off)"
                );
                Scheduling::Refused {
                    requested: p,
                    reason,
                }
            }
        },
    };
    let _ = PROCESS.set(outcome.clone());
    outcome
}

/// What [`apply`] gave this process, if it was called (node binaries call it; nodes
/// run inside a test process do not).
pub fn process() -> Option<&'static Scheduling> {
    PROCESS.get()
}

#[cfg(unix)]
fn set_current_thread_fifo(priority: u8) -> Result<(), String> {
    use thread_priority::unix::{
        RealtimeThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
        thread_native_id,
    };
    use thread_priority::{ThreadPriority, ThreadPriorityValue};
    let value = ThreadPriorityValue::try_from(priority).map_err(|e| e.to_owned())?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| match e {
        thread_priority::Error::OS(code) => std::io::Error::from_raw_os_error(code).to_string(),
        other => format!("{other:?}"),
    })
}

/// Normal time sharing for the calling thread if it inherited a real-time class (a
/// launcher started under `chrt`): 0 means normal, whatever the parent ran at.
#[cfg(unix)]
fn leave_realtime() {
    use thread_priority::unix::{
        NormalThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
        thread_native_id, thread_schedule_policy,
    };
    use thread_priority::{ThreadPriority, ThreadPriorityOsValue};
    if let Ok(ThreadSchedulePolicy::Realtime(_)) = thread_schedule_policy() {
        match set_thread_priority_and_policy(
            thread_native_id(),
            ThreadPriority::Os(ThreadPriorityOsValue::default()),
            ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other),
        ) {
            Ok(()) => tracing::info!(
                "real-time scheduling inherited from the parent process dropped: \
                 scheduling.realtime_priority = 0"
            ),
            Err(e) => tracing::warn!(error = ?e, "cannot leave the inherited real-time scheduling"),
        }
    }
}

#[cfg(not(unix))]
fn leave_realtime() {}

#[cfg(not(unix))]
fn set_current_thread_fifo(_priority: u8) -> Result<(), String> {
    Err("real-time FIFO scheduling is implemented for Unix only".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_priority_range_is_checked_by_name() {
        assert!(SchedulingConfig::default().validate().is_ok());
        assert!(SchedulingConfig::realtime(1).validate().is_ok());
        assert!(SchedulingConfig::realtime(98).validate().is_ok());
        let e = SchedulingConfig::realtime(99).validate().unwrap_err();
        assert!(e.contains("scheduling.realtime_priority"), "{e}");
        let parsed: Result<SchedulingConfig, _> = toml::from_str("realtime_prio = 3");
        assert!(parsed.is_err(), "an unknown field is refused");
    }

    #[test]
    fn the_outcome_says_what_was_asked_and_what_was_granted() {
        assert_eq!(Scheduling::Normal.granted(), 0);
        assert_eq!(Scheduling::Realtime { priority: 40 }.granted(), 40);
        let refused = Scheduling::Refused {
            requested: 40,
            reason: "Operation not permitted".into(),
        };
        assert_eq!(refused.granted(), 0);
        assert_eq!(refused.requested(), 40);
        assert_eq!(
            refused.counters(),
            [
                ("process.realtime_priority".to_owned(), 0),
                ("process.realtime_priority_requested".to_owned(), 40)
            ]
        );
    }

    /// Real scheduling on a thread of its own (so the test process's other threads are
    /// untouched): granted where permitted, refused with the OS's reason otherwise;
    /// either way the thread runs on.
    #[test]
    fn a_thread_gets_fifo_where_permitted_and_runs_on_where_not() {
        let outcome = std::thread::spawn(|| {
            let result = set_current_thread_fifo(5);
            let policy = thread_priority::unix::thread_schedule_policy();
            (result, policy)
        })
        .join()
        .expect("thread");
        match outcome {
            (Ok(()), Ok(policy)) => assert_eq!(
                policy,
                thread_priority::unix::ThreadSchedulePolicy::Realtime(
                    thread_priority::unix::RealtimeThreadSchedulePolicy::Fifo
                )
            ),
            (Err(reason), _) => assert!(!reason.is_empty()),
            (Ok(()), Err(e)) => panic!("policy unreadable after setting it: {e:?}"),
        }
    }

    /// Priority 0 means normal time sharing even for a thread that inherited the
    /// real-time class (a launcher started under `chrt`).
    #[test]
    fn zero_leaves_an_inherited_real_time_class() {
        let policies = std::thread::spawn(|| {
            if set_current_thread_fifo(5).is_err() {
                return None; // not permitted here: nothing to leave
            }
            let before = thread_priority::unix::thread_schedule_policy().ok();
            leave_realtime();
            let after = thread_priority::unix::thread_schedule_policy().ok();
            Some((before, after))
        })
        .join()
        .expect("thread");
        if let Some((before, after)) = policies {
            use thread_priority::unix::{
                NormalThreadSchedulePolicy, RealtimeThreadSchedulePolicy, ThreadSchedulePolicy,
            };
            assert_eq!(
                before,
                Some(ThreadSchedulePolicy::Realtime(
                    RealtimeThreadSchedulePolicy::Fifo
                ))
            );
            assert_eq!(
                after,
                Some(ThreadSchedulePolicy::Normal(
                    NormalThreadSchedulePolicy::Other
                ))
            );
        }
    }
}
