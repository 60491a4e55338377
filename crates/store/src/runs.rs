//! Spilled runs, grouped by key bucket, and reading them back.
//!
//! A full run is not sorted before it is spilled: its records are written grouped by the top
//! bits of their Hilbert keys ([`Bucketing`]), in input order inside each bucket, followed by
//! where each bucket starts (read back when needed: a run keeps nothing per bucket in memory,
//! which with tiny budgets and many runs would outgrow the budget). The final phase loads the
//! same consecutive buckets of every run as one group that fits the budget and sorts it in
//! memory; ties go to the lower run and then to input order, which is the in-memory sort's
//! total order. A bucket too large
//! for one group is spilled again by finer buckets; one of a single key needs no sorting.

use crate::pio::WriteMap;
use crate::sort::Pair;
use crate::StoreError;
use rayon::prelude::*;
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::Mutex;
use std::thread::JoinHandle;

/// Which bucket a key falls in: `(key >> shift) - base`, among `count` buckets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Bucketing {
    pub shift: u32,
    pub base: u64,
    pub count: usize,
}

/// Bits of a key the first bucketing uses: 16 Ki buckets of the 63-bit Hilbert keys (128 KiB of
/// bucket starts a run); points on a surface fill a few hundred of them.
const TOP_BITS: u32 = 14;
/// Bits each finer bucketing adds, inside one bucket too large for a group.
const SUB_BITS: u32 = 12;

impl Bucketing {
    /// The bucketing of spilled runs.
    pub fn top() -> Bucketing {
        let key_bits = 3 * pointlet_core::codes::KEY_BITS;
        Bucketing {
            shift: key_bits - TOP_BITS,
            base: 0,
            count: 1 << TOP_BITS,
        }
    }

    /// The bucket of `key` (keys outside the range go to the nearest end).
    #[inline(always)]
    pub fn of(&self, key: u64) -> usize {
        let b = (key >> self.shift).saturating_sub(self.base);
        b.min(self.count as u64 - 1) as usize
    }

    /// The finer buckets inside bucket `b`; `None` where a bucket holds one key.
    pub fn within(&self, b: usize) -> Option<Bucketing> {
        if self.shift == 0 {
            return None;
        }
        let shift = self.shift.saturating_sub(SUB_BITS);
        let bits = self.shift - shift;
        Some(Bucketing {
            shift,
            base: (self.base + b as u64) << bits,
            count: 1 << bits,
        })
    }
}

/// A name for a temporary file that no other builder (in this or another process) uses.
pub(crate) fn temp_name(dir: &Path, stem: &str, what: &str) -> PathBuf {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    dir.join(format!(".{stem}.{}.{n}.{what}", std::process::id()))
}

/// A temporary run file; dropping it removes the file.
pub(crate) struct RunFile {
    pub path: PathBuf,
    /// Records in the file.
    pub count: u64,
    /// Bytes per record.
    pub rb: usize,
    /// Buckets of the run's [`Bucketing`]: after the records and their keys, the file holds
    /// where each starts (in records, `u64` little-endian) and the end.
    pub buckets: usize,
}

/// Bytes of a record's key in a run file (after all the records, in the same order): the groups
/// read keys back instead of computing them again (2.8 of the 11 core-s out of core spent
/// beyond an in-memory build, GPU machine, docs/BENCHMARKS.md).
pub(crate) const KEY_BYTES: usize = 8;

impl RunFile {
    /// Where buckets `range.start..=range.end` start (the last: where bucket `range.end - 1`
    /// ends), read from the run's file.
    pub fn starts(&self, range: std::ops::Range<usize>) -> Result<Vec<u64>, StoreError> {
        if range.end > self.buckets || range.start > range.end {
            return Err(StoreError::build(
                &self.path,
                format!("internal error: buckets {range:?} of {}", self.buckets),
            ));
        }
        let file = self.open()?;
        let mut raw = vec![0u8; (range.len() + 1) * 8];
        let at = self.keys_at() + self.count * KEY_BYTES as u64 + range.start as u64 * 8;
        crate::pio::read_exact_at(&file, &mut raw, at)
            .map_err(|e| StoreError::io(&self.path, "reading a temporary run file", e))?;
        Ok(raw
            .chunks_exact(8)
            .map(|b| u64::from_le_bytes(crate::format::array(b)))
            .collect())
    }

    /// Where the records' keys start in the file.
    fn keys_at(&self) -> u64 {
        self.count * self.rb as u64
    }

    /// The run's file for positioned reads, writable so that pages read can be given back.
    fn open(&self) -> Result<File, StoreError> {
        OpenOptions::new()
            .read(true)
            .write(true)
            .open(&self.path)
            .map_err(|e| StoreError::io(&self.path, "opening a temporary run file", e))
    }

    /// Records of buckets `range`: the first and one past the last.
    pub fn span(&self, range: std::ops::Range<usize>) -> Result<(u64, u64), StoreError> {
        let s = self.starts(range)?;
        Ok((s[0], s[s.len() - 1]))
    }
}

