//! Conversions between the hardware types and bus messages (`JointState`,
//! `FingertipPressures`), shared by the hardware clients, the simulator process and the
//! feedback publisher. Joints are matched by name, so a publisher may list them in any
//! order; missing joints, wrong lengths and non-finite values are errors naming the
//! joint and field.

use nalgebra::SVector;
use teleop_msgs::{FingertipPressures, Header, JointState, Time};

use crate::hardware::{ARM_JOINTS, ArmCommand, ArmState, FINGER_JOINTS, HandCommand, HandState};

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
    #[error("hand command has neither `position` nor `effort` values")]
    EmptyCommand,
}

/// Values of `field` for the joints `wanted`, by name.
pub fn joint_vector<const N: usize>(
    msg: &JointState,
    wanted: &[&str; N],
    field: &'static str,
) -> Result<SVector<f64, N>, WireError> {
    let values = match field {
        "position" => &msg.position,
        "velocity" => &msg.velocity,
        _ => &msg.effort,
    };
    if values.len() != msg.name.len() {
        return Err(WireError::Length {
            field,
            len: values.len(),
            names: msg.name.len(),
        });
    }
    let mut out = SVector::<f64, N>::zeros();
    for (i, joint) in wanted.iter().enumerate() {
        let idx = msg
            .name
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
    Header::new(Time::from_nanos((time_s * 1e9) as i64), "")
}

pub fn arm_state_msg(s: &ArmState) -> JointState {
    JointState {
        header: stamp(s.time_s),
        name: names(&ARM_JOINTS),
        position: s.position_rad.iter().copied().collect(),
        velocity: s.velocity_rad_s.iter().copied().collect(),
        effort: vec![],
    }
}

/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn arm_state(msg: &JointState) -> Result<ArmState, WireError> {
    Ok(ArmState {
        time_s: msg.header.stamp.as_secs_f64(),
        position_rad: joint_vector(msg, &ARM_JOINTS, "position")?,
        velocity_rad_s: joint_vector(msg, &ARM_JOINTS, "velocity")?,
    })
}

pub fn arm_command_msg(c: &ArmCommand, time_s: f64) -> JointState {
    JointState {
        header: stamp(time_s),
        name: names(&ARM_JOINTS),
        position: vec![],
        velocity: c.velocity_rad_s.iter().copied().collect(),
        effort: vec![],
    }
}

/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn arm_command(msg: &JointState) -> Result<ArmCommand, WireError> {
    Ok(ArmCommand {
        velocity_rad_s: joint_vector(msg, &ARM_JOINTS, "velocity")?,
    })
}

pub fn hand_state_msg(s: &HandState) -> JointState {
    JointState {
        header: stamp(s.time_s),
        name: names(&FINGER_JOINTS),
        position: s.position_rad.iter().copied().collect(),
        velocity: s.velocity_rad_s.iter().copied().collect(),
        effort: s.effort_nm.iter().copied().collect(),
    }
}

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
                        joint: crate::hardware::FINGERTIPS[i].to_owned(),
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
        position_rad: joint_vector(msg, &FINGER_JOINTS, "position")?,
        velocity_rad_s: joint_vector(msg, &FINGER_JOINTS, "velocity")?,
        effort_nm: joint_vector(msg, &FINGER_JOINTS, "effort")?,
        fingertip_force_n,
    })
}

pub fn hand_command_msg(c: &HandCommand, time_s: f64) -> JointState {
    let (position, effort) = match c {
        HandCommand::Position(q) => (q.iter().copied().collect(), vec![]),
        HandCommand::Effort(t) => (vec![], t.iter().copied().collect()),
    };
    JointState {
        header: stamp(time_s),
        name: names(&FINGER_JOINTS),
        position,
        velocity: vec![],
        effort,
    }
}

/// # Errors
/// [`WireError`] naming the joint or field at fault, or [`WireError::EmptyCommand`].
pub fn hand_command(msg: &JointState) -> Result<HandCommand, WireError> {
    if !msg.effort.is_empty() {
        Ok(HandCommand::Effort(joint_vector(
            msg,
            &FINGER_JOINTS,
            "effort",
        )?))
    } else if !msg.position.is_empty() {
        Ok(HandCommand::Position(joint_vector(
            msg,
            &FINGER_JOINTS,
            "position",
        )?))
    } else {
        Err(WireError::EmptyCommand)
    }
}

/// Finger joint targets from the local site's hand inference (`JointState` with the 17
/// finger joint names and positions), as the hand controller's target vector.
///
/// # Errors
/// [`WireError`] naming the joint or field at fault.
pub fn finger_targets(msg: &JointState) -> Result<SVector<f64, 17>, WireError> {
    joint_vector(msg, &FINGER_JOINTS, "position")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() {
        let arm = ArmState {
            time_s: 12.5,
            position_rad: SVector::from_fn(|i, _| i as f64 * 0.1),
            velocity_rad_s: SVector::from_fn(|i, _| -(i as f64)),
        };
        assert_eq!(arm_state(&arm_state_msg(&arm)), Ok(arm));
        let cmd = ArmCommand {
            velocity_rad_s: SVector::from_fn(|i, _| i as f64),
        };
        assert_eq!(arm_command(&arm_command_msg(&cmd, 1.0)), Ok(cmd));
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
        ] {
            assert_eq!(hand_command(&hand_command_msg(&c, 0.0)), Ok(c));
        }
    }

    #[test]
    fn joints_match_by_name_in_any_order() {
        let cmd = ArmCommand {
            velocity_rad_s: SVector::from_fn(|i, _| i as f64),
        };
        let mut msg = arm_command_msg(&cmd, 0.0);
        msg.name.reverse();
        msg.velocity.reverse();
        assert_eq!(arm_command(&msg), Ok(cmd));
    }

    #[test]
    fn errors_name_the_problem() {
        let cmd = ArmCommand::stop();
        let mut msg = arm_command_msg(&cmd, 0.0);
        msg.velocity[2] = f64::NAN;
        assert_eq!(
            arm_command(&msg),
            Err(WireError::NonFinite {
                joint: ARM_JOINTS[2].to_owned(),
                field: "velocity"
            })
        );
        msg.name[0] = "bogus".into();
        assert_eq!(
            arm_command(&msg),
            Err(WireError::MissingJoint(ARM_JOINTS[0].to_owned()))
        );
        msg.velocity.pop();
        assert!(matches!(arm_command(&msg), Err(WireError::Length { .. })));
        let empty = JointState {
            name: names(&FINGER_JOINTS),
            ..Default::default()
        };
        assert_eq!(hand_command(&empty), Err(WireError::EmptyCommand));
    }
}
