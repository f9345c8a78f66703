//! `teleop export lerobot`, checked by LeRobot itself.
//!
//! A bag written here holds what a recording of a run holds (the operator's wrist
//! poses, pedals and finger targets, the robot's joint states, fingertip forces and
//! camera views, the simulator's status), stamped with jitter so that arrival order and
//! stamp order differ, with a 300 ms hole in the hand's joint states inside a clutch
//! engagement and one malformed message per topic. The export must cut the episode at
//! the hole (counting the frames), refuse the malformed messages (counting them), and
//! `tests/interop/check_lerobot.py`, with the `lerobot` package (PyPI, 0.4.4) and an
//! independent MCAP reader, must load the dataset and find every frame's values equal
//! to the bag's by the documented alignment rule, and every video frame the view it
//! should be. Python from `$TELEOP_LEROBOT_PYTHON` (tests/interop/lerobot-setup.sh
//! makes it; tests/run.sh sets it).

use std::path::{Path, PathBuf};
use std::process::Command;

use teleop_bag::{BagOptions, BagWriter};
use teleop_interfaces::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_interfaces::topics;
use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, JointCommand, JointState, NodeStatus,
    OperatorInput, Point, Pose, PoseStamped, Quaternion, Time, encode,
};

const T0: i64 = 1_765_000_000_000_000_000;
const S: i64 = 1_000_000_000;
const FPS: u32 = 30;

fn header(t: i64) -> Header {
    Header {
        stamp: Time::from_nanos(t),
        frame_id: String::new(),
    }
}

/// Deterministic jitter in [-amp, amp] ns.
fn jitter(i: i64, amp: i64) -> i64 {
    let h = (i.wrapping_mul(2_654_435_761)).rem_euclid(2 * amp + 1);
    h - amp
}

fn jpeg(i: u32) -> Vec<u8> {
    // Distinct views: a colour and a bar position from the index.
    let img = image::RgbImage::from_fn(64, 48, |x, y| {
        let bar = (i * 5) % 64;
        if x.abs_diff(bar) < 4 {
            image::Rgb([255, 255, 255])
        } else {
            image::Rgb([(i * 37 % 256) as u8, (y * 5) as u8, (i * 91 % 256) as u8])
        }
    });
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 92)
        .encode_image(&img)
        .expect("encode a view");
    out
}

struct Msg {
    stamp: i64,
    /// Arrival (the bag's log time).
    log: i64,
    /// Where it goes in the file (by this key).
    file_key: i64,
    topic: usize,
    bytes: Vec<u8>,
}

