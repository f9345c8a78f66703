//! The arm controller's clutch semantics and every watchdog path, on an ideal velocity
//! plant (the joints move exactly as commanded).
#![allow(clippy::unwrap_used)]

use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3};
use teleop_kinematics::robots;
use teleop_remote_site::arm_controller::Pr2ArmState;
use teleop_remote_site::arm_controller::{
    ArmController, ArmControllerConfig, ArmInputs, OperatorSample, RelativeFrame, StopReason,
    WristSample,
};

const DT: f64 = 1.0 / 30.0;

fn q_start() -> SVector<f64, 7> {
    SVector::from_column_slice(&[-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1])
}

struct Rig {
    ctrl: ArmController,
    q: SVector<f64, 7>,
    t: f64,
    clutch: bool,
    enable: bool,
    scale: f64,
    alive: bool,
    hand_alive: bool,
    wrist: Isometry3<f64>,
    send_wrist: bool,
    last_wrist: Option<WristSample>,
    conflict: bool,
    dt: f64,
}

impl Rig {
    fn new() -> Self {
        Self::with(ArmControllerConfig::default())
    }

    /// A rig whose controller has heard the operator's pedals released once (as at any
    /// start: the operator has not pressed yet), so a clutch press engages.
    fn with(config: ArmControllerConfig) -> Self {
        let mut r = Self::started_held(config);
        r.clutch = false;
        let released = r.step_at(0.0);
        assert_eq!(released.stopped, Some(StopReason::ClutchReleased));
        r
    }

    /// A rig whose controller has heard nothing yet.
    fn started_held(config: ArmControllerConfig) -> Self {
        let ctrl = ArmController::new(robots::pr2_arm_chain().unwrap(), config).unwrap();
        Self {
            ctrl,
            q: q_start(),
            t: 0.0,
            clutch: false,
            enable: true,
            scale: 1.0,
            alive: true,
            hand_alive: true,
            wrist: Isometry3::from_parts(
                Translation3::new(0.4, -0.2, 1.0),
                UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
            ),
            send_wrist: true,
            last_wrist: None,
            conflict: false,
            dt: DT,
        }
    }

    fn palm(&self) -> Isometry3<f64> {
        self.ctrl.chain().end_pose(&self.q)
    }

    /// One control period: inputs arrive, the controller steps, the ideal arm moves.
    fn step(&mut self) -> teleop_remote_site::arm_controller::ArmStep {
        self.t += self.dt;
        self.step_at(self.t)
    }

    fn step_at(&mut self, t: f64) -> teleop_remote_site::arm_controller::ArmStep {
        self.t = t;
        if self.send_wrist {
            self.last_wrist = Some(WristSample {
                received_s: self.t,
                pose: self.wrist,
            });
        }
        let inputs = ArmInputs {
            operator: Some(OperatorSample {
                received_s: self.t,
                clutch: self.clutch,
                enable: self.enable,
                motion_scale: self.scale,
            }),
            wrist: self.last_wrist,
            operator_site_alive: self.alive,
            hand_alive: self.hand_alive,
            commander_conflict: self.conflict,
        };
        let state = Pr2ArmState {
            time_s: self.t,
            position_rad: self.q,
            velocity_rad_s: SVector::zeros(),
        };
        let out = self.ctrl.step(self.t, &inputs, &state);
        self.q += out.command.velocity_rad_s * self.dt;
        out
    }

    fn moving(&mut self) -> bool {
        let out = self.step();
        out.command.velocity_rad_s.norm() > 0.0
    }
}

#[test]
fn a_controller_started_with_the_clutch_held_waits_for_a_fresh_press() {
    // A controller process (re)started while the operator holds the clutch and the
    // switch: it does not take the held pedals for a press.
    let mut r = Rig::started_held(ArmControllerConfig::default());
    r.clutch = true;
    for _ in 0..15 {
        r.wrist.translation.vector.x += 0.005;
        let out = r.step();
        assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
        assert_eq!(out.stopped, Some(StopReason::AwaitingClutchRelease));
    }
    assert!(!r.ctrl.is_engaged());
    assert_eq!(r.ctrl.latched(), None, "waiting for a press is not a fault");
    // The operator lets go, then presses: it engages and follows.
    r.clutch = false;
    assert_eq!(r.step().stopped, Some(StopReason::ClutchReleased));
    r.clutch = true;
    assert_eq!(r.step().stopped, None);
    assert!(r.ctrl.is_engaged());
    assert_eq!(r.ctrl.counters().engagements, 1);
}

