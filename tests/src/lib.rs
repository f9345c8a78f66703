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

/// The robot site's simulator node's configuration for a test beside another robot
/// stack: the arm and the hand alone (no objects) on the joint-space engine, no camera
/// views, on `bus`.
pub fn bare_sim_config(bus: teleop_bus::BusConfig) -> teleop_sim_nodes::remote_sim::SimNodeConfig {
    use teleop_sim_nodes::remote_sim::{Engine, SceneKind, SimNodeConfig};
    let mut cfg = SimNodeConfig {
        scene: SceneKind::Free,
        engine: Engine::JointSpace,
        bus,
        ..SimNodeConfig::default()
    };
    cfg.cameras.enabled = false;
    cfg
}

/// A command running `script` with the Python of the interop tests (`$TELEOP_PYTHON`,
/// else `python3`), for the scripts on pyzeros: it compiles its serializers once into
/// `$CYDR_CACHE_DIR`, by default `~/.cache/teleop-cydr` (outside the clone, reused
/// between runs; left unset it would land in the working directory).
pub fn pyzeros_python(script: &str) -> std::process::Command {
    let python = std::env::var("TELEOP_PYTHON").unwrap_or_else(|_| "python3".into());
    let cache = std::env::var_os("CYDR_CACHE_DIR").map_or_else(
        || PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache/teleop-cydr"),
        PathBuf::from,
    );
    let mut command = std::process::Command::new(python);
    command.env("CYDR_CACHE_DIR", cache).arg(script);
    command
}

/// Whether a script's standard output says `ready` (on a line of its own) within 300 s
/// (pyzeros may compile its serializers first); `false` when it ends before or the time
/// runs out.
pub async fn said_ready(stdout: std::process::ChildStdout) -> bool {
    use std::io::BufRead;
    let ready = tokio::task::spawn_blocking(move || {
        std::io::BufReader::new(stdout)
            .lines()
            .map_while(Result::ok)
            .any(|l| l.trim() == "ready")
    });
    matches!(
        tokio::time::timeout(std::time::Duration::from_secs(300), ready).await,
        Ok(Ok(true))
    )
}

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
