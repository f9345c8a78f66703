//! The committed hand model, loaded through `ort` like the run-time node, on a freshly
//! generated seeded test set: its metrics stay at or above the thresholds its report
//! records. Needs ONNX Runtime (`bash tests/run.sh` installs the PyPI wheel into the
//! project environment, where the search finds it).

use std::path::PathBuf;

use teleop_hand_dataset::GeneratorConfig;
use teleop_hand_eval::{COMMITTED_MODEL, COMMITTED_REPORT, Report, evaluate_generated};
use teleop_hand_inference::{HandEstimator, OnnxModel, OnnxOptions};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn the_committed_model_meets_its_report() {
    let report: Report = serde_json::from_str(
        &std::fs::read_to_string(workspace().join(COMMITTED_REPORT)).expect("report.json"),
    )
    .expect("report parses");
    let model = OnnxModel::load(&workspace().join(COMMITTED_MODEL), &OnnxOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    let mut estimator = HandEstimator::new(model).expect("estimator");
    let ci = report.ci;
    let config = GeneratorConfig::training(ci.seed, ci.frames);
    let s = evaluate_generated(&mut estimator, config, ci.frames)
        .expect("evaluation")
        .summary();
    println!(
        "committed model on {} fresh pairs (seed {}): {:.1} % within 0.1 rad, {:.1} % within 0.2 rad, mean {:.4} rad; thresholds {:?}",
        s.frames,
        ci.seed,
        100.0 * s.fraction_within[0],
        100.0 * s.fraction_within[2],
        s.mean_error_rad,
        ci
    );
    assert_eq!(s.frames, ci.frames);
    assert!(s.fraction_within[0] >= ci.min_fraction_within_0_1, "{s:?}");
    assert!(s.fraction_within[2] >= ci.min_fraction_within_0_2, "{s:?}");
    assert!(s.mean_error_rad <= ci.max_mean_error_rad, "{s:?}");
    let stats = estimator.stats();
    assert_eq!(stats.rejected_non_finite, 0);
    assert_eq!(stats.errors, 0);
}

#[test]
fn a_model_with_the_wrong_interface_is_refused_by_name() {
    // Any non-ONNX file: the error names the file.
    let path = std::env::temp_dir().join(format!("not-a-model-{}.onnx", std::process::id()));
    std::fs::write(&path, b"not onnx").expect("write");
    let err = OnnxModel::load(&path, &OnnxOptions::default()).expect_err("garbage model");
    assert!(err.to_string().contains("not-a-model"), "{err}");
    let _ = std::fs::remove_file(&path);
    let err = OnnxModel::load(
        &workspace().join("no/such/model.onnx"),
        &OnnxOptions::default(),
    )
    .expect_err("missing model");
    assert!(err.to_string().contains("no such file"), "{err}");
}
