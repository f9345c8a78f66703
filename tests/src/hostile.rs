//! Hostile inputs for every decoder of bytes that arrive from outside the process: a
//! mutation loop over structure-aware generators, on the stable toolchain (cargo-fuzz
//! needs nightly), deterministic from a seed.
//!
//! Each [`Target`] is one decoder as the shipped code calls it, followed by the check its
//! consumer makes next (the hardware's command check after the CDR of a command, the
//! layout check after a camera image, the pose check after a pose), so an input that
//! decodes also reaches the code that trusts it. Inputs are fresh valid values from the
//! target's generator, or seeds mutated one to four times: bit flips, interesting bytes
//! and 32-bit lengths, inserted, deleted, duplicated and spliced ranges, cuts, and for
//! text targets hostile tokens (`NaN`, `1e309`, huge counts, separators, non-ASCII) and
//! swapped or repeated lines.
//!
//! Per target the run counts inputs accepted and refused, panics (caught, the first one's
//! message and iteration kept), the slowest single call, and, where the binary installs
//! [`PeakAlloc`] and hands it in, the most memory live during one call. A call that takes longer than
//! [`HANG_LIMIT`] aborts the process naming the target, the seed and the iteration, from
//! which [`input_at`] rebuilds that exact input.

use std::cell::RefCell;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use teleop_interfaces::joints::{PR2_ARM_JOINTS, SHADOW_FINGER_JOINTS};
use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, Image, JointCommand, JointState, Message,
    NodeStatus, OperatorInput, Point, Pose, PoseStamped, Quaternion, TFMessage, Time, Transform,
    TransformStamped, Vector3,
};

/// A single call slower than this is a hang: the process aborts, naming the input.
pub const HANG_LIMIT: Duration = Duration::from_secs(5);
/// No generated or mutated input is longer than this, bytes.
pub const MAX_INPUT: usize = 256 * 1024;

// ---------------------------------------------------------------------------------------
// Memory: the binary installs a counting allocator (`peak_alloc`) and hands it in.

/// The counting allocator a binary installs (`#[global_allocator] static A: PeakAlloc =
/// PeakAlloc;`) and passes to [`run`] for the memory figures. Its counts are
/// process-wide: run targets one at a time for exact figures.
pub use peak_alloc::PeakAlloc;

// ---------------------------------------------------------------------------------------
// Randomness: SplitMix64, one fresh stream per iteration (so any input can be rebuilt).

/// A small deterministic random stream.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    fn below(&mut self, n: usize) -> usize {
        // n fits in u64 and the result is below n.
        #[allow(clippy::cast_possible_truncation)]
        let r = (self.next() % n.max(1) as u64) as usize;
        r
    }

    fn chance(&mut self, percent: u64) -> bool {
        self.next() % 100 < percent
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    fn f64(&mut self) -> f64 {
        // An interesting value now and then, else a plain one in [-10, 10).
        const ODD: [f64; 9] = [
            0.0,
            -0.0,
            1.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e308,
            f64::MIN_POSITIVE,
            -1e-320,
        ];
        if self.chance(10) {
            *self.pick(&ODD)
        } else {
            20.0 * self.uniform() - 10.0
        }
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        #[allow(clippy::cast_precision_loss)]
        let u = (self.next() >> 11) as f64 / (1u64 << 53) as f64;
        u
    }

    fn text(&mut self, max: usize) -> String {
        const PIECES: [&str; 12] = [
            "a",
            "FFJ1",
            "r_shoulder_pan_joint",
            "rh_palm",
            "/",
            "é",
            "😀",
            " ",
            "_",
            "0",
            "\u{feff}",
            "jpeg",
        ];
        let n = self.below(max + 1);
        (0..n).map(|_| *self.pick(&PIECES)).collect()
    }
}

/// The stream of iteration `i` of a run seeded `seed`.
fn iteration_rng(seed: u64, i: u64) -> Rng {
    let mut r = Rng::new(seed ^ i.wrapping_mul(0xD134_2543_DE82_EF95));
    r.next();
    r
}

// ---------------------------------------------------------------------------------------
// Mutation.

const INTERESTING_U32: [u32; 14] = [
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    0x7F,
    0xFFFF,
    1 << 20,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFE,
    0xFFFF_FFFF,
];

const HOSTILE_TOKENS: [&str; 30] = [
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e309",
    "-0",
    "0x10",
    "99999999999999999999999",
    "4294967296",
    "-1",
    "\u{feff}",
    "é",
    "\0",
    "||",
    "\r\n",
    "\n",
    ",",
    ",,",
    "[",
    "]]",
    "=",
    "\"",
    "{",
    "}",
    "End Site",
    "JOINT X",
    "CHANNELS 200",
    "MOTION",
    "Frames: 4000000000",
    "[bus.zenoh]",
];

