//! The hand's safety layer: effort limits, no push past a joint limit (faded in over
//! the last stretch before it), no
//! acceleration of a joint already above its speed limit, position targets inside the
//! limits and rate-limited, and a command timeout that holds the posture.

use nalgebra::SVector;
use serde::{Deserialize, Serialize};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;

use super::{Intervention, SafetyConfigError, SafetyCounters, check};
use crate::{FINGER_DOF, HandCommand, HandHardware, HandImpedance, HandState, HardwareError};
use teleop_interfaces::StepTimer;

type Joints = SVector<f64, FINGER_DOF>;

/// Settings of the hand's safety layer (joint limits come from the URDF).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandSafetyConfig {
    /// With no new command for this long the hand holds the posture it has then (its
    /// own position servo), s. Default 0.1 (50 periods of the 500 Hz controller).
    pub command_timeout_s: f64,
    /// Cap on every joint's effort, N m, below the URDF's per-joint limits. Default 2
    /// (the finger joints' URDF limit, and the controller's in every mode).
    pub max_effort_nm: f64,
    /// Fraction of the URDF joint speed limits: above it, effort that would speed a
    /// joint up further is removed. Default 1.5 (contacts make fingers bounce
    /// briefly above the nominal speed; the rule is meant for runaways).
    pub velocity_fraction: f64,
    /// Position targets move toward a new command at most this fraction of the URDF
    /// speed limit. Default 1.
    pub target_speed_fraction: f64,
    /// Longest time step the filter assumes, s. Default 0.05.
    pub max_dt_s: f64,
    /// Cap on a joint impedance's stiffness, N m/rad. Default 20 (the controllers'
    /// stiffest gain: the effort cap at 0.1 rad of error).
    pub max_stiffness_nm_rad: f64,
    /// Cap on a joint impedance's damping, N m s/rad. Default 0.5.
    pub max_damping_nm_s_rad: f64,
    /// Near a joint limit, effort toward it is capped at this stiffness times the
    /// distance left, N m/rad (none at and past the limit). Default 10: the cut fades
    /// in over the last 0.1 rad for 1 N m, 0.2 rad for the 2 N m cap. A cut that
    /// switched at the limit itself made a joint pressed into it chatter between full
    /// and no effort at the layer's rate (MuJoCo's thumb base at +-2 rad/s, its
    /// reaction shaking the wrist at 0.04 rad/s, on 2026-12-05).
    pub limit_stiffness_nm_rad: f64,
}

impl Default for HandSafetyConfig {
    fn default() -> Self {
        Self {
            command_timeout_s: 0.1,
            max_effort_nm: 2.0,
            velocity_fraction: 1.5,
            target_speed_fraction: 1.0,
            max_dt_s: 0.05,
            max_stiffness_nm_rad: 20.0,
            max_damping_nm_s_rad: 0.5,
            limit_stiffness_nm_rad: 10.0,
        }
    }
}

impl HandSafetyConfig {
    /// # Errors
    /// [`SafetyConfigError::Invalid`] naming the field.
    pub fn validate(&self) -> Result<(), SafetyConfigError> {
        check("command_timeout_s", self.command_timeout_s, 1e-3, 10.0)?;
        check("max_effort_nm", self.max_effort_nm, 1e-3, 100.0)?;
        check("velocity_fraction", self.velocity_fraction, 0.1, 10.0)?;
        check(
            "target_speed_fraction",
            self.target_speed_fraction,
            0.01,
            10.0,
        )?;
        check("max_dt_s", self.max_dt_s, 1e-4, 1.0)?;
        check("max_stiffness_nm_rad", self.max_stiffness_nm_rad, 0.0, 1e3)?;
        check("max_damping_nm_s_rad", self.max_damping_nm_s_rad, 0.0, 10.0)?;
        check(
            "limit_stiffness_nm_rad",
            self.limit_stiffness_nm_rad,
            0.1,
            1e4,
        )
    }
}

/// The hand's finger joint limits ([`SHADOW_FINGER_JOINTS`] order).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandLimits {
    pub lower_rad: Joints,
    pub upper_rad: Joints,
    pub velocity_rad_s: Joints,
    pub effort_nm: Joints,
}

