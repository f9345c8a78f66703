//! An independent ROS 2 client decodes every topic type of the project off the wire:
//! `tests/interop/pyzeros_decode.py`, on pyzeros (PyPI), with the project's own `.msg`
//! types (and tf2_msgs/TFMessage) defined on its side. pyzeros puts its own RIHS01 type
//! hashes in the rmw_zenoh data keys it subscribes to, so a sample reaches it only when
//! its hash equals ours; every field it decodes must equal what was sent.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::time::{Duration, Instant};

use serde::Serialize;
use teleop_bus::Bus;
use teleop_interfaces::{Direction, Publishers, QosClass, Topic};
use teleop_msgs::{
    CompressedImage, FingertipPressures, Float64MultiArray, Header, Image, JointCommand,
    JointState, Message, MultiArrayDimension, MultiArrayLayout, NodeStatus, OperatorInput, Point,
    Pose, PoseStamped, Quaternion, TFMessage, Time, Transform, TransformStamped, Vector3,
};
use teleop_system_tests::{
    bare_sim_config, free_port, isolated_pair, pyzeros_python, repo_root, said_ready,
};

const INSTALL_HINT: &str = "install the interop packages with `pip install -r \
     tests/interop/requirements.txt`, or point TELEOP_PYTHON at a Python that has them";

fn header(k: u32) -> Header {
    Header::new(
        Time {
            sec: 1_765_000_000 + i32::try_from(k).unwrap(),
            nanosec: 123_456_789 + k,
        },
        format!("frame_{k}"),
    )
}

/// A publisher of `msg` on `topic`, sending it until told to stop.
struct Sender {
    name: &'static str,
    type_name: &'static str,
    type_hash: &'static str,
    sent: serde_json::Value,
    put: Box<dyn Fn() + Send + Sync>,
}

