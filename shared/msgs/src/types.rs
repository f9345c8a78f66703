//! The message structs. Field order and types follow the ROS 2 definitions exactly; the
//! CDR layout depends on it.

use serde::{Deserialize, Serialize};

use crate::Message;
use crate::description::{BaseType as B, Field as F, MsgDescription};

macro_rules! message {
    ($ty:ident, $name:literal, $hash:literal, [$($field:expr),* $(,)?]) => {
        impl Message for $ty {
            const TYPE_NAME: &'static str = $name;
            const TYPE_HASH: &'static str = $hash;
            fn description() -> &'static MsgDescription {
                static D: MsgDescription = MsgDescription {
                    type_name: $name,
                    fields: &[$($field),*],
                };
                &D
            }
        }
    };
}

// ---------------------------------------------------------------- builtin_interfaces

/// `builtin_interfaces/msg/Time`.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}
message!(
    Time,
    "builtin_interfaces/msg/Time",
    "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    [F::new("sec", B::Int32), F::new("nanosec", B::Uint32)]
);

impl Time {
    /// From nanoseconds since the Unix epoch (saturating outside the `i32` seconds range).
    pub fn from_nanos(ns: i64) -> Self {
        let sec = ns.div_euclid(1_000_000_000);
        let nanosec = ns.rem_euclid(1_000_000_000) as u32;
        Self {
            sec: sec.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
            nanosec,
        }
    }
    /// From seconds since the Unix epoch (the controllers' time base), rounded to the
    /// nanosecond, so a time read from a stamp with [`Time::as_secs_f64`] maps back onto
    /// the same stamp. Saturating like [`Time::from_nanos`]; NaN gives the epoch.
    pub fn from_secs_f64(s: f64) -> Self {
        // `as` saturates at the i64 range and maps NaN to 0.
        #[allow(clippy::cast_possible_truncation)]
        Self::from_nanos((s * 1e9).round() as i64)
    }
    /// Nanoseconds since the Unix epoch.
    pub fn as_nanos(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
    /// The current wall-clock time.
    pub fn now() -> Self {
        Self::from_nanos(unix_nanos_now())
    }
    /// Seconds as `f64`.
    pub fn as_secs_f64(&self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }
}

/// Wall-clock nanoseconds since the Unix epoch (0 if the clock is before 1970).
pub fn unix_nanos_now() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
        .unwrap_or(0)
}

// ---------------------------------------------------------------- std_msgs

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}
message!(
    Header,
    "std_msgs/msg/Header",
    "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    [
        F::new("stamp", B::Nested(Time::description)),
        F::new("frame_id", B::String)
    ]
);

impl Header {
    pub fn new(stamp: Time, frame_id: impl Into<String>) -> Self {
        Self {
            stamp,
            frame_id: frame_id.into(),
        }
    }
}

/// `std_msgs/msg/MultiArrayDimension`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    pub label: String,
    pub size: u32,
    pub stride: u32,
}
message!(
    MultiArrayDimension,
    "std_msgs/msg/MultiArrayDimension",
    "RIHS01_5e773a60a4c7fc8a54985f307c7837aa2994252a126c301957a24e31282c9cbe",
    [
        F::new("label", B::String),
        F::new("size", B::Uint32),
        F::new("stride", B::Uint32)
    ]
);

/// `std_msgs/msg/MultiArrayLayout`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    pub dim: Vec<MultiArrayDimension>,
    pub data_offset: u32,
}
message!(
    MultiArrayLayout,
    "std_msgs/msg/MultiArrayLayout",
    "RIHS01_4c66e6f78e740ac103a94cf63259f968e48c617e7699e829b63c21a5cb50dac6",
    [
        F::seq("dim", B::Nested(MultiArrayDimension::description)),
        F::new("data_offset", B::Uint32)
    ]
);

