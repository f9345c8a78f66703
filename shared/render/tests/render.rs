//! Rendered images against closed-form values and against brute-force parry3d ray
//! casting.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use teleop_render::scenes::{hand_facing_camera, synthetic_hand};
use teleop_render::{
    AMBIENT, Camera, Channels, DepthNoise, DepthRange, Frame, Intrinsics, NoiseParams, Primitive,
    RayBackend, RenderError, Renderer, Rgb8, Scene,
};

fn render(scene: &Scene, camera: &Camera, backend: RayBackend) -> Frame {
    let mut frame = Frame::new(Channels::ALL);
    Renderer::with_backend(backend).render(scene, camera, &mut frame);
    frame
}

fn camera_at_origin(intrinsics: Intrinsics) -> Camera {
    Camera::new(intrinsics, DepthRange::sr300(), Isometry3::identity())
}

#[test]
fn box_face_depth_equals_distance() {
    let mut scene = Scene::new();
    // Front face at exactly 0.5 m, larger than the field of view there.
    scene
        .push(
            Primitive::cuboid(&Vector3::new(1.0, 1.0, 0.01)),
            Isometry3::translation(0.0, 0.0, 0.51),
        )
        .unwrap();
    let frame = render(&scene, &Camera::default(), RayBackend::Analytic);
    assert!(frame.depth_mm().iter().all(|&d| d == 500));
    // Facing the light at the camera: the centre is full white.
    assert_eq!(frame.grey().unwrap()[240 * 640 + 320], 255);
}

#[test]
fn tilted_plane_matches_analytic_depth() {
    let rotation = UnitQuaternion::from_euler_angles(0.5, -0.35, 0.2);
    let centre = Vector3::new(0.02, -0.01, 0.7);
    let half_z = 0.005;
    let mut scene = Scene::new();
    scene
        .push(
            Primitive::cuboid(&Vector3::new(2.0, 2.0, half_z)),
            Isometry3::from_parts(Translation3::from(centre), rotation),
        )
        .unwrap();
    let camera = Camera::default();
    let frame = render(&scene, &camera, RayBackend::Analytic);
    // The face towards the camera: n . X = n . p0 with n = R (0, 0, -1).
    let n = rotation * -Vector3::z();
    let p0 = centre + n * half_z;
    let k = camera.intrinsics;
    let (mut checked, mut out_of_range) = (0, 0);
    for v in 0..480 {
        for u in 0..640 {
            let ray = k.ray_through(f64::from(u), f64::from(v));
            let z = n.dot(&p0) / n.dot(&ray);
            let got = frame.depth_mm_at(u, v).unwrap();
            if (0.2..=1.2).contains(&z) {
                let expected = z * 1000.0;
                assert!(
                    (f64::from(got) - expected).abs() <= 1.0,
                    "({u}, {v}): {got} vs {expected}"
                );
                checked += 1;
            } else if !(0.1999..=1.2001).contains(&z) {
                assert_eq!(got, 0, "({u}, {v}) at {z} m is out of range");
                out_of_range += 1;
            }
        }
    }
    assert!(checked > 200_000, "{checked}");
    assert!(
        out_of_range > 1_000,
        "the plane should leave the range: {out_of_range}"
    );
}

#[test]
fn sphere_silhouette_matches_projection() {
    // Square pixels and an integer principal point make the centre row exact.
    let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 480).unwrap();
    for (r, z) in [(0.05, 0.6), (0.03, 0.3), (0.1, 1.0), (0.015, 0.45)] {
        let mut scene = Scene::new();
        scene
            .push(Primitive::ball(r), Isometry3::translation(0.0, 0.0, z))
            .unwrap();
        let frame = render(&scene, &camera_at_origin(k), RayBackend::Analytic);
        // Image of a sphere on the axis: a circle of radius f r / sqrt(z^2 - r^2).
        let radius_px = 500.0 * r / (z * z - r * r).sqrt();
        let row = &frame.depth_mm()[240 * 640..241 * 640];
        let width = row.iter().filter(|&&d| d != 0).count();
        let expected_width = 2 * radius_px.floor() as usize + 1;
        assert_eq!(width, expected_width, "r {r} z {z}: radius {radius_px} px");
        let area = frame.depth_mm().iter().filter(|&&d| d != 0).count() as f64;
        let area_radius = (area / std::f64::consts::PI).sqrt();
        assert!(
            (area_radius - radius_px).abs() < 0.02 * radius_px + 0.5,
            "area radius {area_radius} vs {radius_px}"
        );
        // The nearest point is on the axis at z - r.
        let centre = frame.depth_mm_at(320, 240).unwrap();
        assert!((f64::from(centre) - (z - r) * 1000.0).abs() <= 0.5);
    }
}

