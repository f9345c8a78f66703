//! Distance constraints for the IK ([`teleop_ik::Goal::MinDistance`]).
//!
//! The solver hands a constraint the frames of one chain: `frames[i]` is the frame of
//! the chain's moving joint `i` after its motion, `frames[N]` the tip, all in the
//! **chain base frame**. In URDF semantics a joint's frame after its motion *is* its
//! child link's frame, so [`ChainBodies`] maps every link of the robot onto them once:
//!
//! * a link below chain joint `i` (and below no later chain joint) gets the pose
//!   `frames[i] · offset`, where `offset` is the link's pose in joint `i`'s child
//!   frame. Links hanging off through fixed joints (the camera on `tool0`, the
//!   Shadow palm's children when the chain ends at `rh_palm`) get a constant offset;
//!   links moved by joints that are not in the chain (the Shadow fingers below the
//!   PR2 arm chain) are frozen at a **rest configuration** given at construction;
//! * every other link is static in the base frame, also at the rest configuration.
//!
//! [`ChainVolumeDistance`] measures the links the chain moves against an
//! [`ExternalVolume`] posed in the chain base frame; [`ChainSelfDistance`] measures the
//! checked (not allowed, see [`crate::CollisionModel`]) link pairs whose relative pose
//! depends on the chain's joints. Both are cheap to rebuild per control step: the
//! mapping is shared through an [`Arc`].
//!
//! The solver differentiates these distances numerically
//! ([`teleop_ik::IkSettings::distance_fd_step`], default 1e-6 rad). The distances are
//! smooth to ~4e-8 m (see [`crate::geometry`]), so that step gives gradients within a
//! few per cent; the tests here use the default. Where a link penetrates deeply and
//! EPA switches features the depth can jump by ~1e-5 m; a larger step (1e-5 rad)
//! averages over that if a solve ever stalls inside a volume.
//!
//! The distance is the minimum over link pairs, so its gradient switches when the
//! closest pair changes; the solver copes (it is a penalty on `max(0, min - d)`),
//! but a solution can sit where two pairs are equally close.

use std::sync::Arc;

use nalgebra::Isometry3;
use teleop_ik::DistanceConstraint;
use teleop_kinematics::{FixedChain, LinkId, Robot};

use crate::body::{LinkBody, PosedBodies, min_group_distance, min_pair_distance};
use crate::error::CollisionError;
use crate::model::{CollisionModel, LinkPairProximity, VolumeProximity};
use crate::volume::ExternalVolume;

/// Where a body sits relative to the chain frames.
#[derive(Debug, Clone, Copy)]
struct Anchor {
    /// Chain joint whose frame carries the body; `None`: static in the base frame.
    frame: Option<usize>,
    /// Body link frame in that frame.
    offset: Isometry3<f64>,
}

/// The robot's collision bodies mapped onto the frames of a chain with `N` moving
/// joints (see the module docs).
#[derive(Debug, Clone)]
pub struct ChainBodies<const N: usize> {
    /// Bodies the chain moves first (`..moving`), then the static ones.
    bodies: Vec<LinkBody>,
    anchors: Vec<Anchor>,
    moving: usize,
    /// Checked pairs whose relative pose depends on the chain (indices into `bodies`).
    self_pairs: Vec<(u32, u32)>,
}

impl<const N: usize> ChainBodies<N> {
    /// The mapping with the robot's other joints at [`Robot::neutral_positions`].
    ///
    /// # Errors
    /// As [`ChainBodies::with_rest`].
    pub fn new(
        model: &CollisionModel,
        robot: &Robot,
        chain: &FixedChain<N>,
    ) -> Result<Self, CollisionError> {
        Self::with_rest(model, robot, chain, &robot.neutral_positions())
    }

