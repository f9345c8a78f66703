//! Conversions between the hardware types and bus messages (`JointState`,
//! `FingertipPressures`). Joints are matched by name, so a publisher may list them in any
//! order; missing joints, wrong lengths and non-finite values are errors naming the
//! joint and field.

use nalgebra::SVector;
use teleop_interfaces::joints::{FINGERTIPS, SHADOW_FINGER_JOINTS};
use teleop_msgs::{FingertipPressures, Header, JointCommand, JointState, Time};

use crate::{ArmCommand, ArmState, FINGER_DOF, HandCommand, HandImpedance, HandState};

/// Why a message could not be turned into a hardware value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum WireError {
    #[error("joint `{0}` is missing from the message")]
    MissingJoint(String),
    #[error("field `{field}` has {len} values for {names} names")]
    Length {
        field: &'static str,
        len: usize,
        names: usize,
    },
    #[error("joint `{joint}`: {field} is not finite")]
    NonFinite { joint: String, field: &'static str },
    #[error("joint `{joint}`: {field} is out of range")]
    OutOfRange { joint: String, field: &'static str },
    #[error("command mode `{0}` is none of effort, position, impedance")]
    UnknownMode(String),
}

impl WireError {
    /// Short name for counters.
    pub fn kind(&self) -> &'static str {
        match self {
            WireError::MissingJoint(_) => "missing_joint",
            WireError::Length { .. } => "length",
            WireError::NonFinite { .. } => "non_finite",
            WireError::OutOfRange { .. } => "out_of_range",
            WireError::UnknownMode(_) => "unknown_mode",
        }
    }
}

/// Which `JointState` field to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    Position,
    Velocity,
    Effort,
}

impl Field {
    fn name(self) -> &'static str {
        match self {
            Field::Position => "position",
            Field::Velocity => "velocity",
            Field::Effort => "effort",
        }
    }
}

/// Values of `field` for the joints `wanted`, by name.
///
/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn joint_vector<const N: usize>(
    msg: &JointState,
    wanted: &[&str; N],
    field: Field,
) -> Result<SVector<f64, N>, WireError> {
    let values = match field {
        Field::Position => &msg.position,
        Field::Velocity => &msg.velocity,
        Field::Effort => &msg.effort,
    };
    by_name(&msg.name, values, field.name(), wanted)
}

/// `values` (the field called `field`, one per name of `names`) for the joints
/// `wanted`, by name.
fn by_name<const N: usize>(
    names: &[String],
    values: &[f64],
    field: &'static str,
    wanted: &[&str; N],
) -> Result<SVector<f64, N>, WireError> {
    if values.len() != names.len() {
        return Err(WireError::Length {
            field,
            len: values.len(),
            names: names.len(),
        });
    }
    let mut out = SVector::<f64, N>::zeros();
    for (i, joint) in wanted.iter().enumerate() {
        let idx = names
            .iter()
            .position(|n| n == joint)
            .ok_or_else(|| WireError::MissingJoint((*joint).to_owned()))?;
        let v = values[idx];
        if !v.is_finite() {
            return Err(WireError::NonFinite {
                joint: (*joint).to_owned(),
                field,
            });
        }
        out[i] = v;
    }
    Ok(out)
}

fn names<const N: usize>(joints: &[&str; N]) -> Vec<String> {
    joints.iter().map(|s| (*s).to_owned()).collect()
}

fn stamp(time_s: f64) -> Header {
    Header::new(Time::from_secs_f64(time_s), "")
}

/// A pose message as an isometry, the quaternion taken as sent (not normalized): the
/// jump filters downstream refuse non-unit or non-finite ones by name, so a bad sample
/// is counted where it is judged instead of silently repaired here.
pub fn isometry(p: &teleop_msgs::Pose) -> nalgebra::Isometry3<f64> {
    let q = p.orientation;
    nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(p.position.x, p.position.y, p.position.z),
        nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z)),
    )
}

/// How far a pose message's quaternion norm may be off 1 where a person's motion
/// arrives over the network (`f32`-rounded senders, other ROS 2 clients): 1 %.
pub const POSE_QUATERNION_TOLERANCE: f64 = 0.01;

