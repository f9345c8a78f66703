//! Segment-segment closest points: the one implementation the simulator's contacts
//! and the hand retargeting's self-collision goal share.

use nalgebra::Point3;

/// Segments shorter than this (m) are treated as points.
const DEGENERATE_M: f64 = 1e-12;

/// Closest points of segments `p1`–`q1` and `p2`–`q2` (Ericson, *Real-Time Collision
/// Detection*, 5.1.9). Returns the two points. For parallel overlapping segments the
/// point pair is one of the closest ones (not unique).
pub fn closest_points_segments(
    p1: &Point3<f64>,
    q1: &Point3<f64>,
    p2: &Point3<f64>,
    q2: &Point3<f64>,
) -> (Point3<f64>, Point3<f64>) {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let eps = DEGENERATE_M * DEGENERATE_M;
    let (s, t) = if a <= eps && e <= eps {
        (0.0, 0.0)
    } else if a <= eps {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            // Parallel segments: any s works; 0.5 keeps the pair central on segment 1.
            let mut s = if denom > eps * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.5
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    (p1 + d1 * s, p2 + d2 * t)
}

/// Distance between segments `p1`-`q1` and `p2`-`q2`.
#[must_use]
pub fn segment_distance(
    p1: &Point3<f64>,
    q1: &Point3<f64>,
    p2: &Point3<f64>,
    q2: &Point3<f64>,
) -> f64 {
    let (a, b) = closest_points_segments(p1, q1, p2, q2);
    (a - b).norm()
}
