//! [`CollisionModel`]: a robot's collision primitives per link, its allowed-collision
//! matrix, and the queries at one configuration.
//!
//! Queries take the pose of every robot link in the robot's root frame, indexed by
//! [`LinkId::index`] — what [`Robot::forward_kinematics`] or
//! [`Robot::link_poses_into`] return — and, for external volumes, a volume posed in
//! the same root frame. Distances are signed, in metres: the gap between the closest
//! surfaces, negative (minus the penetration depth) when they overlap. "Collides"
//! means signed distance `<= 0` (touching counts).
//!
//! # Geometry
//!
//! Each URDF collision primitive becomes a [`PlacedShape`] in its link frame. URDF
//! has no capsule that every tool reads, so our URDFs model one as a cylinder plus a
//! sphere of the same radius on one or both end centres (the Shadow phalanges: a
//! cylinder from the joint and a sphere at the far end). With
//! [`ModelSettings::merge_capsules`] (default) such a group becomes one capsule of
//! the cylinder's length and radius: one exact, closed-form query instead of GJK on a
//! cylinder (capsule–capsule ~90 ns, cylinder–cylinder ~400 ns per shape pair). Where only one end had a sphere, the capsule
//! adds a hemisphere at the other end; on the Shadow hand that end is the joint, and
//! the hemisphere lies inside the parent link's end sphere (which is at least as
//! large) or, at the knuckles, 0.5 mm outside the knuckle sphere — the model grows by
//! at most that. Cylinders with spheres of another radius (the UR5 upper arm) are
//! left as they are.
//!
//! # Allowed-collision matrix (ACM)
//!
//! Self-collision checks every pair of links that both carry geometry, except the
//! pairs the ACM allows. Generation follows MoveIt's setup assistant, simplified:
//!
//! 1. [`AllowReason::Adjacent`]: a link and its nearest ancestor that has geometry
//!    (links without geometry, such as `tool0` or the Shadow `rh_ffmcp` frames, are
//!    skipped, as MoveIt does), i.e. the two bodies a joint connects. One extension:
//!    when that ancestor is only a joint cross — the link's frame sits at the
//!    ancestor's origin, all joints in between revolute or fixed with zero
//!    translation, like the Shadow knuckles between J4 and J3 or the PR2
//!    `r_shoulder_lift_link` between the lift and roll axes — the two links on either
//!    side of it meet at one point like a universal joint, so the link is also
//!    adjacent to the next ancestor with geometry (and so on while the origins stay
//!    coincident). Without it the proximal phalanges' cylinder rims, which rotate
//!    about the knuckle centre, would be reported against the palm box whenever a
//!    finger flexes past ~70 degrees.
//! 2. [`AllowReason::Default`]: pairs in collision at the neutral configuration
//!    ([`Robot::neutral_positions`]: zero, clamped into the limits).
//! 3. [`AllowReason::Always`]: pairs in collision in at least
//!    [`ModelSettings::always_fraction`] of [`ModelSettings::random_samples`]
//!    configurations drawn uniformly within the joint limits (continuous joints in
//!    `[-pi, pi]`) from a generator seeded with [`ModelSettings::seed`], so the matrix is
//!    reproducible.
//! 4. [`AllowReason::User`]: added with [`CollisionModel::allow`].
//!
//! MoveIt also disables pairs never seen colliding in its samples ("Never"); that is a
//! speed-up that can miss rare collisions, and the broad phase here makes it
//! unnecessary, so it is not done. Pairs that collide only sometimes stay checked even
//! when the model's geometry is coarser than the robot (see [`crate::robots`] for the
//! pairs added by hand for the robots of this system, with reasons).
//!
//! Checked pairs are kept in order of how often they collided in the samples, most
//! often first, so a boolean check on a colliding configuration usually stops at
//! one of the first pairs it tries.

