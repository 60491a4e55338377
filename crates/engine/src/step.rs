//! The residency step (virtualized paper §III-C) on a thread of its own: from the latest LoD
//! feedback it requests points from the RAM cache, decides which pages to upload and which to
//! evict, and packs the uploads into a batch that the render thread hands to the GPU with its
//! next frame. The render thread never waits for a step: it draws with the batches it has.
//!
//! The step's model of the page pool runs at most one batch ahead of the GPU: a new step starts
//! only after the render thread has queued the previous step's batch, so every step begins
//! from the state the GPU will have once that batch is flushed.

use crate::residency::ResidencySet;
use crate::source::StoreSource;
use crate::EngineError;
use pointlet_gpu::{PageBatch, PageJob, PointEncoding};
use pointlet_stream::{CacheStats, RamCache};
use rayon::prelude::*;
use std::sync::mpsc::{self, Receiver, Sender, TryRecvError};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Instant;

/// Names of [`StepReport::parts_ms`], in order.
pub const RESIDENCY_PARTS: [&str; 5] = [
    "RAM requests",
    "window upkeep",
    "planning",
    "copy to staging",
    "publish",
];

/// What the render thread hands to a step: the newest LoD feedback and how the view stands.
pub(crate) struct Tick {
    pub frame: u64,
    pub requested: Arc<Vec<u32>>,
    pub drawn: Arc<Vec<u32>>,
    pub feedback_frame: u64,
    /// The camera is still and frames add to the kept framebuffer.
    pub accumulate: bool,
    /// The feedback comes from an accumulating frame: drawn pages may leave the GPU.
    pub drawn_valid: bool,
    /// Check convergence when the feedback is at least this recent.
    pub check_from: Option<u64>,
    /// From this feedback frame on the bucket was at its cap: drawing every request in full
    /// is complete even where a request is short of the pointlet's size.
    pub capped_from: Option<u64>,
    /// An empty batch to pack into (its allocations are reused).
    pub batch: PageBatch,
}

/// What one residency step did, on the residency thread.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepReport {
    /// CPU time of the step (requests, planning, evictions, packing).
    pub ms: f64,
    /// Its parts, named by [`RESIDENCY_PARTS`].
    pub parts_ms: [f64; RESIDENCY_PARTS.len()],
    pub points_uploaded: u64,
    /// Page runs written (a run fills one page, or part of one).
    pub upload_runs: u64,
    pub bytes_uploaded: u64,
    pub pages_evicted: u64,
}

/// A step's report and what the render thread takes over from the residency state.
#[derive(Clone, Debug, Default)]
pub(crate) struct StepOutcome {
    pub report: StepReport,
    pub pages_resident: u32,
    pub gpu_points: u64,
    /// Some GPU window got new colours in this batch.
    pub recoloured: bool,
    /// The feedback frame, when every pointlet it requested was resident in full, drawn in
    /// full and in the current colours as the step began.
    pub complete_at: Option<u64>,
    pub cache: CacheStats,
    pub error: Option<String>,
}

pub(crate) struct StepResult {
    pub batch: PageBatch,
    pub outcome: StepOutcome,
}

/// Everything the residency step owns.
pub(crate) struct ResidencyState {
    pub cache: RamCache<StoreSource>,
    pub residency: ResidencySet,
    pub counts: Arc<Vec<u32>>,
    /// Colouring generation: bumped when the user colours by another attribute.
    pub epoch: u32,
    /// Per pointlet: the generation of the colours in its GPU pages.
    pub gpu_epoch: Vec<u32>,
    /// Pointlets whose `gpu_epoch` is older than `epoch`.
    pub stale: usize,
    pub page_size: u32,
    pub upload_per_frame: u64,
    pub encoding: PointEncoding,
    pub slots: u32,
    pub pool: Arc<rayon::ThreadPool>,
    requested: Arc<Vec<u32>>,
    drawn: Arc<Vec<u32>>,
    order: Vec<(f64, u32)>,
}

