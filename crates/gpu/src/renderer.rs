//! One frame: (LoD →) raster (a compute variant or the hardware baseline) → screen passes.

use crate::cloud::GpuCloud;
use crate::context::GpuContext;
use crate::hw_points::HwPointsPipeline;
use crate::paged::{PagedCloud, PagedView};
use crate::raster::{RasterDispatch, RasterPipelines, RasterVariant};
use crate::reuse::TemporalReuse;
use crate::screen::{ScreenPasses, ScreenSettings};
use crate::splat::{SplatMode, SplatSettings};
use crate::storage::PointEncoding;
use crate::target::RenderTarget;
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
    /// drawn (adaptive splats shrink as a still view adds points, so those frames redraw).
    pub fn accumulates(&self) -> bool {
        self.variant.accumulates() && !self.splats.is_adaptive()
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
    pub(crate) pick: HashMap<(PointEncoding, u32, SplatMode), RasterPipelines>,
    screen: ScreenPasses,
    /// Frames submitted so far (the ids timings carry).
    frames: u64,
    in_flight: std::collections::VecDeque<wgpu::SubmissionIndex>,
}

type Stamps<'a> = Option<wgpu::ComputePassTimestampWrites<'a>>;

impl Renderer {
    pub fn new(ctx: &GpuContext) -> Self {
        Self {
            raster: HashMap::new(),
            hw: HashMap::new(),
            pick: HashMap::new(),
            screen: ScreenPasses::new(&ctx.device),
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
        variant: RasterVariant,
        encoding: PointEncoding,
        page_size: u32,
        splats: SplatMode,
    ) -> Result<(), GpuError> {
        let device = &ctx.device;
        if variant == RasterVariant::HwPoints {
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
        self.ensure_pipelines(ctx, variant, cloud.encoding, cloud.page_size, mode)?;
        cloud.prepare(
            ctx,
            camera,
            (target.width, target.height),
            &settings.hidden_classes,
            &settings.splats,
        );
        self.screen
            .prepare(&ctx.queue, target, &settings.screen, camera.fov_y_deg);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let timer = target.timer.as_ref();
        let stamps = |begin: u32| {
            timer.map(|t| wgpu::ComputePassTimestampWrites {
                query_set: &t.queries,
                beginning_of_pass_write_index: Some(begin),
                end_of_pass_write_index: Some(begin + 1),
            })
        };
        if variant == RasterVariant::HwPoints {
            if let Some(hw) = self.hw.get(&(cloud.encoding, cloud.page_size)) {
                let writes = timer.map(|t| wgpu::RenderPassTimestampWrites {
                    query_set: &t.queries,
                    beginning_of_pass_write_index: Some(2),
                    end_of_pass_write_index: Some(3),
                });
                hw.record(&mut enc, cloud, target, writes);
            }
        } else {
            self.record_raster(
                ctx,
                &mut enc,
                variant,
                (cloud.encoding, cloud.page_size, mode),
                &cloud.storage,
                RasterDispatch::Direct,
                target,
                true,
                stamps(2),
            );
        }
        self.finish_frame(ctx, enc, target, settings, false)
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
        reuse: Option<&mut TemporalReuse>,
    ) -> Result<(), GpuError> {
        let variant = settings.variant;
        if variant == RasterVariant::HwPoints {
            return Err(GpuError::Unsupported {
                what: variant.name().to_string(),
                why: "the point-list baseline draws static clouds only (bench-raster)".into(),
                adapter: ctx.describe(),
            });
        }
        let mode = settings.splats.mode();
        Self::check(ctx, variant, &settings.splats, camera)?;
        self.ensure_pipelines(ctx, variant, paged.encoding, paged.page_size, mode)?;
        self.screen
            .prepare(&ctx.queue, target, &settings.screen, camera.fov_y_deg);
        // Only closest-point rasterizers are order independent and can add points to a kept
        // framebuffer; HQS must see all points of a frame in both of its passes, and adaptive
        // splats change size as points are added.
        let view = PagedView {
            accumulate: view.accumulate && settings.accumulates(),
            ..*view
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let timer = target.timer.as_ref();
        let stamps = |begin: u32| {
            timer.map(|t| wgpu::ComputePassTimestampWrites {
                query_set: &t.queries,
                beginning_of_pass_write_index: Some(begin),
                end_of_pass_write_index: Some(begin + 1),
            })
        };
        paged.record_lod(
            ctx,
            &mut enc,
            camera,
            (target.width, target.height),
            &view,
            settings,
            timer.map(|t| &t.queries),
        )?;
        self.record_raster(
            ctx,
            &mut enc,
            variant,
            (paged.encoding, paged.page_size, mode),
            &paged.storage,
            RasterDispatch::Indirect(&paged.indirect),
            target,
            !view.accumulate,
            stamps(2),
        );
        if let Some(reuse) = reuse {
            if settings.accumulates() {
                let reprojected =
                    !view.accumulate && reuse.record_reproject(ctx, &mut enc, target, camera)?;
                reuse.record_keep(ctx, &mut enc, target, camera, reprojected)?;
            } else {
                reuse.forget();
            }
        }
        self.finish_frame(ctx, enc, target, settings, true)?;
        paged.after_submit();
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn record_raster(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        variant: RasterVariant,
        key: (PointEncoding, u32, SplatMode),
        storage: &crate::storage::PointStorage,
        dispatch: RasterDispatch<'_>,
        target: &RenderTarget,
        clear: bool,
        stamps: Stamps<'_>,
    ) {
        let Some(pipes) = self.raster.get(&(variant, key.0, key.1, key.2)) else {
            return;
        };
        let buffers = variant.buffers().buffers(target);
        if clear {
            for b in &buffers {
                enc.clear_buffer(b, 0, None);
            }
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(variant.name()),
            timestamp_writes: stamps,
        });
        pipes.record(&ctx.device, &mut pass, storage, dispatch, &buffers);
    }

    fn finish_frame(
        &mut self,
        ctx: &GpuContext,
        mut enc: wgpu::CommandEncoder,
        target: &mut RenderTarget,
        settings: &RenderSettings,
        had_lod: bool,
    ) -> Result<(), GpuError> {
        let kind = settings.variant.buffers();
        let device = &ctx.device;
        let screen_passes = &mut self.screen;
        self.frames += 1;
        let frame = self.frames;
        let submission = {
            let target_ref = &*target;
            let stamps = target_ref
                .timer
                .as_ref()
                .map(|t| wgpu::ComputePassTimestampWrites {
                    query_set: &t.queries,
                    beginning_of_pass_write_index: Some(4),
                    end_of_pass_write_index: Some(5),
                });
            screen_passes.record(
                device,
                &mut enc,
                target_ref,
                kind,
                kind.carries_splat_sizes() && !settings.splats.is_pixel(),
                &settings.screen,
                stamps,
            );
            if let Some(t) = target.timer.as_mut() {
                t.resolve(&mut enc, frame, had_lod);
            }
            ctx.checked("rendering a frame", || ctx.queue.submit([enc.finish()]))?
        };
        if let Some(t) = target.timer.as_mut() {
            t.after_submit();
        }
        self.in_flight.push_back(submission);
        Ok(())
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
