//! One frame: (LoD →) raster (a compute variant or the hardware baseline) → screen passes, as
//! the frame's render graph (frame.rs) orders them.

use crate::cloud::GpuCloud;
use crate::context::GpuContext;
use crate::frame::{
    FrameGraph, FrameGraphSummary, FramePass, FrameShape, PixelResources, Source, Stamps,
};
use crate::hw_points::HwPointsPipeline;
use crate::paged::{PagedCloud, PagedView};
use crate::quads::{QuadDraw, QuadsPipeline};
use crate::raster::PixelKind;
use crate::raster::{RasterDispatch, RasterPipelines, RasterVariant};
use crate::reuse::TemporalReuse;
use crate::screen::{ScreenPasses, ScreenSettings};
use crate::splat::{SplatMode, SplatSettings, SplatShape};
use crate::storage::PointEncoding;
use crate::storage::PointStorage;
use crate::target::RenderTarget;
use crate::tile_pool::TilePool;
use crate::GpuError;
use pointlet_core::Camera;
use std::collections::hash_map::Entry;
use std::collections::HashMap;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub variant: RasterVariant,
    pub screen: ScreenSettings,
    /// One bit per ASPRS class (class c is bit c % 32 of word c / 32): set = not drawn.
    pub hidden_classes: [u32; 8],
    /// Point size and shape.
    pub splats: SplatSettings,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            variant: RasterVariant::ReduceEarlyZ,
            screen: ScreenSettings::default(),
            hidden_classes: [0; 8],
            splats: SplatSettings::default(),
        }
    }
}

impl RenderSettings {
    pub fn set_class_hidden(&mut self, class: u8, hidden: bool) {
        let (w, b) = ((class / 32) as usize, class % 32);
        if hidden {
            self.hidden_classes[w] |= 1 << b;
        } else {
            self.hidden_classes[w] &= !(1 << b);
        }
    }

    pub fn class_hidden(&self, class: u8) -> bool {
        self.hidden_classes[(class / 32) as usize] & (1 << (class % 32)) != 0
    }

    /// True when more points can be drawn into a kept framebuffer later with the same result:
    /// closest-point variants with splats whose size does not depend on how many points are
    /// drawn (adaptive splats shrink as a still view adds points, so those frames redraw),
    /// drawn by the compute rasterizers (billboard quads clear their layer each frame).
    pub fn accumulates(&self) -> bool {
        self.variant.accumulates() && !self.splats.is_adaptive() && !self.splats.quads()
    }

    /// The frame uniform's splat words (splat.rs): blending draws gap-filling rings with its
    /// splats, the closest-point rasterizers leave the gaps to a screen pass.
    pub(crate) fn splat_words(&self, focal_px: f64) -> [f32; 4] {
        self.splats.uniform(focal_px, !self.variant.closest_point())
    }

    /// Whether the frame fills splat gaps on the screen (adaptive closest-point splats; blending
    /// draws rings instead).
    pub(crate) fn screen_gaps(&self) -> bool {
        self.splats.is_adaptive() && self.variant.closest_point()
    }

    /// Whether splats go through the billboard-quad pipeline this frame.
    pub fn quads(&self) -> bool {
        self.splats.quads() && self.variant.accumulates()
    }
}

/// GPU time of a frame's stages, from timestamp queries (upload and LoD are 0 for static
/// clouds).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTiming {
    /// Scatter of the frame's new pages and table changes (the residency work on the GPU).
    pub upload_ms: f64,
    pub lod_ms: f64,
    pub raster_ms: f64,
    pub screen_ms: f64,
}

