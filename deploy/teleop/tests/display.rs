//! The operator display's page in a real browser: headless Chromium (Debian's
//! `chromium` package) opens the page of a running system (`teleop launch --display`),
//! driven over the Chrome DevTools Protocol; the test reads what the page has drawn and
//! checks that both camera views and the force bars keep updating, and saves a
//! screenshot (`TELEOP_DISPLAY_SCREENSHOT=docs/img/operator-display.png` writes the one
//! in the docs).
//!
//! The browser: `$TELEOP_CHROMIUM`, else `chromium` on the PATH (`.ci/run` installs it);
//! missing, the test fails and says how to install it (`TELEOP_SKIP_BROWSER=1` skips
//! it on a machine that cannot have one).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::{free_port, http_get};
use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio_tungstenite::tungstenite::Message;

/// Stops a child process (SIGINT, then kill) when dropped.
struct Reaper(Child);

impl Drop for Reaper {
    fn drop(&mut self) {
        if let Ok(pid) = i32::try_from(self.0.id()) {
            let _ = Command::new("kill")
                .arg("-INT")
                .arg(pid.to_string())
                .status();
        }
        let deadline = Instant::now() + Duration::from_secs(15);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn chromium() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("TELEOP_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find_map(|name| {
            std::env::var_os("PATH").and_then(|paths| {
                std::env::split_paths(&paths)
                    .map(|d| d.join(name))
                    .find(|p| p.is_file())
            })
        })
}

/// A Chrome DevTools Protocol connection to the browser, with one page attached.
struct Cdp {
    ws: tokio_tungstenite::WebSocketStream<
        tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>,
    >,
    next_id: u64,
    session: Option<String>,
}

impl Cdp {
    async fn call(&mut self, method: &str, params: Value) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut msg = json!({"id": id, "method": method, "params": params});
        if let Some(s) = &self.session {
            msg["sessionId"] = json!(s);
        }
        self.ws.send(Message::text(msg.to_string())).await.unwrap();
        loop {
            let m = tokio::time::timeout(Duration::from_secs(30), self.ws.next())
                .await
                .unwrap_or_else(|_| panic!("no answer to {method}"))
                .expect("devtools socket closed")
                .unwrap();
            let Message::Text(text) = m else { continue };
            let v: Value = serde_json::from_str(&text).unwrap();
            // Events (no id) and answers to others are not ours.
            if v["id"].as_u64() == Some(id) {
                assert!(v.get("error").is_none(), "{method}: {v}");
                return v["result"].clone();
            }
        }
    }

    /// Evaluates `expr` in the page; its value (JSON-serialisable).
    async fn eval(&mut self, expr: &str) -> Value {
        let r = self
            .call(
                "Runtime.evaluate",
                json!({"expression": expr, "returnByValue": true}),
            )
            .await;
        assert!(r.get("exceptionDetails").is_none(), "{expr}: {r}");
        r["result"]["value"].clone()
    }
}

/// What the page has drawn so far (its `window.teleopDisplay`).
async fn drawn(cdp: &mut Cdp) -> Value {
    cdp.eval(
        "(() => { const d = window.teleopDisplay; if (!d) return null; \
         const img = (n) => document.getElementById('view-' + n); \
         return { connected: d.connected, states: d.states, frames: d.frames, \
           decoded: d.decoded, forceUpdates: d.forceUpdates, lastForces: d.lastForces, \
           nodes: d.nodes, bars: document.querySelectorAll('#force-bars .finger').length, \
           barHeights: Array.from(document.querySelectorAll('#force-bars .fill')).map(e => e.style.height), \
           shownWidth: { top: img('top').naturalWidth, side: img('side').naturalWidth }, \
           pr2Rows: document.querySelectorAll('#pr2-table tbody tr').length, \
           shadowRows: document.querySelectorAll('#shadow-table tbody tr').length, \
           topicRows: document.querySelectorAll('#topic-table tbody tr').length }; })()",
    )
    .await
}

