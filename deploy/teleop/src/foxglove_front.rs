//! The Foxglove WebSocket protocol's older subprotocol name in front of the SDK's server.
//!
//! The Foxglove SDK's server speaks `foxglove.sdk.v1` (and `.v1.1`) only; clients written
//! for the ws-protocol servers (Lichtblick up to 1.21, Foxglove Studio before the SDK,
//! `@foxglove/ws-protocol` users) offer only `foxglove.websocket.v1` and are refused with
//! HTTP 400. Foxglove states that the two names are, for now, the same protocol (the
//! JSON control messages and the binary frames are identical), so `teleop foxglove`
//! listens itself and hands each connection to the SDK's server on loopback: a handshake
//! that offers only `foxglove.websocket.v1` is passed on offering `foxglove.sdk.v1`, and
//! the server's answer names `foxglove.websocket.v1` again; every other handshake passes
//! unchanged (a client offering an SDK name gets what the SDK chooses; one offering
//! neither is refused by the SDK as before). After the handshake the bytes are copied
//! both ways untouched.
//!
//! The handshake's head is bytes from anyone who reaches the port: it is read up to
//! [`MAX_HEAD`] bytes within [`HEAD_TIMEOUT`], and one that is too long, late, not text
//! or not an HTTP request is answered 400 (or dropped) and counted, never passed on.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;

/// The SDK's name of the protocol, which its server speaks.
pub const SDK_V1: &str = "foxglove.sdk.v1";
/// The ws-protocol name of the same protocol, which older clients offer.
pub const LEGACY_V1: &str = "foxglove.websocket.v1";
/// The longest handshake head accepted (request line and headers), bytes.
pub const MAX_HEAD: usize = 16 * 1024;
/// How long a client may take to send its handshake head.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

/// Why a handshake head was not passed on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HeadError {
    #[error("the handshake head is over {MAX_HEAD} bytes")]
    TooLong,
    #[error("the handshake head is not UTF-8 text")]
    NotText,
    #[error("not an HTTP GET request: {0:?}")]
    NotGet(String),
    #[error("a header line without a colon: {0:?}")]
    BadHeader(String),
    #[error("the connection closed before the handshake head ended")]
    Closed,
}

/// The subprotocols a request head offers, in order, from every `Sec-WebSocket-Protocol`
/// header (names are case-insensitive, values comma-separated).
fn offered(lines: &[&str]) -> Vec<String> {
    lines
        .iter()
        .filter_map(|l| l.split_once(':'))
        .filter(|(name, _)| name.trim().eq_ignore_ascii_case("sec-websocket-protocol"))
        .flat_map(|(_, value)| value.split(','))
        .map(|p| p.trim().to_owned())
        .filter(|p| !p.is_empty())
        .collect()
}

/// Checks a request head (without its blank line) and, where it offers
/// `foxglove.websocket.v1` and no SDK name, rewrites its subprotocol headers to offer
/// `foxglove.sdk.v1`. Returns the head to pass on and whether it was renamed.
pub fn rewrite_request(head: &str) -> Result<(String, bool), HeadError> {
    let lines: Vec<&str> = head.split("\r\n").collect();
    let request_line = lines.first().copied().unwrap_or_default();
    if !request_line.starts_with("GET ") || !request_line.contains(" HTTP/1.") {
        return Err(HeadError::NotGet(clip(request_line)));
    }
    if let Some(bad) = lines[1..].iter().find(|l| !l.contains(':')) {
        return Err(HeadError::BadHeader(clip(bad)));
    }
    let offers = offered(&lines[1..]);
    let rename = !offers.iter().any(|p| p.starts_with("foxglove.sdk."))
        && offers.iter().any(|p| p == LEGACY_V1);
    if !rename {
        return Ok((head.to_owned(), false));
    }
    let mut out: Vec<String> = Vec::with_capacity(lines.len());
    let mut written = false;
    for line in &lines {
        let is_protocol = line
            .split_once(':')
            .is_some_and(|(n, _)| n.trim().eq_ignore_ascii_case("sec-websocket-protocol"));
        if !is_protocol {
            out.push((*line).to_owned());
        } else if !written {
            out.push(format!("Sec-WebSocket-Protocol: {SDK_V1}"));
            written = true;
        }
    }
    Ok((out.join("\r\n"), true))
}

