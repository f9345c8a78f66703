//! Typed settings of the simulated world. Every struct is a serde struct with
//! `deny_unknown_fields` and defaults; units are in the field names. Numbers marked
//! "ours" are engineering choices of this simulator, not measured on the real robots.

use serde::{Deserialize, Serialize};

use super::error::SimError;

/// Settings of the whole world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WorldConfig {
    /// Fixed step of the world, seconds. Default 0.001 (the real hand's 1 kHz loop).
    pub dt_s: f64,
    /// Seed of the measurement-noise generator (ChaCha8): the same seed and inputs give
    /// bit-identical runs.
    pub seed: u64,
    /// Gravity in the PR2 `base_link` frame (z up), m/s^2.
    pub gravity_m_s2: [f64; 3],
    /// The PR2 arm.
    pub arm: ArmSimConfig,
    /// The Shadow hand.
    pub hand: HandSimConfig,
    /// Finger–object contacts.
    pub contact: ContactConfig,
    /// Measurement noise added to what `read` returns (ground truth stays exact).
    pub noise: NoiseConfig,
    /// How far the simulated robot's physical parameters lie from the nominal model
    /// the controllers use.
    pub perturbation: PerturbationConfig,
}

impl Default for WorldConfig {
    fn default() -> Self {
        Self {
            dt_s: 0.001,
            seed: 0,
            gravity_m_s2: [0.0, 0.0, -9.81],
            arm: ArmSimConfig::default(),
            hand: HandSimConfig::default(),
            contact: ContactConfig::default(),
            noise: NoiseConfig::default(),
            perturbation: PerturbationConfig::default(),
        }
    }
}

impl WorldConfig {
    /// The nominal robot: no perturbation, no noise (for tests of the physics against
    /// the model itself).
    pub fn nominal() -> Self {
        Self {
            noise: NoiseConfig::none(),
            perturbation: PerturbationConfig::none(),
            ..Self::default()
        }
    }
}

/// The simulated robot is not the model: each physical parameter below is multiplied
/// by a factor drawn uniformly from `[1 - f, 1 + f]` (one draw per link or joint,
/// ChaCha8 seeded with `seed`), while the controllers keep the nominal model. So every
/// figure measured on the simulator carries a model error, as a real robot's would.
/// `World::perturbation` reports the factors drawn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerturbationConfig {
    /// Seed of the draw (independent of the noise seed).
    pub seed: u64,
    /// Mass (and inertia) of every link moved by a finger joint. Default 0.15.
    pub mass_fraction: f64,
    /// Viscous damping of every finger joint. Default 0.3.
    pub damping_fraction: f64,
    /// Actuator armature of every finger joint. Default 0.3.
    pub armature_fraction: f64,
    /// Torque a finger motor delivers per N m commanded (motor constant, tendon
    /// losses). Default 0.1.
    pub motor_gain_fraction: f64,
    /// Contact friction coefficient. Default 0.2.
    pub friction_fraction: f64,
    /// Velocity lag (time constant) of every arm joint. Default 0.3.
    pub arm_lag_fraction: f64,
}

impl Default for PerturbationConfig {
    fn default() -> Self {
        Self {
            seed: 2021,
            mass_fraction: 0.15,
            damping_fraction: 0.3,
            armature_fraction: 0.3,
            motor_gain_fraction: 0.1,
            friction_fraction: 0.2,
            arm_lag_fraction: 0.3,
        }
    }
}

impl PerturbationConfig {
    /// Every factor 1: the simulated robot is the nominal model.
    pub fn none() -> Self {
        Self {
            seed: 0,
            mass_fraction: 0.0,
            damping_fraction: 0.0,
            armature_fraction: 0.0,
            motor_gain_fraction: 0.0,
            friction_fraction: 0.0,
            arm_lag_fraction: 0.0,
        }
    }

    /// Checks that every fraction lies in [0, 0.9) (both worlds call it: a factor
    /// 1 ± 0.9 or more could make a mass or gain vanish or flip).
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] naming the first bad field (`perturbation.<field>`).
    pub fn validate(&self) -> Result<(), SimError> {
        for (field, v) in [
            ("perturbation.mass_fraction", self.mass_fraction),
            ("perturbation.damping_fraction", self.damping_fraction),
            ("perturbation.armature_fraction", self.armature_fraction),
            ("perturbation.motor_gain_fraction", self.motor_gain_fraction),
            ("perturbation.friction_fraction", self.friction_fraction),
            ("perturbation.arm_lag_fraction", self.arm_lag_fraction),
        ] {
            check(field, v, (0.0..0.9).contains(&v), "must be in [0, 0.9)")?;
        }
        Ok(())
    }
}