/// A run's bucket starts as the bytes that follow its records' keys.
fn starts_bytes(starts: impl Iterator<Item = u64>) -> Vec<u8> {
    starts.flat_map(u64::to_le_bytes).collect()
}

impl Drop for RunFile {
    fn drop(&mut self) {
        pointlet_core::cleanup::remove(&self.path);
    }
}

/// Creates a run file for writing; the returned guard removes it again when dropped.
pub(crate) fn create_run(path: PathBuf, rb: usize) -> Result<(RunFile, File), StoreError> {
    let file = pointlet_core::cleanup::create(
        &path,
        OpenOptions::new().read(true).write(true).create_new(true),
    )
    .map_err(|e| StoreError::io(&path, "creating a temporary run file", e))?;
    Ok((
        RunFile {
            path,
            count: 0,
            rb,
            buckets: 0,
        },
        file,
    ))
}

/// Whether run files are written through a mapping of 2 MiB pages: a kernel that backs the
/// run directory's page cache with them takes a run's records straight from the gathering
/// threads, with no copy through `write` by one thread (buffered writes of one file peak at
/// ~5 GiB/s on the GPU machine, copies into such a mapping at 13). Found out with the first
/// run, which asks the kernel; later runs trust the answer.
#[derive(Default)]
pub(crate) struct RunMaps(std::sync::atomic::AtomicU8);

impl RunMaps {
    const UNKNOWN: u8 = 0;
    const MAPPED: u8 = 1;
    const WRITTEN: u8 = 2;

    /// A new run file of `len` bytes, sized, and mapped where runs are mapped.
    fn map(&self, file: &File, len: u64, path: &Path) -> Result<Option<WriteMap>, StoreError> {
        let known = self.0.load(Ordering::Relaxed);
        // A run smaller than one 2 MiB page is written, and says nothing of the larger ones.
        if known == Self::WRITTEN || len < crate::pio::HUGE as u64 {
            return Ok(None);
        }
        let reserved = crate::pio::allocate(file, len)
            .map_err(|e| StoreError::io(path, "reserving space for a temporary run file", e))?;
        let map = WriteMap::new(file, len, reserved, known == Self::UNKNOWN);
        if known == Self::UNKNOWN {
            let found = if map.is_some() {
                Self::MAPPED
            } else {
                Self::WRITTEN
            };
            self.0.store(found, Ordering::Relaxed);
        }
        Ok(map)
    }
}

/// Records a gathering task copies: 2 MiB of output. Into a mapping the first write to a 2 MiB
/// page zero-fills it while every other thread writing there waits (with tasks of 4096
/// records, 14 to a page, the out-of-core reading stage's threads waited 4.0 s in such faults,
/// 1.2 after).
fn gather_piece(rb: usize) -> usize {
    (crate::pio::HUGE / rb.max(1)).max(4096)
}

/// Copies the records of `pairs` (by their indices into `records`) into `out`, one after another.
fn copy_records(records: &[u8], pairs: &[Pair], rb: usize, out: &mut [u8]) {
    crate::emit::copy_records(records, rb, pairs, |p| p.1, out);
}

/// Copies the records of `pairs` (by their indices into `records`) into `out`, on every core.
fn gather_records(records: &[u8], pairs: &[Pair], rb: usize, out: &mut [u8]) {
    let piece = gather_piece(rb);
    out.par_chunks_mut(piece * rb)
        .zip(pairs.par_chunks(piece))
        .for_each(|(o, pairs)| copy_records(records, pairs, rb, o));
}

/// Most tasks of the mapped gather that may run ahead of the first unfinished one: a pool left
/// idle while the reader waits for a spiller gathers with all its threads.
const GATHER_WINDOW: usize = 16;

