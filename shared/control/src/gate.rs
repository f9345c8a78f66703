//! The operator gate: whether the operator lets a robot move, one decision for the arm
//! and the hand alike (thesis ch. 7.3: the right pedal and the deadman switch enable
//! the PR2 arm and the Shadow hand).
//!
//! The gate is open when, at `now_s`:
//! 1. the operator site is alive (its nodes' liveliness);
//! 2. the operator input (pedals, switch) is fresh (received within `input_timeout_s`);
//! 3. the motion scale is valid (finite, in (0, 1]);
//! 4. the enable (deadman) switch is held;
//! 5. with [`GateMode::ClutchAndEnable`], the clutch (right pedal) is pressed.
//!
//! The first condition that fails names why the gate is closed ([`Closed`]), in that
//! order. Pure: no clock, no I/O.

use serde::{Deserialize, Serialize};

/// The operator's pedals and switch as a robot-site node received them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatorSample {
    /// Receive time, s (the node's clock).
    pub received_s: f64,
    /// Right pedal.
    pub clutch: bool,
    /// Deadman switch.
    pub enable: bool,
    /// Scale of the operator's motion on the robot.
    pub motion_scale: f64,
}

impl OperatorSample {
    /// Pedals and switch released (scale 1), received at `received_s`: what a
    /// controller must hear once before it takes a press for one.
    pub fn released(received_s: f64) -> Self {
        Self {
            received_s,
            clutch: false,
            enable: false,
            motion_scale: 1.0,
        }
    }
}

/// What opens the gate besides a live site, fresh input and a valid scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GateMode {
    /// The enable switch alone.
    EnableOnly,
    /// The enable switch and the clutch pedal (the thesis's gating of the arm and the
    /// hand).
    #[default]
    ClutchAndEnable,
}

/// Why the gate is closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Closed {
    /// None of the operator site's nodes is alive.
    OperatorSiteLost,
    /// No operator input yet, or older than the timeout.
    StaleInput,
    /// The motion scale is not in (0, 1].
    InvalidMotionScale,
    /// The enable switch is released.
    EnableReleased,
    /// The clutch pedal is released (in [`GateMode::ClutchAndEnable`]).
    ClutchReleased,
}

impl Closed {
    /// Closed by the operator's own hand (enable or clutch released), not by a fault: a
    /// controller that starts arms only after seeing this once, so a process started (or
    /// restarted) while the pedals are held does not move the robot until the operator
    /// lets go and presses again.
    pub fn by_operator(self) -> bool {
        matches!(self, Closed::EnableReleased | Closed::ClutchReleased)
    }

    /// Short name for counters and logs.
    pub fn name(self) -> &'static str {
        match self {
            Closed::OperatorSiteLost => "operator_site_lost",
            Closed::StaleInput => "stale_operator_input",
            Closed::InvalidMotionScale => "invalid_motion_scale",
            Closed::EnableReleased => "enable_released",
            Closed::ClutchReleased => "clutch_released",
        }
    }
}

/// The gate; see the [module docs](self).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatorGate {
    /// Operator input older than this closes the gate, s.
    pub input_timeout_s: f64,
    /// What opens the gate.
    pub mode: GateMode,
}

impl OperatorGate {
    /// The gate's verdict at `now_s`: the input that opens it, or why it is closed.
    ///
    /// # Errors
    /// [`Closed`] naming the first condition that fails.
    pub fn check(
        &self,
        now_s: f64,
        input: Option<&OperatorSample>,
        site_alive: bool,
    ) -> Result<OperatorSample, Closed> {
        if !site_alive {
            return Err(Closed::OperatorSiteLost);
        }
        let input = input
            .filter(|i| i.received_s.is_finite() && now_s - i.received_s <= self.input_timeout_s)
            .ok_or(Closed::StaleInput)?;
        if !(input.motion_scale.is_finite()
            && input.motion_scale > 0.0
            && input.motion_scale <= 1.0)
        {
            return Err(Closed::InvalidMotionScale);
        }
        if !input.enable {
            return Err(Closed::EnableReleased);
        }
        if self.mode == GateMode::ClutchAndEnable && !input.clutch {
            return Err(Closed::ClutchReleased);
        }
        Ok(*input)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input(t: f64, clutch: bool, enable: bool, scale: f64) -> OperatorSample {
        OperatorSample {
            received_s: t,
            clutch,
            enable,
            motion_scale: scale,
        }
    }

    #[test]
    fn every_condition_closes_the_gate_in_order() {
        let gate = OperatorGate {
            input_timeout_s: 0.2,
            mode: GateMode::ClutchAndEnable,
        };
        let ok = input(10.0, true, true, 1.0);
        assert_eq!(gate.check(10.1, Some(&ok), true), Ok(ok));
        assert_eq!(
            gate.check(10.1, Some(&ok), false),
            Err(Closed::OperatorSiteLost)
        );
        assert_eq!(gate.check(10.3, Some(&ok), true), Err(Closed::StaleInput));
        assert_eq!(gate.check(10.1, None, true), Err(Closed::StaleInput));
        assert_eq!(
            gate.check(10.1, Some(&input(10.0, true, true, 0.0)), true),
            Err(Closed::InvalidMotionScale)
        );
        assert_eq!(
            gate.check(10.1, Some(&input(10.0, true, true, f64::NAN)), true),
            Err(Closed::InvalidMotionScale)
        );
        assert_eq!(
            gate.check(10.1, Some(&input(10.0, true, false, 1.0)), true),
            Err(Closed::EnableReleased)
        );
        let released = input(10.0, false, true, 1.0);
        assert_eq!(
            gate.check(10.1, Some(&released), true),
            Err(Closed::ClutchReleased)
        );
        let enable_only = OperatorGate {
            mode: GateMode::EnableOnly,
            ..gate
        };
        assert_eq!(enable_only.check(10.1, Some(&released), true), Ok(released));
        assert_eq!(
            enable_only.check(f64::NAN, Some(&released), true),
            Err(Closed::StaleInput)
        );
    }
}