/// Owns the pipelines (built on first use) for every variant and encoding drawn so far.
pub struct Renderer {
    raster: HashMap<(RasterVariant, PointEncoding, u32, SplatMode), RasterPipelines>,
    hw: HashMap<(PointEncoding, u32), HwPointsPipeline>,
    quads: HashMap<(PointEncoding, u32, SplatShape), QuadsPipeline>,
    pub(crate) pick: HashMap<(PointEncoding, u32, SplatMode), RasterPipelines>,
    pub(crate) screen: ScreenPasses,
    /// Frame graphs, compiled once per shape.
    pub(crate) graphs: HashMap<FrameShape, FrameGraph>,
    /// CPU time the graphs took besides their passes, and the frames it covers.
    graph_overhead: (std::time::Duration, u64),
    /// The pick passes' graph, compiled on the first pick.
    pub(crate) pick_graph: Option<crate::pick::PickGraph>,
    /// Frames submitted so far (the ids timings carry).
    frames: u64,
    in_flight: std::collections::VecDeque<wgpu::SubmissionIndex>,
}

impl Renderer {
    pub fn new(ctx: &GpuContext) -> Self {
        Self {
            pick_graph: None,
            raster: HashMap::new(),
            hw: HashMap::new(),
            quads: HashMap::new(),
            pick: HashMap::new(),
            screen: ScreenPasses::new(&ctx.device),
            graphs: HashMap::new(),
            graph_overhead: Default::default(),
            frames: 0,
            in_flight: std::collections::VecDeque::new(),
        }
    }

    pub(crate) fn check(
        ctx: &GpuContext,
        variant: RasterVariant,
        splats: &SplatSettings,
        camera: &Camera,
    ) -> Result<(), GpuError> {
        if let Some(why) = variant.unsupported_reason(&ctx.caps) {
            return Err(GpuError::Unsupported {
                what: variant.name().to_string(),
                why: why.to_string(),
                adapter: ctx.describe(),
            });
        }
        if splats.quads() && !variant.accumulates() {
            return Err(GpuError::InvalidInput(format!(
                "billboard quads keep the closest splat per pixel: {} blends or needs two passes; use a closest-point --raster or compute splats",
                variant.name()
            )));
        }
        if variant == RasterVariant::HwPoints && !splats.is_pixel() {
            return Err(GpuError::InvalidInput(
                "hw-points draws one-pixel points (the point-list baseline): larger points need a compute --raster".into(),
            ));
        }
        camera
            .validate()
            .map_err(|e| GpuError::InvalidInput(e.to_string()))
    }

    /// Pipelines are built on first use, inside an error scope: a shader the driver rejects is
    /// an error, not a panic.
    fn ensure_pipelines(
        &mut self,
        ctx: &GpuContext,
        settings: &RenderSettings,
        encoding: PointEncoding,
        page_size: u32,
    ) -> Result<(), GpuError> {
        let device = &ctx.device;
        let (variant, splats) = (settings.variant, settings.splats.mode());
        if settings.quads() {
            let shape = settings.splats.shape;
            if let Entry::Vacant(slot) = self.quads.entry((encoding, page_size, shape)) {
                slot.insert(ctx.checked("building the billboard-quad pipeline", || {
                    QuadsPipeline::new(device, encoding, page_size, shape)
                })?);
            }
        } else if variant == RasterVariant::HwPoints {
            if let Entry::Vacant(slot) = self.hw.entry((encoding, page_size)) {
                slot.insert(ctx.checked("building the hw-points pipeline", || {
                    HwPointsPipeline::new(device, encoding, page_size)
                })?);
            }
        } else if let Entry::Vacant(slot) =
            self.raster.entry((variant, encoding, page_size, splats))
        {
            slot.insert(ctx.checked(
                &format!("building the {} pipelines", variant.name()),
                || RasterPipelines::new(device, variant, encoding, page_size, splats),
            )?);
        }
        Ok(())
    }

