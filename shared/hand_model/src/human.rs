//! A parametric human right hand: 22 joints with human ranges, anthropometric bone
//! lengths with per-hand shape variation, forward kinematics to the 21 BigHand
//! keypoints, and capsule geometry for depth rendering.
//!
//! # Frame
//! The hand's canonical frame has its origin at the wrist keypoint, **x** towards the
//! thumb side (radial), **y** out of the back of the hand (dorsal), **z** towards the
//! fingers (distal) — the same axes as the Shadow hand's `rh_palm`, whose first finger
//! is at +x and whose fingers flex towards -y.
//!
//! # Joints
//! Index, middle and ring: MCP abduction (positive = towards the thumb), MCP flexion,
//! PIP, DIP. Little: CMC cupping (the metacarpal folds towards the palm, like the
//! Shadow's LFJ5) then the same four. Thumb: CMC palmar abduction, CMC flexion (across
//! the palm), MCP flexion, MCP abduction, IP. Flexion is positive towards the palm.
//! Ranges are typical active ranges of motion of an adult hand.
//!
//! # Dimensions
//! Bone lengths of an average adult hand (hand length ~ 185 mm, wrist to middle
//! fingertip), after published anthropometric tables of phalanx and metacarpal
//! lengths. A [`HandShape`] scales them as a whole (hand size) and per segment
//! (finger proportions).

use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::HandModelError;
use crate::keypoints::{Finger, HandKeypoints, KEYPOINT_COUNT, WRIST};

/// Number of joints of the human hand model.
pub const HUMAN_DOF: usize = 22;

/// Joint names, in the order of [`HumanPose::q`].
pub const HUMAN_JOINT_NAMES: [&str; HUMAN_DOF] = [
    "index_mcp_abd",
    "index_mcp_flex",
    "index_pip",
    "index_dip",
    "middle_mcp_abd",
    "middle_mcp_flex",
    "middle_pip",
    "middle_dip",
    "ring_mcp_abd",
    "ring_mcp_flex",
    "ring_pip",
    "ring_dip",
    "little_cmc",
    "little_mcp_abd",
    "little_mcp_flex",
    "little_pip",
    "little_dip",
    "thumb_cmc_abd",
    "thumb_cmc_flex",
    "thumb_mcp_flex",
    "thumb_mcp_abd",
    "thumb_ip",
];

const fn deg(d: f64) -> f64 {
    d * std::f64::consts::PI / 180.0
}

/// Joint limits `(lower, upper)` in radians, in the order of [`HUMAN_JOINT_NAMES`].
pub const HUMAN_JOINT_LIMITS: [(f64, f64); HUMAN_DOF] = [
    // index
    (deg(-20.0), deg(25.0)),
    (deg(-20.0), deg(90.0)),
    (deg(0.0), deg(105.0)),
    (deg(-5.0), deg(80.0)),
    // middle
    (deg(-15.0), deg(15.0)),
    (deg(-20.0), deg(90.0)),
    (deg(0.0), deg(105.0)),
    (deg(-5.0), deg(80.0)),
    // ring
    (deg(-15.0), deg(15.0)),
    (deg(-20.0), deg(90.0)),
    (deg(0.0), deg(105.0)),
    (deg(-5.0), deg(80.0)),
    // little
    (deg(0.0), deg(20.0)),
    (deg(-25.0), deg(20.0)),
    (deg(-20.0), deg(90.0)),
    (deg(0.0), deg(105.0)),
    (deg(-5.0), deg(80.0)),
    // thumb
    (deg(-10.0), deg(60.0)),
    (deg(-20.0), deg(50.0)),
    (deg(-10.0), deg(60.0)),
    (deg(-8.0), deg(8.0)),
    (deg(-15.0), deg(80.0)),
];

/// Index in [`HumanPose::q`] of the first joint of `finger`.
#[must_use]
pub fn first_joint(finger: Finger) -> usize {
    match finger {
        Finger::Index => 0,
        Finger::Middle => 4,
        Finger::Ring => 8,
        Finger::Little => 12,
        Finger::Thumb => 17,
    }
}

/// A pose of the human hand: 22 joint angles (rad) in [`HUMAN_JOINT_NAMES`] order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HumanPose {
    pub q: [f64; HUMAN_DOF],
}

impl HumanPose {
    /// All joints at zero: a flat hand, fingers together, thumb beside the index.
    #[must_use]
    pub fn flat() -> Self {
        Self {
            q: [0.0; HUMAN_DOF],
        }
    }