/// One to four mutations of `input` (`seeds` for splicing; `text` adds token and line
/// mutations).
fn mutate(rng: &mut Rng, input: &mut Vec<u8>, seeds: &[Vec<u8>], text: bool) {
    for _ in 0..=rng.below(4) {
        let len = input.len();
        match rng.below(if text { 11 } else { 9 }) {
            0 if len > 0 => {
                let i = rng.below(len);
                input[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                const BYTES: [u8; 14] = [
                    0, 1, 0x7F, 0x80, 0xFF, b'\n', b',', b' ', b'{', b'}', b'=', b'"', b'[', b'|',
                ];
                let i = rng.below(len);
                input[i] = *rng.pick(&BYTES);
            }
            2 => {
                let at = rng.below(len + 1);
                let n = 1 + rng.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next().to_le_bytes()[0]).collect();
                input.splice(at..at, bytes);
            }
            3 if len > 0 => {
                let a = rng.below(len);
                let b = (a + 1 + rng.below(32)).min(len);
                input.drain(a..b);
            }
            4 if len > 0 => {
                // A range repeated elsewhere, a few times (amplification).
                let a = rng.below(len);
                let b = (a + 1 + rng.below(64)).min(len);
                let piece = input[a..b].to_vec();
                let at = rng.below(len + 1);
                for _ in 0..=rng.below(4) {
                    input.splice(at..at, piece.iter().copied());
                }
            }
            5 if len > 0 => input.truncate(rng.below(len)),
            6 if !seeds.is_empty() => {
                let other = rng.pick(seeds);
                let cut = rng.below(len + 1);
                let from = rng.below(other.len() + 1);
                input.truncate(cut);
                input.extend_from_slice(&other[from..]);
            }
            7 | 8 if len >= 4 => {
                // A 32-bit length or count: interesting, or near the input's length.
                let i = rng.below(len - 3);
                let v = if rng.chance(70) {
                    *rng.pick(&INTERESTING_U32)
                } else {
                    let near = u32::try_from(len).unwrap_or(u32::MAX);
                    near.wrapping_add(u32::try_from(rng.below(9)).unwrap_or(0))
                        .wrapping_sub(4)
                };
                let bytes = if rng.chance(80) {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                };
                input[i..i + 4].copy_from_slice(&bytes);
            }
            9 => {
                let at = rng.below(len + 1);
                input.splice(at..at, rng.pick(&HOSTILE_TOKENS).bytes());
            }
            10 => lines_mutation(rng, input),
            _ => {}
        }
    }
    input.truncate(MAX_INPUT);
}

/// Swaps two lines, repeats one, or drops one.
fn lines_mutation(rng: &mut Rng, input: &mut Vec<u8>) {
    let mut lines: Vec<Vec<u8>> = input.split(|b| *b == b'\n').map(<[u8]>::to_vec).collect();
    if lines.is_empty() {
        return;
    }
    let (a, b) = (rng.below(lines.len()), rng.below(lines.len()));
    match rng.below(3) {
        0 => lines.swap(a, b),
        1 => {
            let l = lines[a].clone();
            for _ in 0..=rng.below(8) {
                lines.insert(b, l.clone());
            }
        }
        _ => {
            lines.remove(a);
        }
    }
    *input = lines.join(&b'\n');
}

// ---------------------------------------------------------------------------------------
// Targets.

/// What a decoder did with an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Decoded, and its consumer's check passed.
    Accepted,
    /// Refused with an error.
    Refused,
}

type Decoder = Box<dyn Fn(&[u8]) -> Outcome + Send + Sync>;
type Generator = Box<dyn Fn(&mut Rng) -> Vec<u8> + Send + Sync>;

/// One decoder of outside bytes.
pub struct Target {
    pub name: &'static str,
    /// Valid inputs the mutations start from.
    pub seeds: Vec<Vec<u8>>,
    /// Text mutations apply too.
    pub text: bool,
    /// A fresh valid input (structure-aware), or none.
    generate: Option<Generator>,
    decode: Decoder,
}

impl std::fmt::Debug for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Target")
            .field("name", &self.name)
            .field("seeds", &self.seeds.len())
            .finish_non_exhaustive()
    }
}

fn outcome<T, E>(r: Result<T, E>) -> Outcome {
    if r.is_ok() {
        Outcome::Accepted
    } else {
        Outcome::Refused
    }
}

