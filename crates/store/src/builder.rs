//! The out-of-core store builder: quantize, key, sort under a RAM budget, write atomically.

use crate::emit::{EmitPlan, Emitter, RecordLayout, Source};
use crate::format::{self, Plan, Preamble, StoreHeader, PREAMBLE_LEN, VERSION};
use crate::runs::{self, Bucketing, Cell, PartBuckets, Run, RunFile, Spiller};
use crate::sort::Pair;
use crate::spilled::{GroupSettings, GroupSorter};
use crate::{meta, pio, pointlet_size, sort, StoreError};
use pointlet_core::codes::KeyGrid;
use pointlet_core::rows;
use pointlet_core::{
    Aabb, LasFields, PartedSource, PointBatch, PointLayout, Quantization, SourceMeta, Vlr,
};
use rayon::prelude::*;
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// The progress callback.
pub(crate) type Progress = Option<Arc<dyn Fn(BuildProgress) + Send + Sync>>;

/// How to build a store.
#[derive(Clone)]
pub struct BuildConfig {
    /// Bytes the builder may hold for sorting; larger inputs sort out of core.
    pub ram_budget: u64,
    /// Folder for temporary run files (default: beside the output).
    pub tmp_dir: Option<PathBuf>,
    /// M of paper eq. 1: the pointlet size is chosen to give about this many pointlets.
    pub target_pointlets: u64,
    /// Seed of the per-pointlet shuffles.
    pub seed: u64,
    /// Called now and then with how far the build is.
    pub progress: Option<Arc<dyn Fn(BuildProgress) + Send + Sync>>,
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            ram_budget: 1 << 30,
            tmp_dir: None,
            target_pointlets: 100_000,
            seed: 0,
            progress: None,
        }
    }
}

impl std::fmt::Debug for BuildConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BuildConfig")
            .field("ram_budget", &self.ram_budget)
            .field("tmp_dir", &self.tmp_dir)
            .field("target_pointlets", &self.target_pointlets)
            .field("seed", &self.seed)
            .field("progress", &self.progress.as_ref().map(|_| "callback"))
            .finish()
    }
}

/// What the builder is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuildPhase {
    /// Taking points (`done` = points pushed, `total` = points the source claims).
    Reading,
    /// Sorting in memory, or spilling the last run and re-keying runs (`done` = points).
    Sorting,
    /// Writing the store (`done` = points written).
    Writing,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BuildProgress {
    pub phase: BuildPhase,
    pub done: u64,
    pub total: u64,
}

/// What [`StoreBuilder::finish`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildSummary {
    pub points: u64,
    pub pointlets: u64,
    pub pointlet_size: u64,
    /// Sorted runs spilled to disk (0 when everything fit the budget).
    pub runs: usize,
    /// Bytes of the store file.
    pub bytes: u64,
    pub bounds: Aabb,
    /// Wall time of each stage.
    pub timings: BuildTimings,
}

/// Wall time of each stage of a build.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BuildTimings {
    /// From `create` to `finish`: taking the points (decoding parted sources), spilling runs.
    pub reading: std::time::Duration,
    /// Sorting what is in memory, or the last spill and re-keying, up to the first write.
    pub sorting: std::time::Duration,
    /// Sorting the buckets (in memory) or groups (out of core), shuffling and writing the store.
    pub writing: std::time::Duration,
    /// The time the writer threads spent in writes during `writing`, added over the threads
    /// (they wait for blocks otherwise); `None` when the store was written through a mapping,
    /// by the threads that computed it.
    pub writer_busy: Option<std::time::Duration>,
    /// Out of core, how the runs were spilled; `None` in memory.
    pub spills: Option<SpillTimings>,
}

/// Where an out-of-core build's reading stage went besides decoding: runs are put in bucket
/// order and written on spilling threads while the next run fills.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpillTimings {
    /// The time filling waited for a spilling thread to take the full run (reading stage).
    pub waited: std::time::Duration,
    /// Putting runs in bucket order, added over the runs (moving the cells the decoding tasks
    /// made, or scattering a run made otherwise on every core it gets).
    pub bucketing: std::time::Duration,
    /// Gathering runs into bucket order and writing them, added over the runs.
    pub writing: std::time::Duration,
}

/// A keying task's result: raw bounds of its points, or the first bad point and why.
type KeyChunk = Result<RawBounds, (usize, String)>;
/// Lowest and highest quantized coordinates.
type RawBounds = ([i32; 3], [i32; 3]);
/// A part decoded into the run: its raw bounds, and its cells where it was grouped by bucket.
type DecodedPart = (RawBounds, Option<Vec<Cell>>);

/// Bounds of no point: any point's widen them to its own.
const NO_BOUNDS: RawBounds = ([i32::MAX; 3], [i32::MIN; 3]);

/// The bounds of both `a` and `b`.
fn widen(a: RawBounds, b: RawBounds) -> RawBounds {
    (
        std::array::from_fn(|i| a.0[i].min(b.0[i])),
        std::array::from_fn(|i| a.1[i].max(b.1[i])),
    )
}

/// Points per parallel task when quantizing and keying a batch.
const KEY_TASK: usize = 1 << 14;
/// Stretches of buckets the in-memory writing stage sorts, one while the previous is written,
/// and the fewest pairs a stretch holds.
const SORT_STRETCHES: usize = 32;
const MIN_STRETCH: usize = 1 << 16;
/// Smallest run, whatever the budget (a tiny budget must still make progress).
const MIN_RUN_POINTS: usize = 1 << 12;

/// The temporary output; removed when dropped unless it was renamed into place.
struct TempOutput {
    path: PathBuf,
    keep: bool,
}

impl Drop for TempOutput {
    fn drop(&mut self) {
        if !self.keep {
            pointlet_core::cleanup::remove(&self.path);
        }
    }
}

