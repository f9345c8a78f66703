//! The Shadow hand's own joint loop: what its motors do with a [`HandCommand`] at the
//! hand's 1 kHz rate, shared by both simulated worlds.

use nalgebra::SVector;
use teleop_hardware::HandCommand;

/// The motors' settings and the simulated robot's deviation from them.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MotorLaw<'a> {
    pub lower: &'a SVector<f64, 17>,
    pub upper: &'a SVector<f64, 17>,
    /// Torque delivered per N m asked (the simulated motors' error).
    pub gain: &'a SVector<f64, 17>,
    /// Torque limit of every motor, N m.
    pub max_nm: f64,
    /// The position servo's gains (for [`HandCommand::Position`]).
    pub servo_kp_nm_rad: f64,
    pub servo_kd_nm_s_rad: f64,
}

/// The motors' torques, and per joint the stiffness and damping of the loop while it is
/// unsaturated (zero where the motor saturates), for an integrator that takes them
/// implicitly.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MotorOutput {
    pub effort: SVector<f64, 17>,
    pub stiffness: SVector<f64, 17>,
    pub damping: SVector<f64, 17>,
}

/// The torques of `command` at joint positions `q` and velocities `v`: effort commands
/// scaled by the motor gain and clamped; position targets (clamped into the limits)
/// through the PD servo; a joint impedance evaluated with the newest state, its effort
/// limit capped by the motors'. A non-finite entry gives zero torque (effort,
/// impedance) or holds the joint where it is (position).
pub(crate) fn motor_torques(
    command: &HandCommand,
    q: &SVector<f64, 17>,
    v: &SVector<f64, 17>,
    law: &MotorLaw<'_>,
) -> MotorOutput {
    let mut stiffness = SVector::<f64, 17>::zeros();
    let mut damping = SVector::<f64, 17>::zeros();
    let max = law.max_nm;
    let gain = law.gain;
    let effort = match command {
        HandCommand::Effort(tau) => SVector::from_fn(|i, _| {
            let t = tau[i];
            if t.is_finite() {
                (t * gain[i]).clamp(-max, max)
            } else {
                0.0
            }
        }),
        HandCommand::Position(target) => SVector::from_fn(|i, _| {
            let goal = if target[i].is_finite() {
                target[i].clamp(law.lower[i], law.upper[i])
            } else {
                q[i]
            };
            let raw = law.servo_kp_nm_rad * (goal - q[i]) - law.servo_kd_nm_s_rad * v[i];
            if raw.abs() < max {
                stiffness[i] = law.servo_kp_nm_rad;
                damping[i] = law.servo_kd_nm_s_rad;
                raw
            } else {
                raw.signum() * max
            }
        }),
        HandCommand::Impedance(z) => SVector::from_fn(|i, _| {
            let set = z.position_rad[i].clamp(law.lower[i], law.upper[i]);
            let (k, c) = (
                z.stiffness_nm_rad[i].max(0.0),
                z.damping_nm_s_rad[i].max(0.0),
            );
            // The motor's torque constant errs as with effort commands.
            let raw = gain[i]
                * (z.feedforward_nm[i] + k * (set - q[i]) + c * (z.velocity_rad_s[i] - v[i]));
            let limit = z.max_effort_nm[i].abs().min(max);
            if !raw.is_finite() {
                0.0
            } else if raw.abs() < limit {
                stiffness[i] = gain[i] * k;
                damping[i] = gain[i] * c;
                raw
            } else {
                raw.signum() * limit
            }
        }),
    };
    MotorOutput {
        effort,
        stiffness,
        damping,
    }
}
