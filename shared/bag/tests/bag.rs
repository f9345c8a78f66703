//! Bags written and read back: what goes in comes out (bytes, times, topics, types),
//! files split, metadata.yaml as rosbag2 writes it, files cut short read up to their
//! last closed chunk and recovered whole.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use teleop_bag::{BagOptions, BagWriter, Compression, read_bag, read_file, recover};
use teleop_interfaces::topics;
use teleop_msgs::{
    CompressedImage, Header, Message, Point, Pose, PoseStamped, Quaternion, Time, decode, encode,
};

fn fresh_dir(name: &str) -> PathBuf {
    let base = std::env::temp_dir().join(format!("teleop-bag-test-{}", std::process::id()));
    std::fs::create_dir_all(&base).unwrap();
    let dir = base.join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn pose(i: u32) -> PoseStamped {
    PoseStamped {
        header: Header::new(Time::from_nanos(i64::from(i) * 1_000_000), "tracker"),
        pose: Pose {
            position: Point {
                x: f64::from(i) * 0.001,
                y: 0.2,
                z: 1.0,
            },
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            },
        },
    }
}

fn image(i: u32, bytes: usize) -> CompressedImage {
    // Incompressible enough that the file grows: a simple generator, not zeros.
    let mut state = u64::from(i) * 0x9E37_79B9_7F4A_7C15 + 1;
    let data = (0..bytes)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state & 0xff) as u8
        })
        .collect();
    CompressedImage {
        header: Header::new(Time::from_nanos(i64::from(i)), "top_camera"),
        format: "jpeg".into(),
        data,
    }
}

const T0: u64 = 1_764_800_000_000_000_000;

#[test]
fn what_goes_in_comes_out_with_rosbag2_metadata() {
    for compression in [Compression::Zstd, Compression::Lz4, Compression::None] {
        let dir = fresh_dir(&format!("roundtrip-{compression:?}"));
        let opts = BagOptions {
            compression,
            ..BagOptions::default()
        };
        let mut bag = BagWriter::create(&dir, opts).unwrap();
        let wrist = bag.add_topic(&topics::WRIST_POSE.spec).unwrap();
        let views = bag.add_topic(&topics::REMOTE_CAMERA_TOP.spec).unwrap();
        let mut sent = Vec::new();
        for i in 0..300u32 {
            let t = T0 + u64::from(i) * 10_000_000;
            let bytes = encode(&pose(i)).unwrap();
            bag.write(wrist, t, t - 2_000_000, i + 1, &bytes).unwrap();
            sent.push(bytes);
            if i % 10 == 0 {
                let img = encode(&image(i, 2000)).unwrap();
                bag.write(views, t + 1, t, i / 10 + 1, &img).unwrap();
            }
        }
        let summary = bag.close().unwrap();
        assert_eq!(summary.messages, 330);
        assert_eq!(summary.files.len(), 1);
        assert_eq!(summary.per_topic["/teleop/wrist_pose"], 300);

        // Read back with the MCAP crate's own stream: bytes, times, sequence, channel.
        let file = dir.join(&summary.files[0]);
        let buf = std::fs::read(&file).unwrap();
        let mut got = Vec::new();
        for m in mcap::MessageStream::new(&buf).unwrap() {
            let m = m.unwrap();
            assert_eq!(m.channel.message_encoding, "cdr");
            let schema = m.channel.schema.as_ref().unwrap();
            assert_eq!(schema.encoding, "ros2msg");
            assert!(m.channel.metadata.contains_key("offered_qos_profiles"));
            if m.channel.topic == "/teleop/wrist_pose" {
                assert_eq!(schema.name, PoseStamped::TYPE_NAME);
                assert_eq!(
                    m.channel.metadata["topic_type_hash"],
                    PoseStamped::TYPE_HASH
                );
                assert_eq!(m.log_time - m.publish_time, 2_000_000);
                assert_eq!(u64::from(m.sequence), got.len() as u64 + 1);
                let p: PoseStamped = decode(&m.data).unwrap();
                assert_eq!(p, pose(m.sequence - 1));
                got.push(m.data.into_owned());
            }
        }
        assert_eq!(got, sent, "{compression:?}: the bytes as they were written");

        let report = read_bag(&dir).unwrap();
        assert_eq!(report.messages(), 330);
        assert_eq!(report.files[0].profile, "ros2");
        assert!(report.files[0].truncated.is_none());
        let t = report.topics();
        assert_eq!(t["/teleop/wrist_pose"].count, 300);
        assert_eq!(
            t["/teleop/remote_camera/top/image/compressed"].type_name,
            CompressedImage::TYPE_NAME
        );
        let rate = report.rate_hz(300).unwrap();
        assert!((rate - 100.3).abs() < 1.0, "{rate}");

        // metadata.yaml: rosbag2's version 9 layout.
        let meta: serde_yaml::Value =
            serde_yaml::from_str(&std::fs::read_to_string(dir.join("metadata.yaml")).unwrap())
                .unwrap();
        let info = &meta["rosbag2_bagfile_information"];
        assert_eq!(info["version"], 9);
        assert_eq!(info["storage_identifier"], "mcap");
        assert_eq!(info["message_count"], 330);
        assert_eq!(info["relative_file_paths"][0], summary.files[0].as_str());
        assert_eq!(
            info["starting_time"]["nanoseconds_since_epoch"].as_u64(),
            Some(T0)
        );
        let topic = &info["topics_with_message_count"][0];
        assert_eq!(topic["topic_metadata"]["name"], "/teleop/wrist_pose");
        assert_eq!(topic["topic_metadata"]["serialization_format"], "cdr");
        assert_eq!(
            topic["topic_metadata"]["offered_qos_profiles"][0]["reliability"],
            "reliable"
        );
        assert_eq!(topic["message_count"], 300);
    }
}

