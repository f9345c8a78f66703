//! Key expressions in rmw_zenoh's formats.
//!
//! * Data: `<domain>/<topic>/<dds type name>/<type hash>`, topic without leading or
//!   trailing `/`, inner slashes kept.
//! * Liveliness (graph): `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/
//!   <namespace>/<node name>[/<topic>/<type>/<hash>/<qos>]`, where `/` inside names is
//!   written `%` and an empty namespace or enclave is `%`.

use teleop_msgs::Message;

/// Prefix of every liveliness token of the ROS 2 graph.
pub const LIVELINESS_PREFIX: &str = "@ros2_lv";

/// Strips leading and trailing slashes from a topic name.
pub fn normalize_topic(topic: &str) -> &str {
    topic.trim_matches('/')
}

/// `<domain>/<topic>/<type>/<hash>` for message type `T`.
pub fn data_key<T: Message>(domain_id: u32, topic: &str) -> String {
    data_key_raw(
        domain_id,
        topic,
        &T::description().dds_type_name(),
        T::TYPE_HASH,
    )
}

/// [`data_key`] from explicit type name and hash.
pub fn data_key_raw(domain_id: u32, topic: &str, dds_type: &str, hash: &str) -> String {
    format!("{domain_id}/{}/{dds_type}/{hash}", normalize_topic(topic))
}

/// Writes `/` as `%`, as rmw_zenoh does inside liveliness tokens; empty becomes `%`.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// Inverse of [`mangle`].
pub fn demangle(name: &str) -> String {
    if name == "%" {
        String::new()
    } else {
        name.replace('%', "/")
    }
}

/// rmw_zenoh's default history depth: a token leaves the depth out when it is this.
pub const RMW_ZENOH_DEFAULT_DEPTH: usize = 42;

/// QoS field of a liveliness token, written as rmw_zenoh writes it
/// (`liveliness_utils.cpp`, `qos_to_keyexpr`):
/// `reliability:durability:history,depth:deadline_s,deadline_ns:lifespan_s,lifespan_ns:
/// liveliness,lease_s,lease_ns`, where every value equal to rmw_zenoh's default (reliable,
/// volatile, keep last, depth 42, infinite durations, automatic liveliness) is left
/// empty. The GID of a publisher hashes the whole token, so one character more or less
/// here makes a different publisher.
///
/// Every publisher and subscriber of this bus is keep-last, volatile, with no deadline,
/// lifespan or lease; `reliable` is what the Zenoh publisher does (Zenoh's reliable
/// channel, dropped on congestion: rmw_zenoh's mapping of RELIABLE + KEEP_LAST).
pub fn qos_string(reliable: bool, depth: usize) -> String {
    let reliability = if reliable { "" } else { "2" };
    let depth = if depth == RMW_ZENOH_DEFAULT_DEPTH {
        String::new()
    } else {
        depth.to_string()
    };
    format!("{reliability}::,{depth}:,:,:,,")
}

/// Kind of entity in a liveliness token.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityKind {
    Node,
    Publisher,
    Subscriber,
}

impl EntityKind {
    fn code(self) -> &'static str {
        match self {
            EntityKind::Node => "NN",
            EntityKind::Publisher => "MP",
            EntityKind::Subscriber => "MS",
        }
    }
}

/// One entity of the graph, as read back from a liveliness token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GraphEntity {
    pub domain_id: u32,
    pub zid: String,
    pub node_id: u32,
    pub entity_id: u32,
    pub kind: EntityKind,
    pub namespace: String,
    pub node_name: String,
    /// For publishers and subscribers: topic name with a leading `/`.
    pub topic: Option<String>,
    pub dds_type: Option<String>,
    pub type_hash: Option<String>,
}

impl GraphEntity {
    /// The node's name with its namespace, e.g. `/pr2_arm_controller`.
    pub fn fq_node_name(&self) -> String {
        format!(
            "{}/{}",
            self.namespace.trim_end_matches('/'),
            self.node_name
        )
    }

    /// The ROS 2 type name (`sensor_msgs/msg/JointState`) from the DDS name.
    pub fn ros_type_name(&self) -> Option<String> {
        let t = self.dds_type.as_deref()?;
        let mut parts = t.split("::");
        let pkg = parts.next()?;
        let _msg = parts.next()?;
        let _dds = parts.next()?;
        let name = parts.next()?.trim_end_matches('_');
        Some(format!("{pkg}/msg/{name}"))
    }
}