/// Builds a store from batches of points. Dropping it without [`finish`](Self::finish), or
/// any error, removes the temporary output and every temporary run file.
pub struct StoreBuilder {
    // Declared before `temp` so the file is closed before the temporary is removed.
    file: Option<File>,
    temp: TempOutput,
    output: PathBuf,
    run_dir: PathBuf,
    stem: String,
    ram_budget: u64,
    target_pointlets: u64,
    seed: u64,
    progress: Option<Arc<dyn Fn(BuildProgress) + Send + Sync>>,
    quantization: Quantization,
    /// The key grid points are keyed with as they come: over the header bounds, snapped to the
    /// quantization grid. `finish` re-keys when the points' own bounds give another grid.
    grid: KeyGrid,
    key_bounds: Aabb,
    layout: PointLayout,
    las_point_format: u8,
    vlrs: Vec<Vlr>,
    las: Option<LasFields>,
    sources: Vec<String>,
    claimed: u64,
    rl: RecordLayout,
    run: Run,
    /// Whether the run's spare room is still the allocator's zero pages, written by no one:
    /// its parts then need no zeroing before they are decoded into it.
    run_untouched: bool,
    run_capacity: usize,
    /// Whether runs spill in the background ([`runs::SPILLERS`] at once) while one fills.
    overlap: bool,
    io_chunk: usize,
    spiller: Option<Spiller>,
    /// How run files are written (found out with the first).
    run_maps: std::sync::Arc<runs::RunMaps>,
    runs: Vec<RunFile>,
    pushed: u64,
    started: std::time::Instant,
    /// Bounds of the stored positions pushed so far.
    raw_bounds: RawBounds,
    failed: bool,
    write_map: WriteMapUse,
    /// The time filling waited for a spilling thread.
    spill_waited: std::time::Duration,
}

/// When an in-memory build writes the store through a mapping ([`pio::WriteMap`]).
#[derive(Clone, Copy, Debug)]
enum WriteMapUse {
    /// Where the kernel gives the file 2 MiB pages (faster than buffered writes only then).
    HugePages,
    /// Wherever the file can be mapped (tests: the mapping's path on any kernel).
    #[cfg_attr(not(test), allow(dead_code))]
    Always,
    /// Never (tests: the writer threads' path).
    #[cfg_attr(not(test), allow(dead_code))]
    Never,
}

/// Sizes derived from the budget: the I/O chunk, the points a run may hold, and whether runs
/// spill in the background (the budget shared by the filling run and those spilling) or not
/// (one run of the whole budget, when the source claims few enough points to fit it).
fn budget_sizes(budget: u64, record: usize, claimed: u64) -> (usize, usize, bool) {
    let io_chunk = (budget / 32).clamp(256 << 10, 16 << 20) as usize;
    // A run holds its records and (key, index) pairs, and the radix pass scatters the pairs
    // into a second array; on top come the pages of run files being gathered (at most three
    // I/O chunks a spilling thread, `runs::write_run`) or the output's being written.
    let per_point = (record + 2 * std::mem::size_of::<Pair>()) as u64;
    let room = budget.saturating_sub(3 * runs::SPILLERS as u64 * io_chunk as u64);
    let whole = room / per_point;
    let clamp = |v: u64| v.clamp(MIN_RUN_POINTS as u64, u32::MAX as u64) as usize;
    if claimed <= whole {
        (io_chunk, clamp(whole), false)
    } else {
        // Runs that spill also hold their parts' cells (`runs::bucket_part`).
        let cells = (std::mem::size_of::<Cell>() / runs::POINTS_PER_CELL) as u64;
        let runs = runs::SPILLERS as u64 + 1;
        (io_chunk, clamp(room / (per_point + cells) / runs), true)
    }
}

