//! The operator display's browser page: HTTP and a WebSocket, served by the
//! `operator_display` node itself (no build step, no internet: the page, its script and
//! its style sheet are compiled into the binary).
//!
//! * `GET /` the page, `GET /display.js`, `GET /display.css` its assets;
//! * `GET /api/state` the newest state as JSON (for `curl` and scripts);
//! * `GET /ws` a WebSocket: the state as a JSON text message at the display's state rate,
//!   each camera view as a binary message as it arrives ([`FRAME_HEADER_LEN`] bytes of
//!   header, then the JPEG).
//!
//! The node hands the newest state and views to a [`WebHub`] (a `watch` channel each:
//! never blocks, keeps only the newest). Each browser has a task of its own that sends
//! what is newest when its socket takes more: a slow browser gets fewer frames (the
//! skipped ones are counted), never a queue, and cannot hold the node or the bus back.
//! The page commands nothing; what a browser sends is read and ignored.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use tokio::sync::watch;

/// The page and its assets, compiled in.
const PAGE_HTML: &str = include_str!("display_web/index.html");
const PAGE_JS: &str = include_str!("display_web/display.js");
const PAGE_CSS: &str = include_str!("display_web/display.css");

/// Bytes before the JPEG in a view's binary message: camera index (u8), the view's
/// sequence number at the display (u64 LE), its source stamp (i64 LE, ns since the Unix
/// epoch).
pub const FRAME_HEADER_LEN: usize = 17;

/// The cameras, in the order of the index in a view's binary message.
pub const CAMERAS: [&str; 2] = ["top", "side"];

/// One camera view ready to send: header and JPEG in one buffer.
#[derive(Debug)]
pub struct ViewFrame {
    pub seq: u64,
    pub message: axum::body::Bytes,
}

impl ViewFrame {
    /// The binary message of view `seq` of camera `camera` (an index into [`CAMERAS`]).
    pub fn new(camera: u8, seq: u64, stamp_ns: i64, jpeg: &[u8]) -> Self {
        let mut buf = Vec::with_capacity(FRAME_HEADER_LEN + jpeg.len());
        buf.push(camera);
        buf.extend_from_slice(&seq.to_le_bytes());
        buf.extend_from_slice(&stamp_ns.to_le_bytes());
        buf.extend_from_slice(jpeg);
        Self {
            seq,
            message: buf.into(),
        }
    }
}

/// What the web side has done, for the node's counters.
#[derive(Debug, Default)]
pub struct WebStats {
    /// Browsers connected now.
    pub clients: AtomicU64,
    /// WebSocket connections accepted since the start.
    pub connections: AtomicU64,
    /// Connections refused because `web_max_clients` were connected.
    pub refused: AtomicU64,
    /// Views sent to browsers (all browsers together).
    pub frames_sent: AtomicU64,
    /// Views a browser did not get because a newer one came before its socket took the
    /// older (slow browsers).
    pub frames_skipped: AtomicU64,
    /// State messages sent.
    pub states_sent: AtomicU64,
    /// Bytes sent over WebSockets.
    pub bytes_sent: AtomicU64,
    /// Browsers dropped because a send did not complete within the send timeout.
    pub send_timeouts: AtomicU64,
    /// HTTP requests served (page, assets, state).
    pub http_requests: AtomicU64,
}

/// Where the node puts the newest state and views for the browsers.
#[derive(Debug)]
pub struct WebHub {
    state: watch::Sender<Arc<str>>,
    views: [watch::Sender<Option<Arc<ViewFrame>>>; 2],
    pub stats: WebStats,
    max_clients: u64,
    send_timeout: Duration,
}

impl WebHub {
    pub fn new(max_clients: u64, send_timeout: Duration) -> Arc<Self> {
        Arc::new(Self {
            state: watch::Sender::new(Arc::from("{}")),
            views: [watch::Sender::new(None), watch::Sender::new(None)],
            stats: WebStats::default(),
            max_clients,
            send_timeout,
        })
    }

    /// The newest state (JSON text). Never blocks.
    pub fn set_state(&self, json: String) {
        self.state.send_replace(Arc::from(json));
    }

    /// The newest view of camera `camera` (an index into [`CAMERAS`]). Never blocks.
    pub fn set_view(&self, camera: usize, frame: ViewFrame) {
        if let Some(tx) = self.views.get(camera) {
            tx.send_replace(Some(Arc::new(frame)));
        }
    }
}

/// Adds `n` to one of the [`WebStats`] counters.
fn count(counter: &AtomicU64, n: u64) {
    counter.fetch_add(n, Ordering::Relaxed);
}

/// Why the page could not be served.
#[derive(Debug, thiserror::Error)]
pub enum WebError {
    #[error("`{0}` is not an address to listen on (host:port, e.g. 127.0.0.1:8088)")]
    BadAddress(String),
    #[error("cannot listen on {addr}: {reason}")]
    Bind { addr: String, reason: String },
}

