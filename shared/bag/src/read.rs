//! Reading the messages of MCAP bytes with the memory a reader may take bounded by the
//! bytes themselves.
//!
//! The `mcap` crate's `MessageStream` trusts two size fields before it has the data they
//! describe: a chunk's uncompressed size, and the length of each record inside a
//! compressed chunk; it reserves that much memory first. One changed field in a small
//! file then asks for exabytes and aborts the process (found by the hostile-input runs,
//! `tests/hostile_inputs.rs`). [`messages`] reads with the crate's sans-io reader
//! instead: [`crate::check_chunk_sizes`] bounds every chunk's uncompressed size by its
//! compressed size first, and no record may be longer than the largest uncompressed
//! size that check let through (or the file, if larger), so what one read may reserve is
//! bounded by [`crate::MAX_CHUNK_RATIO`] times the input.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::info::chunk_limits;

/// A schema of the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SchemaInfo {
    pub id: u16,
    pub name: String,
    pub encoding: String,
    pub data: Vec<u8>,
}

/// A channel of the file, with its schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    pub id: u16,
    pub topic: String,
    pub message_encoding: String,
    pub metadata: BTreeMap<String, String>,
    pub schema: Option<Arc<SchemaInfo>>,
}

/// One message as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredMessage {
    pub channel: Arc<ChannelInfo>,
    pub sequence: u32,
    pub log_time: u64,
    pub publish_time: u64,
    pub data: Vec<u8>,
}

/// The messages of MCAP bytes, in file order; see the module's documentation.
pub struct Messages<'a> {
    buf: &'a [u8],
    at: usize,
    reader: LinearReader,
    schemas: HashMap<u16, Arc<SchemaInfo>>,
    channels: HashMap<u16, Arc<ChannelInfo>>,
    done: bool,
}

impl std::fmt::Debug for Messages<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Messages")
            .field("bytes", &self.buf.len())
            .field("at", &self.at)
            .finish_non_exhaustive()
    }
}

/// Why reading stopped (the file is cut short or malformed there).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ReadError(pub String);

/// The messages of the MCAP bytes `buf` (a whole file, or one cut short).
///
/// # Errors
/// A chunk that claims an implausible uncompressed size ([`crate::check_chunk_sizes`]).
pub fn messages(buf: &[u8]) -> Result<Messages<'_>, ReadError> {
    let largest_chunk = chunk_limits(buf).map_err(ReadError)?;
    let limit = usize::try_from(largest_chunk)
        .unwrap_or(usize::MAX)
        .max(buf.len());
    Ok(Messages {
        buf,
        at: 0,
        reader: LinearReader::new_with_options(
            LinearReaderOptions::default().with_record_length_limit(limit),
        ),
        schemas: HashMap::new(),
        channels: HashMap::new(),
        done: false,
    })
}

impl Iterator for Messages<'_> {
    type Item = Result<StoredMessage, ReadError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            let (opcode, data) = match self.reader.next_event()? {
                Ok(LinearReadEvent::ReadRequest(n)) => {
                    // At most what is left: the request is a hint, and a hostile one may
                    // be huge.
                    let rest = &self.buf[self.at..];
                    let n = n.min(rest.len());
                    let into = self.reader.insert(n);
                    into[..n].copy_from_slice(&rest[..n]);
                    self.reader.notify_read(n);
                    self.at += n;
                    continue;
                }
                Ok(LinearReadEvent::Record { data, opcode }) => (opcode, data),
                Err(e) => {
                    self.done = true;
                    return Some(Err(ReadError(e.to_string())));
                }
            };
            let record = match parse(opcode, data) {
                Ok(r) => r,
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            };
            match record {
                Parsed::Schema(schema) => {
                    self.schemas.insert(schema.id, Arc::new(schema));
                }
                Parsed::Channel {
                    id,
                    schema_id,
                    topic,
                    message_encoding,
                    metadata,
                } => {
                    let schema = self.schemas.get(&schema_id).cloned();
                    if schema_id != 0 && schema.is_none() {
                        self.done = true;
                        return Some(Err(ReadError(format!(
                            "channel {id} names schema {schema_id} before it is defined"
                        ))));
                    }
                    self.channels.insert(
                        id,
                        Arc::new(ChannelInfo {
                            id,
                            topic,
                            message_encoding,
                            metadata,
                            schema,
                        }),
                    );
                }
                Parsed::Message {
                    channel_id,
                    sequence,
                    log_time,
                    publish_time,
                    data,
                } => {
                    let Some(channel) = self.channels.get(&channel_id) else {
                        self.done = true;
                        return Some(Err(ReadError(format!(
                            "a message on channel {channel_id} before the channel is defined"
                        ))));
                    };
                    return Some(Ok(StoredMessage {
                        channel: Arc::clone(channel),
                        sequence,
                        log_time,
                        publish_time,
                        data,
                    }));
                }
                Parsed::Footer => {
                    self.done = true;
                    return None;
                }
                Parsed::Other => {}
            }
        }
    }
}

