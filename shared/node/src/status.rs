//! A node's [`NodeStatus`] on [`topics::NODE_STATUS`].

use teleop_bus::{Bus, BusError, Publisher};
use teleop_interfaces::topics;
use teleop_msgs::{Header, Lifecycle, NodeStatus};

/// Publishes this node's [`NodeStatus`].
#[derive(Debug)]
pub struct StatusReporter {
    publisher: Publisher<NodeStatus>,
    node_name: String,
}

impl StatusReporter {
    /// # Errors
    /// [`BusError`] if the publisher cannot be declared.
    pub async fn new(bus: &Bus) -> Result<Self, BusError> {
        Ok(Self {
            publisher: bus.publisher(&topics::NODE_STATUS).await?,
            node_name: bus.node_name().to_owned(),
        })
    }

    /// Publishes one status report, stamped `now_ns` (node clock).
    ///
    /// # Errors
    /// [`BusError`] if publishing fails.
    pub fn report(
        &self,
        now_ns: i64,
        state: Lifecycle,
        counters: &[(String, u64)],
        last_error: &str,
    ) -> Result<(), BusError> {
        let msg = NodeStatus {
            header: Header::new(teleop_msgs::Time::from_nanos(now_ns), ""),
            node_name: self.node_name.clone(),
            lifecycle_state: state as u8,
            counter_names: counters.iter().map(|(n, _)| n.clone()).collect(),
            counter_values: counters.iter().map(|(_, v)| *v).collect(),
            last_error: last_error.to_owned(),
        };
        self.publisher.put_at(&msg, now_ns)
    }
}