impl ResidencyState {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        cache: RamCache<StoreSource>,
        counts: Arc<Vec<u32>>,
        slots: u32,
        page_size: u32,
        upload_per_frame: u64,
        encoding: PointEncoding,
        pool: Arc<rayon::ThreadPool>,
    ) -> Self {
        let n = counts.len();
        Self {
            cache,
            residency: ResidencySet::new(n, slots, page_size),
            counts,
            epoch: 0,
            gpu_epoch: vec![0; n],
            stale: 0,
            page_size,
            upload_per_frame,
            encoding,
            slots,
            pool,
            requested: Arc::new(vec![0; n]),
            drawn: Arc::new(vec![0; n]),
            order: Vec::new(),
        }
    }

    /// Runs one step on the state's thread pool.
    pub fn step(&mut self, tick: Tick) -> StepResult {
        let started = Instant::now();
        let mut out = StepOutcome::default();
        let report = &mut out.report;
        let Tick {
            frame,
            requested,
            drawn,
            feedback_frame,
            accumulate,
            drawn_valid,
            check_from,
            capped_from,
            mut batch,
        } = tick;
        self.requested = requested;
        self.drawn = drawn;
        let pool = Arc::clone(&self.pool);
        pool.install(|| {
            let capped = capped_from.is_some_and(|since| feedback_frame >= since);
            if check_from.is_some_and(|since| feedback_frame >= since) && self.complete(capped) {
                out.complete_at = Some(feedback_frame);
            }
            out.recoloured = self.update(frame, (accumulate, drawn_valid), &mut batch, report);
        });
        out.pages_resident = self.residency.resident_pages(self.slots);
        out.gpu_points = self.residency.resident_points();
        debug_assert_eq!(
            out.gpu_points,
            self.residency
                .windows()
                .iter()
                .map(|w| w.points() as u64)
                .sum::<u64>()
        );
        out.cache = self.cache.stats();
        out.error = self.cache.take_error().map(|e| e.to_string());
        out.report.ms = started.elapsed().as_secs_f64() * 1e3;
        StepResult {
            batch,
            outcome: out,
        }
    }

    /// Every requested pointlet is resident and drawn in full (or, with `capped`, up to its
    /// request), in the current colours.
    fn complete(&self, capped: bool) -> bool {
        let epoch = self.epoch;
        self.requested
            .par_iter()
            .zip(self.drawn.par_iter())
            .zip(self.counts.par_iter())
            .zip(self.gpu_epoch.par_iter())
            .all(|(((r, d), c), e)| *r == 0 || ((r == c || capped) && d >= r && *e == epoch))
    }

    /// One step's work; true when some GPU window got new colours.
    fn update(
        &mut self,
        frame: u64,
        (accumulate, drawn_valid): (bool, bool),
        batch: &mut PageBatch,
        report: &mut StepReport,
    ) -> bool {
        let n = self.counts.len();
        let ps = self.page_size;
        // RAM holds what the GPU does not: points below a window's end are on the GPU (or, while
        // still, drawn), so under pressure RAM drops them first and a RAM budget smaller than
        // the view still lets every point through. Windows that must restart from 0 keep all.
        let mut clock = Instant::now();
        let mut lap = |k: usize, report: &mut StepReport| {
            report.parts_ms[k] = clock.elapsed().as_secs_f64() * 1e3;
            clock = Instant::now();
        };
        let windows = self.residency.windows();
        let (gpu_epoch, epoch) = (&self.gpu_epoch, self.epoch);
        let (requested, counts) = (&self.requested, &self.counts);
        self.cache.request_with(n, |i| {
            let w = &windows[i];
            let keep = if gpu_epoch[i] != epoch {
                // Its GPU colours are stale: RAM must bring the window back to recolour it.
                w.lo
            } else if w.lo == 0 || accumulate {
                w.hi
            } else {
                0
            };
            // RAM brings whole pages: uploads fill pages to their end (see the planning below).
            ((requested[i].div_ceil(ps) * ps).min(counts[i]), keep)
        });
        lap(0, report);
        // GPU: drawing a moving view needs prefixes, so windows that lost their front while
        // the camera was still start over.
        let fronts_gone = self.residency.touch_requested(&self.requested, frame);
        if !accumulate {
            for i in fronts_gone {
                report.pages_evicted += self.residency.clear(i as usize, 0) as u64;
            }
        }
        let mut budget = self.upload_per_frame;
        let recoloured = self.recolor_stale(batch, &mut budget, report);
        lap(1, report);
        // Most starved first: the smallest share of its request resident.
        let (windows, requested, cache) = (self.residency.windows(), &self.requested, &self.cache);
        let (gpu_epoch, epoch) = (&self.gpu_epoch, self.epoch);
        self.order = (0..n)
            .into_par_iter()
            .filter_map(|i| {
                let (w, want) = (&windows[i], requested[i]);
                let held = cache.held(i);
                let fresh = gpu_epoch[i] == epoch;
                (fresh && want > w.hi && held.start <= w.hi && held.end > w.hi)
                    .then_some((w.hi as f64 / want as f64, i as u32))
            })
            .collect();
        self.order.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let mut victims: Option<Vec<u32>> = None;
        let order = std::mem::take(&mut self.order);
        // Plan: slots and ranges, serially (allocation and eviction decisions).
        let mut jobs: Vec<PageJob> = Vec::new();
        'pointlets: for (_, i) in &order {
            let i = *i as usize;
            // Fill up to the end of the page the request ends in: the page is taken anyway, and
            // the next frames' small growth then needs no upload (no run of a few points each).
            let fill_to = (self.requested[i].div_ceil(ps) * ps).min(self.counts[i]);
            let target_hi = fill_to.min(self.cache.held(i).end);
            while self.residency.window(i).hi < target_hi && budget > 0 {
                let hi = self.residency.window(i).hi;
                let slot = match self.residency.slot_for_next(i) {
                    Some(s) => s,
                    None => {
                        let want = (budget / ps as u64 + 1) as usize;
                        let v = victims.get_or_insert_with(|| self.victims(drawn_valid, want));
                        if !self.evict_one(v, i, drawn_valid, report) {
                            break 'pointlets;
                        }
                        continue;
                    }
                };
                let page_end = (hi / ps + 1) * ps;
                let end = target_hi
                    .min(page_end)
                    .min(hi + budget.min(u32::MAX as u64) as u32);
                jobs.push(PageJob {
                    pointlet: i as u32,
                    slot,
                    first_point: hi,
                    count: end - hi,
                });
                self.residency.extend(i, end);
                budget = budget.saturating_sub((end - hi) as u64);
            }
            if budget == 0 {
                break;
            }
        }
        self.order = order;
        lap(2, report);
        // Copy into the batch in parallel; loaders already encoded the points. The cache holds
        // these ranges until the next request (this thread's), so nothing planned goes missing.
        let cache = &self.cache;
        let written = batch.write_jobs(&jobs, |k, sink| {
            let j = &jobs[k];
            let range = j.first_point..j.first_point + j.count;
            cache.with_points(j.pointlet as usize, range, |first, words, colors| {
                if first == j.first_point {
                    sink.put_words(words, colors);
                }
            });
        });
        for (j, got) in jobs.iter().zip(&written) {
            if *got < j.count {
                // Should not happen (see above); keep the window honest if it does.
                let end = j.first_point + got;
                report.pages_evicted += self.residency.trim_tail(j.pointlet as usize, end) as u64;
            }
            report.points_uploaded += *got as u64;
        }
        report.upload_runs = jobs.len() as u64;
        lap(3, report);
        report.bytes_uploaded += report.points_uploaded * self.encoding.resident_bytes_per_point();
        // Only what changed: new pages' table entries and the ranges of changed pointlets (pages
        // that stay keep their entries when a window's front moves).
        for [i, page, slot] in self.residency.take_new_pages() {
            batch.set_page(i, page, slot);
        }
        for i in self.residency.take_dirty() {
            let w = self.residency.window(i as usize);
            batch.set_state(i, w.lo, w.hi);
        }
        lap(4, report);
        recoloured
    }

    /// Replaces the colours of GPU windows coloured in an older generation, once RAM holds their
    /// points with the new colours; only the colour stream is uploaded (4 bytes a point).
    /// True when some window was recoloured.
    fn recolor_stale(
        &mut self,
        batch: &mut PageBatch,
        budget: &mut u64,
        report: &mut StepReport,
    ) -> bool {
        if self.stale == 0 {
            return false;
        }
        let mut recoloured = false;
        let ps = self.page_size;
        for i in 0..self.counts.len() {
            if self.gpu_epoch[i] == self.epoch {
                continue;
            }
            let w = self.residency.window(i).clone();
            if w.slots.is_empty() {
                self.gpu_epoch[i] = self.epoch;
                self.stale -= 1;
                continue;
            }
            let held = self.cache.held(i);
            if held.start > w.lo || held.end < w.hi || *budget < w.points() as u64 {
                continue;
            }
            for (k, slot) in w.slots.iter().enumerate() {
                let start = w.lo + k as u32 * ps;
                let end = (start + ps).min(w.hi);
                self.cache.with_points(i, start..end, |first, _, colors| {
                    batch.write_colors(*slot, first, colors);
                });
            }
            *budget -= w.points() as u64;
            report.bytes_uploaded += w.points() as u64 * 4;
            self.gpu_epoch[i] = self.epoch;
            self.stale -= 1;
            recoloured = true;
        }
        recoloured
    }

    /// Pointlets whose pages may go, best victims last (popped first): not requested, least
    /// recently used; then those holding more than requested; then (with `drawn_valid`, the
    /// camera still) those with pages already drawn into the kept framebuffer.
    fn victims(&self, drawn_valid: bool, want: usize) -> Vec<u32> {
        let ps = self.page_size;
        let requested = &self.requested;
        let drawn = &self.drawn;
        let mut v: Vec<(u8, u64, u32)> = self
            .residency
            .windows()
            .par_iter()
            .enumerate()
            .filter(|(i, w)| {
                !w.slots.is_empty()
                    && (w.hi > requested[*i] || (drawn_valid && w.lo + ps <= drawn[*i]))
            })
            .map(|(i, w)| ((requested[i] > 0) as u8, w.last_used, i as u32))
            .collect();
        // Only the best `want` pointlets can be needed this frame (each gives a page at least):
        // select them instead of sorting all.
        if v.len() > want {
            v.select_nth_unstable(want);
            v.truncate(want);
        }
        // Popped from the back: unrequested before partly requested, older before newer.
        v.sort_unstable_by(|a, b| b.cmp(a));
        v.into_iter().map(|(_, _, i)| i).collect()
    }

    /// Frees one page from the victim list (never from `needy` itself). False when none is left.
    fn evict_one(
        &mut self,
        victims: &mut Vec<u32>,
        needy: usize,
        drawn_valid: bool,
        report: &mut StepReport,
    ) -> bool {
        let ps = self.page_size;
        while let Some(&v) = victims.last() {
            let v = v as usize;
            let w = self.residency.window(v);
            let keep = self.requested[v];
            if v == needy || w.slots.is_empty() {
                victims.pop();
                continue;
            }
            let freed = if w.hi > keep {
                // The last page, or the part beyond the request if that is a whole page.
                let last_page_start = w.lo + (w.slots.len() as u32 - 1) * ps;
                self.residency.trim_tail(v, last_page_start.max(keep))
            } else if drawn_valid && w.lo + ps <= self.drawn[v] {
                // The first page, already in the kept framebuffer.
                self.residency.trim_head(v, w.lo + ps)
            } else {
                0
            };
            if freed > 0 {
                report.pages_evicted += freed as u64;
                return true;
            }
            victims.pop();
        }
        false
    }
}