use nalgebra::{Isometry3, Point3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_kinematics::{JointKind, LinkId, Robot};

use crate::body::{
    LinkBody, PosedBodies, any_collides_with_group, any_pair_collides, colliding_pairs,
    min_group_distance, min_pair_distance, pair_collides,
};
use crate::error::CollisionError;
use crate::geometry::{PlacedShape, Primitive};
use crate::volume::ExternalVolume;

/// Merge tolerance: sphere radius vs. cylinder radius, sphere centre vs. cylinder end
/// centre (m).
const MERGE_TOLERANCE_M: f64 = 1e-9;

/// Replaces each cylinder that has a sphere of its radius on an end centre by a
/// capsule of the cylinder's length and radius, dropping those spheres.
fn merge_capsules(shapes: Vec<(Primitive, Isometry3<f64>)>) -> Vec<(Primitive, Isometry3<f64>)> {
    let mut consumed = vec![false; shapes.len()];
    let mut merged = shapes.clone();
    for (k, (shape, origin)) in shapes.iter().enumerate() {
        let Primitive::Cylinder {
            half_length_m,
            radius_m,
        } = *shape
        else {
            continue;
        };
        let ends = [
            origin * Point3::new(0.0, 0.0, half_length_m),
            origin * Point3::new(0.0, 0.0, -half_length_m),
        ];
        let mut capped = false;
        for (j, (other, at)) in shapes.iter().enumerate() {
            if let Primitive::Sphere { radius_m: r } = *other
                && !consumed[j]
                && (r - radius_m).abs() <= MERGE_TOLERANCE_M
                && ends
                    .iter()
                    .any(|e| (at.translation.vector - e.coords).norm() <= MERGE_TOLERANCE_M)
            {
                consumed[j] = true;
                capped = true;
            }
        }
        if capped {
            merged[k].0 = Primitive::Capsule {
                half_length_m,
                radius_m,
            };
        }
    }
    merged
        .into_iter()
        .zip(consumed)
        .filter_map(|(s, gone)| (!gone).then_some(s))
        .collect()
}

/// Joint origins closer than this to their parent frame's origin count as coincident.
const COINCIDENT_M: f64 = 1e-9;

/// Why a link pair is excluded from self-collision checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum AllowReason {
    /// The two links are connected by a joint (links without geometry skipped).
    Adjacent,
    /// In collision at the neutral configuration.
    Default,
    /// In collision in (nearly) every random configuration.
    Always,
    /// Allowed by hand ([`CollisionModel::allow`]).
    User,
}

/// How the geometry is converted and the allowed-collision matrix generated (see the
/// module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelSettings {
    /// Turn a URDF cylinder with a sphere of the same radius on one or both end
    /// centres into one capsule (see the module docs).
    pub merge_capsules: bool,
    /// Random configurations sampled for [`AllowReason::Always`]; 0 skips the step.
    pub random_samples: u32,
    /// A pair colliding in at least this fraction of the samples is allowed, in
    /// `(0, 1]`. MoveIt's setup assistant uses 0.95.
    pub always_fraction: f64,
    /// Seed of the sampler.
    pub seed: u64,
}

impl Default for ModelSettings {
    fn default() -> Self {
        Self {
            merge_capsules: true,
            random_samples: 1000,
            always_fraction: 0.95,
            seed: 0,
        }
    }
}

/// Signed distance between a robot link and an external volume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumeProximity {
    /// Signed distance (m), negative when penetrating.
    pub distance_m: f64,
    /// The closest link.
    pub link: LinkId,
    /// Index of the closest primitive in [`ExternalVolume::shapes`].
    pub volume_shape: usize,
}

/// Signed distance between two links of the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkPairProximity {
    /// Signed distance (m), negative when penetrating.
    pub distance_m: f64,
    /// One link.
    pub a: LinkId,
    /// The other link.
    pub b: LinkId,
}

/// A robot's collision geometry and allowed-collision matrix. Built once per robot;
/// queries are `&self` and allocate only small scratch vectors.
#[derive(Debug, Clone)]
pub struct CollisionModel {
    robot_name: String,
    link_names: Vec<String>,
    bodies: Vec<LinkBody>,
    body_of_link: Vec<Option<u32>>,
    /// `bodies.len()²`, symmetric.
    acm: Vec<Option<AllowReason>>,
    /// How often each pair collided in the ACM samples (`bodies.len()²`).
    sample_hits: Vec<u32>,
    /// Checked pairs `(i, j)`, `i < j`, body indices, most often colliding first.
    pairs: Vec<(u32, u32)>,
}

impl CollisionModel {
    /// The model of `robot` with the ACM generated by [`ModelSettings::default`].
    ///
    /// # Errors
    /// As [`CollisionModel::with_settings`].
    pub fn new(robot: &Robot) -> Result<Self, CollisionError> {
        Self::with_settings(robot, ModelSettings::default())
    }

