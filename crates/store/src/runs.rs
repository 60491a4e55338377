//! Sorted runs on disk and their k-way merge.
//!
//! A run file is a sequence of entries `[key: u64 LE][record]` in (key, input order) order.
//! Runs cover consecutive stretches of the input, so ties between runs go to the lower run:
//! the merged order is the same total order an in-memory sort gives.

use crate::sort::Pair;
use crate::StoreError;
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

/// Run files merged at once; more runs are merged in passes (bounded memory and descriptors).
pub(crate) const MAX_FANOUT: usize = 512;

/// A name for a temporary file that no other builder (in this or another process) uses.
pub(crate) fn temp_name(dir: &Path, stem: &str, what: &str) -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    dir.join(format!(".{stem}.{}.{n}.{what}", std::process::id()))
}

/// Entries between two keys of a run's sparse index.
pub(crate) const SPARSE: usize = 1024;

/// A temporary run file; dropping it removes the file.
pub(crate) struct RunFile {
    pub path: PathBuf,
    /// Entries in the file.
    pub count: u64,
    /// The key of every [`SPARSE`]-th entry: where to cut the run for a parallel merge.
    pub sparse: Vec<u64>,
}

impl Drop for RunFile {
    fn drop(&mut self) {
        pointlet_core::cleanup::remove(&self.path);
    }
}

/// Creates a run file for writing; the returned guard removes it again when dropped.
pub(crate) fn create_run(path: PathBuf) -> Result<(RunFile, File), StoreError> {
    let file = pointlet_core::cleanup::create(
        &path,
        OpenOptions::new().read(true).write(true).create_new(true),
    )
    .map_err(|e| StoreError::io(&path, "creating a temporary run file", e))?;
    Ok((
        RunFile {
            path,
            count: 0,
            sparse: Vec::new(),
        },
        file,
    ))
}

/// Writes the records of an in-memory run in sorted `order` as a run file, one chunk written
/// while the next is gathered.
pub(crate) fn write_run(
    path: PathBuf,
    records: &[u8],
    order: &[Pair],
    rb: usize,
    chunk_bytes: usize,
) -> Result<RunFile, StoreError> {
    let (mut run, mut file) = create_run(path)?;
    let entry = 8 + rb;
    let chunk_points = (chunk_bytes / entry).max(1);
    let gather_into = |part: &[Pair], out: &mut [u8]| {
        out.par_chunks_mut(4096 * entry)
            .zip(part.par_chunks(4096))
            .for_each(|(o, keys)| {
                for (e, &Pair(key, idx)) in o.chunks_exact_mut(entry).zip(keys) {
                    let at = idx as usize * rb;
                    e[..8].copy_from_slice(&key.to_le_bytes());
                    e[8..].copy_from_slice(&records[at..at + rb]);
                }
            });
    };
    run.count = order.len() as u64;
    run.sparse = order.iter().step_by(SPARSE).map(|p| p.0).collect();
    let gather = |part: &[Pair], buf: &mut Vec<u8>| {
        buf.clear();
        buf.resize(part.len() * entry, 0);
        gather_into(part, buf);
    };
    let mut parts = order.chunks(chunk_points);
    let mut ready = Vec::new();
    let mut next = Vec::new();
    if let Some(first) = parts.next() {
        gather(first, &mut ready);
    }
    while !ready.is_empty() {
        let part = parts.next();
        let (written, ()) = rayon::join(
            || file.write_all(&ready),
            || match part {
                Some(p) => gather(p, &mut next),
                None => next.clear(),
            },
        );
        written.map_err(|e| StoreError::io(&run.path, "writing a temporary run file", e))?;
        std::mem::swap(&mut ready, &mut next);
    }
    Ok(run)
}

