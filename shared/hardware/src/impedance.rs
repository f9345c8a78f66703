//! The joint impedance a hand's own loop evaluates: the command type of
//! [`crate::HandCommand::Impedance`], part of the hardware's contract (the control laws
//! of `teleop-control` produce it; a driver or a simulator applies it).

use nalgebra::SVector;

/// A joint impedance for the hardware's own loop: there, every period, with its newest
/// measurement, `τ = feedforward + stiffness (position - q) + damping (velocity - q̇)`,
/// clamped to `±max_effort`. Gravity is in the feed-forward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointImpedance<const N: usize> {
    /// Set point (the target), rad.
    pub position_rad: SVector<f64, N>,
    /// Set point velocity (the target's), rad/s.
    pub velocity_rad_s: SVector<f64, N>,
    /// N m/rad.
    pub stiffness_nm_rad: SVector<f64, N>,
    /// N m s/rad.
    pub damping_nm_s_rad: SVector<f64, N>,
    /// N m.
    pub feedforward_nm: SVector<f64, N>,
    /// N m.
    pub max_effort_nm: SVector<f64, N>,
}

impl<const N: usize> JointImpedance<N> {
    /// The clamped effort at `q`, `q̇`, N m (what the hardware applies); a joint whose
    /// law or limit is not finite gets 0.
    pub fn effort_at(
        &self,
        position_rad: &SVector<f64, N>,
        velocity_rad_s: &SVector<f64, N>,
    ) -> SVector<f64, N> {
        SVector::from_fn(|i, _| {
            let tau = self.feedforward_nm[i]
                + self.stiffness_nm_rad[i] * (self.position_rad[i] - position_rad[i])
                + self.damping_nm_s_rad[i] * (self.velocity_rad_s[i] - velocity_rad_s[i]);
            let max = self.max_effort_nm[i].abs();
            if tau.is_finite() && max.is_finite() {
                tau.clamp(-max, max)
            } else {
                0.0
            }
        })
    }

    /// True when every value of every field is finite.
    pub fn is_finite(&self) -> bool {
        [
            &self.position_rad,
            &self.velocity_rad_s,
            &self.stiffness_nm_rad,
            &self.damping_nm_s_rad,
            &self.feedforward_nm,
            &self.max_effort_nm,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()))
    }
}