async fn sender<T: Message + Serialize>(bus: &Bus, name: &'static str, msg: T) -> Sender {
    let topic: Topic<T> = Topic::new(
        name,
        Direction::Both,
        10.0,
        QosClass::Diagnostics,
        None,
        Publishers::EveryNode,
        "interop test",
    );
    let publisher = bus.publisher(&topic).await.unwrap();
    let sent = serde_json::to_value(&msg).unwrap();
    Sender {
        name,
        type_name: T::TYPE_NAME,
        type_hash: T::TYPE_HASH,
        sent,
        put: Box::new(move || publisher.put(&msg).unwrap()),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pyzeros_decodes_every_topic_type_with_the_values_sent() {
    let domain = 84;
    let port = free_port().unwrap();
    let bus = Bus::open("interop_sender", &isolated_pair(domain, port).0)
        .await
        .unwrap();
    let pose = |k: f64| Pose {
        position: Point {
            x: 0.1 * k,
            y: -0.25,
            z: 1.0 / 3.0,
        },
        orientation: Quaternion {
            x: 0.0,
            y: 0.6,
            z: 0.0,
            w: 0.8,
        },
    };
    let senders = vec![
        sender(
            &bus,
            "interop/pose_stamped",
            PoseStamped {
                header: header(1),
                pose: pose(1.0),
            },
        )
        .await,
        sender(
            &bus,
            "interop/joint_state",
            JointState {
                header: header(2),
                name: vec!["a".into(), "b_joint".into()],
                position: vec![0.5, -1.25e-3],
                velocity: vec![f64::MAX, f64::MIN_POSITIVE],
                effort: vec![],
            },
        )
        .await,
        sender(
            &bus,
            "interop/operator_input",
            OperatorInput {
                header: header(3),
                clutch: true,
                enable: false,
                camera_stop: true,
                motion_scale: 0.75,
            },
        )
        .await,
        sender(
            &bus,
            "interop/fingertip_pressures",
            FingertipPressures {
                header: header(4),
                ff: 0.5,
                mf: 1.5,
                rf: 2.5,
                lf: 3.5,
                th: 4.25,
            },
        )
        .await,
        sender(
            &bus,
            "interop/image",
            Image {
                header: header(5),
                height: 2,
                width: 3,
                encoding: "16UC1".into(),
                is_bigendian: 0,
                step: 6,
                data: (0..12).map(|i| i * 21).collect(),
            },
        )
        .await,
        sender(
            &bus,
            "interop/compressed_image",
            CompressedImage {
                header: header(6),
                format: "jpeg".into(),
                data: vec![0xff, 0xd8, 0xff, 0x00, 0x7f],
            },
        )
        .await,
        sender(
            &bus,
            "interop/joint_command",
            JointCommand {
                header: header(7),
                mode: "impedance".into(),
                name: vec!["rh_FFJ3".into()],
                position: vec![0.25],
                velocity: vec![0.0],
                effort: vec![-0.125],
                stiffness: vec![2.0],
                damping: vec![0.05],
                max_effort: vec![0.4],
            },
        )
        .await,
        sender(
            &bus,
            "interop/node_status",
            NodeStatus {
                header: header(8),
                node_name: "remote_sim".into(),
                lifecycle_state: 2,
                counter_names: vec!["x.received".into(), "y".into()],
                counter_values: vec![u64::MAX, 7],
                last_error: "recovered at 08:20:27.2 UTC: ü".into(),
            },
        )
        .await,
        sender(&bus, "interop/header", header(9)).await,
        sender(
            &bus,
            "interop/tf_message",
            TFMessage {
                transforms: vec![TransformStamped {
                    header: header(10),
                    child_frame_id: "can".into(),
                    transform: Transform {
                        translation: Vector3 {
                            x: 0.5,
                            y: 0.0,
                            z: 0.75,
                        },
                        rotation: pose(0.0).orientation,
                    },
                }],
            },
        )
        .await,
        sender(
            &bus,
            "interop/float64_multi_array",
            Float64MultiArray {
                layout: MultiArrayLayout {
                    dim: vec![MultiArrayDimension {
                        label: "joints".into(),
                        size: 3,
                        stride: 3,
                    }],
                    data_offset: 0,
                },
                data: vec![0.1, -0.2, 0.3],
            },
        )
        .await,
    ];
    assert_eq!(
        senders.len(),
        teleop_msgs::topic_types().len(),
        "every topic type"
    );
    let topics: Vec<String> = senders
        .iter()
        .map(|s| format!("/{}={}", s.name, s.type_name))
        .collect();
    let script = repo_root().join("tests/interop/pyzeros_decode.py");
    let mut child = pyzeros_python(script.to_str().unwrap())
        .args(["--connect", &format!("tcp/127.0.0.1:{port}")])
        .args([
            "--domain",
            &domain.to_string(),
            "--topics",
            &topics.join(","),
        ])
        .args(["--timeout-s", "120"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run the interop Python ({e}) => {INSTALL_HINT}"));
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut decoded: BTreeMap<String, serde_json::Value> = BTreeMap::new();
    let mut ready = false;
    let started = Instant::now();
    while decoded.len() < senders.len() && started.elapsed() < Duration::from_secs(240) {
        while let Ok(line) = rx.try_recv() {
            if line.trim() == "ready" {
                ready = true;
            } else if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line) {
                decoded.insert(v["topic"].as_str().unwrap().to_owned(), v);
            }
        }
        if ready {
            for s in &senders {
                (s.put)();
            }
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let _ = child.kill();
    let _ = child.wait();
    assert!(ready, "the decoder never said ready => {INSTALL_HINT}");
    for s in &senders {
        let topic = format!("/{}", s.name);
        let got = decoded.get(&topic).unwrap_or_else(|| {
            panic!(
                "pyzeros decoded nothing on {topic} ({}): its type hash differs from ours \
                 ({}) or its decoder failed",
                s.type_name, s.type_hash
            )
        });
        assert_eq!(got["type"], s.type_name, "{topic}");
        assert_eq!(
            got["hash"], s.type_hash,
            "{topic}: pyzeros's own RIHS01 hash"
        );
        assert_eq!(
            got["msg"], s.sent,
            "{topic}: decoded values differ from those sent"
        );
    }
}

/// ROS 2 nodes on pyzeros as the operator station (`tests/interop/pyzeros_operator.py`:
/// nodes `wrist_tracker` and `hand_inference`) drive the robot site: the PR2 arm
/// controller (the shipped node's code, ticked here) engages on their pedals and moves
/// the simulated arm with their wrist pose; their publishers are identified by the bus's
/// publisher directory (GIDs as rmw_zenoh computes them) as the `wrist_tracker` node's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ros2_nodes_on_pyzeros_as_the_operator_station_drive_the_arm() {
    use teleop_interfaces::topics;
    use teleop_node::Node;
    use teleop_remote_site::arm_node::{ArmNode, ArmNodeConfig};
    use teleop_sim_nodes::remote_sim::SimNode;

    let domain = 86;
    let port = free_port().unwrap();
    let (hub, spoke) = isolated_pair(domain, port);
    let mut sim_cfg = bare_sim_config(hub.clone());
    // The working posture (the default rests at the elbow's limit).
    sim_cfg.world.arm.initial_position_rad = teleop_sim::WORKING_POSTURE_RAD;
    let sim_bus = Bus::open("remote_sim", &hub).await.unwrap();
    let mut sim = SimNode::new(&sim_cfg, &sim_bus).await.unwrap();
    let arm_cfg = ArmNodeConfig {
        bus: spoke.clone(),
        ..ArmNodeConfig::default()
    };
    let arm_bus = Bus::open("pr2_arm_controller", &spoke).await.unwrap();
    let mut arm = ArmNode::new(&arm_cfg, &arm_bus).await.unwrap();
    // The hand's controller, alive (the arm moves only while the hand's nodes are).
    let _hand = Bus::open("shadow_hand_controller", &spoke).await.unwrap();
    let watcher = Bus::open("interop_watcher", &spoke).await.unwrap();
    let poses = watcher.subscriber(&topics::WRIST_POSE).await.unwrap();

    let script = repo_root().join("tests/interop/pyzeros_operator.py");
    let mut child = pyzeros_python(script.to_str().unwrap())
        .args(["--connect", &format!("tcp/127.0.0.1:{port}")])
        .args(["--domain", &domain.to_string(), "--duration-s", "7"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run the interop Python ({e}) => {INSTALL_HINT}"));
    let stdout = child.stdout.take().unwrap();
    assert!(
        said_ready(stdout).await,
        "the station did not say ready within 300 s => {INSTALL_HINT}"
    );
    let q0 = sim.world().lock().unwrap().arm_state().position_rad;
    // The robot site runs while the station's script does (the arm at 30 Hz, the
    // simulator at 100 Hz).
    let mut senders = std::collections::BTreeSet::new();
    let started = Instant::now();
    let mut k = 0u64;
    while started.elapsed() < Duration::from_secs(40) {
        let now = sim_bus.now_s();
        sim.tick(now);
        if k.is_multiple_of(3) {
            arm.tick(now);
        }
        while let Some(r) = poses.try_recv() {
            if let Some(info) = poses.publisher_info(&r.publisher_gid) {
                senders.insert(info.node_name);
            }
        }
        k += 1;
        if matches!(child.try_wait(), Ok(Some(_))) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let _ = child.kill();
    let _ = child.wait();
    let q1 = sim.world().lock().unwrap().arm_state().position_rad;
    let counter = |name: &str| {
        arm.counters()
            .into_iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
            .unwrap_or_else(|| panic!("counter {name}"))
    };
    let nonzero: Vec<(String, u64)> = arm.counters().into_iter().filter(|(_, v)| *v > 0).collect();
    assert_eq!(
        counter("arm.engagements"),
        1,
        "{}; {nonzero:?}",
        arm.last_error()
    );
    // The station moved the wrist 0.10 m along x: the palm follows (relative control,
    // operator and robot frames aligned).
    let chain = teleop_kinematics::robots::pr2_arm_chain().unwrap();
    let palm = |q: nalgebra::SVector<f64, 7>| chain.end_pose(&q).translation.vector;
    let moved = palm(q1) - palm(q0);
    assert!(
        (0.09..0.11).contains(&moved.x) && moved.yz().norm() < 0.01,
        "the palm moved {moved:?} m for the wrist's 0.10 m along x: {}; simulator: {:?}",
        arm.last_error(),
        sim.counters()
            .into_iter()
            .filter(|(n, v)| *v > 0 && n.starts_with("pr2_arm") || n.starts_with("safety.arm"))
            .collect::<Vec<_>>()
    );
    eprintln!(
        "pyzeros operator station: the palm moved {:.4} m along x ({:.4} m across) for the \
         wrist's 0.10 m",
        moved.x,
        moved.yz().norm()
    );
    assert_eq!(
        senders.into_iter().collect::<Vec<_>>(),
        vec!["wrist_tracker".to_owned()],
        "the ROS 2 node's publisher, identified by its GID"
    );
}
