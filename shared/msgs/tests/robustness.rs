//! `decode` faces bytes from the network: whatever they are, it must return (an error
//! or a message) without panicking, quickly, and without allocating more than the
//! payload's size. A `CodecError::Wire` means `check_wire` refused the payload before the
//! `cdr` decoder (which pre-allocates whatever a length field claims) ever ran.
#![allow(clippy::unwrap_used)]

mod common;

use common::*;
use proptest::collection::vec;
use proptest::prelude::*;
use teleop_msgs::{
    CodecError, CompressedImage, FingertipPressures, Header, Image, JointCommand, JointState,
    Message, NodeStatus, OperatorInput, Point, Pose, PoseStamped, Quaternion, Time, Transform,
    TransformStamped, Vector3, WireError, decode, encode,
};

/// Decodes `bytes` as `T` and checks the outcome is consistent:
/// * an error names `T` and is never an encoding error;
/// * a message re-encodes to at most about twice `bytes.len()` (no amplification: the
///   only growth is a zero-length string, which the decoder accepts like Fast-CDR and
///   rosbags do, re-encoded as length 1 + NUL) and that encoding decodes to the same
///   bits.
fn decode_consistent<T: Message>(bytes: &[u8]) -> Result<(), TestCaseError> {
    match decode::<T>(bytes) {
        Ok(msg) => {
            let re = encode(&msg).unwrap();
            prop_assert!(
                re.len() <= 2 * bytes.len() + 8,
                "{}: {} bytes decoded into a message of {} bytes",
                T::TYPE_NAME,
                bytes.len(),
                re.len()
            );
            let again: T = decode(&re).unwrap();
            prop_assert_eq!(encode(&again).unwrap(), re);
        }
        Err(CodecError::Wire { type_name, .. } | CodecError::Decode { type_name, .. }) => {
            prop_assert_eq!(type_name, T::TYPE_NAME);
        }
        Err(other) => prop_assert!(false, "unexpected error {other:?}"),
    }
    Ok(())
}

/// Runs [`decode_consistent`] for every message type.
fn decode_as_every_type(bytes: &[u8]) -> Result<(), TestCaseError> {
    decode_consistent::<Time>(bytes)?;
    decode_consistent::<Header>(bytes)?;
    decode_consistent::<Point>(bytes)?;
    decode_consistent::<Vector3>(bytes)?;
    decode_consistent::<Quaternion>(bytes)?;
    decode_consistent::<Pose>(bytes)?;
    decode_consistent::<PoseStamped>(bytes)?;
    decode_consistent::<Transform>(bytes)?;
    decode_consistent::<TransformStamped>(bytes)?;
    decode_consistent::<JointState>(bytes)?;
    decode_consistent::<Image>(bytes)?;
    decode_consistent::<CompressedImage>(bytes)?;
    decode_consistent::<OperatorInput>(bytes)?;
    decode_consistent::<FingertipPressures>(bytes)?;
    decode_consistent::<NodeStatus>(bytes)?;
    decode_consistent::<JointCommand>(bytes)?;
    Ok(())
}

