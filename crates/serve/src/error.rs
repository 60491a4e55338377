//! Errors of starting the server. Each names the path or address it concerns; nothing a
//! request can do reaches here (requests get HTTP statuses, never a `ServeError`).

use std::net::SocketAddr;
use std::path::PathBuf;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ServeError {
    /// No store argument was given.
    #[error("no stores to serve: give .pointlet files or folders holding them")]
    NothingGiven,
    /// A given path cannot be read (missing, no permission, …).
    #[error("{}: {what}: {cause}", path.display())]
    Io {
        path: PathBuf,
        what: &'static str,
        cause: std::io::Error,
    },
    /// A given file is not named `NAME.pointlet`, or a given path is neither file nor folder.
    #[error("{}: {message}", path.display())]
    NotServable { path: PathBuf, message: String },
    /// A `.pointlet` file that the store reader refuses (its error names the file).
    #[error("not a valid store: {0}")]
    Store(#[from] pointlet_store::StoreError),
    /// A given folder holds no store.
    #[error("{}: the folder holds no .pointlet stores", path.display())]
    EmptyFolder { path: PathBuf },
    /// Two different files would be served under one name.
    #[error(
        "two stores would be served as {name}.pointlet: {} and {} (rename one, or serve them separately)",
        first.display(),
        second.display()
    )]
    DuplicateName {
        name: String,
        first: PathBuf,
        second: PathBuf,
    },
    /// The viewer folder cannot be served.
    #[error("viewer folder {}: {message}", path.display())]
    Viewer { path: PathBuf, message: String },
    /// The address cannot be bound (in use, not local, no permission).
    #[error("cannot listen on {addr}: {cause}")]
    Bind {
        addr: SocketAddr,
        cause: std::io::Error,
    },
    /// The async runtime or the server thread could not start, or the server failed.
    #[error("{what}: {cause}")]
    Runtime {
        what: &'static str,
        cause: std::io::Error,
    },
    /// The server thread panicked.
    #[error("the server thread stopped unexpectedly")]
    ThreadPanicked,
}

impl ServeError {
    pub(crate) fn io(path: impl Into<PathBuf>, what: &'static str, cause: std::io::Error) -> Self {
        ServeError::Io {
            path: path.into(),
            what,
            cause,
        }
    }

    pub(crate) fn not_servable(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        ServeError::NotServable {
            path: path.into(),
            message: message.into(),
        }
    }
}
