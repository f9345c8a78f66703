//! Biomimetic adaptive impedance + feedforward control of the Shadow hand (thesis
//! ch. 8.2.2, eqs. 8.1-8.17), per joint, generic over `N` joints.
//!
//! # The law as implemented
//!
//! Each joint is controlled independently ("each finger ... controlled independently
//! using an impedance-based force controller in the joint space"), so every matrix of
//! the thesis is diagonal and the law is evaluated joint by joint (`i` below):
//!
//! ```text
//! e = q - q_d,  ė = q̇ - q̇_d                                            (8.5)
//! ε = ė + ζ e                                          sliding error, (8.9) text
//! τ_c = τ0 - u - v                                                       (8.1)
//! τ0  = G - Γ ε                                                          (8.2)*
//! u   = K_s e + K_d ė                                                    (8.3)
//! K_s,i = θ_k,iᵀ g,  K_d,i = θ_d,iᵀ g,  v_i = θ_v,iᵀ g                 (8.6)
//! g = normalized Gaussians of the phase s, ṡ = -s                   (8.7, 8.8)
//! θ̇_k,i = Θ_k,i ε_i e_i g                                               (8.15)
//! θ̇_d,i = Θ_d,i ε_i ė_i g                                               (8.16)
//! θ̇_v,i = Θ_v,i ε_i g                                                   (8.17)
//! τ_c ← clamp(τ_c, -τ_max, τ_max)                                      (ours)
//! ```
//!
//! Signs are those printed, and they are the stabilizing ones: with `e = q - q_d`,
//! `-K_s e` pulls the joint back to the target; a persistent error of one sign makes
//! `ε` of that sign, so (8.17) grows `v` with it and `-v` pushes against the error
//! (integral-like action: a static load is learned and cancelled); (8.15) grows
//! `K_s` at rate `Θ_k (ė e + ζ e²)`, i.e. whenever the error persists, and (8.16)
//! grows `K_d` at `Θ_d (ė² + ζ e ė)`.
//!
//! \* `τ0` of (8.2) is `M q̈_e + C q̇_e + G - Γ ε` with `q̇_e = q̇_d - ζ e`. We keep
//! `G` (an input, [`JointInput::gravity_nm`]) and `-Γ ε`, and drop `M q̈_e + C q̇_e`:
//! there is no identified dynamics model of the tendon-driven fingers, each joint's
//! inertia (~1e-5..1e-3 kg m²) makes `M ζ ė` negligible next to `K_d ė`, and `C` is
//! zero for the decoupled per-joint model the thesis uses.
//!
//! # Discretization and what is ours
//!
//! Per period `dt` (capped at `max_dt_s`), in the order of Table 8.1 ("calculate the
//! sliding error; update parameters; generate the force commands"):
//!
//! 1. `e`, `ė`, `ε` from the input (errors saturated, see
//!    [`ERROR_LIMIT_RAD`](super::input::ERROR_LIMIT_RAD));
//! 2. `g` at the current phase `s`;
//! 3. every weight `n` of joint `i`: forward Euler of (8.15)-(8.17),
//!    `θ_n ← θ_n + dt · Θ ε_i (e_i | ė_i | 1) g_n`, preceded (our addition, default
//!    `α = 1/s`; `α = 0` skips it, the law as printed) by forgetting toward the initial weight `θ⁰`,
//!    `θ_n ← θ⁰ + (θ_n - θ⁰) exp(-γ dt)` with `γ = α / (1 + β ε_i²)`; then
//!    **projection** of every weight onto `[K_s,min, K_s,max]`, `[K_d,min, K_d,max]`,
//!    `[-v_max, v_max]` (our safety addition: since `g` is a partition of unity,
//!    `K_s`, `K_d`, `v` stay within the same bounds, and the weights do not wind up
//!    beyond them);
//! 4. `K_s`, `K_d`, `v` from (8.6) with the updated weights, `τ_c` from (8.1), clamped
//!    to `±max_effort_nm`;
//! 5. `s ← s exp(-dt / τ_s)` (exact solution of `τ_s ṡ = -s`).
//!
//! The weights start equal across the basis (`θ⁰ = K_s,0`, `K_d,0`, `v_0`), so the
//! initial profiles do not depend on `s`. The phase restarts at `s = 1` on
//! [`reset`](AdaptiveImpedance::reset) (mode change, clutch); the profiles are indexed
//! by the time since then, and after the basis horizon (default 5 s) only the last
//! units are active, i.e. the controller continues as one adaptive impedance.
//!
//! # Behaviour to know about
//!
//! * **Ratchet.** As printed (`forgetting_rate_per_s = 0`), `∫ ε e dt = e²/2 + ζ ∫ e² dt` only
//!   grows, and so does `K_d` with `∫ ė² dt`: stiffness and damping ratchet up with
//!   every persistent error and every motion, up to their bounds, until a reset. And
//!   `v` integrates any persistent error: pressing into a surface (target behind it)
//!   for long lets the contact torque creep up to `K_s e + v_max`, within
//!   `max_effort_nm` (`tests/hand_adaptive.rs`: 0.67 N m mean over the first second,
//!   2.0 N m, the limit, after 20 s). A nonzero `forgetting_rate_per_s` bounds this
//!   (equilibrium `v ≈ Θ_v ζ e Σg² / γ`): 0.79 N m after 20 s with `α = 2/s`.
//! * **Time-indexed profiles.** Each weight learns in proportion to `g_n`, so a
//!   profile moves at `rate · Σ g_n²` (0.3-1), and while the phase sweeps the basis
//!   (the first `horizon_s` after a reset) what units learned fades as `g` moves to
//!   fresh units. In the first seconds this acts like forgetting: it keeps the
//!   contact forces low (the thesis' compliance claim) but also slows the learning
//!   of a static load. After the horizon `g` is constant and `v` integrates at full
//!   rate.
//!
//! Both make the compliance of this controller a matter of time scales: low initial
//! impedance for a new contact, slow growth against a persistent error. Measured on
//! the simulated finger (1 kHz, defaults): touching a stiff surface 0.1 rad behind it
//! for 1.5 s gives peak/mean contact 0.69/0.48 N m against 0.96/0.92 (fixed-gain
//! impedance) and 1.83/1.76 (position servo).

