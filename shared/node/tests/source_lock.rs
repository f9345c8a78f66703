//! One commander at a time, at the bus level: a `SourceLock` takes the first publisher
//! it hears, refuses the others (counted, reported as a conflict that names them), and
//! moves only when released or when its publisher has been silent.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use teleop_bus::{Bus, BusConfig, ZenohSettings};
use teleop_interfaces::topics;
use teleop_msgs::{Header, OperatorInput, Time};
use teleop_node::SourceLock;

fn configs(domain_id: u32) -> (BusConfig, BusConfig) {
    let port = teleop_bus::testing::free_port().unwrap();
    let settings = |listen: String, connect: Vec<String>| BusConfig {
        domain_id,
        zenoh: ZenohSettings {
            listen: vec![listen],
            connect,
            multicast_scouting: false,
            ..Default::default()
        },
        ..Default::default()
    };
    (
        settings(format!("tcp/127.0.0.1:{port}"), vec![]),
        settings(
            "tcp/127.0.0.1:0".into(),
            vec![format!("tcp/127.0.0.1:{port}")],
        ),
    )
}

fn input(scale: f64) -> OperatorInput {
    OperatorInput {
        header: Header::new(Time::now(), ""),
        clutch: true,
        enable: true,
        camera_stop: false,
        motion_scale: scale,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_first_station_commands_until_it_falls_silent_or_is_released() {
    let (hub, spoke) = configs(41);
    let robot = Bus::open("robot", &hub).await.unwrap();
    let mut lock = SourceLock::new(
        robot.subscriber(&topics::OPERATOR_INPUT).await.unwrap(),
        0.5,
    );
    let first = Bus::open("station_a", &spoke).await.unwrap();
    let second = Bus::open("station_b", &spoke).await.unwrap();
    let a = first.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let b = second.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    // Station a is heard first and takes the lock.
    let mut got = None;
    for _ in 0..200 {
        a.put(&input(0.5)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        if let Some(r) = lock.poll() {
            got = Some(r);
            break;
        }
    }
    assert_eq!(got.unwrap().publisher_gid, a.gid());
    assert_eq!(lock.locked(), Some(a.gid()));
    // Both publish: only a's samples come through; b is refused and named.
    for _ in 0..30 {
        a.put(&input(0.5)).unwrap();
        b.put(&input(1.0)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        if let Some(r) = lock.poll() {
            assert_eq!(r.msg.motion_scale, 0.5);
        }
    }
    let conflict = lock.conflict(robot.now_s()).unwrap().to_owned();
    assert!(conflict.contains("station_b"), "{conflict}");
    assert!(conflict.contains("station_a"), "{conflict}");
    let counters = lock.named_counters();
    let get = |n: &str| counters.iter().find(|(k, _)| k == n).unwrap().1;
    assert!(get("operator_input.rejected_foreign") >= 20);
    assert_eq!(get("operator_input.conflict_active"), 1);
    assert_eq!(get("operator_input.conflicts"), 1);
    // a falls silent: not released before the silence lasts, released after.
    lock.release_if_silent(robot.now_s());
    assert_eq!(lock.locked(), Some(a.gid()));
    for _ in 0..60 {
        b.put(&input(1.0)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        lock.poll();
    }
    lock.release_if_silent(robot.now_s());
    assert_eq!(lock.locked(), None);
    // b takes over at its next sample.
    let mut took = None;
    for _ in 0..100 {
        b.put(&input(1.0)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        if let Some(r) = lock.poll() {
            took = Some(r);
            break;
        }
    }
    assert_eq!(took.unwrap().publisher_gid, b.gid());
    // An explicit release (a takeover allowed at a new engagement) frees it at once.
    lock.release();
    assert_eq!(lock.locked(), None);
    // The conflict ends once no foreign publisher was heard within the window.
    tokio::time::sleep(Duration::from_millis(1100)).await;
    for _ in 0..5 {
        b.put(&input(1.0)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        lock.poll();
    }
    assert!(lock.conflict(robot.now_s()).is_none());
    assert_eq!(lock.locked(), Some(b.gid()));
}
