//! The kinematic tree: links, joints, limits, inertia and collision primitives,
//! built from URDF with [`urdf_rs`].
//!
//! Loading checks the description once (one root, a tree, no unknown links, finite
//! numbers, valid limits, non-zero axes) so evaluation never has to. Fixed joints
//! are kept by name (they carry frames such as `rh_fftip`) but folded out of the
//! evaluation: each moving joint stores its origin relative to the nearest moving
//! ancestor, and each link stores its offset from the moving joint that carries it.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::error::KinematicsError;

/// Index of a link in [`Robot::links`]. Only meaningful for the robot that issued it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LinkId(pub(crate) usize);

impl LinkId {
    /// Position in [`Robot::links`].
    pub fn index(self) -> usize {
        self.0
    }
}

/// Index of a joint in [`Robot::joints`]. Only meaningful for the robot that issued it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JointId(pub(crate) usize);

impl JointId {
    /// Position in [`Robot::joints`].
    pub fn index(self) -> usize {
        self.0
    }
}

/// How a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis, limited.
    Revolute,
    /// Rotation about the axis, unlimited.
    Continuous,
    /// Translation along the axis, limited.
    Prismatic,
    /// No motion; the origin alone places the child.
    Fixed,
}

impl JointKind {
    /// True for every kind that has a joint position.
    pub fn is_moving(self) -> bool {
        !matches!(self, JointKind::Fixed)
    }
}

/// Position, velocity and effort limits of a moving joint (SI units: rad or m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lowest position (rad or m); `-inf` for continuous joints.
    pub lower: f64,
    /// Highest position (rad or m); `+inf` for continuous joints.
    pub upper: f64,
    /// Largest speed (rad/s or m/s) from the URDF `velocity` attribute.
    pub velocity: f64,
    /// Largest effort (N m or N) from the URDF `effort` attribute.
    pub effort: f64,
}

impl JointLimits {
    /// True when `position` lies within `[lower, upper]`.
    pub fn contains(&self, position: f64) -> bool {
        position >= self.lower && position <= self.upper
    }

    /// `position` clamped into `[lower, upper]`.
    pub fn clamp(&self, position: f64) -> f64 {
        position.clamp(self.lower, self.upper)
    }

    /// True when both bounds are finite (not a continuous joint).
    pub fn is_bounded(&self) -> bool {
        self.lower.is_finite() && self.upper.is_finite()
    }
}

/// One joint as written in the URDF, fixed joints included.
#[derive(Debug, Clone)]
pub struct Joint {
    /// URDF name.
    pub name: String,
    /// Motion type.
    pub kind: JointKind,
    /// Parent link.
    pub parent: LinkId,
    /// Child link.
    pub child: LinkId,
    /// Child frame relative to the parent link frame at zero position.
    pub origin: Isometry3<f64>,
    /// Unit axis in the joint frame (x for fixed joints, unused).
    pub axis: Unit<Vector3<f64>>,
    /// Limits for moving joints, `None` for fixed joints.
    pub limits: Option<JointLimits>,
    /// Index into the joint-position vector, `None` for fixed joints.
    pub dof: Option<usize>,
}

/// Mass properties of a link, in the link frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertial {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Frame of the centre of mass; `inertia` is expressed in its axes.
    pub origin: Isometry3<f64>,
    /// Inertia tensor about the centre of mass (kg m^2).
    pub inertia: Matrix3<f64>,
}

/// A collision primitive. URDF meshes are kept by name so a later stage can decide
/// what to do with them; the robots shipped here use primitives only.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Shape {
    /// Axis-aligned box with full side lengths (m).
    Box {
        /// Side lengths along x, y, z.
        size: Vector3<f64>,
    },
    /// Cylinder along the local z axis, centred on the origin.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Full length (m).
        length: f64,
    },
    /// Capsule along the local z axis; `length` excludes the two caps.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part (m).
        length: f64,
    },
    /// Sphere centred on the origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A mesh file, not loaded.
    Mesh {
        /// The filename as written.
        filename: String,
        /// Scale per axis.
        scale: Vector3<f64>,
    },
}

