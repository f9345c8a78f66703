//! Encode -> decode round trips for every message type, and hand-written golden bytes.
#![allow(clippy::unwrap_used)]

mod common;

use common::*;
use proptest::collection::vec;
use proptest::prelude::*;
use teleop_msgs::{
    CodecError, FingertipPressures, Header, Image, JointState, Message, OperatorInput, Point, Pose,
    PoseStamped, Quaternion, Time, decode, encode,
};

// ------------------------------------------------------------------ checks

/// `decode(encode(m)) == m`, the header is CDR LE, and re-encoding gives the same bytes.
fn exact<T: Message>(msg: &T) -> Result<(), TestCaseError> {
    let bytes = encode(msg).unwrap();
    prop_assert_eq!(&bytes[..4], &[0u8, 1, 0, 0][..]);
    let back: T = decode(&bytes).unwrap();
    prop_assert_eq!(&back, msg);
    prop_assert_eq!(encode(&back).unwrap(), bytes);
    Ok(())
}

/// With NaN `PartialEq` fails, so compare bitwise: the encoding is a deterministic
/// function of the bits of every field, so equal re-encodings mean equal bits.
fn bitwise<T: Message>(msg: &T) -> Result<(), TestCaseError> {
    let bytes = encode(msg).unwrap();
    let back: T = decode(&bytes).unwrap();
    prop_assert_eq!(encode(&back).unwrap(), bytes);
    Ok(())
}

macro_rules! roundtrips {
    ($($exact:ident / $bits:ident : $strat:expr ;)*) => {
        proptest! {
            $(
                #[test]
                fn $exact(msg in $strat(Floats::Finite)) {
                    exact(&msg)?;
                }
                #[test]
                fn $bits(msg in $strat(Floats::Any)) {
                    bitwise(&msg)?;
                }
            )*
        }
    };
}

roundtrips! {
    time_exact / time_bits: |_k| time();
    header_exact / header_bits: |_k| header();
    point_exact / point_bits: point;
    vector3_exact / vector3_bits: vector3;
    quaternion_exact / quaternion_bits: quaternion;
    pose_exact / pose_bits: pose;
    pose_stamped_exact / pose_stamped_bits: pose_stamped;
    transform_exact / transform_bits: transform;
    transform_stamped_exact / transform_stamped_bits: transform_stamped;
    joint_state_exact / joint_state_bits: joint_state;
    image_exact / image_bits: |_k| image();
    operator_input_exact / operator_input_bits: operator_input;
    fingertip_pressures_exact / fingertip_pressures_bits: fingertip_pressures;
    node_status_exact / node_status_bits: |_k| node_status();
}

proptest! {
    /// The `cdr` crate writes strings as their UTF-8 bytes plus a NUL, so non-ASCII text
    /// round-trips (ROS 2 `string` is UTF-8 by convention).
    #[test]
    fn unicode_strings_roundtrip(frame in "\\PC{0,16}", names in vec("\\PC{0,8}", 0..5)) {
        let msg = JointState {
            header: Header::new(Time::default(), frame.clone()),
            position: vec![0.0; names.len()],
            name: names,
            ..JointState::default()
        };
        exact(&msg)?;
        let bytes = encode(&msg).unwrap();
        // Length field of frame_id = UTF-8 bytes + NUL.
        prop_assert_eq!(
            u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize,
            frame.len() + 1
        );
    }
}

// ------------------------------------------------------------------ special floats

const SPECIAL: [u64; 9] = [
    0x7ff8_0000_0000_0000, // quiet NaN
    0xfff8_0000_0000_0000, // negative quiet NaN
    0x7ff8_dead_beef_0001, // quiet NaN with payload
    0x7ff0_0000_0000_0001, // signalling NaN
    0x7ff0_0000_0000_0000, // +inf
    0xfff0_0000_0000_0000, // -inf
    0x8000_0000_0000_0000, // -0.0
    0x0000_0000_0000_0001, // smallest subnormal
    0x7fef_ffff_ffff_ffff, // f64::MAX
];

