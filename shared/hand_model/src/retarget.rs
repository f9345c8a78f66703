//! Human keypoints to the Shadow hand's 17 finger joints, the way the thesis built its
//! dataset (ch. 3.4), with the project's IK ([`teleop_ik`]):
//!
//! * **Common frame.** Human and robot hands are registered by their palm frames
//!   ([`crate::palm_frame`]): the human wrist keypoint goes onto the origin of
//!   `rh_palm`, 34 mm above the robot wrist (`rh_wrist`), and the palm axes onto the
//!   robot's palm axes computed the same way from the robot's own keypoints.
//! * **Goals per finger** (one IK problem per kinematic chain `rh_palm` -> tip):
//!   fingertip position (weight 1, eq. 3.1), PIP position (0.2), the proximal
//!   phalanx's direction (0.2, eq. 3.2), and for the thumb also the distal phalanx's
//!   direction (0.2). Keypoint correspondences: MCP = knuckle (thumb: `rh_thbase`,
//!   the CMC), PIP = middle joint `J2` (thumb: `rh_thpip`, the MCP), DIP = `J1`,
//!   TIP = `rh_*tip`.
//! * **Self-collision** (eq. 3.3, `max(0, R_col - ‖P_i - P_j‖)`): after the per-finger
//!   solves, each finger's phalanges are capsules; a finger closer than `R_col` (the
//!   sum of the two radii) to another is solved again with a minimum-distance goal
//!   against the others (weight 1), for a configured number of passes.
//!
//! The Shadow's J1s are fixed at 20 deg by the BioTacs, so the chains have 3 joints
//! (FF, MF, RF) and 4 (LF with LFJ5, thumb THJ5..THJ2): 17 in all, in
//! [`SHADOW_FINGER_JOINTS`] order.

use std::sync::Arc;

use nalgebra::{Isometry3, Point3, SVector, Unit, Vector3};
use teleop_ik::{ColdBudget, DistanceConstraint, Goal, IkSettings, Solver};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_kinematics::robots::{self, shadow};
use teleop_kinematics::{KinematicState, Robot};

use crate::HandModelError;
use crate::keypoints::{Finger, HandKeypoints, KEYPOINT_COUNT, WRIST, palm_frame};

/// Number of Shadow finger joints the retargeting (and the network) produce.
pub const SHADOW_FINGER_DOF: usize = 17;

/// Goal weights (thesis ch. 3.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetargetWeights {
    /// Fingertip position goals.
    pub tip: f64,
    /// PIP position goals.
    pub pip: f64,
    /// Direction goals on the proximal phalanges and the thumb's distal phalanx.
    pub direction: f64,
    /// Self-collision goal. Its residual is metres of overlap, the direction goals'
    /// unit-vector differences: 1000 makes 5 mm of overlap cost as much as a 0.35 rad
    /// direction error at weight 0.2 (eq. 3.3 gives no weight; this one measured
    /// best: fewer than 1 % of human hands left overlapping by more than 3 mm).
    pub collision: f64,
}

impl Default for RetargetWeights {
    fn default() -> Self {
        Self {
            tip: 1.0,
            pip: 0.2,
            direction: 0.2,
            collision: 1000.0,
        }
    }
}

/// Retargeting settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetargetSettings {
    pub weights: RetargetWeights,
    /// Levenberg-Marquardt iterations per finger solve.
    pub iterations: u32,
    /// A finger whose fingertip error stays above this (m) is solved again from
    /// `restarts` deterministic random starts, keeping the best (free solves only:
    /// collision re-solves start from the free solution).
    pub restart_above_m: f64,
    pub restarts: u32,
    /// Self-collision passes (0 disables the collision goal).
    pub collision_passes: u32,
    /// Capsule radius of the fingers' phalanges and of the thumb's (m).
    pub finger_radius_m: f64,
    pub thumb_radius_m: f64,
}

impl Default for RetargetSettings {
    fn default() -> Self {
        Self {
            weights: RetargetWeights::default(),
            iterations: 25,
            restart_above_m: 0.01,
            restarts: 4,
            collision_passes: 3,
            finger_radius_m: 0.009,
            thumb_radius_m: 0.0105,
        }
    }
}