/// A valid encoding of every type, with non-empty strings and sequences everywhere.
fn valid_samples() -> Vec<(&'static str, Vec<u8>)> {
    let header = Header::new(
        Time {
            sec: 1_700_000_000,
            nanosec: 123_456_789,
        },
        "hand",
    );
    let q = Quaternion {
        x: 0.1,
        y: -0.2,
        z: 0.3,
        w: 0.9,
    };
    let p = Point {
        x: 1.5,
        y: -2.5,
        z: 3.5,
    };
    let t = Transform {
        translation: Vector3 {
            x: 0.5,
            y: 0.25,
            z: -1.0,
        },
        rotation: q,
    };
    let pose = Pose {
        position: p,
        orientation: q,
    };
    vec![
        (Time::TYPE_NAME, encode(&header.stamp).unwrap()),
        (Header::TYPE_NAME, encode(&header).unwrap()),
        (Point::TYPE_NAME, encode(&p).unwrap()),
        (Vector3::TYPE_NAME, encode(&t.translation).unwrap()),
        (Quaternion::TYPE_NAME, encode(&q).unwrap()),
        (Pose::TYPE_NAME, encode(&pose).unwrap()),
        (
            PoseStamped::TYPE_NAME,
            encode(&PoseStamped {
                header: header.clone(),
                pose,
            })
            .unwrap(),
        ),
        (Transform::TYPE_NAME, encode(&t).unwrap()),
        (
            TransformStamped::TYPE_NAME,
            encode(&TransformStamped {
                header: header.clone(),
                child_frame_id: "ff_distal".into(),
                transform: t,
            })
            .unwrap(),
        ),
        (
            JointState::TYPE_NAME,
            encode(&JointState {
                header: header.clone(),
                name: vec!["FFJ1".into(), "FFJ2".into(), "THJ5".into()],
                position: vec![0.1, 0.2, 0.3],
                velocity: vec![1.0, 2.0, 3.0],
                effort: vec![-1.0, 0.0, 1.0],
            })
            .unwrap(),
        ),
        (
            Image::TYPE_NAME,
            encode(&Image::depth_mm(
                header.clone(),
                3,
                2,
                &[0, 500, 1000, 1500, 2000, 65535],
            ))
            .unwrap(),
        ),
        (
            CompressedImage::TYPE_NAME,
            encode(&CompressedImage {
                header: header.clone(),
                format: "jpeg".into(),
                data: vec![0xff, 0xd8, 0xff, 0xe0, 0x00, 0x10, 0xff, 0xd9],
            })
            .unwrap(),
        ),
        (
            OperatorInput::TYPE_NAME,
            encode(&OperatorInput {
                header: header.clone(),
                clutch: true,
                enable: true,
                camera_stop: false,
                motion_scale: 1.0 / 3.0,
            })
            .unwrap(),
        ),
        (
            FingertipPressures::TYPE_NAME,
            encode(&FingertipPressures {
                header: header.clone(),
                ff: 0.5,
                mf: 1.0,
                rf: 0.0,
                lf: 0.25,
                th: 2.0,
            })
            .unwrap(),
        ),
        (
            NodeStatus::TYPE_NAME,
            encode(&NodeStatus {
                header,
                node_name: "remote_bridge".into(),
                lifecycle_state: 2,
                counter_names: vec!["wrist_pose.rejected_stale".into(), "rx".into()],
                counter_values: vec![3, u64::MAX],
                last_error: "none".into(),
            })
            .unwrap(),
        ),
        (
            JointCommand::TYPE_NAME,
            encode(&JointCommand {
                header: Header::default(),
                mode: "impedance".into(),
                name: vec!["rh_FFJ3".into()],
                position: vec![0.5],
                velocity: vec![0.0],
                effort: vec![0.1],
                stiffness: vec![20.0],
                damping: vec![0.2],
                max_effort: vec![2.0],
            })
            .unwrap(),
        ),
    ]
}

/// Decodes `bytes` as the type called `name`.
fn decode_named(name: &str, bytes: &[u8]) -> Result<(), CodecError> {
    fn d<T: Message>(bytes: &[u8]) -> Result<(), CodecError> {
        decode::<T>(bytes).map(|_| ())
    }
    match name {
        Time::TYPE_NAME => d::<Time>(bytes),
        Header::TYPE_NAME => d::<Header>(bytes),
        Point::TYPE_NAME => d::<Point>(bytes),
        Vector3::TYPE_NAME => d::<Vector3>(bytes),
        Quaternion::TYPE_NAME => d::<Quaternion>(bytes),
        Pose::TYPE_NAME => d::<Pose>(bytes),
        PoseStamped::TYPE_NAME => d::<PoseStamped>(bytes),
        Transform::TYPE_NAME => d::<Transform>(bytes),
        TransformStamped::TYPE_NAME => d::<TransformStamped>(bytes),
        JointState::TYPE_NAME => d::<JointState>(bytes),
        Image::TYPE_NAME => d::<Image>(bytes),
        CompressedImage::TYPE_NAME => d::<CompressedImage>(bytes),
        OperatorInput::TYPE_NAME => d::<OperatorInput>(bytes),
        FingertipPressures::TYPE_NAME => d::<FingertipPressures>(bytes),
        NodeStatus::TYPE_NAME => d::<NodeStatus>(bytes),
        JointCommand::TYPE_NAME => d::<JointCommand>(bytes),
        other => panic!("unknown type {other}"),
    }
}

