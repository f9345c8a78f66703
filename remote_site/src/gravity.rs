//! The hand controller's gravity model, `G(q)` of thesis eq. 8.2: the nominal URDF
//! masses of the Shadow hand with the hand posed by the measured PR2 arm. The
//! simulator feels its own (perturbed) masses, so the compensation carries the model
//! error a real hand would.

use nalgebra::{SVector, Vector3};
use teleop_interfaces::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_kinematics::{GravityModel, KinematicsError, robots};

/// Gravity compensation of the 17 finger joints.
#[derive(Debug, Clone)]
pub struct HandGravity {
    model: GravityModel<17>,
    arm_dof: [usize; 7],
}

impl HandGravity {
    /// The nominal model of our PR2 arm + Shadow hand URDF under `gravity_m_s2` (PR2
    /// `base_link` frame; normally `[0, 0, -9.81]`).
    ///
    /// # Errors
    /// Only if the embedded model lacked a joint.
    pub fn new(gravity_m_s2: Vector3<f64>) -> Result<Self, KinematicsError> {
        let robot = robots::pr2_arm()?;
        let mut arm_dof = [0; 7];
        for (i, name) in PR2_ARM_JOINTS.iter().enumerate() {
            arm_dof[i] = robot.dof_index(name)?;
        }
        Ok(Self {
            model: GravityModel::new(robot, &SHADOW_FINGER_JOINTS, gravity_m_s2)?,
            arm_dof,
        })
    }

    /// The torque each finger joint must produce to hold still against gravity (what
    /// `JointInput::with_gravity` takes), N m, with the arm at `arm_rad` and the
    /// fingers at `hand_rad`.
    pub fn compensation_nm(
        &mut self,
        arm_rad: &SVector<f64, 7>,
        hand_rad: &SVector<f64, 17>,
    ) -> SVector<f64, 17> {
        for (i, &d) in self.arm_dof.iter().enumerate() {
            self.model.set_position(d, arm_rad[i]);
        }
        let dofs = *self.model.dofs();
        for (i, d) in dofs.into_iter().enumerate() {
            self.model.set_position(d, hand_rad[i]);
        }
        self.model.compensation_nm()
    }
}