/// Writes the bag; returns its directory.
fn write_bag(dir: &Path) -> PathBuf {
    let bag_dir = dir.join("bag");
    let specs = [
        topics::PR2_JOINT_STATES.spec,
        topics::SHADOW_JOINT_STATES.spec,
        topics::FINGERTIP_PRESSURES.spec,
        topics::WRIST_POSE.spec,
        topics::OPERATOR_INPUT.spec,
        topics::HAND_JOINT_TARGETS.spec,
        topics::REMOTE_CAMERA_TOP.spec,
        topics::REMOTE_CAMERA_SIDE.spec,
        topics::NODE_STATUS.spec,
        topics::HW_PR2_ARM_COMMAND.spec,
        topics::HW_HAND_COMMAND.spec,
    ];
    let mut msgs: Vec<Msg> = Vec::new();
    let mut msgs_dup: Vec<(i64, Vec<u8>)> = Vec::new();
    // Arrival: the stamp plus a transport delay that varies, so arrival order and
    // stamp order differ.
    let mut push = |stamp: i64, topic: usize, bytes: Vec<u8>| {
        let log = stamp + 3_000_000 + jitter(stamp / 1000, 2_000_000);
        msgs.push(Msg {
            stamp,
            log,
            file_key: log,
            topic,
            bytes,
        });
    };
    let joints = |names: &[&str], t: i64, k: f64, reversed: bool| {
        let s = (t - T0) as f64 / 1e9;
        let mut pairs: Vec<(String, f64)> = names
            .iter()
            .enumerate()
            .map(|(j, n)| {
                (
                    (*n).to_owned(),
                    k * (s * (j as f64 + 1.0)).sin() + j as f64 * 0.01,
                )
            })
            .collect();
        if reversed {
            pairs.reverse();
        }
        JointState {
            header: header(t),
            name: pairs.iter().map(|p| p.0.clone()).collect(),
            position: pairs.iter().map(|p| p.1).collect(),
            velocity: vec![],
            effort: vec![],
        }
    };
    // 6 s of recording.
    for i in 0..600 {
        let t = T0 + i * 10_000_000 + jitter(i, 3_000_000);
        push(
            t,
            0,
            encode(&joints(&PR2_ARM_JOINTS, t, 0.5, true)).expect("arm"),
        );
        let hole = (42..45).contains(&(i / 10));
        if !hole {
            push(
                t + 1_000_000,
                1,
                encode(&joints(&SHADOW_FINGER_JOINTS, t, 0.7, false)).expect("hand"),
            );
        }
        let f = FingertipPressures {
            header: header(t),
            ff: i as f64 * 0.01,
            mf: 0.2,
            rf: 0.3,
            lf: 0.4,
            th: (i % 7) as f64,
        };
        push(t, 2, encode(&f).expect("forces"));
        if i % 25 == 0 {
            // A second message of the same stamp with other values, arriving later but
            // written earlier in the file: the later arrival is the one a frame takes.
            let again = FingertipPressures { mf: 0.9, ..f };
            msgs_dup.push((t, encode(&again).expect("forces")));
        }
    }
    for i in 0..1920 {
        let t = T0 + i * S / 320 + jitter(i, 1_000_000);
        let s = (t - T0) as f64 / 1e9;
        let p = PoseStamped {
            header: header(t),
            pose: Pose {
                position: Point {
                    x: 0.4 + 0.05 * s.sin(),
                    y: -0.1 * s,
                    z: 1.0,
                },
                orientation: Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: (s / 4.0).sin(),
                    w: (s / 4.0).cos(),
                },
            },
        };
        push(t, 3, encode(&p).expect("wrist"));
    }
    for i in 0..300 {
        let t = T0 + i * 20_000_000 + jitter(i, 2_000_000);
        let s = (i * 20) as f64 / 1e3;
        let clutch = (1.0..3.0).contains(&s) || (3.5..5.5).contains(&s) || (0.3..0.6).contains(&s);
        // Clutch without the enable switch is no engagement.
        let enable = !(0.3..0.6).contains(&s);
        let o = OperatorInput {
            header: header(t),
            clutch,
            enable,
            camera_stop: false,
            motion_scale: if s < 3.2 { 1.0 } else { 0.33 },
        };
        push(t, 4, encode(&o).expect("pedals"));
    }
    for i in 0..180 {
        let t = T0 + i * S / 30 + jitter(i, 4_000_000);
        push(
            t,
            5,
            encode(&joints(&SHADOW_FINGER_JOINTS, t, 0.9, true)).expect("fingers"),
        );
    }
    // The robot site's hardware commands (a `teleop record --all` recording): arm
    // velocities at 30 Hz, hand impedance set points at 100 Hz.
    for i in 0..180 {
        let t = T0 + i * S / 30 + jitter(i + 7, 3_000_000);
        let mut cmd = joints(&PR2_ARM_JOINTS, t, 0.3, true);
        cmd.velocity = std::mem::take(&mut cmd.position);
        push(t, 9, encode(&cmd).expect("arm command"));
    }
    for i in 0..600 {
        let t = T0 + i * 10_000_000 + jitter(i + 11, 2_000_000);
        let set = joints(&SHADOW_FINGER_JOINTS, t, 0.8, false);
        let c = JointCommand {
            header: header(t),
            mode: "impedance".to_owned(),
            name: set.name,
            position: set.position,
            stiffness: vec![2.0; 17],
            damping: vec![0.1; 17],
            ..JointCommand::default()
        };
        push(t, 10, encode(&c).expect("hand command"));
    }
    for i in 0..90u32 {
        let t = T0 + i64::from(i) * S / 15 + jitter(i64::from(i), 5_000_000);
        for (topic, salt) in [(6, 0), (7, 1000)] {
            let c = CompressedImage {
                header: header(t),
                format: "rgb8; jpeg compressed bgr8".to_owned(),
                data: jpeg(i + salt),
            };
            push(t, topic, encode(&c).expect("view"));
        }
    }
    for i in 0..6 {
        let t = T0 + i * S + 500_000_000;
        let done = t > T0 + 2 * S + 400_000_000;
        let status = NodeStatus {
            header: header(t),
            node_name: "remote_sim".to_owned(),
            counter_names: [
                "job.lifted",
                "job.succeeded",
                "job.completion_ms",
                "job.failed.timed_out",
            ]
            .map(str::to_owned)
            .to_vec(),
            counter_values: vec![
                u64::from(done),
                u64::from(done),
                if done { 1500 } else { 0 },
                0,
            ],
            ..NodeStatus::default()
        };
        push(t, 8, encode(&status).expect("status"));
    }
    // One malformed message per topic: NaN, a stamp at the epoch, a missing joint, a
    // PNG view, bytes that are no CDR.
    let mut nan = joints(&PR2_ARM_JOINTS, T0 + 2 * S, 0.5, false);
    nan.position[2] = f64::NAN;
    push(T0 + 2 * S, 0, encode(&nan).expect("nan"));
    let zero = joints(&SHADOW_FINGER_JOINTS, 0, 0.7, false);
    push(T0 + 2 * S, 1, encode(&zero).expect("zero"));
    let mut short = joints(&SHADOW_FINGER_JOINTS, T0 + 2 * S, 0.9, false);
    short.name.pop();
    short.position.pop();
    push(T0 + 2 * S, 5, encode(&short).expect("short"));
    let png = CompressedImage {
        header: header(T0 + 2 * S),
        format: "rgb8; png compressed bgr8".to_owned(),
        data: vec![0x89, b'P', b'N', b'G'],
    };
    push(T0 + 2 * S, 6, encode(&png).expect("png"));
    push(T0 + 2 * S, 3, vec![0, 1, 0, 0, 7]);
    // An effort command has no position set points.
    let effort = JointCommand {
        header: header(T0 + 2 * S),
        mode: "effort".to_owned(),
        name: SHADOW_FINGER_JOINTS.map(str::to_owned).to_vec(),
        effort: vec![0.0; 17],
        ..JointCommand::default()
    };
    push(T0 + 2 * S, 10, encode(&effort).expect("effort"));

    for (t, bytes) in msgs_dup {
        msgs.push(Msg {
            stamp: t,
            log: t + 9_000_000,
            file_key: t - 1,
            topic: 2,
            bytes,
        });
    }
    msgs.sort_by_key(|m| m.file_key);
    let mut bag = BagWriter::create(&bag_dir, BagOptions::default()).expect("bag");
    let ids: Vec<_> = specs
        .iter()
        .map(|s| bag.add_topic(s).expect("topic"))
        .collect();
    for (seq, m) in msgs.iter().enumerate() {
        let log = u64::try_from(m.log).expect("positive");
        bag.write(
            ids[m.topic],
            log,
            u64::try_from(m.stamp).expect("positive"),
            seq as u32 + 1,
            &m.bytes,
        )
        .expect("write");
    }
    bag.close().expect("close");
    bag_dir
}

