//! A store rendered through the virtual memory system (virtualized paper §III-C): the GPU LoD
//! requests points per pointlet, loader threads bring them from disk into the RAM cache, and
//! a residency step on its own thread moves a bounded number of them into GPU page slots,
//! evicting pages nobody needs. The render thread never waits for the disk or for that step: it
//! draws what is resident and queues each finished step's uploads with its next frame.

use crate::source::StoreSource;
use crate::step::{ResidencyState, StepResult, StepThread, Tick};
use crate::EngineError;
use pointlet_core::color::{ColorMode, ColorScale};
use pointlet_core::{Aabb, Camera, Quantization};
use pointlet_gpu::{
    GpuContext, PageBatch, PagedCloud, PagedView, PointEncoding, PointletDesc, RenderSettings,
    RenderTarget, Renderer, TemporalReuse,
};
use pointlet_store::Store;
use pointlet_stream::{CacheConfig, CacheStats, RamCache};
use std::path::Path;
use std::sync::Arc;

/// Pointlets one loader reads at once from a remote store.
const REMOTE_LOAD_BATCH: usize = 64;
/// Loader threads of a remote store per loader of a local one.
const REMOTE_LOADERS_PER_LOADER: usize = 4;

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
    /// A moving camera's frame starts from the last frame reprojected (`gpu::TemporalReuse`)
    /// instead of the LoD image alone.
    pub temporal_reuse: bool,
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
            temporal_reuse: false,
            color: ColorMode::Rgb,
        }
    }
}

pub use crate::step::{StepReport, RESIDENCY_PARTS};

