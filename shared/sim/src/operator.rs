//! The simulated operator (the operator site's world; the camera arm and the depth
//! camera join it with the local-site issue): a scripted wrist motion that knows its
//! ground truth, a noisy tracker of it and the pedals, behind the operator-site
//! hardware traits ([`WristTracker`], [`OperatorPanel`]).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use teleop_hardware::{HardwareError, OperatorPanel, PedalState, WristTracker};

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
    rng: ChaCha8Rng,
    noise: Option<Normal<f64>>,
}

impl SimulatedOperator {
    pub fn new(cfg: SimulatedOperatorConfig) -> Self {
        let noise = (cfg.noise_m > 0.0)
            .then(|| Normal::new(0.0, cfg.noise_m).ok())
            .flatten();
        Self {
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
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

impl SimulatedOperator {
    /// The tracker's reading at `t_s` (time since the operator started): the true pose
    /// plus Gaussian position noise.
    pub fn tracked_pose(&mut self, t_s: f64) -> Isometry3<f64> {
        let mut pose = self.true_pose(t_s);
        if let Some(n) = &self.noise {
            let d = Vector3::new(
                n.sample(&mut self.rng),
                n.sample(&mut self.rng),
                n.sample(&mut self.rng),
            );
            pose.translation.vector += d;
        }
        pose
    }

    /// The pedals at `t_s` (time since the operator started).
    pub fn pedals(&self, t_s: f64) -> PedalState {
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

/// The simulated operator as the operator site's hardware: a wrist tracker and a pedal
/// box reading one operator, on a clock that starts at the first read.
#[derive(Debug)]
pub struct SimulatedDevices {
    operator: SimulatedOperator,
    start_s: Option<f64>,
}

impl SimulatedDevices {
    /// The devices of `operator`.
    pub fn new(operator: SimulatedOperator) -> Self {
        Self {
            operator,
            start_s: None,
        }
    }

    /// Time since the first read, s.
    fn elapsed(&mut self, now_s: f64) -> f64 {
        now_s - *self.start_s.get_or_insert(now_s)
    }

    /// The operator (ground truth).
    pub fn operator(&self) -> &SimulatedOperator {
        &self.operator
    }
}

impl WristTracker for SimulatedDevices {
    fn read(&mut self, now_s: f64) -> Result<Option<Isometry3<f64>>, HardwareError> {
        let t = self.elapsed(now_s);
        Ok(Some(self.operator.tracked_pose(t)))
    }
}

impl OperatorPanel for SimulatedDevices {
    fn read(&mut self, now_s: f64) -> Result<PedalState, HardwareError> {
        let t = self.elapsed(now_s);
        Ok(self.operator.pedals(t))
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
            let pa = a.tracked_pose(t);
            let pb = b.tracked_pose(t);
            assert_eq!(pa, pb);
            let err = (pa.translation.vector - a.true_pose(t).translation.vector).norm();
            assert!(err < 0.002, "noise too large: {err}");
        }
    }

    #[test]
    fn clutch_schedule() {
        let op = SimulatedOperator::new(SimulatedOperatorConfig::default());
        assert!(!op.pedals(0.5).clutch);
        assert!(op.pedals(2.0).clutch);
        assert!(!op.pedals(18.0).clutch);
        assert!(op.pedals(22.0).clutch);
        // Through the hardware traits, time starts at the first read.
        let mut dev = SimulatedDevices::new(op);
        assert!(!OperatorPanel::read(&mut dev, 1000.0).unwrap().clutch);
        assert!(OperatorPanel::read(&mut dev, 1002.0).unwrap().clutch);
        assert!(WristTracker::read(&mut dev, 1002.0).unwrap().is_some());
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