use nalgebra::SVector;

use crate::error::{ConfigError, Rejection};
use crate::hand::basis::GaussianBasis;
use crate::hand::config::{AdaptiveConfig, MAX_CONFIG_VALUE, check_vector};
use crate::hand::input::{JointInput, check_dt, clamp_effort};

/// `K_s`, `K_d`, `v` and `ε` of every joint at the last step, for logging.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompliantProfiles<const N: usize> {
    /// Stiffness `K_s` per joint, N m/rad.
    pub stiffness_nm_rad: SVector<f64, N>,
    /// Damping `K_d` per joint, N m s/rad.
    pub damping_nm_s_rad: SVector<f64, N>,
    /// Feedforward `v` per joint, N m (the effort contains `-v`).
    pub feedforward_nm: SVector<f64, N>,
    /// Sliding error `ε = ė + ζ e` per joint, rad/s.
    pub sliding_error_rad_s: SVector<f64, N>,
    /// Phase `s` the profiles were evaluated at.
    pub phase: f64,
}

/// Per-joint constants, resolved from the configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Gains<const N: usize> {
    k0: SVector<f64, N>,
    d0: SVector<f64, N>,
    v0: SVector<f64, N>,
    k_min: SVector<f64, N>,
    k_max: SVector<f64, N>,
    d_min: SVector<f64, N>,
    d_max: SVector<f64, N>,
    v_max: SVector<f64, N>,
    theta_k: SVector<f64, N>,
    theta_d: SVector<f64, N>,
    theta_v: SVector<f64, N>,
    zeta: SVector<f64, N>,
    gamma: SVector<f64, N>,
    alpha: SVector<f64, N>,
    beta: SVector<f64, N>,
}

/// The adaptive impedance + feedforward controller; see the [module docs](self).
/// Allocates in [`new`](Self::new) only.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveImpedance<const N: usize> {
    gains: Gains<N>,
    max_effort_nm: SVector<f64, N>,
    max_dt_s: f64,
    basis: GaussianBasis,
    /// `g` at the last evaluation.
    g: Vec<f64>,
    /// Weights, one vector (over joints) per Gaussian: `weights_k[n][i] = θ_k,i,n`.
    weights_k: Vec<SVector<f64, N>>,
    weights_d: Vec<SVector<f64, N>>,
    weights_v: Vec<SVector<f64, N>>,
    profiles: CompliantProfiles<N>,
}

