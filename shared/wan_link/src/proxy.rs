//! The forwarding: every connection accepted on the listen address is paired with a
//! fresh connection to the upstream (the remote router), and each direction runs its
//! own [`Link`] (its delay, jitter and losses) on the direction's one capped [`Wire`],
//! which all connections share: a reader takes chunks from the sender and schedules
//! them, a writer delivers each at its time (and not while partitioned). A reader stops reading while
//! the capped link's backlog is over `queue_ms` (or [`IN_FLIGHT_BYTES`] are in flight),
//! so the sender's TCP sees the backpressure of a slow link; the sockets' kernel
//! buffers are kept small ([`crate::DEFAULT_SOCKET_KB`]) so that backlog cannot hide in
//! them instead.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::{TcpListener, TcpSocket, TcpStream};
use tokio::sync::{Mutex, Notify, watch};
use tokio::time::Instant;

use crate::{Command, IN_FLIGHT_BYTES, Impairment, Link, Wire};

/// Largest chunk read at once, bytes.
const CHUNK_BYTES: usize = 16 * 1024;

/// Counters of one direction.
#[derive(Debug, Default)]
pub struct DirectionStats {
    pub bytes: AtomicU64,
    pub chunks: AtomicU64,
    /// Chunks delayed by a loss (a retransmission).
    pub losses: AtomicU64,
    /// Most bytes in flight at once (read, not yet delivered).
    pub queue_peak: AtomicU64,
    /// Longest the capped link needed to send what waited for it, microseconds.
    pub backlog_peak_us: AtomicU64,
}

/// Counters of the emulator.
#[derive(Debug, Default)]
pub struct Stats {
    pub connections: AtomicU64,
    pub open: AtomicU64,
    /// `[to upstream, from upstream]`.
    pub dir: [DirectionStats; 2],
}

impl Stats {
    /// One line: `connections=.. open=.. up_bytes=.. ...`.
    pub fn describe(&self) -> String {
        let d = |i: usize, name: &str| {
            let s = &self.dir[i];
            format!(
                "{name}_bytes={} {name}_chunks={} {name}_losses={} {name}_queue_peak={} {name}_backlog_peak_ms={:.1}",
                s.bytes.load(Ordering::Relaxed),
                s.chunks.load(Ordering::Relaxed),
                s.losses.load(Ordering::Relaxed),
                s.queue_peak.load(Ordering::Relaxed),
                {
                    #[allow(clippy::cast_precision_loss)]
                    let us = s.backlog_peak_us.load(Ordering::Relaxed) as f64;
                    us / 1e3
                }
            )
        };
        format!(
            "connections={} open={} {} {}",
            self.connections.load(Ordering::Relaxed),
            self.open.load(Ordering::Relaxed),
            d(0, "up"),
            d(1, "down")
        )
    }
}

/// The emulator's shared state: the impairment (changed by the control port) and the
/// counters.
#[derive(Debug)]
pub struct Emulator {
    impairment: watch::Sender<Impairment>,
    pub stats: Stats,
    seed: u64,
    epoch: Instant,
    /// `SO_RCVBUF` and `SO_SNDBUF` of the sockets it opens, bytes; `None`: the
    /// kernel's autotuning.
    socket_bytes: Option<u32>,
    /// The capped wire of each direction (`[to upstream, from upstream]`), shared by
    /// all connections.
    wires: [Wire; 2],
}

impl Emulator {
    /// An emulator starting with `initial`, drawing from `seed`, whose sockets ask
    /// the kernel for `socket_kb` KiB buffers (0: the kernel's autotuning).
    pub fn new(initial: Impairment, seed: u64, socket_kb: u32) -> Arc<Self> {
        Arc::new(Self {
            impairment: watch::Sender::new(initial),
            stats: Stats::default(),
            seed,
            epoch: Instant::now(),
            socket_bytes: (socket_kb > 0).then(|| socket_kb.saturating_mul(1024)),
            wires: [Wire::default(), Wire::default()],
        })
    }

    /// A TCP socket for `addr` with the emulator's buffer sizes.
    fn socket(&self, addr: SocketAddr) -> std::io::Result<TcpSocket> {
        let s = if addr.is_ipv4() {
            TcpSocket::new_v4()?
        } else {
            TcpSocket::new_v6()?
        };
        if let Some(b) = self.socket_bytes {
            s.set_recv_buffer_size(b)?;
            s.set_send_buffer_size(b)?;
        }
        Ok(s)
    }

