//! How fast one file can be filled: positioned writes against shared memory maps (the builder
//! writes positioned; maps were tried and measured slower there: docs/BENCHMARKS.md). Linux only.
//!
//! ```sh
//! cargo run --release -p pointlet-store --example write_bench -- FILE GIB THREADS MODE
//! ```
//! MODE: `pwrite` (positioned writes of 4 MiB blocks), `mmap` (memcpy into a shared map, one
//! page fault per page) or `mmap-populate` (each 4 MiB range faulted in first with
//! MADV_POPULATE_WRITE); add `-falloc` to reserve the space first with fallocate. The file is
//! removed afterwards; the removal time is printed too (dirty page cache is freed page by page).

#[cfg(target_os = "linux")]
fn main() -> Result<(), String> {
    use std::os::unix::fs::FileExt;
    use std::os::unix::io::AsRawFd;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::Instant;

    let args: Vec<String> = std::env::args().collect();
    let [_, path, gib, threads, mode] = args.as_slice() else {
        return Err("usage: write_bench FILE GIB THREADS MODE".into());
    };
    let gib: usize = gib.parse().map_err(|e| format!("GIB: {e}"))?;
    let threads: usize = threads.parse().map_err(|e| format!("THREADS: {e}"))?;
    let (kind, falloc) = match mode.strip_suffix("-falloc") {
        Some(k) => (k, true),
        None => (mode.as_str(), false),
    };
    if !["pwrite", "mmap", "mmap-populate"].contains(&kind) {
        return Err(format!("unknown mode '{mode}'"));
    }
    let len = gib << 30;
    const BLOCK: usize = 4 << 20;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|e| format!("creating {path}: {e}"))?;
    let started = Instant::now();
    if falloc {
        // SAFETY: a plain system call on a descriptor this `File` owns.
        if unsafe { libc::fallocate(file.as_raw_fd(), 0, 0, len as libc::off_t) } != 0 {
            return Err(format!("fallocate: {}", std::io::Error::last_os_error()));
        }
    } else {
        file.set_len(len as u64).map_err(|e| e.to_string())?;
    }
    let allocated = started.elapsed().as_secs_f64();
    let src: Vec<u8> = (0..BLOCK).map(|i| (i * 7 + 3) as u8).collect();
    let blocks = len / BLOCK;
    let next = AtomicUsize::new(0);
    let take = || Some(next.fetch_add(1, Ordering::Relaxed)).filter(|b| *b < blocks);
    let started = Instant::now();
    if kind == "pwrite" {
        let failed = std::thread::scope(|s| {
            let workers: Vec<_> = (0..threads)
                .map(|_| {
                    s.spawn(|| {
                        while let Some(b) = take() {
                            file.write_all_at(&src, (b * BLOCK) as u64)?;
                        }
                        Ok::<(), std::io::Error>(())
                    })
                })
                .collect();
            workers.into_iter().find_map(|w| match w.join() {
                Ok(Ok(())) => None,
                Ok(Err(e)) => Some(e.to_string()),
                Err(_) => Some("a writer panicked".to_string()),
            })
        });
        if let Some(e) = failed {
            return Err(e);
        }
    } else {
        // SAFETY: a fresh shared mapping of the whole file this program just sized; failure is
        // MAP_FAILED, checked below.
        let map = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if map == libc::MAP_FAILED {
            return Err(format!("mmap: {}", std::io::Error::last_os_error()));
        }
        let base = map as usize;
        let populate = kind == "mmap-populate";
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| {
                    while let Some(b) = take() {
                        let dst = (base + b * BLOCK) as *mut u8;
                        // SAFETY: block b lies inside the mapping and no other thread takes it.
                        unsafe {
                            if populate {
                                libc::madvise(dst as *mut libc::c_void, BLOCK, 23);
                            }
                            std::ptr::copy_nonoverlapping(src.as_ptr(), dst, BLOCK);
                        }
                    }
                });
            }
        });
        // SAFETY: unmaps the mapping made above, once.
        unsafe { libc::munmap(map, len) };
    }
    let wrote = started.elapsed().as_secs_f64();
    let started = Instant::now();
    drop(file);
    std::fs::remove_file(path).map_err(|e| format!("removing {path}: {e}"))?;
    println!(
        "{mode}, {threads} threads: {gib} GiB, allocation {allocated:.3} s, writing {wrote:.3} s \
         = {:.2} GB/s, removal {:.3} s",
        len as f64 / wrote / 1e9,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

#[cfg(not(target_os = "linux"))]
fn main() {
    eprintln!("write_bench measures Linux file writes only");
}
