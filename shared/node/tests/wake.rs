//! A node that asks to be woken (`Node::wake`) is ticked when a sample arrives, not only
//! on its period: a node with a one-hour period still handles every sample it is sent.
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::Duration;

use teleop_bus::{Bus, Notify, Subscriber};
use teleop_interfaces::topics;
use teleop_msgs::{Header, Lifecycle, OperatorInput, Time};
use teleop_node::Node;

struct Woken {
    sub: Subscriber<OperatorInput>,
    wake: Arc<Notify>,
    ticks: Arc<std::sync::atomic::AtomicU64>,
    taken: Arc<std::sync::atomic::AtomicU64>,
}

impl Node for Woken {
    fn period(&self) -> Duration {
        Duration::from_secs(3600)
    }
    fn tick(&mut self, _now_s: f64) {
        use std::sync::atomic::Ordering::Relaxed;
        self.ticks.fetch_add(1, Relaxed);
        while self.sub.try_recv().is_some() {
            self.taken.fetch_add(1, Relaxed);
        }
    }
    fn state(&self) -> Lifecycle {
        Lifecycle::Active
    }
    fn counters(&self) -> Vec<(String, u64)> {
        Vec::new()
    }
    fn last_error(&self) -> String {
        String::new()
    }
    fn wake(&self) -> Option<Arc<Notify>> {
        Some(Arc::clone(&self.wake))
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_woken_node_handles_each_sample_as_it_arrives() {
    use std::sync::atomic::Ordering::Relaxed;
    let (a, b) = teleop_bus::testing::loopback_pair(47);
    let node_bus = Bus::open("woken", &a).await.unwrap();
    let sender = Bus::open("sender", &b).await.unwrap();
    let sub = node_bus.subscriber(&topics::OPERATOR_INPUT).await.unwrap();
    let wake = Arc::new(Notify::new());
    sub.wake_on_sample(Some(Arc::clone(&wake)));
    let ticks = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let taken = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let node = Woken {
        sub,
        wake,
        ticks: Arc::clone(&ticks),
        taken: Arc::clone(&taken),
    };
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let runner = tokio::spawn(teleop_node::run(node_bus, node, async {
        let _ = stop_rx.await;
    }));
    let publisher = sender.publisher(&topics::OPERATOR_INPUT).await.unwrap();
    // The first (immediate) periodic tick has passed once the node is running; every
    // later tick is a wake-up. Samples 20 ms apart (the topic keeps only the newest).
    let mut sent = 0;
    for _ in 0..300 {
        publisher
            .put(&OperatorInput {
                header: Header::new(Time::now(), ""),
                clutch: false,
                enable: false,
                camera_stop: false,
                motion_scale: 0.5,
            })
            .unwrap();
        sent += 1;
        tokio::time::sleep(Duration::from_millis(20)).await;
        if taken.load(Relaxed) >= 20 {
            break;
        }
    }
    let _ = stop_tx.send(());
    runner.await.unwrap().unwrap();
    let (t, n) = (ticks.load(Relaxed), taken.load(Relaxed));
    assert!(n >= 20, "{n} of {sent} samples handled in {t} ticks");
    // Far more ticks than the one-hour period gives: the wake-ups.
    assert!(t >= 20, "{t} ticks");
}