    /// The model of `robot`: one body per link with collision primitives, and the ACM
    /// generated as the module docs describe.
    ///
    /// # Errors
    /// [`CollisionError::UnsupportedShape`] for mesh geometry,
    /// [`CollisionError::InvalidShape`] for bad dimensions,
    /// [`CollisionError::InvalidSettings`] for an `always_fraction` outside `(0, 1]`.
    pub fn with_settings(robot: &Robot, settings: ModelSettings) -> Result<Self, CollisionError> {
        if !(settings.always_fraction > 0.0 && settings.always_fraction <= 1.0) {
            return Err(CollisionError::InvalidSettings {
                reason: "always_fraction must lie in (0, 1]",
            });
        }
        let mut bodies = Vec::new();
        let mut body_of_link = vec![None; robot.links().len()];
        // Depth-first order: a body's parent-side bodies come first.
        for &id in robot.links_depth_first() {
            let link = robot.link(id);
            if link.collisions.is_empty() {
                continue;
            }
            let mut primitives = link
                .collisions
                .iter()
                .map(|c| Ok((Primitive::from_urdf(&c.shape, &link.name)?, c.origin)))
                .collect::<Result<Vec<_>, CollisionError>>()?;
            if settings.merge_capsules {
                primitives = merge_capsules(primitives);
            }
            let shapes = primitives
                .into_iter()
                .map(|(p, origin)| PlacedShape::new(p, origin, 0.0, &link.name))
                .collect::<Result<Vec<_>, _>>()?;
            body_of_link[id.index()] = Some(bodies.len() as u32);
            bodies.push(LinkBody::new(id, link.name.clone(), shapes));
        }
        let (acm, sample_hits) = generate_acm(robot, &bodies, &body_of_link, &settings)?;
        let mut model = Self {
            robot_name: robot.name().to_owned(),
            link_names: robot.links().iter().map(|l| l.name.clone()).collect(),
            acm,
            sample_hits,
            bodies,
            body_of_link,
            pairs: Vec::new(),
        };
        model.rebuild_pairs();
        Ok(model)
    }

    fn set_reason(&mut self, i: usize, j: usize, reason: Option<AllowReason>) {
        let n = self.bodies.len();
        self.acm[i * n + j] = reason;
        self.acm[j * n + i] = reason;
    }

    fn reason_at(&self, i: usize, j: usize) -> Option<AllowReason> {
        self.acm[i * self.bodies.len() + j]
    }

    fn rebuild_pairs(&mut self) {
        let n = self.bodies.len();
        self.pairs.clear();
        for i in 0..n {
            for j in i + 1..n {
                if self.reason_at(i, j).is_none() {
                    self.pairs.push((i as u32, j as u32));
                }
            }
        }
        // A boolean check stops at the first hit: try the usual suspects first.
        let hits = &self.sample_hits;
        self.pairs
            .sort_by_key(|&(i, j)| std::cmp::Reverse(hits[i as usize * n + j as usize]));
    }

    /// `<robot name=...>` of the robot the model was built from.
    pub fn robot_name(&self) -> &str {
        &self.robot_name
    }

    /// Links with collision geometry, in depth-first order.
    pub fn bodies(&self) -> &[LinkBody] {
        &self.bodies
    }

    /// The geometry of `link`, if it has any.
    pub fn body(&self, link: LinkId) -> Option<&LinkBody> {
        self.body_index(link).map(|i| &self.bodies[i])
    }

    pub(crate) fn body_index(&self, link: LinkId) -> Option<usize> {
        self.body_of_link
            .get(link.index())
            .copied()
            .flatten()
            .map(|i| i as usize)
    }

    /// Number of links of the robot (length of the pose slices queries take).
    pub fn link_count(&self) -> usize {
        self.link_names.len()
    }

    /// Why the pair `(a, b)` is not checked, or `None` if it is checked (or either
    /// link has no geometry).
    pub fn allowed(&self, a: LinkId, b: LinkId) -> Option<AllowReason> {
        let (i, j) = (self.body_index(a)?, self.body_index(b)?);
        if i == j {
            return None;
        }
        self.reason_at(i, j)
    }

