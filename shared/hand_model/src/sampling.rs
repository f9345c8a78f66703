//! Hand poses that cover what operators do: uniformly random poses within the joint
//! ranges (with the natural DIP-PIP coupling), the grasp synergies (power, precision,
//! pinch, open, pointing) at random closure with per-joint variation, and blends of
//! two synergies.

use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::human::{HUMAN_DOF, HUMAN_JOINT_LIMITS, HumanPose};

/// A grasp synergy: a whole-hand posture people use, from which samples vary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Synergy {
    /// Flat, fingers slightly spread.
    Open,
    /// Cylindrical power grasp: all fingers wrapped, thumb over them.
    Power,
    /// Precision grasp: fingertips and thumb tip around a small object.
    Precision,
    /// Thumb tip against the index fingertip, other fingers relaxed.
    Pinch,
    /// Index extended, other fingers curled, thumb over the middle finger.
    Pointing,
}

impl Synergy {
    /// All five.
    pub const ALL: [Synergy; 5] = [
        Synergy::Open,
        Synergy::Power,
        Synergy::Precision,
        Synergy::Pinch,
        Synergy::Pointing,
    ];

    /// The name used in manifests and reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Synergy::Open => "open",
            Synergy::Power => "power",
            Synergy::Precision => "precision",
            Synergy::Pinch => "pinch",
            Synergy::Pointing => "pointing",
        }
    }

    /// The synergy's full posture (rad, [`crate::human::HUMAN_JOINT_NAMES`] order).
    #[must_use]
    pub fn posture(self) -> HumanPose {
        // Finger rows: abd, mcp flex, pip, dip; little: cmc first; thumb: cmc abd,
        // cmc flex, mcp flex, mcp abd, ip.
        let q: [f64; HUMAN_DOF] = match self {
            Synergy::Open => [
                0.15, 0.0, 0.05, 0.02, //
                0.02, 0.0, 0.05, 0.02, //
                -0.1, 0.0, 0.05, 0.02, //
                0.0, -0.2, 0.0, 0.05, 0.02, //
                0.0, -0.1, 0.05, 0.0, 0.05,
            ],
            Synergy::Power => [
                0.0, 1.2, 1.45, 0.95, //
                0.0, 1.25, 1.5, 1.0, //
                0.0, 1.3, 1.5, 1.0, //
                0.25, 0.0, 1.35, 1.45, 0.95, //
                0.64, 0.16, 0.64, 0.0, 0.84,
            ],
            Synergy::Precision => [
                0.05, 0.75, 0.65, 0.35, //
                0.0, 0.8, 0.7, 0.4, //
                -0.05, 0.85, 0.75, 0.45, //
                0.15, -0.08, 0.9, 0.8, 0.5, //
                0.74, 0.67, 0.0, 0.0, 0.29,
            ],
            Synergy::Pinch => [
                0.05, 0.8, 0.75, 0.25, //
                0.0, 0.45, 0.55, 0.3, //
                0.0, 0.5, 0.6, 0.35, //
                0.1, 0.0, 0.55, 0.65, 0.4, //
                0.64, 0.16, 0.64, 0.0, -0.2,
            ],
            Synergy::Pointing => [
                0.05, 0.0, 0.05, 0.02, //
                0.0, 1.35, 1.55, 1.0, //
                0.0, 1.4, 1.55, 1.0, //
                0.25, 0.0, 1.4, 1.5, 1.0, //
                0.74, 0.16, 0.64, 0.0, 0.84,
            ],
        };
        HumanPose { q }.clamped()
    }
}

/// How a pose was drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseKind {
    /// Uniform within the ranges (DIP coupled to PIP).
    Random,
    /// One synergy at `closure` between the open hand (0) and the full synergy (1).
    Synergy { synergy: Synergy, closure: f64 },
    /// Blend `(1 - t) a + t b` of two full synergies.
    Blend { a: Synergy, b: Synergy, t: f64 },
}

/// Proportions of the three kinds and the per-joint variation around synergies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSampler {
    /// Probability of a uniformly random pose.
    pub random: f64,
    /// Probability of a single synergy (the rest are blends).
    pub synergy: f64,
    /// Standard deviation (rad) of the per-joint noise added to synergy poses.
    pub joint_sd: f64,
}

impl Default for PoseSampler {
    /// 25 % random, 50 % synergies, 25 % blends, 0.12 rad per-joint variation.
    fn default() -> Self {
        Self {
            random: 0.25,
            synergy: 0.5,
            joint_sd: 0.12,
        }
    }
}

