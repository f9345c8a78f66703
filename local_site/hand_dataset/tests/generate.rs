//! The generator: deterministic for a seed whatever the thread count, readable back,
//! refusing bad configs and existing datasets, and producing plausible pairs.

use std::path::PathBuf;

use teleop_hand_dataset::{
    DatasetError, Generator, GeneratorConfig, IMAGE_SIZE, META_COLUMNS, Manifest, generate, load,
    npy,
};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hand-dataset-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn same_seed_same_bytes_whatever_the_threads() {
    let mut config = GeneratorConfig::training(5, 24);
    config.shard_size = 10;
    let (a, b) = (temp("a"), temp("b"));
    generate(&config, &a, 1, &|_| {}).expect("one thread");
    generate(&config, &b, 3, &|_| {}).expect("three threads");
    for shard in ["shard_00000", "shard_00001", "shard_00002"] {
        for file in [
            "human.npy",
            "robot.npy",
            "joints.npy",
            "robot_uv.npy",
            "human_xyz.npy",
            "meta.npy",
        ] {
            let x = std::fs::read(a.join(shard).join(file)).expect("a");
            let y = std::fs::read(b.join(shard).join(file)).expect("b");
            assert!(x == y, "{shard}/{file} differs between thread counts");
        }
    }
    let loaded = load(&a).expect("load");
    assert_eq!(loaded.count, 24);
    assert_eq!(loaded.human.len(), 24 * IMAGE_SIZE * IMAGE_SIZE);
    assert_eq!(
        loaded
            .manifest
            .shards
            .iter()
            .map(|s| s.count)
            .sum::<usize>(),
        24
    );
    assert_eq!(loaded.manifest.config, config);
    // Another seed, other samples.
    let mut other = config.clone();
    other.seed = 6;
    let c = temp("c");
    generate(&other, &c, 2, &|_| {}).expect("seed 6");
    let x = std::fs::read(a.join("shard_00000/joints.npy")).expect("a");
    let z = std::fs::read(c.join("shard_00000/joints.npy")).expect("c");
    assert_ne!(x, z);
    // An existing dataset is not overwritten.
    let err = generate(&config, &a, 1, &|_| {}).expect_err("exists");
    assert!(err.to_string().contains("already holds a dataset"), "{err}");
    for d in [a, b, c] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn pairs_are_plausible() {
    let mut g = Generator::new(GeneratorConfig::training(9, 100)).expect("generator");
    let (lower, upper): (Vec<f64>, Vec<f64>) = {
        let m = teleop_hand_model::retarget::Retargeter::new(Default::default()).expect("r");
        let (l, u) = m.limits();
        (l.to_vec(), u.to_vec())
    };
    for i in 0..40 {
        let s = g.sample(i).expect("sample");
        for img in [&s.human, &s.robot] {
            assert_eq!(img.len(), IMAGE_SIZE * IMAGE_SIZE);
            assert!(img.iter().all(|v| (-1.0..=1.0).contains(v)));
            let fg = img.iter().filter(|v| **v < 1.0).count() as f64 / img.len() as f64;
            assert!(fg > 0.03, "sample {i}: foreground {fg}");
        }
        for (k, q) in s.joints.iter().enumerate() {
            assert!(f64::from(*q) >= lower[k] - 1e-5 && f64::from(*q) <= upper[k] + 1e-5);
        }
        // The robot's fingertips project inside (or near) the crop.
        for tip in [11usize, 14, 17, 20, 8] {
            let (u, v) = (s.robot_uv[2 * tip], s.robot_uv[2 * tip + 1]);
            assert!(
                (-10.0..106.0).contains(&u) && (-10.0..106.0).contains(&v),
                "tip {tip}: {u} {v}"
            );
        }
        let distance = s.meta[0];
        assert!((0.3..=0.8).contains(&distance), "distance {distance}");
        assert_eq!(s.meta.len(), META_COLUMNS.len());
        // Human and robot images overlap: same camera-to-palm transform.
        let both = s
            .human
            .iter()
            .zip(&s.robot)
            .filter(|(h, r)| **h < 1.0 && **r < 1.0)
            .count();
        let robot_fg = s.robot.iter().filter(|v| **v < 1.0).count();
        assert!(
            both * 3 > robot_fg,
            "sample {i}: human and robot hardly overlap ({both} of {robot_fg})"
        );
    }
}

#[test]
fn bad_configs_and_files_are_refused_by_name() {
    let mut c = GeneratorConfig::training(1, 10);
    c.distance_m = [0.1, 0.5];
    assert!(
        matches!(Generator::new(c.clone()), Err(DatasetError::Config(m)) if m.contains("distance_m"))
    );
    c = GeneratorConfig::training(1, 10);
    c.off_axis_deg = [10.0, f64::NAN];
    assert!(Generator::new(c).is_err());
    let err = GeneratorConfig::preset("nope", 1, 10).expect_err("preset");
    assert!(err.to_string().contains("nope"));
    // Unknown manifest fields are refused.
    let dir = temp("manifest");
    let mut config = GeneratorConfig::training(2, 4);
    config.shard_size = 4;
    generate(&config, &dir, 1, &|_| {}).expect("generate");
    let path = dir.join("manifest.json");
    let text = std::fs::read_to_string(&path).expect("read");
    std::fs::write(&path, text.replacen('{', "{\"surprise\": 1,", 1)).expect("write");
    let err = Manifest::read(&dir).expect_err("unknown field");
    assert!(err.to_string().contains("surprise"), "{err}");
    std::fs::write(&path, text).expect("restore");
    // A truncated array is named.
    let joints = dir.join("shard_00000/joints.npy");
    let bytes = std::fs::read(&joints).expect("joints");
    std::fs::write(&joints, &bytes[..bytes.len() - 8]).expect("truncate");
    let err = load(&dir).expect_err("truncated");
    assert!(err.to_string().contains("joints.npy"), "{err}");
    assert!(npy::read(&dir.join("missing.npy")).is_err());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The run-time path (a full 640 x 480 frame through the one preprocessing) gives the
/// dataset's tensor exactly: training and serving see the same input.
#[test]
fn full_frames_preprocess_to_the_dataset_tensors() {
    let mut config = GeneratorConfig::training(21, 10);
    config.noise = false; // the noise pattern depends on the rendered window's size
    let mut g = Generator::new(config).expect("generator");
    let cfg = teleop_hand_model::preprocess::PreprocessConfig::default();
    let mut scratch = teleop_hand_model::preprocess::Scratch::default();
    let mut checked = 0;
    for i in 0..10 {
        let s = g.sample(i).expect("sample");
        if s.meta[7] != 1.0 {
            continue; // not the first attempt
        }
        let f = g.full_frame(i).expect("frame");
        let mut out = vec![0.0; IMAGE_SIZE * IMAGE_SIZE];
        teleop_hand_model::preprocess::preprocess(
            &f.depth_mm,
            &f.intrinsics,
            &f.centre_m,
            &cfg,
            &mut scratch,
            &mut out,
        )
        .expect("preprocess");
        assert_eq!(out, s.human, "sample {i}");
        for (a, b) in f.joints.iter().zip(&s.joints) {
            assert!((*a as f32 - b).abs() < 1e-6);
        }
        checked += 1;
    }
    assert!(checked >= 8);
}
