//! `teleop foxglove` spoken to as Foxglove speaks to it: the Foxglove WebSocket protocol
//! (subprotocol `foxglove.sdk.v1`, and its older name `foxglove.websocket.v1`; JSON
//! control messages, binary message data) over a
//! plain WebSocket client, not through the `foxglove` crate. The bridge runs as the
//! built binary; the samples come from a publisher on the bus in this process.
//!
//! Also the shipped layout (deploy/foxglove/teleop-layout.json): valid JSON in
//! Foxglove's layout shape, naming only topics the table has and the bridge serves by
//! default, with field paths the messages have.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

mod common;

use common::free_port;
use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use teleop_bus::{Bus, BusConfig, ZenohSettings};
use teleop_interfaces::joints::PR2_ARM_JOINTS;
use teleop_interfaces::topics;
use teleop_msgs::{FingertipPressures, Header, Time};
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;
use tokio_tungstenite::tungstenite::{self, Message};

/// The WebSocket subprotocol the Foxglove SDK's server (and so `teleop foxglove`)
/// speaks; the Foxglove app offers it.
const SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// The same protocol's name on the ws-protocol servers, which older clients offer.
const LEGACY_SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// How long any one step may take before the test gives up.
const STEP: Duration = Duration::from_secs(30);

fn layout_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../deploy/foxglove/teleop-layout.json")
}

/// A running `teleop foxglove`: its standard output line by line, its standard error
/// collected; killed if the test ends without stopping it.
struct Bridge {
    child: Child,
    lines: mpsc::Receiver<String>,
    stderr: Arc<Mutex<String>>,
    url: String,
}

impl Bridge {
    /// Starts `teleop ARGS` and waits for the line naming the server's address.
    fn start(args: &[String]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_teleop"))
            .args(args)
            .env("RUST_BACKTRACE", "0")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start teleop foxglove");
        let (tx, lines) = mpsc::channel();
        let out = child.stdout.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stderr = Arc::new(Mutex::new(String::new()));
        let mut err = child.stderr.take().unwrap();
        let sink = Arc::clone(&stderr);
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                sink.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        let mut bridge = Self {
            child,
            lines,
            stderr,
            url: String::new(),
        };
        let line = bridge.wait_for_line(|l| l.starts_with("Foxglove: open ws://"));
        assert!(line.ends_with(" in Foxglove (Open connection)"), "{line}");
        bridge.url = line
            .trim_start_matches("Foxglove: open ")
            .split_whitespace()
            .next()
            .unwrap()
            .to_owned();
        bridge
    }

    fn wait_for_line(&mut self, pred: impl Fn(&str) -> bool) -> String {
        let until = Instant::now() + STEP;
        loop {
            let left = until.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(l) if pred(&l) => return l,
                Ok(_) => {}
                Err(e) => panic!(
                    "no such line from teleop foxglove ({e}); its stderr:\n{}",
                    self.stderr.lock().unwrap()
                ),
            }
        }
    }

    /// Ctrl-C, then its exit status and the rest of its standard output.
    fn interrupt(mut self) -> (ExitStatus, String) {
        let pid = nix::unistd::Pid::from_raw(i32::try_from(self.child.id()).unwrap());
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
        let until = Instant::now() + STEP;
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s;
            }
            assert!(
                Instant::now() < until,
                "teleop foxglove did not stop on SIGINT; its stderr:\n{}",
                self.stderr.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(50));
        };
        let mut rest = String::new();
        while let Ok(l) = self.lines.recv_timeout(Duration::from_secs(5)) {
            rest.push_str(&l);
            rest.push('\n');
        }
        (status, rest)
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(url: &str, subprotocol: &str) -> Result<Ws, tungstenite::Error> {
    let mut request = url.into_client_request()?;
    request.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        HeaderValue::from_str(subprotocol).unwrap(),
    );
    let (ws, response) = tokio_tungstenite::connect_async(request).await?;
    assert_eq!(
        response
            .headers()
            .get("sec-websocket-protocol")
            .map(|v| v.to_str().unwrap()),
        Some(subprotocol),
        "the server agreed to another subprotocol"
    );
    Ok(ws)
}

