//! A store rendered through the virtual memory system (virtualized paper §III-C): the GPU LoD
//! requests points per pointlet, loader threads bring them from disk into the RAM cache, and
//! each frame moves a bounded number of them into GPU page slots, evicting pages nobody needs.
//! The render thread never waits for the disk: it draws what is resident.

use crate::residency::ResidencySet;
use crate::source::StoreSource;
use crate::EngineError;
use pointlet_core::color::{ColorMode, ColorScale};
use pointlet_core::{Aabb, Camera, Quantization};
use pointlet_gpu::{
    GpuContext, PageJob, PagedCloud, PagedView, PointEncoding, PointletDesc, RenderSettings,
    RenderTarget, Renderer,
};
use pointlet_store::Store;
use pointlet_stream::{CacheConfig, CacheStats, RamCache};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SceneConfig {
    /// GPU memory for points and every table (the framebuffers of the target count too).
    pub vram_budget: u64,
    /// RAM for cached points.
    pub ram_budget: u64,
    /// The LoD's point bucket B (paper default 25 M).
    pub bucket: f64,
    pub encoding: PointEncoding,
    /// Points per GPU page.
    pub page_size: u32,
    pub loaders: usize,
    /// Threads of the residency step's parallel passes (0: half the cores). A pass waits for its
    /// slowest thread: with as many threads as cores, loaders preempt workers and the 1 % low
    /// frame rate halves (docs/BENCHMARKS.md, "Residency threads and loaders").
    pub threads: usize,
    /// Points moved from RAM to the GPU per frame at most (keeps frames steady).
    pub upload_per_frame: u64,
    pub color: ColorMode,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            vram_budget: 2 << 30,
            ram_budget: 4 << 30,
            bucket: 25e6,
            encoding: PointEncoding::Compact8,
            page_size: 256,
            loaders: 4,
            threads: 0,
            upload_per_frame: 1 << 20,
            color: ColorMode::Rgb,
        }
    }
}

/// Names of [`FrameReport::residency_parts_ms`], in order.
pub const RESIDENCY_PARTS: [&str; 5] = [
    "RAM requests",
    "window upkeep",
    "planning",
    "copy to staging",
    "publish",
];

/// What one frame did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    pub frame: u64,
    /// CPU time of the residency step (feedback, requests, uploads, evictions).
    pub residency_ms: f64,
    /// Its parts, named by [`RESIDENCY_PARTS`].
    pub residency_parts_ms: [f64; RESIDENCY_PARTS.len()],
    pub points_uploaded: u64,
    /// Page runs written (a run fills one page, or part of one).
    pub upload_runs: u64,
    pub bytes_uploaded: u64,
    pub pages_evicted: u64,
    pub pages_resident: u32,
    pub gpu_points: u64,
    /// From the latest LoD feedback (a frame or two old).
    pub requested_points: u64,
    pub drawn_points: u64,
    pub bucket: f64,
    pub accumulating: bool,
    /// The image is the full-detail image of this (still) view.
    pub converged: bool,
    pub cache: CacheStats,
}

pub struct VirtualScene {
    store: Arc<Store>,
    cache: RamCache<StoreSource>,
    paged: PagedCloud,
    residency: ResidencySet,
    config: SceneConfig,
    quantization: Quantization,
    counts: Vec<u32>,
    requested: Vec<u32>,
    drawn: Vec<u32>,
    feedback_frame: u64,
    last_camera: Option<(Camera, RenderSettings, (u32, u32))>,
    still_frames: u32,
    /// First frame drawn into the kept framebuffer of the current still view.
    accumulating_since: Option<u64>,
    total_points: u64,
    slots: u32,
    order: Vec<(f64, u32)>,
    /// Colouring generation: bumped when the user colours by another attribute.
    epoch: u32,
    /// Keep refining a still view to full detail (on by default).
    accumulation: bool,
    /// Per pointlet: the generation of the colours in its GPU pages.
    gpu_epoch: Vec<u32>,
    /// Pointlets whose `gpu_epoch` is older than `epoch`.
    stale: usize,
    /// Points requested and drawn in all, by the latest feedback.
    feedback_totals: (u64, u64),
    /// Some GPU window got new colours this frame.
    recoloured: bool,
    /// Runs the residency step's parallel passes.
    pool: Arc<rayon::ThreadPool>,
}

/// A point under the cursor, read back from the store: exact coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PickedPoint {
    pub pointlet: usize,
    /// Index in the pointlet's stored (shuffled) order.
    pub index: u32,
    pub position: [f64; 3],
    /// View depth of the point.
    pub depth: f32,
}

