//! The QoS a topic's publishers offer, in rosbag2's words (metadata version 9: names,
//! not enum numbers). Every publisher of the project announces reliable (Zenoh's reliable
//! channel, dropped on congestion: rmw_zenoh's RELIABLE + KEEP_LAST), volatile, keep-last with its class's depth (`teleop_bus::keys::qos_string`), with no deadline,
//! lifespan or liveliness lease (ROS 2's "infinite": 2147483647 s 4294967295 ns).

use serde::Serialize;
use teleop_interfaces::TopicSpec;

/// One offered QoS profile, as rosbag2 writes it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QosProfile {
    pub history: &'static str,
    pub depth: usize,
    pub reliability: &'static str,
    pub durability: &'static str,
    pub deadline: QosTime,
    pub lifespan: QosTime,
    pub liveliness: &'static str,
    pub liveliness_lease_duration: QosTime,
    pub avoid_ros_namespace_conventions: bool,
}

/// A QoS duration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct QosTime {
    pub sec: i64,
    pub nsec: u64,
}

/// ROS 2's "infinite" duration in QoS profiles.
const INFINITE: QosTime = QosTime {
    sec: 2_147_483_647,
    nsec: 4_294_967_295,
};

/// The profile the topic's publishers offer.
pub fn qos_profile(spec: &TopicSpec) -> QosProfile {
    QosProfile {
        history: "keep_last",
        depth: spec.qos.depth(),
        reliability: "reliable",
        durability: "volatile",
        deadline: INFINITE,
        lifespan: INFINITE,
        liveliness: "automatic",
        liveliness_lease_duration: INFINITE,
        avoid_ros_namespace_conventions: false,
    }
}

/// The `offered_qos_profiles` text of an MCAP channel's metadata: a YAML list of one
/// profile.
pub fn offered_qos_yaml(spec: &TopicSpec) -> String {
    // Serializing a plain struct of strings and numbers cannot fail.
    serde_yaml::to_string(&[qos_profile(spec)]).unwrap_or_default()
}
