//! [`BagWriter`]: samples in, a rosbag2 bag directory of MCAP files out.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use mcap::records::MessageHeader;
use serde::Serialize;
use teleop_interfaces::TopicSpec;

use crate::error::BagError;
use crate::qos::{QosProfile, offered_qos_yaml, qos_profile};

/// How chunks are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    #[default]
    Zstd,
    Lz4,
    None,
}

impl FromStr for Compression {
    type Err = BagError;
    fn from_str(s: &str) -> Result<Self, BagError> {
        match s {
            "zstd" => Ok(Compression::Zstd),
            "lz4" => Ok(Compression::Lz4),
            "none" => Ok(Compression::None),
            other => Err(BagError::Option(format!(
                "compression `{other}`: zstd, lz4 or none"
            ))),
        }
    }
}

impl Compression {
    fn mcap(self) -> Option<mcap::Compression> {
        match self {
            Compression::Zstd => Some(mcap::Compression::Zstd),
            Compression::Lz4 => Some(mcap::Compression::Lz4),
            Compression::None => None,
        }
    }
}

/// How a bag is written.
#[derive(Debug, Clone, PartialEq)]
pub struct BagOptions {
    pub compression: Compression,
    /// A chunk is closed (compressed and written) when it holds this many bytes.
    pub chunk_bytes: u64,
    /// A new file is started when the current one reaches this size on disk.
    pub max_file_bytes: Option<u64>,
    /// ... or spans this long (log time), s.
    pub max_file_duration_s: Option<f64>,
    /// The open chunk is closed and the file flushed at least this often (log time), s:
    /// a crash loses at most the samples of the last interval.
    pub flush_interval_s: f64,
}

impl Default for BagOptions {
    fn default() -> Self {
        Self {
            compression: Compression::Zstd,
            chunk_bytes: 1 << 20,
            max_file_bytes: None,
            max_file_duration_s: None,
            flush_interval_s: 1.0,
        }
    }
}

impl BagOptions {
    /// Checks the numbers.
    ///
    /// # Errors
    /// [`BagError::Option`] naming the first bad one.
    pub fn validate(&self) -> Result<(), BagError> {
        if self.chunk_bytes < 1024 {
            return Err(BagError::Option(format!(
                "chunk_bytes {} is below 1024",
                self.chunk_bytes
            )));
        }
        if self.max_file_bytes.is_some_and(|b| b < 64 * 1024) {
            return Err(BagError::Option(
                "max_file_bytes must be at least 64 KiB".into(),
            ));
        }
        if self
            .max_file_duration_s
            .is_some_and(|d| !(d.is_finite() && d > 0.0))
        {
            return Err(BagError::Option(
                "max_file_duration_s must be a positive number".into(),
            ));
        }
        if !(self.flush_interval_s.is_finite() && self.flush_interval_s > 0.0) {
            return Err(BagError::Option(
                "flush_interval_s must be a positive number".into(),
            ));
        }
        Ok(())
    }
}

/// A topic added to a bag ([`BagWriter::add_topic`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TopicId(usize);

#[derive(Debug)]
struct TopicEntry {
    /// With its leading slash, as ROS 2 names topics in bags.
    name: String,
    type_name: &'static str,
    type_hash: &'static str,
    schema: String,
    qos: QosProfile,
    qos_yaml: String,
    count: u64,
}

/// The file handle under the MCAP writer, counting how far it reached (the file's
/// size, shared with the bag writer).
#[derive(Debug)]
struct Counted {
    inner: BufWriter<File>,
    pos: u64,
    len: Arc<AtomicU64>,
}

impl Write for Counted {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.pos += n as u64;
        self.len.fetch_max(self.pos, Ordering::Relaxed);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for Counted {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.pos = self.inner.seek(to)?;
        Ok(self.pos)
    }
}

struct OpenFile {
    writer: mcap::Writer<Counted>,
    len: Arc<AtomicU64>,
    name: String,
    channels: BTreeMap<TopicId, u16>,
    first_ns: Option<u64>,
    last_ns: u64,
    count: u64,
}

impl OpenFile {
    fn bytes(&self) -> u64 {
        self.len.load(Ordering::Relaxed)
    }
}

/// What a closed bag holds.
#[derive(Debug, Clone, PartialEq)]
pub struct BagSummary {
    pub dir: PathBuf,
    pub files: Vec<String>,
    pub messages: u64,
    /// Messages per topic (with leading slash).
    pub per_topic: BTreeMap<String, u64>,
    pub first_ns: Option<u64>,
    pub last_ns: u64,
}