#[test]
fn the_schemas_carry_the_full_definitions() {
    let text = PoseStamped::description().full_definition();
    assert!(text.starts_with("std_msgs/Header header\n"), "{text}");
    let sep = "=".repeat(80);
    for dep in [
        "MSG: builtin_interfaces/Time",
        "MSG: std_msgs/Header",
        "MSG: geometry_msgs/Pose",
        "MSG: geometry_msgs/Point",
        "MSG: geometry_msgs/Quaternion",
    ] {
        assert!(
            text.contains(&format!("{sep}\n{dep}\n")),
            "{dep} missing:\n{text}"
        );
    }
    // The project's types come from their .msg files, comments and defaults included.
    let input = teleop_msgs::OperatorInput::description().full_definition();
    assert!(input.contains("float64 motion_scale 1.0"), "{input}");
    assert!(input.contains(&format!("{sep}\nMSG: std_msgs/Header\n")));
}

#[test]
fn files_split_by_size_and_by_duration() {
    let dir = fresh_dir("split-size");
    let opts = BagOptions {
        max_file_bytes: Some(256 * 1024),
        chunk_bytes: 32 * 1024,
        ..BagOptions::default()
    };
    let mut bag = BagWriter::create(&dir, opts).unwrap();
    let views = bag.add_topic(&topics::REMOTE_CAMERA_TOP.spec).unwrap();
    for i in 0..100u32 {
        let t = T0 + u64::from(i) * 66_000_000;
        bag.write(views, t, t, i + 1, &encode(&image(i, 20_000)).unwrap())
            .unwrap();
    }
    let summary = bag.close().unwrap();
    assert!(summary.files.len() >= 6, "{:?}", summary.files);
    let report = read_bag(&dir).unwrap();
    assert_eq!(report.messages(), 100);
    for f in &report.files {
        // One chunk of overshoot at most past the limit, plus the summary.
        assert!(
            f.bytes < 256 * 1024 + 64 * 1024,
            "{}: {}",
            f.path.display(),
            f.bytes
        );
        assert!(f.truncated.is_none());
    }
    let meta = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    for name in &summary.files {
        assert!(meta.contains(name.as_str()), "{name} not in metadata.yaml");
    }

    let dir = fresh_dir("split-duration");
    let opts = BagOptions {
        max_file_duration_s: Some(2.0),
        ..BagOptions::default()
    };
    let mut bag = BagWriter::create(&dir, opts).unwrap();
    let wrist = bag.add_topic(&topics::WRIST_POSE.spec).unwrap();
    // 7 s at 100 Hz: files of 2 s each, the last one shorter.
    for i in 0..700u32 {
        let t = T0 + u64::from(i) * 10_000_000;
        bag.write(wrist, t, t, i + 1, &encode(&pose(i)).unwrap())
            .unwrap();
    }
    let summary = bag.close().unwrap();
    assert_eq!(summary.files.len(), 4, "{:?}", summary.files);
    let report = read_bag(&dir).unwrap();
    let counts: Vec<u64> = report.files.iter().map(|f| f.messages).collect();
    assert_eq!(counts, vec![200, 200, 200, 100]);
}