/// A collision primitive placed in its link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionShape {
    /// `<collision name=...>` when given.
    pub name: Option<String>,
    /// Shape frame in the link frame.
    pub origin: Isometry3<f64>,
    /// The primitive.
    pub shape: Shape,
}

/// One link.
#[derive(Debug, Clone)]
pub struct Link {
    /// URDF name.
    pub name: String,
    /// The joint whose child this link is; `None` for the root.
    pub parent_joint: Option<JointId>,
    /// Joints whose parent this link is.
    pub child_joints: Vec<JointId>,
    /// Mass properties (`None` if the URDF gives no `<inertial>` or a zero mass).
    pub inertial: Option<Inertial>,
    /// Collision primitives.
    pub collisions: Vec<CollisionShape>,
}

/// A moving joint after folding fixed joints: what evaluation needs.
#[derive(Debug, Clone)]
pub(crate) struct Dof {
    /// Nearest moving ancestor (index into `dofs`), `None` if only fixed joints lie
    /// between this joint and the root.
    pub parent: Option<usize>,
    /// Joint frame (at zero position) relative to the parent's moving frame, or to
    /// the root link frame.
    pub origin: Isometry3<f64>,
    pub axis: Unit<Vector3<f64>>,
    pub prismatic: bool,
    pub joint: JointId,
}

/// Where a link frame sits: offset from the moving frame of a joint (or the root).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Anchor {
    pub dof: Option<usize>,
    pub offset: Isometry3<f64>,
}

/// A robot: a tree of links and joints loaded from URDF.
///
/// The joint-position vector of a robot holds one entry per moving joint, in
/// [`Robot::dof_joints`] order (depth-first from the root, parents before children,
/// siblings in URDF order).
#[derive(Debug, Clone)]
pub struct Robot {
    name: String,
    links: Vec<Link>,
    joints: Vec<Joint>,
    root: LinkId,
    link_by_name: HashMap<String, LinkId>,
    joint_by_name: HashMap<String, JointId>,
    pub(crate) dofs: Vec<Dof>,
    pub(crate) anchors: Vec<Anchor>,
    /// Links in depth-first order from the root (parents first).
    pub(crate) link_order: Vec<LinkId>,
}

fn pose_to_isometry(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = pose.xyz.0;
    let [r, p, yaw] = pose.rpy.0;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, p, yaw),
    )
}

fn pose_is_finite(pose: &urdf_rs::Pose) -> bool {
    pose.xyz
        .0
        .iter()
        .chain(pose.rpy.0.iter())
        .all(|v| v.is_finite())
}

fn convert_shape(geometry: &urdf_rs::Geometry) -> Shape {
    match geometry {
        urdf_rs::Geometry::Box { size } => Shape::Box {
            size: Vector3::from(size.0),
        },
        urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
            radius: *radius,
            length: *length,
        },
        urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
            radius: *radius,
            length: *length,
        },
        urdf_rs::Geometry::Sphere { radius } => Shape::Sphere { radius: *radius },
        urdf_rs::Geometry::Mesh { filename, scale } => Shape::Mesh {
            filename: filename.clone(),
            scale: scale
                .as_ref()
                .map_or(Vector3::repeat(1.0), |s| Vector3::from(s.0)),
        },
    }
}

fn convert_inertial(inertial: &urdf_rs::Inertial) -> Option<Inertial> {
    let m = inertial.mass.value;
    if m <= 0.0 {
        return None;
    }
    let i = &inertial.inertia;
    Some(Inertial {
        mass_kg: m,
        origin: pose_to_isometry(&inertial.origin),
        inertia: Matrix3::new(
            i.ixx, i.ixy, i.ixz, //
            i.ixy, i.iyy, i.iyz, //
            i.ixz, i.iyz, i.izz,
        ),
    })
}

