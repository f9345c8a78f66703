//! Reading bags back: what a bag or an MCAP file holds (`teleop bag info`), files cut
//! short included, and rewriting such a file whole ([`recover`]).

use std::collections::BTreeMap;
use std::fmt;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::error::BagError;
use crate::writer::{MetaFile, MetaTopic, write_metadata};

/// One topic of a file or a bag.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicReport {
    /// With its leading slash.
    pub topic: String,
    pub type_name: String,
    /// The channel's `topic_type_hash` metadata (empty if none).
    pub type_hash: String,
    /// The channel's `offered_qos_profiles` metadata (YAML text; empty if none).
    pub offered_qos: String,
    pub count: u64,
}

/// What one MCAP file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct FileReport {
    pub path: PathBuf,
    pub bytes: u64,
    pub messages: u64,
    /// Log times of the first and the last message, ns since the epoch.
    pub first_ns: Option<u64>,
    pub last_ns: u64,
    pub topics: BTreeMap<String, TopicReport>,
    /// The file's profile (`ros2` for a rosbag2 file).
    pub profile: String,
    /// Why reading stopped before the file's end: the file was cut short (a crash, a
    /// full disk); everything before is counted. `None` for a whole file.
    pub truncated: Option<String>,
}

/// What a bag (a directory of MCAP files, or one file) holds.
#[derive(Debug, Clone, PartialEq)]
pub struct BagReport {
    pub path: PathBuf,
    pub files: Vec<FileReport>,
}

impl BagReport {
    pub fn messages(&self) -> u64 {
        self.files.iter().map(|f| f.messages).sum()
    }
    pub fn bytes(&self) -> u64 {
        self.files.iter().map(|f| f.bytes).sum()
    }
    pub fn first_ns(&self) -> Option<u64> {
        self.files.iter().filter_map(|f| f.first_ns).min()
    }
    pub fn last_ns(&self) -> u64 {
        self.files.iter().map(|f| f.last_ns).max().unwrap_or(0)
    }
    /// From the first message to the last, s.
    #[allow(clippy::cast_precision_loss)]
    pub fn duration_s(&self) -> f64 {
        self.first_ns()
            .map_or(0.0, |f| self.last_ns().saturating_sub(f) as f64 * 1e-9)
    }
    /// Every topic over all files.
    pub fn topics(&self) -> BTreeMap<String, TopicReport> {
        let mut out: BTreeMap<String, TopicReport> = BTreeMap::new();
        for f in &self.files {
            for (name, t) in &f.topics {
                out.entry(name.clone())
                    .and_modify(|e| e.count += t.count)
                    .or_insert_with(|| t.clone());
            }
        }
        out
    }
    /// A topic's mean rate over the bag's duration, Hz.
    #[allow(clippy::cast_precision_loss)]
    pub fn rate_hz(&self, count: u64) -> Option<f64> {
        let d = self.duration_s();
        (d > 0.0).then(|| count as f64 / d)
    }
}

impl fmt::Display for BagReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "bag:       {}", self.path.display())?;
        #[allow(clippy::cast_precision_loss)]
        let mib = self.bytes() as f64 / (1024.0 * 1024.0);
        writeln!(f, "size:      {mib:.2} MiB in {} file(s)", self.files.len())?;
        writeln!(f, "duration:  {:.3} s", self.duration_s())?;
        if let Some(first) = self.first_ns() {
            #[allow(clippy::cast_precision_loss)]
            let (a, b) = (first as f64 * 1e-9, self.last_ns() as f64 * 1e-9);
            writeln!(f, "start:     {a:.3} s since the epoch")?;
            writeln!(f, "end:       {b:.3} s since the epoch")?;
        }
        writeln!(f, "messages:  {}", self.messages())?;
        let topics = self.topics();
        let width = topics.keys().map(String::len).max().unwrap_or(5).max(5);
        writeln!(
            f,
            "{:<width$}  {:<36}  {:>8}  {:>9}",
            "topic", "type", "count", "rate Hz"
        )?;
        for t in topics.values() {
            let rate = self
                .rate_hz(t.count)
                .map_or_else(|| "-".into(), |r| format!("{r:.1}"));
            writeln!(
                f,
                "{:<width$}  {:<36}  {:>8}  {:>9}",
                t.topic, t.type_name, t.count, rate
            )?;
        }
        for file in &self.files {
            let name = file.path.file_name().map_or_else(
                || file.path.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            match &file.truncated {
                None => writeln!(f, "file {name}: {} messages", file.messages)?,
                Some(why) => writeln!(
                    f,
                    "file {name}: {} messages, CUT SHORT ({why}); `teleop bag recover` rewrites it whole",
                    file.messages
                )?,
            }
        }
        Ok(())
    }
}