/// The outcome of retargeting one hand.
#[derive(Debug, Clone, PartialEq)]
pub struct Retarget {
    /// Shadow finger joints (rad), [`SHADOW_FINGER_JOINTS`] order, within limits.
    pub joints: [f64; SHADOW_FINGER_DOF],
    /// Distance (m) between each robot fingertip and its registered human fingertip,
    /// [`Finger::ALL`] order.
    pub tip_error_m: [f64; 5],
    /// The same for the PIPs.
    pub pip_error_m: [f64; 5],
    /// Smallest capsule clearance between two fingers (m, negative = overlap).
    pub min_clearance_m: f64,
    /// Fingers solved again for self-collision.
    pub collision_resolves: u32,
}

/// Which chain frames carry the PIP and the proximal phalanx, per finger.
#[derive(Debug, Clone, Copy)]
struct FingerFrames {
    pip: usize,
    proximal: usize,
    /// Frame whose z is the distal phalanx (thumb only).
    distal: Option<usize>,
    /// Offset of the finger's first joint in the 17-joint vector.
    offset: usize,
}

const FRAMES: [FingerFrames; 5] = [
    FingerFrames {
        pip: 2,
        proximal: 1,
        distal: None,
        offset: 0,
    },
    FingerFrames {
        pip: 2,
        proximal: 1,
        distal: None,
        offset: 3,
    },
    FingerFrames {
        pip: 2,
        proximal: 1,
        distal: None,
        offset: 6,
    },
    FingerFrames {
        pip: 3,
        proximal: 2,
        distal: None,
        offset: 9,
    },
    FingerFrames {
        pip: 2,
        proximal: 1,
        distal: Some(4),
        offset: 13,
    },
];

/// Registered human targets of one finger (rh_palm frame).
#[derive(Debug, Clone, Copy)]
struct Targets {
    tip: Vector3<f64>,
    pip: Vector3<f64>,
    proximal: Unit<Vector3<f64>>,
    distal: Unit<Vector3<f64>>,
}

/// Retargets human keypoints onto the Shadow hand. Cheap to clone; not shared
/// between threads (clone one per worker).
#[derive(Debug, Clone)]
pub struct Retargeter {
    robot: Robot,
    ff: Solver<3>,
    mf: Solver<3>,
    rf: Solver<3>,
    lf: Solver<4>,
    th: Solver<4>,
    /// Pose of the robot's palm frame in `rh_palm`.
    robot_palm_frame: Isometry3<f64>,
    /// Robot dof index of each of the 17 finger joints.
    dof_of: [usize; SHADOW_FINGER_DOF],
    lower: [f64; SHADOW_FINGER_DOF],
    upper: [f64; SHADOW_FINGER_DOF],
    neutral: [f64; SHADOW_FINGER_DOF],
    settings: RetargetSettings,
}

