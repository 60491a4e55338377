//! A point file drawn while it loads (progressive-rendering paper §3): the load thread of
//! [`ProgressiveLoad`] feeds the shuffled buffer of a [`ProgressiveCloud`], and every frame
//! reprojects the last frame's points, fills in the next S slots and prepares the list for
//! the next frame. S adapts to a target frame time from GPU timestamps (§3.4.1, [`FillBudget`]).
//! A still camera converges to exactly the image of drawing every point once S slots summed
//! over the frames since the camera (or the data) last changed cover the buffer.

use crate::progressive::{LoadColor, LoadConfig, LoadProgress, ProgressiveLoad, Uploaded};
use crate::EngineError;
use pointlet_core::color::{ColorMode, ColorScale};
use pointlet_core::progressive::SlotOrder;
use pointlet_core::{Aabb, Camera};
use pointlet_gpu::progressive::{
    ProgressiveCloud, ProgressiveRenderer, ProgressiveSettings, ProgressiveState, ProgressiveTiming,
};
use pointlet_gpu::shuffle::{ShufflePass, ShuffledContents};
use pointlet_gpu::{GpuContext, RasterVariant, RenderSettings, RenderTarget, SplatSettings};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// GPU bytes of one slot of the shuffled buffer (Full16 position + colour).
pub const SLOT_BYTES: u64 = 16;

/// How to open and draw a point file progressively.
#[derive(Clone, Debug)]
pub struct ProgressiveConfig {
    /// Colouring, batching and reading; `max_slots` is set from `vram_budget`.
    pub load: LoadConfig,
    /// A closest-point rasterizer (atomic-min, early-z, reduce, reduce-early-z, dedup).
    pub variant: RasterVariant,
    pub page_size: u32,
    /// GPU memory the shuffled buffer may take: beyond it a uniform subset is kept.
    pub vram_budget: u64,
    /// The frame time the adaptive fill budget aims at.
    pub target_frame_ms: f64,
    /// A fixed S instead of the adaptive one (`render` draws every slot each frame).
    pub fixed_budget: Option<u64>,
    /// Redraw last frame's points before filling (off: every frame starts empty).
    pub reproject: bool,
    /// Ready batches scattered per frame whatever they cost.
    pub batches_per_frame: usize,
    /// Beyond those, a store's batches (interleaved pointlets, which cost the GPU little: the
    /// render thread's recording is what a frame pays) are scattered while the frame's uploads
    /// have taken less than this share of `target_frame_ms`, at most `max_batches_per_frame`.
    /// Not for permuted batches: their writes to random slots cost the GPU ~1 ns a point,
    /// which this clock does not see.
    pub upload_share: f64,
    pub max_batches_per_frame: usize,
}

impl Default for ProgressiveConfig {
    fn default() -> Self {
        Self {
            load: LoadConfig::default(),
            variant: RasterVariant::AtomicMin,
            page_size: 4096,
            vram_budget: 2 << 30,
            target_frame_ms: 1000.0 / 60.0,
            fixed_budget: None,
            reproject: true,
            batches_per_frame: 8,
            upload_share: 0.25,
            max_batches_per_frame: 64,
        }
    }
}

/// The fill budget S of §3.4.1: after each timed frame, S is scaled so that the reproject,
/// fill and screen passes take `target_ms` (at most doubling or halving per step, so one
/// noisy timestamp cannot swing it), and kept between a floor that converges a still view
/// within about ten seconds at the target rate and every slot.
#[derive(Clone, Debug)]
pub struct FillBudget {
    target_ms: f64,
    floor: u64,
    slots: u64,
    current: u64,
}

impl FillBudget {
    /// Share of the target frame time given to the passes (the rest: CPU, presenting).
    const HEADROOM: f64 = 0.85;
    /// Floor: the buffer is covered in at most this many frames.
    const FRAMES_TO_COVER: u64 = 600;
    const MIN_FLOOR: u64 = 1 << 16;

    pub fn new(slots: u64, target_ms: f64) -> Self {
        let floor = (slots / Self::FRAMES_TO_COVER)
            .max(Self::MIN_FLOOR)
            .min(slots);
        Self {
            target_ms,
            floor,
            slots,
            current: (1 << 20).clamp(floor, slots.max(floor)),
        }
    }

