//! The `teleop` binary against a live publisher in this process.
#![allow(clippy::unwrap_used)]

use std::process::Command;
use std::time::Duration;

use teleop_bus::{Bus, BusConfig, ZenohSettings};
use teleop_interfaces::topics;
use teleop_msgs::{Header, OperatorInput, Time};

fn teleop() -> Command {
    Command::new(env!("CARGO_BIN_EXE_teleop"))
}

#[test]
fn topics_markdown_is_the_table() {
    let out = teleop().args(["topics", "--markdown"]).output().unwrap();
    assert!(out.status.success());
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        topics::markdown_table()
    );
}

#[test]
fn unknown_topic_is_a_clear_error() {
    let out = teleop()
        .args([
            "--no-multicast-scouting",
            "topic",
            "echo",
            "/no/such",
            "-n",
            "1",
        ])
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("unknown topic `/no/such`"), "{err}");
    assert!(err.contains("/teleop/wrist_pose"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn echo_node_list_and_hz_against_a_live_node() {
    let port = teleop_bus::testing::free_port().unwrap();
    let cfg = BusConfig {
        domain_id: 31,
        zenoh: ZenohSettings {
            listen: vec![format!("tcp/127.0.0.1:{port}")],
            multicast_scouting: false,
            ..Default::default()
        },
        ..Default::default()
    };
    let bus = Bus::open("pedal_box", &cfg).await.unwrap();
    let publisher = bus.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let gid: String = publisher.gid().iter().map(|b| format!("{b:02x}")).collect();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop2 = stop.clone();
    let pump = tokio::spawn(async move {
        while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
            let msg = OperatorInput {
                header: Header::new(Time::now(), "pedals"),
                clutch: true,
                enable: true,
                camera_stop: false,
                motion_scale: 0.333,
            };
            publisher.put(&msg).unwrap();
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    });
    let common = [
        "--no-multicast-scouting".to_owned(),
        "--connect".to_owned(),
        format!("tcp/127.0.0.1:{port}"),
        "--listen".to_owned(),
        "tcp/127.0.0.1:0".to_owned(),
        "--domain-id".to_owned(),
        "31".to_owned(),
    ];
    let run = move |args: &[&str]| {
        let mut c = teleop();
        c.args(&common).args(args);
        c.output().unwrap()
    };
    let echo = tokio::task::spawn_blocking(move || {
        let out = run(&[
            "topic",
            "echo",
            "/teleop/operator_input",
            "-n",
            "2",
            "--format",
            "json",
            "--duration-s",
            "10",
        ]);
        let nodes = run(&["node", "list", "--wait-s", "1"]);
        let hz = run(&[
            "topic",
            "hz",
            "teleop/operator_input",
            "--duration-s",
            "2.5",
        ]);
        (out, nodes, hz)
    })
    .await
    .unwrap();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    pump.await.unwrap();

    let (echo, nodes, hz) = echo;
    assert!(
        echo.status.success(),
        "{}",
        String::from_utf8_lossy(&echo.stderr)
    );
    let text = String::from_utf8(echo.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    for l in lines {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        assert_eq!(v["clutch"], true);
        assert_eq!(v["motion_scale"], 0.333);
        assert_eq!(v["header"]["frame_id"], "pedals");
        assert!(v["_meta"]["sequence"].as_i64().unwrap() >= 1);
        // Who sent it: the GID, and the node that announced it once its token is in.
        assert_eq!(v["_meta"]["publisher_gid"], gid.as_str());
        let node = &v["_meta"]["publisher_node"];
        assert!(node.is_null() || node == "pedal_box", "{node}");
    }

    assert!(nodes.status.success());
    let nodes = String::from_utf8(nodes.stdout).unwrap();
    assert!(nodes.contains("/pedal_box"), "{nodes}");
    assert!(
        nodes.contains("publishes  /teleop/operator_input"),
        "{nodes}"
    );

    assert!(hz.status.success());
    let hz = String::from_utf8(hz.stdout).unwrap();
    let row = hz
        .lines()
        .find(|l| l.starts_with("/teleop/operator_input"))
        .unwrap_or_else(|| panic!("{hz}"));
    let rate: f64 = row.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(rate > 10.0, "rate column should show ~100 Hz: {row}");
}

/// `teleop query` reads a router's admin space (on by default, as zenohd's), leaves out
/// its own session's entries, and names a malformed key expression.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn query_reads_a_routers_admin_space() {
    let port = teleop_bus::testing::free_port().unwrap();
    let mut cfg = teleop_node::router::RouterConfig::default();
    cfg.bus.domain_id = 32;
    cfg.bus.zenoh.listen = vec![format!("tcp/127.0.0.1:{port}")];
    let router = zenoh::open(cfg.to_zenoh().unwrap()).await.unwrap();
    let router_zid = router.zid().to_string();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let out = tokio::task::spawn_blocking(move || {
        let run = |key: &str| {
            teleop()
                .args([
                    "--mode",
                    "client",
                    "--no-multicast-scouting",
                    "--connect",
                    &endpoint,
                    "query",
                    key,
                    "--timeout-s",
                    "1.5",
                ])
                .env("RUST_BACKTRACE", "0")
                .output()
                .unwrap()
        };
        (run("@/**"), run("a//b"))
    })
    .await
    .unwrap();
    router.close().await.unwrap();
    let (admin, bad) = out;
    assert!(
        admin.status.success(),
        "{}",
        String::from_utf8_lossy(&admin.stderr)
    );
    let text = String::from_utf8(admin.stdout).unwrap();
    let keys: Vec<&str> = text
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|k| k.starts_with("@/"))
        .collect();
    assert!(!keys.is_empty(), "{text}");
    for k in &keys {
        assert!(
            k.starts_with(&format!("@/{router_zid}/router")),
            "only the router's entries: {k}"
        );
    }
    let last = text.lines().last().unwrap();
    assert_eq!(last, format!("{} replies, 0 errors", keys.len()));
    assert!(!bad.status.success());
    let err = String::from_utf8(bad.stderr).unwrap();
    assert!(err.contains("`a//b` is not a key expression"), "{err}");
}