/// Why a pose message is not a pose.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PoseError {
    #[error("a component of the pose is not finite")]
    NonFinite,
    #[error("the orientation's quaternion has norm {norm}, not 1 within {tolerance}")]
    NotUnit { norm: f64, tolerance: f64 },
}

impl PoseError {
    /// Short name for counters.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            PoseError::NonFinite => "non_finite",
            PoseError::NotUnit { .. } => "not_unit",
        }
    }
}

/// A pose message as an isometry, checked: every component finite and the
/// quaternion's norm within `tolerance` of 1 (then normalized). The one conversion of
/// the nodes that act on a pose themselves (the wrist pose for the crop, the motion
/// capture marker, the report's camera and hand poses); the arm controllers take
/// [`isometry`] and let their jump filters judge.
///
/// # Errors
/// [`PoseError`] naming what was wrong.
pub fn checked_isometry(
    p: &teleop_msgs::Pose,
    tolerance: f64,
) -> Result<nalgebra::Isometry3<f64>, PoseError> {
    if !p.is_finite() {
        return Err(PoseError::NonFinite);
    }
    let o = &p.orientation;
    let q = nalgebra::Quaternion::new(o.w, o.x, o.y, o.z);
    let norm = q.norm();
    let within = (norm - 1.0).abs() <= tolerance; // false for a NaN tolerance
    if !within {
        return Err(PoseError::NotUnit { norm, tolerance });
    }
    Ok(nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(p.position.x, p.position.y, p.position.z),
        nalgebra::UnitQuaternion::from_quaternion(q),
    ))
}

/// An isometry as a pose message; `None` if any component is not finite.
pub fn pose_msg(pose: &nalgebra::Isometry3<f64>) -> Option<teleop_msgs::Pose> {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    let msg = teleop_msgs::Pose {
        position: teleop_msgs::Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: teleop_msgs::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    };
    msg.is_finite().then_some(msg)
}

/// An arm state as a `JointState` (positions and velocities).
pub fn arm_state_msg<const N: usize>(joints: &[&str; N], s: &ArmState<N>) -> JointState {
    JointState {
        header: stamp(s.time_s),
        name: names(joints),
        position: s.position_rad.iter().copied().collect(),
        velocity: s.velocity_rad_s.iter().copied().collect(),
        effort: vec![],
    }
}

/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn arm_state<const N: usize>(
    joints: &[&str; N],
    msg: &JointState,
) -> Result<ArmState<N>, WireError> {
    Ok(ArmState {
        time_s: msg.header.stamp.as_secs_f64(),
        position_rad: joint_vector(msg, joints, Field::Position)?,
        velocity_rad_s: joint_vector(msg, joints, Field::Velocity)?,
    })
}

/// An arm command as a `JointState` (velocities only).
pub fn arm_command_msg<const N: usize>(
    joints: &[&str; N],
    c: &ArmCommand<N>,
    time_s: f64,
) -> JointState {
    JointState {
        header: stamp(time_s),
        name: names(joints),
        position: vec![],
        velocity: c.velocity_rad_s.iter().copied().collect(),
        effort: vec![],
    }
}

/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn arm_command<const N: usize>(
    joints: &[&str; N],
    msg: &JointState,
) -> Result<ArmCommand<N>, WireError> {
    Ok(ArmCommand {
        velocity_rad_s: joint_vector(msg, joints, Field::Velocity)?,
    })
}

/// A hand state as a `JointState` (positions, velocities, efforts).
pub fn hand_state_msg(s: &HandState) -> JointState {
    JointState {
        header: stamp(s.time_s),
        name: names(&SHADOW_FINGER_JOINTS),
        position: s.position_rad.iter().copied().collect(),
        velocity: s.velocity_rad_s.iter().copied().collect(),
        effort: s.effort_nm.iter().copied().collect(),
    }
}

/// The fingertip forces of a hand state.
pub fn tactile_msg(s: &HandState) -> FingertipPressures {
    let f = s.fingertip_force_n;
    FingertipPressures {
        header: stamp(s.time_s),
        ff: f[0],
        mf: f[1],
        rf: f[2],
        lf: f[3],
        th: f[4],
    }
}

