//! Smoke run of the `bus_latency` benchmark: two processes, every case, every sample
//! echoed. No timing assertions (the machine may be loaded).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::process::Command;

#[test]
fn bus_latency_quick_run_echoes_every_sample() {
    let json = std::env::temp_dir().join(format!("bus_latency_smoke_{}.json", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_bus_latency"))
        .args(["--quick", "--domain-id", "143", "--json"])
        .arg(&json)
        .output()
        .expect("run bus_latency");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "bus_latency failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    assert!(stdout.contains("zenoh wrist pose"), "{stdout}");
    assert!(stdout.contains("ratio zenoh/udp"), "{stdout}");

    let text = std::fs::read_to_string(&json).expect("JSON report written");
    let _ = std::fs::remove_file(&json);
    let report: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    let cases = report["cases"].as_array().expect("cases");
    let names: Vec<&str> = cases.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "zenoh wrist pose",
            "zenoh raw pose",
            "udp wrist pose",
            "zenoh depth image",
            "tcp depth image"
        ]
    );
    for c in cases {
        let name = c["name"].as_str().unwrap();
        let expected = if name.contains("image") { 30 } else { 500 };
        let n = |key: &str| c[key].as_u64().unwrap_or_else(|| panic!("{name}: {key}"));
        assert_eq!(n("sent"), expected, "{name}: {c}");
        assert_eq!(
            n("returned"),
            expected,
            "{name}: every ping echoed back: {c}"
        );
        assert_eq!(n("lost"), 0, "{name}: {c}");
        assert_eq!(
            n("echoed"),
            expected,
            "{name}: echo side saw every ping: {c}"
        );
        assert_eq!(n("echo_errors"), 0, "{name}: {c}");
        assert_eq!(c["rtt_half"]["n"].as_u64(), Some(expected), "{name}: {c}");
        assert_eq!(c["one_way"]["n"].as_u64(), Some(expected), "{name}: {c}");
        assert!(
            c["rtt_half"]["p50_us"].as_f64().unwrap() > 0.0,
            "{name}: {c}"
        );
        for side in ["echo_subscriber", "driver_subscriber"] {
            if let Some(s) = c[side].as_object() {
                assert_eq!(s["rejected"].as_u64(), Some(0), "{name} {side}: {c}");
            }
        }
    }
}