#[test]
fn pixels_outside_range_are_zero_in_every_image() {
    let camera = Camera::default();
    let wall = Primitive::cuboid(&Vector3::new(2.0, 2.0, 0.01));
    // Beyond the far limit.
    let mut far = Scene::new();
    far.push(wall, Isometry3::translation(0.0, 0.0, 1.5))
        .unwrap();
    // A wall in range behind a plate too close to the sensor: the plate occludes it.
    let mut near = Scene::new();
    near.push(wall, Isometry3::translation(0.0, 0.0, 0.5))
        .unwrap();
    near.push(wall, Isometry3::translation(0.0, 0.0, 0.1))
        .unwrap();
    for scene in [far, near] {
        let frame = render(&scene, &camera, RayBackend::Analytic);
        assert!(frame.depth_mm().iter().all(|&d| d == 0));
        assert!(frame.grey().unwrap().iter().all(|&g| g == 0));
        assert!(frame.rgb().unwrap().iter().all(|&c| c == 0));
        assert!(frame.ids().unwrap().iter().all(|&i| i == 0));
    }
    // An empty scene.
    let frame = render(&Scene::new(), &camera, RayBackend::Analytic);
    assert!(frame.depth_mm().iter().all(|&d| d == 0));
}

#[test]
fn behind_the_camera_is_invisible_and_straddling_shapes_render() {
    let mut scene = Scene::new();
    scene
        .push(Primitive::ball(0.1), Isometry3::translation(0.0, 0.0, -0.5))
        .unwrap();
    let frame = render(&scene, &Camera::default(), RayBackend::Analytic);
    assert!(frame.depth_mm().iter().all(|&d| d == 0));
    // A long capsule from behind the camera to 0.9 m, off-axis: part of it is visible.
    let mut scene = Scene::new();
    scene
        .push(
            Primitive::capsule(
                &Point3::new(0.1, 0.05, -0.5),
                &Point3::new(0.1, 0.05, 0.9),
                0.02,
            ),
            Isometry3::identity(),
        )
        .unwrap();
    let fast = render(&scene, &Camera::default(), RayBackend::Analytic);
    let reference = render(&scene, &Camera::default(), RayBackend::ParryBruteForce);
    let visible = fast.depth_mm().iter().filter(|&&d| d != 0).count();
    assert!(visible > 1_000, "{visible}");
    let stats = compare(&fast, &reference);
    assert_eq!(stats.hit_mismatches, 0, "{stats:?}");
}

