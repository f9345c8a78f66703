//! Simulated optical motion capture (PhaseSpace Impulse X2E-like, thesis ch. 7.2): the
//! 6D pose of the LED marker on the back of the operator's hand, in the capture
//! system's own frame, at 320 Hz, with small noise, occasional dropouts (the markers
//! occluded) and rare glitches (a sample jumped far away, what the jump filter of ch.
//! 7.4 exists for).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Exp, StandardNormal};
use serde::{Deserialize, Serialize};
use teleop_control::TransformConfig;

use super::{default_base_from_mocap, default_hand_from_marker};

/// Settings of the simulated motion capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MocapConfig {
    /// Sample rate, Hz (PhaseSpace: 320; up to 960).
    pub rate_hz: f64,
    /// Standard deviation of the position noise per axis, m.
    pub position_noise_m: f64,
    /// Standard deviation of the rotation noise per axis, deg.
    pub rotation_noise_deg: f64,
    /// Mean number of dropouts (occlusions) per second.
    pub dropouts_per_s: f64,
    /// Mean length of a dropout, s (exponentially distributed).
    pub dropout_mean_s: f64,
    /// Mean number of glitches per second: a sample whose position jumps by
    /// `glitch_jump_m` along a random axis.
    pub glitches_per_s: f64,
    /// Size of a glitch, m (beyond the jump filter's 0.5 m).
    pub glitch_jump_m: f64,
    /// Where the capture system's frame is in the UR5 base frame (the true
    /// installation; the wrist tracker's registration is its calibration of it).
    pub base_from_mocap: TransformConfig,
    /// The marker's true pose in the hand frame.
    pub hand_from_marker: TransformConfig,
}

impl Default for MocapConfig {
    fn default() -> Self {
        Self {
            rate_hz: 320.0,
            position_noise_m: 0.0003,
            rotation_noise_deg: 0.1,
            dropouts_per_s: 0.2,
            dropout_mean_s: 0.05,
            glitches_per_s: 0.05,
            glitch_jump_m: 0.6,
            base_from_mocap: default_base_from_mocap(),
            hand_from_marker: default_hand_from_marker(),
        }
    }
}

impl MocapConfig {
    /// # Errors
    /// A text naming the first invalid field.
    pub fn validate(&self) -> Result<(), String> {
        teleop_control::check_ranges(
            "mocap",
            &[
                ("rate_hz", self.rate_hz, 1.0, 2000.0),
                ("position_noise_m", self.position_noise_m, 0.0, 0.05),
                ("rotation_noise_deg", self.rotation_noise_deg, 0.0, 10.0),
                ("dropouts_per_s", self.dropouts_per_s, 0.0, 100.0),
                ("dropout_mean_s", self.dropout_mean_s, 1e-4, 10.0),
                ("glitches_per_s", self.glitches_per_s, 0.0, 100.0),
                ("glitch_jump_m", self.glitch_jump_m, 0.0, 10.0),
            ],
        )?;
        self.base_from_mocap.validate("mocap.base_from_mocap")?;
        self.hand_from_marker.validate("mocap.hand_from_marker")
    }
}

/// One measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MocapReading {
    /// The marker's pose in the capture frame; `glitch` marks a corrupted sample
    /// (ground truth for tests: a real system does not know).
    Marker { pose: Isometry3<f64>, glitch: bool },
    /// The marker is occluded: no sample.
    Dropout,
}

/// Counters of the simulated capture.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MocapCounts {
    pub samples: u64,
    pub dropouts: u64,
    pub glitches: u64,
}

/// The simulated motion capture.
#[derive(Debug, Clone)]
pub struct Mocap {
    cfg: MocapConfig,
    mocap_from_base: Isometry3<f64>,
    hand_from_marker: Isometry3<f64>,
    rng: ChaCha8Rng,
    dropout_until_s: f64,
    counts: MocapCounts,
}

