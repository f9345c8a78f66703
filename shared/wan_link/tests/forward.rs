//! The emulator's guarantees, through real TCP connections on loopback: nothing arrives
//! before its configured delay minus jitter, in order; nothing crosses a partition and
//! everything held arrives, in order, when it ends; no transfer beats the bandwidth
//! cap, and two connections share it; a full queue holds the sender (the waiting
//! bytes stay bounded); delay alone does not cap the rate; losses cost the
//! retransmission delay; bad control lines change nothing and say why. (Upper bounds
//! on delay depend on the machine's load: `wan_link measure` reports them,
//! docs/network.md has the figures.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::atomic::Ordering;
use std::time::Duration;

use teleop_node::stats::quantile;
use teleop_wan_link::Impairment;
use teleop_wan_link::measure::{Rig, delays, throughput, transfer};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

fn imp(settings: &str) -> Impairment {
    let words: Vec<&str> = settings.split_whitespace().collect();
    Impairment::default().with(&words).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nothing_arrives_early_and_everything_in_order() {
    let mut rig = Rig::new(imp("delay_ms=20 jitter_ms=5"), 1).await.unwrap();
    let mut d = delays(&mut rig, 300, Duration::from_millis(2))
        .await
        .unwrap();
    let min = quantile(&mut d, 0.0);
    assert!(min >= 15.0, "a message arrived {min} ms after it was sent");
    // Jitter drawn, not constant.
    assert!(quantile(&mut d, 0.9) > quantile(&mut d, 0.1), "{d:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_partition_holds_everything_and_releases_it_in_order() {
    let mut rig = Rig::new(imp("delay_ms=1"), 1).await.unwrap();
    assert!(rig.emulator.control("partition on").starts_with("ok"));
    for k in 0u8..20 {
        rig.sender.write_all(&[k; 100]).await.unwrap();
    }
    let mut buf = vec![0u8; 2000];
    let early = tokio::time::timeout(Duration::from_millis(400), rig.receiver.read(&mut buf)).await;
    assert!(early.is_err(), "bytes crossed the partition: {early:?}");
    assert!(rig.emulator.control("partition off").starts_with("ok"));
    tokio::time::timeout(Duration::from_secs(5), rig.receiver.read_exact(&mut buf))
        .await
        .expect("released")
        .unwrap();
    for (k, chunk) in buf.chunks(100).enumerate() {
        assert!(
            chunk.iter().all(|b| usize::from(*b) == k),
            "out of order at {k}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_transfer_beats_the_cap_and_a_full_queue_holds_the_sender() {
    let mut rig = Rig::new(imp("rate_mbit=8 queue_ms=50"), 1).await.unwrap();
    // 1 MiB at 8 Mbit/s (1 MB/s): the first 16 KiB chunk may go at once.
    let t = throughput(&mut rig, 1 << 20).await.unwrap();
    assert!(
        t.bytes_per_s <= 1.0e6 * 1.03,
        "{} B/s through an 8 Mbit/s cap",
        t.bytes_per_s
    );
    // The capped link's backlog stays within its 50 ms buffer plus the one 16 KiB
    // chunk (16 ms at 1 MB/s) read when it was just under, and it did fill.
    let peak_ms = rig.emulator.stats.dir[0]
        .backlog_peak_us
        .load(Ordering::Relaxed) as f64
        / 1e3;
    assert!(
        peak_ms <= 50.0 + 17.0,
        "{peak_ms} ms waited behind a 50 ms buffer"
    );
    assert!(peak_ms > 30.0, "the buffer never filled: {peak_ms} ms");
    // The sender is held: what it wrote and the receiver has not read (its 16 KiB
    // send buffer, the emulator's small socket buffers and its 50 kB queue) stays
    // far below the megabytes the kernel's autotuned buffers would take.
    assert!(
        t.max_lead_bytes <= 256 * 1024,
        "the sender got {} KiB ahead of the receiver",
        t.max_lead_bytes >> 10
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_connections_share_the_cap() {
    // Two connections through one 8 Mbit/s (1 MB/s) link, 512 KiB each at once: the
    // link is one bottleneck, so together they get the rate once (a router that opens
    // a second connection for its camera views gains no bandwidth by it).
    let mut rig = Rig::new(imp("rate_mbit=8 queue_ms=50"), 1).await.unwrap();
    let (mut s2, mut r2) = rig.connection().await.unwrap();
    let start = std::time::Instant::now();
    let (a, b) = tokio::join!(
        throughput(&mut rig, 512 << 10),
        transfer(&mut s2, &mut r2, 512 << 10)
    );
    let (a, b) = (a.unwrap(), b.unwrap());
    let together = f64::from(1u32 << 20) / start.elapsed().as_secs_f64();
    assert!(
        together <= 1.0e6 * 1.05,
        "{together} B/s through one 8 Mbit/s link, {} + {} B/s",
        a.bytes_per_s,
        b.bytes_per_s
    );
    // And neither starves: each got at least a third of it.
    for t in [a, b] {
        assert!(t.bytes_per_s >= 1.0e6 / 3.0 * 0.9, "{} B/s", t.bytes_per_s);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn delay_alone_does_not_cap_the_rate() {
    // 100 ms one way: a 4 MiB transfer takes the delay once, not once per queue's
    // worth (the link is bounded by its in-flight window, 8 MiB, not by its buffer).
    let mut rig = Rig::new(imp("delay_ms=100"), 1).await.unwrap();
    let t = throughput(&mut rig, 4 << 20).await.unwrap();
    let mbit = t.bytes_per_s * 8.0 / 1e6;
    assert!(mbit > 50.0, "{mbit} Mbit/s through an uncapped 100 ms link");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn losses_cost_the_retransmission_delay() {
    let mut rig = Rig::new(imp("loss_pct=5 retransmit_ms=100"), 3)
        .await
        .unwrap();
    let mut d = delays(&mut rig, 400, Duration::from_millis(3))
        .await
        .unwrap();
    let hit = rig.emulator.stats.dir[0].losses.load(Ordering::Relaxed);
    assert!(hit > 0, "no loss in 400 chunks at 5 %");
    // At least the chunk hit waits the retransmission delay.
    assert!(quantile(&mut d, 1.0) >= 100.0, "{d:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_control_lines_change_nothing_and_say_why() {
    let rig = Rig::new(imp("delay_ms=30"), 1).await.unwrap();
    for (line, named) in [
        ("set bogus=1", "bogus"),
        ("set delay_ms=-5", "delay_ms"),
        ("set jitter_ms=50", "jitter_ms"),
        ("fly", "fly"),
    ] {
        let reply = rig.emulator.control(line);
        assert!(
            reply.starts_with("error") && reply.contains(named),
            "{line}: {reply}"
        );
    }
    assert_eq!(rig.emulator.impairment(), imp("delay_ms=30"));
    let show = rig.emulator.control("show");
    assert!(
        show.contains("delay_ms=30") && show.contains("connections=1"),
        "{show}"
    );
    // A partition survives a `set`, and `reset` clears both.
    rig.emulator.control("partition on");
    rig.emulator.control("set delay_ms=10");
    assert!(rig.emulator.impairment().partitioned);
    rig.emulator.control("reset");
    assert_eq!(rig.emulator.impairment(), Impairment::default());
}
