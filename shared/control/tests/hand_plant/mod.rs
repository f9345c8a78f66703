//! A simulated plant of `N` independent finger joints for the hand controller tests:
//! inertia `I`, viscous damping `b`, an optional stiff wall (penalty contact), and an
//! external load torque.
//!
//! ```text
//! I q̈ = τ + τ_load - b q̇ + τ_contact
//! τ_contact = -max(0, k_w (q - q_w) + b_w q̇)   for q > q_w   (the wall pushes back,
//!                                                                never pulls)
//! ```
//!
//! Integrated with semi-implicit Euler at `substeps` per control period, the
//! controller's effort held constant over the period (zero-order hold, like a real
//! effort command).

#![allow(dead_code)]

use nalgebra::SVector;

/// One finger joint of roughly the Shadow hand's scale: link plus reflected drive
/// inertia 1e-3 kg m², damping 0.02 N m s/rad. Our stand-in, not an identified model.
pub const INERTIA_KG_M2: f64 = 1e-3;
/// Viscous joint damping, N m s/rad.
pub const DAMPING_NM_S_RAD: f64 = 0.02;
/// Contact stiffness of the wall, N m/rad (a stiff object: 0.1 rad of penetration
/// would need 20 N m, ten times the joint's effort limit).
pub const WALL_STIFFNESS_NM_RAD: f64 = 200.0;
/// Contact damping of the wall, N m s/rad.
pub const WALL_DAMPING_NM_S_RAD: f64 = 0.5;

#[derive(Debug, Clone)]
pub struct Plant<const N: usize> {
    pub inertia_kg_m2: SVector<f64, N>,
    pub damping_nm_s_rad: SVector<f64, N>,
    /// Wall position per joint, rad; `inf` for free space.
    pub wall_rad: SVector<f64, N>,
    pub wall_stiffness_nm_rad: f64,
    pub wall_damping_nm_s_rad: f64,
    /// External load torque, N m.
    pub load_nm: SVector<f64, N>,
    pub position_rad: SVector<f64, N>,
    pub velocity_rad_s: SVector<f64, N>,
    pub substeps: usize,
    /// Largest and summed contact torque magnitude over the substeps of the last
    /// `step`, N m.
    pub last_peak_contact_nm: SVector<f64, N>,
    pub last_mean_contact_nm: SVector<f64, N>,
}

impl<const N: usize> Plant<N> {
    /// At rest at `q0`, free space, no load, the default constants.
    pub fn new(q0: SVector<f64, N>) -> Self {
        Self {
            inertia_kg_m2: SVector::repeat(INERTIA_KG_M2),
            damping_nm_s_rad: SVector::repeat(DAMPING_NM_S_RAD),
            wall_rad: SVector::repeat(f64::INFINITY),
            wall_stiffness_nm_rad: WALL_STIFFNESS_NM_RAD,
            wall_damping_nm_s_rad: WALL_DAMPING_NM_S_RAD,
            load_nm: SVector::zeros(),
            position_rad: q0,
            velocity_rad_s: SVector::zeros(),
            substeps: 10,
            last_peak_contact_nm: SVector::zeros(),
            last_mean_contact_nm: SVector::zeros(),
        }
    }

    /// Contact torque magnitude per joint at the current state, N m (>= 0).
    pub fn contact_nm(&self) -> SVector<f64, N> {
        SVector::from_fn(|i, _| {
            let pen = self.position_rad[i] - self.wall_rad[i];
            if pen > 0.0 {
                (self.wall_stiffness_nm_rad * pen
                    + self.wall_damping_nm_s_rad * self.velocity_rad_s[i])
                    .max(0.0)
            } else {
                0.0
            }
        })
    }

    /// Applies `effort_nm` for `dt_s`.
    pub fn step(&mut self, effort_nm: &SVector<f64, N>, dt_s: f64) {
        let h = dt_s / self.substeps as f64;
        self.last_peak_contact_nm = SVector::zeros();
        let mut sum = SVector::<f64, N>::zeros();
        for _ in 0..self.substeps {
            let contact = self.contact_nm();
            for i in 0..N {
                let torque = effort_nm[i] + self.load_nm[i]
                    - self.damping_nm_s_rad[i] * self.velocity_rad_s[i]
                    - contact[i];
                self.velocity_rad_s[i] += h * torque / self.inertia_kg_m2[i];
                self.position_rad[i] += h * self.velocity_rad_s[i];
            }
            let after = self.contact_nm();
            self.last_peak_contact_nm = self.last_peak_contact_nm.sup(&after);
            sum += after;
        }
        self.last_mean_contact_nm = sum / self.substeps as f64;
    }
}

/// Peak and mean of a sampled signal.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    pub peak: f64,
    pub sum: f64,
    pub count: usize,
}

impl Stats {
    pub fn add(&mut self, peak: f64, mean: f64) {
        self.peak = self.peak.max(peak);
        self.sum += mean;
        self.count += 1;
    }

    pub fn mean(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            self.sum / self.count as f64
        }
    }
}
