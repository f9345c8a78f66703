//! The bus clients and endpoints are written once: the same code serves the UR5 (6
//! joints) as the PR2 chain (7), and cameras of either kind.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use nalgebra::SVector;
use teleop_bus::{Bus, BusConfig};
use teleop_hardware::{ArmCommand, ArmHardware, ArmState, Camera, CameraKind};
use teleop_hardware_bus::{ArmEndpoint, BusArm, BusCamera};
use teleop_interfaces::hardware::UR5_ARM;
use teleop_interfaces::topics;
use teleop_msgs::{Image, encodings};

fn configs(domain_id: u32) -> (BusConfig, BusConfig) {
    teleop_bus::testing::loopback_pair(domain_id)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_six_joint_arm_over_the_bus_takes_commands_from_its_controller_only() {
    let (a, b) = configs(31);
    let driver = Bus::open("ur5_driver", &a).await.unwrap();
    let mut endpoint = ArmEndpoint::new(&driver, &UR5_ARM, UR5_ARM.controller_node)
        .await
        .unwrap();
    let controller = Bus::open(UR5_ARM.controller_node, &b).await.unwrap();
    let mut arm = BusArm::new(&controller, &UR5_ARM, 0.5).await.unwrap();
    let stranger = Bus::open("stranger", &b).await.unwrap();
    let mut other = BusArm::new(&stranger, &UR5_ARM, 0.5).await.unwrap();
    let state = ArmState {
        time_s: 1.0,
        position_rad: SVector::<f64, 6>::from_fn(|i, _| i as f64 * 0.1),
        velocity_rad_s: SVector::zeros(),
    };
    let mine = ArmCommand {
        velocity_rad_s: SVector::<f64, 6>::repeat(0.2),
    };
    let theirs = ArmCommand {
        velocity_rad_s: SVector::<f64, 6>::repeat(3.0),
    };
    let mut got_state = None;
    let mut got_command = None;
    for _ in 0..200 {
        endpoint.publish_state(&state).unwrap();
        other.write(0.0, &theirs).unwrap();
        arm.write(0.0, &mine).unwrap();
        tokio::time::sleep(Duration::from_millis(20)).await;
        if let Ok(s) = arm.read(controller.now_s()) {
            got_state = Some(s);
        }
        if let Some(c) = endpoint.take_command() {
            assert_eq!(c, mine, "only the controller's commands are taken");
            got_command = Some(c);
        }
        if got_state.is_some() && got_command.is_some() {
            break;
        }
    }
    assert_eq!(got_state.unwrap().position_rad, state.position_rad);
    assert_eq!(got_command, Some(mine));
    tokio::time::sleep(Duration::from_millis(200)).await;
    while endpoint.take_command().is_some() {}
    let counters = endpoint.counters();
    let foreign = counters
        .iter()
        .find(|(n, _)| n == "ur5.command.rejected_foreign")
        .unwrap()
        .1;
    assert!(foreign > 0, "{counters:?}");
    // A monitor handle only reads.
    let mut monitor = BusArm::monitor(&stranger, &UR5_ARM, 0.5).await.unwrap();
    assert!(monitor.write(0.0, &mine).is_err());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_camera_checks_its_images_kind() {
    let (a, b) = configs(32);
    let driver = Bus::open("camera_driver", &a).await.unwrap();
    let publisher = driver.publisher(&topics::HW_HAND_DEPTH).await.unwrap();
    let reader = Bus::open("reader", &b).await.unwrap();
    let mut depth = BusCamera::monitor(&reader, &topics::HW_HAND_DEPTH, CameraKind::Depth)
        .await
        .unwrap();
    let image = |encoding: &str, bytes_per_px: u32| Image {
        height: 2,
        width: 3,
        encoding: encoding.into(),
        step: 3 * bytes_per_px,
        data: vec![0; (6 * bytes_per_px) as usize],
        ..Default::default()
    };
    let mut ok = None;
    for _ in 0..100 {
        publisher.put(&image(encodings::DEPTH_16UC1, 2)).unwrap();
        tokio::time::sleep(Duration::from_millis(20)).await;
        if let Ok(Some(i)) = depth.read(0.0) {
            ok = Some(i);
            break;
        }
    }
    assert_eq!(ok.unwrap().width, 3);
    publisher.put(&image(encodings::RGB8, 3)).unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let e = depth.read(0.0).unwrap_err();
    assert!(e.to_string().contains("rgb8"), "{e}");
    assert_eq!(depth.bad_images(), 1);
}

/// An arm whose state is published but dropped on the way by the hardware access rule
/// (the controller allows hardware topics on another interface than the link's): the
/// error names the publisher, the topic and the rule, not just "no state yet".
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_state_dropped_by_the_hardware_rule_is_named() {
    let (a, mut b) = configs(33);
    b.zenoh.hardware_interfaces = vec!["site_lan0".into()];
    let driver = Bus::open("remote_sim", &a).await.unwrap();
    let endpoint = ArmEndpoint::new(&driver, &UR5_ARM, UR5_ARM.controller_node)
        .await
        .unwrap();
    let controller = Bus::open(UR5_ARM.controller_node, &b).await.unwrap();
    let mut arm = BusArm::new(&controller, &UR5_ARM, 0.5).await.unwrap();
    let started_s = controller.now_s();
    let state = ArmState {
        time_s: 1.0,
        position_rad: SVector::<f64, 6>::zeros(),
        velocity_rad_s: SVector::zeros(),
    };
    let mut last = String::new();
    // Announced for `SILENT_PUBLISHER_AFTER_S` (2 s) before the error names it.
    for _ in 0..400 {
        endpoint.publish_state(&state).unwrap();
        tokio::time::sleep(Duration::from_millis(20)).await;
        match arm.read(controller.now_s()) {
            Ok(_) => panic!("a hardware state crossed loopback against the rule"),
            Err(e) => last = e.to_string(),
        }
        if last.contains("though") {
            break;
        }
    }
    let named_after = controller.now_s() - started_s;
    assert!(
        named_after >= teleop_hardware_bus::SILENT_PUBLISHER_AFTER_S - 0.1,
        "named {named_after:.2} s after the start: {last}"
    );
    assert!(
        last.contains("though remote_sim@")
            && last.contains("publishes /teleop/hw/ur5/state")
            && last.contains("hardware_interfaces (site_lan0)"),
        "{last}"
    );
}
