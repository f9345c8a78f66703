//! The 33-byte sample attachment of rmw_zenoh: sequence number, source timestamp and
//! publisher GID, laid out as zenoh-ext's serializer writes them.
//!
//! | bytes  | content                                        |
//! |--------|------------------------------------------------|
//! | 0..8   | `i64` LE sequence number (starts at 1)          |
//! | 8..16  | `i64` LE source timestamp, ns since Unix epoch |
//! | 16     | VarInt length of the GID: `0x10`               |
//! | 17..33 | 16-byte publisher GID                          |

/// Length of the attachment on the wire.
pub const ATTACHMENT_LEN: usize = 33;

/// Metadata carried by every sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Attachment {
    pub sequence: i64,
    pub source_timestamp_ns: i64,
    pub gid: [u8; 16],
}

/// Why an attachment could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum AttachmentError {
    #[error("sample has no attachment (rmw_zenoh requires one)")]
    Missing,
    #[error("attachment is {0} bytes, expected {ATTACHMENT_LEN}")]
    Length(usize),
    #[error("attachment GID length byte is {0:#04x}, expected 0x10")]
    GidLength(u8),
}

impl Attachment {
    pub fn to_bytes(&self) -> [u8; ATTACHMENT_LEN] {
        let mut out = [0u8; ATTACHMENT_LEN];
        out[0..8].copy_from_slice(&self.sequence.to_le_bytes());
        out[8..16].copy_from_slice(&self.source_timestamp_ns.to_le_bytes());
        out[16] = 16;
        out[17..33].copy_from_slice(&self.gid);
        out
    }

    /// # Errors
    /// [`AttachmentError`] if the length or the GID length byte is wrong.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, AttachmentError> {
        let b: &[u8; ATTACHMENT_LEN] = bytes
            .try_into()
            .map_err(|_| AttachmentError::Length(bytes.len()))?;
        if b[16] != 16 {
            return Err(AttachmentError::GidLength(b[16]));
        }
        let mut seq = [0u8; 8];
        seq.copy_from_slice(&b[0..8]);
        let mut ts = [0u8; 8];
        ts.copy_from_slice(&b[8..16]);
        let mut gid = [0u8; 16];
        gid.copy_from_slice(&b[17..33]);
        Ok(Self {
            sequence: i64::from_le_bytes(seq),
            source_timestamp_ns: i64::from_le_bytes(ts),
            gid,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_rmw_zenoh() {
        let a = Attachment {
            sequence: 0x0102,
            source_timestamp_ns: 1_700_000_000_123_456_789,
            gid: [0xAB; 16],
        };
        let b = a.to_bytes();
        assert_eq!(&b[0..8], &[0x02, 0x01, 0, 0, 0, 0, 0, 0]);
        assert_eq!(&b[8..16], &1_700_000_000_123_456_789i64.to_le_bytes());
        assert_eq!(b[16], 0x10);
        assert_eq!(&b[17..], &[0xAB; 16]);
        assert_eq!(Attachment::from_bytes(&b), Ok(a));
    }

    #[test]
    fn rejects_wrong_lengths() {
        assert_eq!(
            Attachment::from_bytes(&[0; 32]),
            Err(AttachmentError::Length(32))
        );
        let mut b = [0u8; 33];
        b[16] = 15;
        assert_eq!(
            Attachment::from_bytes(&b),
            Err(AttachmentError::GidLength(15))
        );
    }
}
