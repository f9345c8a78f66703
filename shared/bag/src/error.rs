use std::path::PathBuf;

/// What went wrong with a bag.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: MCAP: {message}")]
    Mcap { path: PathBuf, message: String },
    #[error("{path}: metadata.yaml: {message}")]
    Metadata { path: PathBuf, message: String },
    #[error("topic type `{0}` is none of the message types")]
    UnknownType(String),
    #[error("topic id {0} was not added to this bag")]
    UnknownTopic(usize),
    #[error("{path} already exists: a bag is never written over")]
    Exists { path: PathBuf },
    #[error("{path}: no MCAP file in it")]
    Empty { path: PathBuf },
    #[error("invalid bag option: {0}")]
    Option(String),
    #[error("the bag is closed")]
    Closed,
}

impl BagError {
    pub(crate) fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> Self {
        let path = path.into();
        move |source| BagError::Io { path, source }
    }

    pub(crate) fn read(path: impl Into<PathBuf>) -> impl FnOnce(crate::ReadError) -> Self {
        let path = path.into();
        move |e| BagError::Mcap { path, message: e.0 }
    }

    pub(crate) fn mcap(path: impl Into<PathBuf>) -> impl FnOnce(mcap::McapError) -> Self {
        let path = path.into();
        move |e| BagError::Mcap {
            path,
            message: e.to_string(),
        }
    }
}
