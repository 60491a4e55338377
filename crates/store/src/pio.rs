//! Positioned reads and writes: no shared file cursor, so many threads can use one `File`.

use std::fs::File;
use std::io;

#[cfg(unix)]
pub fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(unix)]
pub fn write_all_at(file: &File, buf: &[u8], offset: u64) -> io::Result<()> {
    std::os::unix::fs::FileExt::write_all_at(file, buf, offset)
}

#[cfg(windows)]
pub fn read_exact_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_read(buf, offset) {
            Ok(0) => {
                return Err(io::Error::new(
                    io::ErrorKind::UnexpectedEof,
                    "file ends before the requested range",
                ))
            }
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

#[cfg(windows)]
pub fn write_all_at(file: &File, mut buf: &[u8], mut offset: u64) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_write(buf, offset) {
            Ok(0) => {
                return Err(io::Error::new(
                    io::ErrorKind::WriteZero,
                    "the file accepted no bytes",
                ))
            }
            Ok(n) => {
                buf = &buf[n..];
                offset += n as u64;
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// Targets without positioned file I/O (wasm32 in a browser, which has no files: stores come
/// over HTTP there).
#[cfg(not(any(unix, windows)))]
pub fn read_exact_at(_file: &File, _buf: &mut [u8], _offset: u64) -> io::Result<()> {
    Err(io::ErrorKind::Unsupported.into())
}

#[cfg(not(any(unix, windows)))]
pub fn write_all_at(_file: &File, _buf: &[u8], _offset: u64) -> io::Result<()> {
    Err(io::ErrorKind::Unsupported.into())
}

/// Sizes a new file to `len` bytes with its disk space reserved where the file system can
/// (a full disk fails here, before the work, and the kernel then writes into allocated blocks,
/// which is faster); elsewhere the file is only extended.
pub fn allocate(file: &File, len: u64) -> io::Result<()> {
    if reserve(file, len)? {
        return Ok(());
    }
    file.set_len(len)
}

/// Sizes a new file to `len` bytes with its disk space reserved, if the file system can (true);
/// otherwise leaves the file as it was (false).
fn reserve(file: &File, len: u64) -> io::Result<bool> {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::io::AsRawFd;
        if let Ok(l) = libc::off_t::try_from(len) {
            // SAFETY: a plain system call on a descriptor this `File` owns.
            if unsafe { libc::fallocate(file.as_raw_fd(), 0, 0, l) } == 0 {
                return Ok(true);
            }
            let e = io::Error::last_os_error();
            if !matches!(
                e.raw_os_error(),
                Some(libc::EOPNOTSUPP) | Some(libc::ENOSYS)
            ) {
                return Err(e);
            }
        }
    }
    let _ = (file, len);
    Ok(false)
}

/// Drops the whole pages inside bytes `[offset, offset + len)` of a temporary file whose bytes
/// there were read for the last time: their page cache goes at once, dirty pages without ever
/// being written to the disk, where removing the file at the end waited for the writeback of
/// gigabytes (about 2 s of an out-of-core build on the GPU machine). Best effort: file systems
/// without holes keep the pages until the file is removed.
pub fn discard_range(file: &File, offset: u64, len: u64) {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::io::AsRawFd;
        let page = page_size();
        let (from, to) = (offset.div_ceil(page) * page, (offset + len) / page * page);
        let n = to.saturating_sub(from);
        if let (Ok(at), Ok(n)) = (libc::off_t::try_from(from), libc::off_t::try_from(n)) {
            if n > 0 {
                // SAFETY: a plain system call on a descriptor this `File` owns.
                unsafe {
                    libc::fallocate(
                        file.as_raw_fd(),
                        libc::FALLOC_FL_PUNCH_HOLE | libc::FALLOC_FL_KEEP_SIZE,
                        at,
                        n,
                    )
                };
            }
        }
    }
    let _ = (file, offset, len);
}

/// Puts page cache for byte ranges `(offset, len)` of a file in ahead of writing them, in 1 MiB
/// pieces on every thread: bytes never written read as zeros without disk I/O, and the writes
/// then only copy into pages already there. Buffered writes into one file run one at a time
/// (its inode lock) and allocating their pages was most of their cost (a writer busy 0.67–0.88
/// s without, 0.29–0.33 s with, for a 20 M-point store on the 2-core dev machine). Best effort.
pub fn prefill(file: &File, ranges: &[(u64, u64)]) {
    #[cfg(target_os = "linux")]
    {
        use rayon::prelude::*;
        use std::os::unix::io::AsRawFd;
        const PIECE: u64 = 1 << 20;
        let pieces: Vec<(u64, u64)> = ranges
            .iter()
            .flat_map(|&(at, len)| {
                (at..at + len)
                    .step_by(PIECE as usize)
                    .map(move |p| (p, PIECE.min(at + len - p)))
            })
            .collect();
        let fd = file.as_raw_fd();
        pieces.into_par_iter().for_each(|(at, len)| {
            // SAFETY: a plain system call on a descriptor the caller's `File` owns.
            unsafe { libc::readahead(fd, at as libc::off64_t, len as usize) };
        });
    }
    let _ = (file, ranges);
}

/// Frees a large vector on every thread: its pages go back to the kernel in parallel pieces,
/// where one thread freeing gigabytes at once takes a large share of a second.
pub fn discard<T: Copy + Send>(v: Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        use rayon::prelude::*;
        const PIECE: usize = 8 << 20;
        let start = v.as_ptr() as usize;
        let end = start + v.capacity() * std::mem::size_of::<T>();
        let (from, to) = (start.div_ceil(PIECE) * PIECE, end / PIECE * PIECE);
        if to > from {
            (from..to)
                .step_by(PIECE)
                .collect::<Vec<_>>()
                .into_par_iter()
                .for_each(|at| {
                    // SAFETY: whole pages of the vector's own allocation, which no one reads again:
                    // it is dropped below.
                    unsafe { libc::madvise(at as *mut libc::c_void, PIECE, libc::MADV_DONTNEED) };
                });
        }
    }
    drop(v);
}

#[cfg(target_os = "linux")]
fn page_size() -> u64 {
    // SAFETY: sysconf has no preconditions.
    (unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).max(4096) as u64
}
