//! The one depth preprocessing of the hand network. The dataset generator and the
//! run-time inference call the same function, so training and serving cannot disagree.
//!
//! 1. **Crop** a fixed cube of `cube_mm` (250 mm) centred on the hand-centre estimate:
//!    the cube's projection gives the pixel window, the cube's depth extent the depth
//!    window. Pixels outside the image count as background.
//! 2. **Noise removal**: a morphological opening (3 x 3 erosion then 3 x 3 dilation)
//!    of the in-cube mask removes isolated speckles and thin edge spurs.
//! 3. **Resize** the window to `size x size` (96) by nearest-neighbour sampling (no
//!    blending across depth edges, so no invented "flying" depths).
//! 4. **Normalise** depth to `[-1, 1]` over the cube's depth extent, `(d - d_c) / (cube/2)`;
//!    background is `+1` (far).
//!
//! When too few pixels of the cube hold the hand, the result is
//! [`Crop::NoHand`] — never a tensor of garbage.

use nalgebra::Point3;
use teleop_render::Intrinsics;

use crate::HandModelError;

/// Preprocessing parameters. The defaults are the ones the shipped model was trained
/// with; the model's metadata records them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreprocessConfig {
    /// Edge of the crop cube (mm).
    pub cube_mm: f64,
    /// Output side (pixels).
    pub size: usize,
    /// Apply the 3 x 3 opening.
    pub opening: bool,
    /// Fewer foreground pixels than this fraction of the output = no hand.
    pub min_foreground: f64,
}

impl Default for PreprocessConfig {
    fn default() -> Self {
        Self {
            cube_mm: 250.0,
            size: 96,
            opening: true,
            min_foreground: 0.03,
        }
    }
}

/// A pixel window of an image: top-left corner (may be negative) and size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub u0: i64,
    pub v0: i64,
    pub width: i64,
    pub height: i64,
}

impl Window {
    /// The part of the window inside a `width x height` image, as `(u0, v0, w, h)`,
    /// or `None` if they do not overlap.
    #[must_use]
    pub fn clipped(&self, width: u32, height: u32) -> Option<(u32, u32, u32, u32)> {
        let u0 = self.u0.max(0);
        let v0 = self.v0.max(0);
        let u1 = (self.u0 + self.width).min(i64::from(width));
        let v1 = (self.v0 + self.height).min(i64::from(height));
        if u1 <= u0 || v1 <= v0 {
            return None;
        }
        let c = |v: i64| u32::try_from(v).unwrap_or(0);
        Some((c(u0), c(v0), c(u1 - u0), c(v1 - v0)))
    }
}

/// The pixel window of the crop cube around `centre_m` (camera optical frame, m).
///
/// # Errors
/// [`HandModelError::Invalid`] for a non-finite centre or one closer than 10 cm to the
/// camera plane (or behind it).
pub fn crop_window(
    intrinsics: &Intrinsics,
    centre_m: &Point3<f64>,
    config: &PreprocessConfig,
) -> Result<Window, HandModelError> {
    if !centre_m.coords.iter().all(|v| v.is_finite()) || centre_m.z < 0.1 {
        return Err(HandModelError::Invalid {
            what: "hand centre",
            reason: format!(
                "{centre_m:?} must be finite and at least 0.1 m in front of the camera"
            ),
        });
    }
    let half = config.cube_mm / 2000.0;
    let u = intrinsics.fx() * centre_m.x / centre_m.z + intrinsics.cx();
    let v = intrinsics.fy() * centre_m.y / centre_m.z + intrinsics.cy();
    let hu = intrinsics.fx() * half / centre_m.z;
    let hv = intrinsics.fy() * half / centre_m.z;
    // Pixel centres at integer coordinates: the window spans [u - hu, u + hu].
    let u0 = (u - hu).round() as i64;
    let v0 = (v - hv).round() as i64;
    let width = ((2.0 * hu).round() as i64).max(1);
    let height = ((2.0 * hv).round() as i64).max(1);
    Ok(Window {
        u0,
        v0,
        width,
        height,
    })
}

/// The result of preprocessing one depth image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crop {
    /// The tensor was written; `foreground` is the fraction of hand pixels.
    Hand { foreground: f64 },
    /// Too few pixels in the cube: `foreground` is what was found.
    NoHand { foreground: f64 },
}

/// Reusable buffers of [`preprocess`] (no allocation after the first call of a size).
#[derive(Debug, Clone, Default)]
pub struct Scratch {
    mask: Vec<u8>,
    tmp: Vec<u8>,
}