/// The records [`Messages`] uses, parsed with every length checked against the record's
/// bytes before anything is allocated (the `mcap` crate's record parser reserves what a
/// string's length field claims, up to 4 GiB, before reading it).
enum Parsed {
    Schema(SchemaInfo),
    Channel {
        id: u16,
        schema_id: u16,
        topic: String,
        message_encoding: String,
        metadata: BTreeMap<String, String>,
    },
    Message {
        channel_id: u16,
        sequence: u32,
        log_time: u64,
        publish_time: u64,
        data: Vec<u8>,
    },
    Footer,
    Other,
}

/// A record's body, read front to back; every read checks the bytes are there.
struct Body<'a> {
    bytes: &'a [u8],
    what: &'static str,
}

impl<'a> Body<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], ReadError> {
        if n > self.bytes.len() {
            return Err(ReadError(format!(
                "{} record: a field of {n} bytes with {} left",
                self.what,
                self.bytes.len()
            )));
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], ReadError> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N)?);
        Ok(out)
    }

    fn u16(&mut self) -> Result<u16, ReadError> {
        self.array().map(u16::from_le_bytes)
    }

    fn u32(&mut self) -> Result<u32, ReadError> {
        self.array().map(u32::from_le_bytes)
    }

    fn u64(&mut self) -> Result<u64, ReadError> {
        self.array().map(u64::from_le_bytes)
    }

    fn prefixed(&mut self) -> Result<&'a [u8], ReadError> {
        let n = usize::try_from(self.u32()?).unwrap_or(usize::MAX);
        self.take(n)
    }

    fn string(&mut self) -> Result<String, ReadError> {
        let what = self.what;
        std::str::from_utf8(self.prefixed()?)
            .map(str::to_owned)
            .map_err(|_| ReadError(format!("{what} record: a string that is not UTF-8")))
    }
}

fn parse(opcode: u8, data: &[u8]) -> Result<Parsed, ReadError> {
    const FOOTER: u8 = 0x02;
    const SCHEMA: u8 = 0x03;
    const CHANNEL: u8 = 0x04;
    const MESSAGE: u8 = 0x05;
    match opcode {
        SCHEMA => {
            let mut b = Body {
                bytes: data,
                what: "schema",
            };
            Ok(Parsed::Schema(SchemaInfo {
                id: b.u16()?,
                name: b.string()?,
                encoding: b.string()?,
                data: b.prefixed()?.to_vec(),
            }))
        }
        CHANNEL => {
            let mut b = Body {
                bytes: data,
                what: "channel",
            };
            let (id, schema_id) = (b.u16()?, b.u16()?);
            let (topic, message_encoding) = (b.string()?, b.string()?);
            let mut map = Body {
                bytes: b.prefixed()?,
                what: "channel metadata",
            };
            let mut metadata = BTreeMap::new();
            while !map.bytes.is_empty() {
                let k = map.string()?;
                metadata.insert(k, map.string()?);
            }
            Ok(Parsed::Channel {
                id,
                schema_id,
                topic,
                message_encoding,
                metadata,
            })
        }
        MESSAGE => {
            let mut b = Body {
                bytes: data,
                what: "message",
            };
            Ok(Parsed::Message {
                channel_id: b.u16()?,
                sequence: b.u32()?,
                log_time: b.u64()?,
                publish_time: b.u64()?,
                data: b.bytes.to_vec(),
            })
        }
        FOOTER => Ok(Parsed::Footer),
        _ => Ok(Parsed::Other),
    }
}

/// The profile of the header record that MCAP bytes start with (after the magic).
///
/// # Errors
/// No magic, no header record first, or a malformed one.
pub(crate) fn header_profile(buf: &[u8]) -> Result<String, ReadError> {
    const HEADER: u8 = 0x01;
    let rest = buf
        .strip_prefix(mcap::MAGIC)
        .ok_or_else(|| ReadError("not MCAP: the file does not start with its magic".into()))?;
    let mut b = Body {
        bytes: rest,
        what: "header",
    };
    let [opcode] = b.array::<1>()?;
    if opcode != HEADER {
        return Err(ReadError(format!(
            "the first record is opcode {opcode:#04x}, not a header"
        )));
    }
    let len = usize::try_from(b.u64()?).unwrap_or(usize::MAX);
    let mut body = Body {
        bytes: b.take(len)?,
        what: "header",
    };
    body.string()
}