fn export(bag: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let summary = out.with_extension("summary.json");
    let run = Command::new(env!("CARGO_BIN_EXE_teleop"))
        .args(["export", "lerobot"])
        .arg(bag)
        .arg("--out")
        .arg(out)
        .args(["--fps", &FPS.to_string(), "--summary-json"])
        .arg(&summary)
        .args(extra)
        .output()
        .expect("run teleop export lerobot");
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    println!("{stdout}\n{stderr}");
    assert!(run.status.success(), "export failed:\n{stdout}\n{stderr}");
    serde_json::from_str(&std::fs::read_to_string(&summary).expect("summary")).expect("json")
}

fn lerobot_python() -> String {
    std::env::var("TELEOP_LEROBOT_PYTHON").unwrap_or_else(|_| {
        let home = std::env::var("HOME").unwrap_or_default();
        format!("{home}/.cache/teleop-lerobot-venv/bin/python")
    })
}

/// `check_lerobot.py BAG DATASET` with the export's settings of these tests, offline.
fn check_command(python: &str, script: &Path, bag: &Path, dataset: &Path, dir: &Path) -> Command {
    let mut c = Command::new(python);
    c.arg(script)
        .arg(bag)
        .arg(dataset)
        .args([
            "--fps",
            "30",
            "--max-age-ms",
            "100",
            "--min-episode-s",
            "0.5",
            "--task",
        ])
        .arg(teleop_dataset::lerobot::default_task(
            teleop_dataset::EpisodeSource::Clutch,
        ))
        .env("HF_HUB_OFFLINE", "1")
        .env("HF_HOME", dir.join("hf"));
    c
}

