//! Type descriptions in the shape of ROS 2's `type_description_interfaces`, used for two
//! things:
//!
//! * the RIHS01 type hash (REP 2011) that rmw_zenoh puts in every data key, and
//! * a schema-guided pre-check of CDR bytes that runs before the `cdr` crate decodes
//!   them, so a hostile length field can neither make the decoder allocate gigabytes nor
//!   read past the end of the payload.
//!
//! The hash is SHA-256 over a JSON rendering of the type and of every type it refers to
//! (sorted by name), with default values left out and `", "` / `": "` as separators, as
//! `rosidl_generator_type_description` computes it.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use sha2::{Digest, Sha256};

/// Primitive or nested element type of a field (`type_description_interfaces/FieldType`).
#[derive(Debug, Clone, Copy)]
pub enum BaseType {
    /// A nested message type, given by its description.
    Nested(fn() -> &'static MsgDescription),
    Int8,
    Uint8,
    Int16,
    Uint16,
    Int32,
    Uint32,
    Int64,
    Uint64,
    Float32,
    Float64,
    Bool,
    /// Unbounded `string`.
    String,
}

impl BaseType {
    /// The REP 2011 type id of a single element of this type.
    pub fn type_id(self) -> u8 {
        match self {
            BaseType::Nested(_) => 1,
            BaseType::Int8 => 2,
            BaseType::Uint8 => 3,
            BaseType::Int16 => 4,
            BaseType::Uint16 => 5,
            BaseType::Int32 => 6,
            BaseType::Uint32 => 7,
            BaseType::Int64 => 8,
            BaseType::Uint64 => 9,
            BaseType::Float32 => 10,
            BaseType::Float64 => 11,
            BaseType::Bool => 15,
            BaseType::String => 17,
        }
    }

    /// Size in bytes of a primitive on the wire (also its CDR alignment); `None` for
    /// strings and nested types.
    fn primitive_size(self) -> Option<usize> {
        match self {
            BaseType::Int8 | BaseType::Uint8 | BaseType::Bool => Some(1),
            BaseType::Int16 | BaseType::Uint16 => Some(2),
            BaseType::Int32 | BaseType::Uint32 | BaseType::Float32 => Some(4),
            BaseType::Int64 | BaseType::Uint64 | BaseType::Float64 => Some(8),
            BaseType::String | BaseType::Nested(_) => None,
        }
    }
}

/// How many elements a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arity {
    /// One element.
    Single,
    /// A fixed-size array `T[N]`.
    Array(u32),
    /// An unbounded sequence `T[]`.
    Sequence,
}

/// One field of a message.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub name: &'static str,
    pub base: BaseType,
    pub arity: Arity,
}

impl Field {
    pub const fn new(name: &'static str, base: BaseType) -> Self {
        Self {
            name,
            base,
            arity: Arity::Single,
        }
    }
    pub const fn seq(name: &'static str, base: BaseType) -> Self {
        Self {
            name,
            base,
            arity: Arity::Sequence,
        }
    }
    pub const fn array(name: &'static str, base: BaseType, len: u32) -> Self {
        Self {
            name,
            base,
            arity: Arity::Array(len),
        }
    }

    fn type_id(&self) -> u32 {
        let base = u32::from(self.base.type_id());
        match self.arity {
            Arity::Single => base,
            Arity::Array(_) => base + 48,
            Arity::Sequence => base + 144,
        }
    }

    fn capacity(&self) -> u32 {
        match self.arity {
            Arity::Array(n) => n,
            _ => 0,
        }
    }
}

/// Description of a message type: its full ROS 2 name and its fields, in order.
#[derive(Debug)]
pub struct MsgDescription {
    /// e.g. `sensor_msgs/msg/JointState`.
    pub type_name: &'static str,
    pub fields: &'static [Field],
}

impl MsgDescription {
    /// All message types this one refers to, directly or not, sorted by name.
    pub fn referenced(&'static self) -> Vec<&'static MsgDescription> {
        let mut found: BTreeMap<&'static str, &'static MsgDescription> = BTreeMap::new();
        let mut stack: Vec<&'static MsgDescription> = vec![self];
        while let Some(d) = stack.pop() {
            for f in d.fields {
                if let BaseType::Nested(get) = f.base {
                    let nested = get();
                    if found.insert(nested.type_name, nested).is_none() {
                        stack.push(nested);
                    }
                }
            }
        }
        found.into_values().collect()
    }

    /// The JSON text that REP 2011 hashes (no default values, `", "`/`": "` separators).
    pub fn hashable_json(&'static self) -> String {
        let mut out = String::from("{\"type_description\": ");
        write_type(&mut out, self);
        out.push_str(", \"referenced_type_descriptions\": [");
        for (i, r) in self.referenced().into_iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            write_type(&mut out, r);
        }
        out.push_str("]}");
        out
    }

