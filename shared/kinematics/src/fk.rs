//! Forward kinematics and Jacobians over the whole tree.
//!
//! [`KinematicState`] holds one world frame per moving joint. [`Robot::update`]
//! fills it from a joint-position slice in one pass without allocating; link poses
//! and Jacobians of any link are then read from it. This is what a goal-based IK
//! over a tree (several fingertips sharing the wrist joints) evaluates per iteration.

use nalgebra::{Dim, Isometry3, Matrix, Point3, StorageMut, U6, UnitQuaternion, Vector3};

use crate::error::KinematicsError;
use crate::model::{Dof, LinkId, Robot};

/// Frame of a moving joint after its motion: `parent * origin * motion(q)`.
#[inline(always)]
pub(crate) fn moved_frame(
    parent: &Isometry3<f64>,
    origin: &Isometry3<f64>,
    axis: &nalgebra::Unit<Vector3<f64>>,
    prismatic: bool,
    q: f64,
) -> Isometry3<f64> {
    let mut frame = parent * origin;
    if prismatic {
        frame.translation.vector += frame.rotation * (axis.into_inner() * q);
    } else {
        frame.rotation *= UnitQuaternion::from_axis_angle(axis, q);
    }
    frame
}

/// Writes one Jacobian column for a joint whose moving frame is `frame`, with the
/// linear part relative to the world origin; [`finish_linear`] shifts it to the
/// end point once that is known.
#[inline(always)]
pub(crate) fn write_column<C: Dim, S: StorageMut<f64, U6, C>>(
    jac: &mut Matrix<f64, U6, C, S>,
    col: usize,
    frame: &Isometry3<f64>,
    axis: &nalgebra::Unit<Vector3<f64>>,
    prismatic: bool,
) {
    let a = frame.rotation * axis.into_inner();
    if prismatic {
        jac.fixed_view_mut::<3, 1>(0, col).copy_from(&a);
        jac.fixed_view_mut::<3, 1>(3, col).fill(0.0);
    } else {
        // a x (p_e - p_i) = a x p_e + p_i x a; store p_i x a now.
        let p = frame.translation.vector;
        jac.fixed_view_mut::<3, 1>(0, col).copy_from(&p.cross(&a));
        jac.fixed_view_mut::<3, 1>(3, col).copy_from(&a);
    }
}

/// Adds `a x p_e` to the linear rows of every revolute column (angular part non-zero).
#[inline(always)]
pub(crate) fn finish_linear<C: Dim, S: StorageMut<f64, U6, C>>(
    jac: &mut Matrix<f64, U6, C, S>,
    col: usize,
    end: &Vector3<f64>,
) {
    let a = Vector3::new(jac[(3, col)], jac[(4, col)], jac[(5, col)]);
    let shift = a.cross(end);
    let mut lin = jac.fixed_view_mut::<3, 1>(0, col);
    lin += shift;
}

/// World frames of a robot's moving joints for one configuration. Reusable: create
/// once with [`Robot::new_state`], then [`Robot::update`] per configuration.
#[derive(Debug, Clone)]
pub struct KinematicState {
    positions: Vec<f64>,
    frames: Vec<Isometry3<f64>>,
}

impl KinematicState {
    /// Joint positions of the last update.
    pub fn positions(&self) -> &[f64] {
        &self.positions
    }

    /// World frame of each moving joint after its motion, in DoF order.
    pub fn dof_frames(&self) -> &[Isometry3<f64>] {
        &self.frames
    }
}

impl Robot {
    /// A state buffer sized for this robot, at all-zero positions.
    pub fn new_state(&self) -> KinematicState {
        let mut state = KinematicState {
            positions: vec![0.0; self.dof()],
            frames: vec![Isometry3::identity(); self.dof()],
        };
        self.update_unchecked(&mut state);
        state
    }

