//! Hardware traits of the operator site and their simulated backends.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// A 6D wrist tracker (motion capture, IMU suit, ...), polled by the node.
pub trait WristTracker: Send {
    /// The wrist pose at time `t_s` (seconds since the node started), in the tracker's
    /// frame; `None` when the tracker has no valid measurement (markers occluded).
    fn read(&mut self, t_s: f64) -> Option<Isometry3<f64>>;
}

/// Pedals and switches of the operator.
pub trait OperatorDevice: Send {
    fn read(&mut self, t_s: f64) -> PedalState;
}

/// The state of the operator's pedals and switches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PedalState {
    pub clutch: bool,
    pub enable: bool,
    pub camera_stop: bool,
    pub motion_scale: f64,
}

/// Settings of the simulated operator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimulatedOperatorConfig {
    /// Seed of the measurement noise.
    pub seed: u64,
    /// Centre of the square the wrist traces, metres, tracker frame.
    pub center_m: [f64; 3],
    /// Side of the square, metres.
    pub side_m: f64,
    /// Speed along the square, m/s (the corners are sharp: the velocity turns at once).
    pub speed_m_s: f64,
    /// Amplitude of the wrist's slow rotation about each axis, degrees.
    pub wobble_deg: f64,
    /// Standard deviation of the tracker's position noise, metres.
    pub noise_m: f64,
    /// The clutch pedal is pressed for `clutch_on_s` out of every `clutch_cycle_s`,
    /// starting after `clutch_delay_s`.
    pub clutch_delay_s: f64,
    pub clutch_on_s: f64,
    pub clutch_cycle_s: f64,
    /// Whether the enable (deadman) switch is held.
    pub enable: bool,
    /// Motion scale sent with the pedal state.
    pub motion_scale: f64,
}

impl Default for SimulatedOperatorConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            center_m: [0.5, 0.0, 0.3],
            side_m: 0.2,
            speed_m_s: 0.05,
            wobble_deg: 15.0,
            noise_m: 0.0002,
            clutch_delay_s: 1.0,
            clutch_on_s: 16.0,
            clutch_cycle_s: 20.0,
            enable: true,
            motion_scale: 1.0,
        }
    }
}

impl SimulatedOperatorConfig {
    /// # Errors
    /// A text naming the bad field.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("side_m", self.side_m),
            ("speed_m_s", self.speed_m_s),
            ("clutch_cycle_s", self.clutch_cycle_s),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "operator.{name} must be a positive number, got {v}"
                ));
            }
        }
        if !(self.noise_m.is_finite() && self.noise_m >= 0.0) {
            return Err(format!(
                "operator.noise_m must be >= 0, got {}",
                self.noise_m
            ));
        }
        if !(self.motion_scale > 0.0 && self.motion_scale <= 1.0) {
            return Err(format!(
                "operator.motion_scale must be in (0, 1], got {}",
                self.motion_scale
            ));
        }
        if self.center_m.iter().any(|v| !v.is_finite()) || !self.wobble_deg.is_finite() {
            return Err("operator.center_m and wobble_deg must be finite".into());
        }
        Ok(())
    }
}

/// A simulated operator: the wrist traces a square with sharp corners (like the
/// thesis's Fig. 7.12) while slowly rotating; the tracker adds Gaussian noise. The true
/// pose is available from [`SimulatedOperator::true_pose`].
#[derive(Debug)]
pub struct SimulatedOperator {
    cfg: SimulatedOperatorConfig,
    rng: StdRng,
    noise: Option<Normal<f64>>,
}

impl SimulatedOperator {
    pub fn new(cfg: SimulatedOperatorConfig) -> Self {
        let noise = (cfg.noise_m > 0.0)
            .then(|| Normal::new(0.0, cfg.noise_m).ok())
            .flatten();
        Self {
            rng: StdRng::seed_from_u64(cfg.seed),
            cfg,
            noise,
        }
    }

