//! MJCF generated from the project's robot descriptions ([`teleop_kinematics::Robot`],
//! built from the URDFs), with what URDF lacks: joint damping, armature and dry
//! friction, actuators, contact classes and the BioTac touch sites.
//!
//! Mapping, link by link (depth first from the root, which is welded to the world):
//! * a link is a `<body>` at its parent joint's origin; a moving joint is a `hinge` (or
//!   `slide`) at the body's origin along the URDF axis, with the URDF range (none for a
//!   continuous joint); a fixed joint is a welded body (frames such as `rh_fftip` stay
//!   bodies of their own, so every URDF link has a MuJoCo body of the same name);
//! * the URDF inertial is turned into the link frame (`pos` + `fullinertia`), so MuJoCo
//!   sees the same mass distribution as the project's gravity model;
//! * collision primitives become geoms: boxes, spheres and the arm's cylinders as they
//!   are; the hand's cylinders (radius under 3 cm: the phalanges) become capsules over
//!   the same segment, as the previous simulator modelled them, since capsule contacts
//!   are MuJoCo's smoothest;
//! * robot geoms collide with the environment only (contype 2, conaffinity 1), the
//!   environment with everything (contype 1, conaffinity 3).

use std::fmt::Write as _;

use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector3};
use teleop_kinematics::{JointKind, LinkId, Robot, Shape};

use crate::error::PhysicsError;

/// Geom bit masks ([module docs](self)).
pub const ROBOT_CONTYPE: u32 = 2;
pub const ROBOT_CONAFFINITY: u32 = 1;
pub const ENV_CONTYPE: u32 = 1;
pub const ENV_CONAFFINITY: u32 = 3;

/// Cylinders thinner than this (radius, m) in the robot description become capsules.
pub const CAPSULE_BELOW_RADIUS_M: f64 = 0.03;

/// Passive joint parameters MuJoCo adds to a URDF joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointDynamics {
    /// Viscous damping, N m s/rad.
    pub damping: f64,
    /// Reflected rotor inertia, kg m^2.
    pub armature: f64,
    /// Dry friction, N m.
    pub frictionloss: f64,
}

/// What the robot body tree needs beyond the URDF: per joint dynamics (by joint name;
/// joints not listed get `default_dynamics`) and the touch sites.
#[derive(Debug, Clone)]
pub struct RobotMjcf<'a> {
    pub robot: &'a Robot,
    pub dynamics: Vec<(String, JointDynamics)>,
    pub default_dynamics: JointDynamics,
    /// Links that get a touch site over each of their collision primitives (enlarged by
    /// `touch_margin_m`): the BioTac (distal) links.
    pub touch_links: Vec<String>,
    pub touch_margin_m: f64,
    /// Sliding friction coefficient of the robot's geoms.
    pub friction: f64,
    /// Mass (and inertia) factor by link name (a simulated robot heavier or lighter than
    /// its description); links not listed keep their URDF mass.
    pub mass_scale: Vec<(String, f64)>,
}

/// MJCF numbers: shortest text that reads back to the same `f64`.
pub(crate) fn num(v: f64) -> String {
    if v == 0.0 {
        "0".to_owned()
    } else {
        format!("{v}")
    }
}

pub(crate) fn vec3(v: &Vector3<f64>) -> String {
    format!("{} {} {}", num(v.x), num(v.y), num(v.z))
}

/// MuJoCo's quaternion order: w x y z.
pub(crate) fn quat(q: &UnitQuaternion<f64>) -> String {
    let q = q.quaternion();
    format!("{} {} {} {}", num(q.w), num(q.i), num(q.j), num(q.k))
}

fn pose_attrs(pose: &Isometry3<f64>) -> String {
    let mut s = format!("pos=\"{}\"", vec3(&pose.translation.vector));
    if pose.rotation.angle() > 0.0 {
        let _ = write!(s, " quat=\"{}\"", quat(&pose.rotation));
    }
    s
}

/// Escapes a name for an XML attribute (the URDF names here are plain, but a loaded
/// description could carry anything).
pub(crate) fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The name of the touch site over collision primitive `index` of `link`.
pub fn touch_site_name(link: &str, index: usize) -> String {
    format!("{link}_touch{index}")
}