    /// `RIHS01_<sha256 hex>`: the type hash rmw_zenoh puts in data keys.
    pub fn type_hash(&'static self) -> String {
        let digest = Sha256::digest(self.hashable_json().as_bytes());
        format!("RIHS01_{}", hex::encode(digest))
    }

    /// The DDS-mangled name rmw_zenoh uses in keys, e.g.
    /// `sensor_msgs::msg::dds_::JointState_`.
    pub fn dds_type_name(&self) -> String {
        let mut parts = self.type_name.split('/');
        let pkg = parts.next().unwrap_or_default();
        let _msg = parts.next();
        let name = parts.next().unwrap_or_default();
        format!("{pkg}::msg::dds_::{name}_")
    }

    /// The `.msg` text of this type (fields only; comments and constants live in the
    /// `.msg` files under `shared/msgs/msg`).
    pub fn msg_text(&self) -> String {
        let mut out = String::new();
        for f in self.fields {
            let base = match f.base {
                BaseType::Nested(get) => {
                    let n = get().type_name;
                    n.replace("/msg/", "/")
                }
                BaseType::Int8 => "int8".into(),
                BaseType::Uint8 => "uint8".into(),
                BaseType::Int16 => "int16".into(),
                BaseType::Uint16 => "uint16".into(),
                BaseType::Int32 => "int32".into(),
                BaseType::Uint32 => "uint32".into(),
                BaseType::Int64 => "int64".into(),
                BaseType::Uint64 => "uint64".into(),
                BaseType::Float32 => "float32".into(),
                BaseType::Float64 => "float64".into(),
                BaseType::Bool => "bool".into(),
                BaseType::String => "string".into(),
            };
            let suffix = match f.arity {
                Arity::Single => String::new(),
                Arity::Array(n) => format!("[{n}]"),
                Arity::Sequence => "[]".into(),
            };
            let _ = writeln!(out, "{base}{suffix} {}", f.name);
        }
        out
    }
}

impl MsgDescription {
    /// The type's definition as its package ships it: the project's own types from
    /// their `.msg` files (comments, constants and defaults included), the standard
    /// ones from their fields ([`MsgDescription::msg_text`]).
    pub fn definition(&self) -> String {
        match PROJECT_MSG_FILES.iter().find(|(n, _)| *n == self.type_name) {
            Some((_, text)) => (*text).to_owned(),
            None => self.msg_text(),
        }
    }

    /// The full definition rosbag2 stores in MCAP (`ros2msg` schema encoding) and
    /// ROS 1 bags stored before it: this type's definition, then for each type it
    /// refers to, a line of 80 `=`, `MSG: pkg/Type` and that type's definition.
    pub fn full_definition(&'static self) -> String {
        let mut out = self.definition();
        for r in self.referenced() {
            if !out.ends_with('\n') {
                out.push('\n');
            }
            let _ = write!(
                out,
                "{}\nMSG: {}\n{}",
                "=".repeat(80),
                r.type_name.replace("/msg/", "/"),
                r.definition()
            );
        }
        out
    }
}

/// The project's `.msg` files (`shared/msgs/msg/`), by type name.
const PROJECT_MSG_FILES: &[(&str, &str)] = &[
    (
        "teleop_msgs/msg/OperatorInput",
        include_str!("../msg/OperatorInput.msg"),
    ),
    (
        "teleop_msgs/msg/FingertipPressures",
        include_str!("../msg/FingertipPressures.msg"),
    ),
    (
        "teleop_msgs/msg/JointCommand",
        include_str!("../msg/JointCommand.msg"),
    ),
    (
        "teleop_msgs/msg/NodeStatus",
        include_str!("../msg/NodeStatus.msg"),
    ),
];

fn write_type(out: &mut String, d: &'static MsgDescription) {
    let _ = write!(out, "{{\"type_name\": \"{}\", \"fields\": [", d.type_name);
    for (i, f) in d.fields.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        let nested = match f.base {
            BaseType::Nested(get) => get().type_name,
            _ => "",
        };
        let _ = write!(
            out,
            "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": 0, \"nested_type_name\": \"{}\"}}}}",
            f.name,
            f.type_id(),
            f.capacity(),
            nested
        );
    }
    out.push_str("]}");
}

/// Why a CDR payload was refused before decoding.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum WireError {
    #[error("payload of {len} bytes is shorter than the 4-byte CDR encapsulation header")]
    NoHeader { len: usize },
    #[error("unsupported CDR encapsulation {0:#06x} (expected CDR_BE 0x0000 or CDR_LE 0x0001)")]
    Encapsulation(u16),
    #[error("field `{field}` needs {needed} bytes at offset {offset}, only {available} left")]
    Truncated {
        field: String,
        offset: usize,
        needed: u64,
        available: usize,
    },
    #[error("field `{field}`: boolean byte {value} is neither 0 nor 1")]
    BadBool { field: String, value: u8 },
    /// A non-empty string whose last byte (at `offset`, header included) is not the NUL
    /// terminator CDR requires. Refused because the decoder would silently drop that
    /// byte, turning `"abc"` into `"ab"`.
    #[error("field `{field}`: string ending at offset {offset} is not NUL-terminated")]
    UnterminatedString { field: String, offset: usize },
}

