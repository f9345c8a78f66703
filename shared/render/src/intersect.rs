//! Analytic ray-primitive intersections in the primitive's own frame (`f32`).
//!
//! Every function takes a ray `origin + t * dir` (`dir` need not be unit length; `t` is
//! in units of `dir`) and returns the first `t >= 0` where the ray meets the *solid*
//! primitive together with an outward, not necessarily unit, surface normal. A ray
//! starting inside the solid returns `t = 0` with normal `-dir`, as parry3d's
//! `cast_ray(.., solid = true)` does. Discriminants are computed from a cross product,
//! `|d|^2 r^2 - |o x d|^2` (= `|d|^2 (r^2 - distance^2)` between the centre or axis and
//! the ray's line), rather than as `b^2 - ac`: no cancellation when the origin is far away
//! compared with the radius, and misses are rejected before any division or root.

use parry3d::math::Vector as Vec3;

/// Below this squared sine of the angle between ray and axis, a ray counts as parallel
/// to a capsule's or cylinder's axis.
const PARALLEL_SIN2: f32 = 1e-12;

/// A primitive prepared for repeated ray casts.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Analytic {
    /// Sphere of squared radius `r2` around `center`.
    Sphere { center: Vec3, r2: f32 },
    /// Capsule: segment from `a` along unit `axis` with length `len`, squared radius `r2`.
    Capsule {
        a: Vec3,
        axis: Vec3,
        len: f32,
        r2: f32,
    },
    /// Centred box.
    Cuboid { half: Vec3 },
    /// Centred cylinder along Y.
    Cylinder { half_height: f32, r2: f32 },
}

#[cfg(test)]
impl Analytic {
    /// First hit `(t, outward normal)`, see the module docs.
    #[inline(always)]
    pub(crate) fn cast(&self, origin: Vec3, dir: Vec3) -> Option<(f32, Vec3)> {
        match *self {
            Self::Sphere { center, r2 } => sphere(origin, dir, center, r2),
            Self::Capsule { a, axis, len, r2 } => capsule(origin, dir, a, axis, len, r2),
            Self::Cuboid { half } => cuboid(origin, dir, half),
            Self::Cylinder { half_height, r2 } => cylinder(origin, dir, half_height, r2),
        }
    }
}

/// Sphere of squared radius `r2` centred on `center`.
#[inline(always)]
pub(crate) fn sphere(origin: Vec3, dir: Vec3, center: Vec3, r2: f32) -> Option<(f32, Vec3)> {
    let oc = origin - center;
    let c = oc.length_squared() - r2;
    if c <= 0.0 {
        return Some((0.0, -dir));
    }
    let b = oc.dot(dir);
    if b >= 0.0 {
        // Outside and moving away.
        return None;
    }
    let a = dir.length_squared();
    // a * (r^2 - squared distance from the centre to the ray's line), without a division.
    let ah = r2 * a - oc.cross(dir).length_squared();
    if ah < 0.0 {
        return None;
    }
    let t = ((-b - ah.sqrt()) / a).max(0.0);
    Some((t, oc + dir * t))
}

/// Capsule: all points within `sqrt(r2)` of the segment `a .. a + axis * len`.
#[inline(always)]
pub(crate) fn capsule(
    origin: Vec3,
    dir: Vec3,
    a: Vec3,
    axis: Vec3,
    len: f32,
    r2: f32,
) -> Option<(f32, Vec3)> {
    let oa = origin - a;
    let y0 = oa.dot(axis);
    let on_axis = oa - axis * y0.clamp(0.0, len);
    if on_axis.length_squared() <= r2 {
        return Some((0.0, -dir));
    }
    let dy = dir.dot(axis);
    // Components perpendicular to the axis.
    let op = oa - axis * y0;
    let dp = dir - axis * dy;
    let a2 = dp.length_squared();
    let b_end = a + axis * len;
    if a2 <= PARALLEL_SIN2 * dir.length_squared() {
        // Parallel to the axis: only a cap can be hit; take the nearer.
        return match (sphere(origin, dir, a, r2), sphere(origin, dir, b_end, r2)) {
            (Some(p), Some(q)) => Some(if p.0 <= q.0 { p } else { q }),
            (p, q) => p.or(q),
        };
    }
    // a2 * (r^2 - squared distance from the axis line to the ray's line).
    let ah = r2 * a2 - op.cross(dp).length_squared();
    if ah < 0.0 {
        // Misses the infinite cylinder, hence the capsule inside it.
        return None;
    }
    let t = (-op.dot(dp) - ah.sqrt()) / a2;
    let y = y0 + t * dy;
    if (0.0..=len).contains(&y) {
        return (t >= 0.0).then(|| (t, op + dp * t));
    }
    // Entering the infinite cylinder beyond an end: the first hit, if any, is on the cap
    // sphere of that end (its disc at the end plane fills the cylinder's cross-section).
    let center = if y < 0.0 { a } else { b_end };
    sphere(origin, dir, center, r2)
}

