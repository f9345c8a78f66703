//! Every node binary of the system: its site, the machine it runs on in the thesis's
//! setup (ch. 7.3), its config file, and what it does. The launcher starts them in this
//! order; the config test checks every file named here.

/// The two sites.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Site {
    /// The operator's site.
    Local,
    /// The robot's site.
    Remote,
}

impl Site {
    /// `"local"` / `"remote"`.
    pub fn label(self) -> &'static str {
        match self {
            Site::Local => "local",
            Site::Remote => "remote",
        }
    }
}

/// One node binary.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeSpec {
    /// Binary name, also the node's default name on the bus (unique across sites).
    pub name: &'static str,
    pub site: Site,
    /// Machine in the thesis's setup: `PC1`/`PC3` (operator site), `PC2` (robot site
    /// controllers), `robot` (the robots' own drivers; the simulator stands in).
    pub machine: &'static str,
    /// Shipped configuration, relative to the repository root.
    pub config: &'static str,
    /// What it does.
    pub role: &'static str,
    /// Whether it commands hardware (then its shutdown commands a stop).
    pub commands_hardware: bool,
    /// Whether it owns hardware (a driver, or the simulator standing in for one): it
    /// starts first and stops last, so the controllers' stop commands still reach it.
    pub owns_hardware: bool,
}

/// Every node, in start order (hardware first, then controllers, then the operator
/// site, so each finds what it needs). They stop in the same order with the hardware
/// owners last ([`stop_order`]).
pub const NODES: &[NodeSpec] = &[
    NodeSpec {
        name: "remote_sim",
        site: Site::Remote,
        machine: "robot",
        config: "deploy/config/remote_sim.toml",
        role: "simulated PR2 arm, Shadow hand, objects and camera views, behind the hardware safety layer",
        owns_hardware: true,
        commands_hardware: false,
    },
    NodeSpec {
        name: "pr2_arm_controller",
        site: Site::Remote,
        machine: "PC2",
        config: "deploy/config/pr2_arm_controller.toml",
        role: "PR2 arm relative control (clutch, IK, eq. 6.1 velocity law, watchdog)",
        owns_hardware: false,
        commands_hardware: true,
    },
    NodeSpec {
        name: "shadow_hand_controller",
        site: Site::Remote,
        machine: "PC2",
        config: "deploy/config/shadow_hand_controller.toml",
        role: "Shadow hand control (position / fixed / adaptive impedance, hold watchdog)",
        owns_hardware: false,
        commands_hardware: true,
    },
    NodeSpec {
        name: "feedback_publisher",
        site: Site::Remote,
        machine: "PC2",
        config: "deploy/config/feedback_publisher.toml",
        role: "joint states, fingertip pressures and camera views to the operator site",
        owns_hardware: false,
        commands_hardware: false,
    },
    NodeSpec {
        name: "local_sim",
        site: Site::Local,
        machine: "PC3",
        config: "deploy/config/local_sim.toml",
        role: "simulated operator (scripted tasks, hand shapes), motion capture, pedals, UR5 camera arm and SR300 depth camera, behind the hardware safety layer",
        owns_hardware: true,
        commands_hardware: false,
    },
    NodeSpec {
        name: WRIST_TRACKER,
        site: Site::Local,
        machine: "PC1",
        config: "deploy/config/wrist_tracker.toml",
        role: "operator hand frame in the UR5 base frame (registration, jump filter) and the pedals",
        owns_hardware: false,
        commands_hardware: false,
    },
    NodeSpec {
        name: "camera_arm",
        site: Site::Local,
        machine: "PC1",
        config: "deploy/config/camera_arm.toml",
        role: "active vision: the UR5 keeps the depth camera on the operator's palm (IK, keep-out, limits, left pedal)",
        owns_hardware: false,
        commands_hardware: true,
    },
    NodeSpec {
        name: HAND_INFERENCE,
        site: Site::Local,
        machine: "PC1",
        config: "deploy/config/hand_inference.toml",
        role: "depth image -> 17 Shadow finger targets (ONNX network through ort); no hand in view, no command",
        owns_hardware: false,
        commands_hardware: false,
    },
    NodeSpec {
        name: OPERATOR_DISPLAY,
        site: Site::Local,
        machine: "PC3",
        config: "deploy/config/operator_display.toml",
        role: "what the operator sees of the robot site: camera views (acknowledged, so they are paced to the WAN), feedback ages and rates",
        owns_hardware: false,
        commands_hardware: false,
    },
];

/// The operator-site node that publishes the wrist pose and the pedals
/// ([`WRIST_POSE`](crate::topics::WRIST_POSE), [`OPERATOR_INPUT`](crate::topics::OPERATOR_INPUT)).
pub const WRIST_TRACKER: &str = "wrist_tracker";

/// The operator-site node that publishes the finger targets
/// ([`HAND_JOINT_TARGETS`](crate::topics::HAND_JOINT_TARGETS)).
pub const HAND_INFERENCE: &str = "hand_inference";

/// The operator-site node that moves the depth camera on the UR5
/// ([`CAMERA_POSE`](crate::topics::CAMERA_POSE)).
pub const CAMERA_ARM: &str = "camera_arm";

/// The operator-site node that receives the camera views and acknowledges them
/// ([`REMOTE_CAMERA_RECEIPTS`](crate::topics::REMOTE_CAMERA_RECEIPTS)).
pub const OPERATOR_DISPLAY: &str = "operator_display";

/// The order to stop the nodes in: the nodes that command hardware first (their
/// shutdown commands the robots to stop while their inputs are still alive), then the
/// other nodes, the hardware owners last.
pub fn stop_order() -> impl Iterator<Item = &'static NodeSpec> {
    let commanders = NODES.iter().filter(|n| n.commands_hardware);
    let others = NODES
        .iter()
        .filter(|n| !n.commands_hardware && !n.owns_hardware);
    commanders
        .chain(others)
        .chain(NODES.iter().filter(|n| n.owns_hardware))
}

/// The node named `name`.
pub fn find(name: &str) -> Option<&'static NodeSpec> {
    NODES.iter().find(|n| n.name == name)
}

/// Names of the nodes of `site`, in start order.
pub fn of_site(site: Site) -> impl Iterator<Item = &'static str> {
    NODES.iter().filter(move |n| n.site == site).map(|n| n.name)
}

/// The node table as Markdown (for `docs/architecture.md`).
pub fn markdown_table() -> String {
    let mut out =
        String::from("| node | site | machine | config | role |\n|---|---|---|---|---|\n");
    for n in NODES {
        out.push_str(&format!(
            "| `{}` | {} | {} | `{}` | {} |\n",
            n.name,
            n.site.label(),
            n.machine,
            n.config,
            n.role
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_configs_are_named_after_them() {
        for (i, a) in NODES.iter().enumerate() {
            assert!(NODES[i + 1..].iter().all(|b| b.name != a.name));
            assert_eq!(a.config, format!("deploy/config/{}.toml", a.name));
        }
        assert_eq!(find("remote_sim").map(|n| n.site), Some(Site::Remote));
        assert_eq!(
            of_site(Site::Local).collect::<Vec<_>>(),
            [
                "local_sim",
                "wrist_tracker",
                "camera_arm",
                "hand_inference",
                "operator_display"
            ]
        );
        let stop: Vec<&str> = stop_order().map(|n| n.name).collect();
        assert_eq!(stop.len(), NODES.len());
        assert_eq!(stop[stop.len() - 2..], ["remote_sim", "local_sim"]);
        assert_eq!(
            stop[..3],
            ["pr2_arm_controller", "shadow_hand_controller", "camera_arm"]
        );
    }
}