impl StoreBuilder {
    /// Starts a store at `output` for points described by `meta` (normally from
    /// [`merge_meta`](crate::merge_meta)); `sources` are recorded in the header.
    pub fn create(
        output: &Path,
        config: BuildConfig,
        meta: &SourceMeta,
        sources: Vec<String>,
    ) -> Result<Self, StoreError> {
        let b = &meta.bounds;
        let finite = b.min.iter().chain(b.max.iter()).all(|v| v.is_finite());
        if !finite || b.is_empty() {
            return Err(StoreError::build(
                output,
                format!(
                    "the source bounds {:?} to {:?} are empty or not finite",
                    b.min, b.max
                ),
            ));
        }
        let quantization = match meta.quantization {
            Some(q) => {
                q.validate()
                    .map_err(|e| StoreError::build(output, format!("quantization: {e}")))?;
                q
            }
            None => meta::choose_quantization(&[meta], b)
                .map_err(|e| StoreError::build(output, e.to_string()))?,
        };
        let layout = meta.layout;
        let las_point_format = meta
            .las_point_format
            .unwrap_or_else(|| layout.las_point_format());
        if las_point_format > 10 {
            return Err(StoreError::build(
                output,
                format!("LAS point format {las_point_format} does not exist"),
            ));
        }
        if let Some(d) = &config.tmp_dir {
            if !d.is_dir() {
                return Err(StoreError::build(
                    output,
                    format!("the temporary folder {} is not a folder", d.display()),
                ));
            }
        }
        let stem = output
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| StoreError::build(output, "the output path has no file name"))?;
        let out_dir = match output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let temp_path = runs::temp_name(&out_dir, &stem, "tmp");
        let file = pointlet_core::cleanup::create(
            &temp_path,
            OpenOptions::new().read(true).write(true).create_new(true),
        )
        .map_err(|e| {
            StoreError::io(
                output,
                format!("creating the temporary output {}", temp_path.display()),
                e,
            )
        })?;
        let temp = TempOutput {
            path: temp_path,
            keep: false,
        };
        // Snapping makes exact headers (and the exact bounds of PLY/XYZ pre-passes) give the
        // very box the quantized points span, so only wrong headers cost a second keying.
        let snap = |p: [f64; 3]| quantization.quantize(p).map(|r| quantization.dequantize(r));
        let key_bounds = match (snap(b.min), snap(b.max)) {
            (Ok(min), Ok(max)) => Aabb { min, max },
            _ => *b,
        };
        let rl = RecordLayout::new(&layout);
        let (io_chunk, run_capacity, overlap) =
            budget_sizes(config.ram_budget, rl.len, meta.point_count);
        Ok(StoreBuilder {
            file: Some(file),
            temp,
            output: output.to_path_buf(),
            run_dir: config.tmp_dir.unwrap_or(out_dir),
            stem,
            ram_budget: config.ram_budget,
            target_pointlets: config.target_pointlets.max(1),
            seed: config.seed,
            progress: config.progress,
            quantization,
            grid: KeyGrid::new(&key_bounds),
            key_bounds,
            layout,
            las_point_format,
            vlrs: meta.vlrs.clone(),
            las: meta.las.clone(),
            sources,
            claimed: meta.point_count,
            rl,
            run: Run::default(),
            run_untouched: false,
            run_capacity,
            overlap,
            io_chunk,
            spiller: None,
            run_maps: Default::default(),
            runs: Vec::new(),
            pushed: 0,
            started: std::time::Instant::now(),
            raw_bounds: NO_BOUNDS,
            failed: false,
            write_map: WriteMapUse::HugePages,
            spill_waited: std::time::Duration::ZERO,
        })
    }

    fn report(&self, phase: BuildPhase, done: u64, total: u64) {
        if let Some(p) = &self.progress {
            p(BuildProgress { phase, done, total });
        }
    }

    fn usable(&self) -> Result<(), StoreError> {
        if self.failed {
            return Err(StoreError::build(
                &self.output,
                "the build already failed; start a new one",
            ));
        }
        Ok(())
    }

    /// Adds points. The batch's layout must be a subset of the store's: missing columns are
    /// stored as zeros.
    pub fn push(&mut self, batch: &PointBatch) -> Result<(), StoreError> {
        self.usable()?;
        let r = self.push_inner(batch);
        if r.is_err() {
            self.failed = true;
        }
        r
    }

    /// Adds every point of a parted file, decoding its parts on all cores. Points keep the
    /// file's order (the store does not depend on how the parts were scheduled).
    pub fn push_parts(&mut self, source: &dyn PartedSource) -> Result<(), StoreError> {
        self.usable()?;
        let r = self.push_parts_inner(source);
        if r.is_err() {
            self.failed = true;
        }
        r
    }

    fn push_parts_inner(&mut self, source: &dyn PartedSource) -> Result<(), StoreError> {
        let sizes = source.part_sizes();
        let mut i = 0;
        while i < sizes.len() {
            let first = usize::try_from(sizes[i]).unwrap_or(usize::MAX);
            if first > self.run_capacity {
                // A part larger than a whole run (a tiny budget): take it as a batch.
                let mut batch = PointBatch::default();
                source
                    .decode_part(i, &mut batch, &mut Vec::new())
                    .map_err(StoreError::Input)?;
                self.push_inner(&batch)?;
                i += 1;
                continue;
            }
            let room = self.run_capacity - self.run.pairs.len();
            if first > room {
                self.spill()?;
                continue;
            }
            let (mut j, mut total) = (i, 0usize);
            while j < sizes.len() && total + sizes[j] as usize <= room {
                total += sizes[j] as usize;
                j += 1;
            }
            self.append_parts(source, i..j, total)?;
            i = j;
        }
        Ok(())
    }

    /// Decodes parts `range` (`total` points, which fit the run) in parallel, each straight
    /// into its place in the run: quantized, keyed and packed while still in the cache.
    fn append_parts(
        &mut self,
        source: &dyn PartedSource,
        range: std::ops::Range<usize>,
        total: usize,
    ) -> Result<(), StoreError> {
        let rb = self.rl.len;
        let n0 = self.run.pairs.len();
        self.reserve_room(total);
        // Each part's slices of the run's spare room, and its first run index: a part zeroes
        // its own slices before decoding into them, while they are in its core's cache (a
        // pass over a reused run first took 40 % of the out-of-core reading stage).
        let sizes = &source.part_sizes()[range.clone()];
        let mut jobs = Vec::with_capacity(sizes.len());
        let mut recs = &mut self.run.records.spare_capacity_mut()[..total * rb];
        let mut pairs = &mut self.run.pairs.spare_capacity_mut()[..total];
        let mut at = n0;
        for (part, &size) in range.clone().zip(sizes) {
            let size = size as usize;
            let (r, rest_r) = std::mem::take(&mut recs).split_at_mut(size * rb);
            let (p, rest_p) = std::mem::take(&mut pairs).split_at_mut(size);
            jobs.push((part, at, r, p));
            (recs, pairs, at) = (rest_r, rest_p, at + size);
        }
        // Where runs spill, each part is put in bucket order here, on the pool, and the
        // spilling thread only moves whole cells (`runs::bucket_run`).
        let bucketing = self.overlap.then(Bucketing::top);
        if n0 == 0 {
            self.run.cells = bucketing.map(|_| self.run.cells.take().unwrap_or_default());
        }
        let (q, grid, rl, want) = (self.quantization, self.grid, &self.rl, self.layout);
        let (pushed, claimed, progress) = (self.pushed, self.claimed, &self.progress);
        let output = &self.output;
        let untouched = self.run_untouched;
        let done = AtomicU64::new(0);
        let results: Vec<Result<DecodedPart, StoreError>> = jobs
            .into_par_iter()
            .map_init(
                || (PointBatch::default(), Vec::new(), PartBuckets::default()),
                |(batch, scratch, tables), (part, at, recs, pairs)| {
                    let (recs, pairs) = if untouched {
                        // SAFETY: the run's spare room is zero pages from the allocator that
                        // nothing wrote since (`run_untouched`), and zero bytes are valid.
                        unsafe { (assume_zeroed(recs), assume_zeroed(pairs)) }
                    } else {
                        (zeroed_in_place(recs), zeroed_in_place(pairs))
                    };
                    // Parts that store positions as integers of the store's quantization decode
                    // straight into their rows: no f64 round trip, no columns in between.
                    let seq = pushed + (at - n0) as u64;
                    // Each stretch of rows is keyed as soon as it is decoded, while in the cache.
                    let (mut bounds, mut keyed) = (NO_BOUNDS, 0);
                    let mut key_stretch = |first: usize, rows: &[u8]| {
                        let n = rows.len() / rl.len;
                        if let Some(pairs) = pairs.get_mut(first..first + n) {
                            let b = key_rows(rows, q, grid, rl.len, at + first, pairs);
                            (bounds, keyed) = (widen(bounds, b), keyed + n);
                        }
                    };
                    let bounds = if source
                        .decode_part_rows(part, &q, &rl.row, recs, scratch, &mut key_stretch)
                        .map_err(StoreError::Input)?
                    {
                        if keyed != pairs.len() {
                            return Err(StoreError::build(
                                output,
                                format!(
                                    "internal error: part {part} handed over {keyed} rows of {}",
                                    pairs.len()
                                ),
                            ));
                        }
                        bounds
                    } else {
                        source
                            .decode_part(part, batch, scratch)
                            .map_err(StoreError::Input)?;
                        if batch.len() != pairs.len() || batch.layout.union(want) != want {
                            return Err(StoreError::build(
                                output,
                                format!(
                                    "internal error: part {part} decoded to {} points of {:?}, \
                                     expected {} of {want:?}",
                                    batch.len(),
                                    batch.layout,
                                    pairs.len()
                                ),
                            ));
                        }
                        key_and_pack(batch, 0, q, grid, rl, at, recs, pairs)
                            .map_err(|(i, m)| bad_point(output, seq + i as u64, m))?
                    };
                    let d = done.fetch_add(pairs.len() as u64, Ordering::Relaxed);
                    if let Some(p) = progress {
                        let now = pushed + d + pairs.len() as u64;
                        p(BuildProgress {
                            phase: BuildPhase::Reading,
                            done: now,
                            total: claimed.max(now),
                        });
                    }
                    let mut cells = Vec::new();
                    let grouped = match bucketing {
                        Some(b) => runs::bucket_part(pairs, b, tables, &mut cells),
                        None => false,
                    };
                    Ok((bounds, grouped.then_some(cells)))
                },
            )
            .collect();
        let parts = results.into_iter().collect::<Result<Vec<_>, _>>()?;
        // SAFETY: every part zeroed and then filled its slices, which tile the `total` points
        // after the first `n0`, within the capacity.
        unsafe {
            self.run.records.set_len((n0 + total) * rb);
            self.run.pairs.set_len(n0 + total);
        }
        for (bounds, cells) in parts {
            self.raw_bounds = widen(self.raw_bounds, bounds);
            match (self.run.cells.as_mut(), cells) {
                (Some(run_cells), Some(cells)) => run_cells.extend(cells),
                // A part left in input order: the run is scattered whole when spilled.
                _ => self.run.cells = None,
            }
        }
        self.pushed += total as u64;
        Ok(())
    }

    fn push_inner(&mut self, batch: &PointBatch) -> Result<(), StoreError> {
        batch
            .check_shape()
            .map_err(|e| StoreError::build(&self.output, format!("bad point batch: {e}")))?;
        let (have, want) = (batch.layout, self.layout);
        if have.union(want) != want {
            return Err(StoreError::build(
                &self.output,
                format!("a batch has attributes the store was not created with: {have:?} is not within {want:?}"),
            ));
        }
        let mut start = 0;
        while start < batch.len() {
            if self.run.pairs.len() >= self.run_capacity {
                self.spill()?;
            }
            let take = (batch.len() - start).min(self.run_capacity - self.run.pairs.len());
            self.append(batch, start, take)?;
            start += take;
        }
        self.report(
            BuildPhase::Reading,
            self.pushed,
            self.claimed.max(self.pushed),
        );
        Ok(())
    }

    /// Lengthens the run by `add` zeroed points ([`reserve_room`](Self::reserve_room), then
    /// zero-filled on every core).
    fn make_room(&mut self, add: usize) {
        let (rb, n0) = (self.rl.len, self.run.pairs.len());
        self.reserve_room(add);
        extend_zeroed(&mut self.run.pairs, n0 + add);
        extend_zeroed(&mut self.run.records, (n0 + add) * rb);
    }

    /// Makes room for `add` more points in the run's columns without lengthening them. A
    /// fresh run's columns come from the allocator's zeroed pages, as long as the source still
    /// claims points (no pass over memory); a run in use grows by doubling.
    fn reserve_room(&mut self, add: usize) {
        let (rb, n0, cap) = (self.rl.len, self.run.pairs.len(), self.run_capacity);
        let expected = n0.saturating_add(self.claimed.saturating_sub(self.pushed) as usize);
        if self.run.records.capacity() == 0 {
            let target = add.max(expected.min(cap));
            self.run.records = vec![0; target * rb];
            self.run.records.clear();
            self.run.pairs = Pair::zeroed(target);
            self.run.pairs.clear();
            pio::huge_pages(&self.run.records);
            pio::huge_pages(&self.run.pairs);
            self.run_untouched = true;
        }
        let pairs_moved = Self::grow(&mut self.run.pairs, n0 + add, expected, cap);
        let records_moved = Self::grow(
            &mut self.run.records,
            (n0 + add) * rb,
            expected.saturating_mul(rb),
            cap * rb,
        );
        if pairs_moved || records_moved {
            self.run_untouched = false;
        }
    }

    /// Grows a run column to hold `need` items: at once to `expected` (what the source still
    /// claims), then by doubling, never past `cap` (the run's capacity).
    /// Whether it reallocated.
    fn grow<T>(v: &mut Vec<T>, need: usize, expected: usize, cap: usize) -> bool {
        if v.capacity() >= need {
            return false;
        }
        let target = need.max(expected.min(cap)).max((2 * v.capacity()).min(cap));
        v.reserve_exact(target - v.len());
        pio::huge_pages(v);
        true
    }

    /// Quantizes, keys and packs points `[start, start + n)` of `batch` into the run.
    fn append(&mut self, batch: &PointBatch, start: usize, n: usize) -> Result<(), StoreError> {
        let rb = self.rl.len;
        let n0 = self.run.pairs.len();
        // These pairs are in input order: the run is bucketed whole when spilled.
        self.run.cells = None;
        self.make_room(n);
        let (q, grid, rl) = (self.quantization, self.grid, &self.rl);
        let results: Vec<KeyChunk> = self.run.records[n0 * rb..]
            .par_chunks_mut(KEY_TASK * rb)
            .zip(self.run.pairs[n0..].par_chunks_mut(KEY_TASK))
            .enumerate()
            .map(|(t, (recs, pairs))| {
                let from = start + t * KEY_TASK;
                key_and_pack(batch, from, q, grid, rl, n0 + t * KEY_TASK, recs, pairs)
                    .map_err(|(i, m)| (from + i, m))
            })
            .collect();
        for r in results {
            match r {
                Ok(bounds) => {
                    self.raw_bounds = widen(self.raw_bounds, bounds);
                }
                Err((i, message)) => {
                    return Err(bad_point(
                        &self.output,
                        self.pushed + (i - start) as u64,
                        message,
                    ));
                }
            }
        }
        self.pushed += n as u64;
        Ok(())
    }

    /// Hands the in-memory run to the spiller, which sorts it and writes it to a run file.
    fn spill(&mut self) -> Result<(), StoreError> {
        if self.run.pairs.is_empty() {
            return Ok(());
        }
        let (rb, chunk) = (self.rl.len, self.io_chunk);
        let spiller = self
            .spiller
            .get_or_insert_with(|| Spiller::new(rb, chunk, self.run_maps.clone()));
        // At most SPILLERS runs are in flight: when all are, the oldest must be on disk now.
        let reuse = if spiller.in_flight() < runs::SPILLERS {
            Run::default()
        } else {
            let from = std::time::Instant::now();
            let oldest = spiller.wait(&self.output);
            self.spill_waited += from.elapsed();
            match oldest? {
                Some((file, emptied)) => {
                    self.runs.push(file);
                    emptied
                }
                None => Run::default(),
            }
        };
        let full = std::mem::replace(&mut self.run, reuse);
        self.run_untouched = false;
        spiller.start(runs::temp_name(&self.run_dir, &self.stem, "run"), full)?;
        if !self.overlap {
            self.drain_spills()?;
        }
        Ok(())
    }

    /// Waits until every started run is on disk.
    fn drain_spills(&mut self) -> Result<(), StoreError> {
        if let Some(spiller) = self.spiller.as_mut() {
            while let Some((file, emptied)) = spiller.wait(&self.output)? {
                self.runs.push(file);
                if self.run.pairs.capacity() == 0 {
                    self.run = emptied;
                }
            }
        }
        Ok(())
    }

    /// Sorts what is left, writes the store and moves it into place.
    pub fn finish(mut self) -> Result<BuildSummary, StoreError> {
        self.usable()?;
        let sorting_from = std::time::Instant::now();
        let mut timings = BuildTimings {
            reading: sorting_from - self.started,
            ..Default::default()
        };
        let n = self.pushed;
        if n == 0 {
            return Err(StoreError::build(
                &self.output,
                "no points: the inputs gave no points",
            ));
        }
        // Everything is on disk once a run was spilled; the groups then need the budget.
        self.report(BuildPhase::Sorting, 0, n);
        let spilled = self.spiller.is_some();
        if spilled {
            self.spill()?;
            self.drain_spills()?;
            if let Some(s) = &self.spiller {
                let (bucketing, writing) = s.busy();
                timings.spills = Some(SpillTimings {
                    waited: self.spill_waited,
                    bucketing,
                    writing,
                });
            }
            self.spiller = None;
            self.run = Run::default();
            self.report(BuildPhase::Sorting, n, n);
        }
        let runs_spilled = self.runs.len();
        let k = pointlet_size(n, self.target_pointlets);
        let pointlets = n.div_ceil(k);
        let bounds = Aabb {
            min: self.quantization.dequantize(self.raw_bounds.0),
            max: self.quantization.dequantize(self.raw_bounds.1),
        };
        if bounds.bounding_cube() != self.key_bounds.bounding_cube() {
            // The header bounds were wrong: keys over them would make pointlets too large.
            self.grid = KeyGrid::new(&bounds);
            if spilled {
                self.rekey_runs()?;
            } else {
                rekey(&mut self.run, self.rl.len, self.quantization, self.grid);
            }
        }
        let mut header = StoreHeader {
            version: VERSION,
            points: n,
            pointlets,
            pointlet_size: k,
            target_pointlets: self.target_pointlets,
            seed: self.seed,
            bounds,
            // The same cube as the grid used, whichever box gave it.
            key_bounds: bounds,
            quantization: self.quantization,
            layout: self.layout,
            las_point_format: self.las_point_format,
            vlrs: std::mem::take(&mut self.vlrs),
            las: self.las.take(),
            sources: std::mem::take(&mut self.sources),
            streams: Vec::new(),
        };
        let (plan, header_bytes) = self.lay_out(&mut header)?;
        let file = self
            .file
            .take()
            .ok_or_else(|| StoreError::build(&self.output, "the output is already closed"))?;
        // Errors name the output the user asked for, not the temporary file.
        let output = self.output.clone();
        let io = |what: &str| {
            let what = what.to_string();
            let p = output.clone();
            move |e| StoreError::io(&p, what, e)
        };
        let reserved = pio::allocate(&file, plan.file_len)
            .map_err(io("reserving disk space for the output"))?;
        pio::write_all_at(&file, &header_bytes, PREAMBLE_LEN).map_err(io("writing the header"))?;
        // Blocks go out in order, a stretch (in memory) or a group (out of core) at a time,
        // and the pages of the last one leave the process as the next is computed.
        let map = match self.write_map {
            WriteMapUse::Never => None,
            // Out of core, a group writes a slice of every stream: slices of less than a couple
            // of 2 MiB pages fault and zero-fill the same pages group after group (dev, 20 M
            // points at a 16 MiB budget: 5.4–6.8 s against 1.7–2.6 s through the writers, and
            // twice the memory), so small groups go through the writer threads.
            WriteMapUse::HugePages if spilled && !groups_span_pages(self.ram_budget, &self.rl) => {
                None
            }
            WriteMapUse::HugePages => pio::WriteMap::new(&file, plan.file_len, reserved, true),
            WriteMapUse::Always => pio::WriteMap::new(&file, plan.file_len, reserved, false),
        };
        let out = EmitPlan {
            file: &file,
            path: &output,
            plan: &plan,
            rl: &self.rl,
            k,
            points: n,
            seed: self.seed,
            quantization: self.quantization,
            map: map.as_ref(),
        };
        let rb = self.rl.len;
        let progress = self.progress.clone();
        let writing_from;
        // Into a mapping a whole stretch or group is one block: every core on it, no waits
        // for a block's last pointlets (1.7 against 2.1 s, GPU machine); buffered, blocks of
        // about an I/O chunk keep the writers' memory bounded.
        let step = if map.is_some() {
            pointlets
        } else {
            (self.io_chunk as u64 / (k * rb as u64)).max(1)
        };
        let ((), table_crc, checksums_crc, writer_busy) = if spilled {
            let runs = runs::join_runs(
                std::mem::take(&mut self.runs),
                (self.ram_budget / 2) as usize,
                &self.run_dir,
                &self.stem,
            )?;
            writing_from = std::time::Instant::now();
            timings.sorting = writing_from - sorting_from;
            let settings = GroupSettings {
                quantization: self.quantization,
                grid: self.grid,
                capacity: group_capacity(self.ram_budget, map.is_some(), &self.rl),
                step,
                io_chunk: self.io_chunk,
                run_dir: &self.run_dir,
                run_maps: &self.run_maps,
                stem: &self.stem,
                progress: progress.clone(),
            };
            let written = Emitter::run(&out, |em| {
                let mut groups = GroupSorter::new(em, settings);
                groups.walk(&runs, Bucketing::top())?;
                groups.finish()
            });
            // Removing a run frees what is left of its page cache: in parallel.
            runs.into_par_iter().for_each(drop);
            written?
        } else {
            let (records, pairs) = (&self.run.records, &mut self.run.pairs);
            let mut scratch = Vec::new();
            let buckets = sort::partition(pairs, &mut scratch);
            pio::discard(scratch);
            writing_from = std::time::Instant::now();
            timings.sorting = writing_from - sorting_from;
            // Buckets are sorted a stretch at a time, each while the blocks of the one before
            // are packed and written: sorting each block's few buckets just before it left most
            // cores idle (4.9 of a 5.6 s writing stage, GPU machine, docs/BENCHMARKS.md).
            let stretch = (n as usize / SORT_STRETCHES).max(MIN_STRETCH);
            let stretch_end = |from: usize| {
                let to = buckets.starts[from] + stretch;
                (buckets.covering(to.min(n as usize)) + 1).min(buckets.len())
            };
            Emitter::run(&out, |em| {
                let mut sorted = stretch_end(0);
                sort::sort_buckets(pairs, &buckets, 0..sorted);
                let mut p0 = 0;
                while p0 < pointlets {
                    let ready = buckets.starts[sorted];
                    let (done, rest) = pairs.split_at_mut(ready);
                    // Past the last bucket this stays at the end: nothing left to sort.
                    let next = stretch_end(sorted);
                    let emit = || -> Result<u64, StoreError> {
                        // The last stretch's pages leave the process while this one computes.
                        em.release_before(p0);
                        let source = Source {
                            records,
                            order: done,
                            first: 0,
                        };
                        let whole = if ready as u64 == n {
                            pointlets
                        } else {
                            ready as u64 / k
                        };
                        let mut p = p0;
                        while p < whole {
                            let p1 = (p + step).min(whole);
                            em.block(p, p1, &source)?;
                            report(&progress, BuildPhase::Writing, (p1 * k).min(n), n);
                            p = p1;
                        }
                        Ok(p)
                    };
                    let sort = || sort::sort_buckets_at(rest, ready, &buckets, sorted..next);
                    let (emitted, ()) = rayon::join(emit, sort);
                    p0 = emitted?;
                    if next == sorted && p0 < pointlets {
                        return Err(StoreError::build(
                            em.path(),
                            "internal error: pointlets left after every bucket was sorted",
                        ));
                    }
                    sorted = next;
                }
                sort::release_second_arrays();
                Ok(())
            })?
        };
        // Unmapped before the preamble is written and the file closed.
        drop(map);
        pio::discard(std::mem::take(&mut self.run.records));
        pio::discard(std::mem::take(&mut self.run.pairs));
        let preamble = Preamble {
            version: VERSION,
            file_len: plan.file_len,
            header: plan.header,
            table: plan.table,
            checksums: plan.checksums,
            data_offset: plan.data_offset,
            header_crc: crc32fast::hash(&header_bytes),
            table_crc,
            checksums_crc,
        };
        pio::write_all_at(&file, &preamble.encode(), 0).map_err(io("writing the preamble"))?;
        // No fsync: it would wait for the disk (seconds per GB) where the page cache is done;
        // a store torn by a power loss fails its checksums instead of being read as good.
        // Closed before the rename (wasm32 has no files: its File has no Drop).
        #[cfg_attr(target_arch = "wasm32", allow(clippy::drop_non_drop))]
        drop(file);
        pointlet_core::cleanup::persist(&self.temp.path, &self.output).map_err(|e| {
            StoreError::io(
                &self.output,
                format!("moving {} into place", self.temp.path.display()),
                e,
            )
        })?;
        self.temp.keep = true;
        Ok(BuildSummary {
            points: n,
            pointlets,
            pointlet_size: k,
            runs: runs_spilled,
            bytes: plan.file_len,
            bounds,
            timings: BuildTimings {
                writing: writing_from.elapsed(),
                writer_busy,
                ..timings
            },
        })
    }

    /// Re-keys every spilled run with the current grid, one run in memory at a time. Points
    /// that share a key keep their order within the run (their order from the first keying).
    fn rekey_runs(&mut self) -> Result<(), StoreError> {
        let rb = self.rl.len;
        let total: u64 = self.runs.iter().map(|r| r.count).sum();
        let mut done = 0;
        for old in std::mem::take(&mut self.runs) {
            let mut run = runs::read_run(&old)?;
            done += old.count;
            drop(old);
            rekey(&mut run, rb, self.quantization, self.grid);
            let starts = runs::bucket_run(&mut run, Bucketing::top());
            let path = runs::temp_name(&self.run_dir, &self.stem, "run");
            self.runs.push(runs::write_run(
                path,
                &run.records,
                &run.pairs,
                &starts,
                rb,
                self.io_chunk,
                &self.run_maps,
            )?);
            self.report(BuildPhase::Sorting, done, total);
        }
        Ok(())
    }

    /// Fixes the header's stream offsets, which depend on the header's own length.
    fn lay_out(&self, header: &mut StoreHeader) -> Result<(Plan, Vec<u8>), StoreError> {
        let mut header_len = 0u64;
        // Longer headers push the streams further, which can only lengthen the header, so
        // this converges; a few rounds are always enough.
        for _ in 0..16 {
            let plan = format::plan(header_len, header.points, header.pointlets, &header.layout)
                .ok_or_else(|| {
                    StoreError::build(&self.output, "the store would exceed 2^64 bytes")
                })?;
            header.streams = plan.streams.clone();
            let bytes =
                format::encode_header(header).map_err(|e| StoreError::build(&self.output, e))?;
            if bytes.len() as u64 == header_len {
                if header_len > format::MAX_HEADER_LEN {
                    return Err(StoreError::build(
                        &self.output,
                        format!(
                            "the header would take {header_len} bytes (too many VLRs or sources)"
                        ),
                    ));
                }
                return Ok((plan, bytes));
            }
            header_len = bytes.len() as u64;
        }
        Err(StoreError::build(
            &self.output,
            "internal error: the header layout does not settle",
        ))
    }
}