/// Axis-aligned box centred on the origin with half extents `half` (slab test).
#[inline(always)]
pub(crate) fn cuboid(origin: Vec3, dir: Vec3, half: Vec3) -> Option<(f32, Vec3)> {
    let inv = dir.recip();
    let t1 = (-half - origin) * inv;
    let t2 = (half - origin) * inv;
    let t_lo = t1.min(t2);
    let t_hi = t1.max(t2);
    let t_near = t_lo.x.max(t_lo.y).max(t_lo.z);
    let t_far = t_hi.x.min(t_hi.y).min(t_hi.z);
    if t_near > t_far || t_far < 0.0 || t_near.is_nan() {
        return None;
    }
    if t_near < 0.0 {
        return Some((0.0, -dir));
    }
    let normal = if t_lo.x >= t_lo.y && t_lo.x >= t_lo.z {
        Vec3::new(-dir.x.signum(), 0.0, 0.0)
    } else if t_lo.y >= t_lo.z {
        Vec3::new(0.0, -dir.y.signum(), 0.0)
    } else {
        Vec3::new(0.0, 0.0, -dir.z.signum())
    };
    Some((t_near, normal))
}

/// Cylinder centred on the origin, axis along Y, caps at `y = +-half_height`.
#[inline(always)]
pub(crate) fn cylinder(origin: Vec3, dir: Vec3, half_height: f32, r2: f32) -> Option<(f32, Vec3)> {
    let o_rr = origin.x * origin.x + origin.z * origin.z;
    if o_rr <= r2 && origin.y.abs() <= half_height {
        return Some((0.0, -dir));
    }
    // Side: circle in the XZ plane.
    let a2 = dir.x * dir.x + dir.z * dir.z;
    let (side_in, side_out) = if a2 > PARALLEL_SIN2 * dir.length_squared() {
        let b = origin.x * dir.x + origin.z * dir.z;
        // a2 * (r^2 - squared distance from the axis to the ray's line in XZ).
        let cross = origin.x * dir.z - origin.z * dir.x;
        let ah = r2 * a2 - cross * cross;
        if ah < 0.0 {
            return None;
        }
        let root = ah.sqrt();
        ((-b - root) / a2, (-b + root) / a2)
    } else if o_rr <= r2 {
        (f32::NEG_INFINITY, f32::INFINITY)
    } else {
        return None;
    };
    // Caps: slab in Y.
    let (cap_in, cap_out) = if dir.y != 0.0 {
        let inv = dir.y.recip();
        let t1 = (-half_height - origin.y) * inv;
        let t2 = (half_height - origin.y) * inv;
        (t1.min(t2), t1.max(t2))
    } else if origin.y.abs() <= half_height {
        (f32::NEG_INFINITY, f32::INFINITY)
    } else {
        return None;
    };
    let t_near = side_in.max(cap_in);
    let t_far = side_out.min(cap_out);
    if t_near > t_far || t_near < 0.0 || t_near.is_nan() {
        return None;
    }
    let normal = if side_in >= cap_in {
        let p = origin + dir * t_near;
        Vec3::new(p.x, 0.0, p.z)
    } else {
        Vec3::new(0.0, -dir.y.signum(), 0.0)
    };
    Some((t_near, normal))
}

#[cfg(test)]
mod tests {
    //! Agreement with an exact `f64` evaluation and with parry3d's `RayCast` on many
    //! random rays and shapes.