/// Reads a run file back into memory: its records in file order, with pairs `(0, i)` whose
/// keys the caller computes anew.
pub(crate) fn read_run(run: &RunFile, rb: usize, chunk_bytes: usize) -> Result<Run, StoreError> {
    let entry = 8 + rb;
    let n = usize::try_from(run.count)
        .map_err(|_| StoreError::build(&run.path, "a run larger than memory"))?;
    let mut file = File::open(&run.path)
        .map_err(|e| StoreError::io(&run.path, "opening a temporary run file", e))?;
    let mut out = Run {
        records: Vec::with_capacity(n * rb),
        pairs: (0..n as u32).map(|i| Pair(0, i)).collect(),
        scratch: Vec::new(),
    };
    let mut buf = vec![0u8; (chunk_bytes / entry).max(1) * entry];
    let mut left = n;
    while left > 0 {
        let take = left.min(buf.len() / entry);
        let part = &mut buf[..take * entry];
        file.read_exact(part)
            .map_err(|e| StoreError::io(&run.path, "reading a temporary run file", e))?;
        for e in part.chunks_exact(entry) {
            out.records.extend_from_slice(&e[8..]);
        }
        left -= take;
    }
    Ok(out)
}

/// A run in memory: records in input order and their (key, index) pairs.
#[derive(Default)]
pub(crate) struct Run {
    pub records: Vec<u8>,
    pub pairs: Vec<Pair>,
    /// The radix pass's second array, kept from one spill to the next.
    pub scratch: Vec<Pair>,
}

type SpillResult = Result<(RunFile, Run), StoreError>;

/// Runs sorted and written at once, each to its own file, while the next fills. With one,
/// filling waited 3.2–3.6 s of a 200 M-point build's 4.9–5.6 s reading stage for the spiller
/// (sort, then gather and write, one run after another); with two, 1.2–1.4 s of 3.9–4.2 s,
/// and three were no faster (GPU machine, docs/BENCHMARKS.md).
pub(crate) const SPILLERS: usize = 2;

/// A run to spill, and where to send the result.
type SpillJob = (PathBuf, Run, SyncSender<SpillResult>);

/// Sorts and writes full runs on threads of their own while the next run fills; hands the
/// emptied buffers back for reuse. Results are taken in the order the runs were started.
pub(crate) struct Spiller {
    jobs: Option<SyncSender<SpillJob>>,
    pending: std::collections::VecDeque<Receiver<SpillResult>>,
    workers: Vec<JoinHandle<()>>,
    busy: std::sync::Arc<SpillBusy>,
}

/// Nanoseconds the spilling threads spent sorting runs and writing them, added over the runs.
#[derive(Default)]
struct SpillBusy {
    sorting: AtomicU64,
    writing: AtomicU64,
}

impl Spiller {
    pub fn new(rb: usize, chunk_bytes: usize) -> Spiller {
        let (jobs, todo) = sync_channel::<SpillJob>(SPILLERS);
        let todo = std::sync::Arc::new(std::sync::Mutex::new(todo));
        let busy = std::sync::Arc::new(SpillBusy::default());
        let workers = (0..SPILLERS)
            .map(|_| {
                let (todo, busy) = (todo.clone(), busy.clone());
                std::thread::spawn(move || loop {
                    let job = todo.lock().map(|queue| queue.recv());
                    let Ok(Ok((path, mut run, reply))) = job else {
                        return;
                    };
                    let started = std::time::Instant::now();
                    crate::sort::sort_pairs_with(&mut run.pairs, &mut run.scratch);
                    let sorted = std::time::Instant::now();
                    let result =
                        write_run(path, &run.records, &run.pairs, rb, chunk_bytes).map(|f| {
                            run.records.clear();
                            run.pairs.clear();
                            (f, run)
                        });
                    let nanos = |d: std::time::Duration| d.as_nanos() as u64;
                    busy.sorting
                        .fetch_add(nanos(sorted - started), Ordering::Relaxed);
                    busy.writing
                        .fetch_add(nanos(sorted.elapsed()), Ordering::Relaxed);
                    // A dropped receiver means the build was abandoned; the run file goes too.
                    let _ = reply.send(result);
                })
            })
            .collect();
        Spiller {
            jobs: Some(jobs),
            pending: Default::default(),
            workers,
            busy,
        }
    }

    /// The time spent sorting runs and writing them so far, each added over the runs.
    pub fn busy(&self) -> (std::time::Duration, std::time::Duration) {
        let d = |ns: &AtomicU64| std::time::Duration::from_nanos(ns.load(Ordering::Relaxed));
        (d(&self.busy.sorting), d(&self.busy.writing))
    }

    fn stopped(path: &Path) -> StoreError {
        StoreError::build(path, "the run spilling thread stopped")
    }

