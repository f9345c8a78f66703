//! Proptest strategies shared by the integration tests.
#![allow(dead_code)]

use proptest::collection::vec;
use proptest::prelude::*;
use teleop_msgs::{
    FingertipPressures, Header, Image, JointState, NodeStatus, OperatorInput, Point, Pose,
    PoseStamped, Quaternion, Time, Transform, TransformStamped, Vector3,
};

/// Which floats a strategy produces.
#[derive(Debug, Clone, Copy)]
pub enum Floats {
    /// Finite only (normal, subnormal, ±0): `PartialEq` works.
    Finite,
    /// Anything, including ±inf and NaN: compare bitwise.
    Any,
}

pub fn f64s(k: Floats) -> BoxedStrategy<f64> {
    use proptest::num::f64 as f;
    match k {
        Floats::Finite => (f::POSITIVE | f::NEGATIVE | f::NORMAL | f::SUBNORMAL | f::ZERO).boxed(),
        Floats::Any => f::ANY.boxed(),
    }
}

/// Printable ASCII (ROS 2 `string` content as the project uses it).
pub fn ascii() -> BoxedStrategy<String> {
    "[ -~]{0,24}".boxed()
}

pub fn time() -> impl Strategy<Value = Time> {
    (any::<i32>(), any::<u32>()).prop_map(|(sec, nanosec)| Time { sec, nanosec })
}

pub fn header() -> impl Strategy<Value = Header> {
    (time(), ascii()).prop_map(|(stamp, frame_id)| Header { stamp, frame_id })
}

pub fn point(k: Floats) -> impl Strategy<Value = Point> {
    (f64s(k), f64s(k), f64s(k)).prop_map(|(x, y, z)| Point { x, y, z })
}

pub fn vector3(k: Floats) -> impl Strategy<Value = Vector3> {
    (f64s(k), f64s(k), f64s(k)).prop_map(|(x, y, z)| Vector3 { x, y, z })
}

pub fn quaternion(k: Floats) -> impl Strategy<Value = Quaternion> {
    (f64s(k), f64s(k), f64s(k), f64s(k)).prop_map(|(x, y, z, w)| Quaternion { x, y, z, w })
}

pub fn pose(k: Floats) -> impl Strategy<Value = Pose> {
    (point(k), quaternion(k)).prop_map(|(position, orientation)| Pose {
        position,
        orientation,
    })
}

pub fn pose_stamped(k: Floats) -> impl Strategy<Value = PoseStamped> {
    (header(), pose(k)).prop_map(|(header, pose)| PoseStamped { header, pose })
}

pub fn transform(k: Floats) -> impl Strategy<Value = Transform> {
    (vector3(k), quaternion(k)).prop_map(|(translation, rotation)| Transform {
        translation,
        rotation,
    })
}

pub fn transform_stamped(k: Floats) -> impl Strategy<Value = TransformStamped> {
    (header(), ascii(), transform(k)).prop_map(|(header, child_frame_id, transform)| {
        TransformStamped {
            header,
            child_frame_id,
            transform,
        }
    })
}

pub fn joint_state(k: Floats) -> impl Strategy<Value = JointState> {
    (
        header(),
        vec(ascii(), 0..30),
        vec(f64s(k), 0..30),
        vec(f64s(k), 0..30),
        vec(f64s(k), 0..30),
    )
        .prop_map(|(header, name, position, velocity, effort)| JointState {
            header,
            name,
            position,
            velocity,
            effort,
        })
}

pub fn image() -> impl Strategy<Value = Image> {
    (
        header(),
        any::<u32>(),
        any::<u32>(),
        ascii(),
        any::<u8>(),
        any::<u32>(),
        vec(any::<u8>(), 0..600),
    )
        .prop_map(
            |(header, height, width, encoding, is_bigendian, step, data)| Image {
                header,
                height,
                width,
                encoding,
                is_bigendian,
                step,
                data,
            },
        )
}

pub fn operator_input(k: Floats) -> impl Strategy<Value = OperatorInput> {
    (
        header(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        f64s(k),
    )
        .prop_map(
            |(header, clutch, enable, camera_stop, motion_scale)| OperatorInput {
                header,
                clutch,
                enable,
                camera_stop,
                motion_scale,
            },
        )
}

pub fn fingertip_pressures(k: Floats) -> impl Strategy<Value = FingertipPressures> {
    (header(), f64s(k), f64s(k), f64s(k), f64s(k), f64s(k)).prop_map(
        |(header, ff, mf, rf, lf, th)| FingertipPressures {
            header,
            ff,
            mf,
            rf,
            lf,
            th,
        },
    )
}

pub fn node_status() -> impl Strategy<Value = NodeStatus> {
    (
        header(),
        ascii(),
        any::<u8>(),
        vec(ascii(), 0..12),
        vec(any::<u64>(), 0..12),
        ascii(),
    )
        .prop_map(
            |(header, node_name, lifecycle_state, counter_names, counter_values, last_error)| {
                NodeStatus {
                    header,
                    node_name,
                    lifecycle_state,
                    counter_names,
                    counter_values,
                    last_error,
                }
            },
        )
}