    use super::*;
    use nalgebra::Vector3;
    use parry3d::math::Pose;
    use parry3d::query::Ray;
    use parry3d::shape::{Ball, Capsule, Cuboid, Cylinder, Shape, TriMesh};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Grow / shrink margin used to classify near-tangent rays (m).
    const MARGIN: f32 = 2e-5;
    /// Segments of the tessellated reference cylinder: sagitta `r (1 - cos(pi / n))`
    /// = 0.4 um at r = 0.08 m, well inside `MARGIN`.
    const CYLINDER_SEGMENTS: u32 = 1024;

    type V = Vector3<f64>;

    fn v64(v: Vec3) -> V {
        V::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
    }

    /// Textbook `f64` first entry `t >= 0` of a ray into a sphere (origin outside).
    fn exact_sphere(o: V, d: V, c: V, r: f64) -> Option<f64> {
        let oc = o - c;
        let (a, b, cc) = (d.dot(&d), oc.dot(&d), oc.dot(&oc) - r * r);
        let disc = b * b - a * cc;
        let t = (-b - disc.max(0.0).sqrt()) / a;
        (disc >= 0.0 && t >= 0.0).then_some(t)
    }

    /// Exact `f64` first hit for each primitive (origin outside it).
    fn exact(shape: &Analytic, o: Vec3, d: Vec3) -> Option<f64> {
        let (o, d) = (v64(o), v64(d));
        match *shape {
            Analytic::Sphere { center, r2 } => {
                exact_sphere(o, d, v64(center), f64::from(r2).sqrt())
            }
            Analytic::Capsule { a, axis, len, r2 } => {
                // Union of the body cylinder and both end spheres: first hit = min.
                let (a, u, len, r) = (v64(a), v64(axis), f64::from(len), f64::from(r2).sqrt());
                let oa = o - a;
                let (op, dp) = (oa - u * oa.dot(&u), d - u * d.dot(&u));
                let (qa, qb, qc) = (dp.dot(&dp), op.dot(&dp), op.dot(&op) - r * r);
                let disc = qb * qb - qa * qc;
                let body = (disc >= 0.0 && qa > 0.0)
                    .then(|| (-qb - disc.sqrt()) / qa)
                    .filter(|t| *t >= 0.0 && (0.0..=len).contains(&(oa + d * *t).dot(&u)));
                [
                    body,
                    exact_sphere(o, d, a, r),
                    exact_sphere(o, d, a + u * len, r),
                ]
                .into_iter()
                .flatten()
                .reduce(f64::min)
            }
            Analytic::Cuboid { half } => {
                let h = v64(half);
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                for k in 0..3 {
                    let (ta, tb) = ((-h[k] - o[k]) / d[k], (h[k] - o[k]) / d[k]);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                (t0 <= t1 && t0 >= 0.0).then_some(t0)
            }
            Analytic::Cylinder { half_height, r2 } => {
                let (hh, r2) = (f64::from(half_height), f64::from(r2));
                let qa = d.x * d.x + d.z * d.z;
                let qb = o.x * d.x + o.z * d.z;
                let disc = qb * qb - qa * (o.x * o.x + o.z * o.z - r2);
                if disc < 0.0 || qa == 0.0 {
                    return None;
                }
                let (s0, s1) = ((-qb - disc.sqrt()) / qa, (-qb + disc.sqrt()) / qa);
                let (ya, yb) = ((-hh - o.y) / d.y, (hh - o.y) / d.y);
                let (t0, t1) = (s0.max(ya.min(yb)), s1.min(ya.max(yb)));
                (t0 <= t1 && t0 >= 0.0).then_some(t0)
            }
        }
    }

    fn random_unit(rng: &mut ChaCha8Rng) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let n = v.length();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }

    /// A shape as (parry3d reference shape, analytic form), exact and grown/shrunk by
    /// `MARGIN`. parry3d's own `Cylinder` ray cast runs GJK with a ~1e-3 relative
    /// tolerance (mm-level errors near the cap rims), so the cylinder's reference is a
    /// finely tessellated parry3d `TriMesh` instead.
    fn random_shape(rng: &mut ChaCha8Rng, kind: usize) -> [(Box<dyn Shape>, Analytic); 3] {
        let mut size = || rng.random_range(0.003_f32..0.08);
        match kind {
            0 => {
                let r = size();
                [r, r + MARGIN, r - MARGIN].map(|r| {
                    let analytic = Analytic::Sphere {
                        center: Vec3::ZERO,
                        r2: r * r,
                    };
                    (Box::new(Ball::new(r)) as Box<dyn Shape>, analytic)
                })
            }
            1 => {
                let (r, hl) = (size(), size());
                let axis = random_unit(rng);
                let a = axis * -hl + Vec3::new(0.01, -0.02, 0.005);
                [r, r + MARGIN, r - MARGIN].map(|r| {
                    let analytic = Analytic::Capsule {
                        a,
                        axis,
                        len: 2.0 * hl,
                        r2: r * r,
                    };
                    let shape = Capsule::new(a, a + axis * 2.0 * hl, r);
                    (Box::new(shape) as Box<dyn Shape>, analytic)
                })
            }
            2 => {
                let half = Vec3::new(size(), size(), size());
                [0.0, MARGIN, -MARGIN].map(|m| {
                    let half = half + Vec3::splat(m);
                    let analytic = Analytic::Cuboid { half };
                    (Box::new(Cuboid::new(half)) as Box<dyn Shape>, analytic)
                })
            }
            _ => {
                let (hh, r) = (size(), size());
                [0.0, MARGIN, -MARGIN].map(|m| {
                    let (hh, r) = (hh + m, r + m);
                    let analytic = Analytic::Cylinder {
                        half_height: hh,
                        r2: r * r,
                    };
                    let (vertices, indices) = Cylinder::new(hh, r).to_trimesh(CYLINDER_SEGMENTS);
                    let mesh = TriMesh::new(vertices, indices).expect("cylinder mesh");
                    (Box::new(mesh) as Box<dyn Shape>, analytic)
                })
            }
        }
    }

    fn parry_cast(shape: &dyn Shape, origin: Vec3, dir: Vec3) -> Option<(f32, Vec3)> {
        shape
            .cast_ray_and_get_normal(&Pose::identity(), &Ray::new(origin, dir), f32::MAX, true)
            .map(|hit| (hit.time_of_impact, hit.normal))
    }