/// Subscribes to `channel` as subscription `id` and returns the first `count`
/// messageData frames: opcode 0x01, subscription id (u32 LE), log time (u64 LE, ns),
/// the message as it travelled on the bus.
async fn subscribed_frames(
    ws: &mut Ws,
    channel: u64,
    id: u32,
    count: usize,
) -> Vec<(u32, u64, Vec<u8>)> {
    let subscribe = json!({"op": "subscribe", "subscriptions": [{"id": id, "channelId": channel}]});
    ws.send(Message::text(subscribe.to_string())).await.unwrap();
    let mut frames = Vec::new();
    while frames.len() < count {
        let Message::Binary(frame) = next(ws).await else {
            continue;
        };
        assert!(frame.len() > 13, "{} bytes", frame.len());
        assert_eq!(frame[0], 0x01, "opcode of messageData");
        let subscription = u32::from_le_bytes(frame[1..5].try_into().unwrap());
        let log_time = u64::from_le_bytes(frame[5..13].try_into().unwrap());
        frames.push((subscription, log_time, frame[13..].to_vec()));
    }
    frames
}

/// The next message from the server (pings are answered by the client itself).
async fn next(ws: &mut Ws) -> Message {
    tokio::time::timeout(STEP, ws.next())
        .await
        .expect("a message from the server in time")
        .expect("the connection open")
        .expect("a well-formed WebSocket message")
}

/// Reads the server's JSON messages until its `serverInfo` and the advertisements of
/// `want` topics have come; returns the server info and every channel advertised, by
/// topic.
async fn server_info_and_channels(
    ws: &mut Ws,
    want: &BTreeSet<String>,
) -> (Value, BTreeMap<String, Value>) {
    let (mut info, mut channels) = (None, BTreeMap::new());
    while info.is_none() || !want.iter().all(|t| channels.contains_key(t)) {
        let Message::Text(text) = next(ws).await else {
            continue;
        };
        let v: Value = serde_json::from_str(text.as_str()).expect("JSON control message");
        match v["op"].as_str() {
            Some("serverInfo") => info = Some(v),
            Some("advertise") => {
                for c in v["channels"].as_array().expect("advertise.channels") {
                    let topic = c["topic"].as_str().expect("channel topic").to_owned();
                    assert!(
                        channels.insert(topic.clone(), c.clone()).is_none(),
                        "{topic} advertised twice"
                    );
                }
            }
            _ => {}
        }
    }
    (info.unwrap(), channels)
}

/// A bus on loopback that the bridge connects to (no scouting), and the bridge's
/// Zenoh arguments for it.
fn bus_on_loopback(domain: u32) -> (BusConfig, Vec<String>) {
    let port = free_port();
    let cfg = BusConfig {
        domain_id: domain,
        zenoh: ZenohSettings {
            listen: vec![format!("tcp/127.0.0.1:{port}")],
            multicast_scouting: false,
            ..Default::default()
        },
        ..Default::default()
    };
    let args = [
        "--no-multicast-scouting",
        "--connect",
        &format!("tcp/127.0.0.1:{port}"),
        "--listen",
        "tcp/127.0.0.1:0",
        "--domain-id",
        &domain.to_string(),
    ]
    .map(str::to_owned)
    .to_vec();
    (cfg, args)
}

