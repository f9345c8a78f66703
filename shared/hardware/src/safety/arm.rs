//! The arm's safety layer: joint velocity, position and acceleration limits, an
//! end-effector speed cap and a command timeout, on a velocity-commanded arm.

use nalgebra::{SVector, Vector3};
use serde::{Deserialize, Serialize};
use teleop_kinematics::FixedChain;

use super::{Intervention, SafetyConfigError, SafetyCounters, check};
use crate::{ArmCommand, ArmHardware, ArmState, HardwareError};
use teleop_interfaces::StepTimer;

/// Settings of the arm's safety layer (the joint limits come from the URDF).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmSafetyConfig {
    /// With no new command for this long the arm is braked to a stop (at the
    /// acceleration limit), s. Default 0.1 (three periods of the 30 Hz controller).
    pub command_timeout_s: f64,
    /// Largest change of the commanded joint speed, rad/s^2. Default 8 (ours: the PR2
    /// description gives none).
    pub max_acceleration_rad_s2: f64,
    /// Fraction of the URDF joint velocity limits the arm may use, (0, 1]. Default 1.
    pub velocity_fraction: f64,
    /// Motion toward a joint's position limit is slowed so that, braking at
    /// `max_acceleration_rad_s2`, it stops this far inside the limit, rad. Default 0.02.
    pub position_margin_rad: f64,
    /// Largest linear speed of any tool point, m/s. Default 0.25: ISO 10218-1's
    /// reduced speed for collaborative operation; the thesis's Cartesian limit is
    /// 0.2 m/s, which the arm controller enforces on its target, so the cap does not
    /// act in normal operation.
    pub max_tool_speed_m_s: f64,
    /// Points whose speed is capped, in the frame of the chain's tip, m. Default: the
    /// tip origin.
    pub tool_points_m: Vec<[f64; 3]>,
    /// Longest time step the filter assumes, s (a stalled loop must not allow a jump).
    /// Default 0.05.
    pub max_dt_s: f64,
}

impl Default for ArmSafetyConfig {
    fn default() -> Self {
        Self {
            command_timeout_s: 0.1,
            max_acceleration_rad_s2: 8.0,
            velocity_fraction: 1.0,
            position_margin_rad: 0.02,
            max_tool_speed_m_s: 0.25,
            tool_points_m: vec![[0.0; 3]],
            max_dt_s: 0.05,
        }
    }
}

impl ArmSafetyConfig {
    /// # Errors
    /// [`SafetyConfigError::Invalid`] naming the field.
    pub fn validate(&self) -> Result<(), SafetyConfigError> {
        check("command_timeout_s", self.command_timeout_s, 1e-3, 10.0)?;
        check(
            "max_acceleration_rad_s2",
            self.max_acceleration_rad_s2,
            1e-3,
            1e3,
        )?;
        check("velocity_fraction", self.velocity_fraction, 1e-3, 1.0)?;
        check("position_margin_rad", self.position_margin_rad, 0.0, 0.5)?;
        check("max_tool_speed_m_s", self.max_tool_speed_m_s, 1e-3, 10.0)?;
        check("max_dt_s", self.max_dt_s, 1e-4, 1.0)?;
        if self.tool_points_m.is_empty() {
            return Err(SafetyConfigError::Invalid {
                field: "tool_points_m",
                value: 0.0,
                reason: "name at least one point",
            });
        }
        for p in &self.tool_points_m {
            for v in p {
                check("tool_points_m", *v, -2.0, 2.0)?;
            }
        }
        Ok(())
    }
}

/// Joint limits of an arm, from its URDF chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmLimits<const N: usize> {
    pub lower_rad: SVector<f64, N>,
    pub upper_rad: SVector<f64, N>,
    pub velocity_rad_s: SVector<f64, N>,
}

impl<const N: usize> ArmLimits<N> {
    /// The limits of `chain`.
    pub fn of_chain(chain: &FixedChain<N>) -> Self {
        Self {
            lower_rad: chain.lower_limits(),
            upper_rad: chain.upper_limits(),
            velocity_rad_s: chain.velocity_limits(),
        }
    }
}

