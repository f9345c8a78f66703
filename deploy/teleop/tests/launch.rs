//! `teleop launch` starts every node, lets the simulated operator clutch and move, stops
//! the system gracefully on `--duration-s` and prints each node's final status.
//!
//! Needs the node binaries next to `teleop` (`cargo build --release --workspace --bins`;
//! `tests/run.sh` builds them first).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::Command;

mod common;

use teleop_interfaces::nodes::NODES;

/// One whole system at a time: three at once (24 processes) starve a 2-core machine,
/// and a starved system stops its robots on stale inputs, as it should.
static ONE_SYSTEM: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn one_system() -> std::sync::MutexGuard<'static, ()> {
    ONE_SYSTEM
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Every node of the table has a summary line: stopped gracefully, its final status
/// reported, exit status 0.
fn assert_every_node_stopped_gracefully(stdout: &str) {
    for node in NODES {
        let line = stdout
            .lines()
            .find(|l| l.starts_with(&format!("{} ", node.name)))
            .unwrap_or_else(|| panic!("no summary line for {}:\n{stdout}", node.name));
        assert!(line.contains("graceful"), "{line}");
        assert!(line.contains("reported"), "{line}");
        assert!(line.contains("exit status: 0"), "{line}");
    }
}

/// Runs `teleop` with `args` to its end, prints its output and asserts it succeeded;
/// returns its standard output.
fn launch_ok(args: &[&std::ffi::OsStr]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_teleop"))
        .args(args)
        .output()
        .expect("run teleop launch");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "launch failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    stdout
}

#[test]
fn launch_runs_the_system_and_stops_it_gracefully_with_a_summary() {
    let _one = one_system();
    let teleop = Path::new(env!("CARGO_BIN_EXE_teleop"));
    let dir = teleop.parent().unwrap();
    for node in NODES {
        assert!(
            dir.join(node.name).is_file(),
            "{} missing next to teleop: build the node binaries first \
             (cargo build --release --workspace --bins; tests/run.sh does)",
            node.name
        );
    }
    let stdout = launch_ok(
        &[
            "--domain-id",
            "91",
            "launch",
            "--duration-s",
            "7",
            "--quiet",
            "--no-report-files",
        ]
        .map(std::ffi::OsStr::new),
    );
    assert!(stdout.contains("== teleop launch: summary"), "{stdout}");
    assert_every_node_stopped_gracefully(&stdout);
    // The simulated operator pressed the clutch after 2 s and started the task: the
    // arm and the hand (its finger targets from hand inference, the depth camera on
    // the UR5 following the hand) were engaged when the system stopped.
    let state = |name: &str| {
        stdout
            .lines()
            .find(|l| l.starts_with(&format!("{name} ")))
            .unwrap()
            .split_whitespace()
            .nth(2)
            .unwrap()
            .to_owned()
    };
    assert_eq!(state("pr2_arm_controller"), "Active", "{stdout}");
    assert_eq!(state("shadow_hand_controller"), "Active", "{stdout}");
    assert_eq!(state("camera_arm"), "Active", "{stdout}");
    assert_eq!(state("hand_inference"), "Active", "{stdout}");
    assert_eq!(state("remote_sim"), "Active", "{stdout}");
    assert_eq!(state("local_sim"), "Active", "{stdout}");
    // The operator display saw the robot site's feedback, and the camera views it
    // acknowledged were all it was sent, paced by its receipts.
    assert_eq!(state("operator_display"), "Active", "{stdout}");
    assert!(stdout.contains("arm.engagements=1"), "{stdout}");
    assert!(stdout.contains("hand.engagements=1"), "{stdout}");
    assert!(
        stdout.contains("== teleop launch: end-of-run report"),
        "{stdout}"
    );
    // What the running nodes publish is what the topic table says (the table the
    // sites' routers enforce): nothing more, nothing missing.
    let check = stdout
        .lines()
        .find(|l| l.starts_with("publishers vs the topic table"))
        .unwrap_or_else(|| panic!("no publisher check:\n{stdout}"));
    assert!(
        check.contains("are in the table") && check.contains("of the 9 running nodes"),
        "{check}"
    );
}

/// The shipped model's mean joint error on its offline test set, read from the
/// evaluation `hand_eval` wrote beside it (`local_site/models/hand/report.json`) the way
/// the hand-inference node reads it; the closed loop may be at most 1.2x that.
fn offline_test_mean_error_rad() -> f64 {
    let model = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(teleop_hand_inference::node::DEFAULT_MODEL);
    match teleop_hand_inference::node::offline_test_error(&model) {
        Ok(Some(e)) => e,
        Ok(None) => panic!(
            "no offline test error for {} in its report.json",
            model.display()
        ),
        Err(e) => panic!("the model's offline evaluation: {e}"),
    }
}

/// `--task` runs one task of the simulated operator and ends by itself when it is done,
/// with the end-of-run report printed and written as JSON and PNG. The report's
/// figures come from the closed loop against the simulator's ground truth and are held
/// to the local-site issue's goals: the camera within 1 cm on average and 3 cm at worst
/// of its goal with the hand fully in view in >= 99.5 % of frames, the PR2 within 5 mm
/// on average of the scaled operator motion, the hand joints within 1.2x the model's
/// offline error. (The latency goal is measured, not asserted: tests assert behaviour,
/// never timing; docs/local-site.md has the figures.)
#[test]
fn tasks_run_once_and_meet_the_goals_in_the_report() {
    let _one = one_system();
    // Sharp corners at constant speed; reaching, carrying, putting down; and the 90 deg
    // turn of pouring (the camera goes round the hand to stay within the UR5's reach,
    // the PR2's palm rolls about its fingers).
    for (task, domain, duration) in [
        ("fader", "93", 15.0..40.0),
        ("pick_and_place", "94", 13.0..40.0),
        ("pouring", "95", 18.0..45.0),
    ] {
        task_meets_the_goals(task, domain, duration, &[], &[]);
    }
}