/// Gathers the records of `order` into `map` in 2 MiB tasks taken in file order, by the calling
/// thread and by any pool thread that comes free, releasing the finished prefix every
/// `release_bytes`. The calling thread (a spiller) works through the tasks itself: pool threads
/// take queued jobs only once the reader's decoding leaves them idle, and a spiller that waited
/// for them chunk after chunk kept the reader waiting in turn (GPU machine, docs/BENCHMARKS.md).
/// Tasks run at most two releases ahead, so the process maps at most three releases of the
/// run (and the page either side) whatever the threads do.
fn gather_into_map(
    map: &WriteMap,
    records: &[u8],
    order: &[Pair],
    rb: usize,
    release_bytes: usize,
) -> bool {
    let keys_at = (order.len() * rb) as u64;
    use std::sync::atomic::{AtomicBool, AtomicUsize};
    let piece = gather_piece(rb);
    let tasks = order.len().div_ceil(piece);
    let window = (2 * release_bytes / (piece * rb)).clamp(1, GATHER_WINDOW);
    let next = AtomicUsize::new(0);
    let done: Vec<AtomicBool> = (0..tasks).map(|_| AtomicBool::new(false)).collect();
    let outside = AtomicBool::new(false);
    // The first unfinished task and the bytes released so far; `first` mirrors the former for
    // the tasks waiting on the window.
    let frontier = Mutex::new((0usize, 0u64));
    let first = AtomicUsize::new(0);
    // A pool thread leaves where the window is full; the calling thread waits there for
    // whoever holds the first unfinished task, which is copying.
    let worker = |helper: bool| loop {
        let t = next.load(Ordering::Relaxed);
        if t >= tasks {
            return;
        }
        if t >= first.load(Ordering::Acquire) + window {
            if helper {
                return;
            }
            std::thread::yield_now();
            continue;
        }
        if next
            .compare_exchange(t, t + 1, Ordering::Relaxed, Ordering::Relaxed)
            .is_err()
        {
            continue;
        }
        let part = &order[t * piece..((t + 1) * piece).min(order.len())];
        // SAFETY: task t's records and keys, which no other task covers.
        let out = unsafe { map.slice((t * piece * rb) as u64, part.len() * rb) };
        let keys_from = keys_at + (t * piece * KEY_BYTES) as u64;
        // SAFETY: as above, in the keys after the records.
        let keys = unsafe { map.slice(keys_from, part.len() * KEY_BYTES) };
        match (out, keys) {
            (Some(out), Some(keys)) => {
                copy_records(records, part, rb, out);
                for (k, p) in keys.chunks_exact_mut(KEY_BYTES).zip(part) {
                    k.copy_from_slice(&{ p.0 }.to_le_bytes());
                }
            }
            _ => outside.store(true, Ordering::Relaxed),
        }
        done[t].store(true, Ordering::Release);
        let mut f = crate::emit::lock(&frontier);
        while f.0 < tasks && done[f.0].load(Ordering::Acquire) {
            f.0 += 1;
        }
        first.store(f.0, Ordering::Release);
        let done_records = (f.0 * piece).min(order.len()) as u64;
        let written = done_records * rb as u64;
        if written >= f.1 + release_bytes as u64 || f.0 == tasks {
            map.release(0, written);
            map.release(keys_at, done_records * KEY_BYTES as u64);
            f.1 = written;
        }
    };
    rayon::in_place_scope(|s| {
        for _ in 0..rayon::current_num_threads() {
            s.spawn(|_| worker(true));
        }
        worker(false);
    });
    !outside.load(Ordering::Relaxed)
}

/// Writes the records of an in-memory run in `order` (bucketed, bucket `b` at
/// `order[starts[b]..starts[b + 1]]`) as a run file: gathered into its mapping, its pages
/// leaving the process as they are written, or else one chunk written while the next is
/// gathered.
pub(crate) fn write_run(
    path: PathBuf,
    records: &[u8],
    order: &[Pair],
    starts: &[usize],
    rb: usize,
    chunk_bytes: usize,
    maps: &RunMaps,
) -> Result<RunFile, StoreError> {
    let (mut run, mut file) = create_run(path, rb)?;
    let chunk_points = (chunk_bytes / rb.max(1)).max(1);
    run.count = order.len() as u64;
    run.buckets = starts.len() - 1;
    let tail = starts_bytes(starts.iter().map(|&s| s as u64));
    let records_len = order.len() * rb;
    let keys_len = order.len() * KEY_BYTES;
    let failed = |e| StoreError::io(&run.path, "writing a temporary run file", e);
    let file_len = (records_len + keys_len + tail.len()) as u64;
    if let Some(map) = maps.map(&file, file_len, &run.path)? {
        let outside = || StoreError::build(&run.path, "internal error: a run outside its file");
        if !gather_into_map(&map, records, order, rb, chunk_bytes) {
            return Err(outside());
        }
        // SAFETY: the bytes after the records and keys, which no other slice covers.
        unsafe { map.slice((records_len + keys_len) as u64, tail.len()) }
            .ok_or_else(outside)?
            .copy_from_slice(&tail);
        return Ok(run);
    }
    let gather = |part: &[Pair], buf: &mut Vec<u8>| {
        buf.clear();
        buf.resize(part.len() * rb, 0);
        gather_records(records, part, rb, buf);
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
        written.map_err(failed)?;
        std::mem::swap(&mut ready, &mut next);
    }
    for part in order.chunks(chunk_points) {
        ready.clear();
        ready.extend(part.iter().flat_map(|p| { p.0 }.to_le_bytes()));
        file.write_all(&ready).map_err(failed)?;
    }
    file.write_all(&tail).map_err(failed)?;
    Ok(run)
}

/// Reads a run file back into memory: its records in file order, with pairs `(0, i)` whose
/// keys the caller computes anew.
pub(crate) fn read_run(run: &RunFile) -> Result<Run, StoreError> {
    let rb = run.rb;
    let n = usize::try_from(run.count)
        .map_err(|_| StoreError::build(&run.path, "a run larger than memory"))?;
    let mut file = run.open()?;
    let mut records = vec![0u8; n * rb];
    file.read_exact(&mut records)
        .map_err(|e| StoreError::io(&run.path, "reading a temporary run file", e))?;
    Ok(Run {
        records,
        pairs: (0..n as u32).map(|i| Pair(0, i)).collect(),
        scratch: Vec::new(),
        cells: None,
    })
}