    /// A pose from joint angles, refusing non-finite values and values outside the
    /// limits (by more than 1e-9 rad).
    ///
    /// # Errors
    /// [`HandModelError::Invalid`] naming the joint.
    pub fn new(q: [f64; HUMAN_DOF]) -> Result<Self, HandModelError> {
        for (i, v) in q.iter().enumerate() {
            let (lo, hi) = HUMAN_JOINT_LIMITS[i];
            if !v.is_finite() || *v < lo - 1e-9 || *v > hi + 1e-9 {
                return Err(HandModelError::Invalid {
                    what: "human joint angle",
                    reason: format!(
                        "{} = {v} rad is outside [{lo:.3}, {hi:.3}]",
                        HUMAN_JOINT_NAMES[i]
                    ),
                });
            }
        }
        Ok(Self { q })
    }

    /// The pose with every joint clamped into its limits (non-finite values become 0
    /// clamped).
    #[must_use]
    pub fn clamped(mut self) -> Self {
        for (v, (lo, hi)) in self.q.iter_mut().zip(HUMAN_JOINT_LIMITS) {
            let x = if v.is_finite() { *v } else { 0.0 };
            *v = x.clamp(lo, hi);
        }
        self
    }

    /// Whether every joint is finite and within its limits.
    #[must_use]
    pub fn within_limits(&self) -> bool {
        self.q
            .iter()
            .zip(HUMAN_JOINT_LIMITS)
            .all(|(v, (lo, hi))| v.is_finite() && *v >= lo - 1e-9 && *v <= hi + 1e-9)
    }

    /// `(1 - t) * self + t * other`.
    #[must_use]
    pub fn lerp(&self, other: &Self, t: f64) -> Self {
        let mut q = self.q;
        for (v, o) in q.iter_mut().zip(other.q) {
            *v += t * (o - *v);
        }
        Self { q }
    }
}

/// How one hand differs from the average: overall size and per-segment proportions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandShape {
    /// Overall scale of every length (1 = the average adult hand, ~185 mm long).
    pub scale: f64,
    /// Per finger ([`Finger::ALL`] order), per bone (metacarpal or palm offset,
    /// proximal, middle, distal; thumb: metacarpal, proximal, distal, and the CMC's
    /// palm offset) a factor on the average length.
    pub segments: [[f64; 4]; 5],
    /// Factor on the palm's width (MCP spacing) and the finger thickness.
    pub width: f64,
}

impl HandShape {
    /// Smallest and largest overall scale a shape may have.
    pub const SCALE_RANGE: (f64, f64) = (0.7, 1.35);
    /// Smallest and largest per-segment or width factor.
    pub const FACTOR_RANGE: (f64, f64) = (0.75, 1.3);

    /// The average hand.
    #[must_use]
    pub fn average() -> Self {
        Self {
            scale: 1.0,
            segments: [[1.0; 4]; 5],
            width: 1.0,
        }
    }

    /// A random adult hand: overall scale ~ N(1, `scale_sd`) clipped to
    /// `1 ± 2.2 scale_sd`, each segment ~ N(1, `segment_sd`) clipped to `1 ± 2.5 sd`,
    /// width ~ N(1, `segment_sd`). The training distribution uses
    /// `(0.07, 0.04)` (hand length 5th-95th percentile about ±11 %).
    #[must_use]
    pub fn sample<R: Rng + ?Sized>(rng: &mut R, scale_sd: f64, segment_sd: f64) -> Self {
        let clip = |v: f64, sd: f64, k: f64| v.clamp(1.0 - k * sd, 1.0 + k * sd);
        let scale_sd = scale_sd.clamp(0.0, 0.12);
        let segment_sd = segment_sd.clamp(0.0, 0.1);
        let draw =
            |rng: &mut R, sd: f64| Normal::new(1.0, sd.max(1e-12)).map_or(1.0, |n| n.sample(rng));
        let scale = clip(draw(rng, scale_sd), scale_sd, 2.2);
        let mut segments = [[1.0; 4]; 5];
        for finger in &mut segments {
            for s in finger.iter_mut() {
                *s = clip(draw(rng, segment_sd), segment_sd, 2.5);
            }
        }
        let width = clip(draw(rng, segment_sd), segment_sd, 2.5);
        Self {
            scale,
            segments,
            width,
        }
    }