impl Target {
    /// A target whose seeds are the first `n` inputs of its own generator, drawn from
    /// the stream seeded `seed`; the generator also makes fresh inputs during the run.
    fn generated(
        name: &'static str,
        text: bool,
        (seed, n): (u64, usize),
        generate: impl Fn(&mut Rng) -> Vec<u8> + Send + Sync + 'static,
        decode: Decoder,
    ) -> Self {
        let mut rng = Rng::new(seed);
        Self {
            name,
            seeds: (0..n).map(|_| generate(&mut rng)).collect(),
            text,
            generate: Some(Box::new(generate)),
            decode,
        }
    }
}

/// A decoder of UTF-8 text: bytes that are not UTF-8 are refused, the text goes to `f`.
fn text_decoder(f: impl Fn(&str) -> Outcome + Send + Sync + 'static) -> Decoder {
    Box::new(move |b| match std::str::from_utf8(b) {
        Ok(text) => f(text),
        Err(_) => Outcome::Refused,
    })
}

fn enc<T: Message>(msg: &T) -> Vec<u8> {
    teleop_msgs::encode(msg).unwrap_or_default()
}

fn header(rng: &mut Rng) -> Header {
    Header::new(
        Time {
            sec: i32::try_from(rng.next() % 2_000_000_000).unwrap_or(0),
            nanosec: u32::try_from(rng.next() % 1_000_000_000).unwrap_or(0),
        },
        rng.text(3),
    )
}

/// A value: plausible (finite, in [-1, 1]), or with `odd` anything [`Rng::f64`] gives
/// (NaN, infinities, huge, subnormal now and then).
fn value(rng: &mut Rng, odd: bool) -> f64 {
    if odd {
        rng.f64()
    } else {
        2.0 * rng.uniform() - 1.0
    }
}

fn pose(rng: &mut Rng) -> Pose {
    let odd = rng.chance(20);
    let (x, y, z, w) = (
        value(rng, odd),
        value(rng, odd),
        value(rng, odd),
        value(rng, odd),
    );
    // A unit quaternion unless the values are odd ones.
    let n = (x * x + y * y + z * z + w * w).sqrt();
    let unit = !odd && n > 1e-3;
    Pose {
        position: Point {
            x: value(rng, odd),
            y: value(rng, odd),
            z: value(rng, odd),
        },
        orientation: if unit {
            Quaternion {
                x: x / n,
                y: y / n,
                z: z / n,
                w: w / n,
            }
        } else {
            Quaternion { x, y, z, w }
        },
    }
}

fn floats(rng: &mut Rng, n: usize, odd: bool) -> Vec<f64> {
    (0..n).map(|_| value(rng, odd)).collect()
}

/// `n` joint names: mostly the `table`'s in its order (what a well-behaved sender
/// sends), else shuffled, or with made-up names among them.
fn names(rng: &mut Rng, n: usize, table: &[&str]) -> Vec<String> {
    let mut out: Vec<String> = (0..n)
        .map(|i| match table.get(i) {
            Some(name) if rng.chance(97) => (*name).to_owned(),
            _ if rng.chance(50) => (*rng.pick(table)).to_owned(),
            _ => rng.text(4),
        })
        .collect();
    if rng.chance(10) && n > 1 {
        let (a, b) = (rng.below(n), rng.below(n));
        out.swap(a, b);
    }
    out
}

/// A CDR target for topic type `T`: decode, then `consume` (the consumer's check).
fn cdr<T: Message>(
    name: &'static str,
    generate: fn(&mut Rng) -> T,
    consume: fn(&T) -> Outcome,
) -> Target {
    Target::generated(
        name,
        false,
        (7, 32),
        move |rng| enc(&generate(rng)),
        Box::new(move |bytes| match teleop_msgs::decode::<T>(bytes) {
            Ok(msg) => consume(&msg),
            Err(_) => Outcome::Refused,
        }),
    )
}

fn joint_state(rng: &mut Rng) -> JointState {
    let n = if rng.chance(70) { 7 } else { rng.below(24) };
    let odd = rng.chance(20);
    let effort = if rng.chance(50) { n } else { 0 };
    JointState {
        header: header(rng),
        name: names(rng, n, &PR2_ARM_JOINTS),
        position: floats(rng, n, odd),
        velocity: floats(rng, n, odd),
        effort: floats(rng, effort, odd),
    }
}

