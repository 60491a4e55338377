//! Reading served files: opening one safely, its validators, and its bytes as a stream.
//!
//! A file is opened by the path resolved at startup, refusing a symlink put there since
//! (`O_NOFOLLOW`) and anything but a regular file; its validators come from the open handle,
//! so they describe the bytes that are then sent. Bodies are read with positioned reads of
//! [`CHUNK_BYTES`](crate::config::CHUNK_BYTES) on tokio's blocking pool, one chunk at a time as
//! the connection takes them: memory per response stays a few chunks whatever the range, and
//! a client that goes away simply drops the stream. A file that shrinks under a response
//! ends the body early with an error, which closes the connection (the client sees a short
//! body, never wrong bytes labelled as the file's).

use crate::config::CHUNK_BYTES;
use axum::body::Body;
use bytes::Bytes;
use std::fs::{File, Metadata};
use std::io;
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;
use std::time::{SystemTime, UNIX_EPOCH};
use tokio::sync::OwnedSemaphorePermit;

/// What identifies one version of a file: its strong ETag and its modification time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Validators {
    /// Bytes in the file.
    pub len: u64,
    /// The entity tag with its quotes: `"LEN-MTIME_NS-INODE"` in hex. Replacing the file (a
    /// new inode, as the store builder's atomic rename makes) or writing to it (a new
    /// modification time) changes it.
    pub etag: String,
    /// The modification time, as `Last-Modified` sends it (whole seconds).
    pub modified: SystemTime,
}

impl Validators {
    pub fn of(meta: &Metadata) -> Validators {
        let modified = meta.modified().unwrap_or(UNIX_EPOCH);
        let nanos = modified
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        let etag = format!("\"{:x}-{:x}-{:x}\"", meta.len(), nanos, inode(meta));
        Validators {
            len: meta.len(),
            etag,
            modified,
        }
    }

    /// `Last-Modified`'s value.
    pub fn last_modified(&self) -> String {
        httpdate::fmt_http_date(self.modified)
    }
}

#[cfg(unix)]
fn inode(meta: &Metadata) -> u64 {
    use std::os::unix::fs::MetadataExt;
    meta.ino()
}

#[cfg(not(unix))]
fn inode(_meta: &Metadata) -> u64 {
    0
}

/// A served file, open.
pub struct OpenFile {
    pub file: Arc<File>,
    pub validators: Validators,
}

/// Opens `path` for reading without following a symlink at its last component. `Ok(None)`:
/// the path is missing, a symlink or not a regular file; the request gets a 404.
pub fn open_regular(path: &Path) -> io::Result<Option<OpenFile>> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK);
    }
    let file = match options.open(path) {
        Ok(f) => f,
        Err(e) if is_absent(&e) => return Ok(None),
        Err(e) => return Err(e),
    };
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Ok(None);
    }
    Ok(Some(OpenFile {
        file: Arc::new(file),
        validators: Validators::of(&meta),
    }))
}

/// Errors that mean "nothing servable there": missing, a symlink (`ELOOP` under
/// `O_NOFOLLOW`), a folder in the way.
fn is_absent(e: &io::Error) -> bool {
    if matches!(
        e.kind(),
        io::ErrorKind::NotFound | io::ErrorKind::NotADirectory | io::ErrorKind::IsADirectory
    ) {
        return true;
    }
    #[cfg(unix)]
    if e.raw_os_error() == Some(libc::ELOOP) {
        return true;
    }
    false
}

/// The body of bytes `range` of `file`, read chunk by chunk. `permit` (a stream slot) is held
/// until the body is finished or dropped.
pub fn body(file: Arc<File>, range: Range<u64>, permit: OwnedSemaphorePermit) -> Body {
    let state = (file, range.start, range.end, permit);
    let stream = futures_util::stream::unfold(state, |(file, pos, end, permit)| async move {
        if pos >= end {
            return None;
        }
        let n = (end - pos).min(CHUNK_BYTES as u64) as usize;
        let reader = Arc::clone(&file);
        let read = tokio::task::spawn_blocking(move || {
            let mut buf = vec![0u8; n];
            read_exact_at(&reader, &mut buf, pos).map(|()| Bytes::from(buf))
        })
        .await;
        let chunk = match read {
            Ok(Ok(bytes)) => bytes,
            Ok(Err(e)) => return Some((Err(e), (file, end, end, permit))),
            Err(join) => return Some((Err(io::Error::other(join)), (file, end, end, permit))),
        };
        Some((Ok(chunk), (file, pos + n as u64, end, permit)))
    });
    Body::from_stream(stream)
}

/// Fills `buf` from `offset` of `file` without moving any shared cursor.
#[cfg(unix)]
fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> io::Result<()> {
    use std::os::unix::fs::FileExt;
    file.read_exact_at(buf, offset)
}

#[cfg(windows)]
fn read_exact_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_read(buf, offset) {
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