impl HandLimits {
    /// The Shadow hand's limits from our URDF.
    ///
    /// # Errors
    /// [`SafetyConfigError::Model`] if the model lacked a finger joint.
    pub fn shadow() -> Result<Self, SafetyConfigError> {
        let model = |e: teleop_kinematics::KinematicsError| SafetyConfigError::Model(e.to_string());
        let robot = teleop_kinematics::robots::shadow_hand().map_err(model)?;
        let limits: Vec<_> = robot.dof_limits().collect();
        let mut out = Self {
            lower_rad: Joints::zeros(),
            upper_rad: Joints::zeros(),
            velocity_rad_s: Joints::zeros(),
            effort_nm: Joints::zeros(),
        };
        for (i, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            let l = limits[robot.dof_index(name).map_err(model)?];
            out.lower_rad[i] = l.lower;
            out.upper_rad[i] = l.upper;
            out.velocity_rad_s[i] = l.velocity;
            out.effort_nm[i] = l.effort;
        }
        Ok(out)
    }
}

/// The hand's safety filter, a pure core; see [`HandSafety::step`].
#[derive(Debug, Clone)]
pub struct HandSafety {
    config: HandSafetyConfig,
    limits: HandLimits,
    effort_cap: Joints,
    command: Option<(HandCommand, f64)>,
    /// Posture held after a timeout.
    hold: Option<Joints>,
    /// Last position target sent (for the rate limit).
    last_target: Option<Joints>,
    step_timer: StepTimer,
    counters: SafetyCounters,
}

impl HandSafety {
    /// A filter with the given limits.
    ///
    /// # Errors
    /// [`SafetyConfigError::Invalid`] naming a bad setting.
    pub fn new(limits: HandLimits, config: HandSafetyConfig) -> Result<Self, SafetyConfigError> {
        config.validate()?;
        let effort_cap = limits.effort_nm.map(|e| e.min(config.max_effort_nm));
        Ok(Self {
            config,
            limits,
            effort_cap,
            command: None,
            hold: None,
            last_target: None,
            step_timer: StepTimer::new(),
            counters: SafetyCounters::default(),
        })
    }

    /// The limits in force.
    pub fn limits(&self) -> &HandLimits {
        &self.limits
    }

    /// Effort limit per joint (URDF limit capped by `max_effort_nm`), N m.
    pub fn effort_cap_nm(&self) -> &Joints {
        &self.effort_cap
    }

    /// Interventions so far.
    pub fn counters(&self) -> &SafetyCounters {
        &self.counters
    }

    /// One period at `now_s`: `command` if one arrived, the measured `state`.
    /// Returns the command for the hardware, or `None` when there is nothing to send
    /// (no command ever and no state: the hardware keeps its own initial hold).
    ///
    /// * **Effort**: clamped to the effort cap; at or past a position limit, effort
    ///   pushing further out is removed; a joint faster than `velocity_fraction ·` its
    ///   limit gets no effort in its direction of motion.
    /// * **Position**: targets clamped into the limits and moved toward the command at
    ///   most `target_speed_fraction ·` the speed limit.
    /// * **Impedance**: the set point as a position target; its velocity within
    ///   `±target_speed_fraction ·` the speed limit; stiffness and damping capped at
    ///   `max_stiffness_nm_rad` / `max_damping_nm_s_rad`; the maximum effort at the
    ///   effort cap (the hardware clamps the law's output to it); the feed-forward
    ///   torque filtered as an effort command.
    /// * **Timeout** (no valid command for `command_timeout_s`) or no state: hold the
    ///   posture measured then (position command).
    pub fn step(
        &mut self,
        now_s: f64,
        command: Option<&HandCommand>,
        state: Option<&HandState>,
    ) -> Option<HandCommand> {
        // The first step, and one whose clock did not advance, count as the longest.
        let dt = self
            .step_timer
            .step(now_s, self.config.max_dt_s, self.config.max_dt_s);
        self.counters.periods += 1;
        if let Some(c) = command {
            self.counters.commands += 1;
            if c.is_finite() {
                self.command = Some((*c, now_s));
                self.hold = None;
            } else {
                self.counters.count(Intervention::NonFinite);
            }
        }
        let state = state.filter(|s| {
            s.position_rad.iter().all(|v| v.is_finite())
                && s.velocity_rad_s.iter().all(|v| v.is_finite())
        });
        let fresh = self
            .command
            .filter(|(_, at)| now_s - at <= self.config.command_timeout_s);
        let (Some((command, _)), Some(state)) = (fresh, state) else {
            // Never commanded: the hardware holds its initial posture on its own.
            self.command?;
            self.counters.count(if state.is_none() {
                Intervention::NoState
            } else {
                Intervention::Timeout
            });
            let hold = self
                .hold
                .or(state.map(|s| s.position_rad))
                .or(self.last_target)?;
            if self.hold.is_none() {
                tracing::warn!("hand commands stopped or state lost: holding the posture");
            }
            self.hold = Some(hold);
            self.last_target = Some(hold);
            return Some(HandCommand::Position(hold));
        };
        Some(match command {
            HandCommand::Effort(tau) => {
                // Efforts alone: the next position target starts from the measurement.
                self.last_target = None;
                HandCommand::Effort(self.filter_effort(&tau, state))
            }
            HandCommand::Position(q) => HandCommand::Position(self.filter_target(&q, state, dt)),
            HandCommand::Impedance(z) => {
                HandCommand::Impedance(self.filter_impedance(&z, state, dt))
            }
        })
    }

