//! Every config file shipped in the repository parses into its typed struct and
//! validates; unknown fields are refused with their name.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use teleop_hand_inference::node::HandInferenceConfig;
use teleop_local_site::camera_arm_node::CameraArmNodeConfig;
use teleop_local_site::operator_display::OperatorDisplayConfig;
use teleop_local_site::wrist_tracker::WristTrackerConfig;
use teleop_node::NodeConfig;
use teleop_node::config::{load_toml, parse_toml};
use teleop_node::router::RouterConfig;
use teleop_remote_site::arm_node::ArmNodeConfig;
use teleop_remote_site::feedback_node::FeedbackConfig;
use teleop_remote_site::hand_node::HandNodeConfig;
use teleop_sim_nodes::local_sim::LocalSimConfig;
use teleop_sim_nodes::remote_sim::SimNodeConfig;
use teleop_system_tests::repo_root;

fn check<C: NodeConfig>(path: &Path) {
    teleop_node::config::load_checked::<C>(path).unwrap_or_else(|e| panic!("{e}"));
}

fn equals_default<C: NodeConfig + PartialEq + std::fmt::Debug + serde::Serialize>(path: &Path) {
    let shipped: C = load_toml(path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        shipped,
        C::default(),
        "{} is not the defaults; regenerate it with `<node> --show-default-config`",
        path.display()
    );
    // Every field written out: a field missing from the file parses as its default
    // and would pass above, leaving the example without a setting users can see.
    let written: toml::Value = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert_eq!(
        written,
        toml::Value::try_from(C::default()).unwrap(),
        "{} does not list every field; regenerate it with `<node> --show-default-config`",
        path.display()
    );
}

/// Node name (file stem) -> (parse and validate, compare with the defaults). A config
/// file with no entry fails the test, so no file escapes checking.
/// (parse and validate, compare with the defaults) for one node's config type.
type Checks = (fn(&Path), fn(&Path));

fn checker(stem: &str) -> Option<Checks> {
    match stem {
        "wrist_tracker" => Some((
            check::<WristTrackerConfig>,
            equals_default::<WristTrackerConfig>,
        )),
        "pr2_arm_controller" => Some((check::<ArmNodeConfig>, equals_default::<ArmNodeConfig>)),
        "remote_sim" => Some((check::<SimNodeConfig>, equals_default::<SimNodeConfig>)),
        "feedback_publisher" => Some((check::<FeedbackConfig>, equals_default::<FeedbackConfig>)),
        "shadow_hand_controller" => {
            Some((check::<HandNodeConfig>, equals_default::<HandNodeConfig>))
        }
        "local_sim" => Some((check::<LocalSimConfig>, equals_default::<LocalSimConfig>)),
        "camera_arm" => Some((
            check::<CameraArmNodeConfig>,
            equals_default::<CameraArmNodeConfig>,
        )),
        "hand_inference" => Some((
            check::<HandInferenceConfig>,
            equals_default::<HandInferenceConfig>,
        )),
        "operator_display" => Some((
            check::<OperatorDisplayConfig>,
            equals_default::<OperatorDisplayConfig>,
        )),
        "router" => Some((check::<RouterConfig>, equals_default::<RouterConfig>)),
        _ => None,
    }
}

fn toml_files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "toml")
                // The `teleop` program's crate manifest (`deploy/teleop`) is no node config.
                && path.file_name().is_some_and(|n| n != "Cargo.toml")
            {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

fn stem(path: &Path) -> String {
    path.file_stem().unwrap().to_string_lossy().to_string()
}

/// Every config file shipped under `deploy/` (per-machine files may differ from the
/// defaults) parses with unknown fields refused and passes validation.
#[test]
fn every_shipped_config_parses_and_validates() {
    let files = toml_files(&repo_root().join("deploy"));
    for path in &files {
        let (parse, _) = checker(&stem(path))
            .unwrap_or_else(|| panic!("no config type known for {}", path.display()));
        parse(path);
    }
    assert!(files.len() >= teleop_interfaces::nodes::NODES.len());
}

/// Every node of the node table has its config file where the table says.
#[test]
fn the_node_table_names_existing_configs() {
    for node in teleop_interfaces::nodes::NODES {
        let path = repo_root().join(node.config);
        assert!(path.is_file(), "{} missing", path.display());
        assert!(checker(node.name).is_some(), "{} has no checker", node.name);
    }
}

/// `deploy/defaults/` holds each node's defaults as `--show-default-config` prints
/// them: an example to start a machine's file from.
#[test]
fn defaults_examples_equal_built_in_defaults() {
    let files = toml_files(&repo_root().join("deploy/defaults"));
    assert_eq!(files.len(), teleop_interfaces::nodes::NODES.len());
    for path in &files {
        let (_, same) = checker(&stem(path)).unwrap();
        same(path);
    }
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
    let err = parse_toml::<WristTrackerConfig>("[reacquire]\naftr_s = 3.0\n").unwrap_err();
    assert!(err.contains("aftr_s"), "{err}");
    let err = parse_toml::<WristTrackerConfig>("[bus.zenoh]\nmode = \"bridge\"\n").unwrap_err();
    assert!(err.contains("bridge"), "{err}");
    // What parses but does not validate: the error naming it.
    let refused = |toml: &str| {
        let mut cfg: WristTrackerConfig = parse_toml(toml).unwrap();
        teleop_node::config::validate_all(&mut cfg).unwrap_err()
    };
    // `router` is a mode, but only for `teleop router`.
    let err = refused("[bus.zenoh]\nmode = \"router\"\n");
    assert!(err.contains("teleop router"), "{err}");
    // A malformed hardware subnet is named at load, for nodes as for routers.
    let err = refused("[bus.zenoh]\nhardware_interfaces = [\"lo\", \"172.30.1.0/99\"]\n");
    assert!(
        err.contains("hardware_interfaces") && err.contains("172.30.1.0/99"),
        "{err}"
    );
    // A deadline for a topic the table does not have; one it has is taken.
    let err = refused("[bus.deadlines_ms]\n\"teleop/wrist_poses\" = 150\n");
    assert!(
        err.contains("bus.deadlines_ms") && err.contains("teleop/wrist_poses"),
        "{err}"
    );
    let mut cfg: WristTrackerConfig =
        parse_toml("[bus.deadlines_ms]\n\"teleop/wrist_pose\" = 150\n").unwrap();
    teleop_node::config::validate_all(&mut cfg).expect("a topic of the table");
    let cfg: WristTrackerConfig = parse_toml("pose_rate_hz = -1.0\n").unwrap();
    assert!(cfg.validate().unwrap_err().contains("pose_rate_hz"));
}
