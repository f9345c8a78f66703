//! Groups of placed primitives (a link's, or an external volume's) and the distance
//! engine over them: bounding-ball broad phase, then the narrow phase of
//! [`crate::geometry`].
//!
//! Broad phase: every group and every shape carries a bounding ball. The distance
//! between two shapes is at least `|c_a - c_b| - r_a - r_b` (also when they overlap:
//! moving one by that much along the centre line separates the balls), so a pair
//! whose lower bound is not below the best distance found so far is skipped. Minimum
//! searches evaluate the pair with the smallest lower bound first, which makes the
//! bound tight early; collision checks skip every pair whose balls are apart.

use nalgebra::{Isometry3, Vector3};
use teleop_kinematics::LinkId;

use crate::geometry::{PlacedShape, Posed, collides, signed_distance_below};

/// A link's collision primitives in the link frame, with a bounding ball.
#[derive(Debug, Clone)]
pub struct LinkBody {
    link: LinkId,
    name: String,
    shapes: Vec<PlacedShape>,
    center: Vector3<f64>,
    radius_m: f64,
}

impl LinkBody {
    pub(crate) fn new(link: LinkId, name: String, shapes: Vec<PlacedShape>) -> Self {
        let (center, radius_m) = bounding_ball(&shapes);
        Self {
            link,
            name,
            shapes,
            center,
            radius_m,
        }
    }

    /// The link.
    pub fn link(&self) -> LinkId {
        self.link
    }

    /// The link's URDF name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The primitives, placed in the link frame.
    pub fn shapes(&self) -> &[PlacedShape] {
        &self.shapes
    }

    /// Centre of the bounding ball, link frame (m).
    pub fn bounding_center(&self) -> Vector3<f64> {
        self.center
    }

    /// Radius of the bounding ball (m).
    pub fn bounding_radius_m(&self) -> f64 {
        self.radius_m
    }
}

/// A ball containing every shape's bounding ball (not the smallest one: centred on
/// the box around them).
pub(crate) fn bounding_ball(shapes: &[PlacedShape]) -> (Vector3<f64>, f64) {
    if shapes.is_empty() {
        return (Vector3::zeros(), 0.0);
    }
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for s in shapes {
        let c = s.bounding_center();
        let r = Vector3::repeat(s.bounding_radius_m());
        lo = lo.inf(&(c - r));
        hi = hi.sup(&(c + r));
    }
    let center = (lo + hi) / 2.0;
    let radius = shapes
        .iter()
        .map(|s| (s.bounding_center() - center).norm() + s.bounding_radius_m())
        .fold(0.0, f64::max);
    (center, radius)
}

#[inline]
fn ball_gap(ca: &Vector3<f64>, ra: f64, cb: &Vector3<f64>, rb: f64) -> f64 {
    (ca - cb).norm() - ra - rb
}

/// A group of shapes posed for one query: the shapes and their poses, aligned.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Group<'a> {
    pub shapes: &'a [PlacedShape],
    pub posed: &'a [Posed],
}

/// Bodies posed for one query: every shape's frame and bounding centre computed once.
#[derive(Debug)]
pub(crate) struct PosedBodies<'a> {
    bodies: &'a [LinkBody],
    centers: Vec<Vector3<f64>>,
    starts: Vec<usize>,
    posed: Vec<Posed>,
}

impl<'a> PosedBodies<'a> {
    /// `poses` holds one link pose per body, in the common frame.
    pub(crate) fn new(
        bodies: &'a [LinkBody],
        poses: impl IntoIterator<Item = Isometry3<f64>>,
    ) -> Self {
        let mut centers = Vec::with_capacity(bodies.len());
        let mut starts = Vec::with_capacity(bodies.len() + 1);
        let mut posed = Vec::with_capacity(bodies.len() * 2);
        for (b, p) in bodies.iter().zip(poses) {
            centers.push(p * b.center);
            starts.push(posed.len());
            posed.extend(b.shapes.iter().map(|s| s.posed(&p)));
        }
        starts.push(posed.len());
        Self {
            bodies,
            centers,
            starts,
            posed,
        }
    }

    fn len(&self) -> usize {
        self.centers.len()
    }

    fn group(&self, i: usize) -> Group<'_> {
        Group {
            shapes: &self.bodies[i].shapes,
            posed: &self.posed[self.starts[i]..self.starts[i + 1]],
        }
    }

    fn gap(&self, i: usize, j: usize) -> f64 {
        ball_gap(
            &self.centers[i],
            self.bodies[i].radius_m,
            &self.centers[j],
            self.bodies[j].radius_m,
        )
    }

    fn gap_to(&self, i: usize, center: &Vector3<f64>, radius_m: f64) -> f64 {
        ball_gap(&self.centers[i], self.bodies[i].radius_m, center, radius_m)
    }
}