/// Parses the display's `http_listen`.
///
/// # Errors
/// [`WebError::BadAddress`] naming the text.
pub fn parse_listen(text: &str) -> Result<SocketAddr, WebError> {
    text.parse()
        .map_err(|_| WebError::BadAddress(text.to_owned()))
}

/// Binds `addr` and serves the page from `hub` until `stop` completes. Returns the
/// bound address (port 0 picks a free one) once listening; serving goes on in a task.
///
/// # Errors
/// [`WebError::Bind`] if the address cannot be bound (in use, not ours).
pub async fn serve(
    addr: SocketAddr,
    hub: Arc<WebHub>,
    stop: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(SocketAddr, tokio::task::JoinHandle<()>), WebError> {
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|e| WebError::Bind {
            addr: addr.to_string(),
            reason: e.to_string(),
        })?;
    let local = listener.local_addr().map_err(|e| WebError::Bind {
        addr: addr.to_string(),
        reason: e.to_string(),
    })?;
    let app = Router::new()
        .route("/", get(page))
        .route("/index.html", get(page))
        .route("/display.js", get(script))
        .route("/display.css", get(style))
        .route("/api/state", get(state))
        .route("/ws", get(socket))
        .with_state(hub);
    let task = tokio::spawn(async move {
        if let Err(e) = axum::serve(listener, app)
            .with_graceful_shutdown(stop)
            .await
        {
            tracing::error!("operator display page: {e}");
        }
    });
    Ok((local, task))
}

fn asset(hub: &WebHub, content_type: &'static str, body: &'static str) -> Response {
    count(&hub.stats.http_requests, 1);
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn page(State(hub): State<Arc<WebHub>>) -> Response {
    asset(&hub, "text/html; charset=utf-8", PAGE_HTML)
}

async fn script(State(hub): State<Arc<WebHub>>) -> Response {
    asset(&hub, "text/javascript; charset=utf-8", PAGE_JS)
}

async fn style(State(hub): State<Arc<WebHub>>) -> Response {
    asset(&hub, "text/css; charset=utf-8", PAGE_CSS)
}

async fn state(State(hub): State<Arc<WebHub>>) -> Response {
    count(&hub.stats.http_requests, 1);
    let json = hub.state.borrow().clone();
    (
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        json.to_string(),
    )
        .into_response()
}

async fn socket(State(hub): State<Arc<WebHub>>, ws: WebSocketUpgrade) -> Response {
    if hub.stats.clients.load(Ordering::Relaxed) >= hub.max_clients {
        count(&hub.stats.refused, 1);
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!(
                "the operator display serves at most {} browsers at once",
                hub.max_clients
            ),
        )
            .into_response();
    }
    hub.stats.clients.fetch_add(1, Ordering::Relaxed);
    count(&hub.stats.connections, 1);
    ws.on_upgrade(move |socket| async move {
        client(socket, &hub).await;
        hub.stats.clients.fetch_sub(1, Ordering::Relaxed);
    })
}

/// What changed for one browser.
enum Next {
    State,
    View(usize),
    Incoming(Option<Result<Message, axum::Error>>),
    Closed,
}