impl<const N: usize> AdaptiveImpedance<N> {
    /// A controller with the initial profiles of `config`, phase 1, effort limits
    /// `max_effort_nm` (N m) and adaptation step cap `max_dt_s` (s).
    ///
    /// # Errors
    ///
    /// [`AdaptiveConfig::validate`]'s error; [`ConfigError::OutOfRange`] for an effort
    /// limit that is not finite and positive; [`ConfigError::NotPositive`] for
    /// `max_dt_s`.
    pub fn new(
        config: &AdaptiveConfig<N>,
        max_effort_nm: SVector<f64, N>,
        max_dt_s: f64,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        check_vector(
            "max_effort_nm",
            &max_effort_nm,
            f64::MIN_POSITIVE,
            MAX_CONFIG_VALUE,
        )?;
        crate::error::positive("max_dt_s", max_dt_s)?;
        let gains = Gains {
            k0: config.initial_stiffness_nm_rad.to_vector(),
            d0: config.initial_damping_nm_s_rad.to_vector(),
            v0: config.initial_feedforward_nm.to_vector(),
            k_min: config.min_stiffness_nm_rad.to_vector(),
            k_max: config.max_stiffness_nm_rad.to_vector(),
            d_min: config.min_damping_nm_s_rad.to_vector(),
            d_max: config.max_damping_nm_s_rad.to_vector(),
            v_max: config.max_feedforward_nm.to_vector(),
            theta_k: config.stiffness_adaptation.to_vector(),
            theta_d: config.damping_adaptation.to_vector(),
            theta_v: config.feedforward_adaptation.to_vector(),
            zeta: config.sliding_gain_per_s.to_vector(),
            gamma: config.sliding_feedback_nm_s_rad.to_vector(),
            alpha: config.forgetting_rate_per_s.to_vector(),
            beta: config.forgetting_error_scale_s2_rad2.to_vector(),
        };
        let basis = GaussianBasis::new(&config.basis)?;
        let count = basis.len();
        let mut controller = Self {
            gains,
            max_effort_nm,
            max_dt_s,
            basis,
            g: vec![0.0; count],
            weights_k: vec![gains.k0; count],
            weights_d: vec![gains.d0; count],
            weights_v: vec![gains.v0; count],
            profiles: CompliantProfiles {
                stiffness_nm_rad: gains.k0,
                damping_nm_s_rad: gains.d0,
                feedforward_nm: gains.v0,
                sliding_error_rad_s: SVector::zeros(),
                phase: 1.0,
            },
        };
        controller.reset();
        Ok(controller)
    }

    /// Back to the initial profiles (every weight `θ⁰`) and phase `s = 1`.
    pub fn reset(&mut self) {
        let g = &self.gains;
        self.weights_k.iter_mut().for_each(|w| *w = g.k0);
        self.weights_d.iter_mut().for_each(|w| *w = g.d0);
        self.weights_v.iter_mut().for_each(|w| *w = g.v0);
        self.basis.reset();
        self.basis.evaluate(&mut self.g);
        self.profiles = CompliantProfiles {
            stiffness_nm_rad: g.k0,
            damping_nm_s_rad: g.d0,
            feedforward_nm: g.v0,
            sliding_error_rad_s: SVector::zeros(),
            phase: 1.0,
        };
    }

    /// One control period: adapts the profiles (eqs. 8.15-8.17), returns the effort
    /// `τ_c` (eq. 8.1) clamped to the effort limits, N m, and advances the phase.
    ///
    /// # Errors
    ///
    /// [`Rejection::InvalidTimeStep`] (`dt_s` NaN, infinite or `<= 0`) and
    /// [`Rejection::NonFinite`]; the state is then unchanged.
    pub fn step(&mut self, dt_s: f64, input: &JointInput<N>) -> Result<SVector<f64, N>, Rejection> {
        check_dt(dt_s)?;
        input.check()?;
        let limit = self.max_effort_nm;
        Ok(self.step_checked(dt_s, input, &limit))
    }

