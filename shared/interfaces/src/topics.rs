//! The one table that names every topic of the system: key, message type, direction,
//! nominal rate and QoS class. `docs/topics.md` is generated from [`markdown_table`] and
//! a test keeps the two identical. The transport (`teleop-bus`) implements the QoS
//! classes on Zenoh; it knows no topic of this table.

use std::marker::PhantomData;

use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, Image, JointCommand, JointState, Message,
    NodeStatus, OperatorInput, PoseStamped, TFMessage,
};

/// Which way a topic crosses (or does not cross) between the two sites.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Operator site to robot site.
    LocalToRemote,
    /// Robot site to operator site.
    RemoteToLocal,
    /// Stays on the operator's site.
    LocalInternal,
    /// Stays on the robot's site.
    RemoteInternal,
    /// Published by every node on both sites.
    Both,
}

impl Direction {
    pub fn label(self) -> &'static str {
        match self {
            Direction::LocalToRemote => "local -> remote",
            Direction::RemoteToLocal => "remote -> local",
            Direction::LocalInternal => "local only",
            Direction::RemoteInternal => "remote only",
            Direction::Both => "both sites",
        }
    }
    /// True if samples of this topic travel between the machines of the two sites.
    pub fn crosses_sites(self) -> bool {
        matches!(
            self,
            Direction::LocalToRemote | Direction::RemoteToLocal | Direction::Both
        )
    }
    /// True if samples of this topic reach `site` in a deployment: every topic but the
    /// other site's internal ones.
    pub fn reaches(self, site: crate::nodes::Site) -> bool {
        use crate::nodes::Site;
        !matches!(
            (site, self),
            (Site::Local, Direction::RemoteInternal) | (Site::Remote, Direction::LocalInternal)
        )
    }
}

/// Quality-of-service class of a topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum QosClass {
    /// Commands and poses: express, real-time priority, dropped on congestion; the
    /// subscriber keeps only the newest sample and enforces sequence order and a
    /// deadline on the source timestamp.
    Control,
    /// Robot state feedback: express, interactive priority, drop, newest only, sequence
    /// order enforced.
    State,
    /// Camera images: data-low priority, drop, newest only.
    Image,
    /// Acknowledgements (the camera views' receipts): express, interactive priority,
    /// drop, every sample kept (up to 16 queued: each one acknowledges its own view),
    /// sequence order enforced.
    Receipt,
    /// Diagnostics (node status): background priority, drop, last few kept.
    Diagnostics,
}

impl QosClass {
    pub fn label(self) -> &'static str {
        match self {
            QosClass::Control => "control",
            QosClass::State => "state",
            QosClass::Image => "image",
            QosClass::Receipt => "receipt",
            QosClass::Diagnostics => "diagnostics",
        }
    }
    /// Whether samples skip batching.
    pub fn express(self) -> bool {
        matches!(
            self,
            QosClass::Control | QosClass::State | QosClass::Receipt
        )
    }
    /// How many received samples a subscriber keeps before it drops the oldest.
    pub fn depth(self) -> usize {
        match self {
            QosClass::Control | QosClass::State | QosClass::Image => 1,
            QosClass::Diagnostics | QosClass::Receipt => 16,
        }
    }
    /// Whether a subscriber drops samples that are not newer than the last accepted
    /// one from the same publisher.
    pub fn enforces_order(self) -> bool {
        matches!(
            self,
            QosClass::Control | QosClass::State | QosClass::Receipt
        )
    }
}

/// Which nodes may publish a topic: the access control between and within the sites
/// is generated from this (`teleop_node::access`), and a system test checks it against
/// what the running nodes announce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Publishers {
    /// Only these nodes (by node name, as in [`crate::nodes::NODES`]).
    Nodes(&'static [&'static str]),
    /// Every node of either site (e.g. the node status).
    EveryNode,
}

impl Publishers {
    /// Whether `node` may publish the topic.
    pub fn includes(self, node: &str) -> bool {
        match self {
            Publishers::Nodes(names) => names.contains(&node),
            Publishers::EveryNode => true,
        }
    }
}

