//! Serial chains between two links of a robot: the fast path for arm IK.
//!
//! A [`Chain`] copies the joints on the path from a base link to a tip link, with
//! fixed joints folded into the next moving joint's origin, so evaluating it touches
//! only a small contiguous array. Poses and Jacobians are expressed in the **base
//! link's frame**. [`FixedChain<N>`] is the same with the DoF in the type:
//! `SVector<f64, N>` in, `SMatrix<f64, 6, N>` out, no length checks and no heap.

use nalgebra::{
    Dim, Isometry3, Matrix, Matrix6xX, SMatrix, SVector, StorageMut, U6, Unit, Vector3,
};

use crate::error::KinematicsError;
use crate::fk::{finish_linear, moved_frame, write_column};
use crate::model::{JointId, JointLimits, LinkId, Robot};

/// One moving joint of a chain with the fixed transforms before it folded in.
#[derive(Debug, Clone, Copy)]
pub struct ChainJoint {
    /// The joint in the robot.
    pub joint: JointId,
    /// Its index in the robot's joint-position vector.
    pub robot_dof: usize,
    /// Joint frame at zero position relative to the previous joint's moving frame
    /// (or the base link for the first joint).
    pub origin: Isometry3<f64>,
    /// Unit axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Translation (true) or rotation (false).
    pub prismatic: bool,
    /// Position, velocity and effort limits.
    pub limits: JointLimits,
}

/// A serial chain from `base` to `tip`, evaluated in the base link's frame.
#[derive(Debug, Clone)]
pub struct Chain {
    base: LinkId,
    tip: LinkId,
    base_name: String,
    tip_name: String,
    names: Vec<String>,
    joints: Vec<ChainJoint>,
    tip_offset: Isometry3<f64>,
}

impl Robot {
    /// The serial chain from link `base` to link `tip` (base must be an ancestor).
    ///
    /// # Errors
    /// [`KinematicsError::UnknownLink`] for an unknown name,
    /// [`KinematicsError::NotAncestor`] if `base` is not on `tip`'s path to the root.
    pub fn chain(&self, base: &str, tip: &str) -> Result<Chain, KinematicsError> {
        let base_id = self.link_id(base)?;
        let tip_id = self.link_id(tip)?;
        self.chain_between(base_id, tip_id)
    }

    /// As [`Robot::chain`], by id.
    ///
    /// # Errors
    /// [`KinematicsError::NotAncestor`] if `base` is not on `tip`'s path to the root.
    pub fn chain_between(&self, base: LinkId, tip: LinkId) -> Result<Chain, KinematicsError> {
        if !self.is_ancestor(base, tip) {
            return Err(KinematicsError::NotAncestor {
                base: self.link(base).name.clone(),
                tip: self.link(tip).name.clone(),
            });
        }
        let mut path = Vec::new();
        let mut cur = tip;
        while cur != base {
            // Ancestry checked above: every link between tip and base has a parent joint.
            let Some(jid) = self.link(cur).parent_joint else {
                break;
            };
            path.push(jid);
            cur = self.joint(jid).parent;
        }
        path.reverse();
        let mut joints = Vec::new();
        let mut names = Vec::new();
        let mut pending = Isometry3::identity();
        for jid in path {
            let j = self.joint(jid);
            match (j.dof, j.limits) {
                (Some(robot_dof), Some(limits)) => {
                    joints.push(ChainJoint {
                        joint: jid,
                        robot_dof,
                        origin: pending * j.origin,
                        axis: j.axis,
                        prismatic: j.kind == crate::model::JointKind::Prismatic,
                        limits,
                    });
                    names.push(j.name.clone());
                    pending = Isometry3::identity();
                }
                _ => pending *= j.origin,
            }
        }
        Ok(Chain {
            base,
            tip,
            base_name: self.link(base).name.clone(),
            tip_name: self.link(tip).name.clone(),
            names,
            joints,
            tip_offset: pending,
        })
    }
}