/// `s` zeroed, as initialized items (zero bytes are a valid `T`).
fn zeroed_in_place<T: bytemuck::Zeroable>(s: &mut [std::mem::MaybeUninit<T>]) -> &mut [T] {
    // SAFETY: every byte of `s` is zeroed here, and all-zero bytes are a valid `T`.
    unsafe {
        std::ptr::write_bytes(s.as_mut_ptr(), 0, s.len());
        assume_zeroed(s)
    }
}

/// `s` as initialized items, without writing it.
///
/// # Safety
/// Every byte of `s` must be zero already (and all-zero bytes a valid `T`).
unsafe fn assume_zeroed<T: bytemuck::Zeroable>(s: &mut [std::mem::MaybeUninit<T>]) -> &mut [T] {
    // SAFETY: the caller's promise: the bytes are initialized, and zero.
    unsafe { &mut *(s as *mut [std::mem::MaybeUninit<T>] as *mut [T]) }
}

/// Lengthens `v` to `len` with zeros written on every core: a run of gigabytes would
/// otherwise be zeroed (and its pages faulted in) by one thread.
fn extend_zeroed<T: Copy + Default + Send + Sync>(v: &mut Vec<T>, len: usize) {
    if len > v.len() {
        let add = len - v.len();
        v.par_extend(rayon::iter::repeat_n(T::default(), add));
    }
}

