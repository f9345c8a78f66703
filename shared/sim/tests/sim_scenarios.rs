//! Thesis scenarios: mouse touching, cup grasp, screw-pouring load.
#![allow(clippy::unwrap_used)]

use nalgebra::SVector;
use teleop_hardware::HandCommand;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_sim::{
    CupGraspConfig, ExternalLoad, LoadTarget, TouchingTaskConfig, World, WorldConfig,
};

fn idx(name: &str) -> usize {
    SHADOW_FINGER_JOINTS
        .iter()
        .position(|j| *j == name)
        .unwrap()
}

#[test]
fn touching_surface_is_placed_at_the_clearance() {
    let config = TouchingTaskConfig {
        world: WorldConfig::nominal(),
        ..TouchingTaskConfig::default()
    };
    let mut w = World::touching_task(&config).unwrap();
    let ff = w.distal_link(0).unwrap();
    let gap = w.clearance_m(0, None).unwrap();
    assert!((gap - config.clearance_m).abs() < 1e-6, "{gap}");
    assert!((w.clearance_m(0, Some(ff)).unwrap() - config.clearance_m).abs() < 1e-6);
    for f in 1..5 {
        let other = w.distal_link(f).unwrap();
        assert!(w.clearance_m(0, Some(other)).unwrap() > config.clearance_m);
    }
    // Holding the reference posture: no contact.
    w.step(0.5);
    assert_eq!(w.fingertip_force_n(), [0.0; 5]);
    assert!(w.contacts().is_empty());
}

#[test]
fn flexing_ff_into_the_mouse_loads_ff_only_and_deeper_pushes_harder() {
    let config = TouchingTaskConfig {
        world: WorldConfig::nominal(),
        ..TouchingTaskConfig::default()
    };
    let mut w = World::touching_task(&config).unwrap();
    let reference = SVector::<f64, 17>::from(config.hand_posture_rad);
    let mut forces = Vec::new();
    for extra in [0.1, 0.2, 0.3] {
        let mut q = reference;
        q[idx("rh_FFJ3")] += extra;
        q[idx("rh_FFJ2")] += extra;
        w.command_hand(&HandCommand::Position(q));
        w.step(1.0);
        let tips = w.hand_state().fingertip_force_n;
        assert!(tips[0] > 0.2, "ff force at +{extra} rad: {tips:?}");
        assert_eq!(&tips[1..], &[0.0; 4], "only ff touches");
        assert!(
            w.contacts()
                .iter()
                .all(|c| c.fingertip == Some(0) && c.object == 0)
        );
        forces.push(tips[0]);
    }
    assert!(forces[0] < forces[1] && forces[1] < forces[2], "{forces:?}");
    // The contact lies on the mouse's surface (within the penetration).
    let c = w.contacts()[0];
    let centre = w.objects()[0].pose.translation.vector;
    let r = (c.point_m.coords - centre).norm();
    assert!((r - config.surface_radius_m).abs() < c.depth_m, "{r}");
    // The normal force points away from the mouse.
    assert!(c.normal.dot(&(c.point_m.coords - centre)) > 0.0);
}

#[test]
fn closing_the_hand_on_the_cup_loads_several_fingertips() {
    let config = CupGraspConfig {
        world: WorldConfig::nominal(),
        ..CupGraspConfig::default()
    };
    let mut w = World::cup_grasp(&config).unwrap();
    assert!(w.clearance_m(0, None).unwrap() >= config.clearance_m - 1e-12);
    w.step(0.3);
    assert_eq!(w.fingertip_force_n(), [0.0; 5], "open hand clears the cup");
    w.command_hand(&HandCommand::Position(SVector::from(
        config.closed_posture_rad,
    )));
    w.step(2.0);
    let tips = w.hand_state().fingertip_force_n;
    let loaded = tips.iter().filter(|f| **f > 0.2).count();
    assert!(loaded >= 3, "{tips:?}");
    assert!(tips[4] > 0.2, "the thumb opposes: {tips:?}");
    assert!(w.hand_velocity_rad_s().amax() < 1e-3, "a steady grasp");
}

#[test]
fn screw_pouring_load_makes_the_thumb_slip_under_position_control() {
    let mut w = World::screw_pouring(1.0).unwrap();
    let closed = SVector::from(
        CupGraspConfig {
            world: WorldConfig::nominal(),
            ..CupGraspConfig::default()
        }
        .closed_posture_rad,
    );
    w.command_hand(&HandCommand::Position(closed));
    w.step(1.0);
    let th4 = idx("rh_THJ4");
    let before = w.hand_position_rad()[th4];
    let force_before = w.fingertip_force_n()[4];
    w.step(3.0);
    let after = w.hand_position_rad()[th4];
    assert!(
        before - after > 0.01,
        "THJ4 pushed open: {before} -> {after}"
    );
    assert!(w.fingertip_force_n()[4] < force_before);

    // A fingertip-force load works as well and is refused for an unknown finger.
    let mut w = World::cup_grasp(&CupGraspConfig {
        world: WorldConfig::nominal(),
        ..CupGraspConfig::default()
    })
    .unwrap();
    let bad = ExternalLoad {
        target: LoadTarget::FingertipForce {
            finger: "xx".to_owned(),
            force_n: [0.0; 3],
        },
        start_s: 0.0,
        ramp_s: 0.0,
        end_s: None,
    };
    assert!(w.add_load(bad).is_err());
    let load = ExternalLoad {
        target: LoadTarget::FingertipForce {
            finger: "ff".to_owned(),
            force_n: [0.0, 0.0, -2.0],
        },
        start_s: 0.0,
        ramp_s: 0.0,
        end_s: Some(0.5),
    };
    w.add_load(load).unwrap();
    w.command_hand(&HandCommand::Effort(SVector::zeros()));
    let z0 = w.fingertip_positions_m()[0].z;
    w.step(0.1);
    assert!(w.fingertip_positions_m()[0].z < z0 - 0.002);
}
