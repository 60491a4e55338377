//! One frame: raster (a compute variant or the hardware baseline) → screen passes → image.

use crate::cloud::GpuCloud;
use crate::context::GpuContext;
use crate::hw_points::HwPointsPipeline;
use crate::raster::{RasterPipelines, RasterVariant};
use crate::screen::{ScreenPasses, ScreenSettings};
use crate::storage::PointEncoding;
use crate::target::RenderTarget;
use crate::GpuError;
use pointlet_core::Camera;
use std::collections::HashMap;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub variant: RasterVariant,
    pub screen: ScreenSettings,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            variant: RasterVariant::ReduceEarlyZ,
            screen: ScreenSettings::default(),
        }
    }
}

/// GPU time of a frame's stages, from timestamp queries.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTiming {
    pub raster_ms: f64,
    pub screen_ms: f64,
}

/// Owns the pipelines (built on first use) for every variant and encoding drawn so far.
pub struct Renderer {
    raster: HashMap<(RasterVariant, PointEncoding, u32), RasterPipelines>,
    hw: HashMap<(PointEncoding, u32), HwPointsPipeline>,
    screen: ScreenPasses,
}

impl Renderer {
    pub fn new(ctx: &GpuContext) -> Self {
        Self {
            raster: HashMap::new(),
            hw: HashMap::new(),
            screen: ScreenPasses::new(&ctx.device),
        }
    }

    /// Records and submits one frame of `cloud` seen by `camera` into `target`.
    pub fn render(
        &mut self,
        ctx: &GpuContext,
        cloud: &mut GpuCloud,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<(), GpuError> {
        let variant = settings.variant;
        if let Some(why) = variant.unsupported_reason(&ctx.caps) {
            return Err(GpuError::Unsupported {
                what: variant.name().to_string(),
                why: why.to_string(),
                adapter: ctx.describe(),
            });
        }
        camera
            .validate()
            .map_err(|e| GpuError::InvalidInput(e.to_string()))?;
        cloud.prepare(ctx, camera, target.width, target.height);
        self.screen.prepare(&ctx.queue, target, &settings.screen);
        let device = &ctx.device;
        let key = (cloud.encoding, cloud.page_size);
        // Pipelines are built on first use, inside an error scope: a shader the driver rejects
        // is an error, not a panic.
        if variant == RasterVariant::HwPoints {
            if let std::collections::hash_map::Entry::Vacant(slot) = self.hw.entry(key) {
                slot.insert(ctx.checked("building the hw-points pipeline", || {
                    HwPointsPipeline::new(device, key.0, key.1)
                })?);
            }
        } else if let std::collections::hash_map::Entry::Vacant(slot) =
            self.raster.entry((variant, key.0, key.1))
        {
            slot.insert(ctx.checked(
                &format!("building the {} pipelines", variant.name()),
                || RasterPipelines::new(device, variant, key.0, key.1),
            )?);
        }
        let mut enc = device.create_command_encoder(&Default::default());
        let kind = variant.buffers();
        let timer = target.timer.as_ref();
        let stamps = |begin: u32| {
            timer.map(|t| wgpu::ComputePassTimestampWrites {
                query_set: &t.queries,
                beginning_of_pass_write_index: Some(begin),
                end_of_pass_write_index: Some(begin + 1),
            })
        };
        if variant == RasterVariant::HwPoints {
            if let Some(hw) = self.hw.get(&key) {
                let writes = timer.map(|t| wgpu::RenderPassTimestampWrites {
                    query_set: &t.queries,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                });
                hw.record(&mut enc, cloud, target, writes);
            }
        } else if let Some(pipes) = self.raster.get(&(variant, key.0, key.1)) {
            let buffers = kind.buffers(target);
            for b in &buffers {
                enc.clear_buffer(b, 0, None);
            }
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(variant.name()),
                timestamp_writes: stamps(0),
            });
            pipes.record(device, &mut pass, cloud, &buffers);
        }
        let screen = &mut self.screen;
        ctx.checked("rendering a frame", || {
            screen.record(device, &mut enc, target, kind, &settings.screen, stamps(2));
            if let Some(t) = timer {
                t.resolve(&mut enc);
            }
            ctx.queue.submit([enc.finish()]);
        })?;
        Ok(())
    }

    /// GPU timings of the last frame rendered into `target` (waits for it); `None` without
    /// timestamp queries.
    pub fn timing(
        &self,
        ctx: &GpuContext,
        target: &RenderTarget,
    ) -> Result<Option<FrameTiming>, GpuError> {
        let Some(t) = &target.timer else {
            return Ok(None);
        };
        let (raster_ms, screen_ms) = t.read(ctx)?;
        Ok(Some(FrameTiming {
            raster_ms,
            screen_ms,
        }))
    }
}