impl Retargeter {
    /// A retargeter for the project's Shadow hand model.
    ///
    /// # Errors
    /// [`HandModelError::Kinematics`] only if the embedded URDF were broken;
    /// [`HandModelError::Invalid`] for non-finite or negative settings.
    pub fn new(settings: RetargetSettings) -> Result<Self, HandModelError> {
        let w = settings.weights;
        let values = [
            w.tip,
            w.pip,
            w.direction,
            w.collision,
            settings.restart_above_m,
            settings.finger_radius_m,
            settings.thumb_radius_m,
        ];
        if values.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(HandModelError::Invalid {
                what: "retarget settings",
                reason: format!(
                    "weights, radii and thresholds must be finite and >= 0: {settings:?}"
                ),
            });
        }
        let robot = robots::shadow_hand()?;
        let ik = IkSettings {
            tracking_iterations: settings.iterations.max(1),
            cold_iterations: settings.iterations.max(1),
            ..IkSettings::default()
        };
        let chain3 = |tip: &str| -> Result<Solver<3>, HandModelError> {
            Ok(Solver::new(
                robot.chain(shadow::PALM, tip)?.fixed::<3>()?,
                ik,
            ))
        };
        let chain4 = |tip: &str| -> Result<Solver<4>, HandModelError> {
            Ok(Solver::new(
                robot.chain(shadow::PALM, tip)?.fixed::<4>()?,
                ik,
            ))
        };
        let (ff, mf, rf) = (
            chain3(shadow::TIPS[0])?,
            chain3(shadow::TIPS[1])?,
            chain3(shadow::TIPS[2])?,
        );
        let (lf, th) = (chain4(shadow::TIPS[3])?, chain4(shadow::TIPS[4])?);
        let mut dof_of = [0; SHADOW_FINGER_DOF];
        let mut lower = [0.0; SHADOW_FINGER_DOF];
        let mut upper = [0.0; SHADOW_FINGER_DOF];
        let limits: Vec<_> = robot.dof_limits().collect();
        for (i, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
            dof_of[i] = robot.dof_index(name)?;
            lower[i] = limits[dof_of[i]].lower;
            upper[i] = limits[dof_of[i]].upper;
        }
        // Chains list their joints in the same order as the joint table.
        let mut neutral = [0.0; SHADOW_FINGER_DOF];
        for i in 0..SHADOW_FINGER_DOF {
            neutral[i] = (0.3_f64).clamp(lower[i], upper[i]);
            if lower[i] < 0.0 && upper[i] > 0.0 && (upper[i] + lower[i]).abs() < 1e-9 {
                neutral[i] = 0.0; // symmetric abduction joints
            }
        }
        let mut me = Self {
            robot,
            ff,
            mf,
            rf,
            lf,
            th,
            robot_palm_frame: Isometry3::identity(),
            dof_of,
            lower,
            upper,
            neutral,
            settings,
        };
        let rest = me.shadow_keypoints(&[0.0; SHADOW_FINGER_DOF]);
        me.robot_palm_frame = palm_frame(&rest)?;
        Ok(me)
    }

    /// The settings in use.
    #[must_use]
    pub fn settings(&self) -> &RetargetSettings {
        &self.settings
    }

    /// Lower and upper limits of the 17 joints.
    #[must_use]
    pub fn limits(&self) -> ([f64; SHADOW_FINGER_DOF], [f64; SHADOW_FINGER_DOF]) {
        (self.lower, self.upper)
    }

    /// The pose of the robot's palm frame (the registration frame) in `rh_palm`.
    #[must_use]
    pub fn robot_palm_frame(&self) -> Isometry3<f64> {
        self.robot_palm_frame
    }

    /// The transform taking points of the keypoints' frame into `rh_palm` once the
    /// human palm frame is registered onto the robot's.
    ///
    /// # Errors
    /// [`HandModelError::DegenerateHand`] for keypoints without a palm frame.
    pub fn registration(&self, human: &HandKeypoints) -> Result<Isometry3<f64>, HandModelError> {
        Ok(self.robot_palm_frame * palm_frame(human)?.inverse())
    }

    /// The Shadow hand's 21 keypoints at `joints` (rh_palm frame; J1s at 20 deg,
    /// out-of-limit joints evaluated as given).
    #[must_use]
    pub fn shadow_keypoints(&self, joints: &[f64; SHADOW_FINGER_DOF]) -> HandKeypoints {
        let mut positions = vec![0.0; self.robot.dof()];
        for (i, d) in self.dof_of.iter().enumerate() {
            positions[*d] = joints[i];
        }
        let mut state: KinematicState = self.robot.new_state();
        if self.robot.update(&mut state, &positions).is_err() {
            // Sized from the robot itself: cannot fail.
            return HandKeypoints([Point3::origin(); KEYPOINT_COUNT]);
        }
        let link = |name: &str| self.robot.link_id(name).ok();
        let palm_inv = link(shadow::PALM)
            .map(|id| self.robot.link_pose(&state, id).inverse())
            .unwrap_or_else(Isometry3::identity);
        let at = |name: &str| -> Point3<f64> {
            link(name).map_or_else(Point3::origin, |id| {
                palm_inv * Point3::from(self.robot.link_pose(&state, id).translation.vector)
            })
        };
        let mut kp = [Point3::origin(); KEYPOINT_COUNT];
        kp[WRIST] = Point3::origin();
        for f in Finger::ALL {
            let i = f.index();
            let [a, b, c, d] = f.keypoints();
            kp[a] = at(shadow::MCPS[i]);
            kp[b] = at(shadow::PIPS[i]);
            kp[c] = at(shadow::DIPS[i]);
            kp[d] = at(shadow::TIPS[i]);
        }
        HandKeypoints(kp)
    }

    /// Retargets one hand (keypoints in any frame, e.g. the camera's), optionally
    /// warm-started from the previous frame's joints.
    ///
    /// # Errors
    /// [`HandModelError::DegenerateHand`] for non-finite keypoints or keypoints
    /// without a palm frame, or a phalanx of zero length.
    pub fn retarget(
        &self,
        human: &HandKeypoints,
        previous: Option<&[f64; SHADOW_FINGER_DOF]>,
    ) -> Result<Retarget, HandModelError> {
        let registration = self.registration(human)?;
        let kp = human.transformed(&registration);
        let mut targets = [None; 5];
        for f in Finger::ALL {
            let [mcp, pip, dip, tip] = kp.finger(f);
            let unit = |v: Vector3<f64>| {
                Unit::try_new(v, 1e-6).ok_or(HandModelError::DegenerateHand {
                    reason: "a phalanx has zero length",
                })
            };
            targets[f.index()] = Some(Targets {
                tip: tip.coords,
                pip: pip.coords,
                proximal: unit(pip - mcp)?,
                distal: unit(tip - dip)?,
            });
        }
        let targets = targets.map(|t| {
            t.unwrap_or(Targets {
                tip: Vector3::zeros(),
                pip: Vector3::zeros(),
                proximal: Vector3::z_axis(),
                distal: Vector3::z_axis(),
            })
        });
        let start = previous.copied().unwrap_or(self.neutral);
        let mut joints = start.map(|v| if v.is_finite() { v } else { 0.0 });
        for f in Finger::ALL {
            self.solve_finger(f, &targets[f.index()], None, &mut joints);
        }
        let mut resolves = 0;
        if self.settings.weights.collision > 0.0 {
            // Capsules change only when a finger is solved again.
            let mut segments = self.segments(&joints);
            for _ in 0..self.settings.collision_passes {
                let mut any = false;
                // The thumb first: most contacts are the thumb pressing into a finger.
                for f in [
                    Finger::Thumb,
                    Finger::Index,
                    Finger::Middle,
                    Finger::Ring,
                    Finger::Little,
                ] {
                    if clearance_to_others(&segments, f.index()) >= 0.0 {
                        continue;
                    }
                    let others: Vec<Capsule> = segments
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| *i != f.index())
                        .flat_map(|(_, s)| s.iter().copied())
                        .collect();
                    self.solve_finger(f, &targets[f.index()], Some(others), &mut joints);
                    segments = self.segments(&joints);
                    resolves += 1;
                    any = true;
                }
                if !any {
                    break;
                }
            }
        }
        for (i, v) in joints.iter_mut().enumerate() {
            *v = v.clamp(self.lower[i], self.upper[i]);
        }
        let robot_kp = self.shadow_keypoints(&joints);
        let mut tip_error_m = [0.0; 5];
        let mut pip_error_m = [0.0; 5];
        for f in Finger::ALL {
            let [_, pip, _, tip] = f.keypoints();
            tip_error_m[f.index()] = (robot_kp.0[tip] - kp.0[tip]).norm();
            pip_error_m[f.index()] = (robot_kp.0[pip] - kp.0[pip]).norm();
        }
        let segments = self.segments(&joints);
        let min_clearance_m = (0..5)
            .map(|i| clearance_to_others(&segments, i))
            .fold(f64::INFINITY, f64::min);
        Ok(Retarget {
            joints,
            tip_error_m,
            pip_error_m,
            min_clearance_m,
            collision_resolves: resolves,
        })
    }

    fn solve_finger(
        &self,
        finger: Finger,
        targets: &Targets,
        avoid: Option<Vec<Capsule>>,
        joints: &mut [f64; SHADOW_FINGER_DOF],
    ) {
        let i = finger.index();
        let frames = FRAMES[i];
        let radius = self.radius(finger);
        match finger {
            Finger::Index => self.solve_chain(&self.ff, frames, targets, avoid, radius, joints),
            Finger::Middle => self.solve_chain(&self.mf, frames, targets, avoid, radius, joints),
            Finger::Ring => self.solve_chain(&self.rf, frames, targets, avoid, radius, joints),
            Finger::Little => self.solve_chain(&self.lf, frames, targets, avoid, radius, joints),
            Finger::Thumb => self.solve_chain(&self.th, frames, targets, avoid, radius, joints),
        }
    }

    fn radius(&self, finger: Finger) -> f64 {
        if finger == Finger::Thumb {
            self.settings.thumb_radius_m
        } else {
            self.settings.finger_radius_m
        }
    }

    fn solve_chain<const N: usize>(
        &self,
        solver: &Solver<N>,
        frames: FingerFrames,
        targets: &Targets,
        avoid: Option<Vec<Capsule>>,
        radius: f64,
        joints: &mut [f64; SHADOW_FINGER_DOF],
    ) {
        let w = self.settings.weights;
        let mut goals: Vec<Goal<N>> = vec![
            Goal::Position {
                target: targets.tip,
                weight: w.tip,
            },
            Goal::FramePosition {
                frame: frames.pip,
                offset: Vector3::zeros(),
                target: targets.pip,
                weight: w.pip,
            },
            Goal::FrameDirection {
                frame: frames.proximal,
                axis: Vector3::z_axis(),
                direction: targets.proximal,
                weight: w.direction,
            },
        ];
        if let Some(distal) = frames.distal {
            goals.push(Goal::FrameDirection {
                frame: distal,
                axis: Vector3::z_axis(),
                direction: targets.distal,
                weight: w.direction,
            });
        }
        let collision_resolve = avoid.is_some();
        if let Some(others) = avoid {
            goals.push(Goal::MinDistance {
                constraint: Arc::new(Clearance {
                    segments: own_segments::<N>(frames, radius),
                    others,
                }),
                min_distance_m: 0.0,
                weight: w.collision,
            });
        }
        let start: SVector<f64, N> = SVector::from_fn(|k, _| joints[frames.offset + k]);
        let result = solver.solve_tracking(&goals, &start);
        let mut best = match result {
            Ok(s) => s,
            Err(e) => *e.best,
        };
        let tip_error = (best.tip.translation.vector - targets.tip).norm();
        // Random restarts only for the free solve: a collision re-solve starts from the
        // finger's best free solution, which restarts would rarely beat.
        if !collision_resolve
            && tip_error > self.settings.restart_above_m
            && self.settings.restarts > 0
        {
            let budget = ColdBudget {
                max_restarts: self.settings.restarts,
                time_limit: None,
            };
            let seed = 0x5EED_0000 + frames.offset as u64;
            let cold = match solver.solve_cold(&goals, Some(&best.q), seed, budget) {
                Ok(s) => s,
                Err(e) => *e.best,
            };
            if cold.cost < best.cost {
                best = cold;
            }
        }
        for k in 0..N {
            joints[frames.offset + k] = best.q[k];
        }
    }

    /// Each finger's phalanx capsules (rh_palm frame) at `joints`.
    fn segments(&self, joints: &[f64; SHADOW_FINGER_DOF]) -> [[Capsule; 2]; 5] {
        let mut out = [[Capsule::default(); 2]; 5];
        for f in Finger::ALL {
            let i = f.index();
            let fr = FRAMES[i];
            let radius = self.radius(f);
            out[i] = match f {
                Finger::Index => chain_capsules(&self.ff, fr, radius, joints),
                Finger::Middle => chain_capsules(&self.mf, fr, radius, joints),
                Finger::Ring => chain_capsules(&self.rf, fr, radius, joints),
                Finger::Little => chain_capsules(&self.lf, fr, radius, joints),
                Finger::Thumb => chain_capsules(&self.th, fr, radius, joints),
            };
        }
        out
    }
}