    /// [`step`](Self::step) for an input and `dt_s` already checked, with effort
    /// limits `limit_nm`.
    pub(crate) fn step_checked(
        &mut self,
        dt_s: f64,
        input: &JointInput<N>,
        limit_nm: &SVector<f64, N>,
    ) -> SVector<f64, N> {
        let h = dt_s.min(self.max_dt_s);
        let (e, de) = input.errors();
        let c = &self.gains;
        let eps = de + c.zeta.component_mul(&e);
        self.basis.evaluate(&mut self.g);

        for i in 0..N {
            // Rates of eqs. 8.15-8.17 without the factor g_n.
            let rate_k = c.theta_k[i] * eps[i] * e[i];
            let rate_d = c.theta_d[i] * eps[i] * de[i];
            let rate_v = c.theta_v[i] * eps[i];
            // Forgetting (ours; on by default, fading with the sliding error): exact decay toward θ⁰ over h,
            // skipped entirely at α = 0 so the printed law is computed exactly.
            let gamma = c.alpha[i] / (1.0 + c.beta[i] * eps[i] * eps[i]);
            let forget = |w: f64, w0: f64| {
                if gamma > 0.0 {
                    w0 + (w - w0) * (-gamma * h).exp()
                } else {
                    w
                }
            };
            for (n, &gn) in self.g.iter().enumerate() {
                let k = &mut self.weights_k[n][i];
                *k = project(
                    forget(*k, c.k0[i]) + h * rate_k * gn,
                    c.k_min[i],
                    c.k_max[i],
                    *k,
                );
                let d = &mut self.weights_d[n][i];
                *d = project(
                    forget(*d, c.d0[i]) + h * rate_d * gn,
                    c.d_min[i],
                    c.d_max[i],
                    *d,
                );
                let v = &mut self.weights_v[n][i];
                *v = project(
                    forget(*v, c.v0[i]) + h * rate_v * gn,
                    -c.v_max[i],
                    c.v_max[i],
                    *v,
                );
            }
        }

        let tau = self.effort_from_weights(input, &e, &de, &eps, limit_nm);
        self.basis.advance(h);
        tau
    }

    /// The law of the current profiles as a joint impedance about the target,
    /// `τ = G + f + K (q_d - q) + D (q̇_d - q̇)`: returns `(K, D, f)` with
    /// `K = K_s + Γ ζ`, `D = K_d + Γ`, `f = -v` (eqs. 8.1-8.3 regrouped; without the
    /// error saturation of the effort form).
    pub fn impedance(&self) -> (SVector<f64, N>, SVector<f64, N>, SVector<f64, N>) {
        let c = &self.gains;
        let p = &self.profiles;
        (
            p.stiffness_nm_rad + c.gamma.component_mul(&c.zeta),
            p.damping_nm_s_rad + c.gamma,
            -p.feedforward_nm,
        )
    }

    /// The effort of the current profiles without adapting them or advancing the
    /// phase, clamped to `±limit_nm` (the hold behaviour: a stale target must not
    /// train the profiles). Updates [`profiles`](Self::profiles). The input must be
    /// checked.
    pub(crate) fn effort_frozen(
        &mut self,
        input: &JointInput<N>,
        limit_nm: &SVector<f64, N>,
    ) -> SVector<f64, N> {
        let (e, de) = input.errors();
        let eps = de + self.gains.zeta.component_mul(&e);
        self.basis.evaluate(&mut self.g);
        self.effort_from_weights(input, &e, &de, &eps, limit_nm)
    }

    /// Eq. 8.6 then 8.1-8.3 with `g` already evaluated; records the profiles.
    fn effort_from_weights(
        &mut self,
        input: &JointInput<N>,
        e: &SVector<f64, N>,
        de: &SVector<f64, N>,
        eps: &SVector<f64, N>,
        limit_nm: &SVector<f64, N>,
    ) -> SVector<f64, N> {
        let mut ks = SVector::<f64, N>::zeros();
        let mut kd = SVector::<f64, N>::zeros();
        let mut v = SVector::<f64, N>::zeros();
        for (n, &gn) in self.g.iter().enumerate() {
            ks.axpy(gn, &self.weights_k[n], 1.0);
            kd.axpy(gn, &self.weights_d[n], 1.0);
            v.axpy(gn, &self.weights_v[n], 1.0);
        }
        // A convex combination of bounded weights is within the bounds; the clamp
        // only removes the rounding of the sum.
        let c = &self.gains;
        let ks: SVector<f64, N> = SVector::from_fn(|i, _| ks[i].clamp(c.k_min[i], c.k_max[i]));
        let kd: SVector<f64, N> = SVector::from_fn(|i, _| kd[i].clamp(c.d_min[i], c.d_max[i]));
        let v: SVector<f64, N> = SVector::from_fn(|i, _| v[i].clamp(-c.v_max[i], c.v_max[i]));
        // τ0 = G - Γ ε (8.2, without M, C); u = K_s e + K_d ė (8.3); τ = τ0 - u - v (8.1).
        let tau0 = input.gravity_nm - c.gamma.component_mul(eps);
        let u = ks.component_mul(e) + kd.component_mul(de);
        let tau = tau0 - u - v;
        self.profiles = CompliantProfiles {
            stiffness_nm_rad: ks,
            damping_nm_s_rad: kd,
            feedforward_nm: v,
            sliding_error_rad_s: *eps,
            phase: self.basis.phase(),
        };
        clamp_effort(&tau, limit_nm)
    }