/// `--time-scale 2`: every process runs on one simulated time passing twice as fast as
/// the wall clock. The task takes as many simulated seconds as in real time (so in
/// about half the wall time) and still meets every goal of the report, which says its
/// time scale.
#[test]
fn a_task_on_simulated_time_twice_as_fast_meets_the_goals() {
    let _one = one_system();
    let started = std::time::Instant::now();
    let json = task_meets_the_goals(
        "fader",
        "98",
        15.0..40.0,
        &["--time-scale", "2"],
        &["--no-realtime"],
    );
    let wall_s = started.elapsed().as_secs_f64();
    assert_eq!(json["time_scale"], 2.0, "{json}");
    let sim_s = json["duration_s"].as_f64().expect("duration_s");
    // The run (start-up and shut-down included) took less wall time than the task's
    // simulated time: the simulated clock ran faster than the wall clock.
    assert!(
        wall_s < sim_s,
        "{sim_s} s of simulated time took {wall_s} s"
    );
}

/// `teleop launch --as-fast-as-possible`: the launcher paces the run's simulated time on
/// the machine's load; every node follows the changing rate (one clock file), and the
/// task meets every goal the real-time test asserts.
#[test]
fn a_task_as_fast_as_possible_meets_the_goals() {
    let _one = one_system();
    let started = std::time::Instant::now();
    let json = task_meets_the_goals("fader", "89", 15.0..40.0, &[], &["--as-fast-as-possible"]);
    let wall_s = started.elapsed().as_secs_f64();
    let pacing = &json["pacing"];
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or_else(|| panic!("{pacing}"));
    // The pacer measured the load every half second of the run and changed the rate.
    let sim_s = num(&json["duration_s"]);
    assert!(
        num(&pacing["samples"]) >= 0.5 * sim_s / num(&pacing["max_rate"]),
        "{pacing}"
    );
    assert!(num(&pacing["changes"]) >= 1.0, "{pacing}");
    let (min, max, mean) = (
        num(&pacing["min_rate"]),
        num(&pacing["max_rate"]),
        num(&json["time_scale"]),
    );
    assert!(
        (0.25..=20.0).contains(&min) && min <= max && max <= 20.0,
        "{pacing}"
    );
    // The report's mean rate is the run's simulated over its wall seconds: within the
    // rates the pacer set (start-up and shut-down at the rates of their moments), and
    // the whole command took at least the run's wall time.
    assert!(
        mean >= 0.9 * min.min(1.0) && mean <= 1.1 * max,
        "{mean} {pacing}"
    );
    assert!(
        wall_s >= sim_s / mean * 0.9,
        "{wall_s} s wall, {sim_s} s at {mean}x"
    );
}

/// Runs `teleop launch --task pick` with `extra` launch arguments for at most
/// `duration_s`; the report's JSON.
fn pick_job(domain: &str, duration_s: &str, extra: &[&str]) -> serde_json::Value {
    task_report("pick", domain, duration_s, extra)
}

/// Runs `teleop launch --task TASK` with `extra` launch arguments for at most
/// `duration_s`; the report's JSON.
fn task_report(task: &str, domain: &str, duration_s: &str, extra: &[&str]) -> serde_json::Value {
    let dir = std::env::temp_dir().join(format!(
        "teleop-report-test-{}-{task}-{domain}",
        std::process::id()
    ));
    let mut args: Vec<&std::ffi::OsStr> = [
        "--domain-id",
        domain,
        "launch",
        "--quiet",
        "--task",
        task,
        "--duration-s",
        duration_s,
        "--report-dir",
    ]
    .map(std::ffi::OsStr::new)
    .to_vec();
    args.push(dir.as_os_str());
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    let stdout = launch_ok(&args);
    assert_every_node_stopped_gracefully(&stdout);
    serde_json::from_str(
        &std::fs::read_to_string(dir.join("report.json")).expect("report.json written"),
    )
    .expect("report.json parses")
}

/// The camera is judged against the goal of the settings the run started the camera
/// arm with (`--set camera_arm.camera_arm.standoff_m=0.48`), not against the built-in
/// defaults (0.40 m): its mean error against that goal stays within the goal's 1 cm,
/// where against the default goal it would be some 8 cm.
#[test]
fn the_camera_is_judged_against_the_goal_the_run_configured() {
    let _one = one_system();
    let json = task_report(
        "pick_and_place",
        "113",
        "40",
        &["--set", "camera_arm.camera_arm.standoff_m=0.48"],
    );
    let e = &json["camera_position_error_m"];
    let (mean, samples) = (e["mean"].as_f64(), e["samples"].as_f64());
    assert!(samples.is_some_and(|n| n > 300.0), "{json}");
    assert!(mean.is_some_and(|m| m <= 0.01), "{json}");
}

/// With no camera views reaching the operator site, the operator who watches the
/// display sees the robot (its joint states arrive) but not the can: it waits, never
/// presses the clutch, and the arm never moves.
#[test]
fn the_watching_operator_without_camera_views_waits_and_never_engages_the_arm() {
    let _one = one_system();
    let json = pick_job("111", "12", &["--set", "remote_sim.cameras.enabled=false"]);
    let op = &json["operator"];
    let n = |v: &serde_json::Value| v.as_u64().unwrap_or_else(|| panic!("{op}"));
    assert_eq!(op["phase"], "waiting_for_view", "{op}");
    assert_eq!(n(&op["views_received"]), 0, "{op}");
    assert_eq!(n(&op["scene_percepts"]), 0, "{op}");
    assert!(n(&op["robot_percepts"]) > 100, "it saw the robot: {op}");
    assert_eq!(n(&op["submovements"]), 0, "{op}");
    assert_eq!(n(&json["clutch_engagements"]), 0, "{json}");
    assert_eq!(json["job"]["lifted"], false, "{json}");
}