/// Forward pass shared by [`Chain`] and [`FixedChain`]: end pose, and Jacobian if asked.
#[inline(always)]
fn evaluate<C: Dim, S: StorageMut<f64, U6, C>>(
    joints: &[ChainJoint],
    tip_offset: &Isometry3<f64>,
    q: impl Fn(usize) -> f64,
    mut jac: Option<&mut Matrix<f64, U6, C, S>>,
) -> Isometry3<f64> {
    let mut frame = Isometry3::identity();
    for (i, j) in joints.iter().enumerate() {
        frame = moved_frame(&frame, &j.origin, &j.axis, j.prismatic, q(i));
        if let Some(jac) = jac.as_deref_mut() {
            write_column(jac, i, &frame, &j.axis, j.prismatic);
        }
    }
    let end = frame * tip_offset;
    if let Some(jac) = jac {
        for (i, j) in joints.iter().enumerate() {
            if !j.prismatic {
                finish_linear(jac, i, &end.translation.vector);
            }
        }
    }
    end
}

impl Chain {
    /// Number of moving joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Base link (the frame results are expressed in).
    pub fn base(&self) -> LinkId {
        self.base
    }

    /// Tip link.
    pub fn tip(&self) -> LinkId {
        self.tip
    }

    /// Base link name.
    pub fn base_name(&self) -> &str {
        &self.base_name
    }

    /// Tip link name.
    pub fn tip_name(&self) -> &str {
        &self.tip_name
    }

    /// Moving joints from base to tip.
    pub fn joints(&self) -> &[ChainJoint] {
        &self.joints
    }

    /// Names of the moving joints from base to tip.
    pub fn joint_names(&self) -> impl ExactSizeIterator<Item = &str> + '_ {
        self.names.iter().map(String::as_str)
    }

    /// Limits of the moving joints from base to tip.
    pub fn limits(&self) -> impl ExactSizeIterator<Item = JointLimits> + '_ {
        self.joints.iter().map(|j| j.limits)
    }

    /// Picks this chain's joint positions out of a robot-wide position vector.
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] if `robot_positions` is too short for an index.
    pub fn gather(&self, robot_positions: &[f64], out: &mut [f64]) -> Result<(), KinematicsError> {
        if out.len() != self.dof() {
            return Err(KinematicsError::JointCount {
                expected: self.dof(),
                actual: out.len(),
            });
        }
        for (o, j) in out.iter_mut().zip(&self.joints) {
            *o = *robot_positions
                .get(j.robot_dof)
                .ok_or(KinematicsError::JointCount {
                    expected: j.robot_dof + 1,
                    actual: robot_positions.len(),
                })?;
        }
        Ok(())
    }

    fn check_len(&self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() == self.dof() {
            Ok(())
        } else {
            Err(KinematicsError::JointCount {
                expected: self.dof(),
                actual: q.len(),
            })
        }
    }

    /// Pose of the tip in the base frame.
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] if `q.len() != self.dof()`.
    pub fn end_pose(&self, q: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
        self.check_len(q)?;
        Ok(evaluate::<
            nalgebra::Dyn,
            nalgebra::VecStorage<f64, U6, nalgebra::Dyn>,
        >(&self.joints, &self.tip_offset, |i| q[i], None))
    }

    /// Tip pose and geometric Jacobian (rows: linear then angular velocity of the tip
    /// origin, both in the base frame), written into `jac` without allocating.
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] for a wrong-length `q`,
    /// [`KinematicsError::JacobianColumns`] if `jac` has the wrong width.
    pub fn end_pose_and_jacobian_into<C: Dim, S: StorageMut<f64, U6, C>>(
        &self,
        q: &[f64],
        jac: &mut Matrix<f64, U6, C, S>,
    ) -> Result<Isometry3<f64>, KinematicsError> {
        self.check_len(q)?;
        if jac.ncols() != self.dof() {
            return Err(KinematicsError::JacobianColumns {
                expected: self.dof(),
                actual: jac.ncols(),
            });
        }
        Ok(evaluate(
            &self.joints,
            &self.tip_offset,
            |i| q[i],
            Some(jac),
        ))
    }

    /// Allocating form of [`Chain::end_pose_and_jacobian_into`].
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] for a wrong-length `q`.
    pub fn end_pose_and_jacobian(
        &self,
        q: &[f64],
    ) -> Result<(Isometry3<f64>, Matrix6xX<f64>), KinematicsError> {
        let mut jac = Matrix6xX::zeros(self.dof());
        let pose = self.end_pose_and_jacobian_into(q, &mut jac)?;
        Ok((pose, jac))
    }

    /// Frames of each moving joint (after motion) and of the tip, in the base frame.
    /// `out` must hold `dof() + 1` entries; the last is the tip.
    ///
    /// # Errors
    /// [`KinematicsError::JointCount`] for a wrong-length `q` or `out`.
    pub fn frames_into(
        &self,
        q: &[f64],
        out: &mut [Isometry3<f64>],
    ) -> Result<(), KinematicsError> {
        self.check_len(q)?;
        if out.len() != self.dof() + 1 {
            return Err(KinematicsError::JointCount {
                expected: self.dof() + 1,
                actual: out.len(),
            });
        }
        let mut frame = Isometry3::identity();
        for (i, j) in self.joints.iter().enumerate() {
            frame = moved_frame(&frame, &j.origin, &j.axis, j.prismatic, q[i]);
            out[i] = frame;
        }
        out[self.dof()] = frame * self.tip_offset;
        Ok(())
    }

    /// The same chain with its DoF in the type.
    ///
    /// # Errors
    /// [`KinematicsError::ChainDof`] if the chain does not have exactly `N` moving joints.
    pub fn fixed<const N: usize>(&self) -> Result<FixedChain<N>, KinematicsError> {
        let joints: [ChainJoint; N] =
            self.joints
                .clone()
                .try_into()
                .map_err(|_| KinematicsError::ChainDof {
                    base: self.base_name.clone(),
                    tip: self.tip_name.clone(),
                    expected: N,
                    actual: self.dof(),
                })?;
        Ok(FixedChain {
            chain: self.clone(),
            joints,
            tip_offset: self.tip_offset,
        })
    }
}

