//! Paired samples per second of the dataset generator (goal >= 250/s on 2 cores): one
//! worker's time per pair, and the whole `generate` call on every core.
//!
//! `cargo bench -p teleop-hand-dataset --bench generate`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use teleop_hand_dataset::{Generator, GeneratorConfig, generate};

fn bench(c: &mut Criterion) {
    let config = GeneratorConfig::training(7, 100_000);
    let mut generator = Generator::new(config).expect("generator");
    let mut i = 0u64;
    c.bench_function("dataset/one pair, one thread", |b| {
        b.iter(|| {
            i += 1;
            black_box(generator.sample(i).expect("sample"))
        });
    });
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut group = c.benchmark_group("dataset");
    group.sample_size(10);
    let n = 512;
    let mut run = 0;
    group.bench_function(format!("{n} pairs to disk, {threads} threads"), |b| {
        b.iter(|| {
            run += 1;
            let dir = std::env::temp_dir()
                .join(format!("hand-dataset-bench-{}-{run}", std::process::id()));
            let mut cfg = GeneratorConfig::training(run, n);
            cfg.shard_size = 256;
            let m = generate(&cfg, &dir, threads, &|_| {}).expect("generate");
            let _ = std::fs::remove_dir_all(&dir);
            black_box(m)
        });
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