/// Bytes of GPU memory a render target of this size allocates.
pub fn target_bytes(width: u32, height: u32) -> u64 {
    RenderTarget::bytes_for(width, height)
}

impl VirtualScene {
    /// Opens a store for rendering into images of `image` pixels within the budgets.
    pub fn open(
        ctx: &GpuContext,
        path: &Path,
        config: SceneConfig,
        image: (u32, u32),
    ) -> Result<Self, EngineError> {
        let store = Arc::new(Store::open(path)?);
        let header = store.header().clone();
        if !crate::source::has_attribute(&header.layout, config.color) {
            return Err(EngineError::Config(format!(
                "{} has no {} attribute to colour by",
                path.display(),
                config.color.name()
            )));
        }
        let descs: Vec<PointletDesc> = store
            .pointlets()
            .iter()
            .map(|p| PointletDesc {
                aabb: p.aabb,
                count: p.count,
            })
            .collect();
        let fixed =
            PagedCloud::overhead_bytes(&descs, config.page_size) + target_bytes(image.0, image.1);
        let per_slot = PagedCloud::slot_bytes(config.encoding, config.page_size);
        let slots = config.vram_budget.saturating_sub(fixed) / per_slot;
        // A page per pointlet at least, or the LoD could never draw some visible pointlet.
        if slots < descs.len() as u64 {
            return Err(EngineError::Config(format!(
                "a VRAM budget of {} is too small for {} pointlets: the tables and a {}×{} frame need {}, and every pointlet a page of {} bytes (at least {} in all)",
                pointlet_core::size::format_bytes(config.vram_budget),
                descs.len(),
                image.0,
                image.1,
                pointlet_core::size::format_bytes(fixed),
                per_slot,
                pointlet_core::size::format_bytes(fixed + descs.len() as u64 * per_slot)
            )));
        }
        let slots = slots.min(u32::MAX as u64 / 2) as u32;
        let paged = PagedCloud::new(ctx, descs.clone(), config.encoding, config.page_size, slots)?;
        let source = StoreSource::new(store.clone(), config.color, config.encoding)?;
        let cache = RamCache::new(
            source,
            CacheConfig {
                ram_budget: config.ram_budget,
                loaders: config.loaders.max(1),
                ..Default::default()
            },
        )
        .map_err(|e| EngineError::Config(format!("starting loader threads: {e}")))?;
        let threads = match config.threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get() / 2),
            t => t,
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .thread_name(|k| format!("residency-{k}"))
            .build()
            .map_err(|e| EngineError::Config(format!("starting residency threads: {e}")))?;
        let n = descs.len();
        Ok(Self {
            pool: Arc::new(pool),
            store,
            cache,
            residency: ResidencySet::new(n, slots, config.page_size),
            paged,
            quantization: header.quantization,
            counts: descs.iter().map(|d| d.count).collect(),
            requested: vec![0; n],
            drawn: vec![0; n],
            feedback_frame: 0,
            last_camera: None,
            still_frames: 0,
            accumulating_since: None,
            total_points: header.points,
            slots,
            config,
            order: Vec::new(),
            epoch: 0,
            accumulation: true,
            gpu_epoch: vec![0; n],
            stale: 0,
            feedback_totals: (0, 0),
            recoloured: false,
        })
    }

    pub fn color_mode(&self) -> ColorMode {
        self.cache.source().scale().mode
    }

    /// With accumulation off, a still camera keeps drawing the LoD image of the bucket (for
    /// quality measurements of the LoD itself).
    pub fn set_accumulation(&mut self, on: bool) {
        self.accumulation = on;
    }

    pub fn bucket(&self) -> f64 {
        self.config.bucket
    }

    pub fn set_bucket(&mut self, bucket: f64) {
        self.config.bucket = bucket.max(1.0);
    }

    /// The colouring the loaders apply.
    pub fn color_scale(&self) -> ColorScale {
        self.cache.source().scale()
    }

    /// Colours by another attribute, with ranges fitted to the data.
    pub fn set_color(&mut self, mode: ColorMode) -> Result<(), EngineError> {
        self.check_color_mode(mode)?;
        let scale = crate::source::fit_scale(&self.store, mode)?;
        self.set_color_scale(scale)
    }

    /// Colours with `scale` (mode, range, gamma, ramp). The RAM cache reloads with the new
    /// colours; GPU pages keep their positions and get only their colour stream replaced as
    /// the new colours arrive.
    pub fn set_color_scale(&mut self, scale: ColorScale) -> Result<(), EngineError> {
        self.check_color_mode(scale.mode)?;
        if scale == self.color_scale() {
            return Ok(());
        }
        self.cache.source().set_scale(scale);
        self.cache.clear();
        self.epoch += 1;
        self.stale = self.counts.len();
        Ok(())
    }

    fn check_color_mode(&self, mode: ColorMode) -> Result<(), EngineError> {
        if crate::source::has_attribute(&self.store.header().layout, mode) {
            return Ok(());
        }
        Err(EngineError::Config(format!(
            "{} has no {} attribute to colour by",
            self.store.path().display(),
            mode.name()
        )))
    }

    /// The point nearest to `pixel` within `radius` pixels among those drawn for `camera`.
    #[allow(clippy::too_many_arguments)]
    pub fn pick(
        &mut self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
        pixel: [u32; 2],
        radius: u32,
    ) -> Result<Option<PickedPoint>, EngineError> {
        let view = PagedView {
            bucket: self.moving_bucket(),
            accumulate: false,
        };
        let Some(hit) = renderer.pick_paged(
            ctx,
            &mut self.paged,
            camera,
            settings,
            &view,
            target,
            pixel,
            radius,
        )?
        else {
            return Ok(None);
        };
        let Some((pointlet, index)) = self.residency.point_of(hit.id) else {
            return Ok(None);
        };
        let raw = self.store.read_positions(pointlet, index..index + 1)?;
        Ok(raw.first().map(|p| PickedPoint {
            pointlet,
            index,
            position: self.quantization.dequantize(*p),
            depth: hit.depth,
        }))
    }

    /// The bucket of a moving frame: the configured one, within what the pool holds.
    fn moving_bucket(&self) -> f64 {
        // Asking for more than the pool holds only starves pointlets at random; within it the
        // LoD shares points out fairly. Half a page per pointlet is lost to rounding.
        let ps = self.config.page_size as f64;
        let pool = self.slots as f64 * ps - 0.5 * ps * self.counts.len() as f64;
        self.config.bucket.min(pool.max(ps))
    }

    pub fn bounds(&self) -> Aabb {
        self.store.header().bounds
    }

    pub fn store(&self) -> &Store {
        &self.store
    }

    pub fn points(&self) -> u64 {
        self.total_points
    }

    /// GPU bytes this scene allocated (pool and tables; add the render target's).
    pub fn gpu_bytes(&self) -> u64 {
        self.paged.gpu_bytes()
    }

    pub fn slots(&self) -> u32 {
        self.slots
    }

    pub fn cache_stats(&self) -> CacheStats {
        self.cache.stats()
    }

    pub fn config(&self) -> &SceneConfig {
        &self.config
    }

    /// Draws one frame; never waits for disk. A camera that did not move since the last frame
    /// keeps the framebuffer and adds points (growing the bucket) until the full-detail image.
    pub fn frame(
        &mut self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<FrameReport, EngineError> {
        let started = Instant::now();
        let view_key = (*camera, *settings, (target.width, target.height));
        let still = self.last_camera.as_ref() == Some(&view_key);
        self.last_camera = Some(view_key);
        // Pages recoloured last frame may already be in the kept framebuffer with their old
        // colours: accumulation starts over, as after a camera move.
        let recoloured = std::mem::take(&mut self.recoloured);
        let accumulate =
            still && !recoloured && self.accumulation && settings.variant.accumulates();
        if accumulate {
            self.still_frames += 1;
            if self.accumulating_since.is_none() {
                self.accumulating_since = Some(self.paged.frames() + 1);
            }
        } else {
            self.still_frames = 0;
            self.accumulating_since = None;
        }
        let bucket = if accumulate {
            let growth = 2f64.powi(self.still_frames.min(60) as i32);
            (self.config.bucket * growth).min(self.total_points as f64 * 1048576.0)
        } else {
            self.moving_bucket()
        };
        if let Some(fb) = self.paged.poll_feedback(ctx) {
            self.requested = fb.requested;
            self.drawn = fb.drawn;
            self.feedback_frame = fb.frame;
            let pool = Arc::clone(&self.pool);
            self.feedback_totals = pool.install(|| {
                (
                    self.requested.par_iter().map(|v| *v as u64).sum(),
                    self.drawn.par_iter().map(|v| *v as u64).sum(),
                )
            });
        }
        let mut report = FrameReport {
            frame: self.paged.frames() + 1,
            bucket,
            accumulating: accumulate,
            ..Default::default()
        };
        let pool = Arc::clone(&self.pool);
        pool.install(|| self.update_residency(accumulate, &mut report));
        report.residency_ms = started.elapsed().as_secs_f64() * 1e3;
        renderer.render_paged(
            ctx,
            &mut self.paged,
            camera,
            settings,
            &PagedView { bucket, accumulate },
            target,
        )?;
        (report.requested_points, report.drawn_points) = self.feedback_totals;
        report.pages_resident = self.residency.resident_pages(self.slots);
        report.gpu_points = self.residency.resident_points();
        debug_assert_eq!(
            report.gpu_points,
            self.residency
                .windows()
                .iter()
                .map(|w| w.points() as u64)
                .sum::<u64>()
        );
        report.converged = pool.install(|| self.converged());
        report.cache = self.cache.stats();
        if let Some(e) = self.cache.take_error() {
            return Err(EngineError::Read(e.to_string()));
        }
        Ok(report)
    }

    /// True once feedback from a still frame shows every visible pointlet requested and drawn
    /// in full.
    fn converged(&self) -> bool {
        let Some(since) = self.accumulating_since else {
            return false;
        };
        // Recoloured pages restart accumulation next frame: this image may hold old colours.
        !self.recoloured
            && self.feedback_frame >= since
            && self
                .requested
                .par_iter()
                .zip(self.drawn.par_iter())
                .zip(self.counts.par_iter())
                .zip(self.gpu_epoch.par_iter())
                .all(|(((r, d), c), e)| *r == 0 || (r == c && d >= r && *e == self.epoch))
    }

    fn update_residency(&mut self, accumulate: bool, report: &mut FrameReport) {
        let n = self.counts.len();
        let ps = self.config.page_size;
        let frame = report.frame;
        // RAM holds what the GPU does not: points below a window's end are on the GPU (or, while
        // still, drawn), so under pressure RAM drops them first and a RAM budget smaller than
        // the view still lets every point through. Windows that must restart from 0 keep all.
        let mut clock = Instant::now();
        let mut lap = |k: usize, report: &mut FrameReport| {
            report.residency_parts_ms[k] = clock.elapsed().as_secs_f64() * 1e3;
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
        // While still, pages already drawn may go when room is needed — judged only by feedback
        // of accumulating frames, whose drawn counts never shrink.
        let drawn_valid = accumulate
            && self
                .accumulating_since
                .is_some_and(|since| self.feedback_frame >= since);
        let mut budget = self.config.upload_per_frame;
        self.recolor_stale(&mut budget, report);
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
        // Copy into the upload staging in parallel; loaders already encoded the points. The
        // cache holds these ranges until the next request (this thread's), so nothing planned
        // goes missing.
        let cache = &self.cache;
        let written = self.paged.write_jobs(&jobs, |k, sink| {
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
        report.bytes_uploaded +=
            report.points_uploaded * self.config.encoding.resident_bytes_per_point();
        // Only what changed: new pages' table entries and the ranges of changed pointlets (pages
        // that stay keep their entries when a window's front moves).
        for [i, page, slot] in self.residency.take_new_pages() {
            self.paged.set_page(i, page, slot);
        }
        for i in self.residency.take_dirty() {
            let w = self.residency.window(i as usize);
            self.paged.set_state(i, w.lo, w.hi);
        }
        lap(4, report);
    }

    /// Replaces the colours of GPU windows coloured in an older generation, once RAM holds their
    /// points with the new colours; only the colour stream is uploaded (4 bytes a point).
    fn recolor_stale(&mut self, budget: &mut u64, report: &mut FrameReport) {
        if self.stale == 0 {
            return;
        }
        let ps = self.config.page_size;
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
                let paged = &mut self.paged;
                self.cache.with_points(i, start..end, |first, _, colors| {
                    paged.write_colors(*slot, first, colors);
                });
            }
            *budget -= w.points() as u64;
            report.bytes_uploaded += w.points() as u64 * 4;
            self.gpu_epoch[i] = self.epoch;
            self.stale -= 1;
            self.recoloured = true;
        }
    }

    /// Pointlets whose pages may go, best victims last (popped first): not requested, least
    /// recently used; then those holding more than requested; then (with `drawn_valid`, the
    /// camera still) those with pages already drawn into the kept framebuffer.
    fn victims(&self, drawn_valid: bool, want: usize) -> Vec<u32> {
        let ps = self.config.page_size;
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
        report: &mut FrameReport,
    ) -> bool {
        let ps = self.config.page_size;
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
