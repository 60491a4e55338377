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
/// which is faster); elsewhere the file is only extended. True when the space is reserved.
pub fn allocate(file: &File, len: u64) -> io::Result<bool> {
    if reserve(file, len)? {
        return Ok(true);
    }
    file.set_len(len).map(|()| false)
}

/// Sizes a new file to `len` bytes with its disk space reserved, if the file system can (true);
/// otherwise leaves the file as it was (false).
pub fn reserve(file: &File, len: u64) -> io::Result<bool> {
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

/// A writable shared memory map of one byte range of a file whose space is reserved
/// ([`reserve`]): many threads can fill such ranges at once, where buffered writes into one file
/// are serialized by its inode lock (3–5 GB/s whatever the threads on the 16-core GPU machine,
/// against 11.6 GB/s for 16 threads filling a map whose pages they fault in ahead with
/// MADV_POPULATE_WRITE; docs/BENCHMARKS.md). Unmapped on drop; the bytes stay in the page cache
/// like written ones.
#[cfg(target_os = "linux")]
pub struct MappedRange {
    map: *mut libc::c_void,
    map_len: usize,
    /// The range's first byte within the map (maps start on a page).
    skip: usize,
    len: usize,
}

// SAFETY: the map is owned memory like a Vec's; nothing else refers to it.
#[cfg(target_os = "linux")]
unsafe impl Send for MappedRange {}
// SAFETY: shared access only reads the pointer and lengths (populate's advice).
#[cfg(target_os = "linux")]
unsafe impl Sync for MappedRange {}

#[cfg(target_os = "linux")]
impl MappedRange {
    /// Maps `len` bytes at `offset` of `file`. The caller must not map overlapping ranges of a
    /// file at once, and the file must stay at least `offset + len` bytes long while mapped (a
    /// shorter file would fault on access).
    pub fn new(file: &File, offset: u64, len: usize) -> io::Result<Self> {
        use std::os::unix::io::AsRawFd;
        // SAFETY: sysconf has no preconditions.
        let page = (unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).max(4096) as u64;
        let start = offset - offset % page;
        let skip = (offset - start) as usize;
        let map_len = skip + len.max(1);
        let at = libc::off_t::try_from(start)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "offset out of range"))?;
        // SAFETY: a fresh shared mapping of a descriptor this `File` owns; failures return
        // MAP_FAILED, checked below.
        let map = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                map_len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                at,
            )
        };
        if map == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        Ok(Self {
            map,
            map_len,
            skip,
            len,
        })
    }

    /// Faults the pages of `ranges` in ahead of writing, 1 MiB pieces on every thread at once:
    /// one fault per page taken by the writes themselves is several times slower, and one
    /// thread faulting a whole block in was 7× slower than positioned writes (measured).
    pub fn populate(ranges: &[MappedRange]) {
        use rayon::prelude::*;
        const MADV_POPULATE_WRITE: libc::c_int = 23;
        const PIECE: usize = 1 << 20;
        let pieces: Vec<(usize, usize)> = ranges
            .iter()
            .flat_map(|r| {
                let base = r.map as usize;
                (0..r.map_len.div_ceil(PIECE))
                    .map(move |k| (base + k * PIECE, PIECE.min(r.map_len - k * PIECE)))
            })
            .collect();
        pieces.into_par_iter().for_each(|(at, len)| {
            // SAFETY: advice on pages of a live mapping. Kernels before 5.14 answer EINVAL and
            // the pages are faulted in as they are written instead.
            unsafe { libc::madvise(at as *mut libc::c_void, len, MADV_POPULATE_WRITE) };
        });
    }

    pub fn bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: `skip + len` ≤ `map_len` bytes are mapped readable and writable for as long
        // as self lives, and no other slice of them exists (the borrow is exclusive).
        unsafe { std::slice::from_raw_parts_mut((self.map as *mut u8).add(self.skip), self.len) }
    }
}

#[cfg(target_os = "linux")]
impl Drop for MappedRange {
    fn drop(&mut self) {
        // SAFETY: unmaps exactly the mapping made in `new`, once.
        unsafe { libc::munmap(self.map, self.map_len) };
    }
}