/// Writes a bag: add the topics, hand it samples, close it.
pub struct BagWriter {
    dir: PathBuf,
    stem: String,
    opts: BagOptions,
    topics: Vec<TopicEntry>,
    open: Option<OpenFile>,
    files: Vec<MetaFile>,
    last_flush_ns: u64,
    closed: bool,
}

impl std::fmt::Debug for BagWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagWriter")
            .field("dir", &self.dir)
            .field("topics", &self.topics.len())
            .field("files", &self.files.len())
            .finish_non_exhaustive()
    }
}

impl BagWriter {
    /// A new bag in the directory `dir`, which must not exist yet (its parent must).
    /// Its files are called after the directory: `<dir name>_<i>.mcap`.
    ///
    /// # Errors
    /// [`BagError::Exists`], [`BagError::Io`], or a bad option.
    pub fn create(dir: &Path, opts: BagOptions) -> Result<Self, BagError> {
        opts.validate()?;
        if dir.exists() {
            return Err(BagError::Exists {
                path: dir.to_owned(),
            });
        }
        std::fs::create_dir(dir).map_err(BagError::io(dir))?;
        let stem = dir
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| "bag".into());
        Ok(Self {
            dir: dir.to_owned(),
            stem,
            opts,
            topics: Vec::new(),
            open: None,
            files: Vec::new(),
            last_flush_ns: 0,
            closed: false,
        })
    }

    /// Adds a topic of the table; its type must be one of the message types.
    ///
    /// # Errors
    /// [`BagError::UnknownType`].
    pub fn add_topic(&mut self, spec: &TopicSpec) -> Result<TopicId, BagError> {
        let description = teleop_msgs::description_of(spec.type_name)
            .ok_or_else(|| BagError::UnknownType(spec.type_name.to_owned()))?;
        self.topics.push(TopicEntry {
            name: format!("/{}", spec.name.trim_start_matches('/')),
            type_name: spec.type_name,
            type_hash: spec.type_hash,
            schema: description.full_definition(),
            qos: qos_profile(spec),
            qos_yaml: offered_qos_yaml(spec),
            count: 0,
        });
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Writes one sample: its CDR bytes as they travelled, when it was received
    /// (`log_time_ns`, ns since the epoch), its source timestamp and sequence number.
    ///
    /// # Errors
    /// [`BagError::UnknownTopic`], [`BagError::Closed`], or the file's errors.
    pub fn write(
        &mut self,
        topic: TopicId,
        log_time_ns: u64,
        publish_time_ns: u64,
        sequence: u32,
        payload: &[u8],
    ) -> Result<(), BagError> {
        if self.closed {
            return Err(BagError::Closed);
        }
        if topic.0 >= self.topics.len() {
            return Err(BagError::UnknownTopic(topic.0));
        }
        if self.split_due(log_time_ns) {
            self.finish_file()?;
        }
        if self.open.is_none() {
            self.open_file()?;
        }
        let path = self.dir.clone();
        let entry = &self.topics[topic.0];
        let Some(file) = self.open.as_mut() else {
            return Err(BagError::Closed);
        };
        let channel = match file.channels.get(&topic) {
            Some(id) => *id,
            None => {
                let schema = file
                    .writer
                    .add_schema(entry.type_name, "ros2msg", entry.schema.as_bytes())
                    .map_err(BagError::mcap(&path))?;
                let metadata = BTreeMap::from([
                    ("offered_qos_profiles".to_owned(), entry.qos_yaml.clone()),
                    ("topic_type_hash".to_owned(), entry.type_hash.to_owned()),
                ]);
                let id = file
                    .writer
                    .add_channel(schema, &entry.name, "cdr", &metadata)
                    .map_err(BagError::mcap(&path))?;
                file.channels.insert(topic, id);
                id
            }
        };
        file.writer
            .write_to_known_channel(
                &MessageHeader {
                    channel_id: channel,
                    sequence,
                    log_time: log_time_ns,
                    publish_time: publish_time_ns,
                },
                payload,
            )
            .map_err(BagError::mcap(&path))?;
        file.first_ns.get_or_insert(log_time_ns);
        file.last_ns = file.last_ns.max(log_time_ns);
        file.count += 1;
        self.topics[topic.0].count += 1;
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            clippy::cast_precision_loss
        )]
        let interval_ns = (self.opts.flush_interval_s * 1e9) as u64;
        if log_time_ns.saturating_sub(self.last_flush_ns) >= interval_ns {
            self.flush()?;
            self.last_flush_ns = log_time_ns;
        }
        Ok(())
    }

    /// Closes the open chunk and flushes the file: what was written so far survives a
    /// crash.
    ///
    /// # Errors
    /// The file's errors.
    pub fn flush(&mut self) -> Result<(), BagError> {
        if let Some(file) = self.open.as_mut() {
            file.writer.flush().map_err(BagError::mcap(&self.dir))?;
        }
        Ok(())
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.topics.iter().map(|t| t.count).sum()
    }

    /// Finishes the open file and writes `metadata.yaml`.
    ///
    /// # Errors
    /// The files' errors.
    pub fn close(mut self) -> Result<BagSummary, BagError> {
        self.finish_file()?;
        self.write_metadata()?;
        self.closed = true;
        Ok(BagSummary {
            dir: self.dir.clone(),
            files: self.files.iter().map(|f| f.name.clone()).collect(),
            messages: self.messages(),
            per_topic: self
                .topics
                .iter()
                .map(|t| (t.name.clone(), t.count))
                .collect(),
            first_ns: self.files.iter().filter_map(|f| f.first_ns).min(),
            last_ns: self.files.iter().map(|f| f.last_ns).max().unwrap_or(0),
        })
    }

    fn split_due(&mut self, log_time_ns: u64) -> bool {
        let (max_bytes, max_s) = (self.opts.max_file_bytes, self.opts.max_file_duration_s);
        let Some(file) = self.open.as_ref() else {
            return false;
        };
        let too_big = max_bytes.is_some_and(|b| file.bytes() >= b);
        #[allow(clippy::cast_precision_loss)]
        let too_long = match (max_s, file.first_ns) {
            (Some(s), Some(first)) => log_time_ns.saturating_sub(first) as f64 * 1e-9 >= s,
            _ => false,
        };
        too_big || too_long
    }

    fn open_file(&mut self) -> Result<(), BagError> {
        let name = format!("{}_{}.mcap", self.stem, self.files.len());
        let path = self.dir.join(&name);
        let f = File::create(&path).map_err(BagError::io(&path))?;
        let len = Arc::new(AtomicU64::new(0));
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("teleop-bag ", env!("CARGO_PKG_VERSION")))
            .compression(self.opts.compression.mcap())
            .chunk_size(Some(self.opts.chunk_bytes))
            .create(Counted {
                inner: BufWriter::new(f),
                pos: 0,
                len: Arc::clone(&len),
            })
            .map_err(BagError::mcap(&path))?;
        self.open = Some(OpenFile {
            writer,
            len,
            name,
            channels: BTreeMap::new(),
            first_ns: None,
            last_ns: 0,
            count: 0,
        });
        Ok(())
    }

    fn finish_file(&mut self) -> Result<(), BagError> {
        let Some(mut file) = self.open.take() else {
            return Ok(());
        };
        let path = self.dir.join(&file.name);
        file.writer.finish().map_err(BagError::mcap(&path))?;
        let mut inner = file.writer.into_inner();
        inner.flush().map_err(BagError::io(&path))?;
        inner
            .inner
            .get_ref()
            .sync_all()
            .map_err(BagError::io(&path))?;
        self.files.push(MetaFile {
            name: file.name,
            first_ns: file.first_ns,
            last_ns: file.last_ns,
            count: file.count,
        });
        // The metadata lists every finished file, so a bag cut short after a split
        // still opens in rosbag2's readers (without its last file).
        self.write_metadata()
    }

    fn write_metadata(&self) -> Result<(), BagError> {
        let topics: Vec<MetaTopic> = self
            .topics
            .iter()
            .map(|t| MetaTopic {
                name: t.name.clone(),
                type_name: t.type_name.to_owned(),
                type_hash: t.type_hash.to_owned(),
                offered_qos_profiles: serde_yaml::to_value(vec![t.qos.clone()])
                    .unwrap_or(serde_yaml::Value::Null),
                count: t.count,
            })
            .collect();
        write_metadata(&self.dir, &topics, &self.files)
    }
}