    pub fn in_flight(&self) -> usize {
        self.pending.len()
    }

    /// Queues a full run to be written to `path`.
    pub fn start(&mut self, path: PathBuf, run: Run) -> Result<(), StoreError> {
        let jobs = self.jobs.as_ref().ok_or_else(|| Self::stopped(&path))?;
        let (reply, result) = sync_channel(1);
        jobs.send((path.clone(), run, reply))
            .map_err(|_| Self::stopped(&path))?;
        self.pending.push_back(result);
        Ok(())
    }

    /// Waits for the oldest run in flight; `None` when none is.
    pub fn wait(&mut self, output: &Path) -> Result<Option<(RunFile, Run)>, StoreError> {
        let Some(result) = self.pending.pop_front() else {
            return Ok(None);
        };
        let r = result.recv().map_err(|_| Self::stopped(output))?;
        r.map(Some)
    }
}

impl Drop for Spiller {
    fn drop(&mut self) {
        // Closing the queue ends the workers after their current run; joining them first
        // means no run file can appear after the builder cleaned up.
        self.jobs = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

/// Entries `[start, end)` of one run, and the open file to read them from.
pub(crate) struct RunSlice<'a> {
    pub run: &'a RunFile,
    pub file: &'a File,
    pub start: u64,
    pub end: u64,
}

/// Reads a stretch of a run file front to back through a buffer of whole entries, with
/// positioned reads so that many cursors can share one file.
struct Cursor<'a> {
    slice: &'a RunSlice<'a>,
    entry: usize,
    buf: Vec<u8>,
    pos: usize,
    end: usize,
    /// Next entry to load from the file.
    next: u64,
}

impl<'a> Cursor<'a> {
    fn new(slice: &'a RunSlice<'a>, entry: usize, buf_bytes: usize) -> Cursor<'a> {
        let per_fill = (buf_bytes / entry).max(1) as u64;
        let len = per_fill.min(slice.end - slice.start) as usize * entry;
        Cursor {
            slice,
            entry,
            buf: vec![0u8; len],
            pos: 0,
            end: 0,
            next: slice.start,
        }
    }

    /// Loads the next entries; false at the end of the stretch.
    fn fill(&mut self) -> Result<bool, StoreError> {
        let left = self.slice.end - self.next;
        if left == 0 {
            return Ok(false);
        }
        let n = ((self.buf.len() / self.entry) as u64).min(left) as usize;
        let bytes = n * self.entry;
        let at = self.next * self.entry as u64;
        crate::pio::read_exact_at(self.slice.file, &mut self.buf[..bytes], at)
            .map_err(|e| StoreError::io(&self.slice.run.path, "reading a temporary run file", e))?;
        // Each entry is read once: its pages are freed now, on the merging threads, rather
        // than all at once when the runs are removed (1–4 s for 9 GB of runs on one build).
        crate::pio::release(self.slice.file, at, bytes as u64);
        self.pos = 0;
        self.end = bytes;
        self.next += n as u64;
        Ok(true)
    }

    fn current(&self) -> &[u8] {
        &self.buf[self.pos..self.pos + self.entry]
    }

    fn key(&self) -> u64 {
        u64::from_le_bytes(crate::format::array(&self.buf[self.pos..self.pos + 8]))
    }

    /// Moves to the next entry; false at the end of the stretch.
    fn advance(&mut self) -> Result<bool, StoreError> {
        self.pos += self.entry;
        if self.pos < self.end {
            return Ok(true);
        }
        self.fill()
    }
}