    /// The mapping with the joints outside the chain at `rest_positions` (a full
    /// robot joint vector; its chain entries are ignored).
    ///
    /// # Errors
    /// [`CollisionError::RobotMismatch`] if `model` was not built from `robot` or
    /// `chain` does not belong to it, [`CollisionError::Kinematics`] for a
    /// wrong-length `rest_positions`.
    pub fn with_rest(
        model: &CollisionModel,
        robot: &Robot,
        chain: &FixedChain<N>,
        rest_positions: &[f64],
    ) -> Result<Self, CollisionError> {
        let mismatch = |what: String| CollisionError::RobotMismatch {
            robot: model.robot_name().to_owned(),
            what,
        };
        if model.robot_name() != robot.name() || model.link_count() != robot.links().len() {
            return Err(mismatch(format!("robot `{}`", robot.name())));
        }
        let dyn_chain = chain.chain();
        let belongs = |id: LinkId, name: &str| {
            id.index() < robot.links().len() && robot.link(id).name == name
        };
        if !belongs(dyn_chain.base(), dyn_chain.base_name())
            || !belongs(dyn_chain.tip(), dyn_chain.tip_name())
        {
            return Err(mismatch(format!(
                "chain `{}` -> `{}`",
                dyn_chain.base_name(),
                dyn_chain.tip_name()
            )));
        }

        let link_poses = robot.forward_kinematics(rest_positions)?;
        let base_inv = link_poses[dyn_chain.base().index()].inverse();
        // Child link of each chain joint = the link carried by that joint's frame.
        let children: Vec<LinkId> = chain
            .joints()
            .iter()
            .map(|j| robot.joint(j.joint).child)
            .collect();

        let mut moving = Vec::new();
        let mut fixed = Vec::new();
        for (model_index, body) in model.bodies().iter().enumerate() {
            let link = body.link();
            let pose = link_poses[link.index()];
            let anchor = match (0..N).rev().find(|&i| robot.is_ancestor(children[i], link)) {
                Some(i) => Anchor {
                    frame: Some(i),
                    offset: link_poses[children[i].index()].inv_mul(&pose),
                },
                None => Anchor {
                    frame: None,
                    offset: base_inv * pose,
                },
            };
            if anchor.frame.is_some() {
                moving.push((model_index, anchor));
            } else {
                fixed.push((model_index, anchor));
            }
        }
        let n_moving = moving.len();
        let order: Vec<(usize, Anchor)> = moving.into_iter().chain(fixed).collect();
        let mut position_of = vec![0u32; model.bodies().len()];
        for (k, (model_index, _)) in order.iter().enumerate() {
            position_of[*model_index] = k as u32;
        }
        let anchors: Vec<Anchor> = order.iter().map(|(_, a)| *a).collect();
        let self_pairs = model
            .checked_body_pairs()
            .iter()
            .map(|&(i, j)| (position_of[i as usize], position_of[j as usize]))
            // A pair carried by the same frame (or both static) keeps its distance.
            .filter(|&(i, j)| anchors[i as usize].frame != anchors[j as usize].frame)
            .collect();
        Ok(Self {
            bodies: order
                .iter()
                .map(|(i, _)| model.bodies()[*i].clone())
                .collect(),
            anchors,
            moving: n_moving,
            self_pairs,
        })
    }

