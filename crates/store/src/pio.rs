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

/// Gives back the whole pages of bytes `offset..offset + len` of a temporary file that nobody
/// reads again (best effort: file systems without hole punching keep them until removal).
pub fn release(file: &File, offset: u64, len: u64) {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::io::AsRawFd;
        const PAGE: u64 = 4096;
        let (from, to) = (offset.div_ceil(PAGE) * PAGE, (offset + len) / PAGE * PAGE);
        if let (Ok(at), Ok(n)) = (
            libc::off_t::try_from(from),
            libc::off_t::try_from(to.saturating_sub(from)),
        ) {
            if n > 0 {
                let mode = libc::FALLOC_FL_PUNCH_HOLE | libc::FALLOC_FL_KEEP_SIZE;
                // SAFETY: a plain system call on a descriptor this `File` owns; a failure only
                // leaves the pages in place.
                let _ = unsafe { libc::fallocate(file.as_raw_fd(), mode, at, n) };
            }
        }
    }
    let _ = (file, offset, len);
}

/// Asks for 2 MiB pages under a large vector's untouched capacity, where the kernel gives them
/// only when asked (transparent huge pages in `madvise` mode, the default of many distributions).
/// A build gathers records in random order from gigabytes of them: with 4 KiB pages nearly every
/// read also misses the TLB, and faulting the buffer in takes 512 times the faults.
pub fn huge_pages<T>(v: &Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        let (from, to) = aligned_span(v, 2 << 20);
        if to > from {
            // SAFETY: advice on whole pages of the vector's own allocation; it changes how the
            // kernel backs them, never their contents, and a refusal leaves them as they were.
            let _ =
                unsafe { libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_HUGEPAGE) };
        }
    }
    let _ = v;
}

/// The addresses of the whole `align`-sized pieces inside a vector's allocation.
#[cfg(target_os = "linux")]
fn aligned_span<T>(v: &Vec<T>, align: usize) -> (usize, usize) {
    let start = v.as_ptr() as usize;
    let end = start + v.capacity() * std::mem::size_of::<T>();
    (start.div_ceil(align) * align, end / align * align)
}

/// Frees a large vector on every thread: its pages go back to the kernel in parallel pieces,
/// where one thread freeing gigabytes at once takes a large share of a second.
pub fn discard<T: Copy + Send>(v: Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        use rayon::prelude::*;
        const PIECE: usize = 8 << 20;
        let (from, to) = aligned_span(&v, PIECE);
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Read, Seek, SeekFrom, Write};

    #[test]
    fn release_frees_only_whole_pages_inside_the_range() -> io::Result<()> {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("run");
        let data: Vec<u8> = (0..5 * 4096u32).map(|i| (i % 251 + 1) as u8).collect();
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(true)
            .read(true)
            .write(true)
            .open(&path)?;
        file.write_all(&data)?;
        // Bytes 100..4096·3+50: only pages 1 and 2 lie wholly inside.
        release(&file, 100, 4096 * 3 - 50);
        let mut back = Vec::new();
        file.seek(SeekFrom::Start(0))?;
        file.read_to_end(&mut back)?;
        assert_eq!(back.len(), data.len());
        assert_eq!(back[..4096], data[..4096]);
        assert_eq!(back[3 * 4096..], data[3 * 4096..]);
        // Where the file system punches holes, the freed pages read as zeros.
        let middle = &back[4096..3 * 4096];
        assert!(middle == &data[4096..3 * 4096] || middle.iter().all(|&b| b == 0));
        Ok(())
    }
}