/// The server's answer to a renamed request, naming `foxglove.websocket.v1` where the
/// server agreed to `foxglove.sdk.v1`.
pub fn rewrite_response(head: &str) -> String {
    head.split("\r\n")
        .map(|line| match line.split_once(':') {
            Some((name, value))
                if name.trim().eq_ignore_ascii_case("sec-websocket-protocol")
                    && value.trim() == SDK_V1 =>
            {
                format!("{name}: {LEGACY_V1}")
            }
            _ => line.to_owned(),
        })
        .collect::<Vec<_>>()
        .join("\r\n")
}

fn clip(s: &str) -> String {
    s.chars().take(80).collect()
}

/// Reads up to the blank line that ends an HTTP head: the head (without the blank line)
/// and whatever bytes came after it.
async fn read_head(stream: &mut (impl AsyncRead + Unpin)) -> Result<(String, Vec<u8>), HeadError> {
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let rest = buf.split_off(end + 4);
            buf.truncate(end);
            let head = String::from_utf8(buf).map_err(|_| HeadError::NotText)?;
            return Ok((head, rest));
        }
        if buf.len() > MAX_HEAD {
            return Err(HeadError::TooLong);
        }
        match stream.read(&mut chunk).await {
            Ok(0) | Err(_) => return Err(HeadError::Closed),
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
        }
    }
}

/// What the front did with the handshakes it saw.
#[derive(Debug, Default)]
pub struct FrontCounts {
    /// Handshakes passed on unchanged.
    pub passed: AtomicU64,
    /// Handshakes that offered only `foxglove.websocket.v1`, renamed.
    pub renamed: AtomicU64,
    /// Heads refused (too long, late, not an HTTP GET) or connections that failed.
    pub refused: AtomicU64,
}

/// The listening front: accepts on `listener`, hands every connection to the server at
/// `upstream` (the SDK's, on loopback). Runs until aborted; the connections it serves
/// end with it.
pub async fn serve(
    listener: TcpListener,
    upstream: std::net::SocketAddr,
    counts: Arc<FrontCounts>,
) {
    let mut connections = JoinSet::new();
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((client, peer)) => {
                    let counts = Arc::clone(&counts);
                    connections.spawn(async move {
                        if let Err(e) = relay(client, upstream, &counts).await {
                            counts.refused.fetch_add(1, Ordering::Relaxed);
                            tracing::warn!(%peer, "Foxglove client refused: {e}");
                        }
                    });
                }
                Err(e) => {
                    tracing::warn!("accepting a Foxglove client: {e}");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            },
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
}

async fn relay(
    mut client: TcpStream,
    upstream: std::net::SocketAddr,
    counts: &FrontCounts,
) -> anyhow::Result<()> {
    // The client's head, checked and perhaps renamed; anything wrong with it is
    // answered 400.
    let checked = match tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut client)).await {
        Ok(Ok((head, rest))) => rewrite_request(&head)
            .map(|(head, renamed)| (head, renamed, rest))
            .map_err(anyhow::Error::from),
        Ok(Err(e)) => Err(e.into()),
        Err(_) => Err(anyhow::anyhow!("no handshake within {HEAD_TIMEOUT:?}")),
    };
    let (head, renamed, rest) = match checked {
        Ok(c) => c,
        Err(e) => {
            refuse(&mut client).await;
            return Err(e);
        }
    };
    let mut server = TcpStream::connect(upstream).await?;
    server.write_all(head.as_bytes()).await?;
    server.write_all(b"\r\n\r\n").await?;
    server.write_all(&rest).await?;
    if renamed {
        counts.renamed.fetch_add(1, Ordering::Relaxed);
        let (answer, rest) = read_head(&mut server).await?;
        client
            .write_all(rewrite_response(&answer).as_bytes())
            .await?;
        client.write_all(b"\r\n\r\n").await?;
        client.write_all(&rest).await?;
    } else {
        counts.passed.fetch_add(1, Ordering::Relaxed);
    }
    // Both directions until either side closes; an error here is a closed connection.
    let _ = tokio::io::copy_bidirectional(&mut client, &mut server).await;
    Ok(())
}