/// `std_msgs/msg/Float64MultiArray`: what ros2_control's forward command controllers
/// take on their `commands` topic (one value per joint of the controller, in its order;
/// the layout is left empty).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Float64MultiArray {
    pub layout: MultiArrayLayout,
    pub data: Vec<f64>,
}
message!(
    Float64MultiArray,
    "std_msgs/msg/Float64MultiArray",
    "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
    [
        F::new("layout", B::Nested(MultiArrayLayout::description)),
        F::seq("data", B::Float64)
    ]
);

impl Float64MultiArray {
    /// The values with an empty layout (a flat array), as ros2_control's forward
    /// command controllers take them.
    pub fn flat(data: Vec<f64>) -> Self {
        Self {
            layout: MultiArrayLayout::default(),
            data,
        }
    }
}

// ---------------------------------------------------------------- geometry_msgs

/// `geometry_msgs/msg/Point` (metres).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}
message!(
    Point,
    "geometry_msgs/msg/Point",
    "RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881",
    [
        F::new("x", B::Float64),
        F::new("y", B::Float64),
        F::new("z", B::Float64)
    ]
);

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}
message!(
    Vector3,
    "geometry_msgs/msg/Vector3",
    "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
    [
        F::new("x", B::Float64),
        F::new("y", B::Float64),
        F::new("z", B::Float64)
    ]
);

/// `geometry_msgs/msg/Quaternion` (x, y, z, w; identity is w = 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}
message!(
    Quaternion,
    "geometry_msgs/msg/Quaternion",
    "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684",
    [
        F::new("x", B::Float64),
        F::new("y", B::Float64),
        F::new("z", B::Float64),
        F::new("w", B::Float64)
    ]
);

impl Default for Quaternion {
    /// The identity rotation, as ROS 2's default value `w = 1`.
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: Point,
    pub orientation: Quaternion,
}
message!(
    Pose,
    "geometry_msgs/msg/Pose",
    "RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    [
        F::new("position", B::Nested(Point::description)),
        F::new("orientation", B::Nested(Quaternion::description))
    ]
);

impl Pose {
    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        let p = &self.position;
        let q = &self.orientation;
        [p.x, p.y, p.z, q.x, q.y, q.z, q.w]
            .iter()
            .all(|v| v.is_finite())
    }
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}
message!(
    PoseStamped,
    "geometry_msgs/msg/PoseStamped",
    "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("pose", B::Nested(Pose::description))
    ]
);

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}
message!(
    Transform,
    "geometry_msgs/msg/Transform",
    "RIHS01_beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc",
    [
        F::new("translation", B::Nested(Vector3::description)),
        F::new("rotation", B::Nested(Quaternion::description))
    ]
);

/// `geometry_msgs/msg/TransformStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}
message!(
    TransformStamped,
    "geometry_msgs/msg/TransformStamped",
    "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("child_frame_id", B::String),
        F::new("transform", B::Nested(Transform::description))
    ]
);

// ---------------------------------------------------------------- tf2_msgs

/// `tf2_msgs/msg/TFMessage`: a list of stamped transforms (what `/tf` carries). The
/// robot-site simulator's ground-truth object poses travel as one: each object a
/// transform from the world frame to a child frame named after it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TFMessage {
    pub transforms: Vec<TransformStamped>,
}
message!(
    TFMessage,
    "tf2_msgs/msg/TFMessage",
    "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    [F::seq(
        "transforms",
        B::Nested(TransformStamped::description)
    )]
);

// ---------------------------------------------------------------- sensor_msgs

/// `sensor_msgs/msg/JointState`: radians, rad/s, N·m, in the order of `name`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}
message!(
    JointState,
    "sensor_msgs/msg/JointState",
    "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    [
        F::new("header", B::Nested(Header::description)),
        F::seq("name", B::String),
        F::seq("position", B::Float64),
        F::seq("velocity", B::Float64),
        F::seq("effort", B::Float64)
    ]
);