/// Reads records `from..from + out.len() / run.rb` of a run into `out`, and their keys into
/// `keys` (as many), through one opening of the file.
pub(crate) fn read_records(
    run: &RunFile,
    from: u64,
    out: &mut [u8],
    keys: &mut [u64],
) -> Result<(), StoreError> {
    let file = run.open()?;
    let failed = |e| StoreError::io(&run.path, "reading a temporary run file", e);
    crate::pio::read_exact_at(&file, out, from * run.rb as u64).map_err(failed)?;
    // Straight into the keys: no buffer to clear and convert from (a no-op on little-endian).
    let raw: &mut [u8] = bytemuck::cast_slice_mut(keys);
    crate::pio::read_exact_at(&file, raw, run.keys_at() + from * KEY_BYTES as u64)
        .map_err(failed)?;
    for k in keys.iter_mut() {
        *k = u64::from_le(*k);
    }
    Ok(())
}

/// Gives back the pages of records `from..to` of a run and of their keys, which were read and
/// are not read again: freeing them as the groups go, on the loading threads, spares the
/// seconds that removing gigabytes of runs at the end would take.
pub(crate) fn release_records(run: &RunFile, from: u64, to: u64) -> Result<(), StoreError> {
    let file = run.open()?;
    let rb = run.rb as u64;
    crate::pio::release(&file, from * rb, (to - from) * rb);
    let kb = KEY_BYTES as u64;
    crate::pio::release(&file, run.keys_at() + from * kb, (to - from) * kb);
    Ok(())
}

/// A run in memory: records in input order and their (key, index) pairs.
#[derive(Default)]
pub(crate) struct Run {
    pub records: Vec<u8>,
    pub pairs: Vec<Pair>,
    /// The bucketing pass's second array, kept from one spill to the next.
    pub scratch: Vec<Pair>,
    /// How the pairs are laid out where each decoding task put its part's pairs in bucket
    /// order ([`bucket_part`]): cell after cell, parts in input order. `None` where any pairs
    /// came otherwise, and the whole run is bucketed when spilled.
    pub cells: Option<Vec<Cell>>,
}

/// A part's pairs of one bucket, consecutive in the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Cell {
    pub bucket: u32,
    pub len: u32,
}

/// Puts a run's pairs in bucket order, stable inside a bucket; where each bucket starts. A
/// run laid out in cells has its cells moved whole by the calling thread; another is
/// scattered pair by pair on the pool, which takes such jobs only when the next run's decoding
/// leaves it idle (42–60 ms a 5 M-point run on the GPU machine, the cells 17–26 ms;
/// docs/BENCHMARKS.md).
pub(crate) fn bucket_run(run: &mut Run, bucketing: Bucketing) -> Vec<usize> {
    if let Some(cells) = run.cells.take() {
        let starts = order_cells(&mut run.pairs, &mut run.scratch, &cells, bucketing.count);
        run.cells = Some(cells);
        if let Some(starts) = starts {
            return starts;
        }
    }
    crate::sort::bucket_by(&mut run.pairs, &mut run.scratch, bucketing.count, |k| {
        bucketing.of(k)
    })
}

/// A decoding task's tables for [`bucket_part`], kept from one part to the next.
#[derive(Default)]
pub(crate) struct PartBuckets {
    /// Pairs per bucket, then where each goes; zero again between parts.
    counts: Vec<u32>,
    /// The buckets the part touches.
    touched: Vec<u32>,
    scratch: Vec<Pair>,
}

/// Points per cell a part needs at least to be put in cells: the cells of a run then take at
/// most 2 bytes a point ([`Cell`]'s 8 bytes per 4 points), which the run budget counts.
pub(crate) const POINTS_PER_CELL: usize = 4;

/// Puts a part's pairs in bucket order (stable inside a bucket) while they are in the
/// decoding core's cache, and appends the part's cells, in bucket order, to `cells`. A part
/// spread over more than a [`POINTS_PER_CELL`]th of its size in buckets (a small part, points
/// scattered through the volume) is left as it is: `false`, and the run is scattered whole.
pub(crate) fn bucket_part(
    pairs: &mut [Pair],
    bucketing: Bucketing,
    tables: &mut PartBuckets,
    cells: &mut Vec<Cell>,
) -> bool {
    let PartBuckets {
        counts,
        touched,
        scratch,
    } = tables;
    if counts.len() != bucketing.count {
        *counts = vec![0; bucketing.count];
    }
    touched.clear();
    for p in pairs.iter() {
        let b = bucketing.of(p.0);
        if counts[b] == 0 {
            touched.push(b as u32);
        }
        counts[b] += 1;
    }
    if touched.len() > pairs.len() / POINTS_PER_CELL {
        for &b in touched.iter() {
            counts[b as usize] = 0;
        }
        return false;
    }
    touched.sort_unstable();
    let mut at = 0u32;
    for &b in touched.iter() {
        let len = counts[b as usize];
        cells.push(Cell { bucket: b, len });
        counts[b as usize] = at;
        at += len;
    }
    if touched.len() > 1 {
        scratch.clear();
        scratch.extend_from_slice(pairs);
        for p in scratch.iter() {
            let b = bucketing.of(p.0);
            pairs[counts[b] as usize] = *p;
            counts[b] += 1;
        }
    }
    for &b in touched.iter() {
        counts[b as usize] = 0;
    }
    true
}