/// The operator who watches the display does the pick job through the shipped nodes
/// (default seed): it sees the can in the views it received, reaches the top grasp by
/// corrected submovements, closes the hand, lifts, carries, places the can and goes
/// back: the judge (from ground truth, in the robot-site simulator) calls the job a
/// success, having run on every tick without refusals. On this machine: a success with
/// each of three seeds, in 23.3-23.5 s (docs/physics.md, "The top grasp").
#[test]
fn the_watching_operator_picks_and_places_the_can_through_the_shipped_nodes() {
    let _one = one_system();
    let json = pick_job("112", "60", &[]);
    let op = &json["operator"];
    let n = |v: &serde_json::Value| v.as_u64().unwrap_or_else(|| panic!("{op}"));
    assert!(n(&op["scene_percepts"]) > 100, "{op}");
    assert!(n(&op["robot_percepts"]) > 1000, "{op}");
    assert!(
        n(&op["grasp_attempts"]) >= 1,
        "it reached the grasp and closed: {op}"
    );
    // At least one to the pre-grasp pose and one toward the grasp (the approach stops
    // at its first move when the can is seen pushed).
    assert!(n(&op["submovements"]) >= 2, "{op}");
    assert_eq!(n(&op["bad_input"]), 0, "{op}");
    assert_ne!(op["phase"], "waiting_for_view", "{op}");
    assert!(n(&json["clutch_engagements"]) >= 1, "{json}");
    assert_eq!(json["job"]["judge_errors"], 0, "{json}");
    assert_eq!(json["job"]["lifted"], true, "the can came up: {json}");
    assert_eq!(json["job"]["succeeded"], true, "judged a success: {json}");
    assert_eq!(op["phase"], "done", "{op}");
}

/// `--seeds 1 --wan delay_ms=25`: the pick job with each site behind a router of its
/// own and the WAN link emulator between them (a 50 ms round trip), run on a held-out
/// seed and summed up beside the thesis's figures. The feedback reaches the operator's
/// site through the link (its latency there is at least the one-way delay), the
/// operator still sees enough of the robot to lift the can, and the summary counts
/// the judge's verdict. On this machine: docs/physics.md, "Success rate and time".
#[test]
fn a_seeded_pick_through_an_emulated_wan_is_summed_up_beside_the_thesis() {
    let _one = one_system();
    let dir = std::env::temp_dir().join(format!("teleop-seeds-test-{}", std::process::id()));
    let mut args: Vec<&std::ffi::OsStr> = [
        "--domain-id",
        "114",
        "launch",
        "--quiet",
        "--task",
        "pick",
        "--duration-s",
        "70",
        "--seeds",
        "1",
        "--seed-base",
        "1005",
        "--wan",
        "delay_ms=25",
        "--report-dir",
    ]
    .map(std::ffi::OsStr::new)
    .to_vec();
    args.push(dir.as_os_str());
    let stdout = launch_ok(&args);
    assert_every_node_stopped_gracefully(&stdout);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).expect("written")).expect("parses")
    };
    let summary = read(&dir.join("summary.json"));
    assert!(dir.join("summary.png").is_file());
    assert_eq!(summary["round_trip_ms"], 50.0, "{summary}");
    assert_eq!(
        summary["runs"].as_array().map(Vec::len),
        Some(1),
        "{summary}"
    );
    assert_eq!(summary["runs"][0]["seed"], 1005, "{summary}");
    assert_eq!(
        summary["thesis"].as_array().map(Vec::len),
        Some(2),
        "{summary}"
    );
    let report = read(&dir.join("seed-1005").join("report.json"));
    assert!(
        report["wan"]
            .as_str()
            .is_some_and(|w| w.contains("round trip 50 ms")),
        "{}",
        report["wan"]
    );
    // The robot's joint states come across the link: half the round trip at least.
    let feedback = report["latency"]
        .as_array()
        .and_then(|l| l.iter().find(|s| s["stage"] == "PR2 joints -> feedback"))
        .unwrap_or_else(|| panic!("no feedback stage: {}", report["latency"]));
    assert!(
        feedback["samples"].as_u64().is_some_and(|n| n > 1000),
        "{feedback}"
    );
    assert!(
        feedback["p50_ms"].as_f64().is_some_and(|ms| ms >= 25.0),
        "the feedback did not cross the emulated WAN: {feedback}"
    );
    assert!(
        report["operator"]["robot_percepts"]
            .as_u64()
            .is_some_and(|n| n > 1000),
        "{}",
        report["operator"]
    );
    assert_eq!(report["job"]["lifted"], true, "{}", report["job"]);
    // The summary counts what the judge said (at 50 ms this seed's can was placed in
    // most runs here, not in all: docs/physics.md gives the rate over ten seeds).
    let succeeded = report["job"]["succeeded"].as_bool().expect("judged");
    assert_eq!(summary["succeeded"], u64::from(succeeded), "{summary}");
    assert_eq!(
        summary["success_pct"],
        if succeeded { 100.0 } else { 0.0 },
        "{summary}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The nodes whose configs ask for real-time scheduling by default: the depth frame's
/// path to the hand (docs/local-site.md).
const REALTIME_BY_DEFAULT: [&str; 3] = ["hand_inference", "local_sim", "shadow_hand_controller"];

/// The scheduling policy and real-time priority of every thread of process `pid`, by
/// thread name (`/proc/PID/task/*/stat`: fields 41 and 40).
fn thread_scheduling(pid: u32) -> Vec<(String, u32, u32)> {
    let mut out = Vec::new();
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).expect("/proc task list") {
        let dir = task.expect("task").path();
        let (Ok(comm), Ok(stat)) = (
            std::fs::read_to_string(dir.join("comm")),
            std::fs::read_to_string(dir.join("stat")),
        ) else {
            continue; // the thread ended meanwhile
        };
        // After the command name in parentheses: field 3 onwards.
        let rest = &stat[stat.rfind(')').expect("stat") + 2..];
        let fields: Vec<&str> = rest.split_whitespace().collect();
        let field = |n: usize| fields[n - 3].parse::<u32>().expect("number");
        out.push((comm.trim().to_owned(), field(41), field(40)));
    }
    out
}

/// Whether this process may put a thread in the real-time FIFO class (root,
/// CAP_SYS_NICE or an RLIMIT_RTPRIO): util-linux's `chrt` asks the OS.
fn realtime_permitted() -> bool {
    Command::new("chrt")
        .args(["-f", "5", "true"])
        .output()
        .expect("chrt (util-linux)")
        .status
        .success()
}