/// A [`Chain`] with exactly `N` moving joints, evaluated on `SVector<f64, N>`.
#[derive(Debug, Clone)]
pub struct FixedChain<const N: usize> {
    chain: Chain,
    joints: [ChainJoint; N],
    tip_offset: Isometry3<f64>,
}

impl<const N: usize> FixedChain<N> {
    /// The dynamic form (names, base and tip).
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Pose of the tip in the base frame.
    pub fn end_pose(&self, q: &SVector<f64, N>) -> Isometry3<f64> {
        evaluate::<nalgebra::Const<N>, nalgebra::ArrayStorage<f64, 6, N>>(
            &self.joints,
            &self.tip_offset,
            |i| q[i],
            None,
        )
    }

    /// Tip pose and geometric Jacobian (linear rows then angular, base frame).
    pub fn end_pose_and_jacobian(
        &self,
        q: &SVector<f64, N>,
    ) -> (Isometry3<f64>, SMatrix<f64, 6, N>) {
        let mut jac = SMatrix::<f64, 6, N>::zeros();
        let pose = evaluate(&self.joints, &self.tip_offset, |i| q[i], Some(&mut jac));
        (pose, jac)
    }

    /// Lower position limits (`-inf` for continuous joints).
    pub fn lower_limits(&self) -> SVector<f64, N> {
        SVector::from_fn(|i, _| self.joints[i].limits.lower)
    }

    /// Upper position limits (`+inf` for continuous joints).
    pub fn upper_limits(&self) -> SVector<f64, N> {
        SVector::from_fn(|i, _| self.joints[i].limits.upper)
    }

    /// Velocity limits (rad/s or m/s) from the URDF.
    pub fn velocity_limits(&self) -> SVector<f64, N> {
        SVector::from_fn(|i, _| self.joints[i].limits.velocity)
    }

    /// `q` clamped into the position limits.
    pub fn clamp(&self, q: &SVector<f64, N>) -> SVector<f64, N> {
        SVector::from_fn(|i, _| self.joints[i].limits.clamp(q[i]))
    }

    /// True when every position lies within its limits.
    pub fn within_limits(&self, q: &SVector<f64, N>) -> bool {
        (0..N).all(|i| self.joints[i].limits.contains(q[i]))
    }

    /// Moving joints from base to tip.
    pub fn joints(&self) -> &[ChainJoint; N] {
        &self.joints
    }
}
