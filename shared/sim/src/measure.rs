//! What the simulated drivers report: the true state with the configured measurement
//! noise, shared by both robot-site worlds.

use nalgebra::SVector;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use teleop_hardware::{ArmState, HandState};

use crate::config::NoiseConfig;

/// The true robot state at one instant.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrueState {
    pub time_s: f64,
    pub arm_q: SVector<f64, 7>,
    pub arm_v: SVector<f64, 7>,
    pub hand_q: SVector<f64, 17>,
    pub hand_v: SVector<f64, 17>,
    /// The motors' applied torques (reported as they are).
    pub hand_effort: SVector<f64, 17>,
    /// The BioTacs' true normal forces, N.
    pub tips: [f64; 5],
}

/// The states the drivers report: Gaussian noise from `rng` on joint positions and
/// velocities (arm, then hand, a position and a velocity per joint) and on the fingertip
/// forces (clamped at 0). The draw order is fixed, so a seed gives the same readings.
pub(crate) fn measured(
    truth: &TrueState,
    noise: &NoiseConfig,
    rng: &mut ChaCha8Rng,
) -> (ArmState<7>, HandState) {
    let mut gauss = |std: f64| -> f64 {
        if std > 0.0 {
            std * rng.sample::<f64, _>(StandardNormal)
        } else {
            0.0
        }
    };
    let (mut arm_q, mut arm_v) = (truth.arm_q, truth.arm_v);
    for i in 0..7 {
        arm_q[i] += gauss(noise.joint_position_std_rad);
        arm_v[i] += gauss(noise.joint_velocity_std_rad_s);
    }
    let (mut hand_q, mut hand_v) = (truth.hand_q, truth.hand_v);
    for i in 0..17 {
        hand_q[i] += gauss(noise.joint_position_std_rad);
        hand_v[i] += gauss(noise.joint_velocity_std_rad_s);
    }
    let mut tips = truth.tips;
    for f in &mut tips {
        *f = (*f + gauss(noise.fingertip_force_std_n)).max(0.0);
    }
    (
        ArmState {
            time_s: truth.time_s,
            position_rad: arm_q,
            velocity_rad_s: arm_v,
        },
        HandState {
            time_s: truth.time_s,
            position_rad: hand_q,
            velocity_rad_s: hand_v,
            effort_nm: truth.hand_effort,
            fingertip_force_n: tips,
        },
    )
}

/// A robot at rest at the origin of every joint, as reported before a first step.
pub(crate) fn at_rest() -> (ArmState<7>, HandState) {
    measured(
        &TrueState {
            time_s: 0.0,
            arm_q: SVector::zeros(),
            arm_v: SVector::zeros(),
            hand_q: SVector::zeros(),
            hand_v: SVector::zeros(),
            hand_effort: SVector::zeros(),
            tips: [0.0; 5],
        },
        &NoiseConfig::none(),
        &mut rand::SeedableRng::seed_from_u64(0),
    )
}