#[test]
fn arm_moves_only_with_clutch_and_enable() {
    let mut r = Rig::new();
    for _ in 0..10 {
        r.wrist.translation.vector.x += 0.005;
        let out = r.step();
        assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
        assert_eq!(out.stopped, Some(StopReason::ClutchReleased));
    }
    r.clutch = true;
    r.enable = false;
    r.wrist.translation.vector.x += 0.005;
    assert_eq!(r.step().stopped, Some(StopReason::EnableReleased));
}

#[test]
fn wrist_frame_mode_copies_the_motion_scaled_in_the_robot_wrist_frame() {
    let mut r = Rig::with(ArmControllerConfig {
        frame: RelativeFrame::Wrist,
        ..ArmControllerConfig::default()
    });
    r.clutch = true;
    r.scale = 1.0 / 3.0;
    r.step(); // engage
    let robot_ref = r.palm();
    let human_ref = r.wrist;
    // The operator moves 9 cm along its own wrist x axis, and turns 20 deg about z.
    for k in 1..=60 {
        let f = f64::from(k) / 60.0;
        r.wrist = human_ref
            * Isometry3::from_parts(
                Translation3::new(0.09 * f, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 20f64.to_radians() * f),
            );
        r.step();
    }
    for _ in 0..90 {
        r.step();
    }
    let expected = robot_ref
        * Isometry3::from_parts(
            Translation3::new(0.03, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 20f64.to_radians()),
        );
    let got = r.palm();
    let dp = (got.translation.vector - expected.translation.vector).norm();
    let da = (got.rotation * expected.rotation.inverse())
        .angle()
        .to_degrees();
    assert!(dp < 0.002, "position error {dp} m");
    assert!(da < 0.5, "orientation error {da} deg");
}

#[test]
fn releasing_the_clutch_stops_at_once_and_reengaging_recentres() {
    let mut r = Rig::new();
    r.clutch = true;
    r.step();
    for _ in 0..15 {
        r.wrist.translation.vector.y += 0.004;
        assert!(r.moving() || r.ctrl.is_engaged());
    }
    r.clutch = false;
    let out = r.step();
    assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
    assert!(!r.ctrl.is_engaged());
    // The operator re-centres with the clutch released: the robot does not move.
    let palm = r.palm();
    for _ in 0..20 {
        r.wrist.translation.vector.y -= 0.01;
        r.step();
    }
    assert_eq!(r.palm(), palm);
    // Re-engaging starts from the new poses: no jump toward the old reference.
    r.clutch = true;
    let out = r.step();
    assert!(r.ctrl.is_engaged());
    assert!(
        out.command.velocity_rad_s.norm() < 1e-6,
        "{}",
        out.command.velocity_rad_s.norm()
    );
}

/// Engages and moves for a while, so the arm is moving when the fault happens.
fn engaged_and_moving() -> Rig {
    let mut r = Rig::new();
    r.clutch = true;
    r.step();
    for _ in 0..10 {
        r.wrist.translation.vector.z += 0.004;
        r.step();
    }
    assert!(r.ctrl.is_engaged());
    r
}

#[test]
fn stale_wrist_pose_stops_within_one_period_after_the_deadline() {
    let mut r = engaged_and_moving();
    r.send_wrist = false;
    // 100 ms deadline at 30 Hz: steps at +33, +67, +100 ms may still move; +133 ms stops.
    let mut stopped_at = None;
    for k in 1..=6 {
        let out = r.step();
        if out.stopped.is_some() {
            assert_eq!(out.stopped, Some(StopReason::StaleWristPose));
            assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
            stopped_at = Some(k);
            break;
        }
    }
    let k = stopped_at.expect("arm never stopped");
    assert!(
        f64::from(k) * DT <= 0.1 + DT + 1e-9,
        "stopped after {k} periods"
    );
    // Poses come back, but a safety stop needs a fresh clutch press.
    r.send_wrist = true;
    for _ in 0..5 {
        assert_eq!(r.step().stopped, Some(StopReason::AwaitingClutchRelease));
    }
    r.clutch = false;
    r.step();
    r.clutch = true;
    r.step();
    assert!(r.ctrl.is_engaged());
}