impl RobotMjcf<'_> {
    fn dynamics_of(&self, joint: &str) -> JointDynamics {
        self.dynamics
            .iter()
            .find(|(n, _)| n == joint)
            .map_or(self.default_dynamics, |(_, d)| *d)
    }

    /// The robot's `<body>` tree (to go inside `<worldbody>`), and the names of the touch
    /// sites per touch link (in `touch_links` order).
    ///
    /// # Errors
    /// [`PhysicsError::Model`] for a collision mesh (the project's descriptions use
    /// primitives only) or a non-finite number.
    pub fn body_tree(&self) -> Result<(String, Vec<Vec<String>>), PhysicsError> {
        let mut out = String::new();
        let mut sites = vec![Vec::new(); self.touch_links.len()];
        self.write_body(self.robot.root(), 2, &mut out, &mut sites)?;
        Ok((out, sites))
    }

    fn write_body(
        &self,
        id: LinkId,
        indent: usize,
        out: &mut String,
        sites: &mut [Vec<String>],
    ) -> Result<(), PhysicsError> {
        let robot = self.robot;
        let link = robot.link(id);
        let pad = " ".repeat(indent);
        let name = xml_escape(&link.name);
        let pose = match link.parent_joint {
            Some(j) => robot.joint(j).origin,
            None => Isometry3::identity(),
        };
        check_finite(&link.name, pose.translation.vector.iter().copied())?;
        let _ = writeln!(out, "{pad}<body name=\"{name}\" {}>", pose_attrs(&pose));
        if let Some(j) = link.parent_joint {
            let joint = robot.joint(j);
            if joint.kind.is_moving() {
                let d = self.dynamics_of(&joint.name);
                let kind = if joint.kind == JointKind::Prismatic {
                    "slide"
                } else {
                    "hinge"
                };
                let mut attrs = format!(
                    "name=\"{}\" type=\"{kind}\" axis=\"{}\" damping=\"{}\" armature=\"{}\" frictionloss=\"{}\"",
                    xml_escape(&joint.name),
                    vec3(&joint.axis),
                    num(d.damping),
                    num(d.armature),
                    num(d.frictionloss)
                );
                if joint.kind != JointKind::Continuous
                    && let Some(l) = joint.limits.filter(|l| l.is_bounded())
                {
                    let _ = write!(
                        attrs,
                        " limited=\"true\" range=\"{} {}\"",
                        num(l.lower),
                        num(l.upper)
                    );
                } else {
                    attrs.push_str(" limited=\"false\"");
                }
                let _ = writeln!(out, "{pad}  <joint {attrs}/>");
            }
        }
        if let Some(inertial) = &link.inertial {
            let scale = self
                .mass_scale
                .iter()
                .find(|(n, _)| *n == link.name)
                .map_or(1.0, |(_, f)| *f);
            // The inertia turned into the link frame: R I R^T about the CoM.
            let r: Matrix3<f64> = inertial.origin.rotation.to_rotation_matrix().into_inner();
            let i = r * inertial.inertia * r.transpose() * scale;
            check_finite(&link.name, i.iter().copied())?;
            let _ = writeln!(
                out,
                "{pad}  <inertial pos=\"{}\" mass=\"{}\" fullinertia=\"{} {} {} {} {} {}\"/>",
                vec3(&inertial.origin.translation.vector),
                num(inertial.mass_kg * scale),
                num(i[(0, 0)]),
                num(i[(1, 1)]),
                num(i[(2, 2)]),
                num(i[(0, 1)]),
                num(i[(0, 2)]),
                num(i[(1, 2)])
            );
        }
        let touch = self.touch_links.iter().position(|l| *l == link.name);
        for (k, c) in link.collisions.iter().enumerate() {
            let geom_name = format!("{name}_geom{k}");
            let (kind, size) = match &c.shape {
                Shape::Box { size } => ("box", vec3(&(size / 2.0))),
                Shape::Sphere { radius } => ("sphere", num(*radius)),
                Shape::Cylinder { radius, length } if *radius < CAPSULE_BELOW_RADIUS_M => {
                    ("capsule", format!("{} {}", num(*radius), num(length / 2.0)))
                }
                Shape::Cylinder { radius, length } => (
                    "cylinder",
                    format!("{} {}", num(*radius), num(length / 2.0)),
                ),
                Shape::Capsule { radius, length } => {
                    ("capsule", format!("{} {}", num(*radius), num(length / 2.0)))
                }
                Shape::Mesh { filename, .. } => {
                    return Err(PhysicsError::Model(format!(
                        "link {}: collision mesh {filename} (only primitives are supported)",
                        link.name
                    )));
                }
                _ => {
                    return Err(PhysicsError::Model(format!(
                        "link {}: unsupported collision shape",
                        link.name
                    )));
                }
            };
            let _ = writeln!(
                out,
                "{pad}  <geom name=\"{geom_name}\" type=\"{kind}\" size=\"{size}\" {} contype=\"{ROBOT_CONTYPE}\" conaffinity=\"{ROBOT_CONAFFINITY}\" friction=\"{} 0.005 0.0001\" group=\"1\"/>",
                pose_attrs(&c.origin),
                num(self.friction)
            );
            if let Some(t) = touch {
                let m = self.touch_margin_m;
                let site_size = match &c.shape {
                    Shape::Sphere { radius } => Some(("sphere", num(radius + m))),
                    Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => {
                        Some((
                            "capsule",
                            format!("{} {}", num(radius + m), num(length / 2.0)),
                        ))
                    }
                    Shape::Box { size } => Some(("box", vec3(&(size / 2.0).add_scalar(m)))),
                    _ => None,
                };
                if let Some((kind, size)) = site_size {
                    let site = touch_site_name(&link.name, k);
                    let _ = writeln!(
                        out,
                        "{pad}  <site name=\"{}\" type=\"{kind}\" size=\"{size}\" {} group=\"3\"/>",
                        xml_escape(&site),
                        pose_attrs(&c.origin)
                    );
                    sites[t].push(site);
                }
            }
        }
        for &j in &link.child_joints {
            self.write_body(robot.joint(j).child, indent + 2, out, sites)?;
        }
        let _ = writeln!(out, "{pad}</body>");
        Ok(())
    }
}

fn check_finite(what: &str, values: impl Iterator<Item = f64>) -> Result<(), PhysicsError> {
    let mut values = values;
    if values.all(f64::is_finite) {
        Ok(())
    } else {
        Err(PhysicsError::Model(format!(
            "{what}: a number is not finite"
        )))
    }
}