/// The velocity-commanded PR2 arm (+ Shadow wrist), joints in
/// [`PR2_ARM_JOINTS`](teleop_interfaces::joints::PR2_ARM_JOINTS) order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmSimConfig {
    /// Time constant of the first-order lag from commanded to actual joint velocity,
    /// seconds. Default 0.03 (ours: the PR2 joint velocity loops settle in a few tens of
    /// ms).
    pub velocity_lag_s: f64,
    /// Largest joint acceleration, rad/s^2, per joint. Default 8 for every joint
    /// (ours; `pr2_description` gives none). Also the braking deceleration on timeout.
    pub acceleration_limit_rad_s2: [f64; 7],
    /// Scale on the URDF velocity limits (the PR2 URDF already carries its 0.6 safety
    /// scale). Default 1.
    pub velocity_limit_scale: f64,
    /// With no command for longer than this, the simulated driver brakes the arm to
    /// zero velocity, seconds. Default 0.1.
    pub command_timeout_s: f64,
    /// Initial joint positions, rad. Default all zero: arm straight forward, palm
    /// down.
    pub initial_position_rad: [f64; 7],
}

impl Default for ArmSimConfig {
    fn default() -> Self {
        Self {
            velocity_lag_s: 0.03,
            acceleration_limit_rad_s2: [8.0; 7],
            velocity_limit_scale: 1.0,
            command_timeout_s: 0.1,
            initial_position_rad: [0.0; 7],
        }
    }
}

/// The torque-driven Shadow hand, joints in [`SHADOW_FINGER_JOINTS`](teleop_interfaces::joints::SHADOW_FINGER_JOINTS) order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HandSimConfig {
    /// Viscous joint damping, N m s/rad. Default 0.05 (the MuJoCo Menagerie Shadow hand
    /// model's value; ours within 0.01-0.05).
    pub damping_nm_s_rad: f64,
    /// Reflected actuator (motor + gearbox + tendon) inertia added to every joint's
    /// link inertia, kg m^2. Default 2e-4 (MuJoCo Menagerie's `armature`); 0 gives the
    /// bare link inertia.
    pub armature_kg_m2: f64,
    /// Largest joint torque of the motors, N m (effort commands and the position servo
    /// are clamped to it). Default 2.0: the finger joints' `effort` limit in our Shadow
    /// hand URDF, the same limit the hand controller clamps to in every mode (MuJoCo
    /// Menagerie's model uses 1.0).
    pub max_effort_nm: f64,
    /// Proportional gain of the position servo, N m/rad. Default 2.0 (ours).
    pub servo_kp_nm_rad: f64,
    /// Derivative gain of the position servo, N m s/rad. Default 0.01 (ours).
    pub servo_kd_nm_s_rad: f64,
    /// Stiffness of the joint-limit penalty springs, N m/rad. Default 50 (ours: a
    /// 1 N m push overshoots a limit by ~1 deg).
    pub limit_stiffness_nm_rad: f64,
    /// Damping of the joint-limit springs while beyond a limit, N m s/rad. Default 0.1.
    pub limit_damping_nm_s_rad: f64,
    /// Integration substeps per world step. Default 2 (0.5 ms at dt = 1 ms).
    pub substeps: u32,
    /// Initial finger joint positions, rad (clamped into the joint limits).
    /// Default all zero: fingers straight.
    pub initial_position_rad: [f64; 17],
}

impl Default for HandSimConfig {
    fn default() -> Self {
        Self {
            damping_nm_s_rad: 0.05,
            armature_kg_m2: 2e-4,
            max_effort_nm: 2.0,
            servo_kp_nm_rad: 2.0,
            servo_kd_nm_s_rad: 0.01,
            limit_stiffness_nm_rad: 50.0,
            limit_damping_nm_s_rad: 0.1,
            substeps: 2,
            initial_position_rad: [0.0; 17],
        }
    }
}

/// Penalty contacts between finger links and objects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ContactConfig {
    /// Normal stiffness, N/m. Default 3000 (a BioTac's skin and fluid are compliant:
    /// ~1 mm under 3 N).
    pub stiffness_n_m: f64,
    /// Normal damping while penetrating, N s/m. Default 5 (ours; the normal force
    /// never pulls).
    pub damping_n_s_m: f64,
    /// Coulomb friction coefficient; 0 disables friction. Default 0.8 (silicone skin).
    pub friction_coefficient: f64,
    /// Tangential viscous gain below the Coulomb limit (regularised friction), N s/m.
    /// Default 20.
    pub friction_damping_n_s_m: f64,
}