#[test]
fn enable_released_and_site_lost_stop_in_the_same_period() {
    let mut r = engaged_and_moving();
    r.enable = false;
    let out = r.step();
    assert_eq!(out.stopped, Some(StopReason::EnableReleased));
    assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());

    let mut r = engaged_and_moving();
    r.alive = false;
    let out = r.step();
    assert_eq!(out.stopped, Some(StopReason::OperatorSiteLost));
    assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
    // Site back, clutch still held: stays stopped until a fresh press.
    r.alive = true;
    assert_eq!(r.step().stopped, Some(StopReason::AwaitingClutchRelease));
}

#[test]
fn a_lost_hand_controller_stops_the_arm_until_a_fresh_press() {
    // The hand on the arm has nobody controlling it: the arm stops in the same period,
    // and stays stopped after the controller is back until the operator presses again.
    let mut r = engaged_and_moving();
    r.hand_alive = false;
    let out = r.step();
    assert_eq!(out.stopped, Some(StopReason::HandNodeLost));
    assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
    assert_eq!(r.ctrl.latched(), Some(StopReason::HandNodeLost));
    r.hand_alive = true;
    for _ in 0..5 {
        r.wrist.translation.vector.x += 0.005;
        assert_eq!(r.step().stopped, Some(StopReason::AwaitingClutchRelease));
    }
    r.clutch = false;
    r.step();
    r.clutch = true;
    r.step();
    assert!(r.ctrl.is_engaged(), "a fresh press engages again");
    // Without a hand controller the arm does not engage either (nothing latches).
    let mut r = engaged_and_moving();
    r.clutch = false;
    r.step();
    r.hand_alive = false;
    r.clutch = true;
    assert_eq!(r.step().stopped, Some(StopReason::HandNodeLost));
    assert!(!r.ctrl.is_engaged());
    assert_eq!(r.ctrl.latched(), None);
    r.hand_alive = true;
    r.step();
    assert!(
        r.ctrl.is_engaged(),
        "the press held while the hand came back engages"
    );
}

#[test]
fn nan_and_jumping_poses_are_rejected_and_counted() {
    let mut r = engaged_and_moving();
    let palm = r.palm();
    // A NaN pose, then a 60 cm jump: neither moves the target; the deadline then stops.
    r.wrist.translation.vector.x = f64::NAN;
    r.step();
    r.wrist.translation.vector.x = 10.0;
    r.step();
    let mut stopped = false;
    for _ in 0..5 {
        if r.step().stopped == Some(StopReason::StaleWristPose) {
            stopped = true;
            break;
        }
    }
    assert!(stopped, "rejected poses must not keep the arm alive");
    let names = r.ctrl.named_counters();
    let get = |n: &str| names.iter().find(|(k, _)| k == n).map(|(_, v)| *v).unwrap();
    assert!(get("wrist_pose.rejected_by_controller") >= 3);
    assert!(get("wrist_pose.rejected_non_finite") >= 1);
    assert!(get("wrist_pose.rejected_position_jump") >= 1);
    // The arm drifted at most what the limiter allowed before the rejections.
    assert!((r.palm().translation.vector - palm.translation.vector).norm() < 0.05);
}

#[test]
fn invalid_motion_scale_and_arm_state_stop() {
    let mut r = engaged_and_moving();
    r.scale = f64::NAN;
    let out = r.step();
    assert_eq!(out.stopped, Some(StopReason::InvalidMotionScale));
    let mut r = engaged_and_moving();
    r.scale = 3.0;
    assert_eq!(r.step().stopped, Some(StopReason::InvalidMotionScale));
    let mut r = engaged_and_moving();
    r.q[3] = f64::NAN;
    let out = r.step();
    assert_eq!(out.stopped, Some(StopReason::InvalidArmState));
    assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
}

#[test]
fn commands_respect_joint_velocity_limits_on_large_motions() {
    let mut r = Rig::new();
    r.clutch = true;
    r.step();
    let limits = r.ctrl.chain().velocity_limits();
    for _ in 0..60 {
        r.wrist.translation.vector += Vector3::new(0.01, -0.01, 0.01);
        let out = r.step();
        for i in 0..7 {
            assert!(out.command.velocity_rad_s[i].abs() <= limits[i] + 1e-9);
        }
    }
}

