//! CDR encode/decode cost of the two hot messages, next to a plain copy of the same
//! payload bytes (`Vec::clone`, i.e. one allocation + memcpy) so results can be read as
//! ratios: `cargo bench --workspace --bench cdr`. Malformed input (a length word of
//! u32::MAX, a bit flipped in every byte) is refused at a cost read against decoding the
//! valid message in the same run: the robustness tests assert that it is refused and
//! allocates nothing out of proportion, this bench how long refusing takes.

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main};
use teleop_msgs::{Header, Image, JointState, Message, Time, decode, encode};

/// The 24 joints of the Shadow Dexterous Hand.
fn shadow_joint_state() -> JointState {
    let mut name = Vec::new();
    for (finger, n) in [
        ("FF", 4),
        ("MF", 4),
        ("RF", 4),
        ("LF", 5),
        ("TH", 5),
        ("WR", 2),
    ] {
        for j in 1..=n {
            name.push(format!("{finger}J{j}"));
        }
    }
    let n = name.len();
    JointState {
        header: Header::new(
            Time {
                sec: 1_767_225_600,
                nanosec: 123_456_789,
            },
            "shadow_palm",
        ),
        name,
        position: (0..n).map(|i| i as f64 * 0.05).collect(),
        velocity: (0..n).map(|i| i as f64 * -0.01).collect(),
        effort: (0..n).map(|i| i as f64 * 0.001).collect(),
    }
}

fn depth_image_640x480() -> Image {
    let (w, h) = (640u32, 480u32);
    let depth: Vec<u16> = (0..w * h).map(|i| (400 + i % 3000) as u16).collect();
    Image::depth_mm(
        Header::new(Time { sec: 1, nanosec: 2 }, "camera_depth_optical"),
        w,
        h,
        &depth,
    )
}

fn bench_message<T: Message>(group: &mut BenchmarkGroup<'_, WallTime>, msg: &T) {
    let bytes = encode(msg).expect("encode");
    assert_eq!(&decode::<T>(&bytes).expect("decode"), msg);
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.bench_function("memcpy_baseline", |b| {
        b.iter(|| black_box(black_box(&bytes).clone()))
    });
    group.bench_function("encode", |b| {
        b.iter(|| encode(black_box(msg)).expect("encode"))
    });
    group.bench_function("decode", |b| {
        b.iter(|| decode::<T>(black_box(&bytes)).expect("decode"))
    });
    group.bench_function("encode_decode", |b| {
        b.iter(|| {
            let bytes = encode(black_box(msg)).expect("encode");
            decode::<T>(&bytes).expect("decode")
        })
    });
}

/// Decoding the valid message against refusing it with its first sequence length (the
/// joint names') set to u32::MAX, and against decoding every one-bit corruption of it.
fn bench_malformed(group: &mut BenchmarkGroup<'_, WallTime>, msg: &JointState) {
    let bytes = encode(msg).expect("encode");
    // After the 4-byte encapsulation: stamp (8), frame id (4 + len, padded to 4), then
    // the names' count.
    let frame_len = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
    let at = 16 + frame_len.div_ceil(4) * 4;
    let mut huge = bytes.clone();
    huge[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(
        decode::<JointState>(&huge).is_err(),
        "a huge count must be refused"
    );
    let flipped: Vec<Vec<u8>> = (4..bytes.len())
        .flat_map(|i| {
            let bytes = &bytes;
            (0..8).map(move |bit| {
                let mut m = bytes.clone();
                m[i] ^= 1 << bit;
                m
            })
        })
        .collect();
    group.bench_function("decode_valid", |b| {
        b.iter(|| decode::<JointState>(black_box(&bytes)).expect("decode"))
    });
    group.bench_function("refuse_huge_count", |b| {
        b.iter(|| decode::<JointState>(black_box(&huge)).is_err())
    });
    group.throughput(Throughput::Elements(flipped.len() as u64));
    group.bench_function("every_bit_flip", |b| {
        b.iter(|| {
            flipped
                .iter()
                .filter(|m| decode::<JointState>(black_box(m)).is_ok())
                .count()
        })
    });
}

fn cdr(c: &mut Criterion) {
    let js = shadow_joint_state();
    let mut group = c.benchmark_group("joint_state_24");
    bench_message(&mut group, &js);
    group.finish();

    let mut group = c.benchmark_group("joint_state_24_malformed");
    bench_malformed(&mut group, &js);
    group.finish();

    let img = depth_image_640x480();
    let mut group = c.benchmark_group("image_640x480_16uc1");
    bench_message(&mut group, &img);
    group.finish();
}

criterion_group!(benches, cdr);
criterion_main!(benches);