/// What the channel of `topic` must say: CDR, the table's ROS 2 type, its full
/// `ros2msg` definition (every type it uses after its own, as rosbag2 stores it).
fn assert_channel_is_the_topics(channel: &Value, topic: &str) {
    let spec = topics::find(topic).unwrap();
    assert_eq!(channel["topic"], topic, "{channel}");
    assert_eq!(channel["encoding"], "cdr", "{channel}");
    assert_eq!(channel["schemaName"], spec.type_name, "{channel}");
    assert_eq!(channel["schemaEncoding"], "ros2msg", "{channel}");
    let definition = teleop_msgs::description_of(spec.type_name)
        .unwrap()
        .full_definition();
    assert_eq!(channel["schema"], definition.as_str(), "{channel}");
    assert_eq!(channel["metadata"]["topic_type_hash"], spec.type_hash);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_subscribed_client_gets_the_cdr_of_the_bus_with_its_ros2_schema() {
    const TOPIC: &str = "/teleop/shadow/fingertip_pressures";
    let (cfg, zenoh_args) = bus_on_loopback(47);
    let bus = Bus::open("feedback_publisher", &cfg).await.unwrap();
    let publisher = bus.publisher(&topics::FINGERTIP_PRESSURES).await.unwrap();
    // Every message published, to find each one the client gets among them.
    let published: Arc<Mutex<Vec<FingertipPressures>>> = Arc::default();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let pump = {
        let (published, stop) = (Arc::clone(&published), Arc::clone(&stop));
        tokio::spawn(async move {
            let mut k = 0.0;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                k += 1.0;
                let msg = FingertipPressures {
                    header: Header::new(Time::now(), "rh_palm"),
                    ff: 0.5 * k,
                    mf: 1.25,
                    rf: -0.0,
                    lf: 1e-3 * k,
                    th: 7.75,
                };
                published.lock().unwrap().push(msg.clone());
                publisher.put(&msg).unwrap();
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
    };

    let ws_port = free_port();
    let mut args = zenoh_args;
    args.extend(
        [
            "foxglove",
            "--port",
            &ws_port.to_string(),
            TOPIC,
            "--duration-s",
            "120",
        ]
        .map(str::to_owned),
    );
    let bridge = tokio::task::spawn_blocking(move || Bridge::start(&args))
        .await
        .unwrap();
    assert_eq!(bridge.url, format!("ws://127.0.0.1:{ws_port}"));

    // What is not a WebSocket request is answered 400 by the front itself.
    {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut raw = tokio::net::TcpStream::connect(bridge.url.trim_start_matches("ws://"))
            .await
            .unwrap();
        raw.write_all(b"BREW /pot HTCPCP/1.0\r\n\x00\xff\r\n\r\n")
            .await
            .unwrap();
        let mut answer = Vec::new();
        tokio::time::timeout(STEP, raw.read_to_end(&mut answer))
            .await
            .unwrap()
            .unwrap();
        let answer = String::from_utf8_lossy(&answer);
        assert!(answer.starts_with("HTTP/1.1 400 "), "{answer}");
    }
    // A client offering neither name is refused at the handshake (by the SDK's server).
    match connect(&bridge.url, "some.other.protocol").await {
        Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 400),
        Err(e) => panic!("expected HTTP 400, got {e}"),
        Ok(_) => panic!("a client offering no Foxglove subprotocol was accepted"),
    }
    // A client offering only the subprotocol name of the older ws-protocol servers
    // (Lichtblick up to 1.21, Foxglove Studio before the SDK) is answered in that name
    // and served the same protocol.
    let want = BTreeSet::from([TOPIC.to_owned()]);
    let mut legacy = connect(&bridge.url, LEGACY_SUBPROTOCOL).await.unwrap();
    let (info, channels) = server_info_and_channels(&mut legacy, &want).await;
    assert_eq!(info["name"], "teleop", "{info}");
    assert_channel_is_the_topics(&channels[TOPIC], TOPIC);
    let frames =
        subscribed_frames(&mut legacy, channels[TOPIC]["id"].as_u64().unwrap(), 7, 3).await;
    assert!(
        frames.iter().all(|(sub, _, _)| *sub == 7),
        "frames of another subscription"
    );
    legacy.close(None).await.ok();

    let mut ws = connect(&bridge.url, SUBPROTOCOL).await.unwrap();
    let (info, channels) = server_info_and_channels(&mut ws, &want).await;
    assert_eq!(info["name"], "teleop", "{info}");
    assert_eq!(
        channels.keys().cloned().collect::<BTreeSet<_>>(),
        want,
        "only the topic asked for is served"
    );
    let channel = &channels[TOPIC];
    assert_channel_is_the_topics(channel, TOPIC);
    let schema = channel["schema"].as_str().unwrap();
    for line in [
        "float64 ff",
        "float64 th",
        "MSG: std_msgs/Header",
        "MSG: builtin_interfaces/Time",
    ] {
        assert!(schema.contains(line), "{line} not in the schema:\n{schema}");
    }

    let channel_id = channel["id"].as_u64().unwrap();
    let mut decoded = Vec::new();
    for (subscription, log_time, payload) in subscribed_frames(&mut ws, channel_id, 1, 5).await {
        assert_eq!(subscription, 1);
        assert_eq!(&payload[..4], &[0x00, 0x01, 0x00, 0x00], "CDR LE header");
        let msg: FingertipPressures = teleop_msgs::decode(&payload).unwrap();
        // The log time is when the bridge received the sample: after it was stamped.
        let stamped = u64::try_from(msg.header.stamp.as_nanos()).unwrap();
        assert!(
            log_time >= stamped,
            "log time {log_time} before stamp {stamped}"
        );
        decoded.push(msg);
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    pump.await.unwrap();
    let published = published.lock().unwrap().clone();
    for m in &decoded {
        assert!(
            published.contains(m),
            "{m:?} is not a message that was published"
        );
        assert_eq!(m.header.frame_id, "rh_palm");
        assert_eq!((m.mf, m.th), (1.25, 7.75));
    }
    // In the order they were published.
    assert!(decoded.windows(2).all(|w| w[0].ff < w[1].ff), "{decoded:?}");

    ws.close(None).await.ok();
    let (status, out) = tokio::task::spawn_blocking(move || bridge.interrupt())
        .await
        .unwrap();
    assert!(status.success(), "{status}\n{out}");
    let row = out
        .lines()
        .find(|l| l.trim_start().starts_with(TOPIC))
        .unwrap_or_else(|| panic!("no count for {TOPIC}:\n{out}"));
    let count: u64 = row.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(count >= 5, "{row}");
    assert!(
        out.contains("handshakes: 2 passed as offered, 1 renamed from foxglove.websocket.v1, 1 refused at the front"),
        "{out}"
    );
    bus.close().await.unwrap();
}

#[test]
fn an_unknown_topic_is_refused_by_name() {
    let (err, out) = foxglove_fails(&["--port", "0", "/teleop/status", "/teleop/no_such_topic"]);
    assert!(
        err.contains("unknown topic `/teleop/no_such_topic`"),
        "{err}"
    );
    assert!(!out.contains("ws://"));
}

/// Runs `teleop foxglove ARGS`, asserts it failed; its stderr and stdout.
fn foxglove_fails(args: &[&str]) -> (String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_teleop"))
        .args(["--no-multicast-scouting", "foxglove"])
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(!out.status.success(), "teleop foxglove {args:?} succeeded");
    (
        String::from_utf8_lossy(&out.stderr).into_owned(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn a_port_in_use_is_a_clear_error() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let (err, _) = foxglove_fails(&["--port", &port.to_string(), "/teleop/status"]);
    assert!(
        err.contains(&format!("port {port} on 127.0.0.1 is in use")),
        "{err}"
    );
    drop(taken);
}

/// The mosaic tree's leaves (panel ids).
fn leaves(node: &Value, out: &mut Vec<String>) {
    match node {
        Value::String(id) => out.push(id.clone()),
        Value::Object(split) => {
            assert!(
                matches!(split["direction"].as_str(), Some("row" | "column")),
                "{split:?}"
            );
            leaves(&split["first"], out);
            leaves(&split["second"], out);
        }
        other => panic!("not a mosaic node: {other}"),
    }
}

/// A message path `/topic.field...` split into its topic and field path.
fn split_path(path: &str) -> (&str, &str) {
    path.split_once('.').unwrap_or((path, ""))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_layout_shows_topics_the_bridge_serves_by_default() {
    let text = std::fs::read_to_string(layout_path()).unwrap();
    let layout: Value = serde_json::from_str(&text).expect("the layout is JSON");
    for key in ["configById", "layout", "globalVariables", "userNodes"] {
        assert!(layout.get(key).is_some(), "no {key}");
    }
    assert!(layout["playbackConfig"]["speed"].is_number());
    let config = layout["configById"].as_object().unwrap();
    let mut panels = Vec::new();
    leaves(&layout["layout"], &mut panels);
    assert_eq!(
        panels.iter().cloned().collect::<BTreeSet<_>>(),
        config.keys().cloned().collect::<BTreeSet<_>>(),
        "every panel configured is placed, and only those"
    );

    // (panel kind, topic, field path) of everything the layout shows.
    let mut shown: Vec<(&str, &str, &str)> = Vec::new();
    for (id, cfg) in config {
        let kind = id.split('!').next().unwrap();
        match kind {
            "Image" => shown.push((kind, cfg["imageMode"]["imageTopic"].as_str().unwrap(), "")),
            "Plot" => {
                for p in cfg["paths"].as_array().unwrap() {
                    assert_eq!(p["enabled"], true, "{p}");
                    let (topic, field) = split_path(p["value"].as_str().unwrap());
                    shown.push((kind, topic, field));
                }
            }
            "RawMessages" => {
                let (topic, field) = split_path(cfg["topicPath"].as_str().unwrap());
                shown.push((kind, topic, field));
            }
            other => panic!("a panel the test does not know: {other}"),
        }
    }
    let count = |k: &str| config.keys().filter(|id| id.starts_with(k)).count();
    assert_eq!(count("Image!"), 2);
    // Each topic is in the table, crosses between the sites (so the bridge serves it
    // with no topic named), and has the fields the panels read.
    for (kind, topic, field) in &shown {
        let spec = topics::find(topic).unwrap_or_else(|| panic!("{topic} not in the table"));
        assert!(topic.starts_with('/'), "{topic}");
        assert!(
            spec.direction.crosses_sites(),
            "{topic} is not bridged by default"
        );
        let desc = teleop_msgs::description_of(spec.type_name).unwrap();
        if !field.is_empty() {
            let name = field.split('[').next().unwrap();
            assert!(
                desc.fields.iter().any(|f| f.name == name),
                "{topic} ({}) has no field {name}",
                spec.type_name
            );
        }
        if *kind == "Image" {
            assert_eq!(spec.type_name, "sensor_msgs/msg/CompressedImage", "{topic}");
        }
    }
    let topics_shown: BTreeSet<&str> = shown.iter().map(|(_, t, _)| *t).collect();
    for t in [
        "/teleop/remote_camera/top/image/compressed",
        "/teleop/remote_camera/side/image/compressed",
        "/teleop/shadow/fingertip_pressures",
        "/teleop/pr2/joint_states",
        "/teleop/shadow/joint_states",
        "/teleop/status",
    ] {
        assert!(topics_shown.contains(t), "the layout does not show {t}");
    }
    // The five fingertips plotted, and the PR2 chain's seven joints.
    let fields = |topic: &str| -> BTreeSet<&str> {
        shown
            .iter()
            .filter(|(k, t, _)| *k == "Plot" && *t == topic)
            .map(|(_, _, f)| *f)
            .collect()
    };
    assert_eq!(
        fields("/teleop/shadow/fingertip_pressures"),
        BTreeSet::from(["ff", "mf", "rf", "lf", "th"])
    );
    let pr2 = fields("/teleop/pr2/joint_states");
    assert_eq!(pr2.len(), PR2_ARM_JOINTS.len());
    for i in 0..PR2_ARM_JOINTS.len() {
        assert!(pr2.contains(format!("position[{i}]").as_str()), "{pr2:?}");
    }

    // The bridge with no topic named serves every topic the layout shows, with its
    // table's type: exactly the topics that cross between the sites.
    let ws_port = free_port();
    let args: Vec<String> = [
        "--no-multicast-scouting",
        "--listen",
        "tcp/127.0.0.1:0",
        "--domain-id",
        "48",
        "foxglove",
        "--port",
        &ws_port.to_string(),
    ]
    .map(str::to_owned)
    .to_vec();
    let bridge = tokio::task::spawn_blocking(move || Bridge::start(&args))
        .await
        .unwrap();
    let mut ws = connect(&bridge.url, SUBPROTOCOL).await.unwrap();
    let crossing: BTreeSet<String> = topics::ALL
        .iter()
        .filter(|t| t.direction.crosses_sites())
        .map(|t| format!("/{}", t.name))
        .collect();
    let (_, channels) = server_info_and_channels(&mut ws, &crossing).await;
    assert_eq!(channels.keys().cloned().collect::<BTreeSet<_>>(), crossing);
    for t in &topics_shown {
        assert_channel_is_the_topics(&channels[*t], t);
    }
    ws.close(None).await.ok();
    let (status, out) = tokio::task::spawn_blocking(move || bridge.interrupt())
        .await
        .unwrap();
    assert!(status.success(), "{status}\n{out}");
}