/// Smallest signed distance between two groups, over shape pairs whose bounding
/// balls are closer than `cutoff`. Returns `cutoff` and `None` when no pair beats it,
/// else the distance and the index into `b`.
fn group_distance(a: Group<'_>, b: Group<'_>, cutoff: f64) -> (f64, Option<usize>) {
    let mut best = cutoff;
    let mut which = None;
    for (sa, pa) in a.shapes.iter().zip(a.posed) {
        for (j, (sb, pb)) in b.shapes.iter().zip(b.posed).enumerate() {
            if ball_gap(
                &pa.center,
                sa.bounding_radius_m(),
                &pb.center,
                sb.bounding_radius_m(),
            ) >= best
            {
                continue;
            }
            if let Some(d) = signed_distance_below(sa, pa, sb, pb, best) {
                best = d;
                which = Some(j);
            }
        }
    }
    (best, which)
}

/// True when any shape of `a` touches or overlaps any shape of `b`.
fn groups_collide(a: Group<'_>, b: Group<'_>) -> bool {
    a.shapes.iter().zip(a.posed).any(|(sa, pa)| {
        b.shapes.iter().zip(b.posed).any(|(sb, pb)| {
            ball_gap(
                &pa.center,
                sa.bounding_radius_m(),
                &pb.center,
                sb.bounding_radius_m(),
            ) <= 0.0
                && collides(sa, pa, sb, pb)
        })
    })
}

/// Index of the smallest value.
fn argmin(values: &[f64]) -> Option<usize> {
    values
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))
        .map(|(k, _)| k)
}

/// Closest pair among `pairs` (body indices): distance and pair index.
pub(crate) fn min_pair_distance(
    posed: &PosedBodies<'_>,
    pairs: &[(u32, u32)],
) -> Option<(f64, usize)> {
    let lower: Vec<f64> = pairs
        .iter()
        .map(|&(i, j)| posed.gap(i as usize, j as usize))
        .collect();
    let first = argmin(&lower)?;
    let eval = |k: usize, cutoff: f64| {
        let (i, j) = (pairs[k].0 as usize, pairs[k].1 as usize);
        group_distance(posed.group(i), posed.group(j), cutoff).0
    };
    let mut best = eval(first, f64::INFINITY);
    let mut best_k = first;
    for (k, lb) in lower.iter().enumerate() {
        if k == first || *lb >= best {
            continue;
        }
        let d = eval(k, best);
        if d < best {
            best = d;
            best_k = k;
        }
    }
    Some((best, best_k))
}

/// Indices of the colliding pairs among `pairs`, each with its signed distance (<= 0).
pub(crate) fn colliding_pairs(
    posed: &PosedBodies<'_>,
    pairs: &[(u32, u32)],
    out: &mut Vec<(usize, f64)>,
) {
    for (k, &(i, j)) in pairs.iter().enumerate() {
        let (i, j) = (i as usize, j as usize);
        if posed.gap(i, j) > 0.0 || !groups_collide(posed.group(i), posed.group(j)) {
            continue;
        }
        let d = group_distance(posed.group(i), posed.group(j), f64::INFINITY).0;
        out.push((k, d.min(0.0)));
    }
}

/// True when bodies `i` and `j` touch or overlap.
pub(crate) fn pair_collides(posed: &PosedBodies<'_>, i: usize, j: usize) -> bool {
    posed.gap(i, j) <= 0.0 && groups_collide(posed.group(i), posed.group(j))
}

/// True when any pair among `pairs` collides.
pub(crate) fn any_pair_collides(posed: &PosedBodies<'_>, pairs: &[(u32, u32)]) -> bool {
    pairs
        .iter()
        .any(|&(i, j)| pair_collides(posed, i as usize, j as usize))
}

/// A posed group of shapes that is not a robot link (an external volume).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PosedGroup<'a> {
    pub group: Group<'a>,
    /// Centre and radius of the group's bounding ball, common frame.
    pub center: Vector3<f64>,
    pub radius_m: f64,
}

/// Closest body to the group: distance, body index, group shape index.
pub(crate) fn min_group_distance(
    posed: &PosedBodies<'_>,
    group: &PosedGroup<'_>,
) -> Option<(f64, usize, usize)> {
    if group.group.shapes.is_empty() {
        return None;
    }
    let lower: Vec<f64> = (0..posed.len())
        .map(|i| posed.gap_to(i, &group.center, group.radius_m))
        .collect();
    let first = argmin(&lower)?;
    let mut best = f64::INFINITY;
    let mut found = None;
    // The body with the smallest lower bound first, then the rest in order.
    for i in std::iter::once(first).chain((0..posed.len()).filter(|&i| i != first)) {
        if lower[i] >= best {
            continue;
        }
        let (d, j) = group_distance(posed.group(i), group.group, best);
        if let Some(j) = j {
            best = d;
            found = Some((i, j));
        }
    }
    found.map(|(i, j)| (best, i, j))
}

/// True when any body touches the group.
pub(crate) fn any_collides_with_group(posed: &PosedBodies<'_>, group: &PosedGroup<'_>) -> bool {
    (0..posed.len()).any(|i| {
        posed.gap_to(i, &group.center, group.radius_m) <= 0.0
            && groups_collide(posed.group(i), group.group)
    })
}