impl JointState {
    /// Positions only (no velocities or efforts), `name[i]` for `position[i]`.
    #[must_use]
    pub fn positions(header: Header, names: &[&str], position: &[f64]) -> Self {
        Self {
            header,
            name: names.iter().map(|s| (*s).to_owned()).collect(),
            position: position.to_vec(),
            velocity: Vec::new(),
            effort: Vec::new(),
        }
    }
}

/// `sensor_msgs/msg/Image`. Depth is `16UC1` in millimetres (0 = no return) or `32FC1`
/// in metres; colour is `rgb8`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Image {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: u8,
    pub step: u32,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}
message!(
    Image,
    "sensor_msgs/msg/Image",
    "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("height", B::Uint32),
        F::new("width", B::Uint32),
        F::new("encoding", B::String),
        F::new("is_bigendian", B::Uint8),
        F::new("step", B::Uint32),
        F::seq("data", B::Uint8)
    ]
);

/// Encodings of [`Image`] the project produces.
pub mod encodings {
    pub const DEPTH_16UC1: &str = "16UC1";
    pub const DEPTH_32FC1: &str = "32FC1";
    pub const RGB8: &str = "rgb8";
    pub const MONO8: &str = "mono8";

    /// Bytes per pixel of a known encoding.
    pub fn bytes_per_pixel(encoding: &str) -> Option<u32> {
        match encoding {
            DEPTH_16UC1 => Some(2),
            DEPTH_32FC1 => Some(4),
            RGB8 => Some(3),
            MONO8 => Some(1),
            _ => None,
        }
    }
}

impl Image {
    /// A little-endian `16UC1` depth image in millimetres.
    pub fn depth_mm(header: Header, width: u32, height: u32, depth_mm: &[u16]) -> Self {
        let mut data = Vec::with_capacity(depth_mm.len() * 2);
        for d in depth_mm {
            data.extend_from_slice(&d.to_le_bytes());
        }
        Self {
            header,
            height,
            width,
            encoding: encodings::DEPTH_16UC1.into(),
            is_bigendian: 0,
            step: width * 2,
            data,
        }
    }

    /// Checks that the encoding is known and `step`/`data` match the size.
    ///
    /// # Errors
    /// A text naming the inconsistent field.
    pub fn check_layout(&self) -> Result<(), String> {
        let bpp = encodings::bytes_per_pixel(&self.encoding)
            .ok_or_else(|| format!("unknown image encoding `{}`", self.encoding))?;
        let min_step = u64::from(self.width) * u64::from(bpp);
        if u64::from(self.step) < min_step {
            return Err(format!(
                "step {} is smaller than width {} x {} bytes",
                self.step, self.width, bpp
            ));
        }
        let expected = u64::from(self.step) * u64::from(self.height);
        if self.data.len() as u64 != expected {
            return Err(format!(
                "data has {} bytes, step x height = {expected}",
                self.data.len()
            ));
        }
        Ok(())
    }

    /// Depth in millimetres at (u, v) of a `16UC1` image.
    pub fn depth_mm_at(&self, u: u32, v: u32) -> Option<u16> {
        if self.encoding != encodings::DEPTH_16UC1 || u >= self.width || v >= self.height {
            return None;
        }
        let i = (v as usize) * (self.step as usize) + (u as usize) * 2;
        let b = self.data.get(i..i + 2)?;
        Some(if self.is_bigendian == 0 {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            u16::from_be_bytes([b[0], b[1]])
        })
    }
}

/// `sensor_msgs/msg/CompressedImage`: an image in a file format, as ROS's
/// `image_transport` "compressed" transport publishes it on `<image topic>/compressed`.
/// `format` is `"jpeg"` or `"png"` (the transport also writes e.g. `"rgb8; jpeg
/// compressed bgr8"`; [`CompressedImage::codec`] reads either form).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    pub header: Header,
    pub format: String,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}
message!(
    CompressedImage,
    "sensor_msgs/msg/CompressedImage",
    "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("format", B::String),
        F::seq("data", B::Uint8)
    ]
);

