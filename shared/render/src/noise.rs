//! Seeded depth-sensor noise: axial noise growing with z^2, silhouette dropouts,
//! random dropouts.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::{Frame, RenderError};

/// Parameters of [`DepthNoise`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseParams {
    /// `k` in `sigma_z = k * z^2` (both in metres, so `k` is in 1/m). Structured-light
    /// and stereo sensors have axial noise growing with the square of the distance.
    pub sigma_coeff_per_m: f64,
    /// A valid pixel whose 4-neighbour has no return or differs by more than this
    /// (mm) is a silhouette-edge pixel.
    pub edge_jump_mm: u16,
    /// Probability that a silhouette-edge pixel has no return.
    pub edge_dropout_probability: f64,
    /// Probability that any other valid pixel has no return.
    pub dropout_probability: f64,
}

impl NoiseParams {
    /// SR300-like figures (order of magnitude, not a calibration): `sigma_z` = 1 mm at
    /// 0.5 m and 4 mm at 1 m, half of the silhouette pixels lost, 0.2 % random holes.
    #[must_use]
    pub fn sr300() -> Self {
        Self {
            sigma_coeff_per_m: 0.004,
            edge_jump_mm: 10,
            edge_dropout_probability: 0.5,
            dropout_probability: 0.002,
        }
    }

    /// Axial noise only, no dropouts.
    #[must_use]
    pub fn gaussian_only(sigma_coeff_per_m: f64) -> Self {
        Self {
            sigma_coeff_per_m,
            edge_jump_mm: u16::MAX,
            edge_dropout_probability: 0.0,
            dropout_probability: 0.0,
        }
    }
}

impl Default for NoiseParams {
    /// [`NoiseParams::sr300`].
    fn default() -> Self {
        Self::sr300()
    }
}

/// A seeded noise model for depth images.
///
/// The same parameters, seed and sequence of input frames give the same output bits.
/// Works on any `16UC1` image in millimetres (0 = no return) through
/// [`DepthNoise::apply_to_depth`]; [`DepthNoise::apply`] changes a [`Frame`]'s depth
/// only — its grey, colour and id images stay the clean ground truth.
#[derive(Debug, Clone)]
pub struct DepthNoise {
    params: NoiseParams,
    rng: ChaCha8Rng,
    clean: Vec<u16>,
}

impl DepthNoise {
    /// A noise model seeded with `seed`.
    ///
    /// # Errors
    /// [`RenderError::InvalidNoiseParameter`] if `sigma_coeff_per_m` is negative or not
    /// finite, or a probability lies outside `[0, 1]`.
    pub fn new(params: NoiseParams, seed: u64) -> Result<Self, RenderError> {
        if !(params.sigma_coeff_per_m.is_finite() && params.sigma_coeff_per_m >= 0.0) {
            return Err(RenderError::InvalidNoiseParameter {
                name: "sigma_coeff_per_m",
                value: params.sigma_coeff_per_m,
            });
        }
        for (name, value) in [
            ("edge_dropout_probability", params.edge_dropout_probability),
            ("dropout_probability", params.dropout_probability),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(RenderError::InvalidNoiseParameter { name, value });
            }
        }
        Ok(Self {
            params,
            rng: ChaCha8Rng::seed_from_u64(seed),
            clean: Vec::new(),
        })
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &NoiseParams {
        &self.params
    }

    /// Adds noise to a frame's depth image.
    pub fn apply(&mut self, frame: &mut Frame) {
        let (w, h) = (frame.width() as usize, frame.height() as usize);
        self.apply_to_depth(frame.depth_mm_mut(), w, h);
    }

    /// Adds noise to a row-major `width x height` depth image in millimetres.
    ///
    /// Per valid pixel, in order: a silhouette-edge pixel (see
    /// [`NoiseParams::edge_jump_mm`]) is dropped with the edge probability; any other is
    /// dropped with the dropout probability; a kept pixel becomes
    /// `round(d + N(0, sigma(d)))`, clamped to `1..=65535` so it stays valid.
    /// Edges are found on the clean input.
    ///
    /// # Panics
    /// If `depth_mm.len() != width * height`.
    pub fn apply_to_depth(&mut self, depth_mm: &mut [u16], width: usize, height: usize) {
        assert_eq!(depth_mm.len(), width * height, "depth image size");
        self.clean.clear();
        self.clean.extend_from_slice(depth_mm);
        let p = self.params;
        let jump = i32::from(p.edge_jump_mm);
        let clean = &self.clean;
        for v in 0..height {
            for u in 0..width {
                let i = v * width + u;
                let d = clean[i];
                if d == 0 {
                    continue;
                }
                let is_edge_to = |j: usize| {
                    let n = clean[j];
                    n == 0 || (i32::from(n) - i32::from(d)).abs() > jump
                };
                let edge = (u > 0 && is_edge_to(i - 1))
                    || (u + 1 < width && is_edge_to(i + 1))
                    || (v > 0 && is_edge_to(i - width))
                    || (v + 1 < height && is_edge_to(i + width));
                let drop_probability = if edge {
                    p.edge_dropout_probability
                } else {
                    p.dropout_probability
                };
                if drop_probability > 0.0 && self.rng.random::<f64>() < drop_probability {
                    depth_mm[i] = 0;
                    continue;
                }
                if p.sigma_coeff_per_m > 0.0 {
                    let z_m = f64::from(d) * 1e-3;
                    let sigma_mm = p.sigma_coeff_per_m * z_m * z_m * 1e3;
                    let n: f64 = self.rng.sample(StandardNormal);
                    let noisy = (f64::from(d) + sigma_mm * n).round();
                    depth_mm[i] = noisy.clamp(1.0, f64::from(u16::MAX)) as u16;
                }
            }
        }
    }
}