    pub fn current(&self) -> u64 {
        self.current
    }

    pub fn floor(&self) -> u64 {
        self.floor
    }

    /// A frame that filled `used` slots took `timing` on the GPU.
    pub fn observe(&mut self, used: u64, timing: &ProgressiveTiming) {
        if used == 0 || timing.fill_ms <= 0.0 {
            return;
        }
        let fixed = timing.reproject_ms + timing.screen_ms;
        let available = (self.target_ms * Self::HEADROOM - fixed).max(0.0);
        let wanted = used as f64 * (available / timing.fill_ms);
        let next = wanted.clamp(used as f64 / 2.0, used as f64 * 2.0) as u64;
        self.current = next.clamp(self.floor, self.slots.max(self.floor));
    }
}

/// What one frame did.
#[derive(Clone, Debug, PartialEq)]
pub struct ProgressiveReport {
    pub frame: u64,
    pub progress: LoadProgress,
    /// Slots the Fill pass drew this frame (S).
    pub fill_budget: u64,
    /// Points scattered into the buffer before this frame (the frame shows them).
    pub uploaded_points: u64,
    /// A colours-only reload (attribute switching) is running.
    pub recoloring: bool,
    /// The image is final for this camera: all points loaded and drawn since it last moved.
    pub converged: bool,
    /// The GPU timing of an earlier frame that arrived during this one.
    pub timing: Option<(u64, ProgressiveTiming)>,
    /// The reader's error that ended loading, reported in the one frame that received it.
    pub failure: Option<String>,
}

/// A frame timed from its submission to its completion (adapters without timestamps).
struct Untimed {
    frame: u64,
    /// Nanoseconds it took, 0 until it completed.
    done_ns: Arc<AtomicU64>,
}

/// What making a scene's GPU side took (`bench` shows it beside the time to the first frame).
#[derive(Clone, Copy, Debug, Default)]
pub struct OpenTimes {
    /// Building the passes (pipelines).
    pub passes: Duration,
    /// Allocating the shuffled buffer (a store's first chunk: the others are made while it
    /// is drawn) and the draw lists, and marking their slots empty.
    pub buffers: Duration,
    /// Chunks of the shuffled buffer made then, of all it has.
    pub chunks_made: usize,
    pub chunks: usize,
}

/// A point file loading into a shuffled buffer and drawn progressively.
pub struct ProgressiveScene {
    config: ProgressiveConfig,
    open_times: OpenTimes,
    load: ProgressiveLoad,
    /// The points load once it finished (kept for its progress), while `load` recolours.
    finished: Option<LoadProgress>,
    cloud: ProgressiveCloud,
    shuffle: ShufflePass,
    renderer: ProgressiveRenderer,
    state: Option<ProgressiveState>,
    budget: FillBudget,
    bounds: Aabb,
    /// Camera and hidden classes of the last frame, and slots filled since they (or the
    /// buffer's contents) last changed.
    last_view: Option<(Camera, [u32; 8], SplatSettings)>,
    filled_since_change: u64,
    /// Fill budgets of frames whose timings have not arrived yet.
    pending: VecDeque<(u64, u64)>,
    /// The frame timed without timestamps (fallback timing), while it runs.
    untimed: Option<Untimed>,
    frame: u64,
    failure: Option<String>,
}

impl ProgressiveScene {
    /// Opens `path`, sizes the shuffled buffer to the file (or the VRAM budget) and starts
    /// loading. Errors here mean nothing was loaded.
    pub fn open(
        ctx: &GpuContext,
        path: &Path,
        config: ProgressiveConfig,
    ) -> Result<Self, EngineError> {
        Self::open_many(ctx, &[path.to_path_buf()], config)
    }

    /// [`open`](Self::open) for several inputs drawn together in one coordinate frame.
    pub fn open_many(
        ctx: &GpuContext,
        inputs: &[PathBuf],
        config: ProgressiveConfig,
    ) -> Result<Self, EngineError> {
        let load = Self::start_load_many(inputs, &config)?;
        Self::with_load(ctx, load, config)
    }

