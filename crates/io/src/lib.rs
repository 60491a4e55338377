//! Readers and writers of point files, and the synthetic scene generator.
//!
//! Every reader streams: [`PointReader::read_batch`] hands out structure-of-arrays batches and
//! no reader holds a whole file in memory unless the format forces it. Coordinates stay f64.

pub mod generate;
pub mod las;
pub mod ply;
pub mod writer;
pub mod xyz;

use pointlet_core::{PointBatch, SourceMeta};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// What can go wrong reading or writing a point file. Every variant names the file.
#[derive(Debug, Error)]
pub enum IoError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not what it claims to be, or lies about itself (bad header, truncated, ...).
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    /// A format or feature this build does not read or write.
    #[error("{}: {message}", path.display())]
    Unsupported { path: PathBuf, message: String },
}

impl IoError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        IoError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub fn unsupported(path: &Path, message: impl Into<String>) -> Self {
        IoError::Unsupported {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

/// A streaming source of points.
pub trait PointReader: Send {
    /// The file being read (or a descriptive pseudo-path for generated data).
    fn path(&self) -> &Path;
    /// What the header says; available before the first batch.
    fn meta(&self) -> &SourceMeta;
    /// The next batch of at most `max` points; `None` once every point was read.
    /// A reader that finds fewer points than its header claims returns an error, not `None`.
    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError>;
}