/// A topic as `metadata.yaml` lists it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct MetaTopic {
    pub name: String,
    pub type_name: String,
    pub type_hash: String,
    /// The list of offered profiles (rosbag2 version 9: a YAML list, not a string).
    pub offered_qos_profiles: serde_yaml::Value,
    pub count: u64,
}

/// A file as `metadata.yaml` lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct MetaFile {
    pub name: String,
    pub first_ns: Option<u64>,
    pub last_ns: u64,
    pub count: u64,
}

/// Writes `dir/metadata.yaml` (rosbag2 version 9) for these topics and files.
pub(crate) fn write_metadata(
    dir: &Path,
    topics: &[MetaTopic],
    files: &[MetaFile],
) -> Result<(), BagError> {
    let first = files.iter().filter_map(|f| f.first_ns).min();
    let last = files.iter().map(|f| f.last_ns).max().unwrap_or(0);
    let duration = |first: Option<u64>, last: u64| Nanoseconds {
        nanoseconds: first.map_or(0, |f| last.saturating_sub(f)),
    };
    let meta = MetadataFile {
        rosbag2_bagfile_information: Metadata {
            version: crate::METADATA_VERSION,
            storage_identifier: "mcap",
            duration: duration(first, last),
            starting_time: SinceEpoch {
                nanoseconds_since_epoch: first.unwrap_or(0),
            },
            message_count: files.iter().map(|f| f.count).sum(),
            topics_with_message_count: topics
                .iter()
                .map(|t| TopicWithCount {
                    topic_metadata: TopicMetadata {
                        name: t.name.clone(),
                        r#type: t.type_name.clone(),
                        serialization_format: "cdr",
                        offered_qos_profiles: t.offered_qos_profiles.clone(),
                        type_description_hash: t.type_hash.clone(),
                    },
                    message_count: t.count,
                })
                .collect(),
            // Chunks are compressed inside MCAP ("storage" compression): the files are
            // not compressed as wholes, which is what these two fields describe.
            compression_format: "",
            compression_mode: "",
            relative_file_paths: files.iter().map(|f| f.name.clone()).collect(),
            files: files
                .iter()
                .map(|f| FileMetadata {
                    path: f.name.clone(),
                    starting_time: SinceEpoch {
                        nanoseconds_since_epoch: f.first_ns.unwrap_or(0),
                    },
                    duration: duration(f.first_ns, f.last_ns),
                    message_count: f.count,
                })
                .collect(),
            custom_data: BTreeMap::from([(
                "recorded_by".to_owned(),
                concat!("teleop-bag ", env!("CARGO_PKG_VERSION")).to_owned(),
            )]),
            // The release whose formats the bag follows (RIHS01 type hashes, version-9
            // QoS), so its tools read it as one of theirs.
            ros_distro: "jazzy",
        },
    };
    let path = dir.join("metadata.yaml");
    let text = serde_yaml::to_string(&meta).map_err(|e| BagError::Metadata {
        path: path.clone(),
        message: e.to_string(),
    })?;
    // Written beside and renamed over: a reader never sees half a file.
    let tmp = dir.join(".metadata.yaml.tmp");
    std::fs::write(&tmp, text).map_err(BagError::io(&tmp))?;
    std::fs::rename(&tmp, &path).map_err(BagError::io(&path))
}