/// Preprocesses a depth image (`16UC1`, millimetres, 0 = no return, row-major
/// `width x height`, seen through `intrinsics`) around the hand-centre estimate
/// `centre_m` (camera frame) into `out` (`size * size` values, row-major).
///
/// # Errors
/// [`HandModelError::Invalid`] if the image length does not match the intrinsics, the
/// output length is not `size * size`, the config is not usable, or the centre is not
/// finite or not in front of the camera.
pub fn preprocess(
    depth_mm: &[u16],
    intrinsics: &Intrinsics,
    centre_m: &Point3<f64>,
    config: &PreprocessConfig,
    scratch: &mut Scratch,
    out: &mut [f32],
) -> Result<Crop, HandModelError> {
    let (w, h) = (intrinsics.width() as usize, intrinsics.height() as usize);
    let invalid = |reason: String| HandModelError::Invalid {
        what: "preprocess input",
        reason,
    };
    if depth_mm.len() != w * h {
        return Err(invalid(format!(
            "depth image has {} pixels, the intrinsics say {w} x {h}",
            depth_mm.len()
        )));
    }
    let n = config.size;
    if n == 0 || n > 1024 || out.len() != n * n {
        return Err(invalid(format!(
            "output holds {} values for a {n} x {n} crop",
            out.len()
        )));
    }
    if !(config.cube_mm.is_finite() && config.cube_mm > 10.0) {
        return Err(invalid(format!("cube edge {} mm", config.cube_mm)));
    }
    let window = crop_window(intrinsics, centre_m, config)?;
    let half_mm = config.cube_mm / 2.0;
    let centre_mm = centre_m.z * 1000.0;
    let (near, far) = (centre_mm - half_mm, centre_mm + half_mm);

    // Mask of in-cube pixels over the window (outside the image = background).
    let (ww, wh) = (window.width as usize, window.height as usize);
    scratch.mask.clear();
    scratch.mask.resize(ww * wh, 0);
    if let Some((cu, cv, cw, ch)) = window.clipped(intrinsics.width(), intrinsics.height()) {
        for y in 0..ch as usize {
            let src_row = (cv as usize + y) * w + cu as usize;
            let dst_row = (cv as i64 - window.v0) as usize + y;
            let dst = dst_row * ww + (cu as i64 - window.u0) as usize;
            for x in 0..cw as usize {
                let d = f64::from(depth_mm[src_row + x]);
                scratch.mask[dst + x] = u8::from(d > 0.0 && d >= near && d <= far);
            }
        }
    }
    if config.opening {
        morph(&scratch.mask, &mut scratch.tmp, ww, wh, true);
        morph(&scratch.tmp, &mut scratch.mask, ww, wh, false);
    }

    // Nearest-neighbour resize and normalisation.
    let mut foreground = 0usize;
    let sx = ww as f64 / n as f64;
    let sy = wh as f64 / n as f64;
    for oy in 0..n {
        let wy = (((oy as f64 + 0.5) * sy) as usize).min(wh - 1);
        let iy = window.v0 + wy as i64;
        for ox in 0..n {
            let wx = (((ox as f64 + 0.5) * sx) as usize).min(ww - 1);
            let ix = window.u0 + wx as i64;
            let o = &mut out[oy * n + ox];
            *o = 1.0;
            if scratch.mask[wy * ww + wx] == 0 {
                continue;
            }
            // In the mask means inside the image.
            let d = f64::from(depth_mm[iy as usize * w + ix as usize]);
            *o = ((d - centre_mm) / half_mm).clamp(-1.0, 1.0) as f32;
            foreground += 1;
        }
    }
    let fraction = foreground as f64 / (n * n) as f64;
    Ok(if fraction < config.min_foreground {
        Crop::NoHand {
            foreground: fraction,
        }
    } else {
        Crop::Hand {
            foreground: fraction,
        }
    })
}