/// Engages with the operator's hand turned 90 deg about z against the robot palm, moves
/// the hand 6 cm along the tracker's x axis and turns it 15 deg about the tracker's z:
/// base-aligned (default), the palm moves along the robot base's x and turns about the
/// base's z, whatever the hand's orientation; in wrist mode the same motion goes
/// elsewhere.
#[test]
fn base_aligned_mode_moves_along_the_base_axes_whatever_the_hand_orientation() {
    let run = |frame: RelativeFrame| {
        let mut r = Rig::with(ArmControllerConfig {
            frame,
            ..ArmControllerConfig::default()
        });
        // The palm's orientation at engage; the hand turned 90 deg against it.
        let palm0 = r.palm();
        r.wrist = Isometry3::from_parts(
            Translation3::new(0.4, -0.2, 1.0),
            palm0.rotation * UnitQuaternion::from_euler_angles(0.0, 0.0, 90f64.to_radians()),
        );
        r.clutch = true;
        r.step();
        let robot_ref = r.palm();
        let human_ref = r.wrist;
        for k in 1..=60 {
            let f = f64::from(k) / 60.0;
            r.wrist = Isometry3::from_parts(
                Translation3::from(human_ref.translation.vector + Vector3::new(0.06 * f, 0.0, 0.0)),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 15f64.to_radians() * f)
                    * human_ref.rotation,
            );
            r.step();
        }
        for _ in 0..90 {
            r.step();
        }
        (robot_ref, r.palm())
    };
    let (robot_ref, got) = run(RelativeFrame::BaseAligned);
    let moved = got.translation.vector - robot_ref.translation.vector;
    assert!(
        (moved - Vector3::new(0.06, 0.0, 0.0)).norm() < 0.002,
        "base-aligned palm moved {moved:?}"
    );
    let turned = got.rotation * robot_ref.rotation.inverse();
    let expected = UnitQuaternion::from_euler_angles(0.0, 0.0, 15f64.to_radians());
    assert!(
        (turned * expected.inverse()).angle().to_degrees() < 0.5,
        "turned {turned:?}"
    );
    // The same hand motion in wrist mode is taken in the hand's frame and applied in
    // the palm's: the palm moves along R_palm R_hand^T dp, here the base x turned by
    // -90 deg about the palm's z — 6 cm away from where base-aligned goes.
    let (robot_ref, got) = run(RelativeFrame::Wrist);
    let moved = got.translation.vector - robot_ref.translation.vector;
    let hand_ref =
        robot_ref.rotation * UnitQuaternion::from_euler_angles(0.0, 0.0, 90f64.to_radians());
    let expected = robot_ref.rotation * (hand_ref.inverse() * Vector3::new(0.06, 0.0, 0.0));
    assert!(
        (moved - expected).norm() < 0.002,
        "wrist mode moved {moved:?}, expected {expected:?}"
    );
    assert!((moved - Vector3::new(0.06, 0.0, 0.0)).norm() > 0.05);
}

/// A skipped tick (twice the period) is measured: the commanded speed stays that of
/// the operator's motion, not twice it.
#[test]
fn a_skipped_tick_is_measured_not_assumed() {
    let mut regular = Rig::new();
    let mut skipping = Rig::new();
    for r in [&mut regular, &mut skipping] {
        r.clutch = true;
        r.step();
    }
    // The operator moves at 3 cm/s along x; the second rig ticks at 15 Hz.
    skipping.dt = 2.0 * DT;
    for k in 0..30 {
        regular.wrist.translation.vector.x += 0.03 * DT;
        regular.step();
        if k % 2 == 1 {
            skipping.wrist.translation.vector.x += 0.03 * 2.0 * DT;
            skipping.step();
        }
    }
    let (a, b) = (regular.palm(), skipping.palm());
    // Both follow the 3 cm the operator moved (the slower loop lags a little more);
    // assuming the nominal period instead would double the skipping rig's speed.
    assert!(
        (a.translation.vector - b.translation.vector).norm() < 0.006,
        "{:?} vs {:?}",
        a.translation,
        b.translation
    );
}

/// Poses and pedals from different operator sites: no engagement, named.
#[test]
fn a_commander_conflict_blocks_engagement_but_not_an_engaged_arm() {
    let mut r = Rig::new();
    r.conflict = true;
    r.clutch = true;
    assert_eq!(r.step().stopped, Some(StopReason::CommanderConflict));
    assert!(!r.ctrl.is_engaged());
    r.conflict = false;
    r.step();
    assert!(r.ctrl.is_engaged());
    r.conflict = true;
    r.wrist.translation.vector.x += 0.01;
    assert_eq!(r.step().stopped, None);
}

