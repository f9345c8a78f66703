//! A BigHand2.2M-style annotation file, written by the test, read back and run through
//! the retargeting like the dataset's own keypoints.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use teleop_hand_model::bighand::{self, AnnotatedFrame};
use teleop_hand_model::human::HumanHand;
use teleop_hand_model::retarget::{RetargetSettings, Retargeter};
use teleop_hand_model::sampling::Synergy;

#[test]
fn an_annotation_file_feeds_the_retargeting() {
    let hand = HumanHand::average();
    let camera_from_hand = Isometry3::from_parts(
        Translation3::new(0.02, -0.01, 0.42),
        UnitQuaternion::from_scaled_axis(Vector3::new(1.4, 0.2, -0.3)),
    );
    let frames: Vec<AnnotatedFrame> = Synergy::ALL
        .iter()
        .enumerate()
        .map(|(i, s)| AnnotatedFrame {
            image: format!("image_D{i:08}.png"),
            keypoints: hand.keypoints(&s.posture()).transformed(&camera_from_hand),
        })
        .collect();
    let path = std::env::temp_dir().join(format!("bighand-{}.txt", std::process::id()));
    let text: String = frames
        .iter()
        .map(|f| bighand::format_line(f) + "\n")
        .collect();
    std::fs::write(&path, text).expect("write");
    let read = bighand::read(&path).expect("read");
    assert_eq!(read.len(), frames.len());
    let r = Retargeter::new(RetargetSettings::default()).expect("retargeter");
    for (a, b) in read.iter().zip(&frames) {
        assert_eq!(a.image, b.image);
        // mm with 4 decimals: 0.1 um.
        assert!(a.keypoints.max_distance(&b.keypoints) < 1e-6);
        let ja = r.retarget(&a.keypoints, None).expect("file").joints;
        let jb = r.retarget(&b.keypoints, None).expect("original").joints;
        // The retargeting stops after a fixed iteration budget on an over-determined
        // problem, and a finger that touches another is solved again under a stiff
        // collision penalty: its end point can move by a few 1e-3 rad for a 0.1 um
        // change of input. The same hand, in the task's terms: fingertips within 1 mm.
        for (x, y) in ja.iter().zip(&jb) {
            assert!((x - y).abs() < 0.02, "{x} vs {y}");
        }
        let (ka, kb) = (r.shadow_keypoints(&ja), r.shadow_keypoints(&jb));
        assert!(ka.max_distance(&kb) < 1e-3, "{}", ka.max_distance(&kb));
        // The hand centre projects into the dataset camera's image.
        let (u, v) = bighand::project(&bighand::hand_centre(&a.keypoints)).expect("in front");
        assert!(
            (0.0..640.0).contains(&u) && (0.0..480.0).contains(&v),
            "{u} {v}"
        );
    }
    let err = bighand::read(&path.with_extension("missing")).expect_err("missing file");
    assert!(err.to_string().contains("missing"), "{err}");
    let _ = std::fs::remove_file(&path);
}