/// The thread that runs steps, one at a time, as the render thread asks.
pub(crate) struct StepThread {
    state: Arc<Mutex<ResidencyState>>,
    ticks: Option<Sender<Tick>>,
    results: Receiver<StepResult>,
    handle: Option<JoinHandle<()>>,
}

impl StepThread {
    pub fn start(state: ResidencyState) -> Result<Self, EngineError> {
        let state = Arc::new(Mutex::new(state));
        let (tick_tx, tick_rx) = mpsc::channel::<Tick>();
        let (result_tx, result_rx) = mpsc::channel();
        let worker = Arc::clone(&state);
        let handle = std::thread::Builder::new()
            .name("residency".into())
            .spawn(move || {
                while let Ok(tick) = tick_rx.recv() {
                    let Ok(mut st) = worker.lock() else { return };
                    let result = st.step(tick);
                    drop(st);
                    if result_tx.send(result).is_err() {
                        return;
                    }
                }
            })
            .map_err(|e| EngineError::Config(format!("starting the residency thread: {e}")))?;
        Ok(Self {
            state,
            ticks: Some(tick_tx),
            results: result_rx,
            handle: Some(handle),
        })
    }

    pub fn send(&self, tick: Tick) -> Result<(), EngineError> {
        self.ticks
            .as_ref()
            .and_then(|t| t.send(tick).ok())
            .ok_or_else(stopped)
    }

    /// The finished step, if it has finished.
    pub fn try_take(&self) -> Result<Option<StepResult>, EngineError> {
        match self.results.try_recv() {
            Ok(r) => Ok(Some(r)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => Err(stopped()),
        }
    }

    /// Waits for the step in flight.
    pub fn take(&self) -> Result<StepResult, EngineError> {
        self.results.recv().map_err(|_| stopped())
    }

    /// The state, once no step runs (wait for one with [`take`](Self::take) first to keep it
    /// in step with the GPU).
    pub fn state(&self) -> Result<MutexGuard<'_, ResidencyState>, EngineError> {
        self.state.lock().map_err(|_| stopped())
    }
}

fn stopped() -> EngineError {
    EngineError::Config("the residency thread stopped (a step panicked)".into())
}

impl Drop for StepThread {
    fn drop(&mut self) {
        // Closing the channel ends the thread after its current step.
        self.ticks = None;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