/// The absolute mode's rig: the target in the torso frame, placed relative to the
/// palm's pose at the start.
fn absolute_rig(offset: Translation3<f64>) -> (Rig, Isometry3<f64>) {
    use teleop_remote_site::arm_controller::ArmMode;
    let cfg = ArmControllerConfig {
        mode: ArmMode::Absolute,
        ..ArmControllerConfig::default()
    };
    let base_from_torso = cfg.absolute.base_from_frame.isometry();
    let mut r = Rig::with(cfg);
    let palm_in_torso = base_from_torso.inverse() * r.palm();
    r.wrist = Isometry3::from_parts(offset, UnitQuaternion::identity()) * palm_in_torso;
    (r, base_from_torso)
}

#[test]
fn absolute_mode_follows_the_target_in_the_torso_frame_ignoring_the_motion_scale() {
    let (mut r, base_from_torso) = absolute_rig(Translation3::new(0.05, 0.0, 0.0));
    r.clutch = true;
    r.scale = 1.0 / 3.0; // not applied: the operator site scaled the target already
    let start = r.wrist;
    // The target moves 10 cm along the torso's y and turns 15 deg about its own z over
    // 2 s (0.05 m/s), then holds.
    for k in 1..=60 {
        let f = f64::from(k) / 60.0;
        r.wrist = Isometry3::from_parts(
            Translation3::new(0.0, -0.10 * f, 0.0),
            UnitQuaternion::identity(),
        ) * start
            * Isometry3::rotation(Vector3::z() * 15f64.to_radians() * f);
        let out = r.step();
        assert_eq!(out.stopped, None, "step {k}: {:?}", out.stopped);
    }
    for _ in 0..60 {
        r.step();
    }
    let want = base_from_torso * r.wrist;
    let got = r.palm();
    let dp = (got.translation.vector - want.translation.vector).norm();
    let da = got.rotation.angle_to(&want.rotation).to_degrees();
    assert!(dp < 0.003, "palm {dp} m from the absolute target");
    assert!(da < 2.0, "palm {da} deg from the absolute target");
    assert_eq!(r.ctrl.counters().engagements, 1);
}

#[test]
fn absolute_mode_engages_only_near_the_target_and_approaches_at_the_speed_limit() {
    // 30 cm away: the clutch does not engage, the arm holds, and says why.
    let (mut r, _) = absolute_rig(Translation3::new(0.0, 0.3, 0.0));
    r.clutch = true;
    for _ in 0..10 {
        let out = r.step();
        assert_eq!(out.stopped, Some(StopReason::TargetFarFromArm));
        assert_eq!(out.command.velocity_rad_s, SVector::<f64, 7>::zeros());
    }
    assert_eq!(r.ctrl.counters().engagements, 0);
    assert_eq!(r.ctrl.counters().safety_stops, 0, "not a safety stop");
    // 12 cm away (within 15 cm): it engages and goes there, its target moving no faster
    // than 0.2 m/s (the Cartesian limiter); the palm, pulled onto the IK solution by
    // the feedback term, within 15 % of that.
    let (mut r, base_from_torso) = absolute_rig(Translation3::new(0.0, 0.12, 0.0));
    r.clutch = true;
    let mut last = r.palm().translation.vector;
    let mut last_target: Option<Vector3<f64>> = None;
    let (mut fastest_palm, mut fastest_target): (f64, f64) = (0.0, 0.0);
    for _ in 0..90 {
        let out = r.step();
        assert_eq!(out.stopped, None);
        let target = out.target.unwrap().translation.vector;
        if let Some(t) = last_target {
            fastest_target = fastest_target.max((target - t).norm() / DT);
        }
        last_target = Some(target);
        let p = r.palm().translation.vector;
        fastest_palm = fastest_palm.max((p - last).norm() / DT);
        last = p;
    }
    let dp = (r.palm().translation.vector - (base_from_torso * r.wrist).translation.vector).norm();
    assert!(dp < 0.003, "palm {dp} m from the target after 3 s");
    assert!(
        fastest_target <= 0.2 + 1e-9,
        "target moved at {fastest_target} m/s"
    );
    assert!(
        fastest_target > 0.19,
        "the approach used {fastest_target} m/s only"
    );
    assert!(
        fastest_palm <= 0.2 * 1.15,
        "palm moved at {fastest_palm} m/s"
    );
}

