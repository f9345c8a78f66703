//! The one place where nalgebra `f64` poses become parry3d / glam `f32` poses.

use nalgebra::Isometry3;
use parry3d::math::{Pose, Rotation, Vector};

/// Converts a nalgebra pose (`f64`, the project's math type) to a parry3d pose (`f32`
/// glam types) component by component: translation as is, rotation as the same unit
/// quaternion `(x, y, z, w)`, renormalised after rounding to `f32`.
#[must_use]
pub fn to_parry_pose(pose: &Isometry3<f64>) -> Pose {
    let t = &pose.translation.vector;
    let q = pose.rotation.coords; // (i, j, k, w)
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32).normalize(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn converted_pose_maps_points_alike() {
        let iso = Isometry3::new(Vector3::new(0.1, -0.2, 0.7), Vector3::new(0.3, -1.1, 2.0));
        let pose = to_parry_pose(&iso);
        let p = Point3::new(0.05, 0.02, -0.3);
        let expected = iso * p;
        let got = pose.transform_point(Vector::new(0.05, 0.02, -0.3));
        for (a, b) in [
            (got.x, expected.x),
            (got.y, expected.y),
            (got.z, expected.z),
        ] {
            assert!((f64::from(a) - b).abs() < 1e-6, "{a} vs {b}");
        }
    }
}