/// Builds a liveliness token key.
pub fn liveliness_key(entity: &GraphEntity, qos: &str) -> String {
    let mut key = format!(
        "{LIVELINESS_PREFIX}/{}/{}/{}/{}/{}/%/{}/{}",
        entity.domain_id,
        entity.zid,
        entity.node_id,
        entity.entity_id,
        entity.kind.code(),
        mangle(&entity.namespace),
        mangle(&entity.node_name)
    );
    if let (Some(topic), Some(ty), Some(hash)) =
        (&entity.topic, &entity.dds_type, &entity.type_hash)
    {
        let topic = format!("/{}", normalize_topic(topic));
        key.push_str(&format!("/{}/{ty}/{hash}/{qos}", mangle(&topic)));
    }
    key
}

/// Parses a liveliness token key; `None` for keys of other kinds (services, ...) or
/// malformed keys.
pub fn parse_liveliness_key(key: &str) -> Option<GraphEntity> {
    let parts: Vec<&str> = key.split('/').collect();
    if parts.len() < 9 || parts[0] != LIVELINESS_PREFIX {
        return None;
    }
    let kind = match parts[5] {
        "NN" => EntityKind::Node,
        "MP" => EntityKind::Publisher,
        "MS" => EntityKind::Subscriber,
        _ => return None,
    };
    let (topic, dds_type, type_hash) = if kind == EntityKind::Node {
        (None, None, None)
    } else {
        if parts.len() < 12 {
            return None;
        }
        (
            Some(demangle(parts[9])),
            Some(parts[10].to_owned()),
            Some(parts[11].to_owned()),
        )
    };
    Some(GraphEntity {
        domain_id: parts[1].parse().ok()?,
        zid: parts[2].to_owned(),
        node_id: parts[3].parse().ok()?,
        entity_id: parts[4].parse().ok()?,
        kind,
        namespace: demangle(parts[7]),
        node_name: demangle(parts[8]),
        topic,
        dds_type,
        type_hash,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use teleop_msgs::JointState;

    #[test]
    fn qos_is_written_as_rmw_zenoh_writes_it() {
        // Expected strings from pyzeros 0.1.0 `QosProfile(...).encode()`, which mirrors
        // rmw_zenoh's qos_to_keyexpr (an implementation nobody here wrote).
        assert_eq!(qos_string(true, 1), "::,1:,:,:,,");
        assert_eq!(qos_string(false, 10), "2::,10:,:,:,,");
        assert_eq!(qos_string(true, RMW_ZENOH_DEFAULT_DEPTH), "::,:,:,:,,");
    }

    #[test]
    fn data_key_has_rmw_zenoh_shape() {
        assert_eq!(
            data_key::<JointState>(0, "/teleop/shadow/joint_states/"),
            "0/teleop/shadow/joint_states/sensor_msgs::msg::dds_::JointState_/\
             RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
        );
    }

    #[test]
    fn liveliness_round_trip() {
        let e = GraphEntity {
            domain_id: 3,
            zid: "aac3178e146ba6f1fc6e6a4085e77f21".into(),
            node_id: 0,
            entity_id: 7,
            kind: EntityKind::Publisher,
            namespace: String::new(),
            node_name: "wrist_tracker".into(),
            topic: Some("/teleop/wrist_pose".into()),
            dds_type: Some("geometry_msgs::msg::dds_::PoseStamped_".into()),
            type_hash: Some("RIHS01_10".into()),
        };
        let key = liveliness_key(&e, &qos_string(true, 1));
        assert_eq!(
            key,
            "@ros2_lv/3/aac3178e146ba6f1fc6e6a4085e77f21/0/7/MP/%/%/wrist_tracker/\
             %teleop%wrist_pose/geometry_msgs::msg::dds_::PoseStamped_/RIHS01_10/::,1:,:,:,,"
        );
        let back = parse_liveliness_key(&key).expect("parses");
        assert_eq!(back, e);
        assert_eq!(
            back.ros_type_name().as_deref(),
            Some("geometry_msgs/msg/PoseStamped")
        );
        assert_eq!(back.fq_node_name(), "/wrist_tracker");
        assert!(parse_liveliness_key("@ros2_lv/0/x").is_none());
        assert!(parse_liveliness_key("@ros2_lv/zz/z/0/0/NN/%/%/n").is_none());
    }
}