    /// Records and submits one frame of a static `cloud` seen by `camera` into `target`.
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        cloud: &mut GpuCloud,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<(), GpuError> {
        let variant = settings.variant;
        let mode = settings.splats.mode();
        Self::check(ctx, variant, &settings.splats, camera)?;
        self.ensure_pipelines(ctx, settings, cloud.encoding, cloud.page_size)?;
        cloud.prepare(ctx, camera, (target.width, target.height), settings);
        let shape = frame_shape(Source::Static, settings, false);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let pipes = self
            .raster
            .get(&(variant, cloud.encoding, cloud.page_size, mode));
        let hw = self.hw.get(&(cloud.encoding, cloud.page_size));
        let quads = self
            .quads
            .get(&(cloud.encoding, cloud.page_size, settings.splats.shape));
        let cloud = &*cloud;
        let overhead = record_frame(
            (&mut self.screen, &mut self.graphs),
            ctx,
            &mut enc,
            target,
            settings,
            camera,
            shape,
            |pass, enc, px, stamps| {
                match pass {
                    FramePass::HwPoints => {
                        if let (Some(hw), Some(depth)) = (hw, px.hw_depth) {
                            hw.record(enc, cloud, px.raster_layer, depth, stamps.render());
                        }
                    }
                    FramePass::Quads => {
                        if let (Some(q), Some(depth)) = (quads, px.hw_depth) {
                            let draw = QuadDraw::Direct;
                            let layer = px.raster_layer;
                            q.record(enc, &cloud.storage, draw, layer, depth, stamps.render());
                        }
                    }
                    FramePass::Raster(stage) => {
                        let dispatch = RasterDispatch::Direct;
                        let draw = StageDraw {
                            storage: &cloud.storage,
                            dispatch,
                            clear_keys: true,
                        };
                        record_stage(&ctx.device, enc, pipes, stage, &draw, px, variant, &stamps);
                    }
                    _ => {}
                }
                Ok(())
            },
        )?;
        self.graph_overhead.0 += overhead;
        self.graph_overhead.1 += 1;
        self.submit(ctx, enc, target, false)
    }

    /// Records and submits one frame of a paged (virtualized) cloud: the GPU LoD picks each
    /// pointlet's points under `view.bucket` and draws what is resident of them. With temporal
    /// `reuse`, a frame that does not accumulate starts from its kept frame reprojected to
    /// `camera`, and every frame is kept for the next (closest-point variants; the others draw
    /// as without reuse).
    #[allow(clippy::too_many_arguments)]
    pub fn render_paged(
        &mut self,
        ctx: &GpuContext,
        paged: &mut PagedCloud,
        camera: &Camera,
        settings: &RenderSettings,
        view: &PagedView,
        target: &mut RenderTarget,
        mut reuse: Option<&mut TemporalReuse>,
    ) -> Result<(), GpuError> {
        let variant = settings.variant;
        refuse_hw_points(ctx, variant)?;
        let mode = settings.splats.mode();
        Self::check(ctx, variant, &settings.splats, camera)?;
        self.ensure_pipelines(ctx, settings, paged.encoding, paged.page_size)?;
        // Only closest-point rasterizers are order independent and can add points to a kept
        // framebuffer; HQS must see all points of a frame in both of its passes, and adaptive
        // splats change size as points are added.
        let view = PagedView {
            accumulate: view.accumulate && settings.accumulates(),
            ..*view
        };
        // Temporal reuse moves the last frame's 64-bit keys: single-atomic closest-point
        // variants (adaptive splats too), not billboard quads, which write no keys.
        let keyed = variant.accumulates() && !settings.quads();
        if !keyed {
            if let Some(r) = reuse.as_deref_mut() {
                r.forget();
            }
        }
        let reusing = reuse.is_some() && keyed;
        let shape = frame_shape(Source::Paged, settings, reusing);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let pipes = self
            .raster
            .get(&(variant, paged.encoding, paged.page_size, mode));
        let quads = self
            .quads
            .get(&(paged.encoding, paged.page_size, settings.splats.shape));
        let queries = target.timer.as_ref().map(|t| t.queries.clone());
        let size = (target.width, target.height);
        let mut reprojected = false;
        let overhead = record_frame(
            (&mut self.screen, &mut self.graphs),
            ctx,
            &mut enc,
            target,
            settings,
            camera,
            shape,
            |pass, enc, px, stamps| {
                match pass {
                    FramePass::Lod => {
                        paged.record_lod(
                            ctx,
                            enc,
                            camera,
                            size,
                            &view,
                            settings,
                            queries.as_ref(),
                        )?;
                    }
                    FramePass::Raster(stage) => {
                        let draw = StageDraw {
                            storage: &paged.storage,
                            dispatch: RasterDispatch::Indirect(&paged.indirect),
                            clear_keys: !view.accumulate,
                        };
                        record_stage(&ctx.device, enc, pipes, stage, &draw, px, variant, &stamps);
                    }
                    FramePass::Quads => {
                        if let (Some(q), Some(depth)) = (quads, px.hw_depth) {
                            let draw = QuadDraw::Indirect(&paged.draw_args);
                            let layer = px.raster_layer;
                            q.record(enc, &paged.storage, draw, layer, depth, stamps.render());
                        }
                    }
                    FramePass::ReuseReproject => {
                        if let Some(r) = reuse.as_deref_mut() {
                            reprojected = !view.accumulate
                                && r.record_reproject(ctx, enc, px.keys, size, camera)?;
                        }
                    }
                    FramePass::ReuseKeep => {
                        if let Some(r) = reuse.as_deref_mut() {
                            r.record_keep(ctx, enc, px.keys, size, camera, reprojected)?;
                        }
                    }
                    _ => {}
                }
                Ok(())
            },
        )?;
        self.graph_overhead.0 += overhead;
        self.graph_overhead.1 += 1;
        self.submit(ctx, enc, target, true)?;
        paged.after_submit();
        Ok(())
    }

