//! Recordings the way rosbag2 writes them, so ROS 2 users open them with the tools they
//! have (`ros2 bag info`, Foxglove, PlotJuggler, `rosbags`, `mcap`):
//!
//! * a bag is a directory holding `metadata.yaml` (rosbag2's format, version 9) and one
//!   or more MCAP files `<name>_<i>.mcap`, a new one when the current file reaches a
//!   size or a duration ([`BagOptions`]);
//! * each MCAP file has the `ros2` profile; a schema per type with encoding `ros2msg`
//!   and the full definition text (dependencies included); a channel per topic with
//!   message encoding `cdr`, the topic's offered QoS (`offered_qos_profiles`) and type
//!   hash (`topic_type_hash`) in its metadata; messages are the CDR bytes as they
//!   travelled, with receive time (`log_time`), the publisher's source timestamp
//!   (`publish_time`) and sequence number;
//! * chunks are compressed (zstd, lz4 or none) and closed at least every
//!   `flush_interval_s`, so a recording cut short by a crash stays readable up to its
//!   last closed chunk ([`read_file`] reads such a file, and [`recover`] rewrites it
//!   whole).
//!
//! [`BagWriter`] is a pure core: it is handed samples and writes them; the recorder
//! (`teleop record`) subscribes and feeds it.

mod error;
mod info;
mod qos;
mod read;
mod writer;

pub use error::BagError;
pub use info::{
    BagReport, CHUNK_GROWTH_ALLOWANCE, FileReport, MAX_CHUNK_RATIO, TopicReport, check_chunk_sizes,
    mcap_files, read_bag, read_bytes, read_file, recover,
};
pub use qos::{offered_qos_yaml, qos_profile};
pub use read::{ChannelInfo, Messages, ReadError, SchemaInfo, StoredMessage, messages};
pub use writer::{BagOptions, BagSummary, BagWriter, Compression, TopicId};

/// The rosbag2 metadata version this crate writes (ROS 2 Jazzy's).
pub const METADATA_VERSION: u32 = 9;