#[test]
fn ids_colours_and_shading() {
    let mut scene = Scene::new();
    let red = Rgb8([200, 0, 0]);
    let front = scene
        .push_colored(
            Primitive::ball(0.05),
            Isometry3::translation(0.0, 0.0, 0.4),
            red,
        )
        .unwrap();
    let back = scene
        .push(
            Primitive::cuboid(&Vector3::new(1.0, 1.0, 0.01)),
            Isometry3::translation(0.0, 0.0, 0.81),
        )
        .unwrap();
    let frame = render(&scene, &Camera::default(), RayBackend::Analytic);
    let centre = 240 * 640 + 320;
    let ids = frame.ids().unwrap();
    assert_eq!(ids[centre], front.get());
    assert_eq!(ids[0], back.get());
    assert_eq!(frame.depth_mm()[0], 800);
    // Facing the camera: full brightness and the shape's own colour.
    assert_eq!(
        &frame.rgb().unwrap()[3 * centre..3 * centre + 3],
        &[200, 0, 0]
    );
    // The ball's rim is darker than its centre but brighter than the ambient floor.
    let grey = frame.grey().unwrap();
    let rim = (320..640)
        .rev()
        .map(|u| 240 * 640 + u)
        .find(|&i| ids[i] == front.get())
        .unwrap();
    assert!(
        grey[rim] < 150 && f32::from(grey[rim]) >= 255.0 * AMBIENT - 1.0,
        "{}",
        grey[rim]
    );
    // Every image agrees on where there is a return.
    for (i, &d) in frame.depth_mm().iter().enumerate() {
        assert_eq!(d != 0, ids[i] != 0);
        assert_eq!(d != 0, grey[i] != 0);
    }
    // Depth-only frames skip the other images.
    let mut depth_only = Frame::new(Channels::DEPTH_ONLY);
    Renderer::new().render(&scene, &Camera::default(), &mut depth_only);
    assert_eq!(depth_only.depth_mm(), frame.depth_mm());
    assert!(depth_only.grey().is_none() && depth_only.ids().is_none());
}

#[test]
fn look_at_builds_an_optical_frame() {
    // Camera 0.6 m out on +X looking back at the origin, world up = +Z.
    let pose = Camera::look_at(
        &Point3::new(0.6, 0.0, 0.0),
        &Point3::origin(),
        &Vector3::z(),
    )
    .unwrap();
    let camera = Camera::sr300(pose);
    let mut scene = Scene::new();
    scene
        .push(Primitive::ball(0.02), Isometry3::identity())
        .unwrap();
    // A marker above the ball (world +Z) must appear above it in the image (smaller v).
    let marker = scene
        .push(Primitive::ball(0.02), Isometry3::translation(0.0, 0.0, 0.1))
        .unwrap();
    let frame = render(&scene, &camera, RayBackend::Analytic);
    assert_eq!(frame.depth_mm_at(320, 240), Some(580));
    let ids = frame.ids().unwrap();
    let rows: Vec<usize> = (0..480)
        .filter(|&v| ids[v * 640 + 320] == marker.get())
        .collect();
    assert!(
        !rows.is_empty() && rows.iter().all(|&v| v < 200),
        "{rows:?}"
    );
    // Facing -X with +Z up, world +Y is to the right.
    let mut right = Scene::new();
    right
        .push(Primitive::ball(0.02), Isometry3::translation(0.0, 0.1, 0.0))
        .unwrap();
    let frame = render(&right, &camera, RayBackend::Analytic);
    let cols: Vec<u32> = (0..640)
        .filter(|&u| frame.depth_mm_at(u, 240) != Some(0))
        .collect();
    assert!(
        !cols.is_empty() && cols.iter().all(|&u| u > 360),
        "{cols:?}"
    );
    assert!(matches!(
        Camera::look_at(
            &Point3::origin(),
            &Point3::new(0.0, 0.0, 1.0),
            &Vector3::z()
        ),
        Err(RenderError::InvalidPose { .. })
    ));
}