/// A capsule: segment and radius.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Capsule {
    a: Point3<f64>,
    b: Point3<f64>,
    radius: f64,
}

/// Frame indices of a finger's two capsules: proximal (`proximal` frame origin to the
/// PIP frame origin) and middle+distal (PIP frame origin to the tip).
fn own_segments<const N: usize>(frames: FingerFrames, radius: f64) -> [(usize, usize, f64); 2] {
    [
        (frames.proximal, frames.pip, radius),
        (frames.pip, N, radius),
    ]
}

fn chain_capsules<const N: usize>(
    solver: &Solver<N>,
    frames: FingerFrames,
    radius: f64,
    joints: &[f64; SHADOW_FINGER_DOF],
) -> [Capsule; 2] {
    let q: Vec<f64> = (0..N).map(|k| joints[frames.offset + k]).collect();
    let mut buf = vec![Isometry3::identity(); N + 1];
    if solver.chain().chain().frames_into(&q, &mut buf).is_err() {
        return [Capsule::default(); 2];
    }
    own_segments::<N>(frames, radius).map(|(a, b, radius)| Capsule {
        a: Point3::from(buf[a].translation.vector),
        b: Point3::from(buf[b].translation.vector),
        radius,
    })
}

fn clearance_to_others(segments: &[[Capsule; 2]; 5], finger: usize) -> f64 {
    let mut best = f64::INFINITY;
    for (j, other) in segments.iter().enumerate() {
        if j == finger {
            continue;
        }
        for a in &segments[finger] {
            for b in other {
                best = best.min(capsule_clearance(a, b));
            }
        }
    }
    best
}