    /// Records and submits one frame of streamed tiles: the continuous-LoD filter (in the
    /// LoD's place) appends the survivors of the tiles [`TilePool::prepare`] laid out, and
    /// the chosen rasterizer and the screen passes draw them.
    pub fn render_tiles(
        &mut self,
        ctx: &GpuContext,
        pool: &TilePool,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<(), GpuError> {
        let variant = settings.variant;
        refuse_hw_points(ctx, variant)?;
        let mode = settings.splats.mode();
        Self::check(ctx, variant, &settings.splats, camera)?;
        let encoding = PointEncoding::Full16;
        self.ensure_pipelines(ctx, settings, encoding, pool.page_size)?;
        let shape = frame_shape(Source::Paged, settings, false);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let pipes = self.raster.get(&(variant, encoding, pool.page_size, mode));
        let quads = self
            .quads
            .get(&(encoding, pool.page_size, settings.splats.shape));
        let queries = target.timer.as_ref().map(|t| t.queries.clone());
        let overhead = record_frame(
            (&mut self.screen, &mut self.graphs),
            ctx,
            &mut enc,
            target,
            settings,
            camera,
            shape,
            |pass, enc, px, stamps| {
                match pass {
                    FramePass::Lod => {
                        // Timestamps 0/1: the LoD's, as for stores.
                        let writes = queries.as_ref().map(|q| wgpu::ComputePassTimestampWrites {
                            query_set: q,
                            beginning_of_pass_write_index: Some(0),
                            end_of_pass_write_index: Some(1),
                        });
                        pool.record_filter(enc, writes);
                    }
                    FramePass::Raster(stage) => {
                        let draw = StageDraw {
                            storage: &pool.output,
                            dispatch: RasterDispatch::Indirect(&pool.indirect),
                            clear_keys: true,
                        };
                        record_stage(&ctx.device, enc, pipes, stage, &draw, px, variant, &stamps);
                    }
                    FramePass::Quads => {
                        if let (Some(q), Some(depth)) = (quads, px.hw_depth) {
                            let draw = QuadDraw::Indirect(&pool.draw_args);
                            let layer = px.raster_layer;
                            q.record(enc, &pool.output, draw, layer, depth, stamps.render());
                        }
                    }
                    _ => {}
                }
                Ok(())
            },
        )?;
        self.graph_overhead.0 += overhead;
        self.graph_overhead.1 += 1;
        self.submit(ctx, enc, target, true)
    }

    fn submit(
        &mut self,
        ctx: &GpuContext,
        mut enc: wgpu::CommandEncoder,
        target: &mut RenderTarget,
        had_lod: bool,
    ) -> Result<(), GpuError> {
        self.frames += 1;
        if let Some(t) = target.timer.as_mut() {
            t.resolve(&mut enc, self.frames, had_lod);
        }
        let submission = ctx.checked("rendering a frame", || ctx.queue.submit([enc.finish()]))?;
        if let Some(t) = target.timer.as_mut() {
            t.after_submit();
        }
        self.in_flight.push_back(submission);
        Ok(())
    }

    /// Mean CPU time per frame that the render graph took besides recording its passes
    /// (looking up the compiled graph, transient allocation checks, clears, resolving
    /// resources and timestamps), since the last call; `None` before any frame.
    pub fn take_graph_overhead(&mut self) -> Option<std::time::Duration> {
        let (total, frames) = std::mem::take(&mut self.graph_overhead);
        (frames > 0).then(|| total / frames as u32)
    }

    /// The frame graphs compiled so far (one per frame shape drawn).
    pub fn frame_graphs(&self) -> Vec<FrameGraphSummary> {
        self.graphs.values().map(FrameGraph::summary).collect()
    }

    /// Frames submitted so far; timings carry these numbers.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Blocks until at most `max` submitted frames are still running on the GPU (as a swap
    /// chain would), so a render loop measures real throughput without queueing unboundedly.
    pub fn limit_frames_in_flight(&mut self, ctx: &GpuContext, max: usize) -> Result<(), GpuError> {
        limit_in_flight(ctx, &mut self.in_flight, max)
    }

    /// GPU timings that have arrived (never blocks), oldest first, with their frame numbers.
    pub fn poll_timings(
        &mut self,
        ctx: &GpuContext,
        target: &mut RenderTarget,
    ) -> Vec<(u64, FrameTiming)> {
        let Some(t) = target.timer.as_mut() else {
            return Vec::new();
        };
        t.poll(ctx)
            .into_iter()
            .map(|(frame, [lod, raster, screen, upload], paged)| {
                (
                    frame,
                    FrameTiming {
                        upload_ms: if paged { upload } else { 0.0 },
                        lod_ms: if paged { lod } else { 0.0 },
                        raster_ms: raster,
                        screen_ms: screen,
                    },
                )
            })
            .collect()
    }

    /// GPU timings of the last frame rendered into `target` (waits for it); `None` without
    /// timestamp queries or when the frame was not timed.
    pub fn timing(
        &mut self,
        ctx: &GpuContext,
        target: &mut RenderTarget,
    ) -> Result<Option<FrameTiming>, GpuError> {
        ctx.wait()?;
        self.in_flight.clear();
        let last = self.frames;
        Ok(self
            .poll_timings(ctx, target)
            .into_iter()
            .rev()
            .find(|(f, _)| *f == last)
            .map(|(_, t)| t))
    }
}

/// Waits for the oldest of `in_flight` until at most `max` are left.
pub(crate) fn limit_in_flight(
    ctx: &GpuContext,
    in_flight: &mut std::collections::VecDeque<wgpu::SubmissionIndex>,
    max: usize,
) -> Result<(), GpuError> {
    while in_flight.len() > max {
        if let Some(index) = in_flight.pop_front() {
            ctx.device
                .poll(wgpu::PollType::Wait {
                    submission_index: Some(index),
                    timeout: None,
                })
                .map_err(|e| GpuError::Device(format!("waiting for a frame: {e}")))?;
        }
    }
    Ok(())
}

/// The graph shape of a frame of `settings` from `source`.
pub(crate) fn frame_shape(source: Source, settings: &RenderSettings, reuse: bool) -> FrameShape {
    let quads = source != Source::Progressive && settings.quads();
    FrameShape {
        source,
        kind: if source == Source::Progressive {
            PixelKind::Key64
        } else if quads {
            PixelKind::Hardware
        } else {
            settings.variant.buffers()
        },
        quads,
        reuse,
        gaps: settings.screen_gaps().then_some(settings.splats.shape),
        occlusion: settings.screen.occlusion.is_some(),
        fill: settings.screen.fill_radius > 0,
    }
}

/// Prepares the screen passes and records the graph of `shape` (compiled on first use), the
/// passes of points through `points`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn record_frame(
    (screen, graphs): (&mut ScreenPasses, &mut HashMap<FrameShape, FrameGraph>),
    ctx: &GpuContext,
    enc: &mut wgpu::CommandEncoder,
    target: &mut RenderTarget,
    settings: &RenderSettings,
    camera: &Camera,
    shape: FrameShape,
    points: impl FnMut(
        FramePass,
        &mut wgpu::CommandEncoder,
        &PixelResources<'_>,
        Stamps<'_>,
    ) -> Result<(), GpuError>,
) -> Result<std::time::Duration, GpuError> {
    screen.prepare(&ctx.queue, target, &settings.screen, camera.fov_y_deg);
    let looked_up = web_time::Instant::now();
    if let Entry::Vacant(slot) = graphs.entry(shape) {
        slot.insert(FrameGraph::build(shape).map_err(|e| GpuError::Device(e.to_string()))?);
    }
    let Some(graph) = graphs.get(&shape) else {
        return Ok(std::time::Duration::ZERO);
    };
    let lookup = looked_up.elapsed();
    let splat_sizes = shape.kind.carries_splat_sizes() && !settings.splats.is_pixel();
    Ok(lookup + graph.record(ctx, enc, target, screen, splat_sizes, points)?)
}

