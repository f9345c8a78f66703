//! The 21 hand keypoints in BigHand2.2M order, the fingers, and the hand frames computed
//! from keypoints.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::HandModelError;

/// Number of keypoints of a hand.
pub const KEYPOINT_COUNT: usize = 21;

/// Keypoint names in BigHand2.2M (and HANDS 2017) order: the wrist, the five MCPs
/// (thumb, index, middle, ring, pinky), then PIP, DIP, TIP finger by finger. For the
/// thumb the "MCP" is the carpometacarpal joint (CMC), "PIP" the MCP and "DIP" the IP.
pub const KEYPOINT_NAMES: [&str; KEYPOINT_COUNT] = [
    "Wrist", "TMCP", "IMCP", "MMCP", "RMCP", "PMCP", "TPIP", "TDIP", "TTIP", "IPIP", "IDIP",
    "ITIP", "MPIP", "MDIP", "MTIP", "RPIP", "RDIP", "RTIP", "PPIP", "PDIP", "PTIP",
];

/// Index of the wrist keypoint.
pub const WRIST: usize = 0;

/// A finger of the human hand, in the project's one finger order (the Shadow's ff, mf,
/// rf, lf, th: `teleop_interfaces::joints::FINGERTIPS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Finger {
    /// First finger (Shadow ff).
    Index,
    /// Middle finger (mf).
    Middle,
    /// Ring finger (rf).
    Ring,
    /// Little finger (lf).
    Little,
    /// Thumb (th).
    Thumb,
}

impl Finger {
    /// All five, in the project's finger order.
    pub const ALL: [Finger; 5] = [
        Finger::Index,
        Finger::Middle,
        Finger::Ring,
        Finger::Little,
        Finger::Thumb,
    ];

    /// Position in [`Finger::ALL`].
    #[must_use]
    pub fn index(self) -> usize {
        match self {
            Finger::Index => 0,
            Finger::Middle => 1,
            Finger::Ring => 2,
            Finger::Little => 3,
            Finger::Thumb => 4,
        }
    }

    /// Keypoint indices `[MCP, PIP, DIP, TIP]` of this finger in BigHand order.
    #[must_use]
    pub fn keypoints(self) -> [usize; 4] {
        match self {
            Finger::Thumb => [1, 6, 7, 8],
            Finger::Index => [2, 9, 10, 11],
            Finger::Middle => [3, 12, 13, 14],
            Finger::Ring => [4, 15, 16, 17],
            Finger::Little => [5, 18, 19, 20],
        }
    }
}

/// The 21 keypoints of one hand (m), in some frame (camera, hand, robot palm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandKeypoints(pub [Point3<f64>; KEYPOINT_COUNT]);

impl HandKeypoints {
    /// The wrist keypoint.
    #[must_use]
    pub fn wrist(&self) -> Point3<f64> {
        self.0[WRIST]
    }

    /// `[MCP, PIP, DIP, TIP]` of `finger`.
    #[must_use]
    pub fn finger(&self, finger: Finger) -> [Point3<f64>; 4] {
        finger.keypoints().map(|i| self.0[i])
    }

    /// Every coordinate is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.0
            .iter()
            .all(|p| p.coords.iter().all(|v| v.is_finite()))
    }

    /// The keypoints moved by `pose` (`pose * p` for each).
    #[must_use]
    pub fn transformed(&self, pose: &Isometry3<f64>) -> Self {
        Self(self.0.map(|p| pose * p))
    }

    /// Largest distance between corresponding keypoints (m).
    #[must_use]
    pub fn max_distance(&self, other: &Self) -> f64 {
        self.0
            .iter()
            .zip(other.0.iter())
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
    }
}