    /// Listens on `addr` (resolved; the first address); the connections it accepts
    /// inherit the emulator's buffer sizes (set before `listen`, as the kernel needs
    /// for the window it offers).
    ///
    /// # Errors
    /// Resolving, binding or listening.
    pub async fn listen(&self, addr: &str) -> std::io::Result<TcpListener> {
        let a = resolve(addr).await?;
        let s = self.socket(a)?;
        s.set_reuseaddr(true)?;
        s.bind(a)?;
        s.listen(1024)
    }

    /// Connects to `addr` (resolved; the first address) with the emulator's buffer
    /// sizes.
    async fn connect(&self, addr: &str) -> std::io::Result<TcpStream> {
        let a = resolve(addr).await?;
        self.socket(a)?.connect(a).await
    }

    /// The impairment now.
    pub fn impairment(&self) -> Impairment {
        *self.impairment.borrow()
    }

    /// Runs one control line; the reply line.
    pub fn control(&self, line: &str) -> String {
        match Command::parse(line, &self.impairment()) {
            Ok(Command::Set(imp)) => {
                let partitioned = self.impairment().partitioned;
                self.impairment
                    .send_replace(Impairment { partitioned, ..imp });
            }
            Ok(Command::Partition(on)) => {
                self.impairment.send_modify(|i| i.partitioned = on);
            }
            Ok(Command::Reset) => {
                self.impairment.send_replace(Impairment::default());
            }
            Ok(Command::Show) => {}
            Err(e) => return format!("error: {e}"),
        }
        tracing::info!(line = line.trim(), now = %self.impairment().describe(), "control");
        format!(
            "ok {} {}",
            self.impairment().describe(),
            self.stats.describe()
        )
    }

    fn now_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }
}

