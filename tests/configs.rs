//! Every config file shipped in the repository parses into its typed struct and
//! validates; unknown fields are refused with their name.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use teleop_bus::NodeConfig;
use teleop_bus::config::{load_toml, parse_toml};
use teleop_local_site::wrist_tracker::WristTrackerConfig;
use teleop_remote_site::arm_node::ArmNodeConfig;
use teleop_remote_site::feedback_node::FeedbackConfig;
use teleop_remote_site::hand_node::HandNodeConfig;
use teleop_remote_site::sim_node::SimNodeConfig;
use teleop_system_tests::repo_root;

fn check<C: NodeConfig>(path: &Path) {
    let cfg: C = load_toml(path).unwrap_or_else(|e| panic!("{e}"));
    cfg.validate()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// Node name (file stem) -> checker. A shipped config with no entry fails the test, so
/// no file escapes checking.
fn checker(stem: &str) -> Option<fn(&Path)> {
    match stem {
        "wrist_tracker" => Some(check::<WristTrackerConfig>),
        "pr2_arm_controller" => Some(check::<ArmNodeConfig>),
        "remote_sim" => Some(check::<SimNodeConfig>),
        "feedback_publisher" => Some(check::<FeedbackConfig>),
        "shadow_hand_controller" => Some(check::<HandNodeConfig>),
        _ => None,
    }
}

#[test]
fn every_shipped_config_parses_and_validates() {
    let mut checked = 0;
    let mut stack = vec![repo_root().join("deploy")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "toml") {
                let stem = path.file_stem().unwrap().to_string_lossy().to_string();
                let f = checker(&stem)
                    .unwrap_or_else(|| panic!("no config type known for {}", path.display()));
                f(&path);
                checked += 1;
            }
        }
    }
    assert!(checked >= 1, "no config files found under deploy/");
}

#[test]
fn shipped_defaults_equal_built_in_defaults() {
    let path = repo_root().join("deploy/config/wrist_tracker.toml");
    let shipped: WristTrackerConfig = load_toml(&path).unwrap();
    assert_eq!(shipped, WristTrackerConfig::default());
    let path = repo_root().join("deploy/config/pr2_arm_controller.toml");
    let shipped: ArmNodeConfig = load_toml(&path).unwrap();
    assert_eq!(shipped, ArmNodeConfig::default());
    let path = repo_root().join("deploy/config/remote_sim.toml");
    let shipped: SimNodeConfig = load_toml(&path).unwrap();
    assert_eq!(shipped, SimNodeConfig::default());
    let path = repo_root().join("deploy/config/feedback_publisher.toml");
    let shipped: FeedbackConfig = load_toml(&path).unwrap();
    assert_eq!(shipped, FeedbackConfig::default());
    let path = repo_root().join("deploy/config/shadow_hand_controller.toml");
    let shipped: HandNodeConfig = load_toml(&path).unwrap();
    assert_eq!(shipped, HandNodeConfig::default());
}

#[test]
fn hand_controller_config_errors_are_named() {
    let err = parse_toml::<HandNodeConfig>("[hand.controller]\nmode = \"torque\"\n").unwrap_err();
    assert!(err.contains("torque"), "{err}");
    let err = parse_toml::<HandNodeConfig>("[hand.controller.adaptive]\nzeta = 1.0\n").unwrap_err();
    assert!(err.contains("zeta"), "{err}");
    let cfg: HandNodeConfig = parse_toml("[hand]\nrate_hz = 5000.0\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("rate_hz"));
    let cfg: HandNodeConfig = parse_toml("[hand.controller]\nhold_max_effort_nm = 3.0\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("hold_max_effort_nm"));
}

#[test]
fn unknown_and_misspelled_fields_are_named() {
    let err = parse_toml::<WristTrackerConfig>("pose_rate = 100.0\n").unwrap_err();
    assert!(err.contains("pose_rate"), "{err}");
    let err = parse_toml::<WristTrackerConfig>("[operator]\nsede = 3\n").unwrap_err();
    assert!(err.contains("sede"), "{err}");
    let err = parse_toml::<WristTrackerConfig>("[bus.zenoh]\nmode = \"router\"\n").unwrap_err();
    assert!(err.contains("router"), "{err}");
    let cfg: WristTrackerConfig = parse_toml("pose_rate_hz = -1.0\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("pose_rate_hz"));
}