impl Robot {
    /// Parses URDF text.
    ///
    /// # Errors
    /// [`KinematicsError::Parse`] for XML that urdf-rs rejects, and the structural
    /// variants ([`KinematicsError::UndefinedLink`], [`KinematicsError::BadLimits`], ...)
    /// naming the offending joint or link.
    pub fn from_urdf_str(urdf: &str) -> Result<Self, KinematicsError> {
        let parsed = urdf_rs::read_from_string(urdf).map_err(|e| KinematicsError::Parse {
            message: e.to_string(),
        })?;
        Self::from_urdf(&parsed)
    }

    /// Reads and parses a URDF file.
    ///
    /// # Errors
    /// [`KinematicsError::Io`] if the file cannot be read, otherwise as
    /// [`Robot::from_urdf_str`].
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self, KinematicsError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| KinematicsError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_urdf_str(&text)
    }

    /// Builds the tree from an already parsed [`urdf_rs::Robot`].
    ///
    /// # Errors
    /// As [`Robot::from_urdf_str`], without [`KinematicsError::Parse`].
    pub fn from_urdf(urdf: &urdf_rs::Robot) -> Result<Self, KinematicsError> {
        if urdf.links.is_empty() {
            return Err(KinematicsError::NoLinks {
                robot: urdf.name.clone(),
            });
        }
        let mut links = Vec::with_capacity(urdf.links.len());
        let mut link_by_name = HashMap::with_capacity(urdf.links.len());
        for l in &urdf.links {
            let id = LinkId(links.len());
            if link_by_name.insert(l.name.clone(), id).is_some() {
                return Err(KinematicsError::DuplicateLink {
                    link: l.name.clone(),
                });
            }
            links.push(Link {
                name: l.name.clone(),
                parent_joint: None,
                child_joints: Vec::new(),
                inertial: convert_inertial(&l.inertial),
                collisions: l
                    .collision
                    .iter()
                    .map(|c| CollisionShape {
                        name: c.name.clone(),
                        origin: pose_to_isometry(&c.origin),
                        shape: convert_shape(&c.geometry),
                    })
                    .collect(),
            });
        }

        let mut joints = Vec::with_capacity(urdf.joints.len());
        let mut joint_by_name = HashMap::with_capacity(urdf.joints.len());
        for j in &urdf.joints {
            let id = JointId(joints.len());
            if joint_by_name.insert(j.name.clone(), id).is_some() {
                return Err(KinematicsError::DuplicateJoint {
                    joint: j.name.clone(),
                });
            }
            let lookup = |name: &str| {
                link_by_name
                    .get(name)
                    .copied()
                    .ok_or_else(|| KinematicsError::UndefinedLink {
                        joint: j.name.clone(),
                        link: name.to_owned(),
                    })
            };
            let parent = lookup(&j.parent.link)?;
            let child = lookup(&j.child.link)?;
            if j.mimic.is_some() {
                return Err(KinematicsError::UnsupportedMimic {
                    joint: j.name.clone(),
                });
            }
            let kind = match j.joint_type {
                urdf_rs::JointType::Revolute => JointKind::Revolute,
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                urdf_rs::JointType::Fixed => JointKind::Fixed,
                ref other => {
                    return Err(KinematicsError::UnsupportedJointType {
                        joint: j.name.clone(),
                        kind: format!("{other:?}").to_lowercase(),
                    });
                }
            };
            if !pose_is_finite(&j.origin) {
                return Err(KinematicsError::NonFiniteOrigin {
                    joint: j.name.clone(),
                });
            }
            let raw_axis = Vector3::from(j.axis.xyz.0);
            let axis = if kind.is_moving() {
                let norm = raw_axis.norm();
                if !norm.is_finite() || norm < 1e-12 {
                    return Err(KinematicsError::BadAxis {
                        joint: j.name.clone(),
                        axis: j.axis.xyz.0,
                    });
                }
                Unit::new_normalize(raw_axis)
            } else {
                Vector3::x_axis()
            };
            let limits = match kind {
                JointKind::Fixed => None,
                JointKind::Continuous => Some(JointLimits {
                    lower: f64::NEG_INFINITY,
                    upper: f64::INFINITY,
                    velocity: j.limit.velocity,
                    effort: j.limit.effort,
                }),
                JointKind::Revolute | JointKind::Prismatic => {
                    let (lower, upper) = (j.limit.lower, j.limit.upper);
                    if !(lower.is_finite() && upper.is_finite() && lower <= upper) {
                        return Err(KinematicsError::BadLimits {
                            joint: j.name.clone(),
                            lower,
                            upper,
                        });
                    }
                    Some(JointLimits {
                        lower,
                        upper,
                        velocity: j.limit.velocity,
                        effort: j.limit.effort,
                    })
                }
            };
            if let Some(first) = links[child.0].parent_joint {
                let first: &Joint = &joints[first.0];
                return Err(KinematicsError::MultipleParents {
                    link: links[child.0].name.clone(),
                    first: first.name.clone(),
                    second: j.name.clone(),
                });
            }
            links[child.0].parent_joint = Some(id);
            links[parent.0].child_joints.push(id);
            joints.push(Joint {
                name: j.name.clone(),
                kind,
                parent,
                child,
                origin: pose_to_isometry(&j.origin),
                axis,
                limits,
                dof: None,
            });
        }

        let roots: Vec<LinkId> = (0..links.len())
            .map(LinkId)
            .filter(|l| links[l.0].parent_joint.is_none())
            .collect();
        if roots.len() != 1 {
            return Err(KinematicsError::RootCount {
                roots: roots.iter().map(|l| links[l.0].name.clone()).collect(),
            });
        }
        let root = roots[0];

        // Depth-first walk from the root (children in URDF order): parents come
        // before children, which is the order DoF indices are assigned in.
        let mut reached = vec![false; links.len()];
        let mut link_order = Vec::with_capacity(links.len());
        let mut stack = vec![root];
        reached[root.0] = true;
        while let Some(link) = stack.pop() {
            link_order.push(link);
            for &jid in links[link.0].child_joints.iter().rev() {
                let child = joints[jid.0].child;
                if reached[child.0] {
                    return Err(KinematicsError::Unreachable {
                        link: links[child.0].name.clone(),
                    });
                }
                reached[child.0] = true;
                stack.push(child);
            }
        }
        if let Some(l) = reached.iter().position(|r| !r) {
            return Err(KinematicsError::Unreachable {
                link: links[l].name.clone(),
            });
        }

        // Fold fixed joints: every link gets an anchor (moving joint + offset), every
        // moving joint its origin relative to its nearest moving ancestor.
        let mut dofs: Vec<Dof> = Vec::new();
        let mut anchors = vec![
            Anchor {
                dof: None,
                offset: Isometry3::identity(),
            };
            links.len()
        ];
        for &link in &link_order {
            let Some(jid) = links[link.0].parent_joint else {
                continue;
            };
            let joint = &mut joints[jid.0];
            let parent_anchor = anchors[joint.parent.0];
            let origin = parent_anchor.offset * joint.origin;
            if joint.kind.is_moving() {
                let idx = dofs.len();
                dofs.push(Dof {
                    parent: parent_anchor.dof,
                    origin,
                    axis: joint.axis,
                    prismatic: joint.kind == JointKind::Prismatic,
                    joint: jid,
                });
                joint.dof = Some(idx);
                anchors[link.0] = Anchor {
                    dof: Some(idx),
                    offset: Isometry3::identity(),
                };
            } else {
                anchors[link.0] = Anchor {
                    dof: parent_anchor.dof,
                    offset: origin,
                };
            }
        }

        Ok(Robot {
            name: urdf.name.clone(),
            links,
            joints,
            root,
            link_by_name,
            joint_by_name,
            dofs,
            anchors,
            link_order,
        })
    }

    /// `<robot name=...>`.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// All links, indexed by [`LinkId::index`].
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// All joints including fixed ones, indexed by [`JointId::index`].
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// The root link.
    pub fn root(&self) -> LinkId {
        self.root
    }

    /// Number of moving joints (length of the joint-position vector).
    pub fn dof(&self) -> usize {
        self.dofs.len()
    }

    /// Moving joints in joint-position-vector order.
    pub fn dof_joints(&self) -> impl ExactSizeIterator<Item = &Joint> + '_ {
        self.dofs.iter().map(|d| &self.joints[d.joint.0])
    }

    /// Limits of the moving joints in joint-position-vector order.
    pub fn dof_limits(&self) -> impl ExactSizeIterator<Item = JointLimits> + '_ {
        self.dof_joints().map(|j| {
            j.limits.unwrap_or(JointLimits {
                lower: f64::NEG_INFINITY,
                upper: f64::INFINITY,
                velocity: f64::INFINITY,
                effort: f64::INFINITY,
            })
        })
    }

    /// Looks a link up by name.
    ///
    /// # Errors
    /// [`KinematicsError::UnknownLink`].
    pub fn link_id(&self, name: &str) -> Result<LinkId, KinematicsError> {
        self.link_by_name
            .get(name)
            .copied()
            .ok_or_else(|| KinematicsError::UnknownLink {
                link: name.to_owned(),
            })
    }

    /// Looks a joint up by name.
    ///
    /// # Errors
    /// [`KinematicsError::UnknownJoint`].
    pub fn joint_id(&self, name: &str) -> Result<JointId, KinematicsError> {
        self.joint_by_name
            .get(name)
            .copied()
            .ok_or_else(|| KinematicsError::UnknownJoint {
                joint: name.to_owned(),
            })
    }

    /// The link with this id.
    ///
    /// # Panics
    /// If `id` was issued by another robot with fewer links.
    pub fn link(&self, id: LinkId) -> &Link {
        &self.links[id.0]
    }

    /// The joint with this id.
    ///
    /// # Panics
    /// If `id` was issued by another robot with fewer joints.
    pub fn joint(&self, id: JointId) -> &Joint {
        &self.joints[id.0]
    }

    /// Index of a moving joint in the joint-position vector.
    ///
    /// # Errors
    /// [`KinematicsError::UnknownJoint`] if no moving joint has this name.
    pub fn dof_index(&self, joint: &str) -> Result<usize, KinematicsError> {
        self.joint_id(joint)
            .ok()
            .and_then(|j| self.joints[j.0].dof)
            .ok_or_else(|| KinematicsError::UnknownJoint {
                joint: joint.to_owned(),
            })
    }

    /// Joint positions that are all zero, clamped into each joint's limits (a safe
    /// neutral configuration for joints whose range excludes zero).
    pub fn neutral_positions(&self) -> Vec<f64> {
        self.dof_limits().map(|l| l.clamp(0.0)).collect()
    }

    /// Links in depth-first order from the root: every link after its parent.
    pub fn links_depth_first(&self) -> &[LinkId] {
        &self.link_order
    }

    /// Total mass of all links (kg).
    pub fn total_mass_kg(&self) -> f64 {
        self.links
            .iter()
            .filter_map(|l| l.inertial.map(|i| i.mass_kg))
            .sum()
    }

    /// True when `ancestor` lies on the path from the root to `link` (or equals it).
    pub fn is_ancestor(&self, ancestor: LinkId, link: LinkId) -> bool {
        let mut cur = Some(link);
        while let Some(l) = cur {
            if l == ancestor {
                return true;
            }
            cur = self.links[l.0]
                .parent_joint
                .map(|j| self.joints[j.0].parent);
        }
        false
    }
}