impl Mocap {
    /// A capture system with noise drawn from `seed`.
    #[must_use]
    pub fn new(cfg: MocapConfig, seed: u64) -> Self {
        Self {
            mocap_from_base: cfg.base_from_mocap.isometry().inverse(),
            hand_from_marker: cfg.hand_from_marker.isometry(),
            cfg,
            rng: ChaCha8Rng::seed_from_u64(seed),
            dropout_until_s: f64::NEG_INFINITY,
            counts: MocapCounts::default(),
        }
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &MocapConfig {
        &self.cfg
    }

    /// Counters so far.
    #[must_use]
    pub fn counts(&self) -> MocapCounts {
        self.counts
    }

    /// The marker's true pose in the capture frame for the hand frame `base_from_hand`
    /// (UR5 base frame).
    #[must_use]
    pub fn true_marker(&self, base_from_hand: &Isometry3<f64>) -> Isometry3<f64> {
        self.mocap_from_base * base_from_hand * self.hand_from_marker
    }

    /// One sample at `t_s`, one sample period after the previous call.
    pub fn measure(&mut self, t_s: f64, base_from_hand: &Isometry3<f64>) -> MocapReading {
        let dt = 1.0 / self.cfg.rate_hz;
        if t_s < self.dropout_until_s {
            self.counts.dropouts += 1;
            return MocapReading::Dropout;
        }
        if self.cfg.dropouts_per_s > 0.0 && self.rng.random::<f64>() < self.cfg.dropouts_per_s * dt
        {
            let length = Exp::new(1.0 / self.cfg.dropout_mean_s)
                .map_or(self.cfg.dropout_mean_s, |e| e.sample(&mut self.rng));
            self.dropout_until_s = t_s + length;
            self.counts.dropouts += 1;
            return MocapReading::Dropout;
        }
        let mut pose = self.true_marker(base_from_hand);
        let n = |rng: &mut ChaCha8Rng, sd: f64| sd * rng.sample::<f64, _>(StandardNormal);
        let sd_p = self.cfg.position_noise_m;
        let sd_r = self.cfg.rotation_noise_deg.to_radians();
        let dp = Vector3::new(
            n(&mut self.rng, sd_p),
            n(&mut self.rng, sd_p),
            n(&mut self.rng, sd_p),
        );
        let dr = Vector3::new(
            n(&mut self.rng, sd_r),
            n(&mut self.rng, sd_r),
            n(&mut self.rng, sd_r),
        );
        pose = Isometry3::from_parts(
            Translation3::from(pose.translation.vector + dp),
            UnitQuaternion::from_scaled_axis(dr) * pose.rotation,
        );
        let glitch = self.cfg.glitches_per_s > 0.0
            && self.rng.random::<f64>() < self.cfg.glitches_per_s * dt;
        if glitch {
            let axis = self.rng.random_range(0..3);
            let sign = if self.rng.random::<bool>() { 1.0 } else { -1.0 };
            pose.translation.vector[axis] += sign * self.cfg.glitch_jump_m;
            self.counts.glitches += 1;
        }
        self.counts.samples += 1;
        MocapReading::Marker { pose, glitch }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registration_chain_recovers_the_hand() {
        let m = Mocap::new(MocapConfig::default(), 1);
        let hand = Isometry3::from_parts(
            Translation3::new(0.4, -0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
        );
        let marker = m.true_marker(&hand);
        let cfg = MocapConfig::default();
        let back =
            cfg.base_from_mocap.isometry() * marker * cfg.hand_from_marker.isometry().inverse();
        assert!((back.translation.vector - hand.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&hand.rotation) < 1e-12);
    }

    #[test]
    fn noise_dropouts_and_glitches_are_seeded_and_at_their_rates() {
        let cfg = MocapConfig {
            dropouts_per_s: 1.0,
            glitches_per_s: 1.0,
            ..MocapConfig::default()
        };
        let hand = Isometry3::translation(0.5, 0.0, 0.3);
        let run = |seed| {
            let mut m = Mocap::new(cfg.clone(), seed);
            let mut out = Vec::new();
            for k in 0..(320 * 60) {
                out.push(m.measure(f64::from(k) / 320.0, &hand));
            }
            (out, m.counts())
        };
        let (a, counts) = run(3);
        let (b, _) = run(3);
        assert_eq!(a, b);
        // 60 s at 1 glitch/s and 1 dropout/s of 50 ms mean.
        assert!((30..=100).contains(&counts.glitches), "{counts:?}");
        let dropout_fraction = counts.dropouts as f64 / a.len() as f64;
        assert!((0.02..0.10).contains(&dropout_fraction), "{counts:?}");
        let truth = Mocap::new(cfg.clone(), 0).true_marker(&hand);
        for r in &a {
            if let MocapReading::Marker { pose, glitch } = r {
                let err = (pose.translation.vector - truth.translation.vector).norm();
                if *glitch {
                    assert!(err > 0.55, "{err}");
                } else {
                    assert!(err < 0.003, "{err}");
                    assert!(pose.rotation.angle_to(&truth.rotation) < 0.02);
                }
            }
        }
    }
}