    fn validate(&self) -> Result<(), HandModelError> {
        let (lo, hi) = Self::SCALE_RANGE;
        if !(self.scale.is_finite() && (lo..=hi).contains(&self.scale)) {
            return Err(HandModelError::Invalid {
                what: "hand shape",
                reason: format!("scale {} is outside [{lo}, {hi}]", self.scale),
            });
        }
        let (lo, hi) = Self::FACTOR_RANGE;
        let factors = self
            .segments
            .iter()
            .flatten()
            .chain(std::iter::once(&self.width));
        for f in factors {
            if !(f.is_finite() && (lo..=hi).contains(f)) {
                return Err(HandModelError::Invalid {
                    what: "hand shape",
                    reason: format!("segment or width factor {f} is outside [{lo}, {hi}]"),
                });
            }
        }
        Ok(())
    }
}

impl Default for HandShape {
    fn default() -> Self {
        Self::average()
    }
}

/// Average-hand dimensions (m) per finger in [`Finger::ALL`] order.
struct FingerBase {
    /// MCP (thumb: CMC) position in the canonical frame, y = 0 plane for fingers.
    mcp: [f64; 3],
    /// Rest direction of the proximal bone (thumb: metacarpal).
    direction: [f64; 3],
    /// Bone lengths: proximal, middle, distal (thumb: metacarpal, proximal, distal).
    lengths: [f64; 3],
    /// Capsule radii of the three bones.
    radii: [f64; 3],
}

const AVERAGE: [FingerBase; 5] = [
    FingerBase {
        mcp: [0.024, 0.0, 0.088],
        direction: [0.08, 0.0, 1.0],
        lengths: [0.040, 0.023, 0.021],
        radii: [0.0095, 0.0085, 0.0078],
    },
    FingerBase {
        mcp: [0.004, 0.0, 0.090],
        direction: [0.0, 0.0, 1.0],
        lengths: [0.045, 0.027, 0.022],
        radii: [0.0097, 0.0088, 0.008],
    },
    FingerBase {
        mcp: [-0.014, 0.0, 0.085],
        direction: [-0.06, 0.0, 1.0],
        lengths: [0.042, 0.026, 0.022],
        radii: [0.0092, 0.0084, 0.0077],
    },
    FingerBase {
        mcp: [-0.030, 0.0, 0.078],
        direction: [-0.14, 0.0, 1.0],
        lengths: [0.033, 0.018, 0.020],
        radii: [0.0083, 0.0076, 0.007],
    },
    FingerBase {
        mcp: [0.020, -0.012, 0.030],
        direction: [0.62, -0.10, 0.78],
        lengths: [0.046, 0.032, 0.027],
        radii: [0.0125, 0.0102, 0.0092],
    },
];

/// Where the little finger's metacarpal pivots when the palm cups (CMC), and about
/// which axis (the Shadow's LFJ5 axis direction).
const LITTLE_CMC_PIVOT: [f64; 3] = [-0.020, 0.0, 0.020];
const LITTLE_CMC_AXIS: [f64; 3] = [0.573_576_436, 0.0, 0.819_152_044];
/// The direction the thumb's CMC abducts towards (out of the palm's plane, palmar);
/// its flexion moves it across the palm, perpendicular to this and to the metacarpal.
const THUMB_ABDUCTION: [f64; 3] = [0.0, -1.0, 0.0];

/// A capsule of the hand's geometry: segment `a`-`b` and radius, canonical frame (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandCapsule {
    pub a: Point3<f64>,
    pub b: Point3<f64>,
    pub radius: f64,
}

/// One hand: a shape turned into dimensions, ready for forward kinematics.
#[derive(Debug, Clone, PartialEq)]
pub struct HumanHand {
    shape: HandShape,
    mcp: [Point3<f64>; 5],
    base: [Rotation3<f64>; 5],
    lengths: [[f64; 3]; 5],
    radii: [[f64; 3]; 5],
    little_pivot: Point3<f64>,
    little_axis: Unit<Vector3<f64>>,
}

/// Keypoints and bone frames of one posed hand.
#[derive(Debug, Clone, PartialEq)]
pub struct PosedHand {
    /// The 21 keypoints, canonical frame.
    pub keypoints: HandKeypoints,
    /// Per finger, the rotation of each of its three bones (z along the bone).
    pub bones: [[Rotation3<f64>; 3]; 5],
}