    fn filter_impedance(&mut self, z: &HandImpedance, state: &HandState, dt: f64) -> HandImpedance {
        let feedforward_nm = self.filter_effort(&z.feedforward_nm, state);
        let position_rad = self.filter_target(&z.position_rad, state, dt);
        let speed = self.limits.velocity_rad_s * self.config.target_speed_fraction;
        let velocity_rad_s = z.velocity_rad_s.zip_map(&speed, |x, m| x.clamp(-m, m));
        if velocity_rad_s != z.velocity_rad_s {
            self.counters.count(Intervention::Velocity);
        }
        let (k_max, d_max) = (
            self.config.max_stiffness_nm_rad,
            self.config.max_damping_nm_s_rad,
        );
        let stiffness_nm_rad = z.stiffness_nm_rad.map(|k| k.clamp(0.0, k_max));
        let damping_nm_s_rad = z.damping_nm_s_rad.map(|d| d.clamp(0.0, d_max));
        if stiffness_nm_rad != z.stiffness_nm_rad || damping_nm_s_rad != z.damping_nm_s_rad {
            self.counters.count(Intervention::Gain);
        }
        let max_effort_nm = z
            .max_effort_nm
            .zip_map(&self.effort_cap, |x, m| x.abs().min(m));
        if max_effort_nm != z.max_effort_nm {
            self.counters.count(Intervention::Effort);
        }
        HandImpedance {
            position_rad,
            velocity_rad_s,
            stiffness_nm_rad,
            damping_nm_s_rad,
            feedforward_nm,
            max_effort_nm,
        }
    }

    fn filter_effort(&mut self, tau: &Joints, state: &HandState) -> Joints {
        let mut out = *tau;
        let (mut clamped, mut at_limit, mut runaway) = (false, false, false);
        let k = self.config.limit_stiffness_nm_rad;
        for i in 0..FINGER_DOF {
            let cap = self.effort_cap[i];
            if out[i].abs() > cap {
                out[i] = out[i].signum() * cap;
                clamped = true;
            }
            // Toward a limit at most the stiffness times the room left: continuous in
            // the position, so a joint pressed into its limit settles there.
            let q = state.position_rad[i];
            let up = k * (self.limits.upper_rad[i] - q).max(0.0);
            let down = -k * (q - self.limits.lower_rad[i]).max(0.0);
            if out[i] > up || out[i] < down {
                out[i] = out[i].clamp(down, up);
                at_limit = true;
            }
            let qd = state.velocity_rad_s[i];
            if qd.abs() > self.config.velocity_fraction * self.limits.velocity_rad_s[i]
                && out[i] * qd > 0.0
            {
                out[i] = 0.0;
                runaway = true;
            }
        }
        for (hit, what) in [
            (clamped, Intervention::Effort),
            (at_limit, Intervention::PositionLimit),
            (runaway, Intervention::Velocity),
        ] {
            if hit {
                self.counters.count(what);
            }
        }
        out
    }

    fn filter_target(&mut self, q: &Joints, state: &HandState, dt: f64) -> Joints {
        let clamped = q.zip_zip_map(&self.limits.lower_rad, &self.limits.upper_rad, |x, l, u| {
            x.clamp(l, u)
        });
        if clamped != *q {
            self.counters.count(Intervention::PositionLimit);
        }
        let from = self.last_target.unwrap_or(state.position_rad);
        let mut out = clamped;
        let mut limited = false;
        for i in 0..FINGER_DOF {
            let step = self.config.target_speed_fraction * self.limits.velocity_rad_s[i] * dt;
            let d = clamped[i] - from[i];
            if d.abs() > step {
                out[i] = from[i] + d.signum() * step;
                limited = true;
            }
        }
        if limited {
            self.counters.count(Intervention::Velocity);
        }
        self.last_target = Some(out);
        out
    }
}

/// The hand behind its safety layer: implements [`HandHardware`], and every command,
/// and every period without one ([`SafeHand::idle`]), reaches the backend only
/// through [`HandSafety::step`].
#[derive(Debug)]
pub struct SafeHand<B> {
    backend: B,
    safety: HandSafety,
}