/// The untyped description of a topic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TopicSpec {
    /// ROS-style name without leading slash, e.g. `teleop/wrist_pose`.
    pub name: &'static str,
    /// ROS 2 type name, e.g. `geometry_msgs/msg/PoseStamped`.
    pub type_name: &'static str,
    /// RIHS01 hash of the type.
    pub type_hash: &'static str,
    pub direction: Direction,
    /// Nominal publishing rate.
    pub rate_hz: f64,
    pub qos: QosClass,
    /// Default maximum age of an accepted sample (source timestamp to receipt), in
    /// milliseconds; `None` for no deadline. Nodes may override it in their config.
    pub deadline_ms: Option<u64>,
    /// The nodes that publish it (and the only ones the sites' routers let publish it).
    pub publishers: Publishers,
    /// What the topic carries.
    pub doc: &'static str,
}

/// A topic bound to its message type.
#[derive(Debug)]
pub struct Topic<T> {
    pub spec: TopicSpec,
    _type: PhantomData<fn() -> T>,
}

impl<T> Clone for Topic<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Topic<T> {}

impl<T: Message> Topic<T> {
    pub const fn new(
        name: &'static str,
        direction: Direction,
        rate_hz: f64,
        qos: QosClass,
        deadline_ms: Option<u64>,
        publishers: Publishers,
        doc: &'static str,
    ) -> Self {
        Self {
            spec: TopicSpec {
                name,
                type_name: T::TYPE_NAME,
                type_hash: T::TYPE_HASH,
                direction,
                rate_hz,
                qos,
                deadline_ms,
                publishers,
                doc,
            },
            _type: PhantomData,
        }
    }

    /// The typed topic for `spec`, if `spec` carries `T`.
    pub fn from_spec(spec: &TopicSpec) -> Option<Self> {
        (spec.type_name == T::TYPE_NAME && spec.type_hash == T::TYPE_HASH).then_some(Self {
            spec: *spec,
            _type: PhantomData,
        })
    }

    /// The same topic under another name (e.g. a second camera), same type and QoS.
    pub const fn renamed(self, name: &'static str, doc: &'static str) -> Self {
        let mut spec = self.spec;
        spec.name = name;
        spec.doc = doc;
        Self {
            spec,
            _type: PhantomData,
        }
    }
}

use Direction::*;
use QosClass as Q;

