//! Helpers for the cross-crate tests.

use std::path::PathBuf;

pub mod hostile;
pub mod scenarios;

/// The repository root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .unwrap_or_default()
}

pub use teleop_bus::testing::{free_port, isolated_pair};

/// The wrist tracker's in-process devices, driven by one simulated operator: the pedals,
/// and the wrist pose source too when `tracker` (set `[source]` to
/// `TrackerSource::InProcess` then). The node's library does not link the simulator;
/// a test hands it in, as a program embedding a real driver would.
pub fn simulated_operator(
    operator: &teleop_sim::operator::SimulatedOperatorConfig,
    tracker: bool,
) -> teleop_local_site::wrist_tracker::InProcessDevices {
    use teleop_sim::operator::{SimulatedDevices, SimulatedOperator};
    let devices = || {
        Box::new(SimulatedDevices::new(SimulatedOperator::new(
            operator.clone(),
        )))
    };
    teleop_local_site::wrist_tracker::InProcessDevices {
        tracker: tracker.then(|| devices() as Box<dyn teleop_hardware::WristTracker>),
        panel: Some(devices()),
    }
}