fn bad_point(output: &Path, seq: u64, message: String) -> StoreError {
    StoreError::build(output, format!("input point {seq} {message}"))
}

pub(crate) fn report(progress: &Progress, phase: BuildPhase, done: u64, total: u64) {
    if let Some(p) = progress {
        p(BuildProgress { phase, done, total });
    }
}

/// Records a group of the out-of-core build's last phase holds at most: two groups (one
/// emitted while the next is read and sorted), their pairs, the sort's second array, the keys
/// read with the next, and the mapped pages of the group being written. A mapping also keeps up
/// to two partly written 2 MiB pages of each stream (a byte stream's page spans 2 M points,
/// several groups).
fn group_capacity(budget: u64, mapped: bool, rl: &RecordLayout) -> usize {
    let per_point = (3 * rl.len + 3 * std::mem::size_of::<Pair>() + runs::KEY_BYTES) as u64;
    let pages = if mapped {
        2 * pio::HUGE as u64 * rl.fields.len() as u64
    } else {
        0
    };
    (budget.saturating_sub(pages) / per_point).clamp(MIN_RUN_POINTS as u64, u32::MAX as u64)
        as usize
}

/// Whether an out-of-core group written through the mapping spans at least two 2 MiB pages
/// of its smallest stream (at a 1 GiB budget it does, and the mapping beat the writer threads
/// by 8 % on the GPU machine).
fn groups_span_pages(budget: u64, rl: &RecordLayout) -> bool {
    let capacity = group_capacity(budget, true, rl) as u64;
    let smallest = rl.fields.iter().map(|f| f.2 as u64).min().unwrap_or(1);
    capacity * smallest >= 2 * pio::HUGE as u64
}