#[test]
fn invalid_configuration_is_rejected() {
    assert!(matches!(
        Intrinsics::new(500.0, 500.0, 320.0, 240.0, 0, 480),
        Err(RenderError::ZeroSize { .. })
    ));
    assert!(matches!(
        Intrinsics::new(f64::NAN, 500.0, 320.0, 240.0, 640, 480),
        Err(RenderError::NonFiniteIntrinsic { name: "fx", .. })
    ));
    assert!(matches!(
        Intrinsics::new(500.0, 500.0, f64::INFINITY, 240.0, 640, 480),
        Err(RenderError::NonFiniteIntrinsic { name: "cx", .. })
    ));
    assert!(matches!(
        Intrinsics::new(500.0, -1.0, 320.0, 240.0, 640, 480),
        Err(RenderError::NonPositiveFocalLength { name: "fy", .. })
    ));
    assert!(matches!(
        Intrinsics::new(500.0, 500.0, 320.0, 240.0, 640, 100_000),
        Err(RenderError::TooLarge { .. })
    ));
    for fov in [0.0, 180.0, -10.0, 200.0, f64::NAN] {
        assert!(matches!(
            Intrinsics::from_fov_deg(640, 480, fov, 59.0),
            Err(RenderError::FovOutOfRange {
                name: "horizontal",
                ..
            })
        ));
        assert!(matches!(
            Intrinsics::from_fov_deg(640, 480, 73.0, fov),
            Err(RenderError::FovOutOfRange {
                name: "vertical",
                ..
            })
        ));
    }
    assert!(matches!(
        Intrinsics::from_fov_deg(0, 480, 73.0, 59.0),
        Err(RenderError::ZeroSize { .. })
    ));
    assert!(matches!(
        Intrinsics::sr300().cropped(600, 0, 100, 100),
        Err(RenderError::CropOutOfImage { .. })
    ));
    for (min, max) in [(-0.1, 1.0), (1.0, 1.0), (0.2, 70.0), (f64::NAN, 1.0)] {
        assert!(matches!(
            DepthRange::new(min, max),
            Err(RenderError::InvalidDepthRange { .. })
        ));
    }
    let mut scene = Scene::new();
    assert!(matches!(
        scene.push(Primitive::ball(0.0), Isometry3::identity()),
        Err(RenderError::InvalidShapeDimension { .. })
    ));
    assert!(matches!(
        scene.push(Primitive::cylinder_y(f64::NAN, 0.1), Isometry3::identity()),
        Err(RenderError::InvalidShapeDimension { .. })
    ));
    assert!(matches!(
        scene.push(
            Primitive::ball(0.1),
            Isometry3::translation(f64::NAN, 0.0, 0.0)
        ),
        Err(RenderError::InvalidPose { .. })
    ));
    assert!(matches!(
        DepthNoise::new(
            NoiseParams {
                dropout_probability: 1.5,
                ..NoiseParams::sr300()
            },
            1
        ),
        Err(RenderError::InvalidNoiseParameter { .. })
    ));
}

#[test]
fn fov_constructor_and_sr300_defaults() {
    let k = Intrinsics::from_fov_deg(640, 480, 73.0, 59.0).unwrap();
    assert_eq!(k, Intrinsics::sr300());
    assert!((k.horizontal_fov_deg() - 73.0).abs() < 1e-9);
    assert!((k.vertical_fov_deg() - 59.0).abs() < 1e-9);
    let small = k.resized(96, 96).unwrap();
    assert!((small.horizontal_fov_deg() - 73.0).abs() < 1e-9);
    assert!((small.cx() - 47.5).abs() < 1e-12);
    let crop = k.cropped(100, 50, 200, 200).unwrap();
    assert_eq!((crop.cx(), crop.cy()), (219.5, 189.5));
}