// rosbag2's metadata.yaml, version 9 (field names and nesting as rosbag2 writes them).

#[derive(Serialize)]
struct MetadataFile {
    rosbag2_bagfile_information: Metadata,
}

#[derive(Serialize)]
struct Metadata {
    version: u32,
    storage_identifier: &'static str,
    duration: Nanoseconds,
    starting_time: SinceEpoch,
    message_count: u64,
    topics_with_message_count: Vec<TopicWithCount>,
    compression_format: &'static str,
    compression_mode: &'static str,
    relative_file_paths: Vec<String>,
    files: Vec<FileMetadata>,
    custom_data: BTreeMap<String, String>,
    ros_distro: &'static str,
}

#[derive(Serialize)]
struct Nanoseconds {
    nanoseconds: u64,
}

#[derive(Serialize)]
struct SinceEpoch {
    nanoseconds_since_epoch: u64,
}

#[derive(Serialize)]
struct TopicWithCount {
    topic_metadata: TopicMetadata,
    message_count: u64,
}

#[derive(Serialize)]
struct TopicMetadata {
    name: String,
    r#type: String,
    serialization_format: &'static str,
    offered_qos_profiles: serde_yaml::Value,
    type_description_hash: String,
}

#[derive(Serialize)]
struct FileMetadata {
    path: String,
    starting_time: SinceEpoch,
    duration: Nanoseconds,
    message_count: u64,
}