fn joint_command(rng: &mut Rng) -> JointCommand {
    let n = if rng.chance(70) { 17 } else { rng.below(24) };
    let odd = rng.chance(20);
    let positive =
        |rng: &mut Rng| -> Vec<f64> { (0..n).map(|_| value(rng, odd).abs() + 0.01).collect() };
    JointCommand {
        header: header(rng),
        mode: (*rng.pick(&[
            "position",
            "effort",
            "impedance",
            "impedance",
            "velocity",
            "?",
        ]))
        .to_owned(),
        name: names(rng, n, &SHADOW_FINGER_JOINTS),
        position: floats(rng, n, odd),
        velocity: floats(rng, n, odd),
        effort: floats(rng, n, odd),
        stiffness: positive(rng),
        damping: positive(rng),
        max_effort: positive(rng),
    }
}

fn cdr_targets() -> Vec<Target> {
    vec![
        cdr::<PoseStamped>(
            "cdr PoseStamped + pose check",
            |rng| PoseStamped {
                header: header(rng),
                pose: pose(rng),
            },
            |m| {
                outcome(teleop_hardware::wire::checked_isometry(
                    &m.pose,
                    teleop_hardware::wire::POSE_QUATERNION_TOLERANCE,
                ))
            },
        ),
        cdr::<JointState>("cdr JointState + PR2 arm command check", joint_state, |m| {
            outcome(teleop_hardware::wire::arm_command(&PR2_ARM_JOINTS, m))
        }),
        cdr::<JointCommand>(
            "cdr JointCommand + hand command check",
            joint_command,
            |m| outcome(teleop_hardware::wire::hand_command(m)),
        ),
        cdr::<OperatorInput>(
            "cdr OperatorInput",
            |rng| OperatorInput {
                header: header(rng),
                clutch: rng.chance(50),
                enable: rng.chance(50),
                camera_stop: rng.chance(50),
                motion_scale: value(rng, true),
            },
            |_| Outcome::Accepted,
        ),
        cdr::<FingertipPressures>(
            "cdr FingertipPressures + hand state check",
            |rng| {
                let odd = rng.chance(20);
                FingertipPressures {
                    header: header(rng),
                    ff: value(rng, odd),
                    mf: value(rng, odd),
                    rf: value(rng, odd),
                    lf: value(rng, odd),
                    th: value(rng, odd),
                }
            },
            |m| {
                let joints = JointState {
                    header: m.header.clone(),
                    name: SHADOW_FINGER_JOINTS
                        .iter()
                        .map(|n| (*n).to_owned())
                        .collect(),
                    position: vec![0.1; 17],
                    velocity: vec![0.0; 17],
                    effort: vec![0.0; 17],
                };
                outcome(teleop_hardware::wire::hand_state(&joints, Some(m)))
            },
        ),
        cdr::<Image>(
            "cdr Image + layout check",
            |rng| {
                let (w, h) = (1 + rng.below(6), 1 + rng.below(5));
                let depth: Vec<u16> = (0..w * h)
                    .map(|_| u16::try_from(rng.next() % 4000).unwrap_or(0))
                    .collect();
                let mut img = Image::depth_mm(
                    header(rng),
                    u32::try_from(w).unwrap_or(1),
                    u32::try_from(h).unwrap_or(1),
                    &depth,
                );
                if rng.chance(20) {
                    img.encoding = (*rng.pick(&["rgb8", "mono8", "32FC1", "bgr8", "?"])).into();
                }
                img
            },
            |m| outcome(m.check_layout()),
        ),
        cdr::<CompressedImage>(
            "cdr CompressedImage + view check",
            |rng| {
                let n = rng.below(64);
                let mut data = vec![0xFF, 0xD8];
                data.extend((0..n).map(|_| rng.next().to_le_bytes()[0]));
                CompressedImage {
                    header: header(rng),
                    format: (*rng.pick(&["jpeg", "rgb8; jpeg compressed bgr8", "png", ""])).into(),
                    data,
                }
            },
            |m| outcome(teleop_local_site::operator_display::check_view(m)),
        ),
        cdr::<NodeStatus>(
            "cdr NodeStatus",
            |rng| {
                let n = rng.below(12);
                NodeStatus {
                    header: header(rng),
                    node_name: rng.text(4),
                    lifecycle_state: u8::try_from(rng.below(6)).unwrap_or(0),
                    counter_names: (0..n).map(|_| rng.text(5)).collect(),
                    counter_values: (0..n).map(|_| rng.next()).collect(),
                    last_error: rng.text(8),
                }
            },
            |m| {
                if m.lifecycle().is_some() {
                    Outcome::Accepted
                } else {
                    Outcome::Refused
                }
            },
        ),
        cdr::<Header>("cdr Header (view receipts)", header, |_| Outcome::Accepted),
        cdr::<TFMessage>(
            "cdr TFMessage",
            |rng| TFMessage {
                transforms: (0..rng.below(5))
                    .map(|_| {
                        let p = pose(rng);
                        TransformStamped {
                            header: header(rng),
                            child_frame_id: rng.text(3),
                            transform: Transform {
                                translation: Vector3 {
                                    x: p.position.x,
                                    y: p.position.y,
                                    z: p.position.z,
                                },
                                rotation: p.orientation,
                            },
                        }
                    })
                    .collect(),
            },
            |_| Outcome::Accepted,
        ),
    ]
}