#[test]
fn noise_is_seeded_and_zero_mean() {
    let mut scene = Scene::new();
    scene
        .push(
            Primitive::cuboid(&Vector3::new(2.0, 2.0, 0.01)),
            Isometry3::translation(0.0, 0.0, 0.81),
        )
        .unwrap();
    let clean = render(&scene, &Camera::default(), RayBackend::Analytic);
    let noisy = |params: NoiseParams, seed: u64| {
        let mut frame = clean.clone();
        DepthNoise::new(params, seed).unwrap().apply(&mut frame);
        frame
    };
    let params = NoiseParams::gaussian_only(0.004);
    let a = noisy(params, 1);
    assert_eq!(
        a.depth_mm(),
        noisy(params, 1).depth_mm(),
        "same seed, same bits"
    );
    assert_ne!(a.depth_mm(), noisy(params, 2).depth_mm());
    // Grey, colour and ids stay the clean ground truth.
    assert_eq!(a.grey(), clean.grey());
    let diffs: Vec<f64> = a
        .depth_mm()
        .iter()
        .zip(clean.depth_mm())
        .map(|(&n, &c)| f64::from(n) - f64::from(c))
        .collect();
    let count = diffs.len() as f64;
    let mean = diffs.iter().sum::<f64>() / count;
    let std = (diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / count).sqrt();
    // sigma = 0.004 * 0.8^2 m = 2.56 mm, plus 1/12 mm^2 of rounding.
    let expected_std = (2.56_f64.powi(2) + 1.0 / 12.0).sqrt();
    assert!(mean.abs() < 0.03, "mean {mean} mm");
    assert!(
        (std - expected_std).abs() < 0.05,
        "std {std} vs {expected_std} mm"
    );
    // Noise grows with z^2: at 0.4 m it is a quarter as large.
    let mut near_scene = Scene::new();
    near_scene
        .push(
            Primitive::cuboid(&Vector3::new(2.0, 2.0, 0.01)),
            Isometry3::translation(0.0, 0.0, 0.41),
        )
        .unwrap();
    let mut near = render(&near_scene, &Camera::default(), RayBackend::Analytic);
    DepthNoise::new(params, 3).unwrap().apply(&mut near);
    let near_std = (near
        .depth_mm()
        .iter()
        .map(|&d| (f64::from(d) - 400.0).powi(2))
        .sum::<f64>()
        / count)
        .sqrt();
    assert!(
        (near_std - (0.64_f64.powi(2) + 1.0 / 12.0).sqrt()).abs() < 0.05,
        "{near_std}"
    );
}

#[test]
fn noise_drops_silhouette_edges_and_random_pixels() {
    let scene = synthetic_hand(&hand_facing_camera(0.4), 0.3).unwrap();
    let clean = render(&scene, &Camera::default(), RayBackend::Analytic);
    let params = NoiseParams {
        sigma_coeff_per_m: 0.0,
        ..NoiseParams::sr300()
    };
    let mut frame = clean.clone();
    DepthNoise::new(params, 11).unwrap().apply(&mut frame);
    let (w, h) = (640_usize, 480_usize);
    let d = clean.depth_mm();
    let is_edge = |i: usize| {
        let (u, v) = (i % w, i / w);
        let differs = |j: usize| d[j] == 0 || (i32::from(d[j]) - i32::from(d[i])).abs() > 10;
        (u > 0 && differs(i - 1))
            || (u + 1 < w && differs(i + 1))
            || (v > 0 && differs(i - w))
            || (v + 1 < h && differs(i + w))
    };
    let (mut edges, mut edges_dropped, mut inner, mut inner_dropped) = (0, 0, 0, 0);
    for i in (0..w * h).filter(|&i| d[i] != 0) {
        let dropped = frame.depth_mm()[i] == 0;
        if is_edge(i) {
            edges += 1;
            edges_dropped += usize::from(dropped);
        } else {
            inner += 1;
            inner_dropped += usize::from(dropped);
            // No axial noise configured: kept pixels are unchanged.
            assert!(dropped || frame.depth_mm()[i] == d[i]);
        }
    }
    let edge_rate = edges_dropped as f64 / edges as f64;
    let inner_rate = inner_dropped as f64 / inner as f64;
    assert!(
        edges > 1_000 && inner > 20_000,
        "{edges} edge, {inner} inner pixels"
    );
    assert!((edge_rate - 0.5).abs() < 0.05, "edge dropout {edge_rate}");
    assert!(
        (inner_rate - 0.002).abs() < 0.001,
        "random dropout {inner_rate}"
    );
}

/// Per-pixel comparison of two renders of the same scene.
#[derive(Debug, Default)]
struct Comparison {
    /// Pixels away from silhouettes that one render hits and the other misses.
    hit_mismatches: usize,
    /// Pixels compared for depth.
    depth_compared: usize,
    /// Largest depth difference there (mm).
    max_depth_diff_mm: u16,
    /// Pixels excluded as silhouette / discontinuity pixels.
    excluded: usize,
}