#[test]
fn nan_and_infinities_survive_bit_for_bit() {
    for bits in SPECIAL {
        let v = f64::from_bits(bits);

        let p = Point { x: v, y: 1.0, z: v };
        let back: Point = decode(&encode(&p).unwrap()).unwrap();
        assert_eq!(back.x.to_bits(), bits, "Point.x {bits:#018x}");
        assert_eq!(back.z.to_bits(), bits, "Point.z {bits:#018x}");
        assert_eq!(back.y, 1.0);
        assert_eq!(back.x.is_nan(), v.is_nan());

        let js = JointState {
            name: vec!["a".into(), "b".into()],
            position: vec![v, 0.5],
            velocity: vec![v],
            effort: vec![],
            ..JointState::default()
        };
        let back: JointState = decode(&encode(&js).unwrap()).unwrap();
        assert_eq!(back.position[0].to_bits(), bits);
        assert_eq!(back.position[1], 0.5);
        assert_eq!(back.velocity[0].to_bits(), bits);
        assert!(back.effort.is_empty());

        let oi = OperatorInput {
            motion_scale: v,
            enable: true,
            ..OperatorInput::default()
        };
        let back: OperatorInput = decode(&encode(&oi).unwrap()).unwrap();
        assert_eq!(back.motion_scale.to_bits(), bits);
        assert!(back.enable && !back.clutch);

        let fp = FingertipPressures {
            th: v,
            ..FingertipPressures::default()
        };
        let back: FingertipPressures = decode(&encode(&fp).unwrap()).unwrap();
        assert_eq!(back.th.to_bits(), bits);
        assert_eq!(back.ff, 0.0);
    }
}

#[test]
fn nan_makes_partial_eq_fail_but_bytes_match() {
    let p = Point {
        x: f64::NAN,
        y: 0.0,
        z: 0.0,
    };
    let bytes = encode(&p).unwrap();
    let back: Point = decode(&bytes).unwrap();
    assert_ne!(back, p, "NaN != NaN: equality tests must not use NaN");
    assert!(back.x.is_nan());
    assert_eq!(encode(&back).unwrap(), bytes);
}

// ------------------------------------------------------------------ strings