fn attachment_target() -> Target {
    fn generate(rng: &mut Rng) -> Vec<u8> {
        teleop_bus::Attachment {
            sequence: i64::from_le_bytes(rng.next().to_le_bytes()),
            source_timestamp_ns: i64::from_le_bytes(rng.next().to_le_bytes()),
            gid: [rng.next().to_le_bytes()[0]; 16],
        }
        .to_bytes()
        .to_vec()
    }
    Target::generated(
        "rmw_zenoh attachment",
        false,
        (11, 16),
        generate,
        Box::new(|b| outcome(teleop_bus::Attachment::from_bytes(b))),
    )
}

fn liveliness_target() -> Target {
    use teleop_bus::keys::{EntityKind, GraphEntity, liveliness_key, parse_liveliness_key};
    let mut seeds = Vec::new();
    for (i, spec) in teleop_interfaces::topics::ALL.iter().enumerate() {
        let kind = if i % 2 == 0 {
            EntityKind::Publisher
        } else {
            EntityKind::Subscriber
        };
        let entity = GraphEntity {
            domain_id: u32::try_from(i).unwrap_or(0),
            zid: "1f2e3d4c5b6a79881f2e3d4c5b6a7988".into(),
            node_id: u32::try_from(i).unwrap_or(0),
            entity_id: u32::try_from(i + 10).unwrap_or(0),
            kind,
            namespace: String::new(),
            node_name: "pr2_arm_controller".into(),
            topic: Some(spec.name.to_owned()),
            dds_type: teleop_msgs::description_of(spec.type_name).map(|d| d.dds_type_name()),
            type_hash: Some(spec.type_hash.to_owned()),
        };
        seeds.push(liveliness_key(&entity, "::,10:,:,:,,").into_bytes());
    }
    Target {
        name: "liveliness token / key expression",
        seeds,
        text: true,
        generate: None,
        decode: Box::new(|b| {
            let key = String::from_utf8_lossy(b);
            let parsed = parse_liveliness_key(&key);
            let _gid = teleop_bus::directory::gid_for_token(&key);
            let _ = teleop_bus::keys::demangle(&key);
            if let Some(e) = &parsed {
                let _ = (e.fq_node_name(), e.ros_type_name());
            }
            outcome(parsed.ok_or(()))
        }),
    }
}