    /// Forward kinematics of all moving joints, in place. Positions outside the
    /// limits are evaluated as given (limits are the caller's policy).
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] if `positions.len() != self.dof()` or the
    /// state was made by a robot with another DoF.
    pub fn update(
        &self,
        state: &mut KinematicState,
        positions: &[f64],
    ) -> Result<(), KinematicsError> {
        if positions.len() != self.dof() || state.frames.len() != self.dof() {
            return Err(KinematicsError::JointCount {
                expected: self.dof(),
                actual: positions.len(),
            });
        }
        state.positions.copy_from_slice(positions);
        self.update_unchecked(state);
        Ok(())
    }

    fn update_unchecked(&self, state: &mut KinematicState) {
        for (i, dof) in self.dofs.iter().enumerate() {
            let Dof {
                parent,
                origin,
                axis,
                prismatic,
                ..
            } = dof;
            let parent_frame = match parent {
                Some(p) => state.frames[*p],
                None => Isometry3::identity(),
            };
            state.frames[i] =
                moved_frame(&parent_frame, origin, axis, *prismatic, state.positions[i]);
        }
    }

    /// Pose of a link in the root frame.
    ///
    /// # Panics
    /// If `link` or `state` belong to another robot.
    pub fn link_pose(&self, state: &KinematicState, link: LinkId) -> Isometry3<f64> {
        let anchor = &self.anchors[link.0];
        match anchor.dof {
            Some(d) => state.frames[d] * anchor.offset,
            None => anchor.offset,
        }
    }

    /// Poses of all links in the root frame, indexed by [`LinkId::index`].
    ///
    /// # Panics
    /// If `out.len() != self.links().len()` or `state` belongs to another robot.
    pub fn link_poses_into(&self, state: &KinematicState, out: &mut [Isometry3<f64>]) {
        assert_eq!(out.len(), self.links().len(), "one pose per link");
        for (i, pose) in out.iter_mut().enumerate() {
            *pose = self.link_pose(state, LinkId(i));
        }
    }

    /// Poses of all links in the root frame (allocating convenience form).
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] for a wrong-length `positions`.
    pub fn forward_kinematics(
        &self,
        positions: &[f64],
    ) -> Result<Vec<Isometry3<f64>>, KinematicsError> {
        let mut state = self.new_state();
        self.update(&mut state, positions)?;
        let mut out = vec![Isometry3::identity(); self.links().len()];
        self.link_poses_into(&state, &mut out);
        Ok(out)
    }

    /// Geometric Jacobian (6 x DoF; rows: linear velocity, then angular velocity, both
    /// in the root frame) of the point `point` fixed in `link`'s frame. Columns of
    /// joints that do not move the link are zero. Returns the point in the root frame.
    ///
    /// # Errors
    /// [`KinematicsError::JacobianColumns`] if `jac` does not have `self.dof()` columns.
    ///
    /// # Panics
    /// If `link` or `state` belong to another robot.
    pub fn link_jacobian_into<C: Dim, S: StorageMut<f64, U6, C>>(
        &self,
        state: &KinematicState,
        link: LinkId,
        point: &Point3<f64>,
        jac: &mut Matrix<f64, U6, C, S>,
    ) -> Result<Point3<f64>, KinematicsError> {
        if jac.ncols() != self.dof() {
            return Err(KinematicsError::JacobianColumns {
                expected: self.dof(),
                actual: jac.ncols(),
            });
        }
        jac.fill(0.0);
        let end = self.link_pose(state, link) * point;
        let mut cur = self.anchors[link.0].dof;
        while let Some(i) = cur {
            let dof = &self.dofs[i];
            write_column(jac, i, &state.frames[i], &dof.axis, dof.prismatic);
            if !dof.prismatic {
                finish_linear(jac, i, &end.coords);
            }
            cur = dof.parent;
        }
        Ok(end)
    }

    /// Indices of the moving joints that move `link`, from the root outwards.
    pub fn dofs_moving(&self, link: LinkId) -> Vec<usize> {
        let mut out = Vec::new();
        let mut cur = self.anchors[link.0].dof;
        while let Some(i) = cur {
            out.push(i);
            cur = self.dofs[i].parent;
        }
        out.reverse();
        out
    }
}