async fn refuse(client: &mut TcpStream) {
    let _ = client
        .write_all(b"HTTP/1.1 400 Bad Request\r\nConnection: close\r\nContent-Length: 0\r\n\r\n")
        .await;
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==";

    fn request(protocols: &[&str]) -> String {
        let mut lines = vec![
            "GET / HTTP/1.1".to_owned(),
            "Host: 127.0.0.1:8765".to_owned(),
            "Upgrade: websocket".to_owned(),
            "Connection: Upgrade".to_owned(),
            KEY.to_owned(),
        ];
        lines.extend(
            protocols
                .iter()
                .map(|p| format!("sec-websocket-protocol: {p}")),
        );
        lines.join("\r\n")
    }

    #[test]
    fn only_the_legacy_name_is_renamed() {
        let (head, renamed) = rewrite_request(&request(&[LEGACY_V1])).unwrap();
        assert!(renamed);
        assert!(
            head.ends_with(&format!("Sec-WebSocket-Protocol: {SDK_V1}")),
            "{head}"
        );
        assert!(head.contains(KEY) && head.starts_with("GET / HTTP/1.1\r\n"));
        assert!(!head.contains(LEGACY_V1));

        // Offered beside an SDK name (or in a second header): passed on as it came.
        for offers in [
            vec!["foxglove.websocket.v1, foxglove.sdk.v1"],
            vec![LEGACY_V1, "foxglove.sdk.v1.1"],
            vec!["foxglove.sdk.v1"],
            vec!["something.else"],
            vec![],
        ] {
            let original = request(&offers);
            assert_eq!(
                rewrite_request(&original).unwrap(),
                (original, false),
                "{offers:?}"
            );
        }
        // Several legacy headers become one.
        let (head, renamed) = rewrite_request(&request(&[LEGACY_V1, "other"])).unwrap();
        assert!(renamed);
        assert_eq!(head.matches("Sec-WebSocket-Protocol").count(), 1, "{head}");
    }

    #[test]
    fn the_answer_names_the_legacy_protocol_again() {
        let answer = "HTTP/1.1 101 Switching Protocols\r\nupgrade: websocket\r\n\
                      sec-websocket-protocol: foxglove.sdk.v1\r\nsec-websocket-accept: abc";
        let out = rewrite_response(answer);
        assert!(
            out.contains(&format!("sec-websocket-protocol: {LEGACY_V1}")),
            "{out}"
        );
        assert!(out.contains("sec-websocket-accept: abc") && !out.contains(SDK_V1));
        // A refusal passes as it is.
        let refusal = "HTTP/1.1 400 Bad Request\r\ncontent-length: 0";
        assert_eq!(rewrite_response(refusal), refusal);
    }

    #[test]
    fn what_is_not_a_websocket_request_is_named() {
        assert!(matches!(
            rewrite_request("POST / HTTP/1.1\r\nHost: x"),
            Err(HeadError::NotGet(_))
        ));
        assert!(matches!(rewrite_request(""), Err(HeadError::NotGet(_))));
        assert!(matches!(
            rewrite_request("GET / HTTP/1.1\r\nno colon here"),
            Err(HeadError::BadHeader(l)) if l == "no colon here"
        ));
    }

    #[tokio::test]
    async fn a_head_is_read_to_its_blank_line_and_bounded() {
        let mut input: &[u8] = b"GET / HTTP/1.1\r\nHost: a\r\n\r\n\x81\x00";
        let (head, rest) = read_head(&mut input).await.unwrap();
        assert_eq!(head, "GET / HTTP/1.1\r\nHost: a");
        assert_eq!(rest, b"\x81\x00");

        let long = vec![b'a'; MAX_HEAD + 4096];
        assert_eq!(
            read_head(&mut long.as_slice()).await,
            Err(HeadError::TooLong)
        );
        let mut cut: &[u8] = b"GET / HTTP/1.1\r\nHost";
        assert_eq!(read_head(&mut cut).await, Err(HeadError::Closed));
        let mut binary: &[u8] = b"GET \xff\xfe\r\n\r\n";
        assert_eq!(read_head(&mut binary).await, Err(HeadError::NotText));
    }
}
