//! `teleop launch` starts every node, lets the simulated operator clutch and move, stops
//! the system gracefully on `--duration-s` and prints each node's final status.
//!
//! Needs the node binaries next to `teleop` (`cargo build --release --workspace --bins`;
//! `tests/run.sh` builds them first).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::Command;

use teleop_interfaces::nodes::NODES;

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

#[test]
fn launch_runs_the_system_and_stops_it_gracefully_with_a_summary() {
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
    let out = Command::new(teleop)
        .args([
            "--domain-id",
            "91",
            "launch",
            "--duration-s",
            "7",
            "--quiet",
        ])
        .output()
        .expect("run teleop launch");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "launch failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    assert!(stdout.contains("== teleop launch: summary"), "{stdout}");
    assert_every_node_stopped_gracefully(&stdout);
    // The simulated operator pressed the clutch after 1 s: the arm was engaged and
    // moving when the system stopped; the hand had no targets (no hand inference yet).
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
    assert_eq!(state("shadow_hand_controller"), "Inactive", "{stdout}");
    assert_eq!(state("remote_sim"), "Active", "{stdout}");
    assert!(stdout.contains("arm.engagements=1"), "{stdout}");
    assert!(stdout.contains("hand.hold.no_target="), "{stdout}");
}

/// A terminal's Ctrl-C sends SIGINT to the whole foreground process group: the launcher
/// alone must get it (the nodes run in groups of their own) and stop the nodes in order,
/// each one gracefully.
#[test]
fn ctrl_c_to_the_terminal_group_still_stops_every_node_gracefully() {
    use std::os::unix::process::CommandExt;
    let teleop = Path::new(env!("CARGO_BIN_EXE_teleop"));
    let child = Command::new(teleop)
        .args(["--domain-id", "92", "launch", "--quiet"])
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