/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn hand_state(
    msg: &JointState,
    tactile: Option<&FingertipPressures>,
) -> Result<HandState, WireError> {
    let fingertip_force_n = match tactile {
        Some(t) => {
            let v = t.values();
            for (i, x) in v.iter().enumerate() {
                if !x.is_finite() {
                    return Err(WireError::NonFinite {
                        joint: FINGERTIPS[i].to_owned(),
                        field: "fingertip force",
                    });
                }
            }
            v
        }
        None => [0.0; 5],
    };
    Ok(HandState {
        time_s: msg.header.stamp.as_secs_f64(),
        position_rad: joint_vector(msg, &SHADOW_FINGER_JOINTS, Field::Position)?,
        velocity_rad_s: joint_vector(msg, &SHADOW_FINGER_JOINTS, Field::Velocity)?,
        effort_nm: joint_vector(msg, &SHADOW_FINGER_JOINTS, Field::Effort)?,
        fingertip_force_n,
    })
}

/// The `mode` of a [`JointCommand`] carrying [`HandCommand::Effort`].
pub const MODE_EFFORT: &str = "effort";
/// The `mode` of a [`JointCommand`] carrying [`HandCommand::Position`].
pub const MODE_POSITION: &str = "position";
/// The `mode` of a [`JointCommand`] carrying [`HandCommand::Impedance`].
pub const MODE_IMPEDANCE: &str = "impedance";

/// A hand command as a `JointCommand` (the fields its mode uses; the others empty).
pub fn hand_command_msg(c: &HandCommand, time_s: f64) -> JointCommand {
    let list = |v: &SVector<f64, FINGER_DOF>| v.iter().copied().collect::<Vec<f64>>();
    let mut msg = JointCommand {
        header: stamp(time_s),
        name: names(&SHADOW_FINGER_JOINTS),
        ..JointCommand::default()
    };
    match c {
        HandCommand::Effort(t) => {
            msg.mode = MODE_EFFORT.into();
            msg.effort = list(t);
        }
        HandCommand::Position(q) => {
            msg.mode = MODE_POSITION.into();
            msg.position = list(q);
        }
        HandCommand::Impedance(z) => {
            msg.mode = MODE_IMPEDANCE.into();
            msg.position = list(&z.position_rad);
            msg.velocity = list(&z.velocity_rad_s);
            msg.effort = list(&z.feedforward_nm);
            msg.stiffness = list(&z.stiffness_nm_rad);
            msg.damping = list(&z.damping_nm_s_rad);
            msg.max_effort = list(&z.max_effort_nm);
        }
    }
    msg
}

/// # Errors
/// [`WireError`] naming the joint or field at fault, [`WireError::UnknownMode`], or
/// [`WireError::OutOfRange`] for a negative stiffness or damping or a maximum effort
/// that is not positive.
pub fn hand_command(msg: &JointCommand) -> Result<HandCommand, WireError> {
    let field = |values: &[f64], name: &'static str| {
        by_name(&msg.name, values, name, &SHADOW_FINGER_JOINTS)
    };
    match msg.mode.as_str() {
        MODE_EFFORT => Ok(HandCommand::Effort(field(&msg.effort, "effort")?)),
        MODE_POSITION => Ok(HandCommand::Position(field(&msg.position, "position")?)),
        MODE_IMPEDANCE => {
            let z = HandImpedance {
                position_rad: field(&msg.position, "position")?,
                velocity_rad_s: field(&msg.velocity, "velocity")?,
                feedforward_nm: field(&msg.effort, "effort")?,
                stiffness_nm_rad: field(&msg.stiffness, "stiffness")?,
                damping_nm_s_rad: field(&msg.damping, "damping")?,
                max_effort_nm: field(&msg.max_effort, "max_effort")?,
            };
            for (values, name, positive) in [
                (&z.stiffness_nm_rad, "stiffness", false),
                (&z.damping_nm_s_rad, "damping", false),
                (&z.max_effort_nm, "max_effort", true),
            ] {
                if let Some(i) = values
                    .iter()
                    .position(|&x| if positive { x <= 0.0 } else { x < 0.0 })
                {
                    return Err(WireError::OutOfRange {
                        joint: SHADOW_FINGER_JOINTS[i].to_owned(),
                        field: name,
                    });
                }
            }
            Ok(HandCommand::Impedance(z))
        }
        _ => Err(WireError::UnknownMode(msg.mode.clone())),
    }
}

