//! The controller's gravity model against the simulator's gravity: compensation holds
//! passive fingers still in any arm posture; without it they sag.
#![allow(clippy::unwrap_used)]

use nalgebra::{SVector, Vector3};
use teleop_hardware::HandCommand;
use teleop_remote_site::gravity::HandGravity;
use teleop_sim::{World, WorldConfig};

#[test]
fn compensation_holds_the_fingers_still_and_without_it_they_sag() {
    for arm in [
        [0.0; 7],                                             // palm down
        [0.0, 0.0, 0.0, 0.0, std::f64::consts::PI, 0.0, 0.0], // palm up
        [-0.5, 0.3, -1.0, -1.4, 0.3, -0.1, 0.1],              // working posture
    ] {
        let mut config = WorldConfig::default();
        config.arm.initial_position_rad = arm;
        // Bent fingers, away from the joint limits.
        config.hand.initial_position_rad = [0.3; 17];
        config.hand.initial_position_rad[13] = 0.0; // THJ5 (range -1.05..1.05)
        let mut model = HandGravity::new(Vector3::from(config.gravity_m_s2)).unwrap();
        let mut w = World::new(config.clone()).unwrap();
        let q0 = w.hand_position_rad();
        let g = model.compensation_nm(&w.arm_position_rad(), &q0);
        assert!(g.amax() > 1e-3, "gravity acts on the fingers: {g}");
        for _ in 0..500 {
            let g = model.compensation_nm(&w.arm_position_rad(), &w.hand_position_rad());
            w.command_hand(&HandCommand::Effort(g));
            w.step(0.001);
        }
        let held = (w.hand_position_rad() - q0).amax();
        let mut w = World::new(config).unwrap();
        w.command_hand(&HandCommand::Effort(SVector::zeros()));
        w.step(0.5);
        let sagged = (w.hand_position_rad() - q0).amax();
        println!("arm {arm:?}: drift {held:.2e} rad compensated, {sagged:.3} rad without");
        assert!(held < 1e-6, "compensated fingers drift {held} rad");
        assert!(sagged > 0.05, "uncompensated fingers sag only {sagged} rad");
    }
}