// ------------------------------------------------------------------ random bytes

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in vec(any::<u8>(), 0..2048)) {
        decode_as_every_type(&bytes)?;
    }

    /// Same with a valid header in front, so the schema walk gets past byte 4.
    #[test]
    fn arbitrary_bodies_never_panic(
        little in any::<bool>(),
        body in vec(any::<u8>(), 0..2048),
    ) {
        let mut bytes = vec![0, u8::from(little), 0, 0];
        bytes.extend_from_slice(&body);
        decode_as_every_type(&bytes)?;
    }

    /// Bodies made of small little-endian u32s, so length fields are often plausible and
    /// the decoder itself runs.
    #[test]
    fn small_word_bodies_never_panic(words in vec(0u32..40, 0..256)) {
        let mut bytes = vec![0, 1, 0, 0];
        for w in words {
            bytes.extend_from_slice(&w.to_le_bytes());
        }
        decode_as_every_type(&bytes)?;
    }

    /// Valid messages with a few bytes overwritten.
    #[test]
    fn mutated_valid_messages_never_panic(
        js in joint_state(Floats::Any),
        ns in node_status(),
        img in image(),
        edits in vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
    ) {
        for mut bytes in [encode(&js).unwrap(), encode(&ns).unwrap(), encode(&img).unwrap()] {
            for (at, value) in &edits {
                let i = at.index(bytes.len());
                bytes[i] = *value;
            }
            decode_as_every_type(&bytes)?;
        }
    }

    /// Valid messages with a length field replaced by a huge value.
    #[test]
    fn huge_words_in_valid_messages_are_refused(
        js in joint_state(Floats::Finite),
        at in any::<prop::sample::Index>(),
        value in prop_oneof![Just(u32::MAX), Just(0x8000_0000u32), 0x0100_0000u32..],
    ) {
        let mut bytes = encode(&js).unwrap();
        // Overwrite an aligned 4-byte word of the body.
        let words = (bytes.len() - 4) / 4;
        let w = at.index(words);
        let i = 4 + 4 * w;
        bytes[i..i + 4].copy_from_slice(&value.to_le_bytes());
        // (How long refusing takes is benchmarked: `cargo bench --workspace --bench cdr`,
        // joint_state_24_malformed, docs/benchmarks.md. Tests assert behaviour.)
        let r = decode::<JointState>(&bytes);
        decode_consistent::<JointState>(&bytes)?;
        // A word that was a length field can no longer fit: refused before decoding.
        if let Ok(decoded) = r {
            // The word was a value (stamp, part of a float): the message still decodes.
            prop_assert_eq!(decoded.name.len(), js.name.len());
        }
    }
}

// ------------------------------------------------------------------ systematic mutations

#[test]
fn every_truncation_is_refused_by_the_pre_check() {
    for (name, bytes) in valid_samples() {
        decode_named(name, &bytes).unwrap();
        for len in 0..bytes.len() {
            match decode_named(name, &bytes[..len]) {
                Err(CodecError::Wire {
                    type_name,
                    source: WireError::NoHeader { len: l },
                }) => {
                    assert!(len < 4, "{name}: NoHeader at {len}");
                    assert_eq!((type_name, l), (name, len));
                }
                Err(CodecError::Wire {
                    type_name,
                    source: WireError::Truncated { field, .. },
                }) => {
                    assert!(len >= 4);
                    assert_eq!(type_name, name);
                    assert!(field.starts_with(name), "{field}");
                }
                other => panic!("{name} truncated to {len} bytes: {other:?}"),
            }
        }
    }
}