#[test]
fn non_ascii_strings_encode_as_utf8() {
    // The brief assumed the `cdr` crate refuses non-ASCII; cdr 0.2.4 writes the UTF-8
    // bytes unchanged (and rosbags reads them as UTF-8). Pin that behaviour.
    let h = Header::new(Time { sec: 0, nanosec: 0 }, "größe🤖");
    let bytes = encode(&h).unwrap();
    let mut expected = vec![0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    expected.extend_from_slice(&(("größe🤖".len() + 1) as u32).to_le_bytes());
    expected.extend_from_slice("größe🤖".as_bytes());
    expected.push(0);
    assert_eq!(bytes, expected);
    assert_eq!(decode::<Header>(&bytes).unwrap(), h);
}

#[test]
fn invalid_utf8_is_a_decode_error_not_a_panic() {
    let h = Header::new(Time::default(), "abc");
    let mut bytes = encode(&h).unwrap();
    // "abc\0" starts at 4 + 12 = 16.
    assert_eq!(&bytes[16..20], b"abc\0");
    bytes[17] = 0xff;
    match decode::<Header>(&bytes) {
        Err(CodecError::Decode { type_name, message }) => {
            assert_eq!(type_name, "std_msgs/msg/Header");
            assert!(message.contains("utf-8"), "{message}");
        }
        other => panic!("expected a Decode error, got {other:?}"),
    }
}

#[test]
fn empty_strings_and_sequences() {
    let js = JointState::default();
    let bytes = encode(&js).unwrap();
    assert_eq!(
        bytes,
        [
            0, 1, 0, 0, // encapsulation CDR_LE
            0, 0, 0, 0, 0, 0, 0, 0, // stamp
            1, 0, 0, 0, 0, // frame_id "" = length 1 + NUL
            0, 0, 0, // padding to 4
            0, 0, 0, 0, // name
            0, 0, 0, 0, // position (no padding for the absent f64)
            0, 0, 0, 0, // velocity
            0, 0, 0, 0, // effort
        ]
    );
    assert_eq!(decode::<JointState>(&bytes).unwrap(), js);
}

// ------------------------------------------------------------------ golden bytes

#[test]
fn golden_time() {
    let t = Time {
        sec: -2,
        nanosec: 500_000_000,
    };
    let expected = [
        0x00, 0x01, 0x00, 0x00, // CDR_LE, options 0
        0xfe, 0xff, 0xff, 0xff, // sec = -2
        0x00, 0x65, 0xcd, 0x1d, // nanosec = 500_000_000 = 0x1dcd6500
    ];
    assert_eq!(encode(&t).unwrap(), expected);
    assert_eq!(decode::<Time>(&expected).unwrap(), t);
}

#[test]
fn golden_time_big_endian_decodes() {
    let be = [
        0x00, 0x00, 0x00, 0x00, // CDR_BE
        0xff, 0xff, 0xff, 0xfe, // sec = -2
        0x1d, 0xcd, 0x65, 0x00, // nanosec
    ];
    assert_eq!(
        decode::<Time>(&be).unwrap(),
        Time {
            sec: -2,
            nanosec: 500_000_000
        }
    );
}

/// Offsets in the comments are relative to the first byte after the 4-byte header,
/// which is where CDR alignment is counted from.
const GOLDEN_JOINT_STATE: [u8; 68] = [
    0x00, 0x01, 0x00, 0x00, // header: CDR_LE
    0x01, 0x00, 0x00, 0x00, // 0: stamp.sec = 1
    0x02, 0x00, 0x00, 0x00, // 4: stamp.nanosec = 2
    0x02, 0x00, 0x00, 0x00, // 8: frame_id length 2
    b'h', 0x00, // 12: "h\0"
    0x00, 0x00, // 14: pad to 4
    0x01, 0x00, 0x00, 0x00, // 16: name: 1 element
    0x05, 0x00, 0x00, 0x00, // 20: name[0] length 5
    b'a', b'b', b'c', b'd', 0x00, // 24: "abcd\0"
    0x00, 0x00, 0x00, // 29: pad to 4
    0x01, 0x00, 0x00, 0x00, // 32: position: 1 element
    0x00, 0x00, 0x00, 0x00, // 36: pad to 8 (would be 0 if counted from the buffer start)
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf0, 0x3f, // 40: 1.0
    0x00, 0x00, 0x00, 0x00, // 48: velocity: empty (no alignment for no element)
    0x01, 0x00, 0x00, 0x00, // 52: effort: 1 element
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xe0, 0xbf, // 56: -0.5
];

fn golden_joint_state_msg() -> JointState {
    JointState {
        header: Header::new(Time { sec: 1, nanosec: 2 }, "h"),
        name: vec!["abcd".into()],
        position: vec![1.0],
        velocity: vec![],
        effort: vec![-0.5],
    }
}

#[test]
fn golden_joint_state() {
    let js = golden_joint_state_msg();
    assert_eq!(encode(&js).unwrap(), GOLDEN_JOINT_STATE);
    assert_eq!(decode::<JointState>(&GOLDEN_JOINT_STATE).unwrap(), js);
}

#[test]
fn padding_bytes_are_ignored_on_decode() {
    let mut bytes = GOLDEN_JOINT_STATE;
    for at in [18, 19, 33, 34, 35, 40, 41, 42, 43] {
        bytes[at] = 0xaa;
    }
    assert_eq!(
        decode::<JointState>(&bytes).unwrap(),
        golden_joint_state_msg()
    );
}

#[test]
fn golden_pose_stamped() {
    let ps = PoseStamped {
        header: Header::new(
            Time {
                sec: 10,
                nanosec: 20,
            },
            "world",
        ),
        pose: Pose {
            position: Point {
                x: 1.0,
                y: 2.0,
                z: -3.0,
            },
            orientation: Quaternion::default(),
        },
    };
    #[rustfmt::skip]
    let expected: [u8; 84] = [
        0x00, 0x01, 0x00, 0x00, // header: CDR_LE
        0x0a, 0x00, 0x00, 0x00, // 0: stamp.sec = 10
        0x14, 0x00, 0x00, 0x00, // 4: stamp.nanosec = 20
        0x06, 0x00, 0x00, 0x00, // 8: frame_id length 6
        b'w', b'o', b'r', b'l', b'd', 0x00, // 12: "world\0"
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // 18: pad to 8 (2 bytes if counted from the buffer start)
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf0, 0x3f, // 24: position.x = 1.0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x40, // 32: position.y = 2.0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x08, 0xc0, // 40: position.z = -3.0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // 48: orientation.x = 0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // 56: orientation.y = 0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // 64: orientation.z = 0
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf0, 0x3f, // 72: orientation.w = 1.0
    ];
    assert_eq!(encode(&ps).unwrap(), expected);
    assert_eq!(decode::<PoseStamped>(&expected).unwrap(), ps);
}

#[test]
fn golden_image_data_is_a_plain_byte_sequence() {
    let img = Image {
        header: Header::default(),
        height: 1,
        width: 3,
        encoding: "mono8".into(),
        is_bigendian: 0,
        step: 3,
        data: vec![0x0a, 0x0b, 0x0c],
    };
    #[rustfmt::skip]
    let expected: [u8; 51] = [
        0x00, 0x01, 0x00, 0x00, // header: CDR_LE
        0, 0, 0, 0, 0, 0, 0, 0, // 0: stamp
        0x01, 0x00, 0x00, 0x00, 0x00, // 8: frame_id ""
        0x00, 0x00, 0x00, // 13: pad to 4
        0x01, 0x00, 0x00, 0x00, // 16: height
        0x03, 0x00, 0x00, 0x00, // 20: width
        0x06, 0x00, 0x00, 0x00, b'm', b'o', b'n', b'o', b'8', 0x00, // 24: encoding
        0x00, // 34: is_bigendian
        0x00, // 35: pad to 4
        0x03, 0x00, 0x00, 0x00, // 36: step
        0x03, 0x00, 0x00, 0x00, 0x0a, 0x0b, 0x0c, // 40: data
    ];
    assert_eq!(encode(&img).unwrap(), expected);
    assert_eq!(decode::<Image>(&expected).unwrap(), img);
}
