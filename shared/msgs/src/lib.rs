//! ROS 2 wire-compatible message types for the teleoperation system.
//!
//! * Standard types (`builtin_interfaces`, `std_msgs`, `geometry_msgs`, `sensor_msgs`)
//!   mirror their ROS 2 definitions field by field.
//! * Project types (`teleop_msgs`) are defined by the `.msg` files in `shared/msgs/msg/`
//!   so a ROS 2 user can build an interface package from them; a test keeps the Rust
//!   structs and the files in step.
//! * [`encode`] / [`decode`] produce and read CDR little-endian with the 4-byte
//!   encapsulation header, exactly what rmw_zenoh puts on the wire. [`decode`] first
//!   checks every length field against the payload ([`description::check_wire`]), so no
//!   byte string can make it allocate more than the payload's size or panic.
//! * Every type knows its ROS 2 name and its RIHS01 type hash (REP 2011).

pub mod description;
pub mod image_codec;
mod types;

pub use description::{MsgDescription, WireError};
pub use types::*;

use serde::Serialize;
use serde::de::DeserializeOwned;

/// A message that can travel on the bus.
pub trait Message:
    Serialize + DeserializeOwned + Clone + PartialEq + std::fmt::Debug + Send + Sync + 'static
{
    /// ROS 2 type name, e.g. `sensor_msgs/msg/JointState`.
    const TYPE_NAME: &'static str;
    /// RIHS01 type hash as rmw_zenoh writes it in data keys. Checked against
    /// [`MsgDescription::type_hash`] by the tests.
    const TYPE_HASH: &'static str;
    /// Field layout, used for hashing and for the wire pre-check.
    fn description() -> &'static MsgDescription;
}

/// Every message type of this crate that travels as a topic, by description: for tools
/// that meet a type by its name (recorders, replay, bridges).
pub fn topic_types() -> [&'static MsgDescription; 11] {
    [
        PoseStamped::description(),
        JointState::description(),
        OperatorInput::description(),
        FingertipPressures::description(),
        Image::description(),
        CompressedImage::description(),
        JointCommand::description(),
        NodeStatus::description(),
        Header::description(),
        TFMessage::description(),
        Float64MultiArray::description(),
    ]
}

/// The description of the topic type called `type_name` (`sensor_msgs/msg/JointState`).
pub fn description_of(type_name: &str) -> Option<&'static MsgDescription> {
    topic_types().into_iter().find(|d| d.type_name == type_name)
}

/// Errors of [`encode`] and [`decode`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CodecError {
    #[error("{type_name}: malformed CDR: {source}")]
    Wire {
        type_name: &'static str,
        #[source]
        source: WireError,
    },
    #[error("{type_name}: CDR decoding failed: {message}")]
    Decode {
        type_name: &'static str,
        message: String,
    },
    #[error("{type_name}: CDR encoding failed: {message}")]
    Encode {
        type_name: &'static str,
        message: String,
    },
}

/// Serializes `msg` as CDR little-endian with the `00 01 00 00` encapsulation header.
///
/// Strings are written as their UTF-8 bytes plus a terminating NUL, so non-ASCII text is
/// accepted and round-trips (ROS 2 `string` is UTF-8 by convention).
///
/// # Errors
/// [`CodecError::Encode`] if a string or sequence is longer than `u32::MAX`.
pub fn encode<T: Message>(msg: &T) -> Result<Vec<u8>, CodecError> {
    cdr::serialize::<_, _, cdr::CdrLe>(msg, cdr::Infinite).map_err(|e| CodecError::Encode {
        type_name: T::TYPE_NAME,
        message: e.to_string(),
    })
}

/// Deserializes a CDR payload (header included, either byte order).
///
/// # Errors
/// [`CodecError::Wire`] if a length field does not fit the payload or the header is not
/// plain CDR; [`CodecError::Decode`] for anything else the decoder refuses (invalid
/// UTF-8, ...).
pub fn decode<T: Message>(bytes: &[u8]) -> Result<T, CodecError> {
    description::check_wire(T::description(), bytes).map_err(|source| CodecError::Wire {
        type_name: T::TYPE_NAME,
        source,
    })?;
    let limit = cdr::Bounded(bytes.len() as u64);
    cdr::deserialize_from(bytes, limit).map_err(|e| CodecError::Decode {
        type_name: T::TYPE_NAME,
        message: e.to_string(),
    })
}