#[test]
fn every_single_bit_flip_is_handled() {
    let mut decoded_ok = 0usize;
    let mut refused = 0usize;
    for (name, bytes) in valid_samples() {
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut m = bytes.clone();
                m[i] ^= 1 << bit;
                match decode_named(name, &m) {
                    Ok(()) => decoded_ok += 1,
                    Err(CodecError::Wire { .. } | CodecError::Decode { .. }) => refused += 1,
                    Err(e) => panic!("{name} byte {i} bit {bit}: {e:?}"),
                }
                // The consistency checks (no amplification, stable re-encoding) too.
                decode_as_every_type(&m).unwrap();
            }
        }
    }
    // Flips in values decode; flips in length fields, bools and the header do not.
    assert!(
        decoded_ok > 0 && refused > 0,
        "{decoded_ok} ok, {refused} refused"
    );
}

fn set_u32(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn get_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

fn expect_truncated<T: Message>(bytes: &[u8], field_path: &str) {
    expect_refused::<T>(bytes, field_path, false);
}

/// `decode` refuses `bytes` in the pre-check, naming `field_path` (how long that takes is
/// benchmarked: `cargo bench --workspace --bench cdr`, joint_state_24_malformed).
fn expect_refused<T: Message>(bytes: &[u8], field_path: &str, allow_unterminated: bool) {
    let r = decode::<T>(bytes);
    match r {
        Err(CodecError::Wire {
            type_name,
            source:
                WireError::Truncated {
                    field,
                    needed,
                    available,
                    ..
                },
        }) => {
            assert_eq!(type_name, T::TYPE_NAME);
            assert_eq!(field, format!("{}.{field_path}", T::TYPE_NAME));
            assert!(needed > available as u64);
            assert!(available <= bytes.len());
        }
        // A huge count of strings makes the walk read the following fields as strings;
        // it may stop at one that does not end in NUL before running out of bytes.
        Err(CodecError::Wire {
            type_name,
            source: WireError::UnterminatedString { field, offset },
        }) if allow_unterminated => {
            assert_eq!(type_name, T::TYPE_NAME);
            assert_eq!(field, format!("{}.{field_path}", T::TYPE_NAME));
            assert!(offset < bytes.len());
        }
        other => panic!(
            "{}: expected Truncated in {field_path}, got {other:?}",
            T::TYPE_NAME
        ),
    }
}

const HUGE: [u32; 4] = [u32::MAX, 0x8000_0000, 0x0010_0000, 0x0000_1000];

#[test]
fn huge_lengths_in_joint_state_name_the_field() {
    let js = JointState {
        header: Header::new(Time { sec: 1, nanosec: 2 }, "h"),
        name: vec!["abcd".into()],
        position: vec![1.0],
        velocity: vec![],
        effort: vec![-0.5],
    };
    let bytes = encode(&js).unwrap();
    // Layout as in roundtrip.rs's golden JointState.
    // (absolute offset, current value, field path, is the count of a string sequence)
    let fields = [
        (12, 2, "header.frame_id", false),
        (20, 1, "name", true),
        (24, 5, "name", false),
        (36, 1, "position", false),
        (52, 0, "velocity", false),
        (56, 1, "effort", false),
    ];
    for (at, current, path, string_count) in fields {
        assert_eq!(get_u32(&bytes, at), current, "layout of {path}");
        for huge in HUGE {
            let mut m = bytes.clone();
            set_u32(&mut m, at, huge);
            expect_refused::<JointState>(&m, path, string_count);
            // Big-endian header with the same (now byte-swapped) words: also refused.
            let mut be = m.clone();
            be[1] = 0;
            assert!(matches!(
                decode::<JointState>(&be),
                Err(CodecError::Wire { .. } | CodecError::Decode { .. })
            ));
        }
    }
    // The name-sequence corruption is reported with "name" in the field.
    let mut m = bytes.clone();
    set_u32(&mut m, 20, u32::MAX);
    match decode::<JointState>(&m) {
        Err(CodecError::Wire {
            source: WireError::Truncated { field, .. },
            ..
        }) => assert!(field.contains("name"), "{field}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn huge_lengths_in_image_and_node_status_name_the_field() {
    let img = Image {
        header: Header::default(),
        height: 1,
        width: 3,
        encoding: "mono8".into(),
        is_bigendian: 0,
        step: 3,
        data: vec![1, 2, 3],
    };
    let bytes = encode(&img).unwrap();
    for (at, current, path) in [
        (12, 1, "header.frame_id"),
        (28, 6, "encoding"),
        (44, 3, "data"),
    ] {
        assert_eq!(get_u32(&bytes, at), current, "layout of {path}");
        for huge in HUGE {
            let mut m = bytes.clone();
            set_u32(&mut m, at, huge);
            expect_truncated::<Image>(&m, path);
        }
    }

    let ns = NodeStatus {
        header: Header::default(),
        node_name: "n".into(),
        lifecycle_state: 2,
        counter_names: vec!["c".into()],
        counter_values: vec![7],
        last_error: String::new(),
    };
    let bytes = encode(&ns).unwrap();
    // (absolute offset, current value, field path, is the count of a string sequence)
    for (at, current, path, string_count) in [
        (20, 2, "node_name", false),
        (28, 1, "counter_names", true),
        (32, 2, "counter_names", false),
        (40, 1, "counter_values", false),
        (52, 1, "last_error", false),
    ] {
        assert_eq!(get_u32(&bytes, at), current, "layout of {path}");
        for huge in HUGE {
            let mut m = bytes.clone();
            set_u32(&mut m, at, huge);
            expect_refused::<NodeStatus>(&m, path, string_count);
        }
    }
}

#[test]
fn one_past_the_end_is_refused() {
    // A length exactly one byte too long is refused as well as absurd ones.
    let ns = NodeStatus {
        last_error: "boom".into(),
        ..NodeStatus::default()
    };
    let mut bytes = encode(&ns).unwrap();
    let at = bytes.len() - 5 - 4;
    assert_eq!(get_u32(&bytes, at), 5);
    set_u32(&mut bytes, at, 6);
    expect_truncated::<NodeStatus>(&bytes, "last_error");
}

#[test]
fn bad_bool_names_the_field() {
    let oi = OperatorInput::default();
    let bytes = encode(&oi).unwrap();
    // header: stamp 0..8, frame_id "" 8..13; clutch, enable, camera_stop at 13, 14, 15.
    for (i, path) in [(17, "clutch"), (18, "enable"), (19, "camera_stop")] {
        assert_eq!(bytes[i], 0);
        for value in [2u8, 0x80, 0xff] {
            let mut m = bytes.clone();
            m[i] = value;
            match decode::<OperatorInput>(&m) {
                Err(CodecError::Wire {
                    source: WireError::BadBool { field, value: v },
                    ..
                }) => {
                    assert_eq!(field, format!("teleop_msgs/msg/OperatorInput.{path}"));
                    assert_eq!(v, value);
                }
                other => panic!("{path}={value}: {other:?}"),
            }
        }
        let mut m = bytes.clone();
        m[i] = 1;
        assert!(decode::<OperatorInput>(&m).is_ok());
    }
}

#[test]
fn encapsulation_header_is_checked() {
    let good = encode(&Time { sec: 1, nanosec: 1 }).unwrap();
    for (h0, h1, code) in [
        (0u8, 2u8, 0x0002u16),
        (0, 3, 0x0003),
        (1, 1, 0x0101),
        (0, 0x10, 0x0010),
    ] {
        let mut m = good.clone();
        m[0] = h0;
        m[1] = h1;
        match decode::<Time>(&m) {
            Err(CodecError::Wire {
                source: WireError::Encapsulation(c),
                ..
            }) => assert_eq!(c, code),
            other => panic!("{h0:#x} {h1:#x}: {other:?}"),
        }
    }
    for len in 0..4 {
        assert!(matches!(
            decode::<Time>(&good[..len]),
            Err(CodecError::Wire {
                source: WireError::NoHeader { .. },
                ..
            })
        ));
    }
}

#[test]
fn sequence_count_of_many_short_strings_is_bounded_by_the_payload() {
    // A name count of u32::MAX followed by 100 KB of empty strings: the pre-check walks
    // at most payload/4 strings and gives up at the end of the payload.
    let mut bytes = encode(&JointState::default()).unwrap();
    let name_count_at = 4 + 16;
    set_u32(&mut bytes, name_count_at, u32::MAX);
    bytes.truncate(name_count_at + 4);
    for _ in 0..25_000 {
        bytes.extend_from_slice(&0u32.to_le_bytes());
    }
    expect_truncated::<JointState>(&bytes, "name");
}

#[test]
fn trailing_bytes_are_tolerated() {
    // Some middlewares pad the payload to a multiple of 4; extra bytes are not an error.
    let h = Header::new(Time { sec: 3, nanosec: 4 }, "a");
    let mut bytes = encode(&h).unwrap();
    bytes.extend_from_slice(&[0, 0]);
    assert_eq!(decode::<Header>(&bytes).unwrap(), h);
}

#[test]
fn unterminated_string_is_refused_not_truncated() {
    // The `cdr` decoder drops a string's last byte without looking at it, so "abc"
    // written without its NUL would silently decode as "ab". The pre-check refuses it.
    let h = Header::new(Time { sec: 0, nanosec: 0 }, "abc");
    let mut bytes = encode(&h).unwrap();
    assert_eq!(&bytes[16..20], b"abc\0");
    bytes[19] = b'd';
    match decode::<Header>(&bytes) {
        Err(CodecError::Wire {
            source: WireError::UnterminatedString { field, offset },
            ..
        }) => {
            assert_eq!(field, "std_msgs/msg/Header.frame_id");
            assert_eq!(offset, 19);
        }
        other => panic!("expected UnterminatedString, got {other:?}"),
    }
    // Same inside a sequence of strings.
    let js = JointState {
        name: vec!["FFJ1".into(), "FFJ2".into()],
        position: vec![0.0, 0.0],
        ..JointState::default()
    };
    let mut bytes = encode(&js).unwrap();
    let nul = bytes.windows(5).rposition(|w| w == b"FFJ2\0").unwrap() + 4;
    bytes[nul] = b'!';
    match decode::<JointState>(&bytes) {
        Err(CodecError::Wire {
            source: WireError::UnterminatedString { field, offset },
            ..
        }) => {
            assert_eq!(field, "sensor_msgs/msg/JointState.name");
            assert_eq!(offset, nul);
        }
        other => panic!("expected UnterminatedString, got {other:?}"),
    }
}

#[test]
fn zero_length_string_decodes_as_empty() {
    // Writers put length 1 + NUL for ""; a bare length 0 carries no text to lose, so it
    // is accepted as "" (rosbags refuses it; re-encoding gives the canonical form).
    let bytes = [0, 1, 0, 0, 7, 0, 0, 0, 8, 0, 0, 0, 0, 0, 0, 0];
    let h: Header = decode(&bytes).unwrap();
    assert_eq!(h, Header::new(Time { sec: 7, nanosec: 8 }, ""));
    assert_eq!(
        encode(&h).unwrap(),
        [0, 1, 0, 0, 7, 0, 0, 0, 8, 0, 0, 0, 1, 0, 0, 0, 0]
    );
}
