//! Security between the sites, tried from outside on loopback: two site routers with
//! mutual TLS and the access control generated from the topic and node tables
//! (`teleop_node::access`), the robot site's simulator and PR2 arm controller behind
//! the remote router, and peers that should not be able to make the robot move.
//!
//! * a client whose certificate is not signed by the deployment's authority, and one
//!   without TLS, cannot connect at all;
//! * a client with a valid certificate but no permission (an unknown identity, an
//!   observer, an identity of the other site) publishing clutch, enable and wrist poses
//!   at either router: nothing reaches the controller, the arm does not move;
//! * the operator site's own identity (what a compromised or broken operator node
//!   could send) gets through the routers, and what it sends badly is refused and
//!   counted at the robot site: malformed bytes, a NaN pose, a replayed sequence
//!   number, a future timestamp; the arm does not move.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use nalgebra::SVector;
use teleop_bus::{Attachment, Bus, BusConfig, Mode, Subscriber, ZenohSettings};
use teleop_hardware::wire;
use teleop_interfaces::joints::PR2_ARM_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{Header, JointState, NodeStatus, OperatorInput, Pose, PoseStamped, Time};
use teleop_node::access::{AccessConfig, SiteName};
use teleop_node::certs::{self, Identity};
use teleop_node::router::RouterConfig;
use teleop_remote_site::arm_node::{self, ArmNodeConfig};
use teleop_sim_nodes::remote_sim::{self, SimNodeConfig};
use teleop_system_tests::free_port;

const DOMAIN: u32 = 41;

fn identities(names: &[&str]) -> Vec<Identity> {
    names.iter().map(|n| n.parse().unwrap()).collect()
}

/// A client of the router at `port` with identity `name` from `dir`.
fn client(port: u16, dir: &Path, name: &str) -> BusConfig {
    BusConfig {
        domain_id: DOMAIN,
        zenoh: ZenohSettings {
            mode: Mode::Client,
            connect: vec![format!("tls/127.0.0.1:{port}")],
            listen: Vec::new(),
            multicast_scouting: false,
            tls: Some(certs::tls_settings(dir, name)),
            ..Default::default()
        },
        ..Default::default()
    }
}

/// A site router listening on `port` (and connecting to `peer_port`).
fn router(
    site: SiteName,
    name: &str,
    port: u16,
    peer_port: Option<u16>,
    dir: &Path,
) -> RouterConfig {
    let mut cfg = RouterConfig::default();
    let z = &mut cfg.bus.zenoh;
    z.listen = vec![format!("tls/127.0.0.1:{port}")];
    z.connect = peer_port
        .map(|p| vec![format!("tls/127.0.0.1:{p}")])
        .unwrap_or_default();
    z.tls = Some(certs::tls_settings(dir, name));
    cfg.access = AccessConfig {
        enabled: true,
        site,
        peer_routers: vec![site.other().router_name().into()],
        observers: vec!["teleop-observer".into()],
    };
    teleop_node::config::validate_all(&mut cfg).unwrap();
    cfg
}

fn pose_at(x: f64, stamp_ns: i64) -> PoseStamped {
    let mut p = Pose::default();
    p.position.x = x;
    p.position.z = 0.3;
    p.orientation.w = 1.0;
    PoseStamped {
        header: Header::new(Time::from_nanos(stamp_ns), "ur5_base"),
        pose: p,
    }
}

fn pedals(stamp_ns: i64, clutch: bool) -> OperatorInput {
    OperatorInput {
        header: Header::new(Time::from_nanos(stamp_ns), ""),
        clutch,
        enable: true,
        camera_stop: false,
        motion_scale: 1.0,
    }
}

