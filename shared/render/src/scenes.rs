//! Ready-made scenes for tests, benchmarks and examples.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::{Primitive, RenderError, Scene};

/// Number of primitives in [`synthetic_hand`].
pub const SYNTHETIC_HAND_PRIMITIVES: usize = 40;

/// A hand-sized stand-in built from 40 primitives — a palm box, a wrist capsule, three
/// thenar balls, and per finger (thumb included) three phalanx capsules and balls at
/// the MCP, PIP, DIP joints and the tip. It is a rendering workload of the right size
/// and shape, not a model of the Shadow hand.
///
/// Hand frame: origin at the wrist, +Z towards the fingers, +Y out of the back of the
/// hand, +X towards the thumb. Each finger joint flexes by `flexion_rad` towards the
/// palm (-Y). About 19 cm long and 9 cm wide.
///
/// # Errors
/// [`RenderError::InvalidPose`] if `world_from_hand` is not finite.
pub fn synthetic_hand(
    world_from_hand: &Isometry3<f64>,
    flexion_rad: f64,
) -> Result<Scene, RenderError> {
    let mut scene = Scene::new();
    let at = |p: Vector3<f64>| world_from_hand * Isometry3::translation(p.x, p.y, p.z);
    // Palm, wrist, thenar eminence.
    scene.push(
        Primitive::cuboid(&Vector3::new(0.042, 0.012, 0.05)),
        at(Vector3::new(0.0, 0.0, 0.055)),
    )?;
    scene.push(
        Primitive::capsule(
            &Point3::new(-0.025, 0.0, 0.0),
            &Point3::new(0.025, 0.0, 0.0),
            0.022,
        ),
        at(Vector3::zeros()),
    )?;
    for (x, z) in [(0.03, 0.02), (0.036, 0.04), (0.03, 0.06)] {
        scene.push(Primitive::ball(0.016), at(Vector3::new(x, -0.008, z)))?;
    }
    let fingers = [
        Finger {
            base: Vector3::new(0.045, -0.005, 0.035),
            direction: Vector3::new(0.75, -0.25, 0.6),
            lengths: [0.04, 0.032, 0.028],
            radius: 0.0105,
        },
        Finger {
            base: Vector3::new(0.03, 0.0, 0.105),
            direction: Vector3::z(),
            lengths: [0.045, 0.026, 0.022],
            radius: 0.0095,
        },
        Finger {
            base: Vector3::new(0.01, 0.0, 0.108),
            direction: Vector3::z(),
            lengths: [0.048, 0.029, 0.023],
            radius: 0.0095,
        },
        Finger {
            base: Vector3::new(-0.01, 0.0, 0.105),
            direction: Vector3::z(),
            lengths: [0.045, 0.027, 0.022],
            radius: 0.009,
        },
        Finger {
            base: Vector3::new(-0.03, 0.0, 0.098),
            direction: Vector3::z(),
            lengths: [0.035, 0.021, 0.02],
            radius: 0.0085,
        },
    ];
    for Finger {
        base,
        direction,
        lengths,
        radius,
    } in fingers
    {
        let mut joint = base;
        let mut dir = direction.normalize();
        // Flexion bends the finger towards the palm: about the axis dir x (-Y).
        scene.push(Primitive::ball(radius * 1.05), at(joint))?;
        for length in lengths {
            let axis = dir.cross(&-Vector3::y());
            if let Some(axis) = nalgebra::Unit::try_new(axis, 1e-9) {
                dir = UnitQuaternion::from_axis_angle(&axis, flexion_rad) * dir;
            }
            let next = joint + dir * length;
            scene.push(
                Primitive::capsule(&Point3::from(joint), &Point3::from(next), radius),
                *world_from_hand,
            )?;
            scene.push(Primitive::ball(radius * 1.05), at(next))?;
            joint = next;
        }
    }
    debug_assert_eq!(scene.len(), SYNTHETIC_HAND_PRIMITIVES);
    Ok(scene)
}

/// One finger of [`synthetic_hand`], in the hand frame (m).
struct Finger {
    /// MCP joint position.
    base: Vector3<f64>,
    /// Direction of the proximal phalanx before flexion.
    direction: Vector3<f64>,
    /// Proximal, middle, distal phalanx lengths.
    lengths: [f64; 3],
    /// Phalanx radius.
    radius: f64,
}

/// Pose of [`synthetic_hand`]'s frame that shows its palm to a camera at the world
/// origin looking along +Z (an optical frame), with the palm centre at `distance_m` on
/// the optical axis and the fingers pointing up in the image.
#[must_use]
pub fn hand_facing_camera(distance_m: f64) -> Isometry3<f64> {
    // Hand +Y (back of the hand) away from the camera = world +Z; fingers (hand +Z) up
    // in the image = world -Y; X completes the right-handed frame.
    let y = Vector3::z();
    let z = -Vector3::y();
    let x = y.cross(&z);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::from_columns(&[x, y, z]),
    ));
    let palm_centre_in_hand = Vector3::new(0.0, 0.0, 0.07);
    let translation = Vector3::new(0.0, 0.0, distance_m) - rotation * palm_centre_in_hand;
    Isometry3::from_parts(Translation3::from(translation), rotation)
}