#[test]
fn the_display_page_updates_in_a_real_browser() {
    if std::env::var_os("TELEOP_SKIP_BROWSER").is_some() {
        eprintln!("TELEOP_SKIP_BROWSER is set: the browser test is skipped");
        return;
    }
    let browser = chromium().unwrap_or_else(|| {
        panic!(
            "no Chromium found (TELEOP_CHROMIUM, or chromium on the PATH): install \
             Debian's package (apt-get install chromium), or set TELEOP_SKIP_BROWSER=1"
        )
    });
    let port = free_port();
    let addr = format!("127.0.0.1:{port}");
    let _system = Reaper(
        Command::new(env!("CARGO_BIN_EXE_teleop"))
            .args([
                "--domain-id",
                "94",
                "launch",
                "--duration-s",
                "60",
                "--quiet",
                "--no-report-files",
                "--display",
                &addr,
                // The touching scene: its mouse is a fixture in the operator's path, so
                // the fingertips press on it (the pick scene's objects stand aside until
                // an operator goes for them).
                "--set",
                "remote_sim.scene=touching",
            ])
            .stdout(Stdio::null())
            .spawn()
            .expect("start teleop launch"),
    );
    // The page answers, then the state names camera views received.
    let deadline = Instant::now() + Duration::from_secs(40);
    loop {
        assert!(Instant::now() < deadline, "the page never showed views");
        if let Some((status, body)) = http_get(port, "/api/state") {
            assert!(status.contains("200"), "{status}");
            let v: Value = serde_json::from_str(&body).unwrap_or(Value::Null);
            let views = v["views"].as_array().cloned().unwrap_or_default();
            if views.len() == 2 && views.iter().all(|v| v["received"].as_u64() > Some(3)) {
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    let (status, page) = http_get(port, "/").unwrap();
    assert!(
        status.contains("200") && page.contains("display.js"),
        "{status}"
    );
    let (status, _) = http_get(port, "/no/such/thing").unwrap();
    assert!(status.contains("404"), "{status}");

    let profile = std::env::temp_dir().join(format!("teleop-chromium-{}", std::process::id()));
    let mut chrome = Command::new(&browser)
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
            "--window-size=1500,1250",
            "--remote-debugging-port=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("about:blank")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("starting {}: {e}", browser.display()));
    let stderr = chrome.stderr.take().unwrap();
    let _chrome = Reaper(chrome);
    let mut devtools = None;
    for line in BufReader::new(stderr).lines() {
        let line = line.unwrap();
        if let Some(url) = line.split_whitespace().find(|w| w.starts_with("ws://")) {
            devtools = Some(url.to_owned());
            break;
        }
    }
    let devtools = devtools.expect("Chromium printed no DevTools address");

    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let (ws, _) = tokio_tungstenite::connect_async(&devtools).await.unwrap();
        let mut cdp = Cdp {
            ws,
            next_id: 0,
            session: None,
        };
        let target = cdp
            .call(
                "Target.createTarget",
                json!({"url": format!("http://{addr}/")}),
            )
            .await;
        let attached = cdp
            .call(
                "Target.attachToTarget",
                json!({"targetId": target["targetId"], "flatten": true}),
            )
            .await;
        cdp.session = Some(attached["sessionId"].as_str().unwrap().to_owned());

        // Wait until both views have been decoded and the forces drawn.
        let deadline = Instant::now() + Duration::from_secs(30);
        let first = loop {
            let d = drawn(&mut cdp).await;
            let ready = d["connected"] == json!(true)
                && d["shownWidth"]["top"].as_u64() > Some(0)
                && d["shownWidth"]["side"].as_u64() > Some(0)
                && d["forceUpdates"].as_u64() > Some(0);
            if ready {
                break d;
            }
            assert!(Instant::now() < deadline, "the page did not draw: {d}");
            tokio::time::sleep(Duration::from_millis(500)).await;
        };
        tokio::time::sleep(Duration::from_secs(4)).await;
        let later = drawn(&mut cdp).await;
        println!("first: {first}\nlater: {later}");

        // Both views keep coming and are decoded as JPEG by the browser.
        for cam in ["top", "side"] {
            let (a, b) = (
                first["frames"][cam].as_u64().unwrap(),
                later["frames"][cam].as_u64().unwrap(),
            );
            assert!(b >= a + 10, "{cam}: {a} -> {b} views in 4 s");
            assert!(later["decoded"][cam]["width"].as_u64() > Some(0), "{later}");
        }
        // The force bars are redrawn from new messages: five bars, updated.
        assert_eq!(later["bars"], json!(5), "{later}");
        assert!(
            later["forceUpdates"].as_u64().unwrap() >= first["forceUpdates"].as_u64().unwrap() + 10,
            "force bars not updating: {first} -> {later}"
        );
        assert_eq!(later["lastForces"].as_array().map(Vec::len), Some(5));
        // The state keeps coming (10 Hz): joints, nodes, topics filled in.
        assert!(later["states"].as_u64().unwrap() >= first["states"].as_u64().unwrap() + 20);
        assert_eq!(later["pr2Rows"], json!(7), "{later}");
        // The Shadow hand's joints in two columns.
        assert!(later["shadowRows"].as_u64() >= Some(8), "{later}");
        assert!(later["topicRows"].as_u64() >= Some(7), "{later}");
        for node in teleop_interfaces::nodes::NODES {
            let state = later["nodes"][node.name].as_str().unwrap_or("missing");
            assert!(
                ["active", "inactive"].contains(&state),
                "{}: {state} ({later})",
                node.name
            );
        }

        // When the simulated operator grasps, the bars show the contact: wait for a
        // fingertip pressing more than 1 N, then its bar stands above the floor.
        let deadline = Instant::now() + Duration::from_secs(45);
        let grasp = loop {
            let d = drawn(&mut cdp).await;
            let forces: Vec<f64> = d["lastForces"]
                .as_array()
                .map(|a| a.iter().filter_map(Value::as_f64).collect())
                .unwrap_or_default();
            if let Some(i) = forces.iter().position(|f| *f > 1.0) {
                break (d, i);
            }
            assert!(Instant::now() < deadline, "no grasp seen: {d}");
            tokio::time::sleep(Duration::from_millis(250)).await;
        };
        let (d, finger) = grasp;
        let height: f64 = d["barHeights"][finger]
            .as_str()
            .and_then(|h| h.trim_end_matches('%').parse().ok())
            .unwrap();
        let force = d["lastForces"][finger].as_f64().unwrap();
        println!("grasp: finger {finger} at {force:.2} N, bar {height:.1} %");
        assert!(height > 1.0, "{force} N drawn as {height} %: {d}");
        // Let the page draw the grasp for the picture.
        tokio::time::sleep(Duration::from_millis(500)).await;

        let shot = cdp
            .call(
                "Page.captureScreenshot",
                json!({"format": "png", "captureBeyondViewport": true}),
            )
            .await;
        use base64::Engine as _;
        let png = base64::engine::general_purpose::STANDARD
            .decode(shot["data"].as_str().unwrap())
            .unwrap();
        assert!(png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 50_000);
        let path = std::env::var_os("TELEOP_DISPLAY_SCREENSHOT").map_or_else(
            || std::env::temp_dir().join("teleop-operator-display.png"),
            PathBuf::from,
        );
        std::fs::write(&path, &png).unwrap();
        println!("screenshot: {}", path.display());
        cdp.session = None;
        let _ = cdp.call("Browser.close", json!({})).await;
    });
    let _ = std::fs::remove_dir_all(&profile);
}
