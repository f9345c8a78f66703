//! The normalized Gaussian basis `g(s)` of eqs. 8.7-8.8 and the canonical system
//! `ṡ = -s` that drives it (as in DMPs).
//!
//! ```text
//! ω_n(s) = exp(-0.5 h_n (s - c_n)²)                  (8.8)
//! [g]_n  = ω_n(s) / Σ_m ω_m(s)                        (8.7)
//! τ_s ṡ  = -s,  s = 1 at reset                       (thesis: ṡ = -s, τ_s = 1 s)
//! ```
//!
//! Centres and widths are ours (the thesis gives none): `c_n = exp(-t_n / τ_s)` at
//! `N_g` times `t_n` equally spaced over `[0, horizon_s]`; `h_n = 2 / Δc_n²`. See
//! [`BasisConfig`].
//!
//! `g` is evaluated with the smallest exponent subtracted first, so the largest
//! `ω` is exactly 1: the normalization never divides by an underflowed zero, for any
//! `s` (including `s = 0` long after the horizon). Every `g_n` is in `[0, 1]` and
//! they sum to 1, so `θᵀ g` is a convex combination of the weights: bounding the
//! weights bounds the profiles.

use crate::error::ConfigError;
use crate::hand::config::BasisConfig;

/// Centres, widths and current phase of the basis. Allocates once, in
/// [`GaussianBasis::new`]; evaluation writes into a caller's slice.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianBasis {
    centers: Vec<f64>,
    widths: Vec<f64>,
    phase_time_constant_s: f64,
    phase: f64,
}

impl GaussianBasis {
    /// The basis of `config`, phase 1.
    ///
    /// # Errors
    ///
    /// [`BasisConfig::validate`]'s error.
    pub fn new(config: &BasisConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let n = config.count;
        let centers: Vec<f64> = (0..n)
            .map(|k| {
                let t = if n == 1 {
                    0.0
                } else {
                    config.horizon_s * k as f64 / (n - 1) as f64
                };
                (-t / config.phase_time_constant_s).exp()
            })
            .collect();
        let widths = (0..n)
            .map(|k| {
                if n == 1 {
                    return 1.0;
                }
                let delta = if k + 1 < n {
                    centers[k] - centers[k + 1]
                } else {
                    centers[k - 1] - centers[k]
                };
                // Centres are distinct (exp is strictly decreasing) but, with a huge
                // horizon, two may round to the same value: keep h finite.
                2.0 / delta.abs().max(1e-150).powi(2)
            })
            .collect();
        Ok(Self {
            centers,
            widths,
            phase_time_constant_s: config.phase_time_constant_s,
            phase: 1.0,
        })
    }

    /// Number of Gaussians `N_g`.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// Always `false`: a basis has at least one Gaussian.
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }

    /// Centres `c_n`, in decreasing order (phase units).
    pub fn centers(&self) -> &[f64] {
        &self.centers
    }

    /// Widths `h_n` (1/phase²).
    pub fn widths(&self) -> &[f64] {
        &self.widths
    }

    /// Current phase `s`, in `[0, 1]`, decreasing.
    pub fn phase(&self) -> f64 {
        self.phase
    }

    /// Restarts the phase at `s = 1`.
    pub fn reset(&mut self) {
        self.phase = 1.0;
    }

    /// Advances the phase by `dt_s` with the exact solution of `τ_s ṡ = -s`:
    /// `s ← s exp(-dt / τ_s)`.
    pub fn advance(&mut self, dt_s: f64) {
        self.phase *= (-dt_s / self.phase_time_constant_s).exp();
    }

    /// Writes `g(s)` at the current phase into `g` (`g.len()` must be
    /// [`len`](Self::len); extra entries are left alone, missing ones skipped).
    pub fn evaluate(&self, g: &mut [f64]) {
        let s = self.phase;
        let exponent = |k: usize| 0.5 * self.widths[k] * (s - self.centers[k]).powi(2);
        let smallest = (0..self.len()).map(exponent).fold(f64::INFINITY, f64::min);
        let mut sum = 0.0;
        for (k, gk) in g.iter_mut().enumerate().take(self.len()) {
            *gk = (smallest - exponent(k)).exp();
            sum += *gk;
        }
        // sum >= 1: the unit with the smallest exponent contributes exp(0) = 1.
        for gk in g.iter_mut().take(self.len()) {
            *gk /= sum;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn basis(count: usize) -> GaussianBasis {
        GaussianBasis::new(&BasisConfig {
            count,
            ..BasisConfig::default()
        })
        .unwrap()
    }

    #[test]
    fn centers_follow_the_phase_over_the_horizon() {
        let b = basis(10);
        assert_eq!(b.len(), 10);
        assert_eq!(b.centers()[0], 1.0);
        assert!((b.centers()[9] - (-5.0f64).exp()).abs() < 1e-15);
        assert!(b.centers().windows(2).all(|w| w[0] > w[1]));
        // Neighbours overlap at exp(-1) (h = 2 / Δc²).
        let (c0, c1, h0) = (b.centers()[0], b.centers()[1], b.widths()[0]);
        assert!(((-0.5 * h0 * (c1 - c0).powi(2)).exp() - (-1.0f64).exp()).abs() < 1e-12);
    }

    #[test]
    fn g_is_a_partition_of_unity_for_every_phase() {
        let mut b = basis(10);
        let mut g = vec![0.0; 10];
        for _ in 0..20_000 {
            b.evaluate(&mut g);
            let sum: f64 = g.iter().sum();
            assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
            assert!(g.iter().all(|x| (0.0..=1.0).contains(x)));
            b.advance(0.05); // through s = 0 (underflow) and beyond
        }
        assert!(b.phase() < 1e-300);
        b.evaluate(&mut g);
        assert!(g.iter().all(|x| x.is_finite()));
        // Far past the horizon g is constant, mostly the last unit (with geometric
        // centres and h = 2/Δc², every other unit is equally far from s = 0).
        assert!(g[9] > 0.8, "{g:?}");
        let mut late = b.clone();
        late.phase = 1e-6;
        let mut g_late = vec![0.0; 10];
        late.evaluate(&mut g_late);
        assert!(g.iter().zip(&g_late).all(|(a, b)| (a - b).abs() < 1e-3));
    }

    #[test]
    fn the_active_unit_follows_the_phase() {
        let mut b = basis(10);
        let mut g = vec![0.0; 10];
        b.evaluate(&mut g);
        assert_eq!(argmax(&g), 0);
        // At t = t_4 = 4 * 5/9 s the phase sits on the 5th centre.
        for _ in 0..2222 {
            b.advance(1e-3);
        }
        b.evaluate(&mut g);
        assert_eq!(argmax(&g), 4);
        b.reset();
        assert_eq!(b.phase(), 1.0);
    }

    #[test]
    fn single_unit_is_constant() {
        let mut b = basis(1);
        let mut g = [0.0];
        for _ in 0..10 {
            b.evaluate(&mut g);
            assert_eq!(g, [1.0]);
            b.advance(1.0);
        }
    }

    fn argmax(g: &[f64]) -> usize {
        let mut best = 0;
        for (k, x) in g.iter().enumerate() {
            if *x > g[best] {
                best = k;
            }
        }
        best
    }
}
