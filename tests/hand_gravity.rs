//! The controller's gravity model against the simulator's gravity: on the nominal
//! robot, compensation holds passive fingers still in any arm posture (the model is the
//! physics); on the default simulated robot (link masses perturbed by up to 15 %) it
//! leaves the model error, far less than the sag without it.
#![allow(clippy::unwrap_used)]

use nalgebra::{SVector, Vector3};
use teleop_hardware::HandCommand;
use teleop_remote_site::gravity::HandGravity;
use teleop_sim::{NoiseConfig, PerturbationConfig, World, WorldConfig};

#[test]
fn compensation_holds_the_fingers_still_and_without_it_they_sag() {
    for arm in [
        [0.0; 7],                                             // palm down
        [0.0, 0.0, 0.0, 0.0, std::f64::consts::PI, 0.0, 0.0], // palm up
        [-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1],              // working posture
    ] {
        let mut config = WorldConfig {
            noise: NoiseConfig::none(),
            ..WorldConfig::default()
        };
        config.arm.initial_position_rad = arm;
        // Bent fingers, away from the joint limits.
        config.hand.initial_position_rad = [0.3; 17];
        config.hand.initial_position_rad[13] = 0.0; // THJ5 (range -1.05..1.05)
        let mut model = HandGravity::new(Vector3::from(config.gravity_m_s2)).unwrap();
        // Drift in 0.5 s with the nominal model's compensation, on `world`.
        let mut drift = |config: WorldConfig, compensate: bool| {
            let mut w = World::new(config).unwrap();
            let q0 = w.hand_position_rad();
            for _ in 0..500 {
                let g = if compensate {
                    model.compensation_nm(&w.arm_position_rad(), &w.hand_position_rad())
                } else {
                    SVector::zeros()
                };
                w.command_hand(&HandCommand::Effort(g));
                w.step(0.001);
            }
            (w.hand_position_rad() - q0).amax()
        };
        let nominal = WorldConfig {
            perturbation: PerturbationConfig::none(),
            ..config.clone()
        };
        let exact = drift(nominal.clone(), true);
        let sagged = drift(nominal, false);
        let perturbed = drift(config.clone(), true);
        println!(
            "arm {arm:?}: drift {exact:.2e} rad compensated (nominal robot), {perturbed:.4} rad compensated (perturbed robot), {sagged:.3} rad without"
        );
        assert!(
            exact < 1e-6,
            "compensated nominal fingers drift {exact} rad"
        );
        assert!(sagged > 0.05, "uncompensated fingers sag only {sagged} rad");
        assert!(
            perturbed > 1e-5,
            "the perturbed robot shows its model error"
        );
        assert!(
            perturbed < 0.25 * sagged,
            "compensation still cancels most of it"
        );
    }
}