/// Silhouette pixels (an 8-neighbour differs in hit / no-hit, in either image) are
/// excluded from the hit test; depth-discontinuity pixels (an 8-neighbour more than
/// 3 mm away) also from the depth test.
fn compare(a: &Frame, b: &Frame) -> Comparison {
    let (w, h) = (a.width() as usize, a.height() as usize);
    let (da, db) = (a.depth_mm(), b.depth_mm());
    let mut out = Comparison::default();
    for v in 0..h {
        for u in 0..w {
            let i = v * w + u;
            let (mut silhouette, mut discontinuity) = (false, false);
            for (dv, du) in (-1_i64..=1).flat_map(|dv| (-1_i64..=1).map(move |du| (dv, du))) {
                let (nu, nv) = (u as i64 + du, v as i64 + dv);
                if nu < 0 || nv < 0 || nu >= w as i64 || nv >= h as i64 {
                    continue;
                }
                let j = nv as usize * w + nu as usize;
                for d in [da, db] {
                    silhouette |= (d[i] == 0) != (d[j] == 0);
                    discontinuity |= d[i].abs_diff(d[j]) > 3;
                }
            }
            if silhouette {
                out.excluded += 1;
                continue;
            }
            if (da[i] == 0) != (db[i] == 0) {
                out.hit_mismatches += 1;
            } else if da[i] != 0 && !discontinuity {
                out.depth_compared += 1;
                out.max_depth_diff_mm = out.max_depth_diff_mm.max(da[i].abs_diff(db[i]));
            }
        }
    }
    out
}

/// A random scene of every primitive kind in front of a randomly placed camera.
fn random_scene(rng: &mut ChaCha8Rng, with_cylinders: bool) -> (Scene, Camera) {
    let eye = Point3::new(
        rng.random_range(-0.5..0.5),
        rng.random_range(-0.5..0.5),
        rng.random_range(-0.5..0.5),
    );
    let target = eye
        + Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            1.0,
        );
    let pose =
        Camera::look_at(&eye, &target, &Vector3::new(0.1, -1.0, 0.05)).expect("up not along view");
    let camera = Camera::new(
        Intrinsics::from_fov_deg(320, 240, 73.0, 59.0).expect("valid fov"),
        DepthRange::sr300(),
        pose,
    );
    let mut scene = Scene::new();
    let kinds = if with_cylinders { 4 } else { 3 };
    for _ in 0..30 {
        let kind = rng.random_range(0..kinds);
        let mut size = || rng.random_range(0.005..0.08);
        let primitive = match kind {
            0 => Primitive::ball(size()),
            1 => Primitive::capsule(
                &Point3::new(size(), -size(), 0.0),
                &Point3::new(-size(), size(), size()),
                size(),
            ),
            2 => Primitive::cuboid(&Vector3::new(size(), size(), size())),
            _ => Primitive::cylinder_y(size(), size()),
        };
        // Placed in the optical frame, 0.15 - 1.3 m ahead (some out of range), spread
        // a bit beyond the field of view.
        let z: f64 = rng.random_range(0.15..1.3);
        let in_camera = Isometry3::from_parts(
            Translation3::new(
                z * rng.random_range(-0.9..0.9),
                z * rng.random_range(-0.7..0.7),
                z,
            ),
            UnitQuaternion::from_euler_angles(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
            ),
        );
        scene
            .push(primitive, pose * in_camera)
            .expect("valid shape");
    }
    (scene, camera)
}