/// The arm's safety filter, a pure core: [`ArmSafety::step`] takes the time, the new
/// command (if one arrived this period) and the measured state, and returns the
/// command for the hardware.
///
/// Per period, in order:
/// 1. a new command with NaN/inf is refused (counted; the previous one stays);
/// 2. a command older than `command_timeout_s` is replaced by zero velocity;
/// 3. the change from the last output is limited to `max_acceleration_rad_s2 · dt`;
/// 4. joint speeds above `velocity_fraction ·` URDF limit scale the whole vector down
///    (direction kept);
/// 5. each joint moving toward a position limit is slowed to
///    `sqrt(2 a d)`, `d` its distance to the limit minus the margin (zero at or past
///    it), so it can always stop inside;
/// 6. if a tool point moves faster than `max_tool_speed_m_s` (computed with the
///    chain's Jacobian at the measured joints), the vector is scaled down.
///
/// Steps 4-6 only ever scale speeds down, so they keep what the earlier steps
/// ensured; the speed caps win over the acceleration limit when both cannot hold
/// (braking harder than `a` to respect a cap).
#[derive(Debug, Clone)]
pub struct ArmSafety<const N: usize> {
    config: ArmSafetyConfig,
    chain: FixedChain<N>,
    limits: ArmLimits<N>,
    points: Vec<Vector3<f64>>,
    command: Option<(ArmCommand<N>, f64)>,
    timed_out: bool,
    last_output: SVector<f64, N>,
    step_timer: StepTimer,
    counters: SafetyCounters,
}

impl<const N: usize> ArmSafety<N> {
    /// A filter for the arm `chain` (its URDF limits) with `config`.
    ///
    /// # Errors
    /// [`SafetyConfigError::Invalid`] naming a bad setting.
    pub fn new(chain: FixedChain<N>, config: ArmSafetyConfig) -> Result<Self, SafetyConfigError> {
        config.validate()?;
        let mut limits = ArmLimits::of_chain(&chain);
        limits.velocity_rad_s *= config.velocity_fraction;
        let points = config
            .tool_points_m
            .iter()
            .map(|p| Vector3::from(*p))
            .collect();
        Ok(Self {
            config,
            chain,
            limits,
            points,
            command: None,
            timed_out: false,
            last_output: SVector::zeros(),
            step_timer: StepTimer::new(),
            counters: SafetyCounters::default(),
        })
    }

    /// The limits in force (velocity already scaled by `velocity_fraction`).
    pub fn limits(&self) -> &ArmLimits<N> {
        &self.limits
    }

    /// The settings.
    pub fn config(&self) -> &ArmSafetyConfig {
        &self.config
    }

    /// Interventions so far.
    pub fn counters(&self) -> &SafetyCounters {
        &self.counters
    }

    /// The largest linear speed of the tool points at joints `q` moving at `qd`, m/s.
    pub fn tool_speed_m_s(&self, q: &SVector<f64, N>, qd: &SVector<f64, N>) -> f64 {
        let (pose, jac) = self.chain.end_pose_and_jacobian(q);
        let twist = jac * qd;
        let v = Vector3::new(twist[0], twist[1], twist[2]);
        let w = Vector3::new(twist[3], twist[4], twist[5]);
        self.points
            .iter()
            .map(|p| {
                let r = pose.rotation * p;
                (v + w.cross(&r)).norm()
            })
            .fold(0.0, f64::max)
    }

