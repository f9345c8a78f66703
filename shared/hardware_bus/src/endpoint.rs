//! Hardware-side endpoints: publish the state, take commands from the site's controller
//! only.

use std::collections::BTreeMap;

use teleop_bus::{Bus, BusError, Publisher, Subscriber};
use teleop_hardware::{ArmCommand, ArmState, HandCommand, HandState, wire};
use teleop_interfaces::{ArmInterface, HandInterface};
use teleop_msgs::{FingertipPressures, JointCommand, JointState};

/// Commands refused after they passed the source check, by reason, and the newest
/// refusal's text not yet taken by the owner.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
struct Refusals {
    by_kind: BTreeMap<&'static str, u64>,
    newest: Option<String>,
}

impl Refusals {
    fn count(&mut self, what: &str, e: &wire::WireError) {
        *self.by_kind.entry(e.kind()).or_default() += 1;
        let text = format!("{what} command refused: {e}");
        // The owning node's status names it (once, not per refusal, in its log).
        tracing::debug!("{text}");
        self.newest = Some(text);
    }

    fn named(&self, prefix: &str, out: &mut Vec<(String, u64)>) {
        for (k, n) in &self.by_kind {
            out.push((format!("{prefix}.command_refused.{k}"), *n));
        }
    }
}

/// The arm's side of the bus in the process that owns it.
#[derive(Debug)]
pub struct ArmEndpoint<const N: usize> {
    interface: ArmInterface<N>,
    commands: Subscriber<JointState>,
    state: Publisher<JointState>,
    refused: Refusals,
}

impl<const N: usize> ArmEndpoint<N> {
    /// Serves `interface`, taking commands only from publishers announced by
    /// `controller_node`.
    ///
    /// # Errors
    /// [`BusError`] if the declarations fail or the node name is empty.
    pub async fn new(
        bus: &Bus,
        interface: &ArmInterface<N>,
        controller_node: &str,
    ) -> Result<Self, BusError> {
        Ok(Self {
            interface: *interface,
            commands: bus
                .subscriber_from(&interface.command, controller_node)
                .await?,
            state: bus.publisher(&interface.state).await?,
            refused: Refusals::default(),
        })
    }

    /// The newest command from the controller since the last call, if a valid one
    /// arrived (malformed ones are counted and dropped).
    pub fn take_command(&mut self) -> Option<ArmCommand<N>> {
        let mut newest = None;
        while let Some(r) = self.commands.try_recv() {
            match wire::arm_command(&self.interface.joints, &r.msg) {
                Ok(c) => newest = Some(c),
                Err(e) => self.refused.count(self.interface.name, &e),
            }
        }
        newest
    }

    /// Publishes the measured state.
    ///
    /// # Errors
    /// [`BusError`] if publishing fails.
    pub fn publish_state(&self, state: &ArmState<N>) -> Result<(), BusError> {
        self.state
            .put(&wire::arm_state_msg(&self.interface.joints, state))
    }

    /// Counters: commands received and refused (foreign publishers, stale, malformed).
    pub fn counters(&self) -> Vec<(String, u64)> {
        let name = self.interface.name;
        let mut out: Vec<(String, u64)> = self
            .commands
            .named_counters()
            .into_iter()
            .map(|(k, v)| (format!("{name}.{k}"), v))
            .collect();
        self.refused.named(name, &mut out);
        out
    }

    /// The newest refusal since the last call, if any (for the owner's status).
    pub fn take_refusal(&mut self) -> Option<String> {
        self.refused.newest.take()
    }

    /// The command subscription (statistics, publishers heard from).
    pub fn command_subscriber(&self) -> &Subscriber<JointState> {
        &self.commands
    }
}

/// The hand's side of the bus in the process that owns it.
#[derive(Debug)]
pub struct HandEndpoint {
    name: &'static str,
    commands: Subscriber<JointCommand>,
    state: Publisher<JointState>,
    tactile: Publisher<FingertipPressures>,
    refused: Refusals,
}

impl HandEndpoint {
    /// Serves `interface`, taking commands only from publishers announced by
    /// `controller_node`.
    ///
    /// # Errors
    /// [`BusError`] if the declarations fail or the node name is empty.
    pub async fn new(
        bus: &Bus,
        interface: &HandInterface,
        controller_node: &str,
    ) -> Result<Self, BusError> {
        Ok(Self {
            name: interface.name,
            commands: bus
                .subscriber_from(&interface.command, controller_node)
                .await?,
            state: bus.publisher(&interface.state).await?,
            tactile: bus.publisher(&interface.tactile).await?,
            refused: Refusals::default(),
        })
    }

    /// The newest valid command from the controller since the last call.
    pub fn take_command(&mut self) -> Option<HandCommand> {
        let mut newest = None;
        while let Some(r) = self.commands.try_recv() {
            match wire::hand_command(&r.msg) {
                Ok(c) => newest = Some(c),
                Err(e) => self.refused.count(self.name, &e),
            }
        }
        newest
    }

    /// Publishes the measured state and the fingertip forces.
    ///
    /// # Errors
    /// [`BusError`] if publishing fails.
    pub fn publish_state(&self, state: &HandState) -> Result<(), BusError> {
        self.state.put(&wire::hand_state_msg(state))?;
        self.tactile.put(&wire::tactile_msg(state))
    }

    /// Counters: commands received and refused.
    pub fn counters(&self) -> Vec<(String, u64)> {
        let mut out: Vec<(String, u64)> = self
            .commands
            .named_counters()
            .into_iter()
            .map(|(k, v)| (format!("{}.{k}", self.name), v))
            .collect();
        self.refused.named(self.name, &mut out);
        out
    }

    /// The newest refusal since the last call, if any (for the owner's status).
    pub fn take_refusal(&mut self) -> Option<String> {
        self.refused.newest.take()
    }

    /// The command subscription.
    pub fn command_subscriber(&self) -> &Subscriber<JointCommand> {
        &self.commands
    }
}
