//! Errors of the store. Every variant that concerns a file names it.

use std::path::{Path, PathBuf};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum StoreError {
    /// The operating system refused an operation on a file.
    #[error("{}: {what}: {cause}", path.display())]
    Io {
        path: PathBuf,
        what: String,
        cause: std::io::Error,
    },
    /// The file is not a pointlet store, or it is damaged or truncated.
    #[error("{}: damaged or not a pointlet store: {message}", path.display())]
    Damaged { path: PathBuf, message: String },
    /// The points or settings given to the builder cannot make a store (names the output).
    #[error("{}: {message}", path.display())]
    Build { path: PathBuf, message: String },
    /// The input headers cannot be merged into one store header.
    #[error("{message}")]
    Meta { message: String },
    /// An input could not be read while building (the reader's error names the file).
    #[error("{0}")]
    Input(#[source] pointlet_core::PartError),
    /// A read asked for something the store does not hold (pointlet index, range, stream).
    #[error("{}: {message}", path.display())]
    Request { path: PathBuf, message: String },
    /// The store's bytes could not be read (a local file, or a remote object: the network,
    /// the server, a store replaced while being read).
    #[error("{}: {what}: {cause}", path.display())]
    Source {
        path: PathBuf,
        what: String,
        cause: crate::source::SourceError,
    },
}

impl StoreError {
    pub(crate) fn io(path: &Path, what: impl Into<String>, cause: std::io::Error) -> Self {
        StoreError::Io {
            path: path.to_path_buf(),
            what: what.into(),
            cause,
        }
    }

    pub(crate) fn damaged(path: &Path, message: impl Into<String>) -> Self {
        StoreError::Damaged {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub(crate) fn build(path: &Path, message: impl Into<String>) -> Self {
        StoreError::Build {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub(crate) fn meta(message: impl Into<String>) -> Self {
        StoreError::Meta {
            message: message.into(),
        }
    }

    pub(crate) fn request(path: &Path, message: impl Into<String>) -> Self {
        StoreError::Request {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