/// 3 x 3 erosion (`erode`) or dilation of a 0/1 mask; outside the window counts as 0.
/// Separable: a 1 x 3 pass along rows, then a 3 x 1 pass along columns.
fn morph(src: &[u8], dst: &mut Vec<u8>, w: usize, h: usize, erode: bool) {
    let op = |a: u8, b: u8| if erode { a & b } else { a | b };
    let mut rows = vec![0u8; w * h];
    for (s_row, r_row) in src.chunks_exact(w).zip(rows.chunks_exact_mut(w)) {
        for x in 0..w {
            let left = if x > 0 { s_row[x - 1] } else { 0 };
            let right = if x + 1 < w { s_row[x + 1] } else { 0 };
            r_row[x] = op(op(left, s_row[x]), right);
        }
    }
    dst.clear();
    dst.resize(w * h, 0);
    for y in 0..h {
        let here = &rows[y * w..(y + 1) * w];
        let out = &mut dst[y * w..(y + 1) * w];
        for x in 0..w {
            let up = if y > 0 { rows[(y - 1) * w + x] } else { 0 };
            let down = if y + 1 < h { rows[(y + 1) * w + x] } else { 0 };
            out[x] = op(op(up, here[x]), down);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image_with_square(k: &Intrinsics, depth: u16, half: usize) -> Vec<u16> {
        let (w, h) = (k.width() as usize, k.height() as usize);
        let mut img = vec![0u16; w * h];
        let (cu, cv) = (w / 2, h / 2);
        for y in cv - half..cv + half {
            for x in cu - half..cu + half {
                img[y * w + x] = depth;
            }
        }
        img
    }

    #[test]
    fn a_square_at_the_centre_fills_the_middle_and_normalises() {
        let k = Intrinsics::sr300();
        let img = image_with_square(&k, 500, 40);
        let cfg = PreprocessConfig::default();
        let mut out = vec![0.0; 96 * 96];
        let centre = Point3::new(0.0, 0.0, 0.5);
        let r = preprocess(&img, &k, &centre, &cfg, &mut Scratch::default(), &mut out).expect("ok");
        let Crop::Hand { foreground } = r else {
            panic!("expected a hand, got {r:?}")
        };
        // Square 80 px inside a ~216 px window: (80/216)^2 ~ 0.137.
        assert!((0.11..0.17).contains(&foreground), "{foreground}");
        assert!(
            out[48 * 96 + 48].abs() < 1e-6,
            "centre depth = cube centre -> 0"
        );
        assert_eq!(out[0], 1.0, "corners are background");
        assert!(out.iter().all(|v| (-1.0..=1.0).contains(v)));
    }

    #[test]
    fn speckles_are_removed_and_empty_crops_say_no_hand() {
        let k = Intrinsics::sr300();
        let (w, h) = (k.width() as usize, k.height() as usize);
        let mut img = vec![0u16; w * h];
        for i in (0..w * h).step_by(97) {
            img[i] = 500; // isolated pixels
        }
        let cfg = PreprocessConfig::default();
        let mut out = vec![0.0; 96 * 96];
        let r = preprocess(
            &img,
            &k,
            &Point3::new(0.0, 0.0, 0.5),
            &cfg,
            &mut Scratch::default(),
            &mut out,
        )
        .expect("ok");
        assert_eq!(r, Crop::NoHand { foreground: 0.0 });
        assert!(out.iter().all(|v| *v == 1.0));
        // Depth outside the cube is background too.
        let img = image_with_square(&k, 900, 60);
        let r = preprocess(
            &img,
            &k,
            &Point3::new(0.0, 0.0, 0.5),
            &cfg,
            &mut Scratch::default(),
            &mut out,
        )
        .expect("ok");
        assert!(matches!(r, Crop::NoHand { .. }));
    }

    #[test]
    fn a_window_beyond_the_image_edge_is_padded() {
        let k = Intrinsics::sr300();
        let img = vec![400u16; (k.width() * k.height()) as usize];
        let cfg = PreprocessConfig::default();
        let mut out = vec![0.0; 96 * 96];
        // Centre near the left edge: the left part of the crop is outside the image.
        let centre = Point3::new(-0.3, 0.0, 0.4);
        let r = preprocess(&img, &k, &centre, &cfg, &mut Scratch::default(), &mut out).expect("ok");
        assert!(matches!(r, Crop::Hand { .. }));
        assert_eq!(out[48 * 96], 1.0, "left edge outside the image");
        assert!(out[48 * 96 + 95] < 1.0, "right edge inside");
    }

    #[test]
    fn bad_input_is_refused_by_name() {
        let k = Intrinsics::sr300();
        let cfg = PreprocessConfig::default();
        let mut out = vec![0.0; 96 * 96];
        let mut s = Scratch::default();
        let err = preprocess(
            &[0u16; 10],
            &k,
            &Point3::new(0.0, 0.0, 0.5),
            &cfg,
            &mut s,
            &mut out,
        )
        .expect_err("short image");
        assert!(err.to_string().contains("10 pixels"), "{err}");
        let img = vec![0u16; (k.width() * k.height()) as usize];
        for centre in [Point3::new(f64::NAN, 0.0, 0.5), Point3::new(0.0, 0.0, -0.5)] {
            let err = preprocess(&img, &k, &centre, &cfg, &mut s, &mut out).expect_err("centre");
            assert!(err.to_string().contains("hand centre"), "{err}");
        }
        let mut small = vec![0.0; 10];
        assert!(
            preprocess(
                &img,
                &k,
                &Point3::new(0.0, 0.0, 0.5),
                &cfg,
                &mut s,
                &mut small
            )
            .is_err()
        );
    }

    #[test]
    fn a_cropped_render_window_gives_the_same_tensor_as_the_full_image() {
        let k = Intrinsics::sr300();
        let img = image_with_square(&k, 520, 50);
        let cfg = PreprocessConfig::default();
        let centre = Point3::new(0.01, -0.005, 0.5);
        let mut full = vec![0.0; 96 * 96];
        preprocess(&img, &k, &centre, &cfg, &mut Scratch::default(), &mut full).expect("full");
        let win = crop_window(&k, &centre, &cfg).expect("window");
        let (u0, v0, cw, ch) = win.clipped(k.width(), k.height()).expect("inside");
        let kc = k.cropped(u0, v0, cw, ch).expect("crop");
        let mut sub = Vec::new();
        for y in v0..v0 + ch {
            let row = (y * k.width() + u0) as usize;
            sub.extend_from_slice(&img[row..row + cw as usize]);
        }
        let mut part = vec![0.0; 96 * 96];
        preprocess(&sub, &kc, &centre, &cfg, &mut Scratch::default(), &mut part).expect("part");
        assert_eq!(full, part);
    }
}