/// Blocks of points keyed and packed at a time: small enough that their records stay in the
/// L2 cache while packed column by column.
const BLOCK: usize = 2048;

/// Quantizes, keys and packs points `from..from + pairs.len()` of `batch` into `recs` and
/// `pairs` (run indices from `index`). Returns their raw bounds, or the offset (from `from`)
/// of the first bad point and why.
#[allow(clippy::too_many_arguments)]
fn key_and_pack(
    batch: &PointBatch,
    from: usize,
    q: Quantization,
    grid: KeyGrid,
    rl: &RecordLayout,
    index: usize,
    recs: &mut [u8],
    pairs: &mut [Pair],
) -> KeyChunk {
    let mut bounds = NO_BOUNDS;
    let mut raw = [[0i32; 3]; BLOCK];
    for (b, (recs, pairs)) in recs
        .chunks_mut(BLOCK * rl.len)
        .zip(pairs.chunks_mut(BLOCK))
        .enumerate()
    {
        let first = b * BLOCK;
        let raw = &mut raw[..pairs.len()];
        let rows = from + first..from + first + raw.len();
        for (j, (r, p)) in raw.iter_mut().zip(&batch.xyz[rows]).enumerate() {
            *r = q
                .quantize(*p)
                .map_err(|e| (first + j, format!("at ({}, {}, {}): {e}", p[0], p[1], p[2])))?;
        }
        key_block(raw, q, grid, index + first, pairs, &mut bounds);
        rl.row.pack(batch, from + first, raw, recs);
    }
    Ok(bounds)
}

