//! Where a store's bytes come from: a local file (positioned reads), or an object over HTTP(S)
//! or in S3 (remote.rs: byte ranges). The reader and the loader threads above it only ever ask
//! for a range of bytes, and never know which it is.

use crate::pio;
use std::fs::File;
use std::path::Path;

/// Random access to the bytes of one store.
pub trait ByteSource: Send + Sync + std::fmt::Debug {
    /// Bytes in the store.
    fn size(&self) -> u64;

    /// Fills `buf` with the bytes at `offset..offset + buf.len()`.
    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> Result<(), SourceError>;

    /// Fills each buffer with the bytes at its offset; remote sources fetch them with several
    /// requests in flight, nearby ranges joined.
    fn read_ranges(&self, reads: &mut [(u64, &mut [u8])]) -> Result<(), SourceError> {
        for (offset, buf) in reads.iter_mut() {
            self.read_exact_at(buf, *offset)?;
        }
        Ok(())
    }
}

/// A source could not deliver bytes.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Fewer bytes than asked for exist.
    #[error("the store ends early (truncated?)")]
    Truncated,
    #[error("not found")]
    NotFound,
    #[error("access denied")]
    Denied,
    /// The object's ETag differs from the one it had when opened.
    #[error("the store changed while being read (it was replaced on the server)")]
    Changed,
    /// What the server or the network said, after retries.
    #[error("{0}")]
    Remote(String),
}

/// A store on the local file system.
#[derive(Debug)]
pub struct LocalFile {
    file: File,
    len: u64,
}

impl LocalFile {
    pub fn open(path: &Path) -> Result<Self, SourceError> {
        let file = File::open(path)?;
        let len = file.metadata()?.len();
        Ok(Self { file, len })
    }
}

impl ByteSource for LocalFile {
    fn size(&self) -> u64 {
        self.len
    }

    fn read_exact_at(&self, buf: &mut [u8], offset: u64) -> Result<(), SourceError> {
        pio::read_exact_at(&self.file, buf, offset).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                SourceError::Truncated
            } else {
                SourceError::Io(e)
            }
        })
    }
}

/// True for locations read over the network: `http://`, `https://` and `s3://`.
pub fn is_remote(location: &Path) -> bool {
    let s = location.to_string_lossy();
    ["http://", "https://", "s3://"]
        .iter()
        .any(|p| s.starts_with(p))
}