#[test]
fn a_file_cut_short_is_read_to_its_last_chunk_and_recovered() {
    let dir = fresh_dir("cut");
    // Chunks closed every 0.1 s of log time: a cut loses at most that.
    let opts = BagOptions {
        flush_interval_s: 0.1,
        ..BagOptions::default()
    };
    let mut bag = BagWriter::create(&dir, opts).unwrap();
    let wrist = bag.add_topic(&topics::WRIST_POSE.spec).unwrap();
    for i in 0..1000u32 {
        let t = T0 + u64::from(i) * 10_000_000;
        bag.write(wrist, t, t, i + 1, &encode(&pose(i)).unwrap())
            .unwrap();
    }
    let summary = bag.close().unwrap();
    let file = dir.join(&summary.files[0]);
    let whole = std::fs::read(&file).unwrap();

    // Cut at several points (a crash mid-write): every message before the cut's chunk
    // is read, in order, and the reader says where it stopped; never a panic.
    let mut last = 0;
    for fraction in [0.2, 0.5, 0.8, 0.97] {
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            clippy::cast_precision_loss
        )]
        let at = (whole.len() as f64 * fraction) as usize;
        std::fs::write(&file, &whole[..at]).unwrap();
        let r = read_file(&file).unwrap();
        assert!(r.truncated.is_some(), "cut at {at}: not seen as cut");
        assert!(r.messages > last, "cut at {at}: {} messages", r.messages);
        // At most one chunk (0.1 s = 10 poses) lost behind the cut... of the data
        // written before it: the summary section is at the end, so later cuts lose
        // nothing but it.
        last = r.messages;
    }
    assert!(
        last >= 990,
        "{last} of 1000 read from a file cut in its summary"
    );

    // A cut in the middle, recovered: a whole file with every message before the cut.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss
    )]
    let at = (whole.len() as f64 * 0.5) as usize;
    std::fs::write(&file, &whole[..at]).unwrap();
    let before = read_file(&file).unwrap().messages;
    let report = recover(&dir).unwrap();
    assert!(report.files[0].truncated.is_none());
    assert_eq!(report.messages(), before);
    let again = read_file(&file).unwrap();
    assert!(again.truncated.is_none());
    assert_eq!(again.messages, before);
    let buf = std::fs::read(&file).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().unwrap();
    assert_eq!(summary.stats.unwrap().message_count, before);
    let meta = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(meta.contains(&format!("message_count: {before}")), "{meta}");

    // Not MCAP at all: a named error, no panic.
    let junk = dir.join("junk.mcap");
    std::fs::write(&junk, b"this is not an mcap file").unwrap();
    let e = read_file(&junk).unwrap_err().to_string();
    assert!(e.contains("junk.mcap"), "{e}");
}

#[test]
fn bad_options_and_existing_bags_are_refused() {
    let dir = fresh_dir("refused");
    std::fs::create_dir_all(&dir).unwrap();
    let e = BagWriter::create(&dir, BagOptions::default()).unwrap_err();
    assert!(e.to_string().contains("already exists"), "{e}");
    let e = BagWriter::create(
        &fresh_dir("bad-flush"),
        BagOptions {
            flush_interval_s: f64::NAN,
            ..BagOptions::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("flush_interval_s"), "{e}");
    assert!("gzip".parse::<Compression>().is_err());
    assert_eq!("lz4".parse::<Compression>().unwrap(), Compression::Lz4);
}

#[test]
fn a_chunk_claiming_an_absurd_uncompressed_size_is_refused_not_allocated() {
    // Found by the hostile-input runs: the `mcap` reader reserves a chunk's claimed
    // uncompressed size before decompressing it, so one changed size field made a small
    // file ask for exabytes and abort the process.
    let dir = fresh_dir("absurd");
    let mut bag = BagWriter::create(&dir, BagOptions::default()).unwrap();
    let wrist = bag.add_topic(&topics::WRIST_POSE.spec).unwrap();
    for i in 0..20u32 {
        let t = T0 + u64::from(i) * 10_000_000;
        bag.write(wrist, t, t, i + 1, &encode(&pose(i)).unwrap())
            .unwrap();
    }
    let summary = bag.close().unwrap();
    let file = dir.join(&summary.files[0]);
    let mut bytes = std::fs::read(&file).unwrap();
    assert!(teleop_bag::check_chunk_sizes(&bytes).is_ok());
    assert_eq!(read_file(&file).unwrap().messages, 20);
    // The first chunk record (opcode 0x06) after the magic and the header record; its
    // uncompressed size is the third u64 of its body.
    let mut at = mcap::MAGIC.len();
    while bytes[at] != 0x06 {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap());
        at += 9 + usize::try_from(len).unwrap();
    }
    bytes[at + 9 + 16..at + 9 + 24].copy_from_slice(&(7u64 << 60).to_le_bytes());
    std::fs::write(&file, &bytes).unwrap();
    let e = read_file(&file).unwrap_err().to_string();
    assert!(
        e.contains(&file.display().to_string())
            && e.contains("claims 8070450532247928832 bytes uncompressed"),
        "{e}"
    );
    // So does recovering the bag: refused, the file left as it was.
    assert!(recover(&dir).is_err());
    assert_eq!(std::fs::read(&file).unwrap(), bytes);
}