/// Merges `slices` (in input order) and hands every entry `[key][record]` to `sink` in
/// (key, input order) order. Returns the number of entries.
pub(crate) fn merge(
    slices: &[RunSlice<'_>],
    rb: usize,
    buf_bytes: usize,
    mut sink: impl FnMut(&[u8]) -> Result<(), StoreError>,
) -> Result<u64, StoreError> {
    let entry = 8 + rb;
    let mut cursors = Vec::with_capacity(slices.len());
    let mut heap = BinaryHeap::with_capacity(slices.len());
    for (i, slice) in slices.iter().enumerate() {
        let mut c = Cursor::new(slice, entry, buf_bytes);
        if c.fill()? {
            heap.push(Reverse((c.key(), i)));
        }
        cursors.push(c);
    }
    let mut count = 0u64;
    while let Some(mut top) = heap.peek_mut() {
        let Reverse((_, i)) = *top;
        let c = &mut cursors[i];
        sink(c.current())?;
        count += 1;
        if c.advance()? {
            // Replacing the top in place costs one sift-down instead of a pop and a push.
            *top = Reverse((c.key(), i));
        } else {
            std::collections::binary_heap::PeekMut::pop(top);
        }
    }
    Ok(count)
}

/// Opens every run for positioned reads (and writable: the merge frees what it has read).
pub(crate) fn open_runs(runs: &[RunFile]) -> Result<Vec<File>, StoreError> {
    runs.iter()
        .map(|r| {
            OpenOptions::new()
                .read(true)
                .write(true)
                .open(&r.path)
                .map_err(|e| StoreError::io(&r.path, "opening a temporary run file", e))
        })
        .collect()
}

/// Entries of `run` whose key is below `key`: the sparse index finds the stretch of
/// [`SPARSE`] entries, one positioned read of it the exact place.
pub(crate) fn entries_below(
    run: &RunFile,
    file: &File,
    rb: usize,
    key: u64,
) -> Result<u64, StoreError> {
    let j = run.sparse.partition_point(|&k| k < key);
    if j == 0 {
        return Ok(0);
    }
    // Entry (j - 1)·SPARSE is below `key`, entry j·SPARSE (if any) is not.
    let lo = ((j - 1) * SPARSE) as u64 + 1;
    let hi = ((j * SPARSE) as u64).min(run.count);
    if lo >= hi {
        return Ok(hi);
    }
    let entry = 8 + rb;
    let mut buf = vec![0u8; (hi - lo) as usize * entry];
    crate::pio::read_exact_at(file, &mut buf, lo * entry as u64)
        .map_err(|e| StoreError::io(&run.path, "reading a temporary run file", e))?;
    let below = buf
        .chunks_exact(entry)
        .take_while(|e| u64::from_le_bytes(crate::format::array(&e[..8])) < key)
        .count();
    Ok(lo + below as u64)
}

/// Merges consecutive groups of runs until at most [`MAX_FANOUT`] remain.
pub(crate) fn reduce_runs(
    mut runs: Vec<RunFile>,
    rb: usize,
    buf_bytes: usize,
    dir: &Path,
    stem: &str,
    mut progress: impl FnMut(u64, u64),
) -> Result<Vec<RunFile>, StoreError> {
    while runs.len() > MAX_FANOUT {
        let total: u64 = runs.iter().map(|r| r.count).sum();
        let mut merged_points = 0u64;
        let mut next = Vec::with_capacity(runs.len().div_ceil(MAX_FANOUT));
        let mut rest = runs.into_iter();
        loop {
            let group: Vec<RunFile> = rest.by_ref().take(MAX_FANOUT).collect();
            if group.is_empty() {
                break;
            }
            if group.len() == 1 {
                next.extend(group);
                continue;
            }
            let (mut run, file) = create_run(temp_name(dir, stem, "run"))?;
            let mut w = std::io::BufWriter::with_capacity(buf_bytes.max(1 << 16), file);
            let per_group = buf_bytes / group.len();
            let files = open_runs(&group)?;
            let slices: Vec<RunSlice<'_>> = group
                .iter()
                .zip(&files)
                .map(|(run, file)| RunSlice {
                    run,
                    file,
                    start: 0,
                    end: run.count,
                })
                .collect();
            let mut sparse = Vec::new();
            let mut seen = 0usize;
            let count = merge(&slices, rb, per_group, |e| {
                if seen.is_multiple_of(SPARSE) {
                    sparse.push(u64::from_le_bytes(crate::format::array(&e[..8])));
                }
                seen += 1;
                w.write_all(e)
                    .map_err(|err| StoreError::io(&run.path, "writing a temporary run file", err))
            })?;
            run.sparse = sparse;
            w.flush()
                .map_err(|e| StoreError::io(&run.path, "writing a temporary run file", e))?;
            run.count = count;
            merged_points += count;
            progress(merged_points, total);
            // The group's files go away here; the merged run replaces them.
            drop(slices);
            drop(files);
            drop(group);
            next.push(run);
        }
        runs = next;
    }
    Ok(runs)
}