impl<B: HandHardware> SafeHand<B> {
    /// Wraps `backend`.
    pub fn new(backend: B, safety: HandSafety) -> Self {
        Self { backend, safety }
    }

    /// The wrapped backend, read-only (its own counters): commands reach it only
    /// through the filter.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// The filter (limits, counters).
    pub fn safety(&self) -> &HandSafety {
        &self.safety
    }

    /// A period without a new command.
    ///
    /// # Errors
    /// The backend's.
    pub fn idle(&mut self, now_s: f64) -> Result<(), HardwareError> {
        self.apply(now_s, None)
    }

    fn apply(&mut self, now_s: f64, command: Option<&HandCommand>) -> Result<(), HardwareError> {
        let state = self.backend.read(now_s).ok();
        match self.safety.step(now_s, command, state.as_ref()) {
            Some(out) => self.backend.write(now_s, &out),
            None => Ok(()),
        }
    }
}

impl<B: HandHardware> HandHardware for SafeHand<B> {
    fn read(&mut self, now_s: f64) -> Result<HandState, HardwareError> {
        self.backend.read(now_s)
    }

    fn write(&mut self, now_s: f64, command: &HandCommand) -> Result<(), HardwareError> {
        self.apply(now_s, Some(command))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.002;

    fn safety() -> HandSafety {
        HandSafety::new(HandLimits::shadow().unwrap(), HandSafetyConfig::default()).unwrap()
    }

    fn state(q: Joints, qd: Joints) -> HandState {
        HandState {
            time_s: 0.0,
            position_rad: q,
            velocity_rad_s: qd,
            effort_nm: Joints::zeros(),
            fingertip_force_n: [0.0; 5],
        }
    }

    fn mid() -> Joints {
        let l = HandLimits::shadow().unwrap();
        (l.lower_rad + l.upper_rad) / 2.0
    }

    #[test]
    fn efforts_are_capped_and_runaways_and_limit_pushes_cut() {
        let mut s = safety();
        let out = s.step(
            0.0,
            Some(&HandCommand::Effort(Joints::repeat(10.0))),
            Some(&state(mid(), Joints::zeros())),
        );
        let Some(HandCommand::Effort(tau)) = out else {
            panic!("{out:?}")
        };
        assert!(tau.iter().all(|t| (*t - 2.0).abs() < 1e-12), "{tau}");
        assert_eq!(s.counters().get(Intervention::Effort), 1);
        // At the upper limit, pushing further out is removed; pulling back is kept.
        let mut q = mid();
        q[1] = s.limits().upper_rad[1];
        let mut cmd = Joints::repeat(0.5);
        cmd[2] = -0.5;
        let out = s.step(
            DT,
            Some(&HandCommand::Effort(cmd)),
            Some(&state(q, Joints::zeros())),
        );
        let Some(HandCommand::Effort(tau)) = out else {
            panic!()
        };
        assert_eq!(tau[1], 0.0);
        assert_eq!(tau[2], -0.5);
        // Just short of the limit the push fades in with the room left (10 N m/rad x
        // 0.03 rad), continuous in the position; short of the lower limit likewise.
        q[1] = s.limits().upper_rad[1] - 0.03;
        q[2] = s.limits().lower_rad[2] + 0.02;
        let out = s.step(
            1.5 * DT,
            Some(&HandCommand::Effort(cmd)),
            Some(&state(q, Joints::zeros())),
        );
        let Some(HandCommand::Effort(tau)) = out else {
            panic!()
        };
        assert!((tau[1] - 0.3).abs() < 1e-9, "{}", tau[1]);
        assert!((tau[2] + 0.2).abs() < 1e-9, "{}", tau[2]);
        assert_eq!(tau[0], 0.5);
        // A joint already above 1.5x its speed limit gets no effort along its motion.
        let mut qd = Joints::zeros();
        qd[4] = 3.5;
        let out = s.step(
            2.0 * DT,
            Some(&HandCommand::Effort(Joints::repeat(0.5))),
            Some(&state(mid(), qd)),
        );
        let Some(HandCommand::Effort(tau)) = out else {
            panic!()
        };
        assert_eq!(tau[4], 0.0);
        assert_eq!(tau[5], 0.5);
        assert!(s.counters().get(Intervention::Velocity) >= 1);
    }

    #[test]
    fn impedances_are_capped_and_their_set_points_limited() {
        let mut s = safety();
        let q = mid();
        let mut feedforward = Joints::repeat(0.1);
        feedforward[3] = 7.0;
        let z = HandImpedance {
            position_rad: Joints::repeat(10.0),
            velocity_rad_s: Joints::repeat(100.0),
            stiffness_nm_rad: Joints::repeat(500.0),
            damping_nm_s_rad: Joints::repeat(0.1),
            feedforward_nm: feedforward,
            max_effort_nm: Joints::repeat(9.0),
        };
        let out = s.step(
            0.0,
            Some(&HandCommand::Impedance(z)),
            Some(&state(q, Joints::zeros())),
        );
        let Some(HandCommand::Impedance(f)) = out else {
            panic!("{out:?}")
        };
        let limits = *s.limits();
        for i in 0..FINGER_DOF {
            assert!(f.position_rad[i] <= limits.upper_rad[i] + 1e-12);
            // Rate-limited from the measured posture.
            assert!(f.position_rad[i] - q[i] <= limits.velocity_rad_s[i] * 0.05 + 1e-9);
            assert!(f.velocity_rad_s[i] <= limits.velocity_rad_s[i] + 1e-12);
            assert_eq!(f.stiffness_nm_rad[i], 20.0);
            assert_eq!(f.damping_nm_s_rad[i], 0.1);
            assert_eq!(f.max_effort_nm[i], s.effort_cap_nm()[i]);
        }
        assert_eq!(f.feedforward_nm[3], 2.0);
        assert_eq!(f.feedforward_nm[0], 0.1);
        for what in [
            Intervention::Gain,
            Intervention::Effort,
            Intervention::Velocity,
            Intervention::PositionLimit,
        ] {
            assert!(s.counters().get(what) >= 1, "{what:?}");
        }
        // Whatever the posture, the hardware's law then stays within the cap.
        let tau = f.effort_at(&(q - Joints::repeat(3.0)), &Joints::repeat(-50.0));
        assert!(tau.amax() <= 2.0 + 1e-12);
        // A NaN anywhere in an impedance is refused: the previous command stays.
        let mut bad = z;
        bad.damping_nm_s_rad[5] = f64::NAN;
        let out = s.step(
            DT,
            Some(&HandCommand::Impedance(bad)),
            Some(&state(q, Joints::zeros())),
        );
        assert!(matches!(out, Some(HandCommand::Impedance(_))));
        assert_eq!(s.counters().get(Intervention::NonFinite), 1);
    }

    #[test]
    fn position_targets_are_clamped_and_rate_limited() {
        let mut s = safety();
        let q = mid();
        let far = Joints::repeat(10.0);
        let out = s.step(
            0.0,
            Some(&HandCommand::Position(far)),
            Some(&state(q, Joints::zeros())),
        );
        let Some(HandCommand::Position(t)) = out else {
            panic!()
        };
        // One step of at most 2 rad/s x 0.05 s (the first step assumes max_dt).
        assert!((t - q).amax() <= 4.0 * 0.05 + 1e-12);
        for k in 1..2000 {
            s.step(
                f64::from(k) * DT,
                Some(&HandCommand::Position(far)),
                Some(&state(q, Joints::zeros())),
            );
        }
        let out = s.step(
            4.0,
            Some(&HandCommand::Position(far)),
            Some(&state(q, Joints::zeros())),
        );
        let Some(HandCommand::Position(t)) = out else {
            panic!()
        };
        assert_eq!(t, s.limits().upper_rad);
    }

    #[test]
    fn stale_commands_hold_the_posture_and_nothing_is_sent_before_any() {
        let mut s = safety();
        let q = mid();
        assert_eq!(s.step(0.0, None, Some(&state(q, Joints::zeros()))), None);
        s.step(
            0.0,
            Some(&HandCommand::Effort(Joints::repeat(0.3))),
            Some(&state(q, Joints::zeros())),
        );
        let mut moved = q;
        moved[0] += 0.05;
        let out = s.step(0.2, None, Some(&state(moved, Joints::zeros())));
        assert_eq!(out, Some(HandCommand::Position(moved)));
        // The hold stays where it began.
        let out = s.step(0.3, None, Some(&state(q, Joints::zeros())));
        assert_eq!(out, Some(HandCommand::Position(moved)));
        assert_eq!(s.counters().get(Intervention::Timeout), 2);
        // A NaN command is refused and counted.
        let mut nan = Joints::repeat(0.1);
        nan[3] = f64::NAN;
        s.step(
            0.31,
            Some(&HandCommand::Effort(nan)),
            Some(&state(q, Joints::zeros())),
        );
        assert_eq!(s.counters().get(Intervention::NonFinite), 1);
    }
}