    /// Every allowed pair with its reason.
    pub fn allowed_pairs(&self) -> impl Iterator<Item = (LinkId, LinkId, AllowReason)> + '_ {
        let n = self.bodies.len();
        (0..n).flat_map(move |i| {
            (i + 1..n).filter_map(move |j| {
                self.reason_at(i, j)
                    .map(|r| (self.bodies[i].link(), self.bodies[j].link(), r))
            })
        })
    }

    /// Every pair that self-collision queries check.
    pub fn checked_pairs(&self) -> impl ExactSizeIterator<Item = (LinkId, LinkId)> + '_ {
        self.pairs.iter().map(|&(i, j)| {
            (
                self.bodies[i as usize].link(),
                self.bodies[j as usize].link(),
            )
        })
    }

    pub(crate) fn checked_body_pairs(&self) -> &[(u32, u32)] {
        &self.pairs
    }

    fn body_by_name(&self, name: &str) -> Result<usize, CollisionError> {
        let Some(link) = self.link_names.iter().position(|n| n == name) else {
            return Err(CollisionError::UnknownLink {
                link: name.to_owned(),
            });
        };
        self.body_of_link[link]
            .map(|i| i as usize)
            .ok_or_else(|| CollisionError::NoGeometry {
                link: name.to_owned(),
            })
    }

    /// Excludes the pair `(a, b)` from self-collision checks ([`AllowReason::User`];
    /// a pair already allowed keeps its reason).
    ///
    /// # Errors
    /// [`CollisionError::UnknownLink`] or [`CollisionError::NoGeometry`].
    pub fn allow(&mut self, a: &str, b: &str) -> Result<(), CollisionError> {
        let (i, j) = (self.body_by_name(a)?, self.body_by_name(b)?);
        if i != j && self.reason_at(i, j).is_none() {
            self.set_reason(i, j, Some(AllowReason::User));
            self.rebuild_pairs();
        }
        Ok(())
    }

    /// Checks the pair `(a, b)` again, whatever the reason it was allowed for.
    ///
    /// # Errors
    /// [`CollisionError::UnknownLink`] or [`CollisionError::NoGeometry`].
    pub fn disallow(&mut self, a: &str, b: &str) -> Result<(), CollisionError> {
        let (i, j) = (self.body_by_name(a)?, self.body_by_name(b)?);
        if i != j && self.reason_at(i, j).is_some() {
            self.set_reason(i, j, None);
            self.rebuild_pairs();
        }
        Ok(())
    }

    /// The bodies posed from link poses (one per robot link, root frame).
    fn posed<'a>(
        &'a self,
        link_poses: &[Isometry3<f64>],
    ) -> Result<PosedBodies<'a>, CollisionError> {
        if link_poses.len() != self.link_names.len() {
            return Err(CollisionError::PoseCount {
                expected: self.link_names.len(),
                actual: link_poses.len(),
            });
        }
        Ok(PosedBodies::new(
            &self.bodies,
            self.bodies.iter().map(|b| link_poses[b.link().index()]),
        ))
    }

    /// The link closest to `volume` and its signed distance; `None` if the robot has no
    /// geometry or the volume is empty.
    ///
    /// # Errors
    /// [`CollisionError::PoseCount`] unless `link_poses` holds one pose per link.
    pub fn volume_distance(
        &self,
        link_poses: &[Isometry3<f64>],
        volume: &ExternalVolume,
    ) -> Result<Option<VolumeProximity>, CollisionError> {
        let posed = self.posed(link_poses)?;
        Ok(
            min_group_distance(&posed, &volume.group()).map(|(d, i, j)| VolumeProximity {
                distance_m: d,
                link: self.bodies[i].link(),
                volume_shape: j,
            }),
        )
    }

    /// True when any link touches or penetrates `volume`.
    ///
    /// # Errors
    /// [`CollisionError::PoseCount`] unless `link_poses` holds one pose per link.
    pub fn collides_with(
        &self,
        link_poses: &[Isometry3<f64>],
        volume: &ExternalVolume,
    ) -> Result<bool, CollisionError> {
        let posed = self.posed(link_poses)?;
        Ok(any_collides_with_group(&posed, &volume.group()))
    }

    /// The closest checked (not allowed) link pair and its signed distance; `None` if
    /// no pair is checked.
    ///
    /// # Errors
    /// [`CollisionError::PoseCount`] unless `link_poses` holds one pose per link.
    pub fn self_distance(
        &self,
        link_poses: &[Isometry3<f64>],
    ) -> Result<Option<LinkPairProximity>, CollisionError> {
        let posed = self.posed(link_poses)?;
        Ok(min_pair_distance(&posed, &self.pairs).map(|(d, k)| {
            let (i, j) = self.pairs[k];
            LinkPairProximity {
                distance_m: d,
                a: self.bodies[i as usize].link(),
                b: self.bodies[j as usize].link(),
            }
        }))
    }

    /// Every checked link pair in collision, with its signed distance (`<= 0`).
    ///
    /// # Errors
    /// [`CollisionError::PoseCount`] unless `link_poses` holds one pose per link.
    pub fn self_collisions(
        &self,
        link_poses: &[Isometry3<f64>],
    ) -> Result<Vec<LinkPairProximity>, CollisionError> {
        let posed = self.posed(link_poses)?;
        let mut hits = Vec::new();
        colliding_pairs(&posed, &self.pairs, &mut hits);
        Ok(hits
            .into_iter()
            .map(|(k, d)| {
                let (i, j) = self.pairs[k];
                LinkPairProximity {
                    distance_m: d,
                    a: self.bodies[i as usize].link(),
                    b: self.bodies[j as usize].link(),
                }
            })
            .collect())
    }

    /// True when any checked link pair is in collision (stops at the first).
    ///
    /// # Errors
    /// [`CollisionError::PoseCount`] unless `link_poses` holds one pose per link.
    pub fn in_self_collision(&self, link_poses: &[Isometry3<f64>]) -> Result<bool, CollisionError> {
        let posed = self.posed(link_poses)?;
        Ok(any_pair_collides(&posed, &self.pairs))
    }
}

