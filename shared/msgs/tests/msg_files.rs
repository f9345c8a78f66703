//! The `.msg` files in `shared/msgs/msg/` are what a ROS 2 user builds the
//! `teleop_msgs` interface package from; the Rust structs must describe the same fields
//! in the same order, or the CDR bytes and the type hashes disagree.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use teleop_msgs::{
    FingertipPressures, JointCommand, Lifecycle, Message, NodeStatus, OperatorInput,
};

fn msg_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("msg")
}

fn read_msg(name: &str) -> String {
    let path = msg_dir().join(format!("{name}.msg"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Normalizes a type as written in a `.msg` file: `pkg/msg/Type` and `pkg/Type` both
/// become `pkg/Type`.
fn normalize_type(ty: &str) -> String {
    ty.replace("/msg/", "/")
}

/// A parsed `.msg` line.
#[derive(Debug, PartialEq)]
enum Line {
    /// `type name [default]`
    Field {
        ty: String,
        name: String,
        default: Option<String>,
    },
    /// `type NAME=value`
    Constant {
        ty: String,
        name: String,
        value: String,
    },
}

/// Minimal `.msg` parser: comments, blank lines, constants and fields (with an optional
/// default value). Good enough for the project's files, which use no string constants
/// containing `#`.
fn parse_msg(text: &str) -> Vec<Line> {
    let mut out = Vec::new();
    for raw in text.lines() {
        let line = raw.split('#').next().unwrap().trim();
        if line.is_empty() {
            continue;
        }
        let (ty, rest) = line
            .split_once(char::is_whitespace)
            .unwrap_or_else(|| panic!("line without a name: {raw:?}"));
        let ty = normalize_type(ty.trim());
        let rest = rest.trim();
        if let Some((name, value)) = rest.split_once('=') {
            out.push(Line::Constant {
                ty,
                name: name.trim().to_owned(),
                value: value.trim().to_owned(),
            });
        } else {
            let mut parts = rest.split_whitespace();
            let name = parts.next().unwrap().to_owned();
            let default = parts.next().map(str::to_owned);
            assert!(parts.next().is_none(), "trailing text in {raw:?}");
            out.push(Line::Field { ty, name, default });
        }
    }
    out
}

/// `"type name"` for every field of the file, in order.
fn field_lines(text: &str) -> Vec<String> {
    parse_msg(text)
        .into_iter()
        .filter_map(|l| match l {
            Line::Field { ty, name, .. } => Some(format!("{ty} {name}")),
            Line::Constant { .. } => None,
        })
        .collect()
}

fn description_lines<T: Message>() -> Vec<String> {
    T::description()
        .msg_text()
        .lines()
        .map(|l| {
            let (ty, name) = l.split_once(' ').unwrap();
            format!("{} {name}", normalize_type(ty))
        })
        .collect()
}

fn check_type<T: Message>() {
    let short = T::TYPE_NAME.rsplit('/').next().unwrap();
    let from_file = field_lines(&read_msg(short));
    let from_rust = description_lines::<T>();
    assert!(!from_rust.is_empty(), "{}: no fields", T::TYPE_NAME);
    assert_eq!(
        from_file,
        from_rust,
        "{}: msg/{short}.msg and the Rust description disagree",
        T::TYPE_NAME
    );
}

#[test]
fn operator_input_msg_matches_struct() {
    check_type::<OperatorInput>();
}

#[test]
fn fingertip_pressures_msg_matches_struct() {
    check_type::<FingertipPressures>();
}

#[test]
fn node_status_msg_matches_struct() {
    check_type::<NodeStatus>();
}

#[test]
fn joint_command_msg_matches_struct() {
    check_type::<JointCommand>();
}

#[test]
fn header_is_written_as_std_msgs_header() {
    for name in [
        "OperatorInput",
        "FingertipPressures",
        "NodeStatus",
        "JointCommand",
    ] {
        let text = read_msg(name);
        let fields = parse_msg(&text);
        assert_eq!(
            fields.iter().find(|l| matches!(l, Line::Field { .. })),
            Some(&Line::Field {
                ty: "std_msgs/Header".into(),
                name: "header".into(),
                default: None
            }),
            "{name}.msg must start with `std_msgs/Header header`"
        );
        assert!(
            text.lines().any(|l| l.trim_start().starts_with('#')),
            "{name}.msg has no comments"
        );
    }
}

#[test]
fn every_msg_file_is_a_known_type() {
    let mut names: Vec<String> = std::fs::read_dir(msg_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".msg"))
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "FingertipPressures.msg",
            "JointCommand.msg",
            "NodeStatus.msg",
            "OperatorInput.msg"
        ]
    );
}

