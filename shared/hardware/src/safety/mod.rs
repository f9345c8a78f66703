//! The last safety layer, in the process that owns the hardware.
//!
//! [`SafeArm`] and [`SafeHand`] wrap a backend and implement the same trait, so the
//! owning process hands commands to the wrapper and never to the backend: every command,
//! whoever sent it (the site's controller, a test, a foreign peer that got through the
//! bus), passes the filter, and a period without a command is filtered too (the command
//! timeout). The filters are pure cores ([`ArmSafety::step`], [`HandSafety::step`]) that
//! take the time, the new command if any and the measured state, and return what the
//! hardware gets.
//!
//! Each intervention is counted by kind ([`SafetyCounters`]); the owning process
//! reports them in its status.
//!
//! Limits (joint position, velocity, effort) come from the robot descriptions; the
//! end-effector speed cap, the acceleration limit and the timeouts from the config.

mod arm;
mod hand;

pub use arm::{ArmLimits, ArmSafety, ArmSafetyConfig, SafeArm};
pub use hand::{HandLimits, HandSafety, HandSafetyConfig, SafeHand};

use std::collections::BTreeMap;

/// Why a safety layer changed a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[non_exhaustive]
pub enum Intervention {
    /// A command with NaN/inf was refused (the previous one stays in force).
    NonFinite,
    /// No new command within the timeout: the robot is braked or held.
    Timeout,
    /// A joint speed above its limit was scaled down.
    Velocity,
    /// Motion toward a position limit was slowed so the joint stops before it.
    PositionLimit,
    /// A change of commanded speed above the acceleration limit was limited.
    Acceleration,
    /// An end-effector (tool point) speed above the cap was scaled down.
    ToolSpeed,
    /// An effort above its limit was clamped.
    Effort,
    /// No measured state to check the command against: the robot was stopped.
    NoState,
    /// A joint impedance's stiffness or damping above its cap was lowered.
    Gain,
}

impl Intervention {
    /// Short name for counters.
    pub fn name(self) -> &'static str {
        match self {
            Intervention::NonFinite => "non_finite",
            Intervention::Timeout => "timeout",
            Intervention::Velocity => "velocity",
            Intervention::PositionLimit => "position_limit",
            Intervention::Acceleration => "acceleration",
            Intervention::ToolSpeed => "tool_speed",
            Intervention::Effort => "effort",
            Intervention::NoState => "no_state",
            Intervention::Gain => "gain",
        }
    }
}

/// Periods in which each intervention acted, and commands seen.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SafetyCounters {
    /// Commands handed to the layer.
    pub commands: u64,
    /// Periods filtered.
    pub periods: u64,
    /// Periods (or commands, for [`Intervention::NonFinite`]) per intervention.
    pub interventions: BTreeMap<Intervention, u64>,
}

impl SafetyCounters {
    fn count(&mut self, what: Intervention) {
        *self.interventions.entry(what).or_default() += 1;
    }

    /// How often `what` acted.
    pub fn get(&self, what: Intervention) -> u64 {
        self.interventions.get(&what).copied().unwrap_or(0)
    }

    /// Counters named `<prefix>.commands`, `<prefix>.limited.<kind>`.
    pub fn named(&self, prefix: &str) -> Vec<(String, u64)> {
        let mut out = vec![
            (format!("{prefix}.commands"), self.commands),
            (format!("{prefix}.periods"), self.periods),
        ];
        for (k, n) in &self.interventions {
            out.push((format!("{prefix}.limited.{}", k.name()), *n));
        }
        out
    }
}

/// Why a safety layer could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SafetyConfigError {
    #[error("safety setting `{field}` = {value}: {reason}")]
    Invalid {
        field: &'static str,
        value: f64,
        reason: &'static str,
    },
    #[error("robot model: {0}")]
    Model(String),
}

fn check(field: &'static str, value: f64, lo: f64, hi: f64) -> Result<(), SafetyConfigError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(SafetyConfigError::Invalid {
            field,
            value,
            reason: "out of range",
        })
    }
}
