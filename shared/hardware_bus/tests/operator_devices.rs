//! The operator site's devices over the bus: the motion-capture tracker (newest sample
//! with its capture stamp, bad samples refused and counted, stale and not-connected
//! errors) and the pedal box (latest state, stale after a silence).
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use teleop_bus::{Bus, BusConfig};
use teleop_hardware::{HardwareError, OperatorPanel, WristTracker};
use teleop_hardware_bus::{BusPanel, BusWristTracker};
use teleop_interfaces::topics;
use teleop_msgs::{Header, OperatorInput, PoseStamped, Time};

fn configs(domain_id: u32) -> (BusConfig, BusConfig) {
    teleop_bus::testing::loopback_pair(domain_id)
}

fn marker_msg(pose: &Isometry3<f64>, stamp: Time) -> PoseStamped {
    PoseStamped {
        header: Header::new(stamp, "mocap"),
        pose: teleop_hardware::wire::pose_msg(pose).expect("a finite test pose"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_mocap_tracker_returns_new_samples_with_their_capture_stamp() {
    let (a, b) = configs(41);
    let driver = Bus::open("mocap_driver", &a).await.unwrap();
    let publisher = driver.publisher(&topics::HW_MOCAP_MARKER).await.unwrap();
    let reader = Bus::open("wrist_tracker", &b).await.unwrap();
    let mut tracker = BusWristTracker::mocap(&reader, 0.3).await.unwrap();
    assert!(matches!(
        tracker.read_sample(reader.now_s()),
        Err(HardwareError::NotConnected(_))
    ));

    let pose = Isometry3::from_parts(
        Translation3::new(0.4, -0.2, 1.1),
        UnitQuaternion::from_euler_angles(0.3, -0.1, 2.0),
    );
    let stamp = Time {
        sec: 1_700_000_000,
        nanosec: 123_456_789,
    };
    let mut got = None;
    for _ in 0..200 {
        publisher.put(&marker_msg(&pose, stamp)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        if let Ok(Some(s)) = tracker.read_sample(reader.now_s()) {
            got = Some(s);
            break;
        }
    }
    let sample = got.unwrap();
    assert_eq!(sample.capture, stamp, "the header stamp, exactly");
    assert!((sample.pose.translation.vector - pose.translation.vector).norm() < 1e-15);
    assert!(sample.pose.rotation.angle_to(&pose.rotation) < 1e-12);
    assert_eq!(tracker.newest(), Some(&sample));
    // Drain whatever else of the warm-up arrived: then nothing new is `Ok(None)`.
    tokio::time::sleep(Duration::from_millis(50)).await;
    let _ = tracker.read(reader.now_s()).unwrap();
    assert_eq!(tracker.read(reader.now_s()).unwrap(), None);

    // Two samples before a read: the newer one is returned, the older skipped.
    let later = Time {
        sec: stamp.sec + 1,
        nanosec: 0,
    };
    let skipped_before = tracker.skipped();
    publisher.put(&marker_msg(&pose, stamp)).unwrap();
    publisher.put(&marker_msg(&pose, later)).unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    let s = tracker.read_sample(reader.now_s()).unwrap().unwrap();
    assert_eq!(s.capture, later);
    assert!(tracker.skipped() > skipped_before);

    // A NaN and a non-unit quaternion are refused, counted, and are no sample.
    let mut nan = marker_msg(&pose, later);
    nan.pose.position.y = f64::NAN;
    let mut unnormalized = marker_msg(&pose, later);
    unnormalized.pose.orientation.w *= 1.1;
    publisher.put(&nan).unwrap();
    tokio::time::sleep(Duration::from_millis(50)).await;
    assert_eq!(tracker.read_sample(reader.now_s()).unwrap(), None);
    publisher.put(&unnormalized).unwrap();
    tokio::time::sleep(Duration::from_millis(50)).await;
    assert_eq!(tracker.read_sample(reader.now_s()).unwrap(), None);
    assert_eq!(tracker.non_finite(), 1);
    assert_eq!(tracker.not_normalized(), 1);

    // Silence (refused samples do not count as life): stale.
    tokio::time::sleep(Duration::from_millis(350)).await;
    match tracker.read(reader.now_s()) {
        Err(HardwareError::StaleState { age_s }) => assert!(age_s > 0.3, "{age_s}"),
        other => panic!("{other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_pedal_box_gives_its_latest_state_and_goes_stale() {
    let (a, b) = configs(42);
    let driver = Bus::open("pedal_driver", &a).await.unwrap();
    let publisher = driver.publisher(&topics::HW_PEDALS).await.unwrap();
    let reader = Bus::open("wrist_tracker", &b).await.unwrap();
    let mut panel = BusPanel::pedals(&reader, 0.2).await.unwrap();
    assert!(matches!(
        panel.read(reader.now_s()),
        Err(HardwareError::NotConnected(_))
    ));
    let msg = OperatorInput {
        header: Header::new(Time::now(), ""),
        clutch: true,
        enable: true,
        camera_stop: false,
        motion_scale: 0.5,
    };
    let mut got = None;
    for _ in 0..200 {
        publisher.put(&msg).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        if let Ok(s) = panel.read(reader.now_s()) {
            got = Some(s);
            break;
        }
    }
    let s = got.unwrap();
    assert!(s.clutch && s.enable && !s.camera_stop);
    assert_eq!(s.motion_scale, 0.5);
    // The latest state holds while fresh...
    assert_eq!(panel.read(reader.now_s()).unwrap(), s);
    // ...a non-finite motion scale is refused and does not refresh it...
    publisher
        .put(&OperatorInput {
            motion_scale: f64::NAN,
            ..msg.clone()
        })
        .unwrap();
    tokio::time::sleep(Duration::from_millis(50)).await;
    assert_eq!(panel.read(reader.now_s()).unwrap(), s);
    assert_eq!(panel.bad_states(), 1);
    // ...and after a silence the panel is stale.
    tokio::time::sleep(Duration::from_millis(250)).await;
    assert!(matches!(
        panel.read(reader.now_s()),
        Err(HardwareError::StaleState { .. })
    ));
}