fn capsule_clearance(a: &Capsule, b: &Capsule) -> f64 {
    segment_distance(&a.a, &a.b, &b.a, &b.b) - a.radius - b.radius
}

/// Minimum-distance goal of one finger against the other fingers' capsules.
struct Clearance {
    segments: [(usize, usize, f64); 2],
    others: Vec<Capsule>,
}

impl<const N: usize> DistanceConstraint<N> for Clearance {
    fn distance(&self, frames: &[Isometry3<f64>]) -> f64 {
        let mut best = f64::INFINITY;
        for (a, b, radius) in self.segments {
            let (Some(fa), Some(fb)) = (frames.get(a), frames.get(b)) else {
                continue;
            };
            let own = Capsule {
                a: Point3::from(fa.translation.vector),
                b: Point3::from(fb.translation.vector),
                radius,
            };
            for other in &self.others {
                best = best.min(capsule_clearance(&own, other));
            }
        }
        best
    }
}

pub use teleop_collision::segments::segment_distance;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_distance_matches_simple_cases() {
        let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
        // Parallel segments 1 apart.
        assert!(
            (segment_distance(
                &p(0., 0., 0.),
                &p(1., 0., 0.),
                &p(0., 1., 0.),
                &p(1., 1., 0.)
            ) - 1.0)
                .abs()
                < 1e-12
        );
        // Crossing segments at distance 0.5 in z.
        assert!(
            (segment_distance(
                &p(-1., 0., 0.),
                &p(1., 0., 0.),
                &p(0., -1., 0.5),
                &p(0., 1., 0.5)
            ) - 0.5)
                .abs()
                < 1e-12
        );
        // End to end along a line.
        assert!(
            (segment_distance(
                &p(0., 0., 0.),
                &p(1., 0., 0.),
                &p(3., 0., 0.),
                &p(4., 0., 0.)
            ) - 2.0)
                .abs()
                < 1e-12
        );
        // Degenerate: points.
        assert!(
            (segment_distance(
                &p(0., 0., 0.),
                &p(0., 0., 0.),
                &p(0., 3., 4.),
                &p(0., 3., 4.)
            ) - 5.0)
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn the_robot_keypoints_match_the_urdf() {
        let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
        let kp = r.shadow_keypoints(&[0.0; SHADOW_FINGER_DOF]);
        // FF knuckle at (0.033, 0, 0.095) in rh_palm; proximal 45 mm, middle 25 mm.
        let [mcp, pip, dip, _] = kp.finger(Finger::Index);
        assert!((mcp - Point3::new(0.033, 0.0, 0.095)).norm() < 1e-9);
        assert!(((pip - mcp).norm() - 0.045).abs() < 1e-9);
        assert!(((dip - pip).norm() - 0.025).abs() < 1e-9);
        // The registration frame of the robot sits at the palm origin.
        assert!(r.robot_palm_frame().translation.vector.norm() < 1e-12);
    }
}
