//! The thesis's accuracy metrics (Table 5.1): the fraction of frames whose largest
//! joint error is within a threshold, the mean joint error, the mean error per joint,
//! and the fingertip distance between the predicted and the true Shadow poses.

use teleop_hand_model::Finger;
use teleop_hand_model::retarget::{Retargeter, SHADOW_FINGER_DOF};

/// Thresholds (rad) of the fraction-of-frames table.
pub const THRESHOLDS_RAD: [f64; 4] = [0.1, 0.15, 0.2, 0.25];

/// Accumulates predictions against ground truth.
#[derive(Debug, Clone)]
pub struct Accumulator {
    retargeter: Retargeter,
    max_errors: Vec<f64>,
    sum_per_joint: [f64; SHADOW_FINGER_DOF],
    tip_errors_mm: Vec<f64>,
    frames: usize,
    no_hand: usize,
}

/// The summary of an evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Frames evaluated (including those answered "no hand").
    pub frames: usize,
    /// Frames answered "no hand" (counted as failures in the fractions).
    pub no_hand: usize,
    /// Fraction of frames with max joint error <= each of [`THRESHOLDS_RAD`].
    pub fraction_within: [f64; 4],
    /// Mean absolute joint error over all joints and frames with joints (rad).
    pub mean_error_rad: f64,
    /// Mean absolute error per joint (rad).
    pub per_joint_rad: [f64; SHADOW_FINGER_DOF],
    /// Mean and 90th-percentile fingertip distance (mm) between the Shadow at the
    /// predicted and at the true joints.
    pub tip_mean_mm: f64,
    pub tip_p90_mm: f64,
}

impl Accumulator {
    /// An empty accumulator.
    ///
    /// # Errors
    /// Only if the embedded Shadow model were broken.
    pub fn new() -> Result<Self, teleop_hand_model::HandModelError> {
        Ok(Self {
            retargeter: Retargeter::new(Default::default())?,
            max_errors: Vec::new(),
            sum_per_joint: [0.0; SHADOW_FINGER_DOF],
            tip_errors_mm: Vec::new(),
            frames: 0,
            no_hand: 0,
        })
    }

    /// Adds one frame's prediction (`None` = "no hand").
    pub fn add(
        &mut self,
        predicted: Option<&[f64; SHADOW_FINGER_DOF]>,
        truth: &[f64; SHADOW_FINGER_DOF],
    ) {
        self.frames += 1;
        let Some(p) = predicted else {
            self.no_hand += 1;
            self.max_errors.push(f64::INFINITY);
            return;
        };
        let mut worst = 0.0_f64;
        for i in 0..SHADOW_FINGER_DOF {
            let e = (p[i] - truth[i]).abs();
            worst = worst.max(e);
            self.sum_per_joint[i] += e;
        }
        self.max_errors.push(worst);
        let kp = self.retargeter.shadow_keypoints(p);
        let kt = self.retargeter.shadow_keypoints(truth);
        for f in Finger::ALL {
            let tip = f.keypoints()[3];
            self.tip_errors_mm
                .push((kp.0[tip] - kt.0[tip]).norm() * 1000.0);
        }
    }

    /// Fraction of frames whose max joint error is <= `threshold` (rad).
    #[must_use]
    pub fn fraction_within(&self, threshold: f64) -> f64 {
        if self.frames == 0 {
            return 0.0;
        }
        self.max_errors.iter().filter(|e| **e <= threshold).count() as f64 / self.frames as f64
    }

    /// The summary.
    #[must_use]
    pub fn summary(&self) -> Summary {
        let with = (self.frames - self.no_hand).max(1) as f64;
        let per_joint_rad = self.sum_per_joint.map(|s| s / with);
        let mean_error_rad = per_joint_rad.iter().sum::<f64>() / SHADOW_FINGER_DOF as f64;
        let mut tips = self.tip_errors_mm.clone();
        tips.sort_by(f64::total_cmp);
        let tip_mean_mm = tips.iter().sum::<f64>() / tips.len().max(1) as f64;
        let tip_p90_mm = tips.get(tips.len() * 9 / 10).copied().unwrap_or(0.0);
        Summary {
            frames: self.frames,
            no_hand: self.no_hand,
            fraction_within: THRESHOLDS_RAD.map(|t| self.fraction_within(t)),
            mean_error_rad,
            per_joint_rad,
            tip_mean_mm,
            tip_p90_mm,
        }
    }

    /// `(threshold, fraction)` points of the fraction-of-frames curve, thresholds
    /// `0..=max_rad` in `steps` steps.
    #[must_use]
    pub fn curve(&self, max_rad: f64, steps: usize) -> Vec<(f64, f64)> {
        (0..=steps)
            .map(|i| {
                let t = max_rad * i as f64 / steps as f64;
                (t, self.fraction_within(t))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fractions_and_means_follow_the_definitions() {
        let mut a = Accumulator::new().expect("acc");
        let truth = [0.2; SHADOW_FINGER_DOF];
        let mut p = truth;
        a.add(Some(&p), &truth); // exact
        p[3] += 0.12;
        a.add(Some(&p), &truth); // max 0.12
        a.add(None, &truth); // no hand
        let s = a.summary();
        assert_eq!(s.frames, 3);
        assert_eq!(s.no_hand, 1);
        assert!((s.fraction_within[0] - 1.0 / 3.0).abs() < 1e-12);
        assert!((s.fraction_within[1] - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.per_joint_rad[3] - 0.06).abs() < 1e-12);
        assert!((s.mean_error_rad - 0.06 / 17.0).abs() < 1e-12);
        assert!(s.tip_mean_mm > 0.0, "FFJ2 moved, the FF tip moved");
        let c = a.curve(0.2, 4);
        assert_eq!(c.len(), 5);
        assert!(c.windows(2).all(|w| w[1].1 >= w[0].1));
    }
}