/// Moves `pairs`, laid out as `cells`, into bucket order through `scratch` (each cell whole,
/// in the order of `cells`: stable where that is input order) and returns where each of `nb`
/// buckets starts; `None`, leaving the pairs as they were, where the cells do not describe
/// them.
fn order_cells(
    pairs: &mut Vec<Pair>,
    scratch: &mut Vec<Pair>,
    cells: &[Cell],
    nb: usize,
) -> Option<Vec<usize>> {
    let mut totals = vec![0usize; nb];
    for c in cells {
        *totals.get_mut(c.bucket as usize)? += c.len as usize;
    }
    let mut starts = Vec::with_capacity(nb + 1);
    let mut at = 0usize;
    for t in &totals {
        starts.push(at);
        at += t;
    }
    starts.push(at);
    let n = pairs.len();
    if at != n {
        return None;
    }
    let mut cursor = starts[..nb].to_vec();
    scratch.clear();
    scratch.reserve_exact(n);
    crate::pio::huge_pages(scratch);
    let dst = &mut scratch.spare_capacity_mut()[..n];
    let mut from = 0usize;
    for c in cells {
        let (len, to) = (c.len as usize, &mut cursor[c.bucket as usize]);
        for (d, p) in dst[*to..*to + len].iter_mut().zip(&pairs[from..from + len]) {
            d.write(*p);
        }
        *to += len;
        from += len;
    }
    // SAFETY: each bucket's cells fill its slots `starts[b]..starts[b + 1]` exactly (the
    // cursor of bucket b moves by its cells' lengths, which add up to its total), and the
    // buckets' slots tile `0..n`.
    unsafe { scratch.set_len(n) };
    std::mem::swap(pairs, scratch);
    Some(starts)
}

type SpillResult = Result<(RunFile, Run), StoreError>;

/// Runs bucketed and written at once, each to its own file, while the next fills. With one
/// (when runs were sorted), filling waited 3.2–3.6 s of a 200 M-point build's 4.9–5.6 s
/// reading stage for the spiller; with two, 1.2–1.4 s of 3.9–4.2 s, and three were no faster
/// (GPU machine, docs/BENCHMARKS.md).
pub(crate) const SPILLERS: usize = 2;

/// A run to spill, and where to send the result.
type SpillJob = (PathBuf, Run, SyncSender<SpillResult>);

/// Buckets and writes full runs on threads of their own while the next run fills; hands the
/// emptied buffers back for reuse. Results are taken in the order the runs were started.
pub(crate) struct Spiller {
    jobs: Option<SyncSender<SpillJob>>,
    pending: std::collections::VecDeque<Receiver<SpillResult>>,
    workers: Vec<JoinHandle<()>>,
    busy: std::sync::Arc<SpillBusy>,
}

/// Nanoseconds the spilling threads spent bucketing runs and writing them, added over the runs.
#[derive(Default)]
struct SpillBusy {
    bucketing: AtomicU64,
    writing: AtomicU64,
}