/// `--realtime-priority` (or `scheduling.realtime_priority`): the node sets it before
/// its runtime starts, so every thread it starts afterwards runs in the real-time FIFO
/// class at that priority (Zenoh's shared-memory watchdog sets its own); where the
/// process may not, it says so and runs on at normal priority. Its status says both.
#[test]
fn a_node_runs_every_thread_at_its_configured_real_time_priority() {
    let _one = one_system();
    let dir = Path::new(env!("CARGO_BIN_EXE_teleop")).parent().unwrap();
    for priority in [7u32, 0] {
        let child = Command::new(dir.join("shadow_hand_controller"))
            .args([
                "--domain-id",
                "87",
                "--duration-s",
                "4",
                "--realtime-priority",
            ])
            .arg(priority.to_string())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("start shadow_hand_controller");
        std::thread::sleep(std::time::Duration::from_millis(1500));
        let threads = thread_scheduling(child.id());
        let out = child.wait_with_output().expect("wait");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        println!("priority {priority}: {threads:?}");
        // The runtime's workers, Zenoh's threads and the main thread at least.
        assert!(threads.len() >= 4, "{threads:?}");
        let ours: Vec<_> = threads
            .iter()
            .filter(|(name, _, _)| !name.starts_with("Watchdog"))
            .collect();
        let (policy, rt) = if priority > 0 && realtime_permitted() {
            assert!(stderr.contains("real-time FIFO scheduling"), "{stderr}");
            (1, priority)
        } else {
            if priority > 0 {
                assert!(stderr.contains("real-time scheduling refused"), "{stderr}");
            }
            (0, 0)
        };
        for (name, p, r) in &ours {
            assert_eq!((*p, *r), (policy, rt), "thread {name}: {threads:?}");
        }
    }
}

