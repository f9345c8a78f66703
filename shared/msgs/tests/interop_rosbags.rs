//! Interop with rosbags, an independent (Python) ROS 2 CDR implementation.
//!
//! For every case this test writes `<case>.rust.cdr` (our bytes) and `<case>.json` (type,
//! type hash, field values) into a temp dir and runs `tests/interop/rosbags_interop.py`,
//! which decodes our bytes with rosbags and compares every field with the JSON, checks
//! rosbags' RIHS01 hash of the type, and writes rosbags' own serialization of the JSON
//! message (`<case>.py.cdr`, little endian; `<case>.py.be.cdr`, big endian). This test then
//! decodes those with `teleop_msgs::decode`, compares with the original message, and
//! requires rosbags' little-endian bytes to be identical to ours.
//!
//! Python: `$TELEOP_PYTHON`, else `python3`, with rosbags installed
//! (`pip install -r tests/interop/requirements.txt`). `TELEOP_SKIP_INTEROP=1` skips.
#![allow(clippy::unwrap_used)]

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, Image, JointCommand, JointState, Message,
    NodeStatus, OperatorInput, Point, Pose, PoseStamped, Quaternion, Time, Transform,
    TransformStamped, Vector3, decode, encode, encodings,
};

type Check = Box<dyn Fn(&str, &[u8], &[u8], &[u8]) -> Result<(), String>>;

/// One message, encoded, with the check of what rosbags sends back.
struct Case {
    name: &'static str,
    json: serde_json::Value,
    bytes: Vec<u8>,
    /// (case, our bytes, rosbags LE bytes, rosbags BE bytes)
    check: Check,
}

