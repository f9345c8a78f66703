//! The simulated operator's tasks (thesis ch. 6-7): scripted, repeatable motions of the
//! wrist and the fingers, with the pedals pressed as a person would.
//!
//! A task is a list of keyframes: an offset of the hand from its resting place (m, in
//! the UR5 base frame's axes, the frame the thesis plots its trajectories in), a
//! rotation of the hand about its own axes (deg, hand frame of Fig. 3.6: z along the
//! fingers, y the palm normal), and a grasp (a synergy at a closure). Between keyframes
//! the hand moves either with a minimum-jerk profile (reaching, grasping, pouring: how
//! people move between rest points) or at constant speed with sharp corners (the fader
//! task's straight lines and the precision trajectory of Fig. 7.12).

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use teleop_hand_model::human::HumanPose;
use teleop_hand_model::sampling::Synergy;

/// The tasks the simulated operator performs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskKind {
    /// Reach, power-grasp, lift, carry 25 cm sideways, put down, release, return.
    #[default]
    PickAndPlace,
    /// Grasp, lift, turn the hand 90 deg about the forearm, hold, turn back, put down.
    Pouring,
    /// Open hand sweeping side to side over a table, three strokes.
    Sweeping,
    /// Pinch grip sliding a fader: straight lines with sharp corners (a 20 x 10 cm
    /// rectangle at constant speed).
    Fader,
    /// A 45 s path with sharp corners in all three axes, shaped like the trajectory of
    /// thesis Fig. 7.12 (the exact path is ours).
    Precision,
}

impl TaskKind {
    /// Every task.
    pub const ALL: [TaskKind; 5] = [
        TaskKind::PickAndPlace,
        TaskKind::Pouring,
        TaskKind::Sweeping,
        TaskKind::Fader,
        TaskKind::Precision,
    ];

    /// The name used in configs and reports.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            TaskKind::PickAndPlace => "pick_and_place",
            TaskKind::Pouring => "pouring",
            TaskKind::Sweeping => "sweeping",
            TaskKind::Fader => "fader",
            TaskKind::Precision => "precision",
        }
    }
}

/// How the hand moves between two keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// Minimum-jerk: starts and ends at rest.
    MinJerk,
    /// Constant speed: the velocity turns at once at a keyframe (sharp corners).
    Linear,
}

/// A grasp: `closure` of the way from the open hand to `synergy`'s posture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grasp {
    pub synergy: Synergy,
    /// 0 = open hand, 1 = the synergy's full posture.
    pub closure: f64,
}

impl Grasp {
    const OPEN: Grasp = Grasp {
        synergy: Synergy::Open,
        closure: 0.0,
    };

    const fn power(closure: f64) -> Self {
        Grasp {
            synergy: Synergy::Power,
            closure,
        }
    }

    /// The finger posture.
    #[must_use]
    pub fn posture(&self) -> HumanPose {
        Synergy::Open
            .posture()
            .lerp(&self.synergy.posture(), self.closure.clamp(0.0, 1.0))
    }
}

/// One keyframe of a task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Time from the task's start, s.
    pub t_s: f64,
    /// Offset of the hand from its resting place, UR5 base axes, m.
    pub offset_m: [f64; 3],
    /// Rotation of the hand from its resting orientation, about its own x, y, z, deg.
    pub rotation_deg: [f64; 3],
    pub grasp: Grasp,
}

const fn key(t_s: f64, offset_m: [f64; 3], rotation_deg: [f64; 3], grasp: Grasp) -> Keyframe {
    Keyframe {
        t_s,
        offset_m,
        rotation_deg,
        grasp,
    }
}

/// What the operator does at one instant of a task.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskSample {
    /// Offset of the hand from its resting place, UR5 base axes, m.
    pub offset_m: Vector3<f64>,
    /// Rotation of the hand from its resting orientation (hand frame).
    pub rotation: UnitQuaternion<f64>,
    /// Finger posture.
    pub posture: HumanPose,
    /// Whether the task is under way (after its start and before its end): the
    /// operator holds the clutch pedal.
    pub under_way: bool,
}

