//! Measures the emulator itself on loopback: a sender writes small timestamped
//! messages through it to a receiver, which takes each one's one-way delay (one clock:
//! both ends in this process); a bulk transfer measures the throughput under a cap.
//! `wan_link measure` prints the results next to the configured values; the tests
//! assert the emulator's guarantees on them (nothing early, nothing faster than the
//! cap, nothing through a partition).

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpSocket, TcpStream};
use tokio::time::Instant;

use crate::Impairment;
use crate::proxy::{self, Emulator};

/// The test sender's `SO_SNDBUF`, bytes.
pub const SENDER_BUFFER_BYTES: u32 = 16 * 1024;

/// An emulator on loopback forwarding to a receiver; the sender's stream.
#[derive(Debug)]
pub struct Rig {
    pub emulator: Arc<Emulator>,
    pub sender: TcpStream,
    pub receiver: TcpStream,
    sink: TcpListener,
    front: std::net::SocketAddr,
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        for t in &self.tasks {
            t.abort();
        }
    }
}

impl Rig {
    /// # Errors
    /// Binding or connecting on loopback.
    pub async fn new(imp: Impairment, seed: u64) -> std::io::Result<Self> {
        let sink = TcpListener::bind("127.0.0.1:0").await?;
        let sink_addr = sink.local_addr()?;
        let emulator = Emulator::new(imp, seed, crate::DEFAULT_SOCKET_KB);
        let front = emulator.listen("127.0.0.1:0").await?;
        let front_addr = front.local_addr()?;
        let fwd = tokio::spawn(proxy::forward(
            emulator.clone(),
            front,
            sink_addr.to_string(),
        ));
        let (sender, receiver) = connect(&emulator, &sink, front_addr).await?;
        Ok(Self {
            emulator,
            sender,
            receiver,
            sink,
            front: front_addr,
            tasks: vec![fwd],
        })
    }

    /// Another connection through the same emulator: its sender and receiver.
    ///
    /// # Errors
    /// Connecting on loopback.
    pub async fn connection(&self) -> std::io::Result<(TcpStream, TcpStream)> {
        connect(&self.emulator, &self.sink, self.front).await
    }
}

/// A connection through the emulator listening at `front` to `sink`.
/// Returns once the emulator has counted the connection too: the sink's accept can
/// complete before the emulator's task resumes after its upstream connect (a CI run
/// read `connections=0` just after it).
async fn connect(
    emulator: &Emulator,
    sink: &TcpListener,
    front: std::net::SocketAddr,
) -> std::io::Result<(TcpStream, TcpStream)> {
    let before = emulator.stats.connections.load(Ordering::Relaxed);
    // The sender's send buffer as small as the compose system's routers ask for on
    // their WAN links, so what the sender has written and the receiver not yet read is
    // what the emulator holds (and those small buffers).
    let socket = TcpSocket::new_v4()?;
    socket.set_send_buffer_size(SENDER_BUFFER_BYTES)?;
    let sender = socket.connect(front).await?;
    sender.set_nodelay(true)?;
    let (receiver, _) = sink.accept().await?;
    let counted = async {
        while emulator.stats.connections.load(Ordering::Relaxed) <= before {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    };
    tokio::time::timeout(Duration::from_secs(5), counted)
        .await
        .map_err(|_| {
            std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                "the emulator did not count the connection within 5 s",
            )
        })?;
    Ok((sender, receiver))
}

/// One-way delays of `n` 64-byte messages sent every `every`, ms.
///
/// # Errors
/// The loopback connection failing.
pub async fn delays(rig: &mut Rig, n: usize, every: Duration) -> std::io::Result<Vec<f64>> {
    let epoch = Instant::now();
    let (mut rx, _) = rig.receiver.split();
    let (_, mut tx) = rig.sender.split();
    let send = async {
        for _ in 0..n {
            let mut msg = [0u8; 64];
            let t = u64::try_from(epoch.elapsed().as_nanos()).unwrap_or(u64::MAX);
            msg[..8].copy_from_slice(&t.to_le_bytes());
            tx.write_all(&msg).await?;
            tokio::time::sleep(every).await;
        }
        Ok::<(), std::io::Error>(())
    };
    let recv = async {
        let mut out = Vec::with_capacity(n);
        let mut msg = [0u8; 64];
        for _ in 0..n {
            rx.read_exact(&mut msg).await?;
            let now = epoch.elapsed().as_nanos();
            let mut t = [0u8; 8];
            t.copy_from_slice(&msg[..8]);
            let sent = u128::from(u64::from_le_bytes(t));
            #[allow(clippy::cast_precision_loss)]
            out.push(now.saturating_sub(sent) as f64 * 1e-6);
        }
        Ok::<Vec<f64>, std::io::Error>(out)
    };
    let ((), d) = tokio::try_join!(send, recv)?;
    Ok(d)
}

/// A bulk transfer through the rig.
#[derive(Debug, Clone, Copy)]
pub struct Transfer {
    /// Bytes per second, start to end.
    pub bytes_per_s: f64,
    /// The most bytes the sender had written and the receiver not yet read: what the
    /// sender's send buffer, the emulator (its sockets and its queue) held at once.
    pub max_lead_bytes: usize,
}

/// A bulk transfer of `bytes` through the rig, as fast as the sender can write.
///
/// # Errors
/// The loopback connection failing.
pub async fn throughput(rig: &mut Rig, bytes: usize) -> std::io::Result<Transfer> {
    transfer(&mut rig.sender, &mut rig.receiver, bytes).await
}

/// A bulk transfer of `bytes` from `sender` to `receiver` (a connection through an
/// emulator), as fast as the sender can write.
///
/// # Errors
/// The connection failing.
pub async fn transfer(
    sender: &mut TcpStream,
    receiver: &mut TcpStream,
    bytes: usize,
) -> std::io::Result<Transfer> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let (mut rx, _) = receiver.split();
    let (_, mut tx) = sender.split();
    let sent = AtomicUsize::new(0);
    let start = Instant::now();
    let send = async {
        let block = vec![0u8; 4 * 1024];
        let mut left = bytes;
        while left > 0 {
            let k = left.min(block.len());
            tx.write_all(&block[..k]).await?;
            sent.fetch_add(k, Ordering::Relaxed);
            left -= k;
        }
        Ok::<(), std::io::Error>(())
    };
    let recv = async {
        let mut buf = vec![0u8; 64 * 1024];
        let (mut got, mut lead) = (0, 0);
        while got < bytes {
            lead = lead.max(sent.load(Ordering::Relaxed).saturating_sub(got));
            let n = rx.read(&mut buf).await?;
            if n == 0 {
                break;
            }
            got += n;
        }
        Ok::<(usize, usize), std::io::Error>((got, lead))
    };
    let ((), (got, max_lead_bytes)) = tokio::try_join!(send, recv)?;
    #[allow(clippy::cast_precision_loss)]
    Ok(Transfer {
        bytes_per_s: got as f64 / start.elapsed().as_secs_f64(),
        max_lead_bytes,
    })
}