/// 6D pose of the operator's hand frame (wrist origin) in the UR5 base frame.
pub const WRIST_POSE: Topic<PoseStamped> = Topic::new(
    "teleop/wrist_pose",
    LocalToRemote,
    320.0,
    Q::Control,
    Some(100),
    Publishers::Nodes(&["wrist_tracker"]),
    "Operator hand frame (Fig. 3.6) in the UR5 base frame, registered and jump-filtered, stamped with the capture time; drives the PR2 arm through the clutch and the camera arm",
);
/// Shadow hand finger joint targets from hand inference.
pub const HAND_JOINT_TARGETS: Topic<JointState> = Topic::new(
    "teleop/hand/joint_targets",
    LocalToRemote,
    30.0,
    Q::Control,
    Some(200),
    Publishers::Nodes(&["hand_inference"]),
    "17 Shadow finger joint targets (rad) inferred from the operator's hand depth image",
);
/// Pedals and switches.
pub const OPERATOR_INPUT: Topic<OperatorInput> = Topic::new(
    "teleop/operator_input",
    LocalToRemote,
    50.0,
    Q::Control,
    Some(100),
    Publishers::Nodes(&["wrist_tracker"]),
    "Clutch pedal, enable (deadman) switch, camera-arm stop pedal, motion scale",
);
/// PR2 arm joint states.
pub const PR2_JOINT_STATES: Topic<JointState> = Topic::new(
    "teleop/pr2/joint_states",
    RemoteToLocal,
    100.0,
    Q::State,
    Some(500),
    Publishers::Nodes(&["feedback_publisher"]),
    "PR2 arm chain joint positions/velocities (5 PR2 arm joints + 2 Shadow wrist joints)",
);
/// Shadow hand joint states.
pub const SHADOW_JOINT_STATES: Topic<JointState> = Topic::new(
    "teleop/shadow/joint_states",
    RemoteToLocal,
    100.0,
    Q::State,
    Some(500),
    Publishers::Nodes(&["feedback_publisher"]),
    "Shadow hand finger joint positions/velocities/efforts (17 joints; J1s fixed by the BioTacs)",
);
/// Fingertip pressures.
pub const FINGERTIP_PRESSURES: Topic<FingertipPressures> = Topic::new(
    "teleop/shadow/fingertip_pressures",
    RemoteToLocal,
    100.0,
    Q::State,
    Some(500),
    Publishers::Nodes(&["feedback_publisher"]),
    "Five BioTac-like fingertip contact forces (N)",
);
/// Remote camera, top view, JPEG-compressed (image_transport's `compressed` topic name):
/// a raw view (230 kB) would not cross a capped WAN whole (docs/network.md).
pub const REMOTE_CAMERA_TOP: Topic<CompressedImage> = Topic::new(
    "teleop/remote_camera/top/image/compressed",
    RemoteToLocal,
    15.0,
    Q::Image,
    None,
    Publishers::Nodes(&["feedback_publisher"]),
    "Top view of the robot's workspace (JPEG of the rgb8 camera image), rate-limited",
);
/// Remote camera, side view, JPEG-compressed.
pub const REMOTE_CAMERA_SIDE: Topic<CompressedImage> = REMOTE_CAMERA_TOP.renamed(
    "teleop/remote_camera/side/image/compressed",
    "Side view of the robot's workspace (JPEG of the rgb8 camera image), rate-limited",
);
/// Receipts of the camera views: the operator's display answers each view it receives
/// with the view's header, and the feedback publisher paces the views by the round trip
/// (`teleop_remote_site::view_pacer`), so on a slow WAN they give way to the feedback.
pub const REMOTE_CAMERA_RECEIPTS: Topic<Header> = Topic::new(
    "teleop/remote_camera/receipts",
    LocalToRemote,
    30.0,
    Q::Receipt,
    None,
    Publishers::Nodes(&["operator_display"]),
    "The header (stamp, frame) of each camera view the operator's display received; paces the views so they give way to the feedback on a slow WAN",
);
/// Depth image of the operator's hand from the camera on the UR5, as its driver (or the
/// operator-site simulator standing in for it) publishes it: stamped with the capture
/// time, so every later stage can measure its latency from the camera.
pub const HW_HAND_DEPTH: Topic<Image> = Topic::new(
    "teleop/hw/depth_camera/image",
    LocalInternal,
    30.0,
    Q::Image,
    None,
    Publishers::Nodes(&["local_sim"]),
    "Depth camera hardware: the operator's hand (16UC1, mm, SR300 640x480), stamped with the capture time",
);
/// Where the depth camera is: its optical frame in the UR5 base frame, computed by the
/// camera arm from the measured joints and stamped with their measurement time, so hand
/// inference knows where the camera was when a frame was taken.
pub const CAMERA_POSE: Topic<PoseStamped> = Topic::new(
    "teleop/local_camera/pose",
    LocalInternal,
    30.0,
    Q::State,
    Some(500),
    Publishers::Nodes(&["camera_arm"]),
    "Depth camera optical frame in the UR5 base frame (FK of the measured UR5 joints, stamped with their time)",
);
/// Raw motion-capture reading of the marker on the back of the operator's hand.
pub const HW_MOCAP_MARKER: Topic<PoseStamped> = Topic::new(
    "teleop/hw/mocap/wrist_marker",
    LocalInternal,
    320.0,
    Q::State,
    Some(100),
    Publishers::Nodes(&["local_sim"]),
    "Motion capture hardware: the hand-back marker's 6D pose in the tracker's own frame (PhaseSpace-like, 320 Hz); none while occluded",
);
/// The pedal box and the enable switch, as their driver reads them.
pub const HW_PEDALS: Topic<OperatorInput> = Topic::new(
    "teleop/hw/pedals",
    LocalInternal,
    50.0,
    Q::Control,
    Some(100),
    Publishers::Nodes(&["local_sim"]),
    "Pedal box hardware: clutch (right), camera stop (left), enable switch, motion scale",
);
/// Simulation ground truth: the operator's true hand frame (Fig. 3.6).
pub const SIM_OPERATOR_HAND_POSE: Topic<PoseStamped> = Topic::new(
    "teleop/sim/operator/hand_pose",
    LocalInternal,
    100.0,
    Q::State,
    None,
    Publishers::Nodes(&["local_sim"]),
    "Simulation ground truth: the operator's true hand frame (Fig. 3.6) in the UR5 base frame",
);
/// Simulation ground truth: the operator's fingers retargeted to the Shadow hand.
pub const SIM_OPERATOR_SHADOW_JOINTS: Topic<JointState> = Topic::new(
    "teleop/sim/operator/shadow_joints",
    LocalInternal,
    30.0,
    Q::State,
    None,
    Publishers::Nodes(&["local_sim"]),
    "Simulation ground truth: the operator's true finger posture retargeted to the 17 Shadow finger joints (rad)",
);
/// Simulation ground truth: the robot world's free objects, one transform per object
/// from the world frame to a child frame named after it, stamped with the capture time
/// of the camera views rendered from the same world state. The watching operator model
/// (`local_sim`) takes from it only the poses no newer than the newest camera view the
/// operator site has received: what the display shows, not more.
pub const SIM_ROBOT_OBJECT_POSES: Topic<TFMessage> = Topic::new(
    "teleop/sim/robot/object_poses",
    RemoteToLocal,
    15.0,
    Q::State,
    None,
    Publishers::Nodes(&["remote_sim"]),
    "Simulation ground truth: the robot world's objects (world -> object name), stamped like the camera views rendered from the same state; the operator model uses them only up to the newest received view",
);
/// UR5 joint states.
pub const UR5_JOINT_STATES: Topic<JointState> = Topic::new(
    "teleop/ur5/joint_states",
    LocalInternal,
    100.0,
    Q::State,
    Some(500),
    Publishers::Nodes(&["camera_arm"]),
    "UR5 camera-arm joint states",
);
/// Status of every node.
pub const NODE_STATUS: Topic<NodeStatus> = Topic::new(
    "teleop/status",
    Both,
    1.0,
    Q::Diagnostics,
    None,
    Publishers::EveryNode,
    "Lifecycle state, rejected-input counters and last error of each node",
);