/// A task as keyframes.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskScript {
    kind: TaskKind,
    frames: Vec<Keyframe>,
    profile: Profile,
}

impl TaskScript {
    /// The script of `kind`.
    #[must_use]
    pub fn new(kind: TaskKind) -> Self {
        let o = [0.0; 3];
        let (frames, profile) = match kind {
            TaskKind::PickAndPlace => (
                vec![
                    key(0.0, o, o, Grasp::OPEN),
                    key(2.0, [0.08, 0.0, -0.10], o, Grasp::OPEN),
                    key(3.0, [0.08, 0.0, -0.10], o, Grasp::power(0.8)),
                    key(4.5, [0.08, 0.0, 0.0], o, Grasp::power(0.8)),
                    key(7.0, [0.08, 0.25, 0.0], o, Grasp::power(0.8)),
                    key(8.5, [0.08, 0.25, -0.10], o, Grasp::power(0.8)),
                    key(9.5, [0.08, 0.25, -0.10], o, Grasp::OPEN),
                    key(11.0, [0.08, 0.25, 0.0], o, Grasp::OPEN),
                    key(13.5, o, o, Grasp::OPEN),
                ],
                Profile::MinJerk,
            ),
            // The turn takes 6.5 s each way: the camera, 40 cm from the hand along the
            // palm normal, orbits a quarter circle (0.63 m) as the hand turns, and its
            // 0.2 m/s limit needs at least 1.875 x 0.63 / 0.2 = 5.9 s for that on a
            // minimum-jerk profile (a faster pour leaves the camera behind and the
            // hand out of view).
            TaskKind::Pouring => (
                vec![
                    key(0.0, o, o, Grasp::OPEN),
                    key(1.0, o, o, Grasp::power(0.8)),
                    key(2.5, [0.0, 0.0, 0.08], o, Grasp::power(0.8)),
                    key(9.0, [0.0, 0.0, 0.08], [0.0, 0.0, 90.0], Grasp::power(0.8)),
                    key(10.0, [0.0, 0.0, 0.08], [0.0, 0.0, 90.0], Grasp::power(0.8)),
                    key(16.5, [0.0, 0.0, 0.08], o, Grasp::power(0.8)),
                    key(18.0, o, o, Grasp::power(0.8)),
                    key(19.0, o, o, Grasp::OPEN),
                ],
                Profile::MinJerk,
            ),
            TaskKind::Sweeping => {
                let open = Grasp {
                    synergy: Synergy::Power,
                    closure: 0.15,
                };
                // 30 cm strokes in 3.2 s: 0.18 m/s at the fastest (minimum jerk), under
                // the arms' 0.2 m/s Cartesian limit.
                let mut frames = vec![key(0.0, o, o, Grasp::OPEN), key(1.0, o, o, open)];
                for (i, y) in [0.15, -0.15, 0.15, -0.15, 0.0].into_iter().enumerate() {
                    let t = 2.5 + 3.2 * i as f64;
                    frames.push(key(t, [0.0, y, -0.04], [0.0, 10.0 * y.signum(), 0.0], open));
                }
                frames.push(key(17.0, o, o, Grasp::OPEN));
                (frames, Profile::MinJerk)
            }
            TaskKind::Fader => {
                let pinch = Grasp {
                    synergy: Synergy::Pinch,
                    closure: 0.9,
                };
                // A 20 x 10 cm rectangle at 0.05 m/s: 4 + 2 s per long / short side.
                let corners: [[f64; 2]; 5] = [
                    [-0.10, -0.05],
                    [0.10, -0.05],
                    [0.10, 0.05],
                    [-0.10, 0.05],
                    [-0.10, -0.05],
                ];
                let mut frames = vec![
                    key(0.0, o, o, Grasp::OPEN),
                    key(1.0, o, o, pinch),
                    key(2.0, [-0.10, -0.05, 0.0], o, pinch),
                ];
                let mut t = 2.0;
                for w in corners.windows(2) {
                    let d = ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2)).sqrt();
                    t += d / 0.05;
                    frames.push(key(t, [w[1][0], w[1][1], 0.0], o, pinch));
                }
                frames.push(key(t + 1.0, o, o, pinch));
                frames.push(key(t + 2.0, o, o, Grasp::OPEN));
                (frames, Profile::Linear)
            }
            TaskKind::Precision => {
                let pinch = Grasp {
                    synergy: Synergy::Precision,
                    closure: 0.6,
                };
                // Corners (m) visited at constant speed; about 45 s in all.
                let path = [
                    [0.0, 0.0, 0.0],
                    [0.12, 0.0, 0.0],
                    [0.12, 0.15, 0.0],
                    [0.12, 0.15, 0.10],
                    [-0.05, 0.15, 0.10],
                    [-0.05, -0.15, 0.10],
                    [-0.05, -0.15, -0.05],
                    [0.10, -0.15, -0.05],
                    [0.10, 0.0, 0.05],
                    [0.0, 0.0, 0.0],
                ];
                let mut frames = vec![key(0.0, o, o, pinch)];
                let mut t = 1.0;
                frames.push(key(t, path[0], o, pinch));
                for w in path.windows(2) {
                    let d = Vector3::from(w[1]) - Vector3::from(w[0]);
                    t += d.norm() / 0.04;
                    frames.push(key(t, w[1], o, pinch));
                }
                (frames, Profile::Linear)
            }
        };
        Self {
            kind,
            frames,
            profile,
        }
    }

    /// Which task.
    #[must_use]
    pub fn kind(&self) -> TaskKind {
        self.kind
    }

    /// The keyframes.
    #[must_use]
    pub fn keyframes(&self) -> &[Keyframe] {
        &self.frames
    }

    /// How the hand moves between keyframes.
    #[must_use]
    pub fn profile(&self) -> Profile {
        self.profile
    }

    /// Length of the task, s.
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.frames.last().map_or(0.0, |f| f.t_s)
    }

    /// The operator at `t_s` from the task's start (before it: the first keyframe;
    /// after it: the last one).
    #[must_use]
    pub fn sample(&self, t_s: f64) -> TaskSample {
        let under_way = t_s >= 0.0 && t_s < self.duration_s();
        let frames = &self.frames;
        let at = |f: &Keyframe| TaskSample {
            offset_m: Vector3::from(f.offset_m),
            rotation: rotation(f),
            posture: f.grasp.posture(),
            under_way,
        };
        let (Some(first), Some(last)) = (frames.first(), frames.last()) else {
            return TaskSample {
                offset_m: Vector3::zeros(),
                rotation: UnitQuaternion::identity(),
                posture: Grasp::OPEN.posture(),
                under_way: false,
            };
        };
        if t_s <= first.t_s {
            return at(first);
        }
        if t_s >= last.t_s {
            return at(last);
        }
        let i = frames
            .windows(2)
            .position(|w| t_s < w[1].t_s)
            .unwrap_or(frames.len() - 2);
        let (a, b) = (&frames[i], &frames[i + 1]);
        let s = ((t_s - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
        let w = match self.profile {
            Profile::Linear => s,
            Profile::MinJerk => s * s * s * (10.0 - 15.0 * s + 6.0 * s * s),
        };
        let offset = Vector3::from(a.offset_m).lerp(&Vector3::from(b.offset_m), w);
        let rot = rotation(a).slerp(&rotation(b), w);
        TaskSample {
            offset_m: offset,
            rotation: rot,
            posture: a.grasp.posture().lerp(&b.grasp.posture(), w),
            under_way,
        }
    }
}

fn rotation(f: &Keyframe) -> UnitQuaternion<f64> {
    let [r, p, y] = f.rotation_deg.map(f64::to_radians);
    UnitQuaternion::from_euler_angles(r, p, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_task_starts_and_ends_at_rest_and_is_continuous() {
        for kind in TaskKind::ALL {
            let script = TaskScript::new(kind);
            let d = script.duration_s();
            assert!(d > 5.0 && d < 60.0, "{}: {d} s", kind.name());
            let start = script.sample(0.0);
            let end = script.sample(d + 1.0);
            assert!(start.offset_m.norm() < 1e-12, "{}", kind.name());
            assert!(end.offset_m.norm() < 1e-12, "{}", kind.name());
            assert!(!end.under_way);
            // Continuous: no step between samples 10 ms apart faster than 0.5 m/s.
            let mut prev = script.sample(0.0);
            let mut t = 0.0;
            while t < d {
                t += 0.01;
                let s = script.sample(t);
                let v = (s.offset_m - prev.offset_m).norm() / 0.01;
                assert!(v < 0.5, "{} at {t:.2} s: {v} m/s", kind.name());
                assert!(s.rotation.angle_to(&prev.rotation) < 0.05);
                prev = s;
            }
        }
    }

    #[test]
    fn pouring_turns_the_hand_90_deg_about_the_fingers() {
        let s = TaskScript::new(TaskKind::Pouring).sample(9.5);
        let axis_angle = s.rotation.axis_angle().expect("rotated");
        assert!((axis_angle.1 - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!((axis_angle.0.into_inner() - Vector3::z()).norm() < 1e-9);
    }

    /// Every task stays within what the arms may do (their Cartesian limit 0.2 m/s):
    /// the hand itself, and the camera's goal 40 cm along the palm normal.
    #[test]
    fn no_task_asks_the_arms_for_more_than_their_speed_limit() {
        for kind in TaskKind::ALL {
            let script = TaskScript::new(kind);
            let dt = 0.01;
            let goal = |t: f64| {
                let s = script.sample(t);
                s.offset_m + s.rotation * Vector3::new(0.0, 0.4, 0.08)
            };
            let mut t = 0.0;
            while t + dt <= script.duration_s() {
                let a = script.sample(t);
                let b = script.sample(t + dt);
                let hand = (b.offset_m - a.offset_m).norm() / dt;
                let camera = (goal(t + dt) - goal(t)).norm() / dt;
                assert!(hand < 0.2, "{} at {t:.2} s: hand {hand} m/s", kind.name());
                assert!(
                    camera < 0.2,
                    "{} at {t:.2} s: camera goal {camera} m/s",
                    kind.name()
                );
                t += dt;
            }
        }
    }

    #[test]
    fn fader_has_sharp_corners_at_constant_speed() {
        let script = TaskScript::new(TaskKind::Fader);
        assert_eq!(script.profile(), Profile::Linear);
        // The first corner after the start of the rectangle at 2 s is at 6 s.
        let before = script.sample(5.99).offset_m - script.sample(5.98).offset_m;
        let after = script.sample(6.02).offset_m - script.sample(6.01).offset_m;
        assert!(before.normalize().dot(&after.normalize()).abs() < 1e-6);
        assert!((before.norm() / 0.01 - 0.05).abs() < 1e-6);
    }

    #[test]
    fn the_grasp_closes_and_opens() {
        let script = TaskScript::new(TaskKind::PickAndPlace);
        let open = script.sample(0.0).posture;
        let closed = script.sample(5.0).posture;
        let flexion: f64 = closed
            .q
            .iter()
            .zip(open.q)
            .map(|(c, o)| (c - o).abs())
            .sum();
        assert!(flexion > 1.0, "power grasp closes the fingers: {flexion}");
        assert_eq!(script.sample(20.0).posture, open);
    }
}
