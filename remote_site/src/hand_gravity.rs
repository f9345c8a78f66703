//! Gravity torques on the Shadow hand's 17 finger joints, `G(q)` of thesis eq. 8.2,
//! from the URDF link masses with the hand posed by the PR2 arm. The simulator's finger
//! dynamics and the hand controller's compensation use the same computation
//! ([`add_finger_gravity`]), so the controller cancels exactly the gravity the simulated
//! fingers feel; a real hand differs by its model error.

use nalgebra::{Point3, SVector, Vector3};
use teleop_kinematics::{KinematicState, KinematicsError, LinkId, Robot, robots};

use crate::hardware::{ARM_JOINTS, FINGER_JOINTS};

/// A link with mass carried by at least one finger joint.
#[derive(Debug, Clone)]
pub(crate) struct MassLink {
    pub(crate) link: LinkId,
    pub(crate) mass_kg: f64,
    pub(crate) com_local: Point3<f64>,
    /// Finger joint indices ([`FINGER_JOINTS`] order) moving the link.
    pub(crate) hand_joints: Vec<usize>,
}

/// The links with mass that finger joints move (`dof_hand[d]`: finger joint index of
/// robot DoF `d`, if any).
pub(crate) fn finger_masses(robot: &Robot, dof_hand: &[Option<usize>]) -> Vec<MassLink> {
    let mut masses = Vec::new();
    for link in robot.links() {
        let Ok(id) = robot.link_id(&link.name) else {
            continue;
        };
        let hand_joints: Vec<usize> = robot
            .dofs_moving(id)
            .iter()
            .filter_map(|&d| dof_hand.get(d).copied().flatten())
            .collect();
        if let (false, Some(inertial)) = (hand_joints.is_empty(), link.inertial) {
            masses.push(MassLink {
                link: id,
                mass_kg: inertial.mass_kg,
                com_local: Point3::from(inertial.origin.translation.vector),
                hand_joints,
            });
        }
    }
    masses
}

/// Adds the torque of gravity (`gravity_m_s2`, world frame) on every finger joint to
/// `out`, at the configuration `kin` holds (already updated). The torque a joint feels;
/// the compensation is its negative.
pub(crate) fn add_finger_gravity(
    robot: &Robot,
    kin: &KinematicState,
    masses: &[MassLink],
    hand_dof: &[usize; 17],
    hand_axis_local: &[Vector3<f64>; 17],
    gravity_m_s2: &Vector3<f64>,
    out: &mut SVector<f64, 17>,
) {
    let frames = kin.dof_frames();
    for m in masses {
        let com = robot.link_pose(kin, m.link) * m.com_local;
        let weight = gravity_m_s2 * m.mass_kg;
        for &j in &m.hand_joints {
            let frame = &frames[hand_dof[j]];
            let axis = frame.rotation * hand_axis_local[j];
            out[j] += weight.dot(&axis.cross(&(com.coords - frame.translation.vector)));
        }
    }
}

/// Gravity model of the hand for a controller: give it the arm's and the fingers'
/// measured positions, get the 17 gravity torques.
#[derive(Debug, Clone)]
pub struct HandGravity {
    robot: Robot,
    kin: KinematicState,
    arm_dof: [usize; 7],
    hand_dof: [usize; 17],
    hand_axis_local: [Vector3<f64>; 17],
    masses: Vec<MassLink>,
    q_full: Vec<f64>,
    gravity_m_s2: Vector3<f64>,
}

impl HandGravity {
    /// The model of our PR2 arm + Shadow hand URDF under `gravity_m_s2` (PR2
    /// `base_link` frame; normally `[0, 0, -9.81]`).
    ///
    /// # Errors
    /// Only if the embedded model lacked a joint.
    pub fn new(gravity_m_s2: Vector3<f64>) -> Result<Self, KinematicsError> {
        let robot = robots::pr2_arm()?;
        let joints: Vec<_> = robot.dof_joints().cloned().collect();
        let mut arm_dof = [0; 7];
        for (i, name) in ARM_JOINTS.iter().enumerate() {
            arm_dof[i] = robot.dof_index(name)?;
        }
        let mut hand_dof = [0; 17];
        let mut hand_axis_local = [Vector3::zeros(); 17];
        let mut dof_hand = vec![None; robot.dof()];
        for (i, name) in FINGER_JOINTS.iter().enumerate() {
            let d = robot.dof_index(name)?;
            hand_dof[i] = d;
            dof_hand[d] = Some(i);
            hand_axis_local[i] = joints[d].axis.into_inner();
        }
        let masses = finger_masses(&robot, &dof_hand);
        let kin = robot.new_state();
        Ok(Self {
            q_full: robot.neutral_positions(),
            kin,
            robot,
            arm_dof,
            hand_dof,
            hand_axis_local,
            masses,
            gravity_m_s2,
        })
    }

    /// The torque each finger joint must produce to hold still against gravity (the
    /// `G` of eq. 8.2, what `JointInput::with_gravity` takes), N m, [`FINGER_JOINTS`]
    /// order, with the arm at `arm_rad` ([`ARM_JOINTS`] order) and the fingers at
    /// `hand_rad`.
    pub fn compensation_nm(
        &mut self,
        arm_rad: &SVector<f64, 7>,
        hand_rad: &SVector<f64, 17>,
    ) -> SVector<f64, 17> {
        for i in 0..7 {
            self.q_full[self.arm_dof[i]] = arm_rad[i];
        }
        for i in 0..17 {
            self.q_full[self.hand_dof[i]] = hand_rad[i];
        }
        // Lengths match by construction.
        let _ = self.robot.update(&mut self.kin, &self.q_full);
        let mut out = SVector::zeros();
        add_finger_gravity(
            &self.robot,
            &self.kin,
            &self.masses,
            &self.hand_dof,
            &self.hand_axis_local,
            &self.gravity_m_s2,
            &mut out,
        );
        -out
    }
}