    /// One period at `now_s`: `command` if one arrived, the measured `state` (`None`
    /// when the hardware gave none: the arm is stopped).
    pub fn step(
        &mut self,
        now_s: f64,
        command: Option<&ArmCommand<N>>,
        state: Option<&ArmState<N>>,
    ) -> ArmCommand<N> {
        // The first step, and one whose clock did not advance, count as the longest.
        let dt = self
            .step_timer
            .step(now_s, self.config.max_dt_s, self.config.max_dt_s);
        self.counters.periods += 1;
        if let Some(c) = command {
            self.counters.commands += 1;
            if c.is_finite() {
                self.command = Some((*c, now_s));
                self.timed_out = false;
            } else {
                self.counters.count(Intervention::NonFinite);
            }
        }
        let Some(state) = state.filter(|s| {
            s.position_rad.iter().all(|v| v.is_finite())
                && s.velocity_rad_s.iter().all(|v| v.is_finite())
        }) else {
            self.counters.count(Intervention::NoState);
            self.last_output = SVector::zeros();
            return ArmCommand::stop();
        };
        let wanted = match self.command {
            Some((c, at)) if now_s - at <= self.config.command_timeout_s => c.velocity_rad_s,
            Some(_) => {
                if !self.timed_out {
                    self.timed_out = true;
                    tracing::warn!("arm commands stopped: braking to a stop");
                }
                self.counters.count(Intervention::Timeout);
                SVector::zeros()
            }
            None => SVector::zeros(),
        };
        let mut v = wanted;
        // 3. Acceleration.
        let max_dv = self.config.max_acceleration_rad_s2 * dt;
        let dv = v - self.last_output;
        if dv.amax() > max_dv {
            v = self.last_output + dv.map(|x| x.clamp(-max_dv, max_dv));
            self.counters.count(Intervention::Acceleration);
        }
        // 4. Joint speeds (uniform scaling keeps the direction).
        let mut scale: f64 = 1.0;
        for i in 0..N {
            let lim = self.limits.velocity_rad_s[i];
            if v[i].abs() > lim {
                scale = scale.min(lim / v[i].abs());
            }
        }
        if scale < 1.0 {
            v *= scale;
            self.counters.count(Intervention::Velocity);
        }
        // 5. Position limits: able to stop inside the margin.
        let a = self.config.max_acceleration_rad_s2;
        let mut slowed = false;
        for i in 0..N {
            let q = state.position_rad[i];
            let room = if v[i] > 0.0 {
                self.limits.upper_rad[i] - self.config.position_margin_rad - q
            } else if v[i] < 0.0 {
                q - (self.limits.lower_rad[i] + self.config.position_margin_rad)
            } else {
                continue;
            };
            // Continuous joints have infinite room.
            let allowed = if room.is_finite() {
                (2.0 * a * room.max(0.0)).sqrt()
            } else {
                f64::INFINITY
            };
            if v[i].abs() > allowed {
                v[i] = v[i].signum() * allowed;
                slowed = true;
            }
        }
        if slowed {
            self.counters.count(Intervention::PositionLimit);
        }
        // 6. Tool speed at the measured joints.
        let speed = self.tool_speed_m_s(&state.position_rad, &v);
        if speed > self.config.max_tool_speed_m_s {
            v *= self.config.max_tool_speed_m_s / speed;
            self.counters.count(Intervention::ToolSpeed);
        }
        self.last_output = v;
        ArmCommand { velocity_rad_s: v }
    }
}

/// An arm behind its safety layer: implements [`ArmHardware`] itself, and every
/// command, and every period without one ([`SafeArm::idle`]), reaches the wrapped
/// backend only through [`ArmSafety::step`]. The backend cannot be reached otherwise.
#[derive(Debug)]
pub struct SafeArm<const N: usize, B> {
    backend: B,
    safety: ArmSafety<N>,
}

impl<const N: usize, B: ArmHardware<N>> SafeArm<N, B> {
    /// Wraps `backend`.
    pub fn new(backend: B, safety: ArmSafety<N>) -> Self {
        Self { backend, safety }
    }

    /// The filter (limits, counters).
    pub fn safety(&self) -> &ArmSafety<N> {
        &self.safety
    }

    /// The wrapped backend, read-only (its own counters): commands reach it only
    /// through the filter.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// A period without a new command: the last one stays in force until the timeout,
    /// then the arm brakes.
    ///
    /// # Errors
    /// The backend's.
    pub fn idle(&mut self, now_s: f64) -> Result<(), HardwareError> {
        self.apply(now_s, None)
    }

    fn apply(&mut self, now_s: f64, command: Option<&ArmCommand<N>>) -> Result<(), HardwareError> {
        let state = self.backend.read(now_s).ok();
        let out = self.safety.step(now_s, command, state.as_ref());
        self.backend.write(now_s, &out)
    }
}

impl<const N: usize, B: ArmHardware<N>> ArmHardware<N> for SafeArm<N, B> {
    fn read(&mut self, now_s: f64) -> Result<ArmState<N>, HardwareError> {
        self.backend.read(now_s)
    }