impl PoseSampler {
    /// One pose and how it was drawn. Always within the joint limits.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> (HumanPose, PoseKind) {
        let u: f64 = rng.random();
        if u < self.random {
            return (random_pose(rng), PoseKind::Random);
        }
        let pick = |rng: &mut R| Synergy::ALL[rng.random_range(0..Synergy::ALL.len())];
        let (pose, kind) = if u < self.random + self.synergy {
            let synergy = pick(rng);
            // Closure favours both ends a little less than the middle of the motion.
            let closure: f64 = rng.random::<f64>().powf(0.7);
            let pose = Synergy::Open.posture().lerp(&synergy.posture(), closure);
            (pose, PoseKind::Synergy { synergy, closure })
        } else {
            let a = pick(rng);
            let b = pick(rng);
            let t: f64 = rng.random();
            let pose = a.posture().lerp(&b.posture(), t);
            (pose, PoseKind::Blend { a, b, t })
        };
        (jitter(pose, self.joint_sd, rng), kind)
    }
}

/// A uniformly random pose within the ranges; each DIP follows 2/3 of its PIP with
/// 0.2 rad of spread, as human DIPs do.
pub fn random_pose<R: Rng + ?Sized>(rng: &mut R) -> HumanPose {
    let mut q = [0.0; HUMAN_DOF];
    for (v, (lo, hi)) in q.iter_mut().zip(HUMAN_JOINT_LIMITS) {
        *v = rng.random_range(lo..=hi);
    }
    let coupling = Normal::new(0.0, 0.2).ok();
    for (pip, dip) in [(2, 3), (6, 7), (10, 11), (15, 16)] {
        let noise = coupling.map_or(0.0, |n| n.sample(rng));
        q[dip] = q[pip] * 2.0 / 3.0 + noise;
    }
    HumanPose { q }.clamped()
}

fn jitter<R: Rng + ?Sized>(pose: HumanPose, sd: f64, rng: &mut R) -> HumanPose {
    let Ok(normal) = Normal::new(0.0, sd.max(0.0)) else {
        return pose.clamped();
    };
    let mut q = pose.q;
    for v in &mut q {
        *v += normal.sample(rng);
    }
    HumanPose { q }.clamped()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::HumanHand;
    use crate::keypoints::Finger;
    use rand::SeedableRng;

    #[test]
    fn synergies_look_like_their_names() {
        let hand = HumanHand::average();
        let tip = |s: Synergy, f: Finger| hand.keypoints(&s.posture()).finger(f)[3];
        let gap = |s: Synergy, f: Finger| (tip(s, Finger::Thumb) - tip(s, f)).norm();
        // Pinch: thumb tip and index tip close together.
        assert!(
            gap(Synergy::Pinch, Finger::Index) < 0.025,
            "pinch gap {}",
            gap(Synergy::Pinch, Finger::Index)
        );
        // Open: they are far apart.
        assert!(gap(Synergy::Open, Finger::Index) > 0.07);
        // Power: fingertips on the palm side, near the palm.
        for f in [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little] {
            let t = tip(Synergy::Power, f);
            assert!(t.y < -0.01 && t.z < 0.12, "power {f:?} tip {t}");
        }
        // Pointing: index extended beyond the curled middle finger.
        assert!(
            tip(Synergy::Pointing, Finger::Index).z
                > tip(Synergy::Pointing, Finger::Middle).z + 0.06
        );
        // Precision: fingertips and thumb tip within a small-object span.
        for f in [Finger::Index, Finger::Middle] {
            assert!(
                gap(Synergy::Precision, f) < 0.06,
                "precision {f:?} gap {}",
                gap(Synergy::Precision, f)
            );
        }
    }

    #[test]
    fn samples_stay_within_limits_and_cover_every_kind() {
        let sampler = PoseSampler::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (mut random, mut synergy, mut blend) = (0, 0, 0);
        let mut min = [f64::MAX; HUMAN_DOF];
        let mut max = [f64::MIN; HUMAN_DOF];
        for _ in 0..2000 {
            let (pose, kind) = sampler.sample(&mut rng);
            assert!(pose.within_limits());
            match kind {
                PoseKind::Random => random += 1,
                PoseKind::Synergy { .. } => synergy += 1,
                PoseKind::Blend { .. } => blend += 1,
            }
            for i in 0..HUMAN_DOF {
                min[i] = min[i].min(pose.q[i]);
                max[i] = max[i].max(pose.q[i]);
            }
        }
        assert!(
            random > 400 && synergy > 850 && blend > 400,
            "{random} {synergy} {blend}"
        );
        // Every joint visits at least 80 % of its range.
        for i in 0..HUMAN_DOF {
            let (lo, hi) = HUMAN_JOINT_LIMITS[i];
            assert!(
                max[i] - min[i] > 0.8 * (hi - lo),
                "joint {i}: {} .. {}",
                min[i],
                max[i]
            );
        }
    }

    #[test]
    fn sampling_is_deterministic_for_a_seed() {
        let sampler = PoseSampler::default();
        let mut a = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut b = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..50 {
            assert_eq!(sampler.sample(&mut a), sampler.sample(&mut b));
        }
    }
}