/// Keys the `rb`-byte rows `recs` (whose positions are the stored integers) into `pairs` (run
/// indices from `index`), a block at a time on the stack; their raw bounds.
pub(crate) fn key_rows(
    recs: &[u8],
    q: Quantization,
    grid: KeyGrid,
    rb: usize,
    index: usize,
    pairs: &mut [Pair],
) -> RawBounds {
    let mut bounds = NO_BOUNDS;
    let mut raw = [[0i32; 3]; BLOCK];
    for (b, (recs, pairs)) in recs
        .chunks(BLOCK * rb)
        .zip(pairs.chunks_mut(BLOCK))
        .enumerate()
    {
        let raw = &mut raw[..pairs.len()];
        for (r, rec) in raw.iter_mut().zip(recs.chunks_exact(rb)) {
            *r = rows::row_position(rec);
        }
        key_block(raw, q, grid, index + b * BLOCK, pairs, &mut bounds);
    }
    bounds
}

/// Keys the stored positions `raw` into `pairs` (run indices from `index`) and widens
/// `bounds` to them.
fn key_block(
    raw: &[[i32; 3]],
    q: Quantization,
    grid: KeyGrid,
    index: usize,
    pairs: &mut [Pair],
    bounds: &mut RawBounds,
) {
    let (lo, hi) = bounds;
    for r in raw {
        for a in 0..3 {
            lo[a] = lo[a].min(r[a]);
            hi[a] = hi[a].max(r[a]);
        }
    }
    let mut keys = [0u64; BLOCK];
    let keys = &mut keys[..raw.len()];
    grid.hilbert_raw(&q, raw, keys);
    for (i, (pair, &key)) in pairs.iter_mut().zip(keys.iter()).enumerate() {
        *pair = Pair(key, (index + i) as u32);
    }
}