impl HumanHand {
    /// The hand of `shape`.
    ///
    /// # Errors
    /// [`HandModelError::Invalid`] for a scale or factor outside
    /// [`HandShape::SCALE_RANGE`] / [`HandShape::FACTOR_RANGE`] or not finite.
    pub fn new(shape: HandShape) -> Result<Self, HandModelError> {
        shape.validate()?;
        let s = shape.scale;
        let mut mcp = [Point3::origin(); 5];
        let mut base = [Rotation3::identity(); 5];
        let mut lengths = [[0.0; 3]; 5];
        let mut radii = [[0.0; 3]; 5];
        for (i, avg) in AVERAGE.iter().enumerate() {
            let seg = shape.segments[i];
            let [x, y, z] = avg.mcp;
            // The palm's length scales with the first factor (metacarpal / palm
            // offset), its width with `width`.
            mcp[i] = Point3::new(x * shape.width, y, z * seg[0]) * s;
            base[i] = if i == Finger::Thumb.index() {
                frame_abducting(
                    &Vector3::from(avg.direction),
                    &Vector3::from(THUMB_ABDUCTION),
                )
            } else {
                frame_along(&Vector3::from(avg.direction), &Vector3::y())
            };
            for k in 0..3 {
                // Thumb: the metacarpal's length is seg[1]; fingers: proximal = seg[1].
                lengths[i][k] = avg.lengths[k] * seg[k + 1] * s;
                radii[i][k] = avg.radii[k] * shape.width * s;
            }
        }
        let [px, py, pz] = LITTLE_CMC_PIVOT;
        Ok(Self {
            shape,
            mcp,
            base,
            lengths,
            radii,
            little_pivot: Point3::new(px * shape.width, py, pz) * s,
            little_axis: Unit::new_normalize(Vector3::from(LITTLE_CMC_AXIS)),
        })
    }

    /// The average hand.
    #[must_use]
    pub fn average() -> Self {
        // The average shape is valid by construction.
        Self::new(HandShape::average()).unwrap_or_else(|_| unreachable!("average shape"))
    }

    /// The shape this hand was built from.
    #[must_use]
    pub fn shape(&self) -> &HandShape {
        &self.shape
    }

    /// Bone lengths (m) of `finger`: proximal, middle, distal (thumb: metacarpal,
    /// proximal, distal).
    #[must_use]
    pub fn lengths(&self, finger: Finger) -> [f64; 3] {
        self.lengths[finger.index()]
    }

    /// Forward kinematics: keypoints and bone frames in the canonical frame.
    #[must_use]
    pub fn pose(&self, pose: &HumanPose) -> PosedHand {
        let q = &pose.q;
        let mut kp = [Point3::origin(); KEYPOINT_COUNT];
        kp[WRIST] = Point3::origin();
        let mut bones = [[Rotation3::identity(); 3]; 5];
        for finger in Finger::ALL {
            let i = finger.index();
            let j = first_joint(finger);
            let len = self.lengths[i];
            let (mcp, r1, flex2, flex3) = match finger {
                Finger::Thumb => {
                    let r1 = self.base[i] * ry(q[j]) * rx(q[j + 1]);
                    let r2_extra = ry(q[j + 3]) * rx(q[j + 2]);
                    (self.mcp[i], r1, r2_extra, rx(q[j + 4]))
                }
                Finger::Little => {
                    let cmc = Rotation3::from_axis_angle(&self.little_axis, q[j]);
                    let mcp = self.little_pivot + cmc * (self.mcp[i] - self.little_pivot);
                    let r1 = cmc * self.base[i] * ry(q[j + 1]) * rx(q[j + 2]);
                    (mcp, r1, rx(q[j + 3]), rx(q[j + 4]))
                }
                _ => {
                    let r1 = self.base[i] * ry(q[j]) * rx(q[j + 1]);
                    (self.mcp[i], r1, rx(q[j + 2]), rx(q[j + 3]))
                }
            };
            let r2 = r1 * flex2;
            let r3 = r2 * flex3;
            let pip = mcp + r1 * Vector3::z() * len[0];
            let dip = pip + r2 * Vector3::z() * len[1];
            let tip = dip + r3 * Vector3::z() * len[2];
            let [a, b, c, d] = finger.keypoints();
            kp[a] = mcp;
            kp[b] = pip;
            kp[c] = dip;
            kp[d] = tip;
            bones[i] = [r1, r2, r3];
        }
        PosedHand {
            keypoints: HandKeypoints(kp),
            bones,
        }
    }

