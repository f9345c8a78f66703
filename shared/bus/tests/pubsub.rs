//! Two Zenoh sessions in one process, connected over TCP loopback without scouting.
#![allow(clippy::unwrap_used)]

use std::time::Duration;

use teleop_bus::attachment::Attachment;
use teleop_bus::{Bus, BusConfig, NodeEvent};
use teleop_interfaces::topics::{self, WRIST_POSE};
use teleop_msgs::{Header, JointState, PoseStamped, Time, unix_nanos_now};

fn pair_config(domain_id: u32) -> (BusConfig, BusConfig) {
    teleop_bus::testing::loopback_pair(domain_id)
}

async fn pair(domain_id: u32) -> (Bus, Bus) {
    let (a, b) = pair_config(domain_id);
    let a = Bus::open("node_a", &a).await.unwrap();
    let b = Bus::open("node_b", &b).await.unwrap();
    (a, b)
}

fn joint_state(i: usize) -> JointState {
    JointState {
        header: Header::new(Time::from_nanos(i as i64), "hand"),
        name: vec!["FFJ3".into(), "FFJ2".into()],
        position: vec![i as f64, 0.5],
        velocity: vec![],
        effort: vec![],
    }
}

/// Publishes until the subscriber sees something (discovery takes a moment).
async fn wait_connected(
    publisher: &teleop_bus::Publisher<JointState>,
    sub: &teleop_bus::Subscriber<JointState>,
) {
    for _ in 0..200 {
        publisher.put(&joint_state(0)).unwrap();
        if sub.recv_timeout(Duration::from_millis(25)).await.is_some() {
            // Let samples still in flight land, then drain them.
            tokio::time::sleep(Duration::from_millis(100)).await;
            while sub.try_recv().is_some() {}
            return;
        }
    }
    panic!("publisher and subscriber never connected");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn typed_round_trip_with_metadata() {
    let (a, b) = pair(11).await;
    let publisher = a.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    let sub = b.subscriber(&topics::SHADOW_JOINT_STATES).await.unwrap();
    wait_connected(&publisher, &sub).await;

    let seq = publisher.next_sequence();
    let sent = joint_state(42);
    publisher.put(&sent).unwrap();
    let got = sub.recv_timeout(Duration::from_secs(2)).await.unwrap();
    assert_eq!(got.msg, sent);
    assert_eq!(got.sequence, seq);
    assert_eq!(got.publisher_gid, publisher.gid());
    // From the source stamp on the same clock: never negative (how long it is, is
    // bus_latency's to measure, docs/benchmarks.md).
    assert!(got.latency_ns() >= 0);
    let stats = sub.stats();
    assert!(stats.accepted >= 2);
    assert_eq!(stats.rejected(), 0);
    assert!(stats.latency_p50_us > 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn control_topics_keep_only_the_newest() {
    let (a, b) = pair(12).await;
    let publisher = a.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    let sub = b.subscriber(&topics::SHADOW_JOINT_STATES).await.unwrap();
    wait_connected(&publisher, &sub).await;
    for i in 1..=20 {
        publisher.put(&joint_state(i)).unwrap();
        // Spaced so the transport's queue never overflows (it would drop samples).
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    // Wait until the last one is in, then there must be exactly one sample queued.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let got = sub.try_recv().unwrap();
    assert_eq!(got.msg.position[0], 20.0);
    assert!(sub.try_recv().is_none());
    assert!(sub.stats().overwritten >= 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stale_out_of_order_and_malformed_samples_are_dropped_and_counted() {
    let (a, b) = pair(13).await;
    let publisher = a.publisher(&WRIST_POSE).await.unwrap();
    let sub = b.subscriber(&WRIST_POSE).await.unwrap();
    // Connect.
    let mut connected = false;
    for _ in 0..200 {
        publisher.put(&PoseStamped::default()).unwrap();
        if sub.recv_timeout(Duration::from_millis(25)).await.is_some() {
            connected = true;
            break;
        }
    }
    assert!(connected);
    // Let samples still in flight land before taking the baseline.
    tokio::time::sleep(Duration::from_millis(100)).await;
    while sub.try_recv().is_some() {}
    let base = sub.stats();
    // Samples are spaced out below: the transport drops samples of a burst that
    // overflows its queue (congestion control `Drop`), which is not what is tested.
    let gap = || tokio::time::sleep(Duration::from_millis(10));

    // Stale: source timestamp 1 s ago, deadline is 100 ms (+20 ms tolerance).
    publisher
        .put_at(&PoseStamped::default(), unix_nanos_now() - 1_000_000_000)
        .unwrap();
    gap().await;
    // Out of order: a sequence number below the last accepted one.
    let payload = teleop_msgs::encode(&PoseStamped::default()).unwrap();
    publisher
        .put_raw(
            payload.clone(),
            Some(Attachment {
                sequence: 0,
                source_timestamp_ns: unix_nanos_now(),
                gid: publisher.gid(),
            }),
        )
        .unwrap();
    gap().await;
    // Malformed payload with a valid attachment, and a valid payload without attachment.
    let good_att = |seq| Attachment {
        sequence: seq,
        source_timestamp_ns: unix_nanos_now(),
        gid: [9; 16],
    };
    publisher
        .put_raw(vec![0, 1, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF], Some(good_att(1)))
        .unwrap();
    gap().await;
    publisher.put_raw(payload.clone(), None).unwrap();
    gap().await;
    // A sample from 1 h in the future.
    publisher
        .put_at(
            &PoseStamped::default(),
            unix_nanos_now() + 3_600_000_000_000,
        )
        .unwrap();

    tokio::time::sleep(Duration::from_millis(400)).await;
    assert!(
        sub.try_recv().is_none(),
        "nothing bad may reach the application"
    );
    let s = sub.stats();
    assert_eq!(s.dropped_stale - base.dropped_stale, 1, "{s:?}");
    assert_eq!(
        s.dropped_out_of_order - base.dropped_out_of_order,
        1,
        "{s:?}"
    );
    assert_eq!(s.decode_errors - base.decode_errors, 1, "{s:?}");
    assert_eq!(s.bad_attachment - base.bad_attachment, 1, "{s:?}");
    assert_eq!(s.dropped_from_future - base.dropped_from_future, 1, "{s:?}");
    assert_eq!(s.accepted, base.accepted);

    // A good sample still goes through afterwards.
    let mut pose = PoseStamped::default();
    pose.pose.position.x = 0.25;
    publisher.put(&pose).unwrap();
    let got = sub.recv_timeout(Duration::from_secs(2)).await.unwrap();
    assert_eq!(got.msg.pose.position.x, 0.25);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn liveliness_reports_nodes_appearing_and_vanishing() {
    let (ca, cb) = pair_config(14);
    let a = Bus::open("watcher", &ca).await.unwrap();
    let watch = a.watch_nodes().await.unwrap();
    assert_eq!(
        watch.next_event(Duration::from_secs(2)).await,
        Some(NodeEvent::Appeared("watcher".into()))
    );
    let b = Bus::open("operator_site", &cb).await.unwrap();
    let mut saw = false;
    for _ in 0..5 {
        if watch.next_event(Duration::from_secs(2)).await
            == Some(NodeEvent::Appeared("operator_site".into()))
        {
            saw = true;
            break;
        }
    }
    assert!(saw, "never saw operator_site appear");
    assert!(watch.is_alive("operator_site"));

    let publisher = b.publisher(&WRIST_POSE).await.unwrap();
    let mut entry = None;
    for _ in 0..50 {
        let graph = a.graph(Duration::from_millis(500)).await.unwrap();
        entry = graph
            .into_iter()
            .find(|e| e.node_name == "operator_site" && e.topic.is_some());
        if entry.is_some() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let entry = entry.expect("publisher announced in the graph");
    assert_eq!(entry.topic.as_deref(), Some("/teleop/wrist_pose"));
    assert_eq!(
        entry.ros_type_name().as_deref(),
        Some("geometry_msgs/msg/PoseStamped")
    );
    drop(publisher);

    b.close().await.unwrap();
    let mut gone = false;
    for _ in 0..5 {
        if watch.next_event(Duration::from_secs(2)).await
            == Some(NodeEvent::Vanished("operator_site".into()))
        {
            gone = true;
            break;
        }
    }
    assert!(gone, "never saw operator_site vanish");
    assert!(!watch.is_alive("operator_site"));
    assert_eq!(watch.alive(), vec!["watcher".to_owned()]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn samples_on_the_wire_match_rmw_zenoh() {
    let (a, b) = pair(15).await;
    let publisher = a.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    let expected_key = "15/teleop/shadow/joint_states/sensor_msgs::msg::dds_::JointState_/\
                        RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e";
    assert_eq!(publisher.key(), expected_key);
    let raw = b.session().declare_subscriber(expected_key).await.unwrap();
    let mut got = None;
    for _ in 0..200 {
        publisher.put(&joint_state(3)).unwrap();
        if let Ok(Some(s)) = raw.recv_timeout(Duration::from_millis(25)) {
            got = Some(s);
            break;
        }
    }
    let sample = got.unwrap();
    let payload = sample.payload().to_bytes();
    assert_eq!(&payload[..4], &[0, 1, 0, 0], "CDR LE encapsulation header");
    let att = sample.attachment().unwrap().to_bytes();
    assert_eq!(att.len(), 33);
    let att = Attachment::from_bytes(&att).unwrap();
    assert_eq!(att.gid, publisher.gid());
    let msg: JointState = teleop_msgs::decode(&payload).unwrap();
    assert_eq!(msg.name, vec!["FFJ3", "FFJ2"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn invalid_node_names_are_refused() {
    let err = Bus::open("bad name/x", &BusConfig::default())
        .await
        .unwrap_err();
    assert!(err.to_string().contains("bad name/x"));
}

/// A subscriber with a node source policy takes samples only from publishers that node
/// announced; a locked subscriber only from the locked publisher. Refused samples are
/// counted as foreign and their publishers remembered.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn source_policy_and_lock_refuse_other_publishers() {
    let (a, b) = pair(17).await;
    let own = a.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    let from_a = b
        .subscriber_from(&topics::SHADOW_JOINT_STATES, "node_a")
        .await
        .unwrap();
    let from_other = b
        .subscriber_from(&topics::SHADOW_JOINT_STATES, "someone_else")
        .await
        .unwrap();
    let any = b.subscriber(&topics::SHADOW_JOINT_STATES).await.unwrap();
    wait_connected(&own, &from_a).await;
    // Node a's samples reach the subscriber that wants node a, never the other.
    own.put(&joint_state(5)).unwrap();
    let got = from_a.recv_timeout(Duration::from_secs(2)).await.unwrap();
    assert_eq!(got.msg.position[0], 5.0);
    let info = from_a
        .publisher_info(&got.publisher_gid)
        .expect("announced");
    assert_eq!(info.node_name, "node_a");
    assert!(from_other.try_recv().is_none());
    // The other subscriber refuses the same samples on its own callback: give it the
    // time to see them (the probe of `wait_connected` and sample 5).
    let deadline = tokio::time::Instant::now() + Duration::from_secs(2);
    while from_other.stats().foreign < 2 && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(from_other.stats().foreign >= 2, "{:?}", from_other.stats());
    assert_eq!(from_a.stats().foreign, 0);
    // A second publisher of node a: the lock keeps only the first.
    let second = a.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    any.lock_source(Some(own.gid()));
    tokio::time::sleep(Duration::from_millis(300)).await;
    while any.try_recv().is_some() {}
    let before = any.stats().foreign;
    for i in 0..10 {
        second.put(&joint_state(100 + i)).unwrap();
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    own.put(&joint_state(7)).unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let got = any.try_recv().unwrap();
    assert_eq!(got.msg.position[0], 7.0);
    assert_eq!(got.publisher_gid, own.gid());
    assert!(any.stats().foreign >= before + 10);
    let heard = any.publishers_since(0);
    assert!(heard.iter().any(|p| p.gid == second.gid() && p.refused));
    assert!(heard.iter().any(|p| p.gid == own.gid() && !p.refused));
    any.lock_source(None);
    second.put(&joint_state(9)).unwrap();
    let got = any.recv_timeout(Duration::from_secs(2)).await.unwrap();
    assert_eq!(got.msg.position[0], 9.0);
}

/// A node that joins later (through the listening session, as a second operator station
/// would) is known by name to the others' directories.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_late_publisher_is_announced_to_the_directory() {
    let (a_cfg, mut b_cfg) = pair_config(18);
    // Listening lets the connecting sessions reach each other once gossip tells them.
    b_cfg.zenoh.listen = vec!["tcp/127.0.0.1:0".into()];
    let a = Bus::open("node_a", &a_cfg).await.unwrap();
    let b = Bus::open("node_b", &b_cfg).await.unwrap();
    let sub = b.subscriber(&topics::SHADOW_JOINT_STATES).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let c = Bus::open("late_node_c", &b_cfg).await.unwrap();
    let publisher = c.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    wait_connected(&publisher, &sub).await;
    publisher.put(&joint_state(3)).unwrap();
    let got = sub.recv_timeout(Duration::from_secs(2)).await.unwrap();
    let mut info = sub.publisher_info(&got.publisher_gid);
    for _ in 0..20 {
        if info.is_some() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
        info = sub.publisher_info(&got.publisher_gid);
    }
    assert_eq!(info.expect("announced").node_name, "late_node_c");
    drop(a);
}

/// Hardware topics travel only on the interfaces a node allows: on loopback by
/// default; a node that allows only another interface neither sends nor takes them over
/// loopback, while the other topics still flow.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hardware_topics_stay_on_the_allowed_interfaces() {
    // Allowed on loopback (the default): the command arrives.
    let (a, b) = pair(19).await;
    let cmd = a.publisher(&topics::HW_PR2_ARM_COMMAND).await.unwrap();
    let sub = b.subscriber(&topics::HW_PR2_ARM_COMMAND).await.unwrap();
    wait_connected(&cmd, &sub).await;
    drop((a, b));
    // The receiving node allows hardware topics on a LAN interface only.
    let (a_cfg, mut b_cfg) = pair_config(20);
    b_cfg.zenoh.hardware_interfaces = vec!["site_lan0".into()];
    let a = Bus::open("node_a", &a_cfg).await.unwrap();
    let b = Bus::open("node_b", &b_cfg).await.unwrap();
    let state = a.publisher(&topics::SHADOW_JOINT_STATES).await.unwrap();
    let state_sub = b.subscriber(&topics::SHADOW_JOINT_STATES).await.unwrap();
    wait_connected(&state, &state_sub).await;
    let cmd = a.publisher(&topics::HW_PR2_ARM_COMMAND).await.unwrap();
    let sub = b.subscriber(&topics::HW_PR2_ARM_COMMAND).await.unwrap();
    for i in 0..50 {
        cmd.put(&joint_state(i)).unwrap();
        state.put(&joint_state(i)).unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(
        sub.try_recv().is_none(),
        "a hardware command crossed loopback"
    );
    assert_eq!(sub.stats().received, 0);
    assert!(state_sub.try_recv().is_some(), "other topics still flow");
}

/// A node that also listens on an address outside its hardware interfaces (for the
/// operator site, say) keeps its hardware links with a peer on this host whichever of
/// its addresses that peer dials: its hardware topics travel on a second session that
/// listens on loopback alone. Trial 0 makes the peer dial the outside address on
/// purpose (before the second session, the arm's state and commands were dropped
/// there by the `lo` rule every time); the others let multicast scouting pick, as
/// `teleop launch` does.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_listening_outside_its_hardware_interfaces_keeps_same_host_hardware_links() {
    let outside = teleop_bus::config::host_addresses()
        .into_iter()
        .map(|(_, ip)| ip)
        .find(|ip| !ip.is_loopback())
        .expect("this test needs an IPv4 address on an interface other than loopback");
    for trial in 0..5u32 {
        let domain_id = 9300 + trial + std::process::id() % 500 * 8;
        let mut controller_cfg = BusConfig {
            domain_id,
            ..Default::default()
        };
        let port = teleop_bus::testing::free_port().unwrap();
        controller_cfg.zenoh.listen =
            vec![format!("tcp/{outside}:{port}"), "tcp/127.0.0.1:0".into()];
        let mut sim_cfg = BusConfig {
            domain_id,
            ..Default::default()
        };
        if trial == 0 {
            sim_cfg.zenoh.connect = vec![format!("tcp/{outside}:{port}")];
        }
        let controller = Bus::open("controller", &controller_cfg).await.unwrap();
        assert!(controller.hardware_zid().is_some(), "a hardware session");
        let sim = Bus::open("sim", &sim_cfg).await.unwrap();
        assert!(sim.hardware_zid().is_none(), "loopback only: one session");
        let cmd = controller
            .publisher(&topics::HW_PR2_ARM_COMMAND)
            .await
            .unwrap();
        let cmd_sub = sim
            .subscriber_from(&topics::HW_PR2_ARM_COMMAND, "controller")
            .await
            .unwrap();
        let state = sim.publisher(&topics::HW_PR2_ARM_STATE).await.unwrap();
        let state_sub = controller
            .subscriber(&topics::HW_PR2_ARM_STATE)
            .await
            .unwrap();
        let status = controller
            .publisher(&topics::SHADOW_JOINT_STATES)
            .await
            .unwrap();
        let status_sub = sim.subscriber(&topics::SHADOW_JOINT_STATES).await.unwrap();
        wait_connected(&cmd, &cmd_sub).await;
        wait_connected(&state, &state_sub).await;
        wait_connected(&status, &status_sub).await;
        // The command's publisher is known by name (the hardware session's token),
        // so a hardware interface that takes its controller's commands alone takes it.
        cmd.put(&joint_state(7)).unwrap();
        let got = cmd_sub
            .recv_timeout(Duration::from_secs(2))
            .await
            .unwrap_or_else(|| panic!("trial {trial}: the command did not arrive"));
        assert_eq!(got.msg.position[0], 7.0);
        controller.close().await.unwrap();
        sim.close().await.unwrap();
    }
}