    fn write(&mut self, now_s: f64, command: &ArmCommand<N>) -> Result<(), HardwareError> {
        self.apply(now_s, Some(command))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use teleop_kinematics::robots;

    const DT: f64 = 0.004;

    fn safety(config: ArmSafetyConfig) -> ArmSafety<7> {
        ArmSafety::new(robots::pr2_arm_chain().unwrap(), config).unwrap()
    }

    fn state(q: SVector<f64, 7>) -> ArmState<7> {
        ArmState {
            time_s: 0.0,
            position_rad: q,
            velocity_rad_s: SVector::zeros(),
        }
    }

    fn working() -> SVector<f64, 7> {
        SVector::from_column_slice(&[-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1])
    }

    fn cmd(v: SVector<f64, 7>) -> ArmCommand<7> {
        ArmCommand { velocity_rad_s: v }
    }

    #[test]
    fn a_small_command_passes_unchanged_after_the_ramp() {
        let mut s = safety(ArmSafetyConfig::default());
        let v = SVector::repeat(0.01);
        let mut out = ArmCommand::stop();
        for k in 0..50 {
            out = s.step(f64::from(k) * DT, Some(&cmd(v)), Some(&state(working())));
        }
        assert_eq!(out.velocity_rad_s, v);
    }

    #[test]
    fn speeds_acceleration_and_tool_speed_are_limited_and_counted() {
        let mut s = safety(ArmSafetyConfig::default());
        let q = working();
        let over = cmd(SVector::repeat(5.0));
        let mut last = SVector::<f64, 7>::zeros();
        for k in 0..500 {
            let out = s.step(f64::from(k) * DT, Some(&over), Some(&state(q)));
            let v = out.velocity_rad_s;
            // Acceleration, joint speed and tool speed limits all hold.
            assert!((v - last).amax() <= 8.0 * DT + 1e-9 || s.tool_speed_m_s(&q, &v) <= 0.25);
            for i in 0..7 {
                assert!(v[i].abs() <= s.limits().velocity_rad_s[i] + 1e-12);
            }
            assert!(s.tool_speed_m_s(&q, &v) <= 0.25 + 1e-9);
            last = v;
        }
        let c = s.counters();
        assert!(c.get(Intervention::Acceleration) > 0);
        assert!(c.get(Intervention::ToolSpeed) > 0);
        assert_eq!(c.commands, 500);
    }

    #[test]
    fn a_stale_command_brakes_to_zero_and_nan_is_refused() {
        let mut s = safety(ArmSafetyConfig::default());
        let q = working();
        let v = cmd(SVector::repeat(0.05));
        for k in 0..50 {
            s.step(f64::from(k) * DT, Some(&v), Some(&state(q)));
        }
        // A NaN command is refused: the previous one stays in force.
        let mut nan = v;
        nan.velocity_rad_s[2] = f64::NAN;
        let out = s.step(50.0 * DT, Some(&nan), Some(&state(q)));
        assert_eq!(out.velocity_rad_s, v.velocity_rad_s);
        assert_eq!(s.counters().get(Intervention::NonFinite), 1);
        // No command for longer than the timeout: zero.
        let mut t = 50.0 * DT;
        let mut out = ArmCommand::stop();
        while t < 50.0 * DT + 0.2 {
            t += DT;
            out = s.step(t, None, Some(&state(q)));
        }
        assert_eq!(out.velocity_rad_s, SVector::<f64, 7>::zeros());
        assert!(s.counters().get(Intervention::Timeout) > 0);
        // No state: stop at once.
        let out = s.step(t + DT, Some(&v), None);
        assert_eq!(out.velocity_rad_s, SVector::<f64, 7>::zeros());
        assert_eq!(s.counters().get(Intervention::NoState), 1);
    }

    #[test]
    fn motion_toward_a_position_limit_stops_inside_it() {
        let mut s = safety(ArmSafetyConfig::default());
        // Elbow (joint 3) near its upper limit, commanded toward it.
        let mut q = working();
        let upper = s.limits().upper_rad[3];
        q[3] = upper - 0.021;
        let mut v = SVector::zeros();
        v[3] = 0.5;
        let mut out = ArmCommand::stop();
        for k in 0..200 {
            out = s.step(f64::from(k) * DT, Some(&cmd(v)), Some(&state(q)));
            q += out.velocity_rad_s * DT;
        }
        assert!(
            q[3] <= upper - 0.02 + 1e-3,
            "stopped at {} of {upper}",
            q[3]
        );
        assert!(out.velocity_rad_s[3].abs() < 0.05);
        assert!(s.counters().get(Intervention::PositionLimit) > 0);
        // Away from the limit is free.
        v[3] = -0.05;
        for k in 200..300 {
            out = s.step(f64::from(k) * DT, Some(&cmd(v)), Some(&state(q)));
        }
        assert!((out.velocity_rad_s[3] + 0.05).abs() < 1e-12);
    }

    #[test]
    fn bad_settings_are_named() {
        let e = ArmSafety::new(
            robots::pr2_arm_chain().unwrap(),
            ArmSafetyConfig {
                max_tool_speed_m_s: f64::NAN,
                ..ArmSafetyConfig::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("max_tool_speed_m_s"), "{e}");
    }
}
