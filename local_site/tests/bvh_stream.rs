//! The BVH source end to end: a skeleton file and an Axis-Neuron-style broadcast server
//! written by the test, read through the `WristTracker` trait.

use std::io::Write;
use std::net::TcpListener;
use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use teleop_hardware::WristTracker;
use teleop_local_site::tracking::bvh::{
    BvhError, BvhStreamConfig, BvhStreamTracker, Skeleton, parse_stream, parse_stream_frame,
};

/// Hips (6 channels) -> Spine3 -> RightArm -> RightHand, rotations Y X Z, lengths in cm.
const SKELETON: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0 100 0
  CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation
  JOINT Spine3
  {
    OFFSET 0 40 0
    CHANNELS 3 Yrotation Xrotation Zrotation
    JOINT RightArm
    {
      OFFSET -20 10 0
      CHANNELS 3 Yrotation Xrotation Zrotation
      JOINT RightHand
      {
        OFFSET -55 0 0
        CHANNELS 3 Yrotation Xrotation Zrotation
        End Site
        {
          OFFSET -10 0 0
        }
      }
    }
  }
}
";

/// Frame values: hips at (5, 95, 2) cm turned 30 deg about Y, spine bent 10 deg about X,
/// the upper arm (shoulder to wrist) raised 90 deg about Z, the hand turned 20 deg about X.
fn frame() -> Vec<f64> {
    vec![
        5.0, 95.0, 2.0, 30.0, 0.0, 0.0, // Hips
        0.0, 10.0, 0.0, // Spine3
        0.0, 0.0, 90.0, // RightArm
        0.0, 20.0, 0.0, // RightHand
    ]
}

fn expected_hand_in_spine() -> Isometry3<f64> {
    let rot = |axis: nalgebra::Unit<Vector3<f64>>, deg: f64| {
        UnitQuaternion::from_axis_angle(&axis, f64::to_radians(deg))
    };
    // Spine3 -> RightArm: offset (-20, 10, 0) cm, rotated 90 deg about Z.
    let arm = Isometry3::from_parts(
        Translation3::new(-0.20, 0.10, 0.0),
        rot(Vector3::z_axis(), 90.0),
    );
    // RightArm -> RightHand: offset (-55, 0, 0) cm, rotated 20 deg about X.
    let hand = Isometry3::from_parts(
        Translation3::new(-0.55, 0.0, 0.0),
        rot(Vector3::x_axis(), 20.0),
    );
    arm * hand
}

#[test]
fn skeleton_and_relative_pose() {
    let (skeleton, motion) = Skeleton::parse(SKELETON).expect("parses");
    assert!(motion.is_none());
    assert_eq!(skeleton.joints().len(), 4);
    assert_eq!(skeleton.channel_count(), 15);
    let spine = skeleton.joint("Spine3").expect("spine");
    let hand = skeleton.joint("RightHand").expect("hand");
    let pose = skeleton
        .relative_pose(&frame(), spine, hand, 0.01)
        .expect("pose");
    let want = expected_hand_in_spine();
    // The arm turned 90 deg about Z points along -Y of the spine: the hand is 55 cm below.
    assert!((pose.translation.vector - Vector3::new(-0.20, -0.45, 0.0)).norm() < 1e-9);
    assert!((pose.translation.vector - want.translation.vector).norm() < 1e-9);
    assert!(pose.rotation.angle_to(&want.rotation) < 1e-9);
    // The relative pose does not depend on where the hips are or how they turn.
    let mut moved = frame();
    moved[0] += 50.0;
    moved[3] += 45.0;
    moved[4] -= 10.0;
    let again = skeleton
        .relative_pose(&moved, spine, hand, 0.01)
        .expect("pose");
    assert!((again.translation.vector - pose.translation.vector).norm() < 1e-9);
    assert!(again.rotation.angle_to(&pose.rotation) < 1e-9);
    // The world pose of the hips follows the root channels (cm -> m).
    let world = skeleton.world_poses(&frame(), 0.01).expect("poses");
    assert!((world[0].translation.vector - Vector3::new(0.05, 0.95, 0.02)).norm() < 1e-12);
}

#[test]
fn motion_section_and_malformed_files() {
    let values: Vec<String> = frame().iter().map(f64::to_string).collect();
    let with_motion = format!(
        "{SKELETON}MOTION\nFrames: 2\nFrame Time: 0.02\n{}\n{}\n",
        values.join(" "),
        values.join(" ")
    );
    let (_, motion) = Skeleton::parse(&with_motion).expect("parses");
    let motion = motion.expect("motion");
    assert_eq!(motion.frames.len(), 2);
    assert!((motion.frame_time_s - 0.02).abs() < 1e-12);
    assert_eq!(motion.frames[1], frame());

    let cases: [(String, &str); 5] = [
        (
            SKELETON.replace(
                "CHANNELS 3 Yrotation Xrotation Zrotation\n    JOINT RightArm",
                "CHANNELS 3 Yrotation Xrotation Wrotation\n    JOINT RightArm",
            ),
            "unknown channel `Wrotation`",
        ),
        (
            SKELETON.replace("OFFSET 0 40 0", "OFFSET 0 forty 0"),
            "line 8: `forty` is not a finite number",
        ),
        (
            SKELETON.replace("JOINT RightHand", "JOINT RightArm"),
            "names joint `RightArm` twice",
        ),
        (
            SKELETON[..SKELETON.len() - 3].to_string(),
            "unexpected end of file",
        ),
        (
            format!(
                "{SKELETON}MOTION\nFrames: 3\nFrame Time: 0.02\n{}\n",
                values.join(" ")
            ),
            "unexpected end of file",
        ),
    ];
    for (text, want) in cases {
        let err = Skeleton::parse(&text).expect_err(want).to_string();
        assert!(err.contains(want), "`{err}` should contain `{want}`");
    }
    let (skeleton, _) = Skeleton::parse(SKELETON).expect("parses");
    assert_eq!(
        skeleton.world_poses(&frame()[..14], 0.01),
        Err(BvhError::FrameLength {
            found: 14,
            expected: 15
        })
    );
    let mut nan = frame();
    nan[7] = f64::NAN;
    assert!(matches!(
        skeleton.world_poses(&nan, 0.01),
        Err(BvhError::BadValue { index: 7, .. })
    ));
    assert_eq!(
        skeleton.joint("LeftHand"),
        Err(BvhError::UnknownJoint("LeftHand".into()))
    );
}