    /// Starts loading `path` as [`open`](Self::open) would, before any GPU exists (the viewer
    /// reads while its window opens); [`with_load`](Self::with_load) takes it from there.
    pub fn start_load(
        path: &Path,
        config: &ProgressiveConfig,
    ) -> Result<ProgressiveLoad, EngineError> {
        Self::start_load_many(&[path.to_path_buf()], config)
    }

    /// [`start_load`](Self::start_load) for several inputs.
    pub fn start_load_many(
        inputs: &[PathBuf],
        config: &ProgressiveConfig,
    ) -> Result<ProgressiveLoad, EngineError> {
        let budget_slots = (config.vram_budget / SLOT_BYTES).max(1);
        let load = LoadConfig {
            max_slots: config.load.max_slots.min(budget_slots),
            colors_only: false,
            ..config.load.clone()
        };
        ProgressiveLoad::start_many(inputs, load)
    }

    /// The scene of a load begun by [`start_load`](Self::start_load) with the same `config`.
    pub fn with_load(
        ctx: &GpuContext,
        load: ProgressiveLoad,
        mut config: ProgressiveConfig,
    ) -> Result<Self, EngineError> {
        let path = load.path().to_path_buf();
        // Batches decoded from now on go straight into upload memory.
        load.use_device(ctx);
        config.load.max_slots = load.slots();
        let started = Instant::now();
        let renderer = ProgressiveRenderer::new(ctx, config.variant, config.page_size)?;
        let shuffle = ShufflePass::new(ctx)?;
        let passes = started.elapsed();
        if load.slots() > u64::from(u32::MAX) {
            return Err(EngineError::Config(format!(
                "{}: {} slots exceed a shuffled buffer's {}",
                path.display(),
                load.slots(),
                u32::MAX
            )));
        }
        let meta_bounds = load.bounds();
        let started = Instant::now();
        // Where the device makes memory slowly, a store's pointlets go chunk by chunk, each
        // drawn once it is made and loaded; else they interleave over the whole buffer, made
        // before the first frame, so that every fill draws a sample of the whole store.
        let order = match (
            load.order(),
            ProgressiveCloud::chunk_slots(ctx, config.page_size),
        ) {
            (SlotOrder::Interleaved(g), Some(chunk_slots)) => g
                .chunked(chunk_slots)
                .map(SlotOrder::Interleaved)
                .map_err(|e| EngineError::Config(format!("{}: {e}", path.display())))?,
            (order, _) => order,
        };
        let cloud = ProgressiveCloud::with_order(ctx, order, meta_bounds, config.page_size)?;
        let buffers = started.elapsed();
        let (chunks_made, chunks) = cloud.chunks();
        let budget = FillBudget::new(u64::from(cloud.points()), config.target_frame_ms);
        Ok(Self {
            config,
            open_times: OpenTimes {
                passes,
                buffers,
                chunks_made,
                chunks,
            },
            load,
            finished: None,
            cloud,
            shuffle,
            renderer,
            state: None,
            budget,
            bounds: meta_bounds,
            last_view: None,
            filled_since_change: 0,
            pending: VecDeque::new(),
            untimed: None,
            frame: 0,
            failure: None,
        })
    }

    pub fn path(&self) -> &Path {
        self.load.path()
    }

    /// The inputs drawn, in order.
    pub fn inputs(&self) -> &[PathBuf] {
        self.load.inputs()
    }

    /// Draws `inputs` instead, loading them from the start into a buffer sized for them; the
    /// colouring and the passes stay.
    pub fn reopen(&mut self, ctx: &GpuContext, inputs: &[PathBuf]) -> Result<(), EngineError> {
        let mut config = self.config.clone();
        // The VRAM budget sizes the new buffer, not the old one's slot count.
        config.load.max_slots = LoadConfig::default().max_slots;
        config.load.colors_only = false;
        config.load.color = self.asked_mode();
        *self = Self::open_many(ctx, inputs, config)?;
        Ok(())
    }

    /// What the reader noted about the file.
    pub fn notes(&self) -> &[String] {
        self.load.notes()
    }