#[test]
fn lerobot_loads_the_export_with_every_frame_equal_to_the_bags() {
    let dir = std::env::temp_dir().join(format!("teleop-lerobot-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let bag = write_bag(&dir);
    let out = dir.join("dataset");
    let s = export(
        &bag,
        &out,
        &["--max-age-ms", "100", "--min-episode-s", "0.5"],
    );

    // Two engagements (the one without the enable switch is none); the second cut at
    // the hand's hole: 300 ms of holes less the 100 ms a message may be old.
    assert_eq!(s["intervals"], 2, "{s}");
    assert_eq!(s["intervals_cut"], 1, "{s}");
    assert_eq!(s["episodes"], 3, "{s}");
    let hole = s["frames_missing_input"]["hand_state"]
        .as_u64()
        .expect("hand_state missing");
    assert!(
        (5..=8).contains(&hole),
        "{hole} frames missing the hand state: {s}"
    );
    assert_eq!(s["frames_missing"].as_u64(), Some(hole), "{s}");
    // Two 2 s engagements at 30 fps, their edges jittered by the pedals' stamps: 59 or
    // 60 frames each (the Python check derives the exact count from the bag).
    let frames = s["frames"].as_u64().expect("frames");
    assert!((116..=120).contains(&(frames + hole)), "{s}");
    assert_eq!(s["video_frames"].as_u64(), Some(2 * frames), "{s}");
    for topic in [
        "/teleop/pr2/joint_states",
        "/teleop/shadow/joint_states",
        "/teleop/hand/joint_targets",
        "/teleop/remote_camera/top/image/compressed",
        "/teleop/wrist_pose",
    ] {
        assert_eq!(s["rejected"][topic], 1, "{topic}: {s}");
    }
    for f in [
        "meta/info.json",
        "meta/stats.json",
        "meta/tasks.parquet",
        "meta/episodes/chunk-000/file-000.parquet",
        "data/chunk-000/file-000.parquet",
        "videos/observation.images.top/chunk-000/file-000.mp4",
        "videos/observation.images.side/chunk-000/file-000.mp4",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }

    let python = lerobot_python();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/interop/check_lerobot.py");
    let check = check_command(&python, &script, &bag, &out, &dir)
        .output()
        .unwrap_or_else(|e| panic!("{python}: {e} (bash tests/interop/lerobot-setup.sh makes it)"));
    let stdout = String::from_utf8_lossy(&check.stdout);
    let stderr = String::from_utf8_lossy(&check.stderr);
    println!("{stdout}\n{stderr}");
    assert!(
        check.status.success(),
        "{python} {}: {stdout}\n{stderr}",
        script.display()
    );
    let got: serde_json::Value =
        serde_json::from_str(stdout.lines().last().unwrap_or("")).expect("json");
    assert_eq!(got["frames"], s["frames"], "{got}");
    assert_eq!(got["episodes"], 3, "{got}");
    assert_eq!(got["frames_missing"].as_u64(), Some(hole), "{got}");
    assert_eq!(got["wrong_views"], 0, "{got}");

    // The robot-side commands as the action: the same episodes, the effort command
    // refused, every action value equal to the bag's (the Python check, `--action robot`).
    let robot = dir.join("robot");
    let r = export(
        &bag,
        &robot,
        &[
            "--action",
            "robot",
            "--max-age-ms",
            "100",
            "--min-episode-s",
            "0.5",
        ],
    );
    assert_eq!(r["episodes"], 3, "{r}");
    assert_eq!(r["rejected"]["/teleop/hw/shadow_hand/command"], 1, "{r}");
    let check = check_command(&python, &script, &bag, &robot, &dir)
        .args(["--action", "robot"])
        .output()
        .expect("run check_lerobot.py");
    let stdout = String::from_utf8_lossy(&check.stdout);
    let stderr = String::from_utf8_lossy(&check.stderr);
    assert!(check.status.success(), "--action robot: {stdout}\n{stderr}");
    let got: serde_json::Value =
        serde_json::from_str(stdout.lines().last().unwrap_or("")).expect("json");
    assert_eq!(got["frames"], r["frames"], "{got}");
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(robot.join("meta/info.json")).expect("info"))
            .expect("json");
    assert_eq!(info["features"]["action"]["shape"][0], 24);
    assert_eq!(
        info["features"]["action"]["names"][0],
        "r_shoulder_pan_joint_velocity_cmd"
    );

    // The job's episode: from the first engagement to the simulator's verdict (the
    // status at 2.5 s), cameras left out.
    let job = dir.join("job");
    let s = export(&bag, &job, &["--episodes", "job", "--no-cameras"]);
    assert_eq!(s["episodes"], 1, "{s}");
    assert_eq!(s["frames"], 45, "{s}");
    assert_eq!(s["video_frames"], 0, "{s}");
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(job.join("meta/info.json")).expect("info"))
            .expect("json");
    assert_eq!(info["total_frames"], 45);
    assert_eq!(info["video_path"], serde_json::Value::Null);
    assert!(info["features"].get("observation.images.top").is_none());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_exports_are_refused_by_name() {
    let dir = std::env::temp_dir().join(format!("teleop-lerobot-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    let teleop = env!("CARGO_BIN_EXE_teleop");
    let run = |args: &[&str]| {
        let o = Command::new(teleop).args(args).output().expect("run");
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let out = dir.join("out");
    let out = out.to_str().expect("utf-8");
    let (ok, err) = run(&["export", "lerobot", "/nonexistent/bag", "--out", out]);
    assert!(!ok && err.contains("/nonexistent/bag"), "{err}");
    let (ok, err) = run(&[
        "export",
        "lerobot",
        "x",
        "--out",
        out,
        "--episodes",
        "sometimes",
    ]);
    assert!(!ok && err.contains("sometimes"), "{err}");
    let (ok, err) = run(&["export", "lerobot", "x", "--out", out, "--fps", "0"]);
    assert!(!ok && err.contains("fps"), "{err}");
    // A bag without the robot's state.
    let bag = dir.join("bag");
    let mut w = BagWriter::create(&bag, BagOptions::default()).expect("bag");
    let id = w.add_topic(&topics::WRIST_POSE.spec).expect("topic");
    let p = PoseStamped {
        header: header(T0),
        pose: Pose::default(),
    };
    w.write(id, T0 as u64, T0 as u64, 1, &encode(&p).expect("pose"))
        .expect("write");
    w.close().expect("close");
    let (ok, err) = run(&[
        "export",
        "lerobot",
        bag.to_str().expect("utf-8"),
        "--out",
        out,
    ]);
    assert!(!ok && err.contains("/teleop/pr2/joint_states"), "{err}");
    assert!(!Path::new(out).exists(), "nothing left behind");
    // Found wanting after the dataset was begun (no run of complete frames lasts 100 s):
    // refused, and what was begun is gone.
    std::fs::create_dir_all(dir.join("full")).expect("dir");
    let full = write_bag(&dir.join("full"));
    let (ok, err) = run(&[
        "export",
        "lerobot",
        full.to_str().expect("utf-8"),
        "--out",
        out,
        "--min-episode-s",
        "100",
    ]);
    assert!(!ok && err.contains("no episode to export"), "{err}");
    assert!(!Path::new(out).exists(), "nothing left behind");
    let _ = std::fs::remove_dir_all(&dir);
}