/// What one frame did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    pub frame: u64,
    /// The residency step whose batch this frame queued; None when none finished in time.
    pub step: Option<StepReport>,
    /// Render-thread time spent handing feedback to the residency thread and taking its batch.
    pub handoff_ms: f64,
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
    paged: PagedCloud,
    steps: StepThread,
    /// A step runs; its batch is not yet queued.
    in_flight: bool,
    /// An empty batch for the next step.
    spare: Option<PageBatch>,
    config: SceneConfig,
    quantization: Quantization,
    counts: Arc<Vec<u32>>,
    scale: ColorScale,
    requested: Arc<Vec<u32>>,
    drawn: Arc<Vec<u32>>,
    feedback_frame: u64,
    last_camera: Option<(Camera, RenderSettings, (u32, u32))>,
    still_frames: u32,
    /// First frame of the current still view (refining towards full detail).
    accumulating_since: Option<u64>,
    total_points: u64,
    slots: u32,
    /// The pool holds every page of the store: no bucket can overfill it.
    holds_store: bool,
    /// Keep refining a still view to full detail (on by default).
    accumulation: bool,
    /// First frame of the current still view whose bucket could grow no further.
    capped_since: Option<u64>,
    /// Points requested and drawn in all, by the latest feedback.
    feedback_totals: (u64, u64),
    /// Some GPU window got new colours in the batch queued this frame.
    recoloured: bool,
    /// Feedback frame a finished step found complete (see `StepReport::complete_at`).
    complete_at: Option<u64>,
    /// The latest step's view of the pool and the cache.
    pages_resident: u32,
    gpu_points: u64,
    cache: CacheStats,
    /// The last frame, kept for reprojection (with `SceneConfig::temporal_reuse`).
    reuse: Option<TemporalReuse>,
    /// The framebuffer holds reprojected pixels: a still view starts its refinement afresh.
    reused_last: bool,
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
        if config.bucket.is_nan() || config.bucket < 1.0 {
            return Err(EngineError::Config(format!(
                "the point bucket B must be at least 1 point (got {})",
                config.bucket
            )));
        }
        let store = Arc::new(Store::open(path)?);
        let header = store.header().clone();
        if !config.color.available_in(&header.layout) {
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
        // Only what the whole store needs when it fits: the budget is a ceiling, not a size.
        let store_pages: u64 = descs
            .iter()
            .map(|d| d.count.div_ceil(config.page_size) as u64)
            .sum();
        let slots = slots.min(store_pages).min(u32::MAX as u64 / 2) as u32;
        let paged = PagedCloud::new(ctx, descs.clone(), config.encoding, config.page_size, slots)?;
        let slots = paged.slots;
        let source = StoreSource::new(store.clone(), config.color, config.encoding)?;
        let remote = pointlet_store::is_remote(store.path());
        let cache = RamCache::new(
            source,
            CacheConfig {
                ram_budget: config.ram_budget,
                // Over the network each read waits a round trip: more loaders wait at once, and
                // each fetches many pointlets' ranges at once (joined, several requests in
                // flight). Waiting threads cost no CPU.
                loaders: if remote {
                    config.loaders.max(1) * REMOTE_LOADERS_PER_LOADER
                } else {
                    config.loaders.max(1)
                },
                batch: if remote { REMOTE_LOAD_BATCH } else { 1 },
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
        let counts = Arc::new(descs.iter().map(|d| d.count).collect::<Vec<u32>>());
        let scale = cache.source().scale();
        let state = ResidencyState::new(
            cache,
            Arc::clone(&counts),
            slots,
            config.page_size,
            config.upload_per_frame,
            config.encoding,
            Arc::new(pool),
        );
        let steps = StepThread::start(state)?;
        Ok(Self {
            store,
            spare: Some(paged.new_batch()),
            paged,
            steps,
            in_flight: false,
            quantization: header.quantization,
            counts,
            scale,
            requested: Arc::new(vec![0; n]),
            drawn: Arc::new(vec![0; n]),
            feedback_frame: 0,
            last_camera: None,
            still_frames: 0,
            accumulating_since: None,
            total_points: header.points,
            slots,
            holds_store: slots as u64 == store_pages,
            config,
            accumulation: true,
            capped_since: None,
            feedback_totals: (0, 0),
            recoloured: false,
            reuse: None,
            reused_last: false,
            complete_at: None,
            pages_resident: 0,
            gpu_points: 0,
            cache: CacheStats::default(),
        })
    }

    pub fn color_mode(&self) -> ColorMode {
        self.scale.mode
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

    /// Moving frames start from the last frame reprojected (on) or from the LoD image alone.
    pub fn set_temporal_reuse(&mut self, on: bool) {
        self.config.temporal_reuse = on;
        if !on && self.reuse.take().is_some() {
            // The framebuffer may hold reprojected pixels: the next frame starts clean.
            self.reused_last = false;
            self.last_camera = None;
        }
    }

    pub fn temporal_reuse(&self) -> bool {
        self.config.temporal_reuse
    }

    /// The colouring the loaders apply.
    pub fn color_scale(&self) -> ColorScale {
        self.scale
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
        if scale == self.scale {
            return Ok(());
        }
        self.settle()?;
        let mut st = self.steps.state()?;
        st.cache.source().set_scale(scale);
        st.cache.clear();
        st.epoch += 1;
        st.stale = self.counts.len();
        drop(st);
        self.scale = scale;
        self.complete_at = None;
        Ok(())
    }

    /// Waits for the step in flight and queues its batch: the residency state then matches
    /// what the GPU will hold at the next frame.
    fn settle(&mut self) -> Result<(), EngineError> {
        if self.in_flight {
            let result = self.steps.take()?;
            self.apply(result, &mut FrameReport::default())?;
        }
        Ok(())
    }

    /// Queues a finished step's batch for this frame and takes over its report.
    fn apply(&mut self, result: StepResult, report: &mut FrameReport) -> Result<(), EngineError> {
        self.in_flight = false;
        self.spare = Some(self.paged.submit(result.batch));
        let r = result.outcome;
        if let Some(e) = r.error {
            return Err(EngineError::Read(e));
        }
        self.recoloured |= r.recoloured;
        if r.complete_at.is_some() {
            self.complete_at = r.complete_at;
        }
        self.pages_resident = r.pages_resident;
        self.gpu_points = r.gpu_points;
        self.cache = r.cache;
        report.step = Some(r.report);
        Ok(())
    }

    fn check_color_mode(&self, mode: ColorMode) -> Result<(), EngineError> {
        if mode.available_in(&self.store.header().layout) {
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
        // The pick pass draws the pool as the residency state describes it.
        self.settle()?;
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
        let Some((pointlet, index)) = self.steps.state()?.residency.point_of(hit.id) else {
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
        if self.holds_store {
            return self.config.bucket;
        }
        // Asking for more than the pool holds only starves pointlets at random; within it the
        // LoD shares points out fairly. Half a page per pointlet is lost to rounding.
        let ps = self.config.page_size as f64;
        let pool = self.slots as f64 * ps - 0.5 * ps * self.counts.len() as f64;
        self.config.bucket.min(pool.max(ps))
    }

    /// The largest bucket whose requests all fit the pool at once, however they round to pages
    /// (each pointlet at most one page beyond its share); None when the pool holds the store.
    fn single_pass_cap(&self) -> Option<f64> {
        if self.holds_store {
            return None;
        }
        let spare = self.slots.saturating_sub(self.counts.len() as u32) as f64;
        Some((spare * self.config.page_size as f64).max(1.0))
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

    /// The RAM cache's counters now (waits for a running step).
    pub fn cache_stats(&self) -> CacheStats {
        self.steps
            .state()
            .map_or_else(|_| self.cache, |st| st.cache.stats())
    }

    pub fn config(&self) -> &SceneConfig {
        &self.config
    }

    /// Draws one frame; never waits for disk or for the residency step. A camera that did not
    /// move since the last frame keeps the framebuffer and adds points (growing the bucket)
    /// until the full-detail image.
    pub fn frame(
        &mut self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<FrameReport, EngineError> {
        let view_key = (*camera, *settings, (target.width, target.height));
        let mut still = self.last_camera.as_ref() == Some(&view_key);
        let same_settings = self
            .last_camera
            .as_ref()
            .is_some_and(|k| (k.1, k.2) == (view_key.1, view_key.2));
        self.last_camera = Some(view_key);
        // Pages recoloured by the batch queued last frame may already be in the kept
        // framebuffer with their old colours: accumulation starts over, as after a camera move.
        let recoloured = std::mem::take(&mut self.recoloured);
        if self.config.temporal_reuse && self.reuse.is_none() {
            self.reuse = Some(TemporalReuse::new(ctx)?);
        }
        if let Some(reuse) = &mut self.reuse {
            // Reprojected pixels approximate the points (pixel centres): a still view drops
            // them and refines from a clean frame; other settings or colours reuse nothing.
            if (still && self.reused_last) || !same_settings || recoloured {
                reuse.forget();
            }
            if still && self.reused_last {
                still = false;
            }
        }
        // A still view grows the bucket to full detail. Closest-point variants add each
        // frame's new points to the kept framebuffer; the others (HQS) redraw every resident
        // point each frame, so their requests must fit the pool at once.
        let refine = still && !recoloured && self.accumulation;
        let accumulate = refine && settings.accumulates();
        if refine {
            self.still_frames += 1;
            if self.accumulating_since.is_none() {
                self.accumulating_since = Some(self.paged.frames() + 1);
            }
        } else {
            self.still_frames = 0;
            self.accumulating_since = None;
        }
        let pool_cap = self.single_pass_cap().filter(|_| !accumulate);
        let bucket = if refine {
            let growth = 2f64.powi(self.still_frames.min(60) as i32);
            let cap = pool_cap.unwrap_or(self.total_points as f64 * 1048576.0);
            (self.config.bucket * growth).min(cap)
        } else {
            self.moving_bucket()
        };
        // At the pool's cap the bucket cannot grow: the view is final once its requests are
        // drawn, though some fall short of full detail.
        if refine && pool_cap.is_some_and(|cap| bucket >= cap) {
            self.capped_since.get_or_insert(self.paged.frames() + 1);
        } else {
            self.capped_since = None;
        }
        let handoff = std::time::Instant::now();
        if let Some(fb) = self.paged.poll_feedback(ctx) {
            self.feedback_totals = (
                fb.requested.iter().map(|v| *v as u64).sum(),
                fb.drawn.iter().map(|v| *v as u64).sum(),
            );
            self.requested = Arc::new(fb.requested);
            self.drawn = Arc::new(fb.drawn);
            self.feedback_frame = fb.frame;
        }
        let mut report = FrameReport {
            frame: self.paged.frames() + 1,
            bucket,
            accumulating: refine,
            ..Default::default()
        };
        // Queue the step that finished, then start the next one on the newest feedback.
        if self.in_flight {
            if let Some(result) = self.steps.try_take()? {
                self.apply(result, &mut report)?;
            }
        }
        if !self.in_flight {
            // While still, pages already drawn may go when room is needed — judged only by
            // feedback of accumulating frames, whose drawn counts never shrink.
            let drawn_valid = accumulate
                && self
                    .accumulating_since
                    .is_some_and(|since| self.feedback_frame >= since);
            let batch = match self.spare.take() {
                Some(b) => b,
                None => self.paged.new_batch(),
            };
            self.steps.send(Tick {
                frame: report.frame,
                requested: Arc::clone(&self.requested),
                drawn: Arc::clone(&self.drawn),
                feedback_frame: self.feedback_frame,
                accumulate,
                drawn_valid,
                check_from: self.accumulating_since,
                capped_from: self.capped_since,
                batch,
            })?;
            self.in_flight = true;
        }
        report.handoff_ms = handoff.elapsed().as_secs_f64() * 1e3;
        let view = PagedView { bucket, accumulate };
        self.reused_last = !accumulate && self.reuse.as_ref().is_some_and(|r| r.has_frame());
        renderer.render_paged(
            ctx,
            &mut self.paged,
            camera,
            settings,
            &view,
            target,
            self.reuse.as_mut(),
        )?;
        (report.requested_points, report.drawn_points) = self.feedback_totals;
        report.pages_resident = self.pages_resident;
        report.gpu_points = self.gpu_points;
        report.converged = self.converged();
        report.cache = self.cache;
        Ok(report)
    }

    /// True once a step found feedback from this still view showing every visible pointlet
    /// requested, drawn in full and in the current colours.
    fn converged(&self) -> bool {
        let Some(since) = self.accumulating_since else {
            return false;
        };
        // Recoloured pages restart accumulation next frame: this image may hold old colours.
        !self.recoloured && self.complete_at.is_some_and(|f| f >= since)
    }
}