    /// Ground truth wrist pose at `t_s`.
    pub fn true_pose(&self, t_s: f64) -> Isometry3<f64> {
        let c = &self.cfg;
        let half = c.side_m / 2.0;
        let corners = [
            Vector3::new(-half, -half, 0.0),
            Vector3::new(half, -half, 0.0),
            Vector3::new(half, half, 0.0),
            Vector3::new(-half, half, 0.0),
        ];
        let perimeter = 4.0 * c.side_m;
        let s = (t_s * c.speed_m_s).rem_euclid(perimeter);
        let edge = ((s / c.side_m).floor() as usize).min(3);
        let frac = (s - edge as f64 * c.side_m) / c.side_m;
        let a = corners[edge];
        let b = corners[(edge + 1) % 4];
        let p = Vector3::from(c.center_m) + a + (b - a) * frac;
        let w = c.wobble_deg.to_radians();
        let rot = UnitQuaternion::from_euler_angles(
            w * (0.3 * t_s).sin(),
            w * (0.2 * t_s).sin(),
            w * (0.25 * t_s).cos(),
        );
        Isometry3::from_parts(Translation3::from(p), rot)
    }
}

impl WristTracker for SimulatedOperator {
    fn read(&mut self, t_s: f64) -> Option<Isometry3<f64>> {
        let mut pose = self.true_pose(t_s);
        if let Some(n) = &self.noise {
            let d = Vector3::new(
                n.sample(&mut self.rng),
                n.sample(&mut self.rng),
                n.sample(&mut self.rng),
            );
            pose.translation.vector += d;
        }
        Some(pose)
    }
}

impl OperatorDevice for SimulatedOperator {
    fn read(&mut self, t_s: f64) -> PedalState {
        let c = &self.cfg;
        let phase = (t_s - c.clutch_delay_s).rem_euclid(c.clutch_cycle_s);
        PedalState {
            clutch: t_s >= c.clutch_delay_s && phase < c.clutch_on_s,
            enable: c.enable,
            camera_stop: false,
            motion_scale: c.motion_scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_has_sharp_corners_and_is_closed() {
        let op = SimulatedOperator::new(SimulatedOperatorConfig::default());
        let c = SimulatedOperatorConfig::default();
        let period = 4.0 * c.side_m / c.speed_m_s;
        let p0 = op.true_pose(0.0).translation.vector;
        let p1 = op.true_pose(period).translation.vector;
        assert!((p0 - p1).norm() < 1e-9);
        // Velocity turns by 90 degrees at a corner.
        let t_corner = c.side_m / c.speed_m_s;
        let v_before = op.true_pose(t_corner - 0.01).translation.vector
            - op.true_pose(t_corner - 0.02).translation.vector;
        let v_after = op.true_pose(t_corner + 0.02).translation.vector
            - op.true_pose(t_corner + 0.01).translation.vector;
        assert!(v_before.normalize().dot(&v_after.normalize()).abs() < 1e-6);
    }

    #[test]
    fn noise_is_seeded_and_bounded() {
        let cfg = SimulatedOperatorConfig::default();
        let mut a = SimulatedOperator::new(cfg.clone());
        let mut b = SimulatedOperator::new(cfg);
        for i in 0..100 {
            let t = f64::from(i) * 0.01;
            let pa = WristTracker::read(&mut a, t).expect("pose");
            let pb = WristTracker::read(&mut b, t).expect("pose");
            assert_eq!(pa, pb);
            let err = (pa.translation.vector - a.true_pose(t).translation.vector).norm();
            assert!(err < 0.002, "noise too large: {err}");
        }
    }

    #[test]
    fn clutch_schedule() {
        let mut op = SimulatedOperator::new(SimulatedOperatorConfig::default());
        assert!(!OperatorDevice::read(&mut op, 0.5).clutch);
        assert!(OperatorDevice::read(&mut op, 2.0).clutch);
        assert!(!OperatorDevice::read(&mut op, 18.0).clutch);
        assert!(OperatorDevice::read(&mut op, 22.0).clutch);
    }

    #[test]
    fn validation_names_the_field() {
        let cfg = SimulatedOperatorConfig {
            motion_scale: 0.0,
            ..Default::default()
        };
        assert!(cfg.validate().unwrap_err().contains("motion_scale"));
        let cfg = SimulatedOperatorConfig {
            speed_m_s: f64::NAN,
            ..Default::default()
        };
        assert!(cfg.validate().unwrap_err().contains("speed_m_s"));
    }
}