/// What a raster stage draws: the points and how many workgroups, and whether the 64-bit keys
/// start empty (off when a still view accumulates).
pub(crate) struct StageDraw<'a> {
    pub storage: &'a PointStorage,
    pub dispatch: RasterDispatch<'a>,
    pub clear_keys: bool,
}

/// Records stage `stage` of `pipes` into the pixel buffers of `variant`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn record_stage(
    device: &wgpu::Device,
    enc: &mut wgpu::CommandEncoder,
    pipes: Option<&RasterPipelines>,
    stage: u8,
    draw: &StageDraw<'_>,
    px: &PixelResources<'_>,
    variant: RasterVariant,
    stamps: &Stamps<'_>,
) {
    let Some(pipes) = pipes else {
        return;
    };
    let kind = variant.buffers();
    if kind == PixelKind::Key64 && stage == 0 && draw.clear_keys {
        enc.clear_buffer(px.keys, 0, None);
    }
    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(variant.name()),
        timestamp_writes: stamps.compute(),
    });
    pipes.record_stage(
        device,
        &mut pass,
        stage as usize,
        draw.storage,
        draw.dispatch,
        &px.buffers(kind),
    );
}

/// The point-list baseline draws static clouds only: pages chosen on the GPU (stores, tiles)
/// are drawn by the compute rasterizers.
fn refuse_hw_points(ctx: &GpuContext, variant: RasterVariant) -> Result<(), GpuError> {
    if variant == RasterVariant::HwPoints {
        return Err(GpuError::Unsupported {
            what: variant.name().to_string(),
            why: "the point-list baseline draws static clouds only (bench-raster)".into(),
            adapter: ctx.describe(),
        });
    }
    Ok(())
}