/// Runs `task` once (on `domain`, with `extra` before `launch` and `launch_extra` after
/// it), asserts every node stopped gracefully and the report's figures meet the
/// local-site issue's goals; returns the report's JSON.
fn task_meets_the_goals(
    task: &str,
    domain: &str,
    duration: std::ops::Range<f64>,
    extra: &[&str],
    launch_extra: &[&str],
) -> serde_json::Value {
    let dir = std::env::temp_dir().join(format!(
        "teleop-report-test-{}-{task}-{domain}",
        std::process::id()
    ));
    let mut args: Vec<&std::ffi::OsStr> = extra.iter().map(std::ffi::OsStr::new).collect();
    args.extend(
        [
            "--domain-id",
            domain,
            "launch",
            "--quiet",
            "--task",
            task,
            // A bound in case the task never reports done.
            "--duration-s",
            "60",
            "--report-dir",
        ]
        .map(std::ffi::OsStr::new),
    );
    args.push(dir.as_os_str());
    args.extend(launch_extra.iter().map(std::ffi::OsStr::new));
    let stdout = launch_ok(&args);
    assert_every_node_stopped_gracefully(&stdout);
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("report.json")).expect("report.json written"),
    )
    .expect("report.json parses");
    let png = std::fs::read(dir.join("report.png")).expect("report.png written");
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    let f = |key: &str| {
        json[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} in {json}"))
    };
    let nested = |key: &str, field: &str| {
        json[key][field]
            .as_f64()
            .unwrap_or_else(|| panic!("{key}.{field} in {json}"))
    };
    assert_eq!(json["task"], task);
    // The task ran to its end, and not to the 60 s bound.
    let ran = f("duration_s");
    assert!(duration.contains(&ran), "{task} ran {ran} s");
    // The camera kept the hand in view and near its goal.
    let frames = f("depth_frames");
    assert!(frames > 300.0, "{task}: {frames} depth frames");
    assert!(f("fraction_hand_fully_in_view") >= 0.995, "{task}: {json}");
    assert!(
        nested("camera_position_error_m", "samples") > 300.0,
        "{task}: {json}"
    );
    assert!(
        nested("camera_position_error_m", "mean") <= 0.01,
        "{task}: {json}"
    );
    assert!(
        nested("camera_position_error_m", "max") <= 0.03,
        "{task}: {json}"
    );
    // Hand inference: targets for (nearly) every frame, paired with the truth.
    let offline_expected = offline_test_mean_error_rad();
    assert!(f("finger_target_frames") > 0.8 * frames, "{task}: {json}");
    assert!(
        nested("hand_joint_mean_error_rad", "mean") <= 1.2 * offline_expected,
        "{task}: {json}"
    );
    // The report judges the goals itself, the hand's against the offline error the
    // hand-inference node read beside its model: every goal but the latency (measured,
    // not asserted) met.
    // (The node reports it as a counter in micro-radians.)
    let offline = f("hand_offline_test_error_rad");
    assert!((offline - offline_expected).abs() <= 1e-6, "{task}: {json}");
    let goals = json["goals"].as_array().expect("goals");
    assert_eq!(goals.len(), 5, "{task}: {json}");
    for g in &goals[..4] {
        assert_eq!(g["met"], true, "{task}: {g}");
    }
    // The latency goal is judged in real time only.
    let latency = &goals[4];
    let real_time = json["pacing"].is_null() && json["time_scale"] == 1.0;
    assert!(
        latency["goal"].as_str().unwrap().contains("finger targets")
            && latency["met"].is_boolean() == real_time,
        "{task}: {latency}"
    );
    // The depth frame's path to the hand ran real-time (its nodes' default) where
    // this process may set real-time scheduling too, at normal priority where not;
    // `--no-realtime` runs every node at normal priority.
    let realtime = &json["realtime_scheduling"];
    if launch_extra.contains(&"--no-realtime") {
        assert_eq!(realtime, &serde_json::json!({}), "{task}: {realtime}");
    } else {
        let granted = if realtime_permitted() { 50 } else { 0 };
        let expected: serde_json::Value = REALTIME_BY_DEFAULT
            .iter()
            .map(|n| {
                (
                    (*n).to_owned(),
                    serde_json::json!({"requested": 50, "granted": granted}),
                )
            })
            .collect::<serde_json::Map<_, _>>()
            .into();
        assert_eq!(realtime, &expected, "{task}");
    }
    // Every node's CPU and peak memory, sampled from /proc by the launcher.
    let resources = json["resources"].as_object().expect("resources");
    assert_eq!(
        resources.len(),
        teleop_interfaces::nodes::NODES.len(),
        "{task}: {resources:?}"
    );
    for (node, u) in resources {
        let cpu = u["cpu_cores"].as_f64().unwrap_or(-1.0);
        let rss = u["peak_rss_mb"].as_f64().unwrap_or(-1.0);
        assert!(cpu > 0.0 && cpu < 2.5, "{task}: {node} at {cpu} cores");
        assert!(rss > 1.0, "{task}: {node} peak {rss} MB");
    }
    // The PR2 followed the operator while clutched: one press of the clutch, and one
    // more for each time the operator answered a safety stop on the display by letting
    // go of the pedal and pressing it again.
    assert_eq!(
        f("clutch_engagements"),
        1.0 + f("operator_reclutches"),
        "{task}: {json}"
    );
    // Measured from the references the arm controller took: its status names the wrist
    // pose each engagement started from.
    assert!(
        f("arm_reference_engagements") >= 1.0
            && f("arm_reference_engagements") <= f("clutch_engagements"),
        "{task}: {json}"
    );
    assert!(
        nested("pr2_position_error_m", "samples") > 500.0,
        "{task}: {json}"
    );
    assert!(
        nested("pr2_position_error_m", "mean") <= 0.005,
        "{task}: {json}"
    );
    // The robot site measured the finger targets' age on arrival itself.
    let remote = &json["hand_controller_stages_us"];
    assert!(
        remote["latency.targets.capture_to_received_us.p50"]
            .as_u64()
            .is_some_and(|v| v > 0),
        "{task}: {remote}"
    );
    // Every latency stage was measured.
    for stage in json["latency"].as_array().expect("latency") {
        assert!(
            stage["samples"].as_u64().unwrap_or(0) > 100,
            "{task}: {stage}"
        );
        assert!(
            stage["p50_ms"].as_f64().is_some_and(|v| v > 0.0),
            "{task}: {stage}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    json
}

/// A terminal's Ctrl-C sends SIGINT to the whole foreground process group: the launcher
/// alone must get it (the nodes run in groups of their own) and stop the nodes in order,
/// each one gracefully.
#[test]
fn ctrl_c_to_the_terminal_group_still_stops_every_node_gracefully() {
    let _one = one_system();
    use std::os::unix::process::CommandExt;
    let teleop = Path::new(env!("CARGO_BIN_EXE_teleop"));
    let child = Command::new(teleop)
        .args([
            "--domain-id",
            "92",
            "launch",
            "--quiet",
            "--no-report-files",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .process_group(0)
        .spawn()
        .expect("start teleop launch");
    std::thread::sleep(std::time::Duration::from_secs(6));
    let group = nix::unistd::Pid::from_raw(i32::try_from(child.id()).unwrap());
    nix::sys::signal::killpg(group, nix::sys::signal::Signal::SIGINT).expect("SIGINT to the group");
    let out = child.wait_with_output().expect("wait for teleop launch");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "launch failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    assert_every_node_stopped_gracefully(&stdout);
}

/// `--keyboard`: the pedals come from the launcher's keyboard, forwarded to the wrist
/// tracker's keyboard panel, and no longer from the simulated operator's feet. Without
/// keys the arm never engages, though the simulated operator presses its clutch pedal
/// 2 s in; with space held (its auto-repeat, as a terminal sends it) and `c` pressed,
/// it engages once; letting go of space releases it.
#[test]
fn keyboard_pedals_from_the_launchers_terminal_drive_the_clutch() {
    use std::io::Write;
    let _one = one_system();
    let run = |domain: &str, keys: bool| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_teleop"))
            .args([
                "--domain-id",
                domain,
                "launch",
                "--keyboard",
                "--duration-s",
                "11",
                "--quiet",
                "--no-report-files",
            ])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("start teleop launch --keyboard");
        let mut stdin = child.stdin.take().expect("stdin");
        if keys {
            // The system is up after a few seconds; then space held for 3 s (repeats
            // every 35 ms), `c` 0.5 s into it, then nothing: enable drops 0.7 s
            // after the last space and takes the clutch with it.
            std::thread::sleep(std::time::Duration::from_secs(4));
            for k in 0..86 {
                let key: &[u8] = if k == 14 { b"c" } else { b" " };
                stdin.write_all(key).expect("key");
                stdin.flush().expect("flush");
                std::thread::sleep(std::time::Duration::from_millis(35));
            }
        } else {
            std::thread::sleep(std::time::Duration::from_secs(6));
        }
        let out = child.wait_with_output().expect("wait for teleop launch");
        drop(stdin);
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        println!("{stdout}");
        assert!(
            out.status.success(),
            "launch failed ({}):\n{stdout}\n{stderr}",
            out.status
        );
        assert_every_node_stopped_gracefully(&stdout);
        (stdout, stderr)
    };
    let (idle, _) = run("96", false);
    assert!(!idle.contains("arm.engagements="), "{idle}");
    assert!(!idle.contains("hand.engagements="), "{idle}");
    let (keyed, stderr) = run("97", true);
    assert!(keyed.contains("arm.engagements=1 "), "{keyed}");
    assert!(keyed.contains("hand.engagements=1"), "{keyed}");
    assert!(stderr.contains("keyboard: clutch engaged (c)"), "{stderr}");
    assert!(stderr.contains("keyboard: enable dropped"), "{stderr}");
    // Released with enable: the arm is held at the stop, not active.
    let arm = keyed
        .lines()
        .find(|l| l.starts_with("pr2_arm_controller "))
        .expect("arm line");
    assert!(!arm.contains("Active"), "{arm}");
}

/// `teleop record` beside a running system: the bag holds every topic that crosses
/// between the sites, each message decodes, at about its rate; and two independent
/// readers (Foxglove's `mcap` + `mcap-ros2-support`, and `rosbags` through the bag's
/// metadata.yaml) decode every message and count the same (tests/interop/check_bag.py;
/// Python from `$TELEOP_PYTHON`, as tests/run.sh sets it).
#[test]
fn a_recording_of_the_running_system_reads_in_the_field_s_tools() {
    let _one = one_system();
    let teleop = env!("CARGO_BIN_EXE_teleop");
    let bag = std::env::temp_dir().join(format!("teleop-record-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&bag);
    let launch = spawn_teleop(&[
        "--domain-id",
        "94",
        "launch",
        "--duration-s",
        "16",
        "--quiet",
        "--no-report-files",
    ]);
    std::thread::sleep(std::time::Duration::from_secs(3));
    let record = Command::new(teleop)
        .args(["--domain-id", "94", "record", "--duration-s", "8", "-o"])
        .arg(&bag)
        .output()
        .expect("run teleop record");
    let launched = launch.wait_with_output().expect("wait for teleop launch");
    let out = String::from_utf8_lossy(&record.stdout);
    let err = String::from_utf8_lossy(&record.stderr);
    println!("{out}\n{err}");
    assert!(record.status.success(), "record failed:\n{out}\n{err}");
    assert!(launched.status.success(), "launch failed");
    assert!(err.contains(", 0 dropped,"), "samples dropped:\n{err}");

    let report = teleop_bag::read_bag(&bag).expect("read the bag");
    let topics = report.topics();
    let d = report.duration_s();
    assert!(d > 7.0 && d < 9.0, "duration {d} s");
    for spec in teleop_interfaces::topics::ALL
        .iter()
        .filter(|t| t.direction.crosses_sites())
    {
        let name = format!("/{}", spec.name);
        let t = topics
            .get(&name)
            .unwrap_or_else(|| panic!("{name} not recorded:\n{report}"));
        assert_eq!(t.type_name, spec.type_name);
        assert_eq!(t.type_hash, spec.type_hash);
        // At least a third of the nominal rate (the views are paced, the status comes
        // once a second per node).
        let rate = report.rate_hz(t.count).unwrap();
        assert!(
            rate > spec.rate_hz / 3.0,
            "{name}: {rate:.1} Hz of {} Hz",
            spec.rate_hz
        );
    }
    // Every message decodes with the project's own decoder, too.
    for file in &report.files {
        let buf = std::fs::read(&file.path).unwrap();
        for m in mcap::MessageStream::new(&buf).unwrap() {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            decodes(&schema.name, &m.data);
            assert!(
                m.publish_time <= m.log_time + 50_000_000,
                "{}: published after received",
                m.channel.topic
            );
        }
    }

    let python = std::env::var("TELEOP_PYTHON").unwrap_or_else(|_| "python3".into());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/interop/check_bag.py");
    let check = Command::new(&python)
        .arg(&script)
        .arg(&bag)
        .output()
        .expect("run check_bag.py");
    let stdout = String::from_utf8_lossy(&check.stdout);
    let stderr = String::from_utf8_lossy(&check.stderr);
    assert!(
        check.status.success(),
        "{python} {}: {stdout}\n{stderr}\n(pip install -r tests/interop/requirements.txt, or set TELEOP_PYTHON)",
        script.display()
    );
    let json: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(json["profile"][0], "ros2");
    for (name, t) in &topics {
        assert_eq!(json["mcap"][name].as_u64(), Some(t.count), "{name} (mcap)");
        assert_eq!(
            json["rosbags"][name].as_u64(),
            Some(t.count),
            "{name} (rosbags)"
        );
        assert_eq!(json["qos"][name], true, "{name}: no offered QoS");
    }

    replay_drives_the_operator_display(&bag, &report);
    let _ = std::fs::remove_dir_all(&bag);
}

/// The recording replayed to the operator display alone (its own domain, nothing
/// else running): `teleop play --as-publishers` speaks as the feedback publisher, and
/// the display shows what was recorded: its page's state names the views received and
/// the fingertip forces' and the PR2's states accepted, at least 90 % of what the bag
/// holds.
fn replay_drives_the_operator_display(bag: &Path, report: &teleop_bag::BagReport) {
    let port = common::free_port();
    let config = bag.with_extension("display.toml");
    std::fs::write(&config, format!("http_listen = \"127.0.0.1:{port}\"\n")).unwrap();
    let display_bin = Path::new(env!("CARGO_BIN_EXE_teleop"))
        .parent()
        .unwrap()
        .join("operator_display");
    let mut display = Command::new(display_bin)
        .args(["--domain-id", "95", "--config"])
        .arg(&config)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start operator_display");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
    while common::http_get(port, "/api/state").is_none() {
        assert!(
            std::time::Instant::now() < deadline,
            "the display's page never answered"
        );
        std::thread::sleep(std::time::Duration::from_millis(200));
    }
    let topics = [
        "/teleop/remote_camera/top/image/compressed",
        "/teleop/remote_camera/side/image/compressed",
        "/teleop/shadow/fingertip_pressures",
        "/teleop/pr2/joint_states",
    ];
    let mut args = vec!["--domain-id", "95", "play"];
    let bag_arg = bag.to_str().unwrap();
    args.push(bag_arg);
    args.extend(["--as-publishers", "--delay-s", "1", "--topics"]);
    args.extend(topics);
    teleop_ok(&args, &[]);
    std::thread::sleep(std::time::Duration::from_millis(500));
    let (_, body) = common::http_get(port, "/api/state").expect("the display's state");
    let _ = std::process::Command::new("kill")
        .args(["-INT", &display.id().to_string()])
        .status();
    let _ = display.wait();
    let _ = std::fs::remove_file(&config);

    let state: serde_json::Value = serde_json::from_str(&body).unwrap();
    let recorded = report.topics();
    let count = |name: &str| recorded[name].count;
    for (i, topic) in topics[..2].iter().enumerate() {
        let shown = state["views"][i]["received"].as_u64().unwrap();
        assert_eq!(state["views"][i]["topic"], *topic);
        assert!(
            shown * 10 >= count(topic) * 9 && shown <= count(topic),
            "{topic}: {shown} shown of {} recorded",
            count(topic)
        );
    }
    // The feedback is kept newest-only (the display draws the newest): what its
    // subscriptions accepted is the count to compare.
    for topic in &topics[2..] {
        let accepted = state["topics"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["name"] == *topic)
            .and_then(|t| t["accepted"].as_u64())
            .unwrap_or_else(|| panic!("{topic} not on the page: {state}"));
        assert!(
            accepted * 10 >= count(topic) * 9 && accepted <= count(topic),
            "{topic}: {accepted} accepted of {} recorded",
            count(topic)
        );
    }
    assert!(state["forces"]["received"].as_u64() > Some(0), "{state}");
    assert_eq!(state["forces"]["newton"].as_array().map(Vec::len), Some(5));
    assert_eq!(
        state["pr2"]["position"].as_array().map(Vec::len),
        Some(7),
        "{state}"
    );
}

/// Decodes `data` as the type `type_name` with the project's decoder; panics if not.
fn decodes(type_name: &str, data: &[u8]) {
    use teleop_msgs::*;
    let ok = match type_name {
        t if t == PoseStamped::TYPE_NAME => decode::<PoseStamped>(data).is_ok(),
        t if t == JointState::TYPE_NAME => decode::<JointState>(data).is_ok(),
        t if t == OperatorInput::TYPE_NAME => decode::<OperatorInput>(data).is_ok(),
        t if t == FingertipPressures::TYPE_NAME => decode::<FingertipPressures>(data).is_ok(),
        t if t == CompressedImage::TYPE_NAME => decode::<CompressedImage>(data).is_ok(),
        t if t == Image::TYPE_NAME => decode::<Image>(data).is_ok(),
        t if t == JointCommand::TYPE_NAME => decode::<JointCommand>(data).is_ok(),
        t if t == NodeStatus::TYPE_NAME => decode::<NodeStatus>(data).is_ok(),
        t if t == Header::TYPE_NAME => decode::<Header>(data).is_ok(),
        t if t == TFMessage::TYPE_NAME => decode::<TFMessage>(data).is_ok(),
        other => panic!("unexpected type {other}"),
    };
    assert!(ok, "a {type_name} message does not decode");
}

/// Runs `teleop` with `args` to its end and asserts it succeeded; its stderr.
fn teleop_ok(args: &[&str], extra: &[&Path]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_teleop"))
        .args(args)
        .args(extra)
        .output()
        .expect("run teleop");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "teleop {args:?} failed:\n{stdout}\n{stderr}"
    );
    stderr
}

/// A joint this far from its first reading marks the start of the operator's motion,
/// rad: well above what the arm does before the operator moves it (with 2 mrad, one CI
/// run found the two runs' starts 0.3 s apart, at the edge of the test's window, while
/// the paths matched within 3.5 mm at that shift), and crossed within a few ticks once
/// the clutched arm moves.
const MOTION_START_RAD: f64 = 0.02;

/// The PR2's palm positions over the time since the arm started moving (first joint
/// more than [`MOTION_START_RAD`] from where it stood), from a bag's
/// `/teleop/pr2/joint_states`.
fn palm_path(bag: &Path) -> Vec<(f64, nalgebra::Vector3<f64>)> {
    let chain = teleop_kinematics::robots::pr2_arm_chain().unwrap();
    let names = teleop_interfaces::joints::PR2_ARM_JOINTS;
    let mut samples = Vec::new();
    for file in teleop_bag::mcap_files(bag).unwrap() {
        let buf = std::fs::read(&file).unwrap();
        for m in mcap::MessageStream::new(&buf).unwrap() {
            let m = m.unwrap();
            if m.channel.topic != "/teleop/pr2/joint_states" {
                continue;
            }
            let js: teleop_msgs::JointState = teleop_msgs::decode(&m.data).unwrap();
            let q = nalgebra::SVector::<f64, 7>::from_fn(|i, _| {
                let k = js.name.iter().position(|n| n == names[i]).unwrap();
                js.position[k]
            });
            samples.push((m.log_time as f64 * 1e-9, q));
        }
    }
    assert!(
        !samples.is_empty(),
        "no PR2 joint states in {}",
        bag.display()
    );
    let q0 = samples[0].1;
    let start = samples
        .iter()
        .find(|(_, q)| (q - q0).amax() > MOTION_START_RAD)
        .unwrap_or_else(|| panic!("the PR2 never moved in {}", bag.display()))
        .0;
    samples
        .iter()
        .filter(|(t, _)| *t >= start)
        .map(|(t, q)| (t - start, chain.end_pose(q).translation.vector))
        .collect()
}

/// `teleop play` drives the robot site as the recorded operator did: the whole system
/// runs while `teleop record` takes the operator's commands (wrist pose, pedals, finger
/// targets) and the PR2's joint states; then the robot site alone (`launch --site
/// remote`) gets those commands from `teleop play --as-publishers`, and the
/// PR2's palm follows the same path: within 1 cm on average and 3 cm at most, time
/// since the arm started moving against time since it started moving (aligned to the
/// best constant shift within 0.3 s: the two motion starts are found with some jitter).
#[test]
fn a_recorded_operator_drives_the_robot_site_again() {
    let _one = one_system();
    let base = std::env::temp_dir().join(format!("teleop-play-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    std::fs::create_dir_all(&base).unwrap();
    let (original, replayed) = (base.join("original"), base.join("replayed"));
    let commands = [
        "/teleop/wrist_pose",
        "/teleop/operator_input",
        "/teleop/hand/joint_targets",
    ];

    // The original run, recorded from its start.
    let launch = spawn_teleop(&[
        "--domain-id",
        "95",
        "launch",
        "--duration-s",
        "15",
        "--quiet",
        "--no-report-files",
    ]);
    let mut rec = vec![
        "--domain-id",
        "95",
        "record",
        "--duration-s",
        "13",
        "/teleop/pr2/joint_states",
    ];
    rec.extend(commands);
    rec.push("-o");
    teleop_ok(&rec, &[&original]);
    assert!(launch.wait_with_output().unwrap().status.success());

    // The robot site alone; the operator's commands played back to it.
    let site = spawn_teleop(&[
        "--domain-id",
        "96",
        "launch",
        "--site",
        "remote",
        "--duration-s",
        "20",
        "--quiet",
        "--no-report-files",
    ]);
    std::thread::sleep(std::time::Duration::from_secs(3));
    let record = spawn_teleop(&[
        "--domain-id",
        "96",
        "record",
        "--duration-s",
        "15",
        "/teleop/pr2/joint_states",
        "-o",
        replayed.to_str().unwrap(),
    ]);
    let mut play = vec![
        "--domain-id",
        "96",
        "play",
        original.to_str().unwrap(),
        "--as-publishers",
        "--topics",
    ];
    play.extend(commands);
    let played = teleop_ok(&play, &[]);
    println!("{played}");
    let recorded = record.wait_with_output().unwrap();
    assert!(
        recorded.status.success(),
        "{}",
        String::from_utf8_lossy(&recorded.stderr)
    );
    assert!(site.wait_with_output().unwrap().status.success());

    let a = palm_path(&original);
    let b = palm_path(&replayed);
    let span = a.last().unwrap().0.min(b.last().unwrap().0);
    assert!(span > 6.0, "only {span:.1} s of motion to compare");
    let errors_at = |shift: f64| -> Vec<f64> {
        // The same samples at every shift: those whose shifted time is in both paths.
        b.iter()
            .filter(|(t, _)| (0.3..=span - 0.3).contains(t))
            .map(|(t, p)| {
                let nearest = a
                    .iter()
                    .min_by(|x, y| (x.0 - t - shift).abs().total_cmp(&(y.0 - t - shift).abs()))
                    .unwrap();
                (nearest.1 - p).norm()
            })
            .collect()
    };
    let stats = |e: &[f64]| {
        (
            e.iter().sum::<f64>() / e.len() as f64,
            e.iter().copied().fold(0.0, f64::max),
        )
    };
    let (mean0, max0) = stats(&errors_at(0.0));
    // Each run's motion start is found from its own joint states (the first sample
    // MOTION_START_RAD from the start), as the recorder received them: a few tens of
    // milliseconds of jitter between the two runs, which shows as error wherever the
    // palm moves fast. The paths are compared at the best constant shift within
    // +-0.3 s (10 ms steps); a shift at the edge of that window means they differ.
    let (shift, (mean, max)) = (-30..=30)
        .map(|k| {
            let shift = f64::from(k) * 0.01;
            (shift, stats(&errors_at(shift)))
        })
        .min_by(|x, y| x.1.0.total_cmp(&y.1.0))
        .unwrap();
    println!(
        "replayed palm path against the original: mean {:.1} mm, max {:.1} mm from the motion \
         starts; {:+.2} s later: mean {:.1} mm, max {:.1} mm",
        mean0 * 1e3,
        max0 * 1e3,
        shift,
        mean * 1e3,
        max * 1e3
    );
    assert!(
        shift.abs() < 0.295,
        "the replay fits best {shift:+.2} s off"
    );
    let travel = a
        .windows(2)
        .filter(|w| w[1].0 <= span)
        .map(|w| (w[1].1 - w[0].1).norm())
        .sum::<f64>();
    println!("over {span:.1} s ({travel:.2} m of travel)");
    assert!(
        travel > 0.1,
        "the original palm hardly moved ({travel:.3} m)"
    );
    assert!(
        mean < 0.01 && max < 0.03,
        "mean {mean:.4} m, max {max:.4} m"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// Starts `teleop` with `args`, its output captured.
fn spawn_teleop(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_teleop"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("start teleop {args:?}: {e}"))
}

/// A ROS 2 graph tool nobody here wrote, ROBOTIS's `zenoh-ros2-sdk` (PyPI; its
/// `topic list -t` discovery, through `tests/interop/graph_oracle.py`), reads the running
/// system's liveliness tokens and lists every topic of the topic table with its ROS 2
/// type, and nothing else.
#[test]
fn a_ros2_graph_tool_lists_every_topic_of_a_running_system_with_its_type() {
    let _one = one_system();
    let python = std::env::var("TELEOP_PYTHON").unwrap_or_else(|_| "python3".into());
    let mut system = Command::new(env!("CARGO_BIN_EXE_teleop"))
        .args([
            "--domain-id",
            "88",
            "launch",
            "--duration-s",
            "60",
            "--quiet",
        ])
        .arg("--no-report-files")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start teleop launch");
    let expected: std::collections::BTreeSet<String> = teleop_interfaces::topics::ALL
        .iter()
        .map(|t| format!("/{} [{}]", t.name, t.type_name))
        .collect();
    // The nodes need a few seconds to start, and the tool, a peer among peers without
    // a router, lists the tokens of the peers it has reached: ask until every topic of
    // the table has been listed, and never anything else.
    let mut listed = std::collections::BTreeSet::new();
    let mut extra = std::collections::BTreeSet::new();
    let started = std::time::Instant::now();
    while listed != expected && started.elapsed() < std::time::Duration::from_secs(45) {
        std::thread::sleep(std::time::Duration::from_secs(2));
        let out = Command::new(&python)
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/interop/graph_oracle.py"))
            .args(["88", "5"])
            .output()
            .expect("run the graph oracle (pip install -r tests/interop/requirements.txt)");
        assert!(
            out.status.success(),
            "the graph oracle failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let poll: std::collections::BTreeSet<String> = String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(|l| l.trim().to_owned())
            .filter(|l| !l.is_empty())
            .collect();
        eprintln!(
            "zenoh-ros2-sdk topic list at {:.1} s: {} of the table's {} topics, {} others",
            started.elapsed().as_secs_f64(),
            poll.intersection(&expected).count(),
            expected.len(),
            poll.difference(&expected).count()
        );
        extra.extend(poll.difference(&expected).cloned());
        listed.extend(poll.intersection(&expected).cloned());
    }
    // Stopped as by Ctrl-C: the launcher stops its nodes (killing it would leave them
    // running).
    let stopped = Command::new("kill")
        .args(["-INT", &system.id().to_string()])
        .status()
        .expect("run kill");
    assert!(stopped.success());
    let status = system.wait().expect("teleop launch ends");
    assert!(status.success(), "teleop launch: {status}");
    let missing: Vec<&String> = expected.difference(&listed).collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "the graph tool's list differs from the topic table: missing {missing:#?}, \
         not in the table {extra:#?}"
    );
    assert_eq!(listed.len(), teleop_interfaces::topics::ALL.len());
}
