//! Who publishes what: a live map from publisher GID to the node that announced it.
//!
//! Every publisher carries a GID derived from its liveliness token key exactly as
//! rmw_zenoh derives it (XXH3-128 of the key, [`gid_for_token`]), and the token names the
//! node, its Zenoh session and the topic. So a publisher of this bus and one of a ROS 2
//! node on rmw_zenoh are identified alike. A subscriber that must only take samples from
//! one node (a robot's hardware accepts commands from its own controller only) looks
//! the sample's GID up here. Publishers that announce no token are unknown and refused
//! by such a subscriber.
//!
//! This binds a sample to the node that *announced* a publisher; it does not
//! authenticate the sender (a peer that copies a GID off the wire can forge it). Mutual
//! TLS and access control between sites are the deployment's; the robot-side safety
//! layer limits whatever gets through.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use crate::keys::{self, EntityKind};

/// The GID of the publisher whose liveliness token key is `key`, as rmw_zenoh computes
/// it (`liveliness_utils.cpp`, `Entity::Entity`): the 128-bit XXH3 hash of the whole key,
/// its low 64 bits then its high 64 bits, each in the host's byte order (little-endian
/// on every platform ROS 2 supports; written little-endian here).
pub fn gid_for_token(key: &str) -> [u8; 16] {
    let hash = xxhash_rust::xxh3::xxh3_128(key.as_bytes());
    // `u128::to_le_bytes` puts the low 64 bits first, each half little-endian.
    hash.to_le_bytes()
}

/// What a publisher's token says about it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PublisherInfo {
    /// Node name (without namespace).
    pub node_name: String,
    /// The node's Zenoh session id.
    pub zid: String,
    /// Topic with a leading `/`.
    pub topic: String,
}

impl PublisherInfo {
    /// `node@zid-prefix`, short enough for logs and status texts.
    pub fn label(&self) -> String {
        let zid: String = self.zid.chars().take(8).collect();
        format!("{}@{zid}", self.node_name)
    }
}

/// Live GID -> publisher map, fed by the liveliness subscribers of the bus (one per
/// Zenoh session of the node: a token may be seen through either).
#[derive(Debug, Default)]
pub struct PublisherDirectory {
    /// Each publisher with the sessions (bit per session) that see its token now.
    by_gid: Mutex<HashMap<[u8; 16], (PublisherInfo, u8)>>,
}

impl PublisherDirectory {
    /// An empty directory.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// A token appeared (`alive`) or vanished, seen by the node's session `session`
    /// (0-7): a publisher stays known while any session still sees its token, so a
    /// link lost by one session does not make it a stranger to the other.
    pub fn update_from(&self, session: u8, key: &str, alive: bool) {
        let bit = 1u8 << (session & 7);
        let Some(e) = keys::parse_liveliness_key(key) else {
            return;
        };
        if e.kind != EntityKind::Publisher {
            return;
        }
        let gid = gid_for_token(key);
        let Ok(mut map) = self.by_gid.lock() else {
            return;
        };
        if alive {
            let info = PublisherInfo {
                node_name: e.node_name,
                zid: e.zid,
                topic: e.topic.unwrap_or_default(),
            };
            let seen_by = map.get(&gid).map_or(0, |(_, s)| *s) | bit;
            map.insert(gid, (info, seen_by));
        } else if let Some((_, seen_by)) = map.get_mut(&gid) {
            *seen_by &= !bit;
            if *seen_by == 0 {
                map.remove(&gid);
            }
        }
    }

    /// The publisher with this GID, if a live token announces it.
    pub fn lookup(&self, gid: &[u8; 16]) -> Option<PublisherInfo> {
        self.by_gid.lock().ok()?.get(gid).map(|(p, _)| p.clone())
    }

    /// The live publishers of `topic` (with its leading `/`), ordered by node name.
    pub fn publishers_of(&self, topic: &str) -> Vec<PublisherInfo> {
        let mut out: Vec<PublisherInfo> = self
            .by_gid
            .lock()
            .map(|m| {
                m.values()
                    .filter(|(p, _)| p.topic == topic)
                    .map(|(p, _)| p.clone())
                    .collect()
            })
            .unwrap_or_default();
        out.sort_by(|a, b| (&a.node_name, &a.zid).cmp(&(&b.node_name, &b.zid)));
        out
    }

    /// Number of live publishers known.
    pub fn len(&self) -> usize {
        self.by_gid.lock().map(|m| m.len()).unwrap_or(0)
    }

    /// True when no publisher is known.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keys::{GraphEntity, liveliness_key, qos_string};

    #[test]
    fn gids_are_computed_as_rmw_zenoh_computes_them() {
        // Expected value from pyzeros 0.1.0 `rmw_zenoh_gid` (Python `xxhash`), which
        // mirrors rmw_zenoh's Entity constructor: an implementation nobody here wrote.
        let key = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/7/MP/%/%/wrist_tracker/\
                   %teleop%wrist_pose/geometry_msgs::msg::dds_::PoseStamped_/\
                   RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8/\
                   ::,1:,:,:,,";
        let hex: String = gid_for_token(key)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(hex, "9d914ea70239ce2dd0e4c1a5c94a5c91");
    }

    #[test]
    fn tokens_map_gids_to_nodes() {
        let e = GraphEntity {
            domain_id: 0,
            zid: "aac3178e146ba6f1fc6e6a4085e77f21".into(),
            node_id: 0,
            entity_id: 4,
            kind: EntityKind::Publisher,
            namespace: String::new(),
            node_name: "pr2_arm_controller".into(),
            topic: Some("/teleop/hw/pr2_arm/command".into()),
            dds_type: Some("sensor_msgs::msg::dds_::JointState_".into()),
            type_hash: Some("RIHS01_a1".into()),
        };
        let key = liveliness_key(&e, &qos_string(true, 1));
        let d = PublisherDirectory::new();
        d.update_from(0, &key, true);
        let info = d.lookup(&gid_for_token(&key)).expect("known");
        assert_eq!(info.node_name, "pr2_arm_controller");
        assert_eq!(info.topic, "/teleop/hw/pr2_arm/command");
        assert_eq!(info.label(), "pr2_arm_controller@aac3178e");
        assert_eq!(d.lookup(&[0; 16]), None);
        d.update_from(0, &key, false);
        assert!(d.is_empty());
        // Node tokens are not publishers.
        let node = GraphEntity {
            kind: EntityKind::Node,
            topic: None,
            dds_type: None,
            type_hash: None,
            ..e
        };
        d.update_from(0, &liveliness_key(&node, ""), true);
        assert!(d.is_empty());
        // Seen by both sessions of a node: known until neither sees it.
        d.update_from(0, &key, true);
        d.update_from(1, &key, true);
        d.update_from(0, &key, false);
        assert!(
            d.lookup(&gid_for_token(&key)).is_some(),
            "session 1 still sees it"
        );
        d.update_from(0, &key, false);
        assert!(
            d.lookup(&gid_for_token(&key)).is_some(),
            "a repeated loss is one loss"
        );
        d.update_from(1, &key, false);
        assert!(d.is_empty());
    }
}
