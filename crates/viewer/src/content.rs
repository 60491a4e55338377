//! What is on screen: in-memory points in a static `GpuCloud`, or a store drawn through the
//! virtualized `VirtualScene`. One interface for drawing, picking and recolouring either.

use crate::colors::{available_modes, legend, ColorState, LegendEntry};
use crate::memory::MemoryData;
use crate::ViewerError;
use pointlet_core::color::ColorScale;
use pointlet_core::{Aabb, Camera};
use pointlet_engine::{FrameReport, VirtualScene};
use pointlet_gpu::{
    GpuCloud, GpuContext, PointEncoding, RasterVariant, RenderSettings, RenderTarget, Renderer,
};

/// Pixels around the cursor searched for a point when picking.
pub const PICK_RADIUS: u32 = 6;

pub enum Content {
    Memory { data: MemoryData, cloud: GpuCloud },
    Store(Box<VirtualScene>),
}

/// What a frame drew.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Drawn {
    pub points: u64,
    /// The image is final for this view (stores: accumulated to full detail).
    pub converged: bool,
    /// The virtualized scene's account of the frame (stores only).
    pub report: Option<FrameReport>,
}

impl Content {
    /// Uploads in-memory data coloured by `scale`.
    pub fn upload(
        ctx: &GpuContext,
        data: MemoryData,
        scale: &ColorScale,
        encoding: PointEncoding,
        page_size: u32,
    ) -> Result<Self, ViewerError> {
        let set = data.point_set(scale);
        let cloud = GpuCloud::upload(ctx, &set, encoding, page_size)
            .map_err(|e| ViewerError::Gpu(format!("uploading {}: {e}", data.name)))?;
        Ok(Content::Memory { data, cloud })
    }

    pub fn name(&self) -> String {
        match self {
            Content::Memory { data, .. } => data.name.clone(),
            Content::Store(s) => s.store().path().display().to_string(),
        }
    }

    pub fn bounds(&self) -> Aabb {
        match self {
            Content::Memory { data, .. } => data.bounds,
            Content::Store(s) => s.bounds(),
        }
    }

    pub fn points(&self) -> u64 {
        match self {
            Content::Memory { data, .. } => data.len() as u64,
            Content::Store(s) => s.points(),
        }
    }

    /// GPU bytes of point data and tables (the render target not included).
    pub fn gpu_bytes(&self) -> u64 {
        match self {
            Content::Memory { cloud, .. } => cloud.point_bytes(),
            Content::Store(s) => s.gpu_bytes(),
        }
    }

    /// Whether `variant` can draw this content (the point-list baseline draws static clouds).
    pub fn supports(&self, variant: RasterVariant) -> bool {
        !(matches!(self, Content::Store(_)) && variant == RasterVariant::HwPoints)
    }

    /// The colouring state to start from: `scale` is already on the GPU.
    pub fn color_state(&self, scale: ColorScale) -> ColorState {
        match self {
            Content::Memory { data, .. } => {
                ColorState::new(available_modes(&data.layout), scale, true)
            }
            Content::Store(s) => {
                ColorState::new(available_modes(&s.store().header().layout), scale, false)
            }
        }
    }

    /// The data-fitted scale of `mode`.
    pub fn fitted(&self, mode: pointlet_core::color::ColorMode) -> Result<ColorScale, ViewerError> {
        match self {
            Content::Memory { data, .. } => Ok(data.fitted(mode)),
            Content::Store(s) => pointlet_engine::fit_scale(s.store(), mode)
                .map_err(|e| ViewerError::Load(e.to_string())),
        }
    }

    pub fn legend(&self) -> Vec<LegendEntry> {
        match self {
            Content::Memory { data, .. } => legend(Some(&data.class_counts)),
            Content::Store(_) => legend(None),
        }
    }

    /// Puts `scale`'s colours on the GPU: in memory, every colour is recomputed and only the
    /// colour stream uploaded; a store reloads colours through its cache as they are needed
    /// (only the mode can change there: the engine fits ranges itself).
    pub fn apply_color(&mut self, ctx: &GpuContext, scale: &ColorScale) -> Result<(), ViewerError> {
        match self {
            Content::Memory { data, cloud } => cloud
                .recolor(ctx, &data.colors(scale))
                .map_err(|e| ViewerError::Gpu(format!("recolouring: {e}"))),
            Content::Store(s) => {
                if s.color_mode() == scale.mode {
                    return Ok(());
                }
                s.set_color(scale.mode)
                    .map_err(|e| ViewerError::Gpu(e.to_string()))
            }
        }
    }

    pub fn frame(
        &mut self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<Drawn, ViewerError> {
        match self {
            Content::Memory { cloud, .. } => {
                renderer
                    .render(ctx, cloud, camera, settings, target)
                    .map_err(|e| ViewerError::Gpu(e.to_string()))?;
                Ok(Drawn {
                    points: cloud.points,
                    converged: true,
                    report: None,
                })
            }
            Content::Store(s) => {
                let report = s
                    .frame(ctx, renderer, camera, settings, target)
                    .map_err(|e| ViewerError::Gpu(e.to_string()))?;
                Ok(Drawn {
                    points: report.drawn_points,
                    converged: report.converged,
                    report: Some(report),
                })
            }
        }
    }

    /// The exact coordinates of the point nearest to `pixel` on screen, if any is near.
    pub fn pick(
        &mut self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
        pixel: [u32; 2],
    ) -> Result<Option<[f64; 3]>, ViewerError> {
        let gpu = |e: pointlet_gpu::GpuError| ViewerError::Gpu(format!("picking: {e}"));
        match self {
            Content::Memory { data, cloud } => {
                let hit = renderer
                    .pick(ctx, cloud, camera, settings, target, pixel, PICK_RADIUS)
                    .map_err(gpu)?;
                Ok(hit.and_then(|h| data.position(h.id)))
            }
            Content::Store(s) => {
                let hit = s
                    .pick(ctx, renderer, camera, settings, target, pixel, PICK_RADIUS)
                    .map_err(|e| ViewerError::Gpu(format!("picking: {e}")))?;
                Ok(hit.map(|p| p.position))
            }
        }
    }
}