impl CompressedImage {
    /// The file format named by `format`: its last word (`"rgb8; jpeg compressed bgr8"`
    /// -> `jpeg`, as image_transport writes it) or the whole of it (`"jpeg"`), lower case.
    pub fn codec(&self) -> Option<&'static str> {
        let f = self.format.to_ascii_lowercase();
        ["jpeg", "png"].into_iter().find(|c| {
            f.split(|ch: char| ch == ';' || ch.is_whitespace())
                .any(|w| w == *c)
        })
    }
}

// ---------------------------------------------------------------- teleop_msgs

/// `teleop_msgs/msg/OperatorInput`: the operator's pedals and switches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OperatorInput {
    pub header: Header,
    /// Right foot pedal: while pressed (and `enable` held) the PR2 arm follows the
    /// operator's relative wrist motion.
    pub clutch: bool,
    /// Deadman / enable switch: nothing on the remote site moves without it.
    pub enable: bool,
    /// Left foot pedal: stops the camera arm (UR5).
    pub camera_stop: bool,
    /// Scale applied to the operator's relative wrist translation (thesis: 1/3 for fine
    /// tasks). Valid range (0, 1].
    pub motion_scale: f64,
}
message!(
    OperatorInput,
    "teleop_msgs/msg/OperatorInput",
    "RIHS01_a9311ceb88718e6f27c808f700d1bbad5ec0ccd3f25fb90f555d462d620611ab",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("clutch", B::Bool),
        F::new("enable", B::Bool),
        F::new("camera_stop", B::Bool),
        F::new("motion_scale", B::Float64)
    ]
);

impl Default for OperatorInput {
    /// Everything released: nothing moves.
    fn default() -> Self {
        Self {
            header: Header::default(),
            clutch: false,
            enable: false,
            camera_stop: false,
            motion_scale: 1.0,
        }
    }
}

/// `teleop_msgs/msg/FingertipPressures`: one reading per fingertip sensor (BioTac-like),
/// as normal contact force in newtons.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FingertipPressures {
    pub header: Header,
    pub ff: f64,
    pub mf: f64,
    pub rf: f64,
    pub lf: f64,
    pub th: f64,
}
message!(
    FingertipPressures,
    "teleop_msgs/msg/FingertipPressures",
    "RIHS01_6e9f1f372dadcc239ffe9dc82437470396066bcf8e08e0cc6e9e2b98f5f399fc",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("ff", B::Float64),
        F::new("mf", B::Float64),
        F::new("rf", B::Float64),
        F::new("lf", B::Float64),
        F::new("th", B::Float64)
    ]
);

impl FingertipPressures {
    /// The five values in the order ff, mf, rf, lf, th.
    pub fn values(&self) -> [f64; 5] {
        [self.ff, self.mf, self.rf, self.lf, self.th]
    }
}

/// `teleop_msgs/msg/JointCommand`: a joint-level command for a robot's own real-time
/// loop (effort, position, or impedance evaluated by the hardware), by joint name; see
/// `msg/JointCommand.msg`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointCommand {
    pub header: Header,
    /// `"effort"`, `"position"` or `"impedance"`.
    pub mode: String,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
    pub stiffness: Vec<f64>,
    pub damping: Vec<f64>,
    pub max_effort: Vec<f64>,
}
message!(
    JointCommand,
    "teleop_msgs/msg/JointCommand",
    "RIHS01_08a9321af0698f45d76f0081ed713276db4c5566cbe79d04059b25536e1004d7",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("mode", B::String),
        F::seq("name", B::String),
        F::seq("position", B::Float64),
        F::seq("velocity", B::Float64),
        F::seq("effort", B::Float64),
        F::seq("stiffness", B::Float64),
        F::seq("damping", B::Float64),
        F::seq("max_effort", B::Float64)
    ]
);