#[test]
fn analytic_renderer_matches_brute_force_parry_on_random_scenes() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let mut total = Comparison::default();
    for with_cylinders in [true, false, true, false, true, true, false, true] {
        let (scene, camera) = random_scene(&mut rng, with_cylinders);
        let reference = render(&scene, &camera, RayBackend::ParryBruteForce);
        let mut backends = vec![RayBackend::Analytic];
        if !with_cylinders {
            // parry3d's own (GJK) cylinder cast is approximate; see RayBackend docs.
            backends.push(RayBackend::ParryInRect);
        }
        for backend in backends {
            let frame = render(&scene, &camera, backend);
            let c = compare(&frame, &reference);
            assert_eq!(c.hit_mismatches, 0, "{backend:?}: {c:?}");
            assert!(c.max_depth_diff_mm <= 1, "{backend:?}: {c:?}");
            total.depth_compared += c.depth_compared;
            total.excluded += c.excluded;
        }
    }
    eprintln!("{total:?}");
    assert!(total.depth_compared > 50_000, "{total:?}");
}

#[test]
fn hand_frames_match_brute_force_at_both_sizes() {
    let scene = synthetic_hand(&hand_facing_camera(0.4), 0.4).unwrap();
    assert_eq!(
        scene.len(),
        teleop_render::scenes::SYNTHETIC_HAND_PRIMITIVES
    );
    let full = Camera::default();
    // The hand network's input: a ~250 mm window around the hand, resized to 96x96.
    let crop = Intrinsics::sr300().cropped(185, 105, 270, 270).unwrap();
    let small = Camera::new(
        crop.resized(96, 96).unwrap(),
        DepthRange::sr300(),
        Isometry3::identity(),
    );
    for camera in [full, small] {
        let fast = render(&scene, &camera, RayBackend::Analytic);
        let reference = render(&scene, &camera, RayBackend::ParryBruteForce);
        let c = compare(&fast, &reference);
        assert_eq!(c.hit_mismatches, 0, "{c:?}");
        assert!(c.max_depth_diff_mm <= 1, "{c:?}");
        let n = fast.width() as usize * fast.height() as usize;
        let covered = fast.depth_mm().iter().filter(|&&d| d != 0).count();
        eprintln!(
            "{}x{}: hand covers {covered} px; {c:?}",
            fast.width(),
            fast.height()
        );
        assert!(covered > n / 20, "{covered} of {n}");
        // Everything drawn is the hand, around 0.4 m away.
        let (lo, hi) = fast
            .depth_mm()
            .iter()
            .filter(|&&d| d != 0)
            .fold((u16::MAX, 0), |(lo, hi), &d| (lo.min(d), hi.max(d)));
        eprintln!("hand depth {lo} - {hi} mm");
        assert!(lo > 300 && hi < 450, "hand depth {lo} - {hi} mm");
    }
}

#[test]
fn renders_are_deterministic_and_buffers_reused() {
    let scene = synthetic_hand(&hand_facing_camera(0.4), 0.2).unwrap();
    let mut renderer = Renderer::new();
    let mut frame = Frame::new(Channels::ALL);
    renderer.render(&scene, &Camera::default(), &mut frame);
    let first = frame.clone();
    // A different size in between must not leave stale pixels behind.
    let small = Camera::new(
        Intrinsics::sr300().resized(96, 72).unwrap(),
        DepthRange::sr300(),
        Isometry3::identity(),
    );
    renderer.render(&scene, &small, &mut frame);
    assert_eq!(frame.depth_mm().len(), 96 * 72);
    renderer.render(&scene, &Camera::default(), &mut frame);
    assert_eq!(frame.depth_mm(), first.depth_mm());
    assert_eq!(frame.rgb(), first.rgb());
    assert_eq!(frame.ids(), first.ids());
}

#[test]
fn moving_a_shape_moves_its_image() {
    let mut scene = Scene::new();
    let ball = scene
        .push(Primitive::ball(0.03), Isometry3::translation(0.0, 0.0, 0.5))
        .unwrap();
    let camera = Camera::default();
    assert_eq!(
        render(&scene, &camera, RayBackend::Analytic).depth_mm_at(320, 240),
        Some(470)
    );
    scene
        .set_pose(ball, Isometry3::translation(0.0, 0.0, 0.7))
        .unwrap();
    assert_eq!(
        render(&scene, &camera, RayBackend::Analytic).depth_mm_at(320, 240),
        Some(670)
    );
}