    /// Links whose pose depends on the chain's joints.
    pub fn moving_links(&self) -> impl ExactSizeIterator<Item = LinkId> + '_ {
        self.bodies[..self.moving].iter().map(LinkBody::link)
    }

    /// Link pairs [`ChainSelfDistance`] checks.
    pub fn self_pairs(&self) -> impl ExactSizeIterator<Item = (LinkId, LinkId)> + '_ {
        self.self_pairs.iter().map(|&(i, j)| {
            (
                self.bodies[i as usize].link(),
                self.bodies[j as usize].link(),
            )
        })
    }

    /// Pose of every link with geometry in the chain base frame, as the constraints
    /// see it for these frames: moving links first, then the static ones.
    ///
    /// # Errors
    /// [`CollisionError::FrameCount`] if `frames` has fewer than `N` entries.
    pub fn link_poses(
        &self,
        frames: &[Isometry3<f64>],
    ) -> Result<Vec<(LinkId, Isometry3<f64>)>, CollisionError> {
        let poses = self.poses(frames, self.bodies.len())?;
        Ok(self.bodies.iter().map(LinkBody::link).zip(poses).collect())
    }

    /// Poses (chain base frame) of the first `count` bodies.
    fn poses<'a>(
        &'a self,
        frames: &'a [Isometry3<f64>],
        count: usize,
    ) -> Result<impl Iterator<Item = Isometry3<f64>> + 'a, CollisionError> {
        if frames.len() < N {
            return Err(CollisionError::FrameCount {
                expected: N,
                actual: frames.len(),
            });
        }
        Ok(self.anchors[..count].iter().map(|a| match a.frame {
            Some(i) => frames[i] * a.offset,
            None => a.offset,
        }))
    }

    /// The moving link closest to `volume` (posed in the chain base frame); `None` if
    /// the chain moves no geometry or the volume is empty.
    ///
    /// # Errors
    /// [`CollisionError::FrameCount`] if `frames` has fewer than `N` entries.
    pub fn volume_distance(
        &self,
        frames: &[Isometry3<f64>],
        volume: &ExternalVolume,
    ) -> Result<Option<VolumeProximity>, CollisionError> {
        let posed = PosedBodies::new(
            &self.bodies[..self.moving],
            self.poses(frames, self.moving)?,
        );
        Ok(
            min_group_distance(&posed, &volume.group()).map(|(d, i, j)| VolumeProximity {
                distance_m: d,
                link: self.bodies[i].link(),
                volume_shape: j,
            }),
        )
    }

    /// The closest checked link pair whose distance depends on the chain; `None` if
    /// there is none.
    ///
    /// # Errors
    /// [`CollisionError::FrameCount`] if `frames` has fewer than `N` entries.
    pub fn self_distance(
        &self,
        frames: &[Isometry3<f64>],
    ) -> Result<Option<LinkPairProximity>, CollisionError> {
        let posed = PosedBodies::new(&self.bodies, self.poses(frames, self.bodies.len())?);
        Ok(min_pair_distance(&posed, &self.self_pairs).map(|(d, k)| {
            let (i, j) = self.self_pairs[k];
            LinkPairProximity {
                distance_m: d,
                a: self.bodies[i as usize].link(),
                b: self.bodies[j as usize].link(),
            }
        }))
    }
}

/// Distance from the links a chain moves to an external volume, for
/// [`teleop_ik::Goal::MinDistance`]. `+inf` when there is nothing to measure,
/// `-inf` (maximal violation) if the solver passes too few frames.
#[derive(Debug, Clone)]
pub struct ChainVolumeDistance<const N: usize> {
    bodies: Arc<ChainBodies<N>>,
    volume: ExternalVolume,
}

impl<const N: usize> ChainVolumeDistance<N> {
    /// The constraint for `volume`, posed in the chain base frame.
    pub fn new(bodies: Arc<ChainBodies<N>>, volume: ExternalVolume) -> Self {
        Self { bodies, volume }
    }

    /// The volume.
    pub fn volume(&self) -> &ExternalVolume {
        &self.volume
    }

    /// The body mapping.
    pub fn bodies(&self) -> &Arc<ChainBodies<N>> {
        &self.bodies
    }
}

impl<const N: usize> DistanceConstraint<N> for ChainVolumeDistance<N> {
    fn distance(&self, frames: &[Isometry3<f64>]) -> f64 {
        match self.bodies.volume_distance(frames, &self.volume) {
            Ok(Some(p)) => p.distance_m,
            Ok(None) => f64::INFINITY,
            Err(_) => f64::NEG_INFINITY,
        }
    }
}

/// Smallest self-collision distance that depends on a chain's joints, for
/// [`teleop_ik::Goal::MinDistance`]. `+inf` when no pair is checked, `-inf` if the
/// solver passes too few frames.
#[derive(Debug, Clone)]
pub struct ChainSelfDistance<const N: usize> {
    bodies: Arc<ChainBodies<N>>,
}

impl<const N: usize> ChainSelfDistance<N> {
    /// The constraint over `bodies`' checked pairs.
    pub fn new(bodies: Arc<ChainBodies<N>>) -> Self {
        Self { bodies }
    }

    /// The body mapping.
    pub fn bodies(&self) -> &Arc<ChainBodies<N>> {
        &self.bodies
    }
}

impl<const N: usize> DistanceConstraint<N> for ChainSelfDistance<N> {
    fn distance(&self, frames: &[Isometry3<f64>]) -> f64 {
        match self.bodies.self_distance(frames) {
            Ok(Some(p)) => p.distance_m,
            Ok(None) => f64::INFINITY,
            Err(_) => f64::NEG_INFINITY,
        }
    }
}