fn case<T: Message>(name: &'static str, msg: T) -> Case {
    let bytes = encode(&msg).unwrap();
    let json = serde_json::json!({
        "type": T::TYPE_NAME,
        "type_hash": T::TYPE_HASH,
        "msg": serde_json::to_value(&msg).unwrap(),
    });
    let check: Check = Box::new(move |case, ours, py_le, py_be| {
        let from_le: T = decode(py_le).map_err(|e| format!("{case}: decoding rosbags LE: {e}"))?;
        if from_le != msg {
            return Err(format!(
                "{case}: rosbags LE decodes to\n{from_le:#?}\nexpected\n{msg:#?}"
            ));
        }
        if py_le != ours {
            return Err(format!(
                "{case}: rosbags LE bytes differ from ours\n  py   {}\n  rust {}",
                hex(py_le),
                hex(ours)
            ));
        }
        if py_be.get(..4) != Some(&[0u8, 0, 0, 0][..]) {
            return Err(format!("{case}: rosbags BE header is {:?}", py_be.get(..4)));
        }
        let from_be: T = decode(py_be).map_err(|e| format!("{case}: decoding rosbags BE: {e}"))?;
        if from_be != msg {
            return Err(format!(
                "{case}: rosbags BE decodes to\n{from_be:#?}\nexpected\n{msg:#?}"
            ));
        }
        Ok(())
    });
    Case {
        name,
        json,
        bytes,
        check,
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// The 24 joints of the Shadow Dexterous Hand, in its usual order.
fn shadow_joint_names() -> Vec<String> {
    let mut names = Vec::new();
    for (finger, n) in [
        ("FF", 4),
        ("MF", 4),
        ("RF", 4),
        ("LF", 5),
        ("TH", 5),
        ("WR", 2),
    ] {
        for j in 1..=n {
            names.push(format!("{finger}J{j}"));
        }
    }
    names
}

fn cases() -> Vec<Case> {
    let stamp = Time {
        sec: 1_767_225_600,
        nanosec: 999_999_999,
    };
    let header = Header::new(stamp, "shadow_palm");
    let q = Quaternion {
        x: -0.0,
        y: std::f64::consts::FRAC_1_SQRT_2,
        z: 5e-324, // smallest subnormal
        w: std::f64::consts::FRAC_1_SQRT_2 - f64::EPSILON,
    };
    let point = Point {
        x: 1.0 / 3.0,
        y: -1e300,
        z: f64::MIN_POSITIVE,
    };
    let v = Vector3 {
        x: 0.1,
        y: -0.2,
        z: f64::MAX,
    };
    let pose = Pose {
        position: point,
        orientation: q,
    };
    let transform = Transform {
        translation: v,
        rotation: Quaternion::default(),
    };
    let names = shadow_joint_names();
    assert_eq!(names.len(), 24);
    let n = names.len();
    let joint_state = JointState {
        header: header.clone(),
        position: (0..n).map(|i| i as f64 * 0.0625 - 0.5).collect(),
        velocity: (0..n).map(|i| (i as f64).sin()).collect(),
        effort: (0..n).map(|i| -(i as f64) / 7.0).collect(),
        name: names.clone(),
    };
    let depth: Vec<u16> = (0..4 * 3).map(|i| (i * 997 % 65_536) as u16).collect();
    let depth_image = Image::depth_mm(Header::new(stamp, "camera_depth_optical"), 4, 3, &depth);
    assert!(depth_image.check_layout().is_ok());
    let rgb_image = Image {
        header: Header::new(Time { sec: 5, nanosec: 6 }, "camera_color_optical"),
        height: 2,
        width: 3,
        encoding: encodings::RGB8.into(),
        is_bigendian: 0,
        step: 9,
        data: (0..18).map(|i| (i * 37 % 256) as u8).collect(),
    };
    assert!(rgb_image.check_layout().is_ok());

    vec![
        case("time", stamp),
        case(
            "time_negative",
            Time {
                sec: -1,
                nanosec: 1,
            },
        ),
        case("header", header.clone()),
        case("header_empty_frame", Header::default()),
        case("point", point),
        case("vector3", v),
        case("quaternion", q),
        case("pose", pose),
        case(
            "pose_stamped",
            PoseStamped {
                header: Header::new(stamp, "world"),
                pose,
            },
        ),
        case("transform", transform),
        case(
            "transform_stamped",
            TransformStamped {
                header: Header::new(stamp, "world"),
                child_frame_id: "ur5_tool0".into(),
                transform,
            },
        ),
        case("joint_state_24", joint_state),
        case(
            "joint_state_positions_only",
            JointState {
                header: header.clone(),
                name: names[..5].to_vec(),
                position: vec![0.0, -0.0, 1.5, 2.5, -3.25],
                velocity: vec![],
                effort: vec![],
            },
        ),
        case("image_16uc1", depth_image),
        case("image_rgb8", rgb_image),
        case(
            "operator_input",
            OperatorInput {
                header: header.clone(),
                clutch: true,
                enable: true,
                camera_stop: false,
                motion_scale: 1.0 / 3.0,
            },
        ),
        case("operator_input_default", OperatorInput::default()),
        case(
            "fingertip_pressures",
            FingertipPressures {
                header: header.clone(),
                ff: 0.5,
                mf: 1.25,
                rf: 0.0,
                lf: 3.0e-3,
                th: 12.75,
            },
        ),
        case(
            "node_status",
            NodeStatus {
                header,
                node_name: "remote_bridge".into(),
                lifecycle_state: 3,
                counter_names: vec![
                    "wrist_pose.rejected_stale".into(),
                    "joint_state.sent".into(),
                    "".into(),
                ],
                counter_values: vec![17, 123_456_789_012, u64::MAX],
                last_error: "camera: no frame for 2.0 s".into(),
            },
        ),
        case("node_status_empty", NodeStatus::default()),
        case(
            "joint_command_impedance",
            JointCommand {
                header: Header::default(),
                mode: "impedance".into(),
                name: names[..3].to_vec(),
                position: vec![0.25, -0.5, 1.0],
                velocity: vec![0.0, 0.125, -2.0],
                effort: vec![0.01, 0.0, -0.2],
                stiffness: vec![20.0, 1.0, 0.5],
                damping: vec![0.2, 0.05, 0.0],
                max_effort: vec![2.0, 2.0, 5.0],
            },
        ),
        case(
            "compressed_image_jpeg",
            CompressedImage {
                header: Header::new(stamp, "remote_camera_top_optical_frame"),
                format: "jpeg".into(),
                data: vec![0xff, 0xd8, 0xff, 0xdb, 0x00, 0x43, 0x00, 0xff, 0xd9],
            },
        ),
        case(
            "joint_command_effort",
            JointCommand {
                mode: "effort".into(),
                name: names[..2].to_vec(),
                effort: vec![1.5, -2.0],
                ..JointCommand::default()
            },
        ),
    ]
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn temp_dir() -> PathBuf {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos();
    let dir = std::env::temp_dir().join(format!(
        "teleop-msgs-interop-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const INSTALL_HINT: &str = "install it with `pip install -r tests/interop/requirements.txt` \
     (run from the workspace root), or point TELEOP_PYTHON at a Python that has it; \
     set TELEOP_SKIP_INTEROP=1 to skip this test";

#[test]
fn rosbags_interop() {
    if std::env::var("TELEOP_SKIP_INTEROP").is_ok_and(|v| v == "1") {
        let line = "!!!!!!!! SKIPPED rosbags interop test (TELEOP_SKIP_INTEROP=1): \
                    CDR compatibility with rosbags NOT checked !!!!!!!!";
        // Straight to the process's stderr: libtest captures `println!`/`eprintln!`.
        let _ = writeln!(std::io::stderr(), "\n{line}\n");
        return;
    }
    let python = std::env::var("TELEOP_PYTHON").unwrap_or_else(|_| "python3".into());

    // rosbags must be importable: a missing one is a failure, not a silent skip.
    let probe = Command::new(&python)
        .args([
            "-c",
            "import importlib.metadata as m, rosbags.typesys, rosbags.serde; print(m.version('rosbags'))",
        ])
        .output();
    let version = match probe {
        Ok(out) if out.status.success() => String::from_utf8_lossy(&out.stdout).trim().to_owned(),
        Ok(out) => panic!(
            "`{python}` cannot import rosbags:\n{}\n=> {INSTALL_HINT}",
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => panic!("cannot run `{python}` ({e}) => {INSTALL_HINT}"),
    };
    let pinned = std::fs::read_to_string(workspace_root().join("tests/interop/requirements.txt"))
        .unwrap()
        .lines()
        .find_map(|l| l.trim().strip_prefix("rosbags==").map(str::to_owned))
        .unwrap();
    if version != pinned {
        eprintln!("warning: rosbags {version} installed, requirements.txt pins {pinned}");
    }

    let dir = temp_dir();
    let cases = cases();
    for c in &cases {
        std::fs::write(dir.join(format!("{}.rust.cdr", c.name)), &c.bytes).unwrap();
        std::fs::write(
            dir.join(format!("{}.json", c.name)),
            serde_json::to_vec_pretty(&c.json).unwrap(),
        )
        .unwrap();
    }

    let script = workspace_root().join("tests/interop/rosbags_interop.py");
    let msg_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("msg");
    let out = Command::new(&python)
        .arg(&script)
        .arg(&dir)
        .arg(&msg_dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "rosbags_interop.py failed ({}); case files kept in {}\n{stdout}\n{stderr}",
        out.status,
        dir.display()
    );

    let mut failures = Vec::new();
    for c in &cases {
        let read = |suffix: &str| {
            std::fs::read(dir.join(format!("{}.{suffix}", c.name)))
                .unwrap_or_else(|e| panic!("{}.{suffix}: {e}", c.name))
        };
        if let Err(e) = (c.check)(c.name, &c.bytes, &read("py.cdr"), &read("py.be.cdr")) {
            failures.push(e);
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases differ (files kept in {}):\n{}",
        failures.len(),
        cases.len(),
        dir.display(),
        failures.join("\n")
    );
    assert_eq!(
        stdout.lines().filter(|l| l.ends_with(" ok")).count(),
        cases.len(),
        "every case must be reported ok by the script"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn shadow_hand_has_24_distinct_joints() {
    let names = shadow_joint_names();
    let mut sorted = names.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), 24);
    assert_eq!(names.first().map(String::as_str), Some("FFJ1"));
    assert_eq!(names.last().map(String::as_str), Some("WRJ2"));
}

#[test]
fn case_json_carries_every_field() {
    // The JSON is what rosbags rebuilds the message from: it must name every field of
    // the ROS definition (serde field names are the ROS field names).
    for c in cases() {
        let ty = c.json["type"].as_str().unwrap();
        let (desc, hash) = teleop_msgs::all_descriptions()
            .into_iter()
            .find(|(d, _)| d.type_name == ty)
            .unwrap();
        assert_eq!(c.json["type_hash"], hash);
        let msg = c.json["msg"].as_object().unwrap();
        let keys: Vec<&str> = msg.keys().map(String::as_str).collect();
        let mut fields: Vec<&str> = desc.fields.iter().map(|f| f.name).collect();
        fields.sort_unstable();
        let mut keys_sorted = keys.clone();
        keys_sorted.sort_unstable();
        assert_eq!(keys_sorted, fields, "{}", c.name);
    }
}
