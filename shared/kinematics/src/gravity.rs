//! Gravity torques on chosen joints of a robot from its URDF link masses: the `G(q)` of
//! the hand controller (thesis eq. 8.2) and the gravity the simulated fingers feel.
//!
//! [`GravityModel<N>`] takes the names of the `N` joints of interest (e.g. the Shadow
//! hand's 17 finger joints on the PR2 + hand model, so the hand is posed by the arm);
//! every link moved by one of them contributes `m g · (a_j × (c - o_j))` to joint `j`.
//! The masses can be scaled per link ([`GravityModel::scale_masses`]): a simulated
//! robot built with perturbed masses feels a different gravity than the nominal model
//! a controller compensates.

use nalgebra::{Point3, SVector, Vector3};

use crate::error::KinematicsError;
use crate::fk::KinematicState;
use crate::model::{LinkId, Robot};

/// A link with mass carried by at least one joint of interest.
#[derive(Debug, Clone, PartialEq)]
pub struct MassLink {
    pub link: LinkId,
    pub mass_kg: f64,
    /// Centre of mass in the link frame.
    pub com_local: Point3<f64>,
    /// Indices (into the model's joint list) of the joints of interest moving it.
    pub joints: Vec<usize>,
}

/// Gravity torques on `N` joints of a robot.
#[derive(Debug, Clone)]
pub struct GravityModel<const N: usize> {
    robot: Robot,
    kin: KinematicState,
    dofs: [usize; N],
    axes_local: [Vector3<f64>; N],
    masses: Vec<MassLink>,
    q_full: Vec<f64>,
    gravity_m_s2: Vector3<f64>,
}

impl<const N: usize> GravityModel<N> {
    /// The model of `robot`'s joints `joints` under `gravity_m_s2` (root frame), with
    /// the URDF masses.
    ///
    /// # Errors
    /// [`KinematicsError`] for a joint the robot lacks.
    pub fn new(
        robot: Robot,
        joints: &[&str; N],
        gravity_m_s2: Vector3<f64>,
    ) -> Result<Self, KinematicsError> {
        let all: Vec<_> = robot.dof_joints().cloned().collect();
        let mut dofs = [0; N];
        let mut axes_local = [Vector3::zeros(); N];
        let mut dof_joint = vec![None; robot.dof()];
        for (i, name) in joints.iter().enumerate() {
            let d = robot.dof_index(name)?;
            dofs[i] = d;
            dof_joint[d] = Some(i);
            axes_local[i] = all[d].axis.into_inner();
        }
        let mut masses = Vec::new();
        for link in robot.links() {
            let Ok(id) = robot.link_id(&link.name) else {
                continue;
            };
            let moved_by: Vec<usize> = robot
                .dofs_moving(id)
                .iter()
                .filter_map(|&d| dof_joint.get(d).copied().flatten())
                .collect();
            if let (false, Some(inertial)) = (moved_by.is_empty(), link.inertial) {
                masses.push(MassLink {
                    link: id,
                    mass_kg: inertial.mass_kg,
                    com_local: Point3::from(inertial.origin.translation.vector),
                    joints: moved_by,
                });
            }
        }
        Ok(Self {
            kin: robot.new_state(),
            q_full: robot.neutral_positions(),
            robot,
            dofs,
            axes_local,
            masses,
            gravity_m_s2,
        })
    }

    /// Multiplies each link's mass by `scale(link name)`.
    pub fn scale_masses(&mut self, mut scale: impl FnMut(&str) -> f64) {
        for m in &mut self.masses {
            let name = self.robot.links()[m.link.index()].name.as_str();
            m.mass_kg *= scale(name);
        }
    }

    /// The links that count, with their (possibly scaled) masses.
    pub fn masses(&self) -> &[MassLink] {
        &self.masses
    }

    /// The robot model.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// Robot DoF index of each joint of interest.
    pub fn dofs(&self) -> &[usize; N] {
        &self.dofs
    }

    /// Adds to `out` the torque gravity exerts on each joint of interest at the
    /// configuration `kin` holds (a state of the same robot, already updated). This is
    /// what the joint feels; the compensation is its negative.
    pub fn add_torques(&self, kin: &KinematicState, out: &mut SVector<f64, N>) {
        let frames = kin.dof_frames();
        for m in &self.masses {
            let com = self.robot.link_pose(kin, m.link) * m.com_local;
            let weight = self.gravity_m_s2 * m.mass_kg;
            for &j in &m.joints {
                let frame = &frames[self.dofs[j]];
                let axis = frame.rotation * self.axes_local[j];
                out[j] += weight.dot(&axis.cross(&(com.coords - frame.translation.vector)));
            }
        }
    }

    /// Sets the position of robot DoF `dof` for [`GravityModel::compensation_nm`]
    /// (out-of-range indices are ignored).
    pub fn set_position(&mut self, dof: usize, position: f64) {
        if let Some(q) = self.q_full.get_mut(dof) {
            *q = position;
        }
    }

    /// The torque each joint of interest must produce to hold still against gravity at
    /// the positions set, N m.
    pub fn compensation_nm(&mut self) -> SVector<f64, N> {
        // Lengths match by construction.
        let _ = self.robot.update(&mut self.kin, &self.q_full);
        let mut out = SVector::zeros();
        self.add_torques(&self.kin, &mut out);
        -out
    }
}