/// The hand frame of thesis Fig. 3.6, from keypoints: origin at the wrist; Z the mean of
/// the unit vectors from the wrist to the MCPs of the index, middle, ring and little
/// fingers; Y along `v_middle x v_ring` (made orthogonal to Z), which points out of the
/// palm for a right hand; X = Y x Z, towards the little finger.
///
/// Returns the pose of this frame in the keypoints' frame.
///
/// # Errors
/// [`HandModelError::DegenerateHand`] for non-finite keypoints or MCPs on one line
/// with the wrist.
pub fn hand_frame(keypoints: &HandKeypoints) -> Result<Isometry3<f64>, HandModelError> {
    frame_from(
        keypoints,
        &[Finger::Index, Finger::Middle, Finger::Ring, Finger::Little],
    )
}

/// The frame the retargeting registers human and robot hands in: as [`hand_frame`], but
/// Z averages the index, middle and ring MCP directions only. Their metacarpals are
/// rigid in the palm, while the little finger's moves (cupping on a person, LFJ5 on the
/// Shadow, up to 45 deg), which would tilt the frame with the little finger's pose.
///
/// # Errors
/// As [`hand_frame`].
pub fn palm_frame(keypoints: &HandKeypoints) -> Result<Isometry3<f64>, HandModelError> {
    frame_from(keypoints, &[Finger::Index, Finger::Middle, Finger::Ring])
}

fn frame_from(
    keypoints: &HandKeypoints,
    fingers: &[Finger],
) -> Result<Isometry3<f64>, HandModelError> {
    if !keypoints.is_finite() {
        return Err(HandModelError::DegenerateHand {
            reason: "a keypoint is not finite",
        });
    }
    let wrist = keypoints.wrist();
    let unit = |f: Finger| -> Result<Vector3<f64>, HandModelError> {
        let v = keypoints.finger(f)[0] - wrist;
        let n = v.norm();
        if n < 1e-6 {
            return Err(HandModelError::DegenerateHand {
                reason: "an MCP coincides with the wrist",
            });
        }
        Ok(v / n)
    };
    let mut sum = Vector3::zeros();
    for f in fingers {
        sum += unit(*f)?;
    }
    let z = sum
        .try_normalize(1e-9)
        .ok_or(HandModelError::DegenerateHand {
            reason: "the MCP directions cancel out",
        })?;
    let y_raw = unit(Finger::Middle)?.cross(&unit(Finger::Ring)?);
    let y =
        (y_raw - z * y_raw.dot(&z))
            .try_normalize(1e-9)
            .ok_or(HandModelError::DegenerateHand {
                reason: "middle and ring MCPs are on one line with the wrist",
            })?;
    let x = y.cross(&z);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Ok(Isometry3::from_parts(
        Translation3::from(wrist.coords),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_keypoint_belongs_to_one_finger_or_the_wrist() {
        let mut seen = [false; KEYPOINT_COUNT];
        seen[WRIST] = true;
        for f in Finger::ALL {
            for i in f.keypoints() {
                assert!(!seen[i], "{} twice", KEYPOINT_NAMES[i]);
                seen[i] = true;
            }
            let [mcp, pip, dip, tip] = f.keypoints();
            let letter = &KEYPOINT_NAMES[mcp][..1];
            for (i, suffix) in [(mcp, "MCP"), (pip, "PIP"), (dip, "DIP"), (tip, "TIP")] {
                assert_eq!(KEYPOINT_NAMES[i], format!("{letter}{suffix}"));
            }
        }
        assert!(seen.iter().all(|s| *s));
        for (i, f) in Finger::ALL.iter().enumerate() {
            assert_eq!(f.index(), i);
        }
    }

    #[test]
    fn degenerate_hands_are_refused() {
        let kp = HandKeypoints([Point3::origin(); KEYPOINT_COUNT]);
        assert!(hand_frame(&kp).is_err());
        let mut kp = kp;
        kp.0[3].x = f64::NAN;
        assert!(matches!(
            hand_frame(&kp),
            Err(HandModelError::DegenerateHand { .. })
        ));
    }
}