#[test]
fn node_status_constants_match_lifecycle() {
    let constants: Vec<(String, String, u8)> = parse_msg(&read_msg("NodeStatus"))
        .into_iter()
        .filter_map(|l| match l {
            Line::Constant { ty, name, value } => Some((ty, name, value.parse().unwrap())),
            Line::Field { .. } => None,
        })
        .collect();
    let expected = [
        Lifecycle::Unconfigured,
        Lifecycle::Inactive,
        Lifecycle::Active,
        Lifecycle::Fault,
        Lifecycle::Finalized,
    ]
    .map(|l| ("uint8".to_owned(), l.name().to_uppercase(), l as u8));
    assert_eq!(constants, expected.to_vec());
    for (_, name, value) in &constants {
        assert_eq!(
            Lifecycle::from_u8(*value).map(|l| l.name().to_uppercase()),
            Some(name.clone())
        );
    }
}

#[test]
fn defaults_in_msg_files_match_rust_defaults() {
    // OperatorInput: ROS 2 users get motion_scale 1.0 by default, as Rust's Default.
    let fields = parse_msg(&read_msg("OperatorInput"));
    let default = fields.iter().find_map(|l| match l {
        Line::Field {
            name,
            default: Some(d),
            ..
        } if name == "motion_scale" => Some(d.parse::<f64>().unwrap()),
        _ => None,
    });
    assert_eq!(default, Some(OperatorInput::default().motion_scale));
    // No other field in the project's files has a default value.
    for file in [
        "OperatorInput",
        "FingertipPressures",
        "NodeStatus",
        "JointCommand",
    ] {
        let with_default: Vec<String> = parse_msg(&read_msg(file))
            .into_iter()
            .filter_map(|l| match l {
                Line::Field {
                    name,
                    default: Some(_),
                    ..
                } => Some(name),
                _ => None,
            })
            .collect();
        let expected: &[&str] = if file == "OperatorInput" {
            &["motion_scale"]
        } else {
            &[]
        };
        assert_eq!(with_default, expected, "{file}.msg");
    }
}

#[test]
fn parser_strips_comments_constants_and_normalizes_types() {
    let text = "# comment\n\nuint8 A=1 # c\nstd_msgs/msg/Header header # the header\nfloat64[] x\nstring s \"a\"\n";
    assert_eq!(
        field_lines(text),
        ["std_msgs/Header header", "float64[] x", "string s"]
    );
}

#[test]
fn ros2_package_builds_every_msg_file() {
    let ros2 = Path::new(env!("CARGO_MANIFEST_DIR")).join("ros2");
    let cmake = std::fs::read_to_string(ros2.join("CMakeLists.txt")).unwrap();
    let package = std::fs::read_to_string(ros2.join("package.xml")).unwrap();
    assert!(cmake.contains("project(teleop_msgs)"));
    assert!(cmake.contains("DEPENDENCIES std_msgs"));
    for name in [
        "OperatorInput",
        "FingertipPressures",
        "NodeStatus",
        "JointCommand",
    ] {
        assert!(
            cmake.contains(&format!("\"${{TELEOP_MSGS_ROOT}}:msg/{name}.msg\"")),
            "CMakeLists.txt does not generate {name}"
        );
    }
    assert!(package.contains("<name>teleop_msgs</name>"));
    assert!(package.contains("<member_of_group>rosidl_interface_packages</member_of_group>"));
    assert!(package.contains("<depend>std_msgs</depend>"));
}