/// PR2 arm hardware: measured joint state, published by the process that owns the arm
/// (its driver; the simulator stands in for it).
pub const HW_PR2_ARM_STATE: Topic<JointState> = Topic::new(
    "teleop/hw/pr2_arm/state",
    RemoteInternal,
    250.0,
    Q::State,
    Some(100),
    Publishers::Nodes(&["remote_sim"]),
    "Arm hardware state: 7 joints (5 PR2 arm + 2 Shadow wrist), position and velocity",
);
/// Joint velocity command to the arm hardware.
pub const HW_PR2_ARM_COMMAND: Topic<JointState> = Topic::new(
    "teleop/hw/pr2_arm/command",
    RemoteInternal,
    30.0,
    Q::Control,
    Some(100),
    Publishers::Nodes(&["pr2_arm_controller"]),
    "Arm hardware command: 7 joint velocities (rad/s); the hardware stops on its own if commands stop",
);
/// Hand hardware state.
pub const HW_HAND_STATE: Topic<JointState> = Topic::new(
    "teleop/hw/shadow_hand/state",
    RemoteInternal,
    250.0,
    Q::State,
    Some(100),
    Publishers::Nodes(&["remote_sim"]),
    "Hand hardware state: 17 finger joints, position, velocity and effort",
);
/// Hand hardware tactile readings.
pub const HW_HAND_TACTILE: Topic<FingertipPressures> = Topic::new(
    "teleop/hw/shadow_hand/tactile",
    RemoteInternal,
    250.0,
    Q::State,
    Some(100),
    Publishers::Nodes(&["remote_sim"]),
    "Hand hardware fingertip sensors (N)",
);
/// Hand hardware command.
pub const HW_HAND_COMMAND: Topic<JointCommand> = Topic::new(
    "teleop/hw/shadow_hand/command",
    RemoteInternal,
    500.0,
    Q::Control,
    Some(100),
    Publishers::Nodes(&["shadow_hand_controller"]),
    "Hand hardware command: 17 finger joints, `effort` (N m), `position` (rad) or a joint `impedance` the hand's own loop evaluates",
);