    /// The 21 keypoints of `pose`, canonical frame.
    #[must_use]
    pub fn keypoints(&self, pose: &HumanPose) -> HandKeypoints {
        self.pose(pose).keypoints
    }

    /// The hand's surface as capsules (canonical frame): three per finger, the
    /// metacarpals, the palm's width, the thenar eminence. The distal capsules end at
    /// the fingertip keypoints' surface, not a radius beyond. The forearm is not
    /// included (see [`crate::scene`]).
    pub fn capsules(&self, posed: &PosedHand, out: &mut Vec<HandCapsule>) {
        let kp = &posed.keypoints;
        let s = self.shape.scale;
        let w = self.shape.width;
        let cap = |a: Point3<f64>, b: Point3<f64>, radius: f64| HandCapsule { a, b, radius };
        for finger in Finger::ALL {
            let i = finger.index();
            let [mcp, pip, dip, tip] = kp.finger(finger);
            let r = self.radii[i];
            // The distal capsule's cap ends at the TIP keypoint (the fingertip's end).
            let dir = (tip - dip).try_normalize(1e-9).unwrap_or_else(Vector3::z);
            let tip_end = tip - dir * (r[2] * 0.9).min((tip - dip).norm() * 0.5);
            out.push(cap(mcp, pip, r[0]));
            out.push(cap(pip, dip, r[1]));
            out.push(cap(dip, tip_end, r[2]));
        }
        // Palm: a metacarpal capsule from the carpus to each finger's MCP, plus
        // transverse capsules at the knuckles and across the carpus.
        let palm_r = 0.0115 * s * w;
        let mut carpal = [Point3::origin(); 4];
        for (k, finger) in [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little]
            .into_iter()
            .enumerate()
        {
            let mcp = kp.finger(finger)[0];
            let base = Point3::new(mcp.x * 0.55, -0.002 * s, 0.022 * s);
            carpal[k] = base;
            out.push(cap(base, mcp, palm_r));
        }
        let mcps =
            [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little].map(|f| kp.finger(f)[0]);
        for pair in mcps.windows(2) {
            out.push(cap(pair[0], pair[1], palm_r * 0.95));
        }
        out.push(cap(carpal[0], carpal[3], palm_r * 1.15));
        // Mid-palm filler between the carpus and the knuckles.
        let mid = |a: Point3<f64>, b: Point3<f64>| nalgebra::center(&a, &b);
        out.push(cap(
            mid(carpal[0], mcps[0]),
            mid(carpal[3], mcps[3]),
            palm_r * 1.05,
        ));
        // Thenar eminence: along the thumb metacarpal, and a web towards the index MCP.
        let [tcmc, tmcp, ..] = kp.finger(Finger::Thumb);
        let thenar_base = Point3::new(0.010 * s * w, -0.006 * s, 0.018 * s);
        out.push(cap(thenar_base, mid(tcmc, tmcp), 0.0135 * s * w));
        out.push(cap(mid(tcmc, tmcp), mid(tmcp, mcps[0]), 0.009 * s * w));
    }
}

/// A rotation whose z is `direction` and whose y is as close to `dorsal` as possible.
fn frame_along(direction: &Vector3<f64>, dorsal: &Vector3<f64>) -> Rotation3<f64> {
    let z = direction.normalize();
    let y = (dorsal - z * dorsal.dot(&z)).normalize();
    let x = y.cross(&z);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]))
}

/// A rotation whose z is `direction` and whose x is as close to `abduction` as
/// possible (abduction about local y moves z towards x).
fn frame_abducting(direction: &Vector3<f64>, abduction: &Vector3<f64>) -> Rotation3<f64> {
    let z = direction.normalize();
    let x = (abduction - z * abduction.dot(&z)).normalize();
    let y = z.cross(&x);
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]))
}

/// Flexion: about local x, positive moves z towards -y (the palm).
fn rx(angle: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), angle)
}

