//! The emulator's guarantees, through real TCP connections on loopback: nothing arrives
//! before its configured delay minus jitter, in order; nothing crosses a partition and
//! everything held arrives, in order, when it ends; no transfer beats the bandwidth
//! cap; a full queue holds the sender (the waiting bytes stay bounded); losses cost
//! the retransmission delay; bad control lines change nothing and say why.
//! (Upper bounds on delay depend on the machine's load: `wan_link measure` reports
//! them, docs/network.md has the figures.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::atomic::Ordering;
use std::time::Duration;

use teleop_wan_link::Impairment;
use teleop_wan_link::measure::{Rig, delays, quantile, throughput};
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
    let mut rig = Rig::new(imp("rate_mbit=8 queue_kb=64"), 1).await.unwrap();
    // 1 MiB at 8 Mbit/s (1 MB/s): the first 16 KiB chunk may go at once.
    let bps = throughput(&mut rig, 1 << 20).await.unwrap();
    assert!(bps <= 1.0e6 * 1.03, "{bps} B/s through an 8 Mbit/s cap");
    let peak = rig.emulator.stats.dir[0].queue_peak.load(Ordering::Relaxed);
    assert!(
        peak <= (64 + 16) * 1024,
        "{peak} bytes waited behind a 64 KiB queue"
    );
    assert!(peak > 32 * 1024, "the queue never filled: {peak}");
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