fn mcap_target() -> anyhow::Result<Target> {
    use teleop_bag::{BagOptions, BagWriter, Compression};
    let mut seeds = Vec::new();
    let dir = std::env::temp_dir().join(format!("teleop-hostile-mcap-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    let mut rng = Rng::new(13);
    for (k, compression) in [Compression::None, Compression::Lz4, Compression::Zstd]
        .into_iter()
        .enumerate()
    {
        let bag = dir.join(format!("bag{k}"));
        let mut w = BagWriter::create(
            &bag,
            BagOptions {
                compression,
                chunk_bytes: 1024,
                ..BagOptions::default()
            },
        )?;
        let pose = w.add_topic(&teleop_interfaces::topics::WRIST_POSE.spec)?;
        let joints = w.add_topic(&teleop_interfaces::topics::PR2_JOINT_STATES.spec)?;
        for i in 0..20u32 {
            let t = 1_700_000_000_000_000_000 + u64::from(i) * 10_000_000;
            let p = enc(&PoseStamped {
                header: header(&mut rng),
                pose: pose_unit(),
            });
            w.write(pose, t, t, i, &p)?;
            w.write(joints, t + 1, t, i, &enc(&joint_state(&mut rng)))?;
        }
        w.close()?;
        for f in teleop_bag::mcap_files(&bag)? {
            seeds.push(std::fs::read(f)?);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(Target {
        name: "MCAP bag reader",
        seeds,
        text: false,
        generate: None,
        decode: Box::new(|b| outcome(teleop_bag::read_bytes(Path::new("hostile.mcap"), b))),
    })
}

fn pose_unit() -> Pose {
    Pose {
        position: Point {
            x: 0.4,
            y: -0.1,
            z: 0.9,
        },
        orientation: Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        },
    }
}

fn bvh_targets(repo: &Path) -> anyhow::Result<Vec<Target>> {
    use teleop_local_site::tracking::bvh::{Skeleton, parse_stream_frame};
    let fixture = std::fs::read_to_string(repo.join("tests/fixtures/upper_body.bvh"))?;
    let (skeleton, _) = Skeleton::parse(&fixture)?;
    let channels = skeleton.channel_count();
    let hand = skeleton.joint("RightHand")?;
    let frame = move |rng: &mut Rng| {
        let values: Vec<String> = (0..channels)
            .map(|_| format!("{:.3}", 180.0 * (2.0 * rng.uniform() - 1.0)))
            .collect();
        format!("0 Avatar00 {}", values.join(" ")).into_bytes()
    };
    let stream = Target::generated(
        "BVH stream frame + pose",
        true,
        (17, 16),
        frame,
        text_decoder(move |text| {
            outcome(
                parse_stream_frame(text)
                    .and_then(|f| skeleton.relative_pose(&f.values, 0, hand, 0.01)),
            )
        }),
    );
    let file = Target {
        name: "BVH skeleton file",
        seeds: vec![fixture.into_bytes()],
        text: true,
        generate: None,
        decode: text_decoder(|text| outcome(Skeleton::parse(text))),
    };
    Ok(vec![stream, file])
}

/// The JPEG frame header reader of the dataset export (the camera views of a bag go
/// into its videos unchanged; their size and subsampling come from this).
fn jpeg_target() -> Target {
    fn generate(rng: &mut Rng) -> Vec<u8> {
        let (w, h) = (1 + rng.below(40) as u32, 1 + rng.below(30) as u32);
        let shade = rng.below(256) as u8;
        let image = teleop_msgs::Image {
            header: teleop_msgs::Header::default(),
            height: h,
            width: w,
            encoding: "rgb8".to_owned(),
            is_bigendian: 0,
            step: 3 * w,
            data: (0..3 * w * h)
                .map(|i| shade.wrapping_add(i as u8))
                .collect(),
        };
        teleop_msgs::image_codec::jpeg_from_rgb8(&image, 50 + rng.below(50) as u8)
            .map(|c| c.data)
            .unwrap_or_default()
    }
    Target::generated(
        "JPEG frame header (dataset export)",
        false,
        (23, 8),
        generate,
        Box::new(|b| outcome(teleop_dataset::jpeg::jpeg_info(b))),
    )
}

fn replay_target() -> Target {
    fn generate(rng: &mut Rng) -> Vec<u8> {
        let mut out = String::from("# a recorded wrist path\nt_s,x_m,y_m,z_m,qx,qy,qz,qw\n");
        let mut t = 0.0;
        for _ in 0..1 + rng.below(12) {
            t += 0.003_125;
            if rng.chance(10) {
                out.push_str(&format!("{t:.6},,,,,,,\n"));
            } else {
                out.push_str(&format!(
                    "{t:.6},{:.3},{:.3},{:.3},0,0,{:.4},{:.4}\n",
                    2.0 * rng.uniform() - 1.0,
                    2.0 * rng.uniform() - 1.0,
                    2.0 * rng.uniform() - 1.0,
                    0.0,
                    1.0
                ));
            }
        }
        out.into_bytes()
    }
    Target::generated(
        "CSV pose replay",
        true,
        (19, 16),
        generate,
        text_decoder(|text| {
            outcome(teleop_local_site::tracking::replay::PoseTrajectory::parse(
                text,
                Path::new("hostile.csv"),
            ))
        }),
    )
}

/// Parses `text` as node config `C` and validates it, as a node loads its file.
fn config_outcome<C: teleop_node::NodeConfig>(text: &str) -> Outcome {
    match teleop_node::config::parse_toml::<C>(text) {
        Ok(mut c) => outcome(teleop_node::config::validate_all(&mut c)),
        Err(_) => Outcome::Refused,
    }
}

/// The shipped node config files, each as its node's type. The first byte of an input
/// picks the type (mod the number of types), the rest is the file.
fn config_target(repo: &Path) -> anyhow::Result<Target> {
    use teleop_hand_inference::node::HandInferenceConfig;
    use teleop_local_site::camera_arm_node::CameraArmNodeConfig;
    use teleop_local_site::operator_display::OperatorDisplayConfig;
    use teleop_local_site::wrist_tracker::WristTrackerConfig;
    use teleop_remote_site::arm_node::ArmNodeConfig;
    use teleop_remote_site::feedback_node::FeedbackConfig;
    use teleop_remote_site::hand_node::HandNodeConfig;
    use teleop_sim_nodes::local_sim::LocalSimConfig;
    use teleop_sim_nodes::remote_sim::SimNodeConfig;
    const FILES: [&str; 9] = [
        "wrist_tracker",
        "pr2_arm_controller",
        "remote_sim",
        "feedback_publisher",
        "shadow_hand_controller",
        "local_sim",
        "camera_arm",
        "hand_inference",
        "operator_display",
    ];
    let mut seeds = Vec::new();
    for (i, f) in FILES.iter().enumerate() {
        let mut s = vec![u8::try_from(i).unwrap_or(0)];
        s.extend(std::fs::read(
            repo.join("deploy/config").join(format!("{f}.toml")),
        )?);
        seeds.push(s);
    }
    Ok(Target {
        name: "node config files (TOML)",
        seeds,
        text: true,
        generate: None,
        decode: Box::new(|b| {
            let Some((which, rest)) = b.split_first() else {
                return Outcome::Refused;
            };
            let Ok(text) = std::str::from_utf8(rest) else {
                return Outcome::Refused;
            };
            match which % 9 {
                0 => config_outcome::<WristTrackerConfig>(text),
                1 => config_outcome::<ArmNodeConfig>(text),
                2 => config_outcome::<SimNodeConfig>(text),
                3 => config_outcome::<FeedbackConfig>(text),
                4 => config_outcome::<HandNodeConfig>(text),
                5 => config_outcome::<LocalSimConfig>(text),
                6 => config_outcome::<CameraArmNodeConfig>(text),
                7 => config_outcome::<HandInferenceConfig>(text),
                _ => config_outcome::<OperatorDisplayConfig>(text),
            }
        }),
    })
}

/// Every decoder of outside bytes (`repo`: the repository root, for the shipped files
/// the seeds come from).
///
/// # Errors
/// A seed file missing or a seed bag that cannot be written.
pub fn targets(repo: &Path) -> anyhow::Result<Vec<Target>> {
    let mut all = cdr_targets();
    all.push(attachment_target());
    all.push(liveliness_target());
    all.push(mcap_target()?);
    all.extend(bvh_targets(repo)?);
    all.push(replay_target());
    all.push(jpeg_target());
    all.push(config_target(repo)?);
    Ok(all)
}

// ---------------------------------------------------------------------------------------
// Running.

/// What one target did with a run's inputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    pub name: &'static str,
    pub inputs: u64,
    pub accepted: u64,
    pub refused: u64,
    pub panics: u64,
    /// The first panic: its iteration and message.
    pub first_panic: Option<(u64, String)>,
    /// The slowest single call.
    pub slowest: Duration,
    /// The most memory live during one call beyond what was live before it, bytes
    /// (`None` without an allocator to read).
    pub peak_call_bytes: Option<usize>,
    /// The longest input, bytes.
    pub longest_input: usize,
    pub elapsed: Duration,
}

impl Report {
    /// The report as a markdown table row: decoder, inputs, accepted, refused, panics,
    /// slowest call (ms), most memory live in one call (bytes), longest input (bytes),
    /// inputs per second.
    #[must_use]
    pub fn markdown_row(&self) -> String {
        #[allow(clippy::cast_precision_loss)]
        let rate = self.inputs as f64 / self.elapsed.as_secs_f64().max(1e-9);
        format!(
            "| {} | {} | {} | {} | {} | {:.2} | {} | {} | {:.0} |",
            self.name,
            self.inputs,
            self.accepted,
            self.refused,
            self.panics,
            self.slowest.as_secs_f64() * 1e3,
            self.peak_call_bytes
                .map_or("-".to_owned(), |b| b.to_string()),
            self.longest_input,
            rate
        )
    }
}

/// The header of [`Report::markdown_row`]'s table.
pub const MARKDOWN_HEADER: &str = "| decoder | inputs | accepted | refused | panics | slowest call (ms) | most memory live in one call (B) | longest input (B) | inputs/s |\n|---|---|---|---|---|---|---|---|---|";

thread_local! {
    static PANIC_MESSAGE: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// The input of iteration `i` of a run of `target` seeded `seed`.
#[must_use]
pub fn input_at(target: &Target, seed: u64, i: u64) -> Vec<u8> {
    let mut rng = iteration_rng(seed, i);
    if let Some(generate) = &target.generate
        && rng.chance(10)
    {
        let mut fresh = generate(&mut rng);
        fresh.truncate(MAX_INPUT);
        return fresh;
    }
    let mut input = if target.seeds.is_empty() {
        Vec::new()
    } else {
        rng.pick(&target.seeds).clone()
    };
    if let Some(generate) = &target.generate
        && rng.chance(30)
    {
        input = generate(&mut rng);
    }
    mutate(&mut rng, &mut input, &target.seeds, target.text);
    input
}

/// Feeds `target` `inputs` inputs of the run seeded `seed`. Panics are caught and
/// counted; a call longer than [`HANG_LIMIT`] aborts the process (the message names the
/// target, seed and iteration). `memory`: the process's installed counting allocator,
/// for the memory live during each call.
#[must_use]
pub fn run(target: &Target, inputs: u64, seed: u64, memory: Option<&PeakAlloc>) -> Report {
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|info| {
        let msg = info.to_string();
        PANIC_MESSAGE.with(|m| *m.borrow_mut() = Some(msg));
    }));
    // The watchdog: the iteration in progress and when it started (ns since `t0`, 0:
    // between calls).
    let t0 = Instant::now();
    let busy_since = Arc::new(AtomicU64::new(0));
    let iteration = Arc::new(AtomicU64::new(0));
    let done = Arc::new(AtomicBool::new(false));
    let watchdog = {
        let (busy_since, iteration, done) = (
            Arc::clone(&busy_since),
            Arc::clone(&iteration),
            Arc::clone(&done),
        );
        let name = target.name;
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(100));
                let since = busy_since.load(Ordering::Relaxed);
                let now = u64::try_from(t0.elapsed().as_nanos()).unwrap_or(u64::MAX);
                if since != 0
                    && now.saturating_sub(since)
                        > u64::try_from(HANG_LIMIT.as_nanos()).unwrap_or(u64::MAX)
                {
                    eprintln!(
                        "HANG: `{name}` ran over {HANG_LIMIT:?} on iteration {} of seed {seed} \
                         (rebuild the input with hostile::input_at)",
                        iteration.load(Ordering::Relaxed)
                    );
                    std::process::abort();
                }
            }
        })
    };
    let mut r = Report {
        name: target.name,
        inputs: 0,
        accepted: 0,
        refused: 0,
        panics: 0,
        first_panic: None,
        slowest: Duration::ZERO,
        peak_call_bytes: None,
        longest_input: 0,
        elapsed: Duration::ZERO,
    };
    for i in 0..inputs {
        let input = input_at(target, seed, i);
        r.longest_input = r.longest_input.max(input.len());
        iteration.store(i, Ordering::Relaxed);
        let before = memory.map_or(0, |m| {
            m.reset_peak_usage();
            m.current_usage()
        });
        let started = Instant::now();
        busy_since.store(
            u64::try_from(t0.elapsed().as_nanos())
                .unwrap_or(u64::MAX)
                .max(1),
            Ordering::Relaxed,
        );
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| (target.decode)(&input)));
        busy_since.store(0, Ordering::Relaxed);
        r.slowest = r.slowest.max(started.elapsed());
        if let Some(m) = memory {
            let peak = m.peak_usage().saturating_sub(before);
            r.peak_call_bytes = Some(r.peak_call_bytes.unwrap_or(0).max(peak));
        }
        r.inputs += 1;
        match result {
            Ok(Outcome::Accepted) => r.accepted += 1,
            Ok(Outcome::Refused) => r.refused += 1,
            Err(_) => {
                r.panics += 1;
                if r.first_panic.is_none() {
                    let msg = PANIC_MESSAGE
                        .with(|m| m.borrow_mut().take())
                        .unwrap_or_default();
                    r.first_panic = Some((i, msg));
                }
            }
        }
    }
    r.elapsed = t0.elapsed();
    done.store(true, Ordering::Relaxed);
    let _ = watchdog.join();
    std::panic::set_hook(previous_hook);
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_is_rebuilt_from_its_seed_and_iteration() {
        let t = attachment_target();
        assert_eq!(input_at(&t, 5, 1234), input_at(&t, 5, 1234));
        assert_ne!(input_at(&t, 5, 1234), input_at(&t, 6, 1234));
    }

    #[test]
    fn a_panicking_decoder_is_counted_with_its_message() {
        let t = Target {
            name: "panics on a zero first byte",
            seeds: vec![vec![1, 2, 3]],
            text: false,
            generate: None,
            decode: Box::new(|b| {
                assert!(b.first() != Some(&0), "zero first byte");
                Outcome::Refused
            }),
        };
        let r = run(&t, 5000, 1, None);
        assert!(r.panics > 0, "{r:?}");
        assert_eq!(r.panics + r.refused, 5000);
        let (_, msg) = r.first_panic.unwrap_or_default();
        assert!(msg.contains("zero first byte"), "{msg}");
    }
}