    /// The header's bounds (the camera's framing).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Points of the file (the header's count).
    pub fn points(&self) -> u64 {
        self.load.total()
    }

    /// Slots of the shuffled buffer (fewer than [`points`](Self::points) past the VRAM budget).
    pub fn slots(&self) -> u64 {
        u64::from(self.cloud.points())
    }

    /// What making the GPU side took.
    pub fn open_times(&self) -> OpenTimes {
        self.open_times
    }

    /// Buffers (chunks) of the shuffled buffer made so far, and all it will have: a store's
    /// are made while the first ones are drawn.
    pub fn buffer_chunks(&self) -> (usize, usize) {
        self.cloud.chunks()
    }

    /// GPU bytes of the shuffled buffer.
    pub fn gpu_bytes(&self) -> u64 {
        self.slots() * SLOT_BYTES
    }

    pub fn variant(&self) -> RasterVariant {
        self.config.variant
    }

    /// The colouring, once the load thread has chosen it.
    pub fn color(&self) -> Option<LoadColor> {
        self.load.color()
    }

    /// The colouring, waiting up to `timeout` for the load thread to choose it from its
    /// sample (the first batch, or a few parts decoded in parallel).
    pub fn color_within(&self, timeout: std::time::Duration) -> Option<LoadColor> {
        let start = Instant::now();
        loop {
            let c = self.load.color();
            if c.is_some() || start.elapsed() >= timeout || self.load.progress().is_finished() {
                return c;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }

    /// The attributes the file has.
    pub fn layout(&self) -> pointlet_core::PointLayout {
        self.load.layout()
    }

    /// Its extra-bytes attributes.
    pub fn extras(&self) -> &pointlet_core::extra::ExtraAttributes {
        self.load.extras()
    }

    /// The reader's error that ended loading, if any (the points before it stay drawn).
    pub fn failure(&self) -> Option<&str> {
        self.failure.as_deref()
    }

    /// Progress of loading the points (not of a recolouring).
    pub fn progress(&self) -> LoadProgress {
        self.finished.unwrap_or_else(|| self.load.progress())
    }

    /// Draws with another closest-point rasterizer from the next frame on (the image is
    /// built again from the buffer).
    pub fn set_variant(
        &mut self,
        ctx: &GpuContext,
        variant: RasterVariant,
    ) -> Result<(), EngineError> {
        self.renderer = ProgressiveRenderer::new(ctx, variant, self.config.page_size)?;
        self.config.variant = variant;
        self.state = None;
        self.pending.clear();
        self.untimed = None;
        Ok(())
    }

    /// Colours every point by `mode`: once the points are loaded, the file is read again for
    /// the colours alone (positions stay on the GPU); while loading, loading starts over with
    /// the new colouring.
    pub fn recolor(&mut self, mode: ColorMode) -> Result<(), EngineError> {
        self.reload_colors(Some(mode), None)
    }

    /// The colouring of the newest load: its mode (once chosen, the default's), and the exact
    /// scale when one was given ([`recolor_with`](Self::recolor_with)).
    pub fn asked_mode(&self) -> Option<ColorMode> {
        let l = &self.config.load;
        l.scale
            .map(|s| s.mode)
            .or(l.color)
            .or(self.load.color().map(|c| c.scale.mode))
    }

    pub fn asked_scale(&self) -> Option<ColorScale> {
        self.config.load.scale
    }

    /// Colours every point with exactly `scale` (a range or ramp edited in the viewer), as
    /// [`recolor`](Self::recolor) does.
    pub fn recolor_with(&mut self, scale: ColorScale) -> Result<(), EngineError> {
        self.reload_colors(Some(scale.mode), Some(scale))
    }

    fn reload_colors(
        &mut self,
        mode: Option<ColorMode>,
        scale: Option<ColorScale>,
    ) -> Result<(), EngineError> {
        let mut load = self.config.load.clone();
        load.color = mode;
        load.scale = scale;
        let points_loaded = self.finished.is_some() || self.load.progress().is_finished();
        if points_loaded {
            if self.finished.is_none() {
                self.finished = Some(self.load.progress());
            }
            load.colors_only = true;
        }
        let next = ProgressiveLoad::start_many(self.load.inputs(), load.clone())?;
        if let Some(upload) = self.load.upload() {
            next.use_upload(upload);
        }
        self.load = next;
        self.config.load.color = mode;
        self.config.load.scale = scale;
        Ok(())
    }

    /// Scatters the batches that are ready: `batches_per_frame`, then more while the frame's
    /// share of upload time lasts.
    fn upload(&mut self, ctx: &GpuContext) -> Result<Uploaded, EngineError> {
        let started = Instant::now();
        // A nonsensical share (negative, NaN, infinite) takes no batch beyond the first ones.
        let share = Duration::try_from_secs_f64(
            self.config.target_frame_ms * self.config.upload_share / 1e3,
        )
        .unwrap_or(Duration::ZERO);
        let (dst, pass) = (self.cloud.shuffled(), &mut self.shuffle);
        let mut up = self
            .load
            .upload_ready(ctx, pass, dst, self.config.batches_per_frame)?;
        let interleaved = matches!(dst.order(), SlotOrder::Interleaved(_));
        while interleaved
            && up.batches >= self.config.batches_per_frame
            && up.batches < self.config.max_batches_per_frame
            && up.failure.is_none()
            && started.elapsed() < share
        {
            let more = self.load.upload_ready(ctx, pass, dst, 1)?;
            if more.batches == 0 && more.failure.is_none() {
                break;
            }
            up.batches += more.batches;
            up.points += more.points;
            up.stored += more.stored;
            up.failure = more.failure;
        }
        Ok(up)
    }

    /// Draws one frame: scatters what the load thread has ready, then reproject → fill →
    /// screen passes → prepare. Never waits for the load thread or for the GPU. Another
    /// `settings.variant` than the scene's rebuilds the passes first (see `set_variant`).
    pub fn frame(
        &mut self,
        ctx: &GpuContext,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<ProgressiveReport, EngineError> {
        if settings.variant != self.config.variant {
            self.set_variant(ctx, settings.variant)?;
        }
        let (screen, hidden_classes, splats) =
            (&settings.screen, &settings.hidden_classes, &settings.splats);
        self.frame += 1;
        let up = self.upload(ctx)?;
        if let Some(f) = &up.failure {
            self.failure = Some(f.to_string());
        }
        let recoloring = self.load.colors_only();
        if recoloring && self.load.progress().is_finished() {
            // The colours are in; the points load's progress stands for the file.
            self.finished = self.finished.or(Some(self.load.progress()));
        }
        let size_changed = self
            .state
            .as_ref()
            .is_none_or(|s| s.size() != (target.width, target.height));
        if size_changed {
            self.state = Some(ProgressiveState::new(ctx, target)?);
        }
        let view = (*camera, *hidden_classes, *splats);
        let changed = size_changed || up.batches > 0 || self.last_view != Some(view);
        self.last_view = Some(view);
        let slots = self.slots();
        let budget = self.config.fixed_budget.unwrap_or(self.budget.current());
        let budget = budget.clamp(1, slots.max(1));
        let settings = ProgressiveSettings {
            budget: u32::try_from(budget).unwrap_or(u32::MAX),
            reproject: self.config.reproject,
            screen: *screen,
            hidden_classes: *hidden_classes,
            splats: *splats,
        };
        // Adaptive splats: the buffer holds a uniform subset of the file, so its spacing is the
        // file's grown by √(points in the file / points in the buffer).
        let shown = self.load.progress().shown().max(1);
        if let Some(full) = self.load.spacing() {
            let total = self.load.progress().total.max(shown);
            self.cloud
                .set_spacing(full * (total as f64 / shown as f64).sqrt());
        }
        let Some(state) = self.state.as_mut() else {
            return Err(EngineError::Config("no progressive state".into()));
        };
        if changed {
            self.filled_since_change = 0;
            state.changed();
        }
        self.renderer
            .render(ctx, &self.cloud, state, camera, &settings, target)?;
        // A store's next chunk, made while the GPU draws this frame and copies its batches.
        self.cloud.make_next_chunk(ctx)?;
        let frame = self.renderer.frames();
        self.filled_since_change += budget;
        let timing = self.collect_timing(ctx, target, frame, budget);
        let progress = self.progress();
        let loading = !self.load.progress().is_finished();
        let converged = !loading && self.filled_since_change >= slots;
        Ok(ProgressiveReport {
            frame: self.frame,
            progress,
            fill_budget: budget,
            uploaded_points: up.points,
            recoloring: recoloring && loading,
            converged,
            timing,
            failure: up.failure.map(|e| e.to_string()),
        })
    }

    /// Feeds the adaptive budget with the newest GPU timing (timestamps, or without them the
    /// time from submitting a frame to its completion).
    fn collect_timing(
        &mut self,
        ctx: &GpuContext,
        target: &mut RenderTarget,
        frame: u64,
        budget: u64,
    ) -> Option<(u64, ProgressiveTiming)> {
        self.pending.push_back((frame, budget));
        while self.pending.len() > 64 {
            self.pending.pop_front();
        }
        let mut newest = None;
        if ctx.caps.timestamps {
            for (f, t) in self.renderer.poll_timings(ctx, target) {
                if let Some(&(_, used)) = self.pending.iter().find(|(pf, _)| *pf == f) {
                    self.budget.observe(used, &t);
                }
                self.pending.retain(|(pf, _)| *pf > f);
                newest = Some((f, t));
            }
            return newest;
        }
        // Without timestamps: one frame at a time is timed from submission to completion.
        let _ = ctx.device.poll(wgpu::PollType::Poll);
        let done = self
            .untimed
            .as_ref()
            .map(|u| u.done_ns.load(Ordering::Acquire));
        if let (Some(untimed), Some(ns)) = (&self.untimed, done.filter(|ns| *ns > 0)) {
            let t = ProgressiveTiming {
                fill_ms: ns as f64 * 1e-6,
                ..Default::default()
            };
            let f = untimed.frame;
            if let Some(&(_, used)) = self.pending.iter().find(|(pf, _)| *pf == f) {
                self.budget.observe(used, &t);
            }
            self.pending.retain(|(pf, _)| *pf > f);
            newest = Some((f, t));
            self.untimed = None;
        }
        if self.untimed.is_none() {
            let done_ns = Arc::new(AtomicU64::new(0));
            let (flag, at) = (Arc::clone(&done_ns), Instant::now());
            ctx.queue.on_submitted_work_done(move || {
                let ns = at.elapsed().as_nanos().clamp(1, u128::from(u64::MAX)) as u64;
                flag.store(ns, Ordering::Release);
            });
            self.untimed = Some(Untimed { frame, done_ns });
        }
        newest
    }

    /// The shuffled buffer's streams read back in slot order, and the origin its positions
    /// are relative to (waits for the GPU; for tests and diagnostics).
    pub fn read_buffer(
        &self,
        ctx: &GpuContext,
    ) -> Result<(ShuffledContents, [f64; 3]), EngineError> {
        Ok((self.cloud.shuffled().read(ctx)?, self.cloud.origin()))
    }

    /// The position of the point the last frame showed nearest to `pixel` (within `radius`
    /// pixels), to f32 precision around the cloud's minimum; waits for the GPU.
    pub fn pick(
        &self,
        ctx: &GpuContext,
        pixel: [u32; 2],
        radius: u32,
    ) -> Result<Option<[f64; 3]>, EngineError> {
        let Some(state) = &self.state else {
            return Ok(None);
        };
        match state.pick(ctx, pixel, radius)? {
            Some(hit) => Ok(self.cloud.position(ctx, hit.id)?),
            None => Ok(None),
        }
    }

    /// Blocks until at most `max` frames run on the GPU (a swap chain's depth).
    pub fn limit_frames_in_flight(
        &mut self,
        ctx: &GpuContext,
        max: usize,
    ) -> Result<(), EngineError> {
        Ok(self.renderer.limit_frames_in_flight(ctx, max)?)
    }

    /// Waits up to `timeout` until the load thread has something new for the next frame.
    pub fn wait_ready(&mut self, timeout: std::time::Duration) -> bool {
        self.load.wait_ready(timeout)
    }
}
