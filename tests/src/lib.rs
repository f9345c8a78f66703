//! Helpers for the cross-crate tests.

use std::path::PathBuf;

pub mod scenarios;

/// The repository root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .unwrap_or_default()
}

pub use teleop_bus::testing::{free_port, isolated_pair};