/// Abduction: about local y, positive moves z towards +x (the thumb side).
fn ry(angle: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::y_axis(), angle)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keypoints::hand_frame;
    use rand::SeedableRng;

    #[test]
    fn the_flat_average_hand_has_human_proportions() {
        let hand = HumanHand::average();
        let kp = hand.keypoints(&HumanPose::flat());
        // Hand length: wrist to middle fingertip, 170-200 mm for an average adult.
        let length = (kp.finger(Finger::Middle)[3] - kp.wrist()).norm();
        assert!((0.17..0.2).contains(&length), "hand length {length}");
        // Breadth at the knuckles (index to little MCP centres) ~ 55 mm.
        let breadth = (kp.finger(Finger::Index)[0] - kp.finger(Finger::Little)[0]).norm();
        assert!((0.045..0.065).contains(&breadth), "breadth {breadth}");
        // Fingers point along +z, the thumb to the radial side.
        for f in [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little] {
            let [mcp, _, _, tip] = kp.finger(f);
            assert!(tip.z > mcp.z + 0.06, "{f:?} tip {tip}");
        }
        assert!(kp.finger(Finger::Thumb)[3].x > 0.05);
        // The hand frame of a flat hand is the canonical frame up to a small tilt.
        let frame = hand_frame(&kp).expect("frame");
        let z = frame.rotation * Vector3::z();
        assert!(z.z > 0.98, "hand frame z {z}");
        let y = frame.rotation * Vector3::y();
        assert!(y.y.abs() > 0.95, "hand frame y {y}");
    }

    #[test]
    fn flexion_curls_towards_the_palm_and_bones_keep_their_length() {
        let hand = HumanHand::average();
        let mut pose = HumanPose::flat();
        for f in [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little] {
            let j = first_joint(f) + usize::from(f == Finger::Little);
            pose.q[j + 1] = 1.2;
            pose.q[j + 2] = 1.4;
            pose.q[j + 3] = 0.9;
        }
        let flat = hand.keypoints(&HumanPose::flat());
        let fist = hand.keypoints(&pose);
        for f in [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little] {
            let tip = fist.finger(f)[3];
            assert!(tip.y < -0.02, "{f:?} tip {tip} should be on the palm side");
            for k in 0..3 {
                let a = f.keypoints()[k];
                let b = f.keypoints()[k + 1];
                let l0 = (flat.0[b] - flat.0[a]).norm();
                let l1 = (fist.0[b] - fist.0[a]).norm();
                assert!((l0 - l1).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn shapes_are_validated_and_scale_the_hand() {
        let mut shape = HandShape::average();
        shape.scale = 1.1;
        let big = HumanHand::new(shape).expect("valid");
        let kb = big.keypoints(&HumanPose::flat());
        let ka = HumanHand::average().keypoints(&HumanPose::flat());
        let lb = (kb.finger(Finger::Middle)[3] - kb.wrist()).norm();
        let la = (ka.finger(Finger::Middle)[3] - ka.wrist()).norm();
        assert!((lb / la - 1.1).abs() < 1e-9);
        shape.scale = f64::NAN;
        assert!(matches!(
            HumanHand::new(shape),
            Err(HandModelError::Invalid { .. })
        ));
        shape.scale = 1.0;
        shape.segments[2][1] = 3.0;
        let err = HumanHand::new(shape).expect_err("factor 3");
        assert!(err.to_string().contains("factor 3"), "{err}");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for _ in 0..200 {
            let s = HandShape::sample(&mut rng, 0.07, 0.04);
            assert!(HumanHand::new(s).is_ok(), "{s:?}");
        }
    }

    #[test]
    fn poses_outside_the_limits_are_refused_by_name() {
        let mut q = [0.0; HUMAN_DOF];
        q[6] = 3.0;
        let err = HumanPose::new(q).expect_err("middle PIP 3 rad");
        assert!(err.to_string().contains("middle_pip"), "{err}");
        q[6] = f64::NAN;
        assert!(HumanPose::new(q).is_err());
        let clamped = HumanPose { q }.clamped();
        assert!(clamped.within_limits());
    }

    #[test]
    fn capsules_cover_every_bone() {
        let hand = HumanHand::average();
        let posed = hand.pose(&HumanPose::flat());
        let mut caps = Vec::new();
        hand.capsules(&posed, &mut caps);
        assert!(caps.len() >= 20);
        for c in &caps {
            assert!(c.radius > 0.005 && c.radius < 0.02);
            assert!(
                c.a.coords
                    .iter()
                    .chain(c.b.coords.iter())
                    .all(|v| v.is_finite())
            );
        }
        // The fingertip surface ends at the TIP keypoint (within a millimetre).
        let tip = posed.keypoints.finger(Finger::Middle)[3];
        let reach = caps
            .iter()
            .map(|c| c.a.z.max(c.b.z) + c.radius)
            .fold(f64::MIN, f64::max);
        assert!((reach - tip.z).abs() < 1e-3, "reach {reach} tip {}", tip.z);
    }
}