/// UR5 hardware: measured joint state, published by the process that owns the camera
/// arm (its driver; the operator-site simulator stands in for it).
pub const HW_UR5_STATE: Topic<JointState> = Topic::new(
    "teleop/hw/ur5/state",
    LocalInternal,
    250.0,
    Q::State,
    Some(100),
    Publishers::Nodes(&["local_sim"]),
    "Camera-arm hardware state: 6 UR5 joints, position and velocity",
);
/// Joint velocity command to the UR5 hardware.
pub const HW_UR5_COMMAND: Topic<JointState> = Topic::new(
    "teleop/hw/ur5/command",
    LocalInternal,
    30.0,
    Q::Control,
    Some(100),
    Publishers::Nodes(&["camera_arm"]),
    "Camera-arm hardware command: 6 joint velocities (rad/s); the hardware stops on its own if commands stop",
);

/// Camera hardware, top view of the robot's workspace (the simulator renders it as a
/// camera driver would publish it).
pub const HW_CAMERA_TOP: Topic<Image> = Topic::new(
    "teleop/hw/camera/top/image",
    RemoteInternal,
    15.0,
    Q::Image,
    None,
    Publishers::Nodes(&["remote_sim"]),
    "Camera hardware, top view of the workspace (rgb8); forwarded rate-limited by the feedback publisher",
);
/// Camera hardware, side view.
pub const HW_CAMERA_SIDE: Topic<Image> = HW_CAMERA_TOP.renamed(
    "teleop/hw/camera/side/image",
    "Camera hardware, side view of the workspace (rgb8); forwarded rate-limited by the feedback publisher",
);

/// Prefix of the hardware topics (`teleop/hw/...`): what the process that owns a robot
/// or a sensor offers to its own site's controllers. They never cross between sites.
pub const HARDWARE_PREFIX: &str = "teleop/hw/";

/// True for a hardware topic (leading slash ignored).
pub fn is_hardware_topic(name: &str) -> bool {
    name.trim_start_matches('/').starts_with(HARDWARE_PREFIX)
}

/// Every topic of the system.
pub const ALL: &[TopicSpec] = &[
    WRIST_POSE.spec,
    HAND_JOINT_TARGETS.spec,
    OPERATOR_INPUT.spec,
    PR2_JOINT_STATES.spec,
    SHADOW_JOINT_STATES.spec,
    FINGERTIP_PRESSURES.spec,
    REMOTE_CAMERA_TOP.spec,
    REMOTE_CAMERA_SIDE.spec,
    REMOTE_CAMERA_RECEIPTS.spec,
    HW_HAND_DEPTH.spec,
    CAMERA_POSE.spec,
    UR5_JOINT_STATES.spec,
    NODE_STATUS.spec,
    HW_PR2_ARM_STATE.spec,
    HW_PR2_ARM_COMMAND.spec,
    HW_HAND_STATE.spec,
    HW_HAND_TACTILE.spec,
    HW_HAND_COMMAND.spec,
    HW_UR5_STATE.spec,
    HW_UR5_COMMAND.spec,
    HW_CAMERA_TOP.spec,
    HW_CAMERA_SIDE.spec,
    HW_MOCAP_MARKER.spec,
    HW_PEDALS.spec,
    SIM_OPERATOR_HAND_POSE.spec,
    SIM_OPERATOR_SHADOW_JOINTS.spec,
    SIM_ROBOT_OBJECT_POSES.spec,
];

/// Looks a topic up by name (leading/trailing slashes ignored).
pub fn find(name: &str) -> Option<&'static TopicSpec> {
    let name = name.trim_matches('/');
    ALL.iter().find(|t| t.name == name)
}