#[test]
fn stream_frames_parse() {
    let f = parse_stream_frame("0 Avatar00 1 2.5 -3").expect("frame");
    assert_eq!(f.avatar_index, 0);
    assert_eq!(f.avatar_name, "Avatar00");
    assert_eq!(f.values, vec![1.0, 2.5, -3.0]);
    assert_eq!(parse_stream_frame("Avatar00 1 2"), Err(BvhError::BadPrefix));
    assert_eq!(parse_stream_frame("0 1 2"), Err(BvhError::BadPrefix));
    assert!(matches!(
        parse_stream_frame("0 Avatar00 1 inf 3"),
        Err(BvhError::BadValue { index: 1, .. })
    ));
    let frames = parse_stream("0 A 1 2 ||\n0 A 3 4 ||\n".as_bytes()).expect("frames");
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[1].values, vec![3.0, 4.0]);
}

#[test]
fn tracker_reads_a_live_broadcast() {
    let dir = std::env::temp_dir().join(format!("teleop-bvh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let skeleton_path = dir.join("skeleton.bvh");
    std::fs::write(&skeleton_path, SKELETON).expect("write skeleton");
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let address = listener.local_addr().expect("address").to_string();

    // The server: a malformed frame, another avatar's frame, then good frames at 50 Hz
    // (a frame split across writes on purpose), then it closes the connection.
    let server = std::thread::spawn(move || {
        let (mut conn, _) = listener.accept().expect("accept");
        let good: Vec<String> = frame().iter().map(f64::to_string).collect();
        let good = format!("0 Avatar00 {} ||", good.join(" "));
        conn.write_all(b"0 Avatar00 1 2 3 ||").expect("write");
        conn.write_all(good.replacen("0 Avatar00", "1 Avatar01", 1).as_bytes())
            .expect("write");
        for _ in 0..25 {
            let (a, b) = good.split_at(good.len() / 2);
            conn.write_all(a.as_bytes()).expect("write");
            conn.flush().expect("flush");
            std::thread::sleep(Duration::from_millis(5));
            conn.write_all(b.as_bytes()).expect("write");
            std::thread::sleep(Duration::from_millis(15));
        }
    });

    let config = BvhStreamConfig {
        address,
        skeleton: skeleton_path,
        avatar_index: 0,
        reference_joint: "Spine3".into(),
        hand_joint: "RightHand".into(),
        to_metres: 0.01,
        stale_after_s: 0.2,
        reconnect_s: 0.05,
        arm: None,
    };
    config.validate().expect("valid");
    let mut tracker = BvhStreamTracker::start(&config).expect("starts");
    let deadline = Instant::now() + Duration::from_secs(10);
    let pose = loop {
        if let Ok(Some(p)) = tracker.read(0.0) {
            break p;
        }
        assert!(Instant::now() < deadline, "no pose from the BVH stream");
        std::thread::sleep(Duration::from_millis(5));
    };
    let want = expected_hand_in_spine();
    assert!((pose.translation.vector - want.translation.vector).norm() < 1e-9);
    assert!(pose.rotation.angle_to(&want.rotation) < 1e-9);
    server.join().expect("server thread");
    // The server is gone: the pose goes stale, then the tracker says why.
    let deadline = Instant::now() + Duration::from_secs(10);
    let err = loop {
        match tracker.read(0.0) {
            Err(e) => break e.to_string(),
            Ok(_) => {
                assert!(
                    Instant::now() < deadline,
                    "the lost stream was not reported"
                );
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    };
    assert!(err.contains("BVH stream"), "{err}");
    let c = tracker.counters();
    assert!(c.frames >= 20, "{c:?}");
    assert_eq!(c.rejected, 1, "{c:?}");
    assert_eq!(c.other_avatars, 1, "{c:?}");
    assert!(c.connections >= 1);

    // A skeleton without the configured joint is refused at start.
    let bad = BvhStreamConfig {
        hand_joint: "LeftHand".into(),
        ..config
    };
    assert!(matches!(
        BvhStreamTracker::start(&bad),
        Err(BvhError::UnknownJoint(name)) if name == "LeftHand"
    ));
    let _ = std::fs::remove_dir_all(&dir);
}