/// Walks `bytes` (header included) with `desc` as the schema and checks that every
/// length field fits in what is left, before any decoder allocates for it; also that
/// booleans are 0 or 1 and non-empty strings end in NUL.
///
/// # Errors
/// [`WireError`] naming the first field that does not fit or is malformed.
pub fn check_wire(desc: &'static MsgDescription, bytes: &[u8]) -> Result<(), WireError> {
    if bytes.len() < 4 {
        return Err(WireError::NoHeader { len: bytes.len() });
    }
    let little = match (bytes[0], bytes[1]) {
        (0, 0) => false,
        (0, 1) => true,
        (a, b) => return Err(WireError::Encapsulation(u16::from_be_bytes([a, b]))),
    };
    let mut w = Walker {
        data: &bytes[4..],
        pos: 0,
        little,
        path: Vec::with_capacity(8),
    };
    w.path.push(desc.type_name);
    w.message(desc)
}

/// Schema-guided cursor over a CDR payload. `path` is the stack of field names being
/// visited; it is joined into a text only when an error is reported, so the happy path
/// does not allocate per field.
struct Walker<'a> {
    data: &'a [u8],
    pos: usize,
    little: bool,
    path: Vec<&'static str>,
}

impl Walker<'_> {
    /// Dotted name of the field being visited, e.g. `sensor_msgs/msg/JointState.name`.
    fn field(&self) -> String {
        self.path.join(".")
    }

    fn take(&mut self, align: usize, n: u64) -> Result<usize, WireError> {
        let pad = (align - self.pos % align) % align;
        let available = self.data.len().saturating_sub(self.pos);
        let needed = n + pad as u64;
        if needed > available as u64 {
            return Err(WireError::Truncated {
                field: self.field(),
                offset: self.pos + 4,
                needed,
                available,
            });
        }
        let start = self.pos + pad;
        // `needed <= available <= usize::MAX`, so the cast is exact.
        self.pos += needed as usize;
        Ok(start)
    }

    fn u32(&mut self) -> Result<u32, WireError> {
        let at = self.take(4, 4)?;
        let raw = [
            self.data[at],
            self.data[at + 1],
            self.data[at + 2],
            self.data[at + 3],
        ];
        Ok(if self.little {
            u32::from_le_bytes(raw)
        } else {
            u32::from_be_bytes(raw)
        })
    }

    fn message(&mut self, desc: &'static MsgDescription) -> Result<(), WireError> {
        for f in desc.fields {
            self.path.push(f.name);
            match f.arity {
                Arity::Single => self.element(f.base)?,
                Arity::Array(n) => self.elements(f.base, n)?,
                Arity::Sequence => {
                    let n = self.u32()?;
                    self.elements(f.base, n)?;
                }
            }
            self.path.pop();
        }
        Ok(())
    }

    fn elements(&mut self, base: BaseType, n: u32) -> Result<(), WireError> {
        match base.primitive_size() {
            Some(size) if !matches!(base, BaseType::Bool) => {
                if n > 0 {
                    self.take(size, u64::from(n) * size as u64)?;
                }
                Ok(())
            }
            _ => {
                // Strings, booleans and nested messages each take at least one byte, so
                // this loop ends within `data.len()` iterations whatever `n` claims.
                for _ in 0..n {
                    self.element(base)?;
                }
                Ok(())
            }
        }
    }

    fn element(&mut self, base: BaseType) -> Result<(), WireError> {
        match base {
            BaseType::Nested(get) => self.message(get()),
            BaseType::String => {
                // Length includes the terminating NUL. A length of 0 (no terminator at
                // all) decodes as "" and is accepted; anything longer must end in NUL.
                let len = self.u32()?;
                let at = self.take(1, u64::from(len))?;
                if len > 0 {
                    // `take` succeeded, so `at + len <= data.len()` and the cast is exact.
                    let last = at + len as usize - 1;
                    if self.data[last] != 0 {
                        return Err(WireError::UnterminatedString {
                            field: self.field(),
                            offset: last + 4,
                        });
                    }
                }
                Ok(())
            }
            BaseType::Bool => {
                let at = self.take(1, 1)?;
                match self.data[at] {
                    0 | 1 => Ok(()),
                    value => Err(WireError::BadBool {
                        field: self.field(),
                        value,
                    }),
                }
            }
            other => {
                let size = other.primitive_size().unwrap_or(1);
                self.take(size, size as u64).map(|_| ())
            }
        }
    }
}