/// Finger joint targets from the operator site's hand inference (`JointState` with the
/// 17 finger joint names and positions).
///
/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn finger_targets(msg: &JointState) -> Result<SVector<f64, FINGER_DOF>, WireError> {
    joint_vector(msg, &SHADOW_FINGER_JOINTS, Field::Position)
}

/// Finger joint targets as a `JointState` (positions).
pub fn finger_targets_msg(q: &SVector<f64, FINGER_DOF>, time_s: f64) -> JointState {
    JointState {
        header: stamp(time_s),
        name: names(&SHADOW_FINGER_JOINTS),
        position: q.iter().copied().collect(),
        velocity: vec![],
        effort: vec![],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use teleop_interfaces::joints::{PR2_ARM_JOINTS, UR5_JOINTS};

    #[test]
    fn pose_messages_are_checked_and_normalized() {
        let mut p = teleop_msgs::Pose::default();
        p.position.x = 0.5;
        p.orientation.w = 1.004;
        let iso = checked_isometry(&p, POSE_QUATERNION_TOLERANCE).expect("0.4 % off");
        assert!((iso.rotation.quaternion().norm() - 1.0).abs() < 1e-12);
        assert!((iso.translation.vector.x - 0.5).abs() < 1e-12);
        assert!(matches!(
            checked_isometry(&p, 1e-6),
            Err(PoseError::NotUnit { .. })
        ));
        p.orientation.w = 0.0;
        let e = checked_isometry(&p, POSE_QUATERNION_TOLERANCE).unwrap_err();
        assert_eq!(e.kind(), "not_unit", "the zero quaternion: {e}");
        p.orientation.w = 1.0;
        p.position.y = f64::NAN;
        assert_eq!(
            checked_isometry(&p, POSE_QUATERNION_TOLERANCE),
            Err(PoseError::NonFinite)
        );
        p.position.y = 0.0;
        assert!(
            checked_isometry(&p, f64::NAN).is_err(),
            "a NaN tolerance refuses"
        );
    }

    #[test]
    fn round_trips() {
        let arm = ArmState {
            time_s: 12.5,
            position_rad: SVector::<f64, 7>::from_fn(|i, _| i as f64 * 0.1),
            velocity_rad_s: SVector::from_fn(|i, _| -(i as f64)),
        };
        assert_eq!(
            arm_state(&PR2_ARM_JOINTS, &arm_state_msg(&PR2_ARM_JOINTS, &arm)),
            Ok(arm)
        );
        let ur5 = ArmCommand {
            velocity_rad_s: SVector::<f64, 6>::from_fn(|i, _| i as f64),
        };
        assert_eq!(
            arm_command(&UR5_JOINTS, &arm_command_msg(&UR5_JOINTS, &ur5, 1.0)),
            Ok(ur5)
        );
        let hand = HandState {
            time_s: 3.0,
            position_rad: SVector::from_fn(|i, _| i as f64 * 0.05),
            velocity_rad_s: SVector::zeros(),
            effort_nm: SVector::from_element(0.1),
            fingertip_force_n: [1.0, 2.0, 3.0, 4.0, 5.0],
        };
        assert_eq!(
            hand_state(&hand_state_msg(&hand), Some(&tactile_msg(&hand))),
            Ok(hand)
        );
        for c in [
            HandCommand::Effort(SVector::from_element(0.2)),
            HandCommand::Position(SVector::from_element(0.3)),
            HandCommand::Impedance(impedance()),
        ] {
            assert_eq!(hand_command(&hand_command_msg(&c, 0.0)), Ok(c));
        }
        let q = SVector::from_fn(|i, _| i as f64 * 0.01);
        assert_eq!(finger_targets(&finger_targets_msg(&q, 1.0)), Ok(q));
    }

    fn impedance() -> HandImpedance {
        HandImpedance {
            position_rad: SVector::from_fn(|i, _| i as f64 * 0.05),
            velocity_rad_s: SVector::from_element(-0.5),
            stiffness_nm_rad: SVector::from_element(20.0),
            damping_nm_s_rad: SVector::from_element(0.2),
            feedforward_nm: SVector::from_fn(|i, _| i as f64 * -0.01),
            max_effort_nm: SVector::from_element(2.0),
        }
    }

    #[test]
    fn impedance_law_is_clamped() {
        let z = impedance();
        let q = z.position_rad.add_scalar(-0.01);
        let tau = z.effort_at(&q, &SVector::zeros());
        // 20 * 0.01 + 0.2 * -0.5 + ff.
        assert!((tau[1] - (0.2 - 0.1 - 0.01)).abs() < 1e-12, "{}", tau[1]);
        let far = z.position_rad.add_scalar(-1.0);
        assert_eq!(z.effort_at(&far, &SVector::zeros())[3], 2.0);
        assert_eq!(
            z.effort_at(&z.position_rad.add_scalar(1.0), &SVector::zeros())[3],
            -2.0
        );
    }

    #[test]
    fn joints_match_by_name_in_any_order() {
        let cmd = ArmCommand {
            velocity_rad_s: SVector::<f64, 7>::from_fn(|i, _| i as f64),
        };
        let mut msg = arm_command_msg(&PR2_ARM_JOINTS, &cmd, 0.0);
        msg.name.reverse();
        msg.velocity.reverse();
        assert_eq!(arm_command(&PR2_ARM_JOINTS, &msg), Ok(cmd));
    }

    #[test]
    fn errors_name_the_problem() {
        let cmd = ArmCommand::<7>::stop();
        let mut msg = arm_command_msg(&PR2_ARM_JOINTS, &cmd, 0.0);
        msg.velocity[2] = f64::NAN;
        assert_eq!(
            arm_command(&PR2_ARM_JOINTS, &msg),
            Err(WireError::NonFinite {
                joint: PR2_ARM_JOINTS[2].to_owned(),
                field: "velocity"
            })
        );
        msg.name[0] = "bogus".into();
        let e = arm_command(&PR2_ARM_JOINTS, &msg).unwrap_err();
        assert_eq!(e, WireError::MissingJoint(PR2_ARM_JOINTS[0].to_owned()));
        assert_eq!(e.kind(), "missing_joint");
        msg.velocity.pop();
        assert!(matches!(
            arm_command(&PR2_ARM_JOINTS, &msg),
            Err(WireError::Length { .. })
        ));
        let unnamed = JointCommand {
            name: names(&SHADOW_FINGER_JOINTS),
            ..Default::default()
        };
        let e = hand_command(&unnamed).unwrap_err();
        assert_eq!(e, WireError::UnknownMode(String::new()));
        assert_eq!(e.kind(), "unknown_mode");
        // An effort command without efforts.
        let empty = JointCommand {
            mode: MODE_EFFORT.into(),
            ..unnamed.clone()
        };
        assert!(matches!(
            hand_command(&empty),
            Err(WireError::Length {
                field: "effort",
                ..
            })
        ));
        // An impedance with a negative damping, a zero effort limit, a NaN stiffness.
        let z = impedance();
        let mut msg = hand_command_msg(&HandCommand::Impedance(z), 0.0);
        msg.damping[4] = -0.1;
        assert_eq!(
            hand_command(&msg),
            Err(WireError::OutOfRange {
                joint: SHADOW_FINGER_JOINTS[4].to_owned(),
                field: "damping"
            })
        );
        let mut msg = hand_command_msg(&HandCommand::Impedance(z), 0.0);
        msg.max_effort[0] = 0.0;
        assert_eq!(hand_command(&msg).unwrap_err().kind(), "out_of_range");
        let mut msg = hand_command_msg(&HandCommand::Impedance(z), 0.0);
        msg.stiffness[16] = f64::NAN;
        assert_eq!(
            hand_command(&msg),
            Err(WireError::NonFinite {
                joint: SHADOW_FINGER_JOINTS[16].to_owned(),
                field: "stiffness"
            })
        );
        // A UR5 message is not a PR2 command.
        let ur5 = arm_command_msg(&UR5_JOINTS, &ArmCommand::<6>::stop(), 0.0);
        assert!(arm_command(&PR2_ARM_JOINTS, &ur5).is_err());
    }
}