/// One browser: sends the newest state and views as its socket takes them.
async fn client(mut socket: WebSocket, hub: &WebHub) {
    let mut state_rx = hub.state.subscribe();
    let mut top_rx = hub.views[0].subscribe();
    let mut side_rx = hub.views[1].subscribe();
    // What is there already goes out at once.
    state_rx.mark_changed();
    let mut last_seq: [Option<u64>; 2] = [None, None];
    loop {
        let next = tokio::select! {
            r = state_rx.changed() => if r.is_ok() { Next::State } else { Next::Closed },
            r = top_rx.changed() => if r.is_ok() { Next::View(0) } else { Next::Closed },
            r = side_rx.changed() => if r.is_ok() { Next::View(1) } else { Next::Closed },
            m = socket.recv() => Next::Incoming(m),
        };
        let message = match next {
            Next::Closed | Next::Incoming(None | Some(Err(_)) | Some(Ok(Message::Close(_)))) => {
                break;
            }
            // The page commands nothing: anything else a browser sends is ignored.
            Next::Incoming(Some(Ok(_))) => continue,
            Next::State => {
                let json = state_rx.borrow_and_update().clone();
                count(&hub.stats.states_sent, 1);
                Message::Text(json.to_string().into())
            }
            Next::View(camera) => {
                let rx = if camera == 0 {
                    &mut top_rx
                } else {
                    &mut side_rx
                };
                let Some(frame) = rx.borrow_and_update().clone() else {
                    continue;
                };
                if let Some(prev) = last_seq[camera] {
                    count(
                        &hub.stats.frames_skipped,
                        frame.seq.saturating_sub(prev).saturating_sub(1),
                    );
                }
                last_seq[camera] = Some(frame.seq);
                count(&hub.stats.frames_sent, 1);
                Message::Binary(frame.message.clone())
            }
        };
        let len = match &message {
            Message::Text(t) => t.len(),
            Message::Binary(b) => b.len(),
            _ => 0,
        };
        match tokio::time::timeout(hub.send_timeout, socket.send(message)).await {
            Ok(Ok(())) => count(&hub.stats.bytes_sent, len as u64),
            Ok(Err(_)) => break,
            Err(_) => {
                count(&hub.stats.send_timeouts, 1);
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_view_message_carries_camera_sequence_stamp_and_the_jpeg() {
        let f = ViewFrame::new(1, 42, -7, &[0xFF, 0xD8, 9]);
        assert_eq!(f.message.len(), FRAME_HEADER_LEN + 3);
        assert_eq!(f.message[0], 1);
        assert_eq!(u64::from_le_bytes(f.message[1..9].try_into().unwrap()), 42);
        assert_eq!(i64::from_le_bytes(f.message[9..17].try_into().unwrap()), -7);
        assert_eq!(&f.message[17..], &[0xFF, 0xD8, 9]);
    }

    #[test]
    fn listen_addresses_are_checked_and_named() {
        assert!(parse_listen("127.0.0.1:8088").is_ok());
        let e = parse_listen("localhost").unwrap_err();
        assert!(e.to_string().contains("`localhost`"), "{e}");
    }

    /// Reads views until view `last` comes, pausing `pause` after each: how many it
    /// got and the newest.
    async fn read_views(
        mut ws: tokio_tungstenite::WebSocketStream<
            tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>,
        >,
        last: u64,
        pause: Duration,
    ) -> (u64, u64) {
        use futures_util::StreamExt;
        let (mut frames, mut newest) = (0, 0);
        while let Some(Ok(m)) = ws.next().await {
            if let tokio_tungstenite::tungstenite::Message::Binary(b) = m {
                frames += 1;
                newest = u64::from_le_bytes(b[1..9].try_into().unwrap());
                if newest == last {
                    break;
                }
                tokio::time::sleep(pause).await;
            }
        }
        (frames, newest)
    }

    /// A browser that reads slowly gets fewer frames (the ones a newer one replaced
    /// before its socket took them are skipped and counted) but always the newest; one
    /// that stops reading is dropped after the send timeout; a fast one gets the newest
    /// too, and the node's side never waits. A browser beyond the limit is refused.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_slow_browser_gets_fewer_frames_and_holds_nothing_back() {
        let hub = WebHub::new(3, Duration::from_secs(2));
        let (addr, _task) = serve(
            "127.0.0.1:0".parse().unwrap(),
            Arc::clone(&hub),
            std::future::pending(),
        )
        .await
        .unwrap();
        let url = format!("ws://{addr}/ws");
        let (fast, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
        let (slow, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
        let (_stalled, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
        // A fourth is one too many.
        let refused = tokio_tungstenite::connect_async(&url).await;
        assert!(refused.is_err(), "a fourth browser was served");
        assert_eq!(hub.stats.refused.load(Ordering::Relaxed), 1);

        const LAST: u64 = 400;
        let fast = tokio::spawn(read_views(fast, LAST, Duration::ZERO));
        let slow = tokio::spawn(read_views(slow, LAST, Duration::from_millis(100)));
        let jpeg = vec![0xAB_u8; 256 * 1024];
        for seq in 1..=LAST {
            // `set_view` only replaces the newest: it returns whatever the sockets do.
            hub.set_view(0, ViewFrame::new(0, seq, 0, &jpeg));
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        let wait = |h: tokio::task::JoinHandle<(u64, u64)>| async move {
            tokio::time::timeout(Duration::from_secs(30), h)
                .await
                .expect("a reading browser did not get the newest view")
                .unwrap()
        };
        let (fast_frames, fast_newest) = wait(fast).await;
        let (slow_frames, slow_newest) = wait(slow).await;
        assert_eq!((fast_newest, slow_newest), (LAST, LAST));
        assert!(fast_frames > 10, "{fast_frames}");
        assert!(
            slow_frames < LAST / 2,
            "the slow browser got {slow_frames} of {LAST}"
        );
        assert!(slow_frames < fast_frames, "{slow_frames} vs {fast_frames}");
        assert!(
            hub.stats.frames_skipped.load(Ordering::Relaxed) > 0,
            "{:?}",
            hub.stats
        );
        // The one that never read was dropped.
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while hub.stats.send_timeouts.load(Ordering::Relaxed) == 0 {
            assert!(std::time::Instant::now() < deadline, "{:?}", hub.stats);
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    #[test]
    fn the_page_loads_its_assets_from_the_binary_only() {
        // No build step, no internet: the page names only its own two assets and the
        // socket, nothing from another host.
        assert!(PAGE_HTML.contains("display.js") && PAGE_HTML.contains("display.css"));
        for text in [PAGE_HTML, PAGE_JS, PAGE_CSS] {
            assert!(!text.contains("http://") && !text.contains("https://"));
        }
    }
}
