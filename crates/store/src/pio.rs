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
/// Returns whether the space is reserved.
pub fn allocate(file: &File, len: u64) -> io::Result<bool> {
    if reserve(file, len)? {
        return Ok(true);
    }
    file.set_len(len)?;
    Ok(false)
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

/// A store file's bytes mapped for writing, in 2 MiB pages. Threads copy into disjoint parts of
/// it at once: buffered writes to one file take the file's lock (about 5 GiB/s on the GPU
/// machine from any number of threads), where copies into a mapping of 2 MiB pages reach
/// 13 GiB/s (docs/BENCHMARKS.md, issue 15).
pub struct WriteMap {
    ptr: *mut u8,
    len: usize,
}

// SAFETY: the mapping is plain memory shared by the threads; `slice` hands out each byte once.
unsafe impl Send for WriteMap {}
unsafe impl Sync for WriteMap {}

/// 2 MiB: the large page size mappings and buffers ask for.
pub(crate) const HUGE: usize = 2 << 20;

impl WriteMap {
    /// Maps the `len` bytes of `file`, which [`allocate`] sized with its disk space reserved
    /// (writes into the mapping then never need new blocks, so a full disk cannot fault them).
    /// `None` where that would be slower than buffered writes or could fail late: another
    /// system than Linux, a file system without reservation, or (with `huge_only`) a kernel
    /// that backs the file's pages with 4 KiB pages only (many threads faulting those in
    /// contend: 2 GiB/s).
    pub fn new(file: &File, len: u64, reserved: bool, huge_only: bool) -> Option<WriteMap> {
        #[cfg(target_os = "linux")]
        {
            if !reserved || len < HUGE as u64 {
                return None;
            }
            let map = Self::map(file, usize::try_from(len).ok()?)?;
            (!huge_only || map.backed_by_huge_pages()).then_some(map)
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = (file, len, reserved, huge_only);
            None
        }
    }

    /// Maps the file at a 2 MiB-aligned address (huge pages need the address and the file
    /// offset aligned alike) and asks for huge pages.
    #[cfg(target_os = "linux")]
    fn map(file: &File, len: usize) -> Option<WriteMap> {
        use std::os::unix::io::AsRawFd;
        let span = len.checked_add(HUGE)?;
        // SAFETY: reserves address space only (no access, no backing); unmapped on every path.
        let area = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                span,
                libc::PROT_NONE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
                -1,
                0,
            )
        };
        if area == libc::MAP_FAILED {
            return None;
        }
        let start = area as usize;
        let at = start.div_ceil(HUGE) * HUGE;
        // SAFETY: replaces part of the reservation above with the file; MAP_FIXED inside our
        // own reservation cannot clobber anything else.
        let ptr = unsafe {
            libc::mmap(
                at as *mut libc::c_void,
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED | libc::MAP_FIXED,
                file.as_raw_fd(),
                0,
            )
        };
        // SAFETY: the reservation's slack before and after the file mapping (or all of it).
        unsafe {
            if ptr == libc::MAP_FAILED {
                libc::munmap(area, span);
                return None;
            }
            if at > start {
                libc::munmap(area, at - start);
            }
            let end = at + len;
            if start + span > end {
                libc::munmap(end as *mut libc::c_void, start + span - end);
            }
            // A refusal leaves 4 KiB pages, which the check below then finds.
            libc::madvise(ptr, len, libc::MADV_HUGEPAGE);
        }
        Some(WriteMap {
            ptr: ptr.cast(),
            len,
        })
    }

    /// Writes into the last whole 2 MiB page and asks the kernel how it mapped it: file
    /// systems give page cache in 2 MiB pages only on recent kernels (ext4 from Linux 6.16).
    /// (Not the first page: the header written before shares it in small pages.)
    #[cfg(target_os = "linux")]
    fn backed_by_huge_pages(&self) -> bool {
        let at = (self.len / HUGE - 1) * HUGE;
        // SAFETY: inside the mapping. A new file reads as zeros where nothing was written yet
        // (only the header is, at its start), so writing a zero changes nothing; writing
        // without reading first matters: a read maps the page read-only, and the write after
        // it would split a huge mapping into small ones.
        unsafe { self.ptr.add(at).write_volatile(0) };
        let Ok(smaps) = std::fs::read_to_string("/proc/self/smaps") else {
            return false;
        };
        let head = format!("{:08x}-", self.ptr as usize);
        let mut lines = smaps.lines().skip_while(|l| !l.starts_with(&head));
        lines.next().is_some()
            && lines
                .take_while(|l| !is_mapping_line(l))
                .find_map(|l| l.strip_prefix("FilePmdMapped:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
                .is_some_and(|kb| kb > 0)
    }

    /// Bytes `offset..offset + len` of the file, to write.
    ///
    /// # Safety
    /// No other slice handed out may overlap these bytes while this one lives.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn slice(&self, offset: u64, len: usize) -> Option<&mut [u8]> {
        let at = usize::try_from(offset).ok()?;
        if at.checked_add(len)? > self.len {
            return None;
        }
        // SAFETY: inside the mapping; the caller guarantees no overlap.
        Some(unsafe { std::slice::from_raw_parts_mut(self.ptr.add(at), len) })
    }

    /// Unmaps the whole 2 MiB pages inside bytes `offset..offset + len`, which are written and
    /// no longer touched: they stay in the page cache (dirty, written back as usual) but leave
    /// the process, so its memory stays within the build's budget.
    pub fn release(&self, offset: u64, len: u64) {
        #[cfg(target_os = "linux")]
        {
            let h = HUGE as u64;
            let from = offset.div_ceil(h) * h;
            let to = (offset.saturating_add(len)).min(self.len as u64) / h * h;
            if to > from {
                // SAFETY: whole pages inside the mapping, which nobody writes any more; for a
                // shared file mapping this only drops them from the process.
                unsafe {
                    libc::madvise(
                        self.ptr.add(from as usize).cast(),
                        (to - from) as usize,
                        libc::MADV_DONTNEED,
                    );
                }
            }
        }
        let _ = (offset, len);
    }
}

/// Whether a line of /proc/self/smaps starts a mapping (`start-end perms …`) rather than
/// giving one of its figures (`Name: value`).
#[cfg(target_os = "linux")]
fn is_mapping_line(line: &str) -> bool {
    line.split(' ')
        .next()
        .and_then(|range| range.split_once('-'))
        .is_some_and(|(a, b)| {
            u64::from_str_radix(a, 16).is_ok() && u64::from_str_radix(b, 16).is_ok()
        })
}

impl Drop for WriteMap {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        // SAFETY: the mapping `map` made; no slice outlives the map (they borrow it).
        unsafe {
            libc::munmap(self.ptr.cast(), self.len);
        }
    }
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
        let (from, to) = aligned_span(v, HUGE);
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