/// The MCAP files of a bag directory, in order (`<name>_0.mcap`, `<name>_1.mcap`, ...),
/// or the one file given.
///
/// # Errors
/// [`BagError::Io`] if it cannot be read, [`BagError::Empty`] if it holds none.
pub fn mcap_files(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    if path.is_file() {
        return Ok(vec![path.to_owned()]);
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(BagError::io(path))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    // By the split index after the last `_`, then by name.
    let index = |p: &PathBuf| -> (u64, String) {
        let stem = p
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let i = stem
            .rsplit('_')
            .next()
            .and_then(|n| n.parse().ok())
            .unwrap_or(u64::MAX);
        (i, stem)
    };
    files.sort_by_key(index);
    if files.is_empty() {
        return Err(BagError::Empty {
            path: path.to_owned(),
        });
    }
    Ok(files)
}

/// What a bag directory (or one MCAP file) holds.
///
/// # Errors
/// See [`mcap_files`] and [`read_file`].
pub fn read_bag(path: &Path) -> Result<BagReport, BagError> {
    let files = mcap_files(path)?
        .iter()
        .map(|p| read_file(p))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(BagReport {
        path: path.to_owned(),
        files,
    })
}

/// What one MCAP file holds: every message read from its start, to its end or to where
/// it was cut short.
///
/// # Errors
/// [`BagError::Io`] if it cannot be read; [`BagError::Mcap`] if it is not MCAP at all
/// (no magic, no header).
pub fn read_file(path: &Path) -> Result<FileReport, BagError> {
    let buf = std::fs::read(path).map_err(BagError::io(path))?;
    read_bytes(path, &buf)
}

/// What the MCAP bytes `buf` hold, as [`read_file`] reads a file (`path` names them in
/// the report and in errors). Whatever the bytes, it returns without panicking.
///
/// # Errors
/// [`BagError::Mcap`] if they are not MCAP at all (no magic, no header).
pub fn read_bytes(path: &Path, buf: &[u8]) -> Result<FileReport, BagError> {
    let stream = crate::messages(buf).map_err(BagError::read(path))?;
    let profile = crate::read::header_profile(buf).map_err(BagError::read(path))?;
    let mut report = FileReport {
        path: path.to_owned(),
        bytes: buf.len() as u64,
        messages: 0,
        first_ns: None,
        last_ns: 0,
        topics: BTreeMap::new(),
        profile,
        truncated: None,
    };
    for m in stream {
        match m {
            Ok(m) => {
                report.messages += 1;
                report.first_ns = Some(report.first_ns.map_or(m.log_time, |f| f.min(m.log_time)));
                report.last_ns = report.last_ns.max(m.log_time);
                let c = &m.channel;
                report
                    .topics
                    .entry(c.topic.clone())
                    .or_insert_with(|| TopicReport {
                        topic: c.topic.clone(),
                        type_name: c
                            .schema
                            .as_ref()
                            .map(|s| s.name.clone())
                            .unwrap_or_default(),
                        type_hash: c
                            .metadata
                            .get("topic_type_hash")
                            .cloned()
                            .unwrap_or_default(),
                        offered_qos: c
                            .metadata
                            .get("offered_qos_profiles")
                            .cloned()
                            .unwrap_or_default(),
                        count: 0,
                    })
                    .count += 1;
            }
            Err(e) => {
                report.truncated = Some(e.to_string());
                break;
            }
        }
    }
    Ok(report)
}

/// The most a chunk may claim to grow when decompressed: this many times its compressed
/// size, plus [`CHUNK_GROWTH_ALLOWANCE`] bytes. (CDR compresses 2-10x; a chunk of zeros
/// can legitimately compress ~1000x.)
pub const MAX_CHUNK_RATIO: u64 = 1024;
/// See [`MAX_CHUNK_RATIO`].
pub const CHUNK_GROWTH_ALLOWANCE: u64 = 1 << 20;

/// Checks that no chunk of the MCAP bytes `buf` claims an uncompressed size beyond
/// [`MAX_CHUNK_RATIO`] times its compressed bytes (plus [`CHUNK_GROWTH_ALLOWANCE`]).
/// The `mcap` crate's readers reserve a chunk's claimed uncompressed size before they
/// decompress it, so a corrupt or hostile size field would otherwise make one small file
/// allocate exabytes (found by the hostile-input runs). Walks the records' framing
/// (opcode, length) only; a file cut short is checked as far as it goes, its last chunk
/// by the bytes it still has. [`crate::messages`] checks this before it reads.
///
/// # Errors
/// The first chunk that claims too much, with its offset and sizes.
pub fn check_chunk_sizes(buf: &[u8]) -> Result<(), String> {
    chunk_limits(buf).map(|_| ())
}

/// [`check_chunk_sizes`], returning the largest uncompressed size a chunk claims.
pub(crate) fn chunk_limits(buf: &[u8]) -> Result<u64, String> {
    const CHUNK: u8 = 0x06;
    const FOOTER: u8 = 0x02;
    let u64_at = |at: usize| -> Option<u64> {
        buf.get(at..at.checked_add(8)?)
            .and_then(|b| b.try_into().ok())
            .map(u64::from_le_bytes)
    };
    let mut largest = 0;
    let mut at = mcap::MAGIC.len();
    while let (Some(&op), Some(len)) = (buf.get(at), u64_at(at + 1)) {
        let body = at + 9;
        let available = (buf.len() - body.min(buf.len())) as u64;
        let compressed = len.min(available);
        if op == CHUNK {
            // Message start and end times, then the uncompressed size.
            if let Some(claimed) = u64_at(body + 16) {
                let most = compressed
                    .saturating_mul(MAX_CHUNK_RATIO)
                    .saturating_add(CHUNK_GROWTH_ALLOWANCE);
                if claimed > most {
                    return Err(format!(
                        "the chunk at byte {at} claims {claimed} bytes uncompressed from \
                         {compressed} bytes (at most {most} accepted)"
                    ));
                }
                largest = largest.max(claimed);
            }
        }
        if op == FOOTER || len > available {
            break;
        }
        // len <= available <= buf.len(): no overflow.
        #[allow(clippy::cast_possible_truncation)]
        let next = body + len as usize;
        at = next;
    }
    Ok(largest)
}

/// Rewrites a bag's MCAP files that were cut short as whole files (every message up to
/// the cut, with its schemas and channels, a summary and a footer) and its
/// `metadata.yaml` from what the files hold, so any reader opens it. Whole files are
/// left as they are. Returns the report of the bag as it is after.
///
/// # Errors
/// [`BagError`] reading or writing the files.
pub fn recover(dir: &Path) -> Result<BagReport, BagError> {
    for path in mcap_files(dir)? {
        if read_file(&path)?.truncated.is_some() {
            rewrite_whole(&path)?;
        }
    }
    let report = read_bag(dir)?;
    if dir.is_dir() {
        let topics: Vec<MetaTopic> = report
            .topics()
            .into_values()
            .map(|t| MetaTopic {
                offered_qos_profiles: serde_yaml::from_str(&t.offered_qos)
                    .unwrap_or(serde_yaml::Value::Null),
                name: t.topic,
                type_name: t.type_name,
                type_hash: t.type_hash,
                count: t.count,
            })
            .collect();
        let files: Vec<MetaFile> = report
            .files
            .iter()
            .map(|f| MetaFile {
                name: f
                    .path
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                first_ns: f.first_ns,
                last_ns: f.last_ns,
                count: f.messages,
            })
            .collect();
        write_metadata(dir, &topics, &files)?;
    }
    Ok(report)
}

/// Every message that can be read from `path`, written to a new whole file that then
/// replaces it.
fn rewrite_whole(path: &Path) -> Result<(), BagError> {
    let buf = std::fs::read(path).map_err(BagError::io(path))?;
    let stream = crate::messages(&buf).map_err(BagError::read(path))?;
    let profile = crate::read::header_profile(&buf).map_err(BagError::read(path))?;
    let tmp = path.with_extension("mcap.recovering");
    let out = File::create(&tmp).map_err(BagError::io(&tmp))?;
    let mut writer = mcap::WriteOptions::new()
        .profile(profile)
        .library(concat!(
            "teleop-bag ",
            env!("CARGO_PKG_VERSION"),
            " (recovered)"
        ))
        .create(BufWriter::new(out))
        .map_err(BagError::mcap(&tmp))?;
    let mut channels: BTreeMap<u16, u16> = BTreeMap::new();
    for m in stream {
        let Ok(m) = m else { break };
        let c = &m.channel;
        let id = match channels.get(&c.id) {
            Some(id) => *id,
            None => {
                let schema = match &c.schema {
                    Some(s) => writer
                        .add_schema(&s.name, &s.encoding, &s.data)
                        .map_err(BagError::mcap(&tmp))?,
                    None => 0,
                };
                let id = writer
                    .add_channel(schema, &c.topic, &c.message_encoding, &c.metadata)
                    .map_err(BagError::mcap(&tmp))?;
                channels.insert(c.id, id);
                id
            }
        };
        writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: id,
                    sequence: m.sequence,
                    log_time: m.log_time,
                    publish_time: m.publish_time,
                },
                &m.data,
            )
            .map_err(BagError::mcap(&tmp))?;
    }
    writer.finish().map_err(BagError::mcap(&tmp))?;
    drop(writer);
    std::fs::rename(&tmp, path).map_err(BagError::io(path))
}
