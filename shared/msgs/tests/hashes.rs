//! RIHS01 type hashes (REP 2011) and DDS type names, as rmw_zenoh puts them in keys.
#![allow(clippy::unwrap_used)]

use teleop_msgs::{
    CompressedImage, FingertipPressures, Float64MultiArray, Header, Image, JointCommand,
    JointState, Message, MultiArrayDimension, MultiArrayLayout, NodeStatus, OperatorInput, Point,
    Pose, PoseStamped, Quaternion, TFMessage, Time, Transform, TransformStamped, Vector3,
};

#[test]
fn computed_hash_equals_declared_hash_for_every_type() {
    let all = teleop_msgs::all_descriptions();
    assert_eq!(all.len(), 20);
    let mut mismatches = Vec::new();
    for (desc, declared) in &all {
        let computed = desc.type_hash();
        if computed != *declared {
            mismatches.push(format!(
                "{}: declared {declared}, computed {computed}",
                desc.type_name
            ));
        }
    }
    assert!(mismatches.is_empty(), "{mismatches:#?}");
}

#[test]
fn all_descriptions_lists_every_type_once() {
    let mut names: Vec<&str> = teleop_msgs::all_descriptions()
        .iter()
        .map(|(d, _)| d.type_name)
        .collect();
    names.sort_unstable();
    let mut expected = vec![
        Time::TYPE_NAME,
        Header::TYPE_NAME,
        Point::TYPE_NAME,
        Vector3::TYPE_NAME,
        Quaternion::TYPE_NAME,
        Pose::TYPE_NAME,
        PoseStamped::TYPE_NAME,
        Transform::TYPE_NAME,
        TransformStamped::TYPE_NAME,
        TFMessage::TYPE_NAME,
        JointState::TYPE_NAME,
        Image::TYPE_NAME,
        CompressedImage::TYPE_NAME,
        OperatorInput::TYPE_NAME,
        FingertipPressures::TYPE_NAME,
        NodeStatus::TYPE_NAME,
        JointCommand::TYPE_NAME,
        MultiArrayDimension::TYPE_NAME,
        MultiArrayLayout::TYPE_NAME,
        Float64MultiArray::TYPE_NAME,
    ];
    expected.sort_unstable();
    assert_eq!(names, expected);
}

fn assert_hash<T: Message>(published: &str) {
    assert_eq!(T::TYPE_HASH, published, "{} declared", T::TYPE_NAME);
    assert_eq!(
        T::description().type_hash(),
        published,
        "{} computed",
        T::TYPE_NAME
    );
}

/// Hashes as published by ROS 2 Kilted (`ros2 interface` / rmw_zenoh keys).
#[test]
fn published_kilted_hashes() {
    // The three std_msgs multi-array types: also what rosbags 0.11.9 computes for
    // ROS2_JAZZY (`get_typestore(Stores.ROS2_JAZZY).hash_rihs01(...)`).
    assert_hash::<Float64MultiArray>(
        "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
    );
    assert_hash::<MultiArrayLayout>(
        "RIHS01_4c66e6f78e740ac103a94cf63259f968e48c617e7699e829b63c21a5cb50dac6",
    );
    assert_hash::<MultiArrayDimension>(
        "RIHS01_5e773a60a4c7fc8a54985f307c7837aa2994252a126c301957a24e31282c9cbe",
    );
    assert_hash::<JointState>(
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    );
    assert_hash::<PoseStamped>(
        "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    );
    assert_hash::<TransformStamped>(
        "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
    );
    assert_hash::<Image>("RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47");
    // As ROS 2's generated type support declares it (and rosbags 0.11.9 computes it).
    assert_hash::<TFMessage>(
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    );
    // Also as rosbags 0.11.9 computes it (ROS2_KILTED store).
    assert_hash::<CompressedImage>(
        "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a",
    );
}

/// Hashes of the nested standard types, as computed independently by rosbags 0.11.9
/// (`Typestore.hash_rihs01`, ROS 2 Kilted store).
#[test]
fn nested_standard_type_hashes() {
    assert_hash::<Time>("RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197");
    assert_hash::<Header>(
        "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    );
}

/// Project types: same hashes as rosbags computes from `msg/*.msg` (constants, comments
/// and default values do not enter the hash).
#[test]
fn teleop_hashes_are_stable() {
    assert_hash::<OperatorInput>(
        "RIHS01_a9311ceb88718e6f27c808f700d1bbad5ec0ccd3f25fb90f555d462d620611ab",
    );
    assert_hash::<FingertipPressures>(
        "RIHS01_6e9f1f372dadcc239ffe9dc82437470396066bcf8e08e0cc6e9e2b98f5f399fc",
    );
    assert_hash::<NodeStatus>(
        "RIHS01_e9ab36cd53de9b842bd28237da566c14b35f9e93152d050477c46abdee6fd004",
    );
    assert_hash::<JointCommand>(
        "RIHS01_08a9321af0698f45d76f0081ed713276db4c5566cbe79d04059b25536e1004d7",
    );
}

#[test]
fn hash_format_is_rihs01_with_64_lowercase_hex_digits() {
    for (desc, _) in teleop_msgs::all_descriptions() {
        let h = desc.type_hash();
        let hex = h.strip_prefix("RIHS01_").unwrap();
        assert_eq!(hex.len(), 64, "{h}");
        assert!(
            hex.bytes()
                .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)),
            "{h}"
        );
    }
}

#[test]
fn hashable_json_of_time_is_exact() {
    // The exact text REP 2011 hashes for a type without references.
    assert_eq!(
        Time::description().hashable_json(),
        "{\"type_description\": {\"type_name\": \"builtin_interfaces/msg/Time\", \"fields\": [\
         {\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}, \
         {\"name\": \"nanosec\", \"type\": {\"type_id\": 7, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, \
         \"referenced_type_descriptions\": []}"
    );
}

#[test]
fn referenced_types_are_sorted_and_complete() {
    let names: Vec<&str> = PoseStamped::description()
        .referenced()
        .iter()
        .map(|d| d.type_name)
        .collect();
    assert_eq!(
        names,
        [
            "builtin_interfaces/msg/Time",
            "geometry_msgs/msg/Point",
            "geometry_msgs/msg/Pose",
            "geometry_msgs/msg/Quaternion",
            "std_msgs/msg/Header",
        ]
    );
    assert!(Time::description().referenced().is_empty());
}

#[test]
fn dds_type_names() {
    let cases: [(&str, String); 6] = [
        (
            "sensor_msgs::msg::dds_::JointState_",
            JointState::description().dds_type_name(),
        ),
        (
            "sensor_msgs::msg::dds_::Image_",
            Image::description().dds_type_name(),
        ),
        (
            "geometry_msgs::msg::dds_::PoseStamped_",
            PoseStamped::description().dds_type_name(),
        ),
        (
            "builtin_interfaces::msg::dds_::Time_",
            Time::description().dds_type_name(),
        ),
        (
            "std_msgs::msg::dds_::Header_",
            Header::description().dds_type_name(),
        ),
        (
            "teleop_msgs::msg::dds_::NodeStatus_",
            NodeStatus::description().dds_type_name(),
        ),
    ];
    for (expected, got) in cases {
        assert_eq!(got, expected);
    }
    for (desc, _) in teleop_msgs::all_descriptions() {
        let dds = desc.dds_type_name();
        let short = desc.type_name.rsplit('/').next().unwrap();
        assert!(dds.ends_with(&format!("::msg::dds_::{short}_")), "{dds}");
    }
}