/// The Markdown table of [`ALL`], as it appears in `docs/topics.md`.
pub fn markdown_table() -> String {
    let mut out = String::from(
        "| topic | type | direction | rate | QoS | deadline | published by | carries |\n|---|---|---|---|---|---|---|---|\n",
    );
    for t in ALL {
        let deadline = t
            .deadline_ms
            .map_or_else(|| "-".to_owned(), |d| format!("{d} ms"));
        let publishers = match t.publishers {
            Publishers::Nodes(names) => names
                .iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(", "),
            Publishers::EveryNode => "every node".to_owned(),
        };
        out.push_str(&format!(
            "| `/{}` | `{}` | {} | {} Hz | {} | {} | {} | {} |\n",
            t.name,
            t.type_name,
            t.direction.label(),
            t.rate_hz,
            t.qos.label(),
            deadline,
            publishers,
            t.doc
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_well_formed() {
        for (i, a) in ALL.iter().enumerate() {
            assert!(
                !a.name.starts_with('/') && !a.name.ends_with('/'),
                "{}",
                a.name
            );
            assert!(a.rate_hz > 0.0, "{}", a.name);
            for b in &ALL[i + 1..] {
                assert_ne!(a.name, b.name);
            }
            if a.qos == QosClass::Control {
                assert!(
                    a.deadline_ms.is_some(),
                    "control topic {} needs a deadline",
                    a.name
                );
            }
        }
        assert_eq!(find("/teleop/wrist_pose/"), Some(&WRIST_POSE.spec));
        assert_eq!(find("nope"), None);
    }

    #[test]
    fn a_site_is_reached_by_all_but_the_other_sites_internal_topics() {
        use crate::nodes::Site;
        assert!(!HW_PR2_ARM_STATE.spec.direction.reaches(Site::Local));
        assert!(PR2_JOINT_STATES.spec.direction.reaches(Site::Local));
        assert!(HW_PEDALS.spec.direction.reaches(Site::Local));
        assert!(WRIST_POSE.spec.direction.reaches(Site::Local));
        assert!(!HW_PEDALS.spec.direction.reaches(Site::Remote));
        assert!(HW_PR2_ARM_STATE.spec.direction.reaches(Site::Remote));
        assert!(NODE_STATUS.spec.direction.reaches(Site::Remote));
    }

    #[test]
    fn control_topics_cross_local_to_remote_or_stay_on_their_site() {
        for t in ALL.iter().filter(|t| t.qos == QosClass::Control) {
            assert!(
                matches!(
                    t.direction,
                    Direction::LocalToRemote | Direction::RemoteInternal | Direction::LocalInternal
                ),
                "{}",
                t.name
            );
        }
    }

    #[test]
    fn publishers_are_nodes_of_the_site_the_topic_leaves_from() {
        use crate::nodes::{NODES, Site};
        for t in ALL {
            let Publishers::Nodes(names) = t.publishers else {
                assert_eq!(t.direction, Direction::Both, "{}", t.name);
                continue;
            };
            assert!(!names.is_empty(), "{} has no publisher", t.name);
            let site = match t.direction {
                Direction::LocalToRemote | Direction::LocalInternal => Site::Local,
                Direction::RemoteToLocal | Direction::RemoteInternal => Site::Remote,
                Direction::Both => panic!("{}: a topic of both sites is every node's", t.name),
            };
            for name in names {
                let node = NODES.iter().find(|n| n.name == *name);
                let node = node.unwrap_or_else(|| panic!("{}: no node `{name}`", t.name));
                assert_eq!(node.site, site, "{}: `{name}` is on the other site", t.name);
            }
        }
        // A hardware command topic is published by the interface's one controller.
        use crate::hardware::{PR2_ARM, SHADOW_HAND, UR5_ARM};
        for (command, controller) in [
            (PR2_ARM.command.spec, PR2_ARM.controller_node),
            (UR5_ARM.command.spec, UR5_ARM.controller_node),
            (SHADOW_HAND.command.spec, SHADOW_HAND.controller_node),
        ] {
            let Publishers::Nodes(names) = command.publishers else {
                panic!("{}: every node publishes it", command.name);
            };
            assert_eq!(names, [controller], "{}", command.name);
        }
        assert!(WRIST_POSE.spec.publishers.includes("wrist_tracker"));
        assert!(!WRIST_POSE.spec.publishers.includes("hand_inference"));
        assert!(NODE_STATUS.spec.publishers.includes("anyone"));
    }

    #[test]
    fn hardware_topics_stay_on_their_site() {
        for t in ALL.iter().filter(|t| t.name.starts_with(HARDWARE_PREFIX)) {
            assert!(!t.direction.crosses_sites(), "{}", t.name);
            assert!(is_hardware_topic(t.name));
        }
        assert!(!is_hardware_topic(WRIST_POSE.spec.name));
    }
}