impl Default for ContactConfig {
    fn default() -> Self {
        Self {
            stiffness_n_m: 3000.0,
            damping_n_s_m: 5.0,
            friction_coefficient: 0.8,
            friction_damping_n_s_m: 20.0,
        }
    }
}

/// Gaussian measurement noise (standard deviations). Defaults: small sensor noise
/// (ours: joint encoders 1e-4 rad, velocities 2e-3 rad/s, BioTac forces 0.02 N).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    /// On measured joint positions (arm and hand), rad.
    pub joint_position_std_rad: f64,
    /// On measured joint velocities (arm and hand), rad/s.
    pub joint_velocity_std_rad_s: f64,
    /// On fingertip forces, N (readings are clamped at 0).
    pub fingertip_force_std_n: f64,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        Self {
            joint_position_std_rad: 1e-4,
            joint_velocity_std_rad_s: 2e-3,
            fingertip_force_std_n: 0.02,
        }
    }
}

impl NoiseConfig {
    /// No noise: readings are the ground truth.
    pub fn none() -> Self {
        Self {
            joint_position_std_rad: 0.0,
            joint_velocity_std_rad_s: 0.0,
            fingertip_force_std_n: 0.0,
        }
    }

    /// Checks that every standard deviation is finite and >= 0 (both worlds call it).
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] naming the first bad field (`noise.<field>`).
    pub fn validate(&self) -> Result<(), SimError> {
        for (field, v) in [
            ("noise.joint_position_std_rad", self.joint_position_std_rad),
            (
                "noise.joint_velocity_std_rad_s",
                self.joint_velocity_std_rad_s,
            ),
            ("noise.fingertip_force_std_n", self.fingertip_force_std_n),
        ] {
            check(field, v, v >= 0.0, "must be >= 0")?;
        }
        Ok(())
    }
}

fn check(field: &'static str, value: f64, ok: bool, reason: &'static str) -> Result<(), SimError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(SimError::InvalidConfig {
            field,
            value,
            reason,
        })
    }
}

impl WorldConfig {
    /// Checks every number for sign and finiteness.
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<(), SimError> {
        check("dt_s", self.dt_s, self.dt_s > 0.0, "must be > 0")?;
        for g in self.gravity_m_s2 {
            check("gravity_m_s2", g, true, "must be finite")?;
        }
        let a = &self.arm;
        check(
            "arm.velocity_lag_s",
            a.velocity_lag_s,
            a.velocity_lag_s >= 0.0,
            "must be >= 0",
        )?;
        for v in a.acceleration_limit_rad_s2 {
            check("arm.acceleration_limit_rad_s2", v, v > 0.0, "must be > 0")?;
        }
        check(
            "arm.velocity_limit_scale",
            a.velocity_limit_scale,
            a.velocity_limit_scale > 0.0,
            "must be > 0",
        )?;
        check(
            "arm.command_timeout_s",
            a.command_timeout_s,
            a.command_timeout_s > 0.0,
            "must be > 0",
        )?;
        for v in a.initial_position_rad {
            check("arm.initial_position_rad", v, true, "must be finite")?;
        }
        let h = &self.hand;
        let non_negative = [
            ("hand.damping_nm_s_rad", h.damping_nm_s_rad),
            ("hand.armature_kg_m2", h.armature_kg_m2),
            ("hand.max_effort_nm", h.max_effort_nm),
            ("hand.servo_kp_nm_rad", h.servo_kp_nm_rad),
            ("hand.servo_kd_nm_s_rad", h.servo_kd_nm_s_rad),
            ("hand.limit_stiffness_nm_rad", h.limit_stiffness_nm_rad),
            ("hand.limit_damping_nm_s_rad", h.limit_damping_nm_s_rad),
            ("contact.stiffness_n_m", self.contact.stiffness_n_m),
            ("contact.damping_n_s_m", self.contact.damping_n_s_m),
            (
                "contact.friction_coefficient",
                self.contact.friction_coefficient,
            ),
            (
                "contact.friction_damping_n_s_m",
                self.contact.friction_damping_n_s_m,
            ),
        ];
        self.noise.validate()?;
        self.perturbation.validate()?;
        for (field, v) in non_negative {
            check(field, v, v >= 0.0, "must be >= 0")?;
        }
        check(
            "hand.substeps",
            f64::from(h.substeps),
            h.substeps >= 1,
            "must be >= 1",
        )?;
        for v in h.initial_position_rad {
            check("hand.initial_position_rad", v, true, "must be finite")?;
        }
        Ok(())
    }
}