    /// `K_s`, `K_d`, `v`, `ε` at the last step (initial profiles after a reset).
    pub fn profiles(&self) -> &CompliantProfiles<N> {
        &self.profiles
    }

    /// Current phase `s`.
    pub fn phase(&self) -> f64 {
        self.basis.phase()
    }

    /// The basis (centres, widths, phase).
    pub fn basis(&self) -> &GaussianBasis {
        &self.basis
    }

    /// Stiffness weights `θ_k`, one vector over the joints per Gaussian, N m/rad.
    pub fn stiffness_weights(&self) -> &[SVector<f64, N>] {
        &self.weights_k
    }

    /// Feedforward weights `θ_v`, one vector over the joints per Gaussian, N m.
    pub fn feedforward_weights(&self) -> &[SVector<f64, N>] {
        &self.weights_v
    }

    /// Effort limits, N m.
    pub fn max_effort_nm(&self) -> &SVector<f64, N> {
        &self.max_effort_nm
    }
}

/// `x` clamped to `[lo, hi]`; `old` if `x` is NaN (cannot happen with a validated
/// configuration and saturated errors, kept so a weight can never become NaN).
fn project(x: f64, lo: f64, hi: f64, old: f64) -> f64 {
    if x.is_nan() { old } else { x.clamp(lo, hi) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hand::config::{BasisConfig, PerJoint};
    use nalgebra::{Vector1, Vector2};

    fn controller(config: &AdaptiveConfig<1>) -> AdaptiveImpedance<1> {
        AdaptiveImpedance::new(config, Vector1::new(2.0), 0.1).unwrap()
    }

    fn at(q: f64, dq: f64, target: f64) -> JointInput<1> {
        JointInput::new(Vector1::new(q), Vector1::new(dq), Vector1::new(target))
    }

    #[test]
    fn first_step_matches_the_equations() {
        let config = AdaptiveConfig::<1>::default();
        let mut c = controller(&config);
        let dt = 1e-3;
        // e = 0.1, ė = 0.2, ζ = 10: ε = 1.2.
        let tau = c.step(dt, &at(0.1, 0.2, 0.0)).unwrap()[0];
        let eps = 0.2 + 10.0 * 0.1;
        // Every weight n moves by dt · rate · g_n (8.15-8.17), so a profile θᵀg moves
        // by dt · rate · Σ g_n², g at s = 1.
        let mut g = vec![0.0; 10];
        GaussianBasis::new(&BasisConfig::default())
            .unwrap()
            .evaluate(&mut g);
        let g2: f64 = g.iter().map(|x| x * x).sum();
        assert!(g2 > 0.3 && g2 < 1.0);
        let ks = 1.0 + dt * 10.0 * eps * 0.1 * g2;
        let kd = 0.05 + dt * 0.05 * eps * 0.2 * g2;
        let v = dt * 2.0 * eps * g2;
        let expected = -0.02 * eps - (ks * 0.1 + kd * 0.2) - v;
        let p = c.profiles();
        assert!((p.stiffness_nm_rad[0] - ks).abs() < 1e-12);
        assert!((p.damping_nm_s_rad[0] - kd).abs() < 1e-12);
        assert!((p.feedforward_nm[0] - v).abs() < 1e-12);
        assert!((p.sliding_error_rad_s[0] - eps).abs() < 1e-12);
        assert!((tau - expected).abs() < 1e-12, "{tau} vs {expected}");
        assert!((c.phase() - (-dt).exp()).abs() < 1e-15);
    }

    #[test]
    fn persistent_error_raises_stiffness_and_feedforward_against_it() {
        let mut c = controller(&AdaptiveConfig::default());
        for _ in 0..1000 {
            c.step(1e-3, &at(0.05, 0.0, 0.0)).unwrap();
        }
        let p = *c.profiles();
        assert!(p.stiffness_nm_rad[0] > 1.0);
        assert!(p.feedforward_nm[0] > 0.0); // the effort has -v: pushes q down
        // Negative error: v of the other sign.
        c.reset();
        for _ in 0..1000 {
            c.step(1e-3, &at(-0.05, 0.0, 0.0)).unwrap();
        }
        assert!(c.profiles().feedforward_nm[0] < 0.0);
    }

    #[test]
    fn profiles_stay_within_bounds() {
        let config = AdaptiveConfig::<1> {
            stiffness_adaptation: PerJoint::Uniform(1e6),
            damping_adaptation: PerJoint::Uniform(1e6),
            feedforward_adaptation: PerJoint::Uniform(1e6),
            ..Default::default()
        };
        let mut c = controller(&config);
        for k in 0..2000 {
            let s = if k % 300 < 150 { 1.0 } else { -1.0 };
            let tau = c.step(1e-3, &at(0.5 * s, 3.0 * s, 0.0)).unwrap()[0];
            assert!(tau.abs() <= 2.0);
            let p = c.profiles();
            assert!((0.2..=20.0).contains(&p.stiffness_nm_rad[0]));
            assert!((0.02..=0.3).contains(&p.damping_nm_s_rad[0]));
            assert!(p.feedforward_nm[0].abs() <= 2.0);
        }
        assert_eq!(c.profiles().stiffness_nm_rad[0], 20.0);
    }

    #[test]
    fn forgetting_returns_to_the_initial_profiles() {
        let config = AdaptiveConfig::<1> {
            forgetting_rate_per_s: PerJoint::Uniform(2.0),
            basis: BasisConfig {
                count: 1,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut c = controller(&config);
        for _ in 0..1000 {
            c.step(1e-3, &at(0.1, 0.0, 0.0)).unwrap();
        }
        let raised = *c.profiles();
        assert!(raised.feedforward_nm[0] > 0.05);
        for _ in 0..5000 {
            c.step(1e-3, &at(0.0, 0.0, 0.0)).unwrap();
        }
        let p = c.profiles();
        assert!((p.stiffness_nm_rad[0] - 1.0).abs() < 1e-3 * raised.stiffness_nm_rad[0]);
        assert!(p.feedforward_nm[0].abs() < 1e-3 * raised.feedforward_nm[0]);
    }

    #[test]
    fn rejected_input_changes_nothing() {
        let mut c = controller(&AdaptiveConfig::default());
        c.step(1e-3, &at(0.1, 0.0, 0.0)).unwrap();
        let before = c.clone();
        assert!(c.step(1e-3, &at(f64::NAN, 0.0, 0.0)).is_err());
        assert!(c.step(-1e-3, &at(0.1, 0.0, 0.0)).is_err());
        assert!(c.step(f64::NAN, &at(0.1, 0.0, 0.0)).is_err());
        assert_eq!(c, before);
    }

    #[test]
    fn joints_are_independent() {
        let mut two =
            AdaptiveImpedance::<2>::new(&AdaptiveConfig::default(), Vector2::repeat(2.0), 0.1)
                .unwrap();
        let mut one = controller(&AdaptiveConfig::default());
        for k in 0..500 {
            let q = 0.1 * (k as f64 * 0.01).sin();
            let t2 = two
                .step(
                    1e-3,
                    &JointInput::new(
                        Vector2::new(q, -0.3),
                        Vector2::new(0.0, 1.0),
                        Vector2::new(0.0, 0.2),
                    ),
                )
                .unwrap();
            let t1 = one.step(1e-3, &at(q, 0.0, 0.0)).unwrap();
            assert_eq!(t2[0], t1[0]);
        }
    }

    #[test]
    fn invalid_bounds_are_refused() {
        let config = AdaptiveConfig::<1> {
            initial_stiffness_nm_rad: PerJoint::Uniform(30.0),
            ..Default::default()
        };
        assert!(AdaptiveImpedance::new(&config, Vector1::new(2.0), 0.1).is_err());
        let config = AdaptiveConfig::<1> {
            sliding_gain_per_s: PerJoint::Uniform(f64::NAN),
            ..Default::default()
        };
        assert!(AdaptiveImpedance::new(&config, Vector1::new(2.0), 0.1).is_err());
    }
}