/// Accepts connections on `listener` and forwards each to `upstream` until the
/// returned future is dropped.
pub async fn forward(emulator: Arc<Emulator>, listener: TcpListener, upstream: String) {
    let mut index: u64 = 0;
    loop {
        let (client, peer) = match listener.accept().await {
            Ok(c) => c,
            Err(e) => {
                tracing::warn!("accept: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        let server = match emulator.connect(&upstream).await {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!(%peer, upstream, "cannot reach the upstream: {e}; connection closed");
                continue;
            }
        };
        let _ = client.set_nodelay(true);
        let _ = server.set_nodelay(true);
        tracing::info!(%peer, upstream, "connection");
        emulator.stats.connections.fetch_add(1, Ordering::Relaxed);
        emulator.stats.open.fetch_add(1, Ordering::Relaxed);
        let (cr, cw) = client.into_split();
        let (sr, sw) = server.into_split();
        let em = emulator.clone();
        let k = index;
        index += 1;
        tokio::spawn(async move {
            let up = pump(
                em.clone(),
                cr,
                sw,
                Link::on(em.wires[0].clone(), em.seed, 2 * k),
                0,
            );
            let down = pump(
                em.clone(),
                sr,
                cw,
                Link::on(em.wires[1].clone(), em.seed, 2 * k + 1),
                1,
            );
            // Either direction ending ends the pair (a closed router connection).
            tokio::select! {
                () = up => {}
                () = down => {}
            }
            em.stats.open.fetch_sub(1, Ordering::Relaxed);
            tracing::info!(%peer, "connection closed");
        });
    }
}

/// Serves the control port: one command per line, one reply line each.
pub async fn control(emulator: Arc<Emulator>, listener: TcpListener) {
    loop {
        let Ok((stream, _)) = listener.accept().await else {
            continue;
        };
        let em = emulator.clone();
        tokio::spawn(async move {
            let (rd, mut wr) = stream.into_split();
            let mut lines = BufReader::new(rd).lines();
            while let Ok(Some(line)) = lines.next_line().await {
                let reply = em.control(&line);
                if wr.write_all(format!("{reply}\n").as_bytes()).await.is_err() {
                    break;
                }
            }
        });
    }
}

/// Bytes waiting in one direction, with their delivery times.
#[derive(Debug, Default)]
struct Queue {
    chunks: VecDeque<(f64, Vec<u8>)>,
    bytes: usize,
    closed: bool,
}

async fn pump(
    em: Arc<Emulator>,
    mut rd: tokio::net::tcp::OwnedReadHalf,
    mut wr: tokio::net::tcp::OwnedWriteHalf,
    mut link: Link,
    dir: usize,
) {
    let queue = Arc::new(Mutex::new(Queue::default()));
    let changed = Arc::new(Notify::new());
    let stats = &em.stats.dir[dir];
    let reader = async {
        let mut buf = vec![0u8; CHUNK_BYTES];
        loop {
            // Hold the sender while the most bytes are in flight. The wake-up is
            // registered before the check, so a chunk delivered in between is not
            // missed.
            loop {
                let woken = changed.notified();
                tokio::pin!(woken);
                woken.as_mut().enable();
                if queue.lock().await.bytes < IN_FLIGHT_BYTES {
                    break;
                }
                woken.await;
            }
            // And while the capped link's buffer is full, or this connection's share
            // of it (`queue_ms` shared equally by the open connections): until the
            // backlog drains (re-checked at least every 50 ms, for a changed setting).
            let now = em.now_s();
            let hold = em.impairment().hold_shared_s(
                link.backlog_s(now),
                link.own_backlog_s(now),
                em.stats.open.load(Ordering::Relaxed),
            );
            if hold > 0.0 {
                tokio::time::sleep(Duration::from_secs_f64(hold.min(0.05))).await;
                continue;
            }
            let n = match rd.read(&mut buf).await {
                Ok(0) | Err(_) => break,
                Ok(n) => n,
            };
            let imp = em.impairment();
            let now = em.now_s();
            let at = link.schedule(&imp, now, n);
            stats.losses.store(link.losses, Ordering::Relaxed);
            stats.backlog_peak_us.fetch_max(
                // Whole microseconds of a backlog of at most seconds.
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                {
                    (link.backlog_s(now) * 1e6) as u64
                },
                Ordering::Relaxed,
            );
            stats.chunks.fetch_add(1, Ordering::Relaxed);
            let mut q = queue.lock().await;
            q.chunks.push_back((at, buf[..n].to_vec()));
            q.bytes += n;
            stats.queue_peak.fetch_max(
                u64::try_from(q.bytes).unwrap_or(u64::MAX),
                Ordering::Relaxed,
            );
            drop(q);
            changed.notify_waiters();
        }
        queue.lock().await.closed = true;
        changed.notify_waiters();
    };
    let writer = async {
        let mut imp_rx = em.impairment.subscribe();
        loop {
            // Registered before the check, so a chunk queued in between wakes it.
            let woken = changed.notified();
            tokio::pin!(woken);
            woken.as_mut().enable();
            let next = {
                let q = queue.lock().await;
                match q.chunks.front() {
                    Some((at, _)) => Some(*at),
                    None if q.closed => return,
                    None => None,
                }
            };
            let Some(at) = next else {
                woken.await;
                continue;
            };
            let wait = at - em.now_s();
            if wait > 0.0 {
                tokio::time::sleep(Duration::from_secs_f64(wait)).await;
            }
            while imp_rx.borrow_and_update().partitioned {
                if imp_rx.changed().await.is_err() {
                    return;
                }
            }
            let Some((_, bytes)) = queue.lock().await.chunks.pop_front() else {
                continue;
            };
            if wr.write_all(&bytes).await.is_err() {
                return;
            }
            stats
                .bytes
                .fetch_add(u64::try_from(bytes.len()).unwrap_or(0), Ordering::Relaxed);
            let mut q = queue.lock().await;
            q.bytes -= bytes.len();
            drop(q);
            changed.notify_waiters();
        }
    };
    tokio::join!(reader, writer);
    let _ = wr.shutdown().await;
}

/// The first address `addr` (`host:port`) resolves to.
async fn resolve(addr: &str) -> std::io::Result<SocketAddr> {
    tokio::net::lookup_host(addr).await?.next().ok_or_else(|| {
        std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("{addr} resolves to no address"),
        )
    })
}

/// The address a listener is bound to, for logs.
pub fn bound(listener: &TcpListener) -> String {
    listener
        .local_addr()
        .map_or_else(|_| "?".to_owned(), |a: SocketAddr| a.to_string())
}
