//! The environment of the robot: a table in front of the PR2 and free objects on it,
//! each with mass, inertia (from its shape, uniform density) and friction, and the
//! per-seed variation of their properties within documented ranges.

use std::fmt::Write as _;

use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::PhysicsError;
use crate::mjcf::{ENV_CONAFFINITY, ENV_CONTYPE, num, quat, vec3, xml_escape};

/// A primitive shape, sizes in m.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ObjectShape {
    /// Half extents along x, y, z.
    Box {
        half_m: [f64; 3],
    },
    /// Upright (axis along z).
    Cylinder {
        radius_m: f64,
        half_height_m: f64,
    },
    Sphere {
        radius_m: f64,
    },
    /// Upright (axis along z): a cylinder of half height `half_length_m` with
    /// hemispherical caps.
    Capsule {
        radius_m: f64,
        half_length_m: f64,
    },
}

impl ObjectShape {
    fn mjcf(&self) -> (&'static str, String) {
        match *self {
            ObjectShape::Box { half_m } => ("box", vec3(&Vector3::from(half_m))),
            ObjectShape::Cylinder {
                radius_m,
                half_height_m,
            } => (
                "cylinder",
                format!("{} {}", num(radius_m), num(half_height_m)),
            ),
            ObjectShape::Sphere { radius_m } => ("sphere", num(radius_m)),
            ObjectShape::Capsule {
                radius_m,
                half_length_m,
            } => (
                "capsule",
                format!("{} {}", num(radius_m), num(half_length_m)),
            ),
        }
    }

    /// Height of the shape's lowest point below its centre when upright, m.
    #[must_use]
    pub fn half_height_m(&self) -> f64 {
        match *self {
            ObjectShape::Box { half_m } => half_m[2],
            ObjectShape::Cylinder { half_height_m, .. } => half_height_m,
            ObjectShape::Sphere { radius_m } => radius_m,
            ObjectShape::Capsule {
                radius_m,
                half_length_m,
            } => radius_m + half_length_m,
        }
    }

    fn sizes(&self) -> Vec<f64> {
        match *self {
            ObjectShape::Box { half_m } => half_m.to_vec(),
            ObjectShape::Cylinder {
                radius_m,
                half_height_m,
            } => vec![radius_m, half_height_m],
            ObjectShape::Sphere { radius_m } => vec![radius_m],
            ObjectShape::Capsule {
                radius_m,
                half_length_m,
            } => vec![radius_m, half_length_m],
        }
    }

    /// The same shape with every size scaled by `s`.
    #[must_use]
    pub fn scaled(&self, s: f64) -> Self {
        match *self {
            ObjectShape::Box { half_m } => ObjectShape::Box {
                half_m: half_m.map(|h| h * s),
            },
            ObjectShape::Cylinder {
                radius_m,
                half_height_m,
            } => ObjectShape::Cylinder {
                radius_m: radius_m * s,
                half_height_m: half_height_m * s,
            },
            ObjectShape::Sphere { radius_m } => ObjectShape::Sphere {
                radius_m: radius_m * s,
            },
            ObjectShape::Capsule {
                radius_m,
                half_length_m,
            } => ObjectShape::Capsule {
                radius_m: radius_m * s,
                half_length_m: half_length_m * s,
            },
        }
    }
}

/// One object of the scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    pub name: String,
    pub shape: ObjectShape,
    /// kg; the inertia is that of the solid shape with this mass.
    pub mass_kg: f64,
    /// Sliding friction coefficient (MuJoCo combines a pair by the maximum).
    pub friction: f64,
    /// Position of the shape's centre in the world (PR2 `base_link`) frame, m.
    pub position_m: [f64; 3],
    /// Rotation about the world z axis, rad.
    pub yaw_rad: f64,
    /// Free to move (a free joint); false welds it to the world (a fixture).
    pub free: bool,
    /// Colour in the camera views, RGBA 0-1.
    pub rgba: [f64; 4],
}

/// The table: a box whose top is at `top_z_m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    /// Centre of the table top in the world's x-y plane, m.
    pub centre_xy_m: [f64; 2],
    /// Size of the top along x and y, m.
    pub size_xy_m: [f64; 2],
    /// Height of the top above the floor (the PR2 base's bottom, z = 0), m.
    pub top_z_m: f64,
    pub friction: f64,
}

