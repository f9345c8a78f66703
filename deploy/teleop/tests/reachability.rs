//! The reachability-map tool on a coarse grid: files written, reachable inside the
//! UR5's 0.85 m reach and nothing far outside it.
#![allow(clippy::unwrap_used)]

use std::process::Command;

#[test]
fn coarse_ur5_map() {
    let dir = std::env::temp_dir().join(format!("reach_{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_reachability_map"))
        .args([
            "--robot",
            "ur5",
            "--resolution-m",
            "0.25",
            "--orientations",
            "12",
            "--out-dir",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(dir.join("ur5_reachability.csv")).unwrap();
    let png = std::fs::read(dir.join("ur5_reachability.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let mut reachable_inside = 0;
    let mut rows = 0;
    for line in csv.lines().skip(1) {
        let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
        let r = (f[0] * f[0] + f[1] * f[1] + (f[2] - 0.089).powi(2)).sqrt();
        let reached = f[3] as usize;
        assert_eq!(f[4] as usize, 12);
        if r > 1.0 {
            assert_eq!(reached, 0, "beyond the UR5's reach: {line}");
        }
        if (0.3..0.7).contains(&r) && reached > 0 {
            reachable_inside += 1;
        }
        rows += 1;
    }
    assert_eq!(rows, 9 * 9 * 9);
    assert!(reachable_inside > 20, "{reachable_inside}");
    std::fs::remove_dir_all(&dir).unwrap();
}