/// Recomputes the keys of a run from its records' quantized positions (their first 12 bytes).
fn rekey(run: &mut Run, rb: usize, q: Quantization, grid: KeyGrid) {
    let records = &run.records;
    run.pairs.par_chunks_mut(BLOCK).for_each(|pairs| {
        let (mut raw, mut keys) = ([[0i32; 3]; BLOCK], [0u64; BLOCK]);
        let (raw, keys) = (&mut raw[..pairs.len()], &mut keys[..pairs.len()]);
        for (r, pair) in raw.iter_mut().zip(pairs.iter()) {
            let at = pair.1 as usize * rb;
            *r = rows::row_position(&records[at..at + rb]);
        }
        grid.hilbert_raw(&q, raw, keys);
        for (pair, &key) in pairs.iter_mut().zip(keys.iter()) {
            pair.0 = key;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::shuffle::SplitMix64;

    #[test]
    fn out_of_core_writes_through_the_mapping_only_when_groups_span_its_pages() {
        // Positions, the one-byte streams (classes, returns, flags…), times and colours.
        let rl = RecordLayout::new(&PointLayout {
            gps_time: true,
            rgb: true,
            ..Default::default()
        });
        assert!(rl.fields.iter().any(|f| f.2 == 1));
        assert!(groups_span_pages(1 << 30, &rl));
        assert!(!groups_span_pages(256 << 20, &rl));
        assert!(!groups_span_pages(16 << 20, &rl));
    }

    /// Builds `n` clustered points with `write_map`; the store's bytes and whether the writer
    /// threads wrote them.
    fn build(dir: &Path, n: usize, write_map: WriteMapUse) -> (Vec<u8>, bool) {
        let layout = PointLayout {
            gps_time: true,
            rgb: true,
            ..Default::default()
        };
        let bounds = Aabb {
            min: [0.0; 3],
            max: [1000.0, 1000.0, 50.0],
        };
        let meta = SourceMeta {
            format: "synthetic".into(),
            point_count: n as u64,
            bounds,
            quantization: Some(Quantization {
                scale: [0.001; 3],
                offset: [0.0; 3],
            }),
            layout,
            las_point_format: None,
            vlrs: Vec::new(),
            las: None,
        };
        let out = dir.join(format!("{write_map:?}.pointlet"));
        let config = BuildConfig {
            ram_budget: 1 << 30,
            target_pointlets: 2_000,
            ..Default::default()
        };
        let mut builder =
            StoreBuilder::create(&out, config, &meta, vec!["synthetic".into()]).expect("create");
        builder.write_map = write_map;
        let mut rng = SplitMix64::new(5);
        let mut batch = PointBatch::with_capacity(layout, n);
        for i in 0..n {
            // A few dense clusters, as surfaces fill a small share of the key space.
            let c = rng.below(6) as f64 * 150.0;
            batch.xyz.push([
                c + rng.unit_f64() * 40.0,
                c + rng.unit_f64() * 40.0,
                rng.unit_f64() * 5.0,
            ]);
            batch.intensity.push(i as u16);
            batch.returns.push(0x11);
            batch.flags.push(0);
            batch.classification.push((i % 7) as u8);
            batch.scan_angle.push(0.0);
            batch.user_data.push(0);
            batch.point_source_id.push(1);
            batch.gps_time.push(i as f64);
            batch.rgb.push([i as u16, 0, 7]);
        }
        builder.push(&batch).expect("push");
        let summary = builder.finish().expect("finish");
        assert_eq!(summary.runs, 0, "built in memory");
        let bytes = std::fs::read(&out).expect("read back");
        (bytes, summary.timings.writer_busy.is_some())
    }

    #[test]
    fn a_mapped_store_file_is_written_like_a_buffered_one() {
        let dir = tempfile::tempdir().expect("tempdir");
        // Several sort stretches and blocks, a store of several 2 MiB pages.
        let n = 400_000;
        let (buffered, by_writers) = build(dir.path(), n, WriteMapUse::Never);
        assert!(by_writers);
        let (mapped, by_writers) = build(dir.path(), n, WriteMapUse::Always);
        // On Linux, a file system that reserves space (ext4, xfs, btrfs, tmpfs) takes the mapping.
        let probe = File::create(dir.path().join("probe")).expect("probe file");
        let reserves = pio::allocate(&probe, 1 << 20).expect("sized");
        if cfg!(target_os = "linux") && reserves {
            assert!(!by_writers, "the store was not written through a mapping");
        }
        assert!(buffered == mapped, "the mapped store differs");
        let (either, _) = build(dir.path(), n, WriteMapUse::HugePages);
        assert!(buffered == either, "the default build differs");
    }
}