impl Default for TableSpec {
    fn default() -> Self {
        Self {
            centre_xy_m: [0.85, -0.15],
            size_xy_m: [0.6, 1.0],
            top_z_m: 0.55,
            friction: 0.8,
        }
    }
}

/// The environment: table (none for a scene of fixtures only), objects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    #[serde(default)]
    pub table: Option<TableSpec>,
    pub objects: Vec<ObjectSpec>,
}

/// How far the objects' properties vary per seed (fractions: a factor drawn uniformly
/// in `1 +- f`; positions in m). The defaults are the documented ranges of
/// docs/physics.md.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObjectVariation {
    pub mass_fraction: f64,
    pub friction_fraction: f64,
    pub size_fraction: f64,
    pub position_m: f64,
    pub yaw_rad: f64,
}

impl Default for ObjectVariation {
    fn default() -> Self {
        Self {
            mass_fraction: 0.2,
            friction_fraction: 0.2,
            size_fraction: 0.05,
            position_m: 0.01,
            yaw_rad: 0.1,
        }
    }
}

impl SceneSpec {
    /// Every number finite and in range, names unique and plain.
    ///
    /// # Errors
    /// [`PhysicsError::Invalid`] naming the object and the field.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        let bad = |why: String| PhysicsError::Invalid { what: "scene", why };
        let table_ok = self.table.as_ref().is_none_or(|t| {
            t.top_z_m.is_finite()
                && t.top_z_m > 0.0
                && t.size_xy_m.iter().all(|v| v.is_finite() && *v > 0.0)
                && t.centre_xy_m.iter().all(|v| v.is_finite())
                && t.friction.is_finite()
                && t.friction > 0.0
        });
        if !table_ok {
            return Err(bad("table: sizes and height must be finite and > 0".into()));
        }
        for (i, o) in self.objects.iter().enumerate() {
            if o.name.is_empty()
                || !o
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_')
            {
                return Err(bad(format!(
                    "object {i}: name {:?} must be ASCII letters, digits and _",
                    o.name
                )));
            }
            if self.objects[..i].iter().any(|p| p.name == o.name) {
                return Err(bad(format!("object {}: name used twice", o.name)));
            }
            if !(o.mass_kg.is_finite() && o.mass_kg > 0.0) {
                return Err(bad(format!("object {}: mass_kg must be > 0", o.name)));
            }
            if !(o.friction.is_finite() && o.friction > 0.0) {
                return Err(bad(format!("object {}: friction must be > 0", o.name)));
            }
            if !o.shape.sizes().iter().all(|v| v.is_finite() && *v > 0.0) {
                return Err(bad(format!("object {}: sizes must be > 0", o.name)));
            }
            if !o
                .position_m
                .iter()
                .chain([&o.yaw_rad])
                .all(|v| v.is_finite())
            {
                return Err(bad(format!("object {}: pose must be finite", o.name)));
            }
            if !o.rgba.iter().all(|v| (0.0..=1.0).contains(v)) {
                return Err(bad(format!("object {}: rgba must be in 0..1", o.name)));
            }
        }
        Ok(())
    }

    /// The scene with every object's mass, friction, size, position and yaw drawn within
    /// `variation` from `seed` (the same seed gives the same scene). Sizes scale about
    /// the centre, and resting objects are kept on the table.
    #[must_use]
    pub fn varied(&self, variation: &ObjectVariation, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6f62_6a65_6374_7321);
        let factor = |f: f64, rng: &mut ChaCha8Rng| -> f64 {
            if f > 0.0 {
                1.0 + f * (2.0 * rng.random::<f64>() - 1.0)
            } else {
                1.0
            }
        };
        let mut out = self.clone();
        for o in &mut out.objects {
            let table_top = self.table.map(|t| t.top_z_m);
            let resting = table_top
                .is_some_and(|top| (o.position_m[2] - o.shape.half_height_m() - top).abs() < 1e-6);
            o.mass_kg *= factor(variation.mass_fraction, &mut rng);
            o.friction *= factor(variation.friction_fraction, &mut rng);
            let s = factor(variation.size_fraction, &mut rng);
            o.shape = o.shape.scaled(s);
            if o.free {
                o.position_m[0] += variation.position_m * (2.0 * rng.random::<f64>() - 1.0);
                o.position_m[1] += variation.position_m * (2.0 * rng.random::<f64>() - 1.0);
                o.yaw_rad += variation.yaw_rad * (2.0 * rng.random::<f64>() - 1.0);
            }
            if let (true, Some(top)) = (resting, table_top) {
                o.position_m[2] = top + o.shape.half_height_m();
            }
        }
        out
    }

    /// The `<worldbody>` part of the environment (floor, table, objects).
    pub(crate) fn worldbody_xml(&self) -> String {
        let mut s = String::new();
        let env = format!("contype=\"{ENV_CONTYPE}\" conaffinity=\"{ENV_CONAFFINITY}\"");
        let _ = writeln!(
            s,
            "    <geom name=\"floor\" type=\"plane\" size=\"4 4 0.1\" {env} rgba=\"0.55 0.55 0.5 1\"/>"
        );
        if let Some(t) = &self.table {
            let _ = writeln!(
                s,
                "    <body name=\"table\" pos=\"{} {} {}\">\n      <geom name=\"table_top\" type=\"box\" size=\"{} {} {}\" {env} friction=\"{} 0.005 0.0001\" rgba=\"0.6 0.45 0.3 1\"/>\n    </body>",
                num(t.centre_xy_m[0]),
                num(t.centre_xy_m[1]),
                num(t.top_z_m / 2.0),
                num(t.size_xy_m[0] / 2.0),
                num(t.size_xy_m[1] / 2.0),
                num(t.top_z_m / 2.0),
                num(t.friction)
            );
        }
        for o in &self.objects {
            let name = xml_escape(&o.name);
            let (kind, size) = o.shape.mjcf();
            let q = UnitQuaternion::from_euler_angles(0.0, 0.0, o.yaw_rad);
            let joint = if o.free {
                format!("\n      <freejoint name=\"{name}_free\"/>")
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "    <body name=\"{name}\" pos=\"{}\" quat=\"{}\">{joint}\n      <geom name=\"{name}_geom\" type=\"{kind}\" size=\"{size}\" mass=\"{}\" {env} friction=\"{} 0.005 0.0001\" condim=\"4\" rgba=\"{} {} {} {}\"/>\n    </body>",
                vec3(&Vector3::from(o.position_m)),
                quat(&q),
                num(o.mass_kg),
                num(o.friction),
                num(o.rgba[0]),
                num(o.rgba[1]),
                num(o.rgba[2]),
                num(o.rgba[3])
            );
        }
        s
    }
}