/// Tries to make the arm move from `bus` for `duration`: enable and clutch held, the
/// wrist sweeping 20 cm, 5 rad/s straight onto the arm's hardware topic, 50 Hz.
async fn try_to_drive(bus: &Bus, duration: Duration) {
    let input = bus.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let wrist = bus.publisher(&topics::WRIST_POSE).await.unwrap();
    let hw = bus.publisher(&topics::HW_PR2_ARM_COMMAND).await.unwrap();
    let fast = JointState {
        name: PR2_ARM_JOINTS.iter().map(|s| (*s).to_owned()).collect(),
        velocity: vec![3.0; 7],
        ..Default::default()
    };
    let t0 = tokio::time::Instant::now();
    let mut i = 0u32;
    while t0.elapsed() < duration {
        let now = bus.clock().now_ns();
        let x = 0.4 + 0.2 * (f64::from(i) / 100.0).min(1.0);
        input.put(&pedals(now, i > 10)).unwrap();
        wrist.put(&pose_at(x, now)).unwrap();
        hw.put(&fast).unwrap();
        i += 1;
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// The newest status of `node` seen on `statuses` within `wait`.
async fn latest_status(
    statuses: &Subscriber<NodeStatus>,
    node: &str,
    wait: Duration,
) -> NodeStatus {
    let until = tokio::time::Instant::now() + wait;
    let mut last = None;
    while tokio::time::Instant::now() < until {
        if let Some(r) = statuses.recv_timeout(Duration::from_millis(100)).await
            && r.msg.node_name == node
        {
            last = Some(r.msg);
        }
    }
    last.unwrap_or_else(|| panic!("no status of {node} within {wait:?}"))
}

fn counter(s: &NodeStatus, name: &str) -> u64 {
    s.counter_names
        .iter()
        .position(|n| n == name)
        .map_or(0, |i| s.counter_values[i])
}

/// Largest joint excursion of the arm over `states` since the first.
fn arm_moved(states: &[JointState]) -> f64 {
    let q: Vec<SVector<f64, 7>> = states
        .iter()
        .map(|m| wire::arm_state(&PR2_ARM_JOINTS, m).unwrap().position_rad)
        .collect();
    q.iter().map(|x| (x - q[0]).amax()).fold(0.0, f64::max)
}

fn drain(sub: &Subscriber<JointState>) -> Vec<JointState> {
    std::iter::from_fn(|| sub.try_recv().map(|r| r.msg)).collect()
}

fn cert_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("teleop-security-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Zenoh's TLS link needs its receive tasks on the transmit thread
/// (teleop_node::tls_runtime); the shipped binaries start themselves again with that
/// setting, a test runs itself again the same way: `false` in the first process (which
/// has run the test `name` in a second one and checked that it passed), `true` in the
/// second, which runs the test's body.
fn in_tls_safe_runtime(name: &str) -> bool {
    use teleop_node::tls_runtime::{TLS_SAFE_RUNTIME, ZENOH_RUNTIME_ENV};
    if std::env::var_os(ZENOH_RUNTIME_ENV).is_some() {
        return true;
    }
    let status = std::process::Command::new(std::env::current_exe().unwrap())
        .args([name, "--exact", "--nocapture"])
        .env(ZENOH_RUNTIME_ENV, TLS_SAFE_RUNTIME)
        .status()
        .unwrap();
    assert!(
        status.success(),
        "the test in a TLS-safe zenoh runtime failed"
    );
    false
}

/// The deployment's authority and identities in a fresh directory (`tag`), two site
/// routers with TLS and the generated access control on loopback, the robot site's
/// simulator and PR2 arm controller (running for `run_s` and `run_s - 1` s) behind the
/// remote router, and an observer there.
struct Deployment {
    dir: PathBuf,
    local_port: u16,
    remote_port: u16,
    local_router: zenoh::Session,
    remote_router: zenoh::Session,
    sim_task: tokio::task::JoinHandle<anyhow::Result<teleop_node::FinalReport>>,
    arm_task: tokio::task::JoinHandle<anyhow::Result<teleop_node::FinalReport>>,
    observer: Bus,
}

impl Deployment {
    async fn start(tag: &str, run_s: u64) -> Self {
        let dir = cert_dir(tag);
        certs::issue(
            &dir,
            &identities(&[
                "local-router=127.0.0.1",
                "remote-router=127.0.0.1",
                "remote_sim",
                "pr2_arm_controller",
                "feedback_publisher",
                "wrist_tracker",
                "hand_inference",
                "teleop-observer",
                "intruder",
            ]),
            1,
            false,
        )
        .unwrap();
        let dir = dir.as_path();
        let (local_port, remote_port) = (free_port().unwrap(), free_port().unwrap());
        let remote_router = zenoh::open(
            router(SiteName::Remote, "remote-router", remote_port, None, dir)
                .to_zenoh()
                .unwrap(),
        )
        .await
        .unwrap();
        let local_router = zenoh::open(
            router(
                SiteName::Local,
                "local-router",
                local_port,
                Some(remote_port),
                dir,
            )
            .to_zenoh()
            .unwrap(),
        )
        .await
        .unwrap();
        let sim = SimNodeConfig {
            bus: client(remote_port, dir, "remote_sim"),
            ..Default::default()
        };
        let sim_task = tokio::spawn(remote_sim::run(sim, Some(Duration::from_secs(run_s))));
        tokio::time::sleep(Duration::from_millis(300)).await;
        let arm = ArmNodeConfig {
            // The arm alone: no hand whose commanders it would wait for.
            hand_nodes: Vec::new(),
            bus: client(remote_port, dir, "pr2_arm_controller"),
            ..Default::default()
        };
        let arm_task = tokio::spawn(arm_node::run(arm, Some(Duration::from_secs(run_s - 1))));
        let observer = Bus::open(
            "teleop_observer",
            &client(remote_port, dir, "teleop-observer"),
        )
        .await
        .unwrap();
        Self {
            dir: dir.to_path_buf(),
            local_port,
            remote_port,
            local_router,
            remote_router,
            sim_task,
            arm_task,
            observer,
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_the_operator_site_commands_the_robot_and_bad_commands_are_refused_and_counted() {
    if !in_tls_safe_runtime(
        "only_the_operator_site_commands_the_robot_and_bad_commands_are_refused_and_counted",
    ) {
        return;
    }
    // The deployment; a rogue authority beside its own.
    let Deployment {
        dir,
        local_port,
        remote_port,
        local_router,
        remote_router,
        sim_task,
        arm_task,
        observer,
    } = Deployment::start("ca", 16).await;
    let rogue = cert_dir("rogue");
    certs::issue(&rogue, &identities(&["wrist_tracker"]), 1, false).unwrap();

    let states = observer
        .subscriber(&topics::HW_PR2_ARM_STATE)
        .await
        .unwrap();
    let statuses = observer
        .subscriber_with(
            &topics::NODE_STATUS,
            teleop_bus::guard::GuardSettings {
                deadline_ns: None,
                ..observer.guard_settings(&topics::NODE_STATUS.spec)
            },
            teleop_bus::SourcePolicy::Any,
        )
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let first = states.recv_timeout(Duration::from_secs(2)).await;
    assert!(
        first.is_some(),
        "the observer hears the arm's encoders on the robot's site"
    );

    // 1. No connection without a certificate of the deployment's authority.
    let mut forged = client(local_port, &rogue, "wrist_tracker");
    if let Some(tls) = forged.zenoh.tls.as_mut() {
        // It even trusts the real authority (its certificate is public).
        tls.ca_certificate = dir.join(certs::CA_CERT);
    }
    let e = Bus::open("wrist_tracker", &forged).await.err();
    assert!(e.is_some(), "a certificate of another authority connected");
    println!("rogue certificate: {}", e.unwrap());
    let mut plain = client(local_port, &dir, "wrist_tracker");
    plain.zenoh.tls = None;
    plain.zenoh.connect = vec![format!("tcp/127.0.0.1:{local_port}")];
    assert!(
        Bus::open("wrist_tracker", &plain).await.is_err(),
        "a client without TLS connected"
    );

    // 2. Valid certificates, no permission: at the operator's router, at the robot's
    // router (as if on the WAN), an observer, an identity of the other site.
    let _ = drain(&states);
    for (who, port, node) in [
        ("intruder", local_port, "wrist_tracker"),
        ("intruder", remote_port, "wrist_tracker"),
        ("teleop-observer", local_port, "teleop_cli_1"),
        ("pr2_arm_controller", local_port, "pr2_arm_controller"),
    ] {
        let bus = Bus::open(node, &client(port, &dir, who)).await.unwrap();
        try_to_drive(&bus, Duration::from_millis(1200)).await;
        bus.close().await.unwrap();
    }
    let status = latest_status(&statuses, "pr2_arm_controller", Duration::from_millis(2200)).await;
    let moved = arm_moved(&drain(&states));
    println!(
        "unauthorised peers: wrist poses received {}, pedals received {}, engagements {}, arm moved {moved:.5} rad",
        counter(&status, "wrist_pose.received"),
        counter(&status, "operator_input.received"),
        counter(&status, "arm.engagements"),
    );
    for c in [
        "wrist_pose.received",
        "operator_input.received",
        "arm.engagements",
    ] {
        assert_eq!(
            counter(&status, c),
            0,
            "{c}: an unauthorised peer's command got through"
        );
    }
    assert!(moved < 2e-3, "the arm moved {moved} rad");
    let sim_status = latest_status(&statuses, "remote_sim", Duration::from_millis(1200)).await;
    let foreign = counter(&sim_status, "pr2_arm.command.rejected_foreign");
    let accepted = counter(&sim_status, "pr2_arm.command.accepted");
    println!(
        "simulator: arm commands accepted {accepted} (the controller's), refused as foreign {foreign}"
    );
    assert_eq!(foreign, 0, "hardware commands reached the simulator");
    assert!(
        accepted > 0,
        "the controller's own commands must reach the simulator"
    );

    // 3. The operator site's own identity: its samples get through, bad ones are
    // refused and counted at the robot site, and the arm stays still.
    let op = Bus::open("wrist_tracker", &client(local_port, &dir, "wrist_tracker"))
        .await
        .unwrap();
    let input = op.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let wrist = op.publisher(&topics::WRIST_POSE).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let gid = wrist.gid();
    let clock = op.clock().clone();
    let att = |sequence: i64, offset_ns: i64| Attachment {
        sequence,
        source_timestamp_ns: clock.now_ns() + offset_ns,
        gid,
    };
    let pose_bytes = |x: f64| teleop_msgs::encode(&pose_at(x, clock.now_ns())).unwrap();
    // a. A fresh clutch press with enable held, NaN poses only: the arm node refuses each at receipt
    // (it polls the newest pose at 30 Hz; they come every 60 ms), nothing engages.
    let mut nan_sent = 0i64;
    for i in 0..30i64 {
        // Released first, then pressed: a fresh press (a controller does not take
        // pedals held since before it heard them for one).
        input.put(&pedals(clock.now_ns(), i >= 3)).unwrap();
        if i % 3 == 2 {
            nan_sent += 1;
            wrist
                .put_raw(pose_bytes(f64::NAN), Some(att(nan_sent, 0)))
                .unwrap();
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // b. Clutch released (enable held): malformed bytes, a sample from 5 s in the
    // future, a valid pose, then a replay of an older sequence number; the bus
    // guards count each at receipt.
    let mut sent = std::collections::BTreeMap::<&str, u64>::new();
    for round in 1..=5i64 {
        input.put(&pedals(clock.now_ns(), false)).unwrap();
        let base = 1000 * round;
        let samples = [
            (
                "malformed",
                vec![0xde, 0xad, 0xbe, 0xef, 1, 2, 3],
                att(base + 1, 0),
            ),
            ("future", pose_bytes(0.45), att(base + 2, 5_000_000_000)),
            ("valid", pose_bytes(0.40), att(base + 50, 0)),
            ("replayed", pose_bytes(0.60), att(base + 3, 0)),
        ];
        for (kind, bytes, attachment) in samples {
            wrist.put_raw(bytes, Some(attachment)).unwrap();
            *sent.entry(kind).or_default() += 1;
            // Spaced: control samples are dropped, not queued, when the link is busy.
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let moved = arm_moved(&drain(&states));
    op.close().await.unwrap();

    let report = arm_task.await.unwrap().unwrap();
    let c = |n: &str| report.counter(n).unwrap_or(0);
    println!(
        "operator identity: received {} wrist poses: decode {}, non-finite {}, from future {}, out of order {}; pedals received {}; engagements {}; arm moved {moved:.5} rad",
        c("wrist_pose.received"),
        c("wrist_pose.rejected_decode"),
        c("wrist_pose.rejected_non_finite"),
        c("wrist_pose.rejected_from_future"),
        c("wrist_pose.rejected_out_of_order"),
        c("operator_input.received"),
        c("arm.engagements"),
    );
    assert!(
        c("operator_input.received") >= 30,
        "the operator's pedals did not get through"
    );
    let total = nan_sent as u64 + sent.values().sum::<u64>();
    assert_eq!(
        c("wrist_pose.received"),
        total,
        "every wrist sample reached the robot site"
    );
    assert_eq!(c("wrist_pose.rejected_decode"), sent["malformed"]);
    assert_eq!(c("wrist_pose.rejected_from_future"), sent["future"]);
    assert_eq!(c("wrist_pose.rejected_out_of_order"), sent["replayed"]);
    assert!(
        c("wrist_pose.rejected_non_finite") >= 1,
        "no NaN pose was refused"
    );
    assert_eq!(c("arm.engagements"), 0, "bad samples engaged the arm");
    assert!(moved < 2e-3, "the arm moved {moved} rad");

    observer.close().await.unwrap();
    sim_task.await.unwrap().unwrap();
    local_router.close().await.unwrap();
    remote_router.close().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&rogue);
}

/// The keys of the replies to a query on `key` from `bus` (an admin-space read), but
/// those of `bus`'s own session (a Zenoh session answers about its own links).
async fn replies(bus: &Bus, key: &str) -> Vec<String> {
    let own = format!("@/{}/", bus.zid());
    let replies = bus
        .session()
        .get(key)
        .timeout(Duration::from_millis(1500))
        .await
        .unwrap();
    let mut keys = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result()
            && !sample.key_expr().as_str().starts_with(&own)
        {
            keys.push(sample.key_expr().to_string());
        }
    }
    keys
}

/// The Zenoh ids that announce node `name` in `bus`'s graph.
async fn zids_of(bus: &Bus, name: &str) -> Vec<String> {
    let mut zids: Vec<String> = bus
        .graph(Duration::from_millis(800))
        .await
        .unwrap()
        .into_iter()
        .filter(|e| e.node_name == name)
        .map(|e| e.zid)
        .collect();
    zids.sort();
    zids.dedup();
    zids
}

/// Identity claims, end to end through the routers: an allowed identity of the robot
/// site (the feedback publisher) announcing a publisher under `pr2_arm_controller` and
/// sending arm commands; an operator-site identity (hand inference) announcing
/// `wrist_tracker` while the real one runs and sending wrist poses; strangers reading
/// the routers' admin space. Each is refused (no token in the robot site's graph, no
/// sample at the robot site, no reply) and nothing moves, while the same paths carry
/// the real nodes' samples and answer the observer.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn identity_claims_are_refused_and_only_observers_read_the_admin_space() {
    if !in_tls_safe_runtime("identity_claims_are_refused_and_only_observers_read_the_admin_space") {
        return;
    }
    let Deployment {
        dir,
        local_port,
        remote_port,
        local_router,
        remote_router,
        sim_task,
        arm_task,
        observer,
    } = Deployment::start("claims", 14).await;
    let states = observer
        .subscriber(&topics::HW_PR2_ARM_STATE)
        .await
        .unwrap();
    let commands = observer
        .subscriber(&topics::HW_PR2_ARM_COMMAND)
        .await
        .unwrap();
    let poses = observer.subscriber(&topics::WRIST_POSE).await.unwrap();
    // The real wrist tracker, at the operator's router: poses with the clutch released.
    let real = Bus::open("wrist_tracker", &client(local_port, &dir, "wrist_tracker"))
        .await
        .unwrap();
    let real_input = real.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    let real_wrist = real.publisher(&topics::WRIST_POSE).await.unwrap();
    let real_gid = real_wrist.gid();
    let real_run = {
        let clock = real.clock().clone();
        tokio::spawn(async move {
            for _ in 0..250 {
                let now = clock.now_ns();
                real_input.put(&pedals(now, false)).unwrap();
                real_wrist.put(&pose_at(0.5, now)).unwrap();
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
    };
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert!(
        states.recv_timeout(Duration::from_secs(2)).await.is_some(),
        "the observer hears the arm's encoders"
    );
    let _ = drain(&states);
    let real_zid = zids_of(&observer, "wrist_tracker").await;
    assert_eq!(
        real_zid,
        [real.zid()],
        "the robot site sees the real tracker"
    );
    let arm_zids = zids_of(&observer, "pr2_arm_controller").await;
    assert_eq!(arm_zids.len(), 1, "one arm controller: {arm_zids:?}");
    let since = observer.clock().now_ns();

    // a. The feedback publisher's identity claims the arm controller's name and sends
    // 3 rad/s to every arm joint; b. hand inference's identity claims the wrist
    // tracker's and sends wrist poses, while the real one runs.
    let fake_arm = Bus::open(
        "pr2_arm_controller",
        &client(remote_port, &dir, "feedback_publisher"),
    )
    .await
    .unwrap();
    let fake_wrist = Bus::open("wrist_tracker", &client(local_port, &dir, "hand_inference"))
        .await
        .unwrap();
    let fake_cmd = fake_arm
        .publisher(&topics::HW_PR2_ARM_COMMAND)
        .await
        .unwrap();
    let fake_pose = fake_wrist.publisher(&topics::WRIST_POSE).await.unwrap();
    let fast = JointState {
        name: PR2_ARM_JOINTS.iter().map(|s| (*s).to_owned()).collect(),
        velocity: vec![3.0; 7],
        ..Default::default()
    };
    for _ in 0..75 {
        fake_cmd.put(&fast).unwrap();
        fake_pose
            .put(&pose_at(0.7, fake_wrist.clock().now_ns()))
            .unwrap();
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let claimed_arm = zids_of(&observer, "pr2_arm_controller").await;
    let claimed_wrist = zids_of(&observer, "wrist_tracker").await;
    let command_sources: Vec<[u8; 16]> = commands
        .publishers_since(since)
        .iter()
        .map(|p| p.gid)
        .collect();
    let pose_sources: Vec<[u8; 16]> = poses
        .publishers_since(since)
        .iter()
        .map(|p| p.gid)
        .collect();
    let moved = arm_moved(&drain(&states));
    println!(
        "claims: arm controller announced by {claimed_arm:?} (the real one {arm_zids:?}); \
         wrist tracker by {claimed_wrist:?} (the real one {real_zid:?}); \
         arm command publishers heard {}, wrist pose publishers heard {}; arm moved {moved:.5} rad",
        command_sources.len(),
        pose_sources.len()
    );
    assert_eq!(
        claimed_arm, arm_zids,
        "a second pr2_arm_controller announced"
    );
    assert_eq!(claimed_wrist, real_zid, "a second wrist_tracker announced");
    assert!(
        !command_sources.contains(&fake_cmd.gid()),
        "the claimed arm controller's commands reached the robot site"
    );
    assert!(
        !command_sources.is_empty(),
        "the real controller's commands are heard (the check can see a command)"
    );
    assert!(
        !pose_sources.contains(&fake_pose.gid()),
        "the claimed wrist tracker's poses reached the robot site"
    );
    assert!(
        pose_sources.contains(&real_gid),
        "the real tracker's poses are heard (the check can see a pose)"
    );
    assert!(moved < 2e-3, "the arm moved {moved} rad");

    // c. The admin space: the routers answer the observer, nobody else.
    let observed = replies(&observer, "@/**").await;
    let mut refused = Vec::new();
    for (who, port) in [
        ("intruder", local_port),
        ("intruder", remote_port),
        ("wrist_tracker", local_port),
        ("pr2_arm_controller", remote_port),
    ] {
        let bus = Bus::open("teleop_cli_2", &client(port, &dir, who))
            .await
            .unwrap();
        refused.push((who, port, replies(&bus, "@/**").await));
        bus.close().await.unwrap();
    }
    println!(
        "admin space: the observer got {} replies ({:?}...); others {refused:?}",
        observed.len(),
        &observed[..observed.len().min(3)]
    );
    assert!(
        !observed.is_empty(),
        "the observer reads the routers' admin space"
    );
    for (who, port, keys) in refused {
        assert!(keys.is_empty(), "{who} at port {port} read {keys:?}");
    }

    fake_arm.close().await.unwrap();
    fake_wrist.close().await.unwrap();
    real_run.abort();
    real.close().await.unwrap();
    observer.close().await.unwrap();
    let report = arm_task.await.unwrap().unwrap();
    assert_eq!(report.counter("arm.engagements").unwrap_or(0), 0);
    sim_task.await.unwrap().unwrap();
    local_router.close().await.unwrap();
    remote_router.close().await.unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
