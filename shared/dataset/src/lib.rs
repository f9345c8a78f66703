//! Robot-learning datasets from the system's recordings.
//!
//! [`lerobot::export_lerobot`] turns bags (`teleop record`) into a LeRobotDataset
//! v3.0 (`teleop export lerobot`): parquet tables ([`table`]), the camera views as
//! MJPEG MP4 files ([`mp4`]), every frame aligned to its messages' source stamps
//! ([`align`]).

pub mod align;
pub mod jpeg;
pub mod lerobot;
pub mod mp4;
pub mod table;

pub use lerobot::{ActionSource, EpisodeSource, ExportOptions, ExportSummary, export_lerobot};

use std::path::Path;

/// What went wrong, naming the file, input or option.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("bag: {0}")]
    Bag(String),
    #[error("JPEG: {0}")]
    Jpeg(String),
    #[error("video: {0}")]
    Video(String),
    #[error("parquet: {0}")]
    Parquet(String),
    #[error("export: {0}")]
    Config(String),
}

impl DatasetError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.display().to_string(),
            source,
        }
    }
}