impl Spiller {
    pub fn new(rb: usize, chunk_bytes: usize, maps: std::sync::Arc<RunMaps>) -> Spiller {
        let (jobs, todo) = sync_channel::<SpillJob>(SPILLERS);
        let todo = std::sync::Arc::new(std::sync::Mutex::new(todo));
        let busy = std::sync::Arc::new(SpillBusy::default());
        let workers = (0..SPILLERS)
            .map(|_| {
                let (todo, busy, maps) = (todo.clone(), busy.clone(), maps.clone());
                std::thread::spawn(move || loop {
                    let job = todo.lock().map(|queue| queue.recv());
                    let Ok(Ok((path, mut run, reply))) = job else {
                        return;
                    };
                    let started = std::time::Instant::now();
                    let starts = bucket_run(&mut run, Bucketing::top());
                    let bucketed = std::time::Instant::now();
                    let (records, pairs) = (&run.records, &run.pairs);
                    let result = write_run(path, records, pairs, &starts, rb, chunk_bytes, &maps)
                        .map(|f| {
                            run.records.clear();
                            run.pairs.clear();
                            if let Some(cells) = run.cells.as_mut() {
                                cells.clear();
                            }
                            (f, run)
                        });
                    let nanos = |d: std::time::Duration| d.as_nanos() as u64;
                    busy.bucketing
                        .fetch_add(nanos(bucketed - started), Ordering::Relaxed);
                    busy.writing
                        .fetch_add(nanos(bucketed.elapsed()), Ordering::Relaxed);
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

    /// The time spent bucketing runs and writing them so far, each added over the runs.
    pub fn busy(&self) -> (std::time::Duration, std::time::Duration) {
        let d = |ns: &AtomicU64| std::time::Duration::from_nanos(ns.load(Ordering::Relaxed));
        (d(&self.busy.bucketing), d(&self.busy.writing))
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

/// Runs at most that a group reads from: beyond them (a tiny budget, a huge input), each group
/// would read a few records from each of thousands of runs, so consecutive runs are joined
/// first.
pub(crate) const RUNS_KEPT: usize = 512;

/// Runs joined into one at a time.
const JOINED: usize = 32;

/// Joins consecutive runs, [`JOINED`] at a time on every core, until at most [`RUNS_KEPT`]
/// remain.
pub(crate) fn join_runs(
    mut runs: Vec<RunFile>,
    buf_bytes: usize,
    dir: &Path,
    stem: &str,
) -> Result<Vec<RunFile>, StoreError> {
    while runs.len() > RUNS_KEPT {
        let groups: Vec<Vec<RunFile>> = {
            let mut rest = runs.into_iter().peekable();
            let mut groups = Vec::new();
            while rest.peek().is_some() {
                groups.push(rest.by_ref().take(JOINED).collect());
            }
            groups
        };
        let buf = (buf_bytes / groups.len().min(rayon::current_num_threads())).max(1 << 16);
        runs = groups
            .into_par_iter()
            .map(|group| match group.len() {
                1 => group.into_iter().next().ok_or_else(|| {
                    StoreError::build(dir, "internal error: an empty group of runs")
                }),
                _ => join(&group, temp_name(dir, stem, "run"), buf),
            })
            .collect::<Result<Vec<_>, _>>()?;
    }
    Ok(runs)
}

/// One run of `group` (consecutive runs of the same bucketing): bucket by bucket, each
/// bucket's records of every run in run order, which is how groups read them.
fn join(group: &[RunFile], path: PathBuf, buf_bytes: usize) -> Result<RunFile, StoreError> {
    let rb = group.first().map_or(1, |r| r.rb);
    let (mut out, file) = create_run(path, rb)?;
    let mut w = std::io::BufWriter::with_capacity(buf_bytes / 2, file);
    let buckets = group.first().map_or(0, |r| r.buckets);
    let runs_starts = group
        .iter()
        .map(|r| r.starts(0..buckets))
        .collect::<Result<Vec<_>, _>>()?;
    // A bucket of the joined run starts where it starts in every run, added up.
    let starts: Vec<u64> = (0..=buckets)
        .map(|b| runs_starts.iter().map(|s| s[b]).sum())
        .collect();
    // The records, then their keys in the same order.
    for keys in [false, true] {
        let size = if keys { KEY_BYTES } else { rb };
        let per_run = (buf_bytes / 2 / group.len() / size).max(1);
        let mut readers = group
            .iter()
            .map(|run| RunReader::new(run, per_run, keys))
            .collect::<Result<Vec<_>, _>>()?;
        for b in 0..buckets {
            for (run_starts, reader) in runs_starts.iter().zip(&mut readers) {
                let mut left = run_starts[b + 1] - run_starts[b];
                while left > 0 {
                    let items = reader.take(left)?;
                    w.write_all(items).map_err(|e| {
                        StoreError::io(&out.path, "writing a temporary run file", e)
                    })?;
                    left -= (items.len() / size) as u64;
                }
            }
        }
    }
    w.write_all(&starts_bytes(starts.iter().copied()))
        .and_then(|()| w.flush())
        .map_err(|e| StoreError::io(&out.path, "writing a temporary run file", e))?;
    out.count = starts[buckets];
    out.buckets = buckets;
    Ok(out)
}

/// Reads a run's records (or their keys) front to back through a buffer, giving its pages back
/// as it goes.
struct RunReader<'a> {
    run: &'a RunFile,
    file: File,
    buf: Vec<u8>,
    pos: usize,
    end: usize,
    /// Next record to load from the file.
    next: u64,
    /// Where the records (or keys) start in the file, and the bytes of one.
    base: u64,
    size: usize,
}

impl<'a> RunReader<'a> {
    fn new(run: &'a RunFile, records: usize, keys: bool) -> Result<Self, StoreError> {
        let file = run.open()?;
        let records = (records as u64).min(run.count) as usize;
        let (base, size) = if keys {
            (run.keys_at(), KEY_BYTES)
        } else {
            (0, run.rb)
        };
        Ok(RunReader {
            run,
            file,
            buf: vec![0; records * size],
            pos: 0,
            end: 0,
            next: 0,
            base,
            size,
        })
    }

    /// The next records (or keys), at most `max` (at least one while the run has any).
    fn take(&mut self, max: u64) -> Result<&[u8], StoreError> {
        if self.pos == self.end {
            let rb = self.size;
            let n = ((self.buf.len() / rb) as u64).min(self.run.count - self.next);
            if n == 0 {
                return Err(StoreError::build(
                    &self.run.path,
                    "internal error: a run ended before its buckets did",
                ));
            }
            let bytes = n as usize * rb;
            let at = self.base + self.next * rb as u64;
            crate::pio::read_exact_at(&self.file, &mut self.buf[..bytes], at)
                .map_err(|e| StoreError::io(&self.run.path, "reading a temporary run file", e))?;
            crate::pio::release(&self.file, at, bytes as u64);
            (self.pos, self.end, self.next) = (0, bytes, self.next + n);
        }
        let n = ((self.end - self.pos) / self.size).min(max as usize);
        let from = self.pos;
        self.pos += n * self.size;
        Ok(&self.buf[from..self.pos])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of 2-byte records `[run, i]` in `buckets` buckets, record i in bucket `i % buckets`.
    fn run(dir: &Path, r: u8, n: u8, buckets: usize) -> RunFile {
        let records: Vec<u8> = (0..n).flat_map(|i| [r, i]).collect();
        let mut pairs: Vec<Pair> = (0..n as u32).map(|i| Pair(u64::from(i), i)).collect();
        let starts = crate::sort::bucket_by(&mut pairs, &mut Vec::new(), buckets, |k| {
            k as usize % buckets
        });
        let maps = RunMaps::default();
        write_run(
            temp_name(dir, "t", "run"),
            &records,
            &pairs,
            &starts,
            2,
            64,
            &maps,
        )
        .unwrap()
    }

    #[test]
    fn a_mapped_run_file_is_written_like_a_buffered_one() {
        let dir = tempfile::tempdir().unwrap();
        // 3 MiB of 24-byte records in 7 buckets, gathered in chunks that end inside 2 MiB pages.
        let (rb, n) = (24, 131_072u32);
        let records: Vec<u8> = (0..n * rb as u32).map(|i| (i * 7 % 251) as u8).collect();
        let mut pairs: Vec<Pair> = (0..n).map(|i| Pair(u64::from(i * 31 % 7), i)).collect();
        let starts = crate::sort::bucket_by(&mut pairs, &mut Vec::new(), 7, |k| k as usize);
        let write = |maps: &RunMaps| {
            let path = temp_name(dir.path(), "t", "run");
            let run = write_run(path, &records, &pairs, &starts, rb, 1_000_000, maps).unwrap();
            (std::fs::read(&run.path).unwrap(), run)
        };
        let (written, _w) = write(&RunMaps(RunMaps::WRITTEN.into()));
        let maps = RunMaps::default();
        // A run of less than a 2 MiB page is written and leaves the question open.
        let small = write_run(
            temp_name(dir.path(), "t", "run"),
            &records,
            &pairs[..9],
            &[0, 9],
            rb,
            64,
            &maps,
        )
        .unwrap();
        assert_eq!(
            std::fs::read(&small.path).unwrap().len(),
            9 * (rb + KEY_BYTES) + 16
        );
        assert_eq!(maps.0.load(Ordering::Relaxed), RunMaps::UNKNOWN);
        let (first, _f) = write(&maps);
        let (second, _s) = write(&maps);
        // Through the mapping whatever pages the kernel gives (as once the first run found
        // 2 MiB ones), wherever the file system reserves space.
        let (mapped, _m) = write(&RunMaps(RunMaps::MAPPED.into()));
        assert_eq!(
            written.len(),
            n as usize * (rb + KEY_BYTES) + 8 * starts.len()
        );
        let keys: Vec<u8> = pairs.iter().flat_map(|p| { p.0 }.to_le_bytes()).collect();
        assert_eq!(written[n as usize * rb..][..keys.len()], keys);
        assert!(
            first == written && second == written && mapped == written,
            "a mapped run differs"
        );
        let (mut back, mut key) = (vec![0u8; rb], [0u64]);
        read_records(&_s, 5, &mut back, &mut key).unwrap();
        let i = pairs[5].1 as usize;
        assert_eq!(back, records[i * rb..(i + 1) * rb]);
        assert_eq!(key, [pairs[5].0]);
    }

    #[test]
    fn a_mapped_run_of_more_gather_tasks_than_the_window_is_written_whole() {
        let dir = tempfile::tempdir().unwrap();
        // 41 MiB of 24-byte records: 20 tasks of 2 MiB, released every 2 MiB, so at most two
        // tasks ahead of the first unfinished one.
        let (rb, n) = (24, 1_800_000u32);
        let records: Vec<u8> = (0..n * rb as u32).map(|i| (i * 13 % 253) as u8).collect();
        let mut pairs: Vec<Pair> = (0..n).map(|i| Pair(u64::from(i * 37 % 101), i)).collect();
        let starts = crate::sort::bucket_by(&mut pairs, &mut Vec::new(), 101, |k| k as usize);
        let write = |maps: RunMaps| {
            let path = temp_name(dir.path(), "t", "run");
            let run = write_run(path, &records, &pairs, &starts, rb, 2 << 20, &maps).unwrap();
            std::fs::read(&run.path).unwrap()
        };
        let written = write(RunMaps(RunMaps::WRITTEN.into()));
        let mapped = write(RunMaps(RunMaps::MAPPED.into()));
        assert_eq!(
            written.len(),
            n as usize * (rb + KEY_BYTES) + 8 * starts.len()
        );
        assert!(mapped == written, "a mapped run differs");
    }

    #[test]
    fn joined_runs_hold_each_bucket_of_every_run_in_run_order() {
        let dir = tempfile::tempdir().unwrap();
        let runs = vec![
            run(dir.path(), 0, 5, 3),
            run(dir.path(), 1, 0, 3),
            run(dir.path(), 2, 4, 3),
        ];
        assert_eq!(runs[0].starts(0..3).unwrap(), [0, 2, 4, 5]);
        let joined = join(&runs, temp_name(dir.path(), "t", "run"), 1 << 16).unwrap();
        assert_eq!((joined.count, joined.buckets), (9, 3));
        assert_eq!(joined.starts(0..3).unwrap(), [0, 4, 7, 9]);
        assert_eq!(joined.span(1..3).unwrap(), (4, 9));
        let (mut records, mut keys) = (vec![0u8; 18], vec![0u64; 9]);
        read_records(&joined, 0, &mut records, &mut keys).unwrap();
        let want = [
            [0, 0],
            [0, 3],
            [2, 0],
            [2, 3],
            [0, 1],
            [0, 4],
            [2, 1],
            [0, 2],
            [2, 2],
        ];
        assert_eq!(records, want.concat());
        // Keys (here a record's second byte) joined in the same order.
        assert_eq!(keys, want.map(|r| u64::from(r[1])));
        drop((runs, joined));
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "run files left"
        );
    }

    #[test]
    fn a_run_bucketed_part_by_part_comes_out_as_one_bucketed_whole() {
        let bucketing = Bucketing {
            shift: 8,
            base: 3,
            count: 64,
        };
        let mut rng = pointlet_core::shuffle::SplitMix64::new(7);
        // Keys below the base and past the last bucket too; parts of 256 to 756 pairs (the
        // 64 buckets take at most a quarter), some of a single bucket.
        let mut pairs = Vec::new();
        let mut parts = Vec::new();
        while pairs.len() < 20_000 {
            let len = 256 + (rng.next_u64() % 501) as usize;
            let one = rng.next_u64().is_multiple_of(4);
            let key = rng.next_u64() % (80 << 8);
            for _ in 0..len {
                let k = if one { key } else { rng.next_u64() % (80 << 8) };
                pairs.push(Pair(k, pairs.len() as u32));
            }
            parts.push(len);
        }
        let mut whole = pairs.clone();
        let want = crate::sort::bucket_by(&mut whole, &mut Vec::new(), 64, |k| bucketing.of(k));
        let mut run = Run {
            pairs,
            cells: Some(Vec::new()),
            ..Default::default()
        };
        let (mut tables, mut from) = (PartBuckets::default(), 0);
        for len in parts {
            let cells = run.cells.as_mut().unwrap();
            let part = &mut run.pairs[from..from + len];
            assert!(bucket_part(part, bucketing, &mut tables, cells));
            from += len;
        }
        let cells = run.cells.take().unwrap();
        assert!(
            cells.windows(2).any(|w| w[0].bucket > w[1].bucket),
            "one part only"
        );
        let starts = order_cells(&mut run.pairs, &mut run.scratch, &cells, 64);
        assert_eq!(starts, Some(want));
        assert_eq!(run.pairs, whole);
        // A part spread over more buckets than a quarter of its points is left as it is.
        let mut spread: Vec<Pair> = (0..40).map(|i| Pair(i << 8 | 5, i as u32)).collect();
        let (before, mut cells) = (spread.clone(), Vec::new());
        assert!(!bucket_part(
            &mut spread,
            bucketing,
            &mut tables,
            &mut cells
        ));
        assert_eq!((spread, cells), (before, Vec::new()));
        // Cells that do not describe the pairs: the run is bucketed pair by pair.
        let mut run = Run {
            pairs: whole.iter().rev().copied().collect(),
            cells: Some(vec![Cell { bucket: 0, len: 3 }]),
            ..Default::default()
        };
        let mut again = run.pairs.clone();
        let want = crate::sort::bucket_by(&mut again, &mut Vec::new(), 64, |k| bucketing.of(k));
        assert_eq!(bucket_run(&mut run, bucketing), want);
        assert_eq!(run.pairs, again);
    }
}