/// A Pringles-like can (thesis ch. 6.4: "pick a Pringles can and place it in a red
/// bowl"): 7.5 cm diameter, 23 cm tall, 0.2 kg (the retail can [EST]).
#[must_use]
pub fn can(name: &str, centre_xy_m: [f64; 2], table_top_z_m: f64) -> ObjectSpec {
    let shape = ObjectShape::Cylinder {
        radius_m: 0.0375,
        half_height_m: 0.115,
    };
    ObjectSpec {
        name: name.to_owned(),
        shape,
        mass_kg: 0.2,
        friction: 0.7,
        position_m: [
            centre_xy_m[0],
            centre_xy_m[1],
            table_top_z_m + shape.half_height_m(),
        ],
        yaw_rad: 0.0,
        free: true,
        rgba: [0.8, 0.2, 0.1, 1.0],
    }
}

/// A cube of side `side_m` (thesis ch. 6.4: "pick a cube on the table", a wooden cube in
/// Fig. 6.8; the tower's blocks), density of wood, 600 kg/m^3 [EST].
#[must_use]
pub fn cube(name: &str, side_m: f64, centre_xy_m: [f64; 2], table_top_z_m: f64) -> ObjectSpec {
    let h = side_m / 2.0;
    ObjectSpec {
        name: name.to_owned(),
        shape: ObjectShape::Box { half_m: [h; 3] },
        mass_kg: 600.0 * side_m.powi(3),
        friction: 0.8,
        position_m: [centre_xy_m[0], centre_xy_m[1], table_top_z_m + h],
        yaw_rad: 0.0,
        free: true,
        rgba: [0.2, 0.4, 0.8, 1.0],
    }
}