    #[test]
    fn analytic_casts_agree_with_exact_f64_and_parry() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let names = ["ball", "capsule", "cuboid", "cylinder"];
        for (kind, name) in names.iter().enumerate() {
            let (mut hits, mut normal_ok) = (0_u32, 0_u32);
            let (mut worst_exact_mm, mut worst_parry_mm) = (0.0_f64, 0.0_f32);
            for _ in 0..200 {
                let [exact_shape, grown, shrunk] = random_shape(&mut rng, kind);
                for _ in 0..200 {
                    // Camera-like rays: origin 0.3 - 1.2 m away (outside the shape),
                    // aimed near it, direction length 1 - 1.5 like the renderer's
                    // (x, y, 1) rays.
                    let origin = random_unit(&mut rng) * rng.random_range(0.3..1.2);
                    let aim = random_unit(&mut rng) * rng.random_range(0.0..0.1);
                    let dir = (aim - origin).normalize() * rng.random_range(1.0..1.5);
                    let ours = exact_shape.1.cast(origin, dir);

                    // 1. Against the exact f64 answer; near-tangent rays may flip.
                    match (ours, exact(&exact_shape.1, origin, dir)) {
                        (Some((t, _)), Some(te)) => {
                            let err_mm = (f64::from(t) - te).abs() * f64::from(dir.length()) * 1e3;
                            worst_exact_mm = worst_exact_mm.max(err_mm);
                            assert!(err_mm < 0.01, "{name}: {t} vs exact {te}");
                        }
                        (None, None) => {}
                        (Some(_), None) => assert!(exact(&grown.1, origin, dir).is_some()),
                        (None, Some(_)) => assert!(exact(&shrunk.1, origin, dir).is_none()),
                    }

                    // 2. Against parry3d.
                    let reference = parry_cast(exact_shape.0.as_ref(), origin, dir);
                    match (ours, reference) {
                        (Some((t, n)), Some((tr, nr))) => {
                            hits += 1;
                            let err_mm = (t - tr).abs() * dir.length() * 1000.0;
                            worst_parry_mm = worst_parry_mm.max(err_mm);
                            assert!(err_mm < 0.5, "{name}: {t} vs parry {tr} ({err_mm} mm)");
                            if n.normalize().dot(nr.normalize()) > 0.999 {
                                normal_ok += 1;
                            }
                        }
                        (None, None) => {}
                        (Some(_), None) => assert!(
                            parry_cast(grown.0.as_ref(), origin, dir).is_some(),
                            "{name}: we hit where parry misses the grown shape"
                        ),
                        (None, Some(_)) => assert!(
                            parry_cast(shrunk.0.as_ref(), origin, dir).is_none(),
                            "{name}: we miss where parry hits the shrunk shape"
                        ),
                    }
                }
            }
            assert!(hits > 10_000, "{name}: only {hits} hits");
            // Edges, rims and mesh facets make the normal ambiguous on a few rays.
            assert!(
                normal_ok as f32 > 0.99 * hits as f32,
                "{name}: normals agree on {normal_ok} of {hits}"
            );
            eprintln!(
                "{name}: {hits} hits; worst depth difference {worst_exact_mm:.5} mm vs exact \
                 f64, {worst_parry_mm:.4} mm vs parry3d"
            );
        }
    }

    /// Documents why the cylinder's reference is a mesh: parry3d's GJK cast on
    /// `Cylinder` is millimetre-approximate near the rims while ours is exact.
    #[test]
    fn parry_gjk_cylinder_is_approximate() {
        let shape = Cylinder::new(0.09920056, 0.027277441);
        let o = Vec3::new(0.017479353, 0.18892089, -0.07481849);
        let d = Vec3::new(-0.04033872, -1.0069596, 1.075716);
        let analytic = Analytic::Cylinder {
            half_height: shape.half_height,
            r2: shape.radius * shape.radius,
        };
        let ours = analytic.cast(o, d).map(|h| f64::from(h.0));
        let exact_t = exact(&analytic, o, d);
        let gjk = parry_cast(&shape, o, d).map(|h| f64::from(h.0));
        let (Some(ours), Some(exact_t), Some(gjk)) = (ours, exact_t, gjk) else {
            panic!("all three should hit: {ours:?} {exact_t:?} {gjk:?}");
        };
        assert!((ours - exact_t).abs() < 1e-6);
        eprintln!(
            "GJK cylinder error: {:.2} mm",
            (gjk - exact_t).abs() * 1e3 * 1.47
        );
    }

    #[test]
    fn origin_inside_returns_zero() {
        let o = Vec3::new(0.001, 0.002, -0.001);
        let d = Vec3::new(0.3, 0.1, 1.0);
        let shapes = [
            Analytic::Sphere {
                center: Vec3::ZERO,
                r2: 0.01,
            },
            Analytic::Capsule {
                a: Vec3::new(0.0, -0.05, 0.0),
                axis: Vec3::Y,
                len: 0.1,
                r2: 0.0004,
            },
            Analytic::Cuboid {
                half: Vec3::splat(0.02),
            },
            Analytic::Cylinder {
                half_height: 0.02,
                r2: 0.0004,
            },
        ];
        for s in shapes {
            assert_eq!(s.cast(o, d).map(|h| h.0), Some(0.0), "{s:?}");
        }
    }

    #[test]
    fn axis_parallel_rays() {
        // Straight down a capsule's and a cylinder's axis, and beside it.
        let capsule = Analytic::Capsule {
            a: Vec3::new(0.0, -0.05, 0.0),
            axis: Vec3::Y,
            len: 0.1,
            r2: 0.0001,
        };
        let hit = capsule.cast(Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.0, -1.0, 0.0));
        assert!((hit.map_or(0.0, |h| h.0) - 0.44).abs() < 1e-5, "{hit:?}");
        let beside = capsule.cast(Vec3::new(0.011, 0.5, 0.0), Vec3::new(0.0, -1.0, 0.0));
        assert!(beside.is_none());
        let cylinder = Analytic::Cylinder {
            half_height: 0.05,
            r2: 0.0001,
        };
        let hit = cylinder.cast(Vec3::new(0.005, -0.5, 0.0), Vec3::new(0.0, 2.0, 0.0));
        assert!((hit.map_or(0.0, |h| h.0) - 0.225).abs() < 1e-6, "{hit:?}");
        assert_eq!(hit.map(|h| h.1), Some(Vec3::new(0.0, -1.0, 0.0)));
    }
}