/// The ACM as the module docs describe, and how often each pair collided in the
/// random samples; `bodies.len()²` entries each, symmetric.
fn generate_acm(
    robot: &Robot,
    bodies: &[LinkBody],
    body_of_link: &[Option<u32>],
    settings: &ModelSettings,
) -> Result<(Vec<Option<AllowReason>>, Vec<u32>), CollisionError> {
    let n = bodies.len();
    let mut acm = vec![None; n * n];
    let mut sample_hits = vec![0u32; n * n];
    // 1. Adjacent: nearest ancestor with geometry, and further ancestors while
    //    the links in between are joint crosses (zero-translation joints).
    for i in 0..n {
        let mut cur = bodies[i].link();
        let mut coincident = true;
        loop {
            let mut ancestor = None;
            while let Some(jid) = robot.link(cur).parent_joint {
                let joint = robot.joint(jid);
                coincident &= joint.origin.translation.vector.norm() <= COINCIDENT_M
                    && joint.kind != JointKind::Prismatic;
                cur = joint.parent;
                if let Some(j) = body_of_link[cur.index()] {
                    ancestor = Some(j as usize);
                    break;
                }
            }
            let Some(j) = ancestor else { break };
            acm[i * n + j] = Some(AllowReason::Adjacent);
            acm[j * n + i] = Some(AllowReason::Adjacent);
            if !coincident {
                break;
            }
        }
    }
    let mut state = robot.new_state();
    let mut pose_at = |q: &[f64]| -> Result<PosedBodies<'_>, CollisionError> {
        robot.update(&mut state, q)?;
        Ok(PosedBodies::new(
            bodies,
            bodies.iter().map(|b| robot.link_pose(&state, b.link())),
        ))
    };
    // 2. Default: colliding at the neutral configuration.
    let posed = pose_at(&robot.neutral_positions())?;
    let mut open: Vec<(usize, usize)> = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            if acm[i * n + j].is_some() {
                continue;
            }
            if pair_collides(&posed, i, j) {
                acm[i * n + j] = Some(AllowReason::Default);
                acm[j * n + i] = Some(AllowReason::Default);
            } else {
                open.push((i, j));
            }
        }
    }
    // 3. Always: colliding in at least `always_fraction` of random samples.
    if settings.random_samples > 0 && !open.is_empty() {
        let limits: Vec<(f64, f64)> = robot
            .dof_limits()
            .map(|l| {
                let pi = std::f64::consts::PI;
                let lo = if l.lower.is_finite() { l.lower } else { -pi };
                let hi = if l.upper.is_finite() { l.upper } else { pi };
                (lo, hi)
            })
            .collect();
        let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
        let mut q = vec![0.0; limits.len()];
        let mut hits = vec![0u32; open.len()];
        for _ in 0..settings.random_samples {
            for (v, (lo, hi)) in q.iter_mut().zip(&limits) {
                *v = if hi > lo {
                    rng.random_range(*lo..=*hi)
                } else {
                    *lo
                };
            }
            let posed = pose_at(&q)?;
            for (h, &(i, j)) in hits.iter_mut().zip(&open) {
                if pair_collides(&posed, i, j) {
                    *h += 1;
                }
            }
        }
        let needed = (settings.always_fraction * f64::from(settings.random_samples)).ceil();
        for (h, &(i, j)) in hits.iter().zip(&open) {
            sample_hits[i * n + j] = *h;
            sample_hits[j * n + i] = *h;
            if f64::from(*h) >= needed {
                acm[i * n + j] = Some(AllowReason::Always);
                acm[j * n + i] = Some(AllowReason::Always);
            }
        }
    }
    Ok((acm, sample_hits))
}