/// Lifecycle states of a node, as published in [`NodeStatus::lifecycle_state`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[repr(u8)]
pub enum Lifecycle {
    /// Started, not yet configured.
    Unconfigured = 0,
    /// Configured, outputs held: a robot under this node does not move.
    Inactive = 1,
    /// Running: a robot under this node may move.
    Active = 2,
    /// Stopped on an error; needs operator action.
    Fault = 3,
    /// Shutting down.
    Finalized = 4,
}

impl Lifecycle {
    pub fn from_u8(v: u8) -> Option<Self> {
        Some(match v {
            0 => Self::Unconfigured,
            1 => Self::Inactive,
            2 => Self::Active,
            3 => Self::Fault,
            4 => Self::Finalized,
            _ => return None,
        })
    }
    pub fn name(self) -> &'static str {
        match self {
            Self::Unconfigured => "unconfigured",
            Self::Inactive => "inactive",
            Self::Active => "active",
            Self::Fault => "fault",
            Self::Finalized => "finalized",
        }
    }
}

/// `teleop_msgs/msg/NodeStatus`: health of one node, published at ~1 Hz.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NodeStatus {
    pub header: Header,
    pub node_name: String,
    /// One of the [`Lifecycle`] values.
    pub lifecycle_state: u8,
    /// Names of the counters, e.g. `wrist_pose.rejected_stale`.
    pub counter_names: Vec<String>,
    /// Values of the counters, same order as `counter_names`.
    pub counter_values: Vec<u64>,
    /// Last error text, empty if none.
    pub last_error: String,
}
message!(
    NodeStatus,
    "teleop_msgs/msg/NodeStatus",
    "RIHS01_e9ab36cd53de9b842bd28237da566c14b35f9e93152d050477c46abdee6fd004",
    [
        F::new("header", B::Nested(Header::description)),
        F::new("node_name", B::String),
        F::new("lifecycle_state", B::Uint8),
        F::seq("counter_names", B::String),
        F::seq("counter_values", B::Uint64),
        F::new("last_error", B::String)
    ]
);

impl NodeStatus {
    pub fn lifecycle(&self) -> Option<Lifecycle> {
        Lifecycle::from_u8(self.lifecycle_state)
    }
    /// Value of the counter `name`, if present.
    pub fn counter(&self, name: &str) -> Option<u64> {
        self.counter_names
            .iter()
            .position(|n| n == name)
            .and_then(|i| self.counter_values.get(i).copied())
    }
}

/// Every message type of the project, for tools and tests that iterate over them.
pub fn all_descriptions() -> Vec<(&'static MsgDescription, &'static str)> {
    vec![
        (Time::description(), Time::TYPE_HASH),
        (Header::description(), Header::TYPE_HASH),
        (
            MultiArrayDimension::description(),
            MultiArrayDimension::TYPE_HASH,
        ),
        (MultiArrayLayout::description(), MultiArrayLayout::TYPE_HASH),
        (
            Float64MultiArray::description(),
            Float64MultiArray::TYPE_HASH,
        ),
        (Point::description(), Point::TYPE_HASH),
        (Vector3::description(), Vector3::TYPE_HASH),
        (Quaternion::description(), Quaternion::TYPE_HASH),
        (Pose::description(), Pose::TYPE_HASH),
        (PoseStamped::description(), PoseStamped::TYPE_HASH),
        (Transform::description(), Transform::TYPE_HASH),
        (TransformStamped::description(), TransformStamped::TYPE_HASH),
        (TFMessage::description(), TFMessage::TYPE_HASH),
        (JointState::description(), JointState::TYPE_HASH),
        (Image::description(), Image::TYPE_HASH),
        (CompressedImage::description(), CompressedImage::TYPE_HASH),
        (OperatorInput::description(), OperatorInput::TYPE_HASH),
        (
            FingertipPressures::description(),
            FingertipPressures::TYPE_HASH,
        ),
        (NodeStatus::description(), NodeStatus::TYPE_HASH),
        (JointCommand::description(), JointCommand::TYPE_HASH),
    ]
}