#[test]
fn absolute_mode_keeps_the_watchdogs_and_the_jump_filter() {
    let (mut r, _) = absolute_rig(Translation3::new(0.02, 0.0, 0.0));
    r.clutch = true;
    r.step();
    assert!(r.ctrl.is_engaged());
    // A 70 cm jump of the target is refused: the arm does not go there.
    let before = r.palm();
    r.wrist.translation.vector.z += 0.7;
    for _ in 0..5 {
        r.step();
    }
    assert!((r.palm().translation.vector - before.translation.vector).norm() < 0.05);
    assert!(r.ctrl.counters().rejected_wrist_poses > 0);
    // ... and with no valid pose for longer than the deadline the arm stops and latches.
    for _ in 0..5 {
        r.step();
    }
    assert!(!r.ctrl.is_engaged());
    assert_eq!(r.ctrl.latched(), Some(StopReason::StaleWristPose));
    assert_eq!(r.step().command.velocity_rad_s, SVector::<f64, 7>::zeros());
    // The stream stopping is the same stale pose.
    let (mut r, _) = absolute_rig(Translation3::new(0.02, 0.0, 0.0));
    r.clutch = true;
    r.step();
    r.send_wrist = false;
    let stops: Vec<_> = (0..6).map(|_| r.step().stopped).collect();
    assert_eq!(stops.last(), Some(&Some(StopReason::AwaitingClutchRelease)));
    assert!(stops.contains(&Some(StopReason::StaleWristPose)));
}

#[test]
fn the_absolute_frame_default_is_the_models_torso() {
    let cfg = teleop_remote_site::arm_controller::AbsoluteConfig::default();
    let robot = robots::pr2_arm().unwrap();
    let torso = robot
        .chain(robots::pr2::BASE, robots::pr2::TORSO)
        .unwrap()
        .end_pose(&[])
        .unwrap();
    let ours = cfg.base_from_frame.isometry();
    assert!((torso.translation.vector - ours.translation.vector).norm() < 1e-9);
    assert!(torso.rotation.angle_to(&ours.rotation) < 1e-9);
    assert_eq!(cfg.frame_id, robots::pr2::TORSO);
}

/// The default frame: the hand's translation along the base's axes, its rotation about
/// its own axes applied about the palm's. A hand whose fingers point up turns 40 deg
/// about its fingers while moving 5 cm along the base's y: the palm moves 5 cm along y
/// and turns 40 deg about its own fingers (z), its fingers keeping their direction.
#[test]
fn default_frame_turns_the_palm_about_its_own_axes_and_moves_along_the_base() {
    assert_eq!(
        ArmControllerConfig::default().frame,
        RelativeFrame::BaseAlignedHandRotation
    );
    let mut r = Rig::new();
    r.wrist = Isometry3::from_parts(
        Translation3::new(-0.85, -0.1, 0.5),
        UnitQuaternion::from_euler_angles(0.0, 0.0, -90f64.to_radians()),
    );
    r.clutch = true;
    r.step();
    let robot_ref = r.palm();
    let human_ref = r.wrist;
    for k in 1..=60 {
        let f = f64::from(k) / 60.0;
        r.wrist = Isometry3::from_parts(
            Translation3::from(human_ref.translation.vector + Vector3::new(0.0, 0.05 * f, 0.0)),
            human_ref.rotation
                * UnitQuaternion::from_euler_angles(0.0, 0.0, 40f64.to_radians() * f),
        );
        r.step();
    }
    for _ in 0..90 {
        r.step();
    }
    let got = r.palm();
    let moved = got.translation.vector - robot_ref.translation.vector;
    assert!(
        (moved - Vector3::new(0.0, 0.05, 0.0)).norm() < 0.002,
        "palm moved {moved:?}"
    );
    let fingers_before = robot_ref.rotation * Vector3::z();
    let fingers_after = got.rotation * Vector3::z();
    assert!(fingers_before.angle(&fingers_after).to_degrees() < 0.5);
    let turned = robot_ref.rotation.inverse() * got.rotation;
    let expected = UnitQuaternion::from_euler_angles(0.0, 0.0, 40f64.to_radians());
    assert!(
        (turned * expected.inverse()).angle().to_degrees() < 0.5,
        "turned {turned:?}"
    );
}
