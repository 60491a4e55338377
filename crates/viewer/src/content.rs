//! What is on screen: in-memory points in a static `GpuCloud`, a store drawn through the
//! virtualized `VirtualScene`, or a point file drawn while it loads (`ProgressiveScene`). One
//! interface for drawing, picking and recolouring each.

use crate::colors::{available_modes, available_with_extras, legend, ColorState, LegendEntry};
use crate::memory::MemoryData;
use crate::ViewerError;
use pointlet_core::color::ColorScale;
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::{Aabb, Camera};
use pointlet_engine::{FrameReport, ProgressiveReport, ProgressiveScene, VirtualScene};
use pointlet_gpu::{
    GpuCloud, GpuContext, PointEncoding, RasterVariant, RenderSettings, RenderTarget, Renderer,
};

/// Pixels around the cursor searched for a point when picking.
pub const PICK_RADIUS: u32 = 6;

pub enum Content {
    Memory(Box<InMemory>),
    Store(Box<VirtualScene>),
    Progressive(Box<ProgressiveScene>),
}

/// Points held in RAM with their attribute columns, and their GPU copy.
pub struct InMemory {
    pub data: MemoryData,
    pub cloud: GpuCloud,
}

/// What a frame drew.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Drawn {
    pub points: u64,
    /// The image is final for this view (stores: accumulated to full detail).
    pub converged: bool,
    /// The virtualized scene's account of the frame (stores only).
    pub report: Option<FrameReport>,
    /// The progressive scene's account of the frame (point files loading while drawn).
    pub progressive: Option<ProgressiveReport>,
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
        Ok(Content::Memory(Box::new(InMemory { data, cloud })))
    }

    pub fn name(&self) -> String {
        match self {
            Content::Memory(m) => m.data.name.clone(),
            Content::Store(s) => s.store().path().display().to_string(),
            Content::Progressive(p) => p.path().display().to_string(),
        }
    }

    pub fn bounds(&self) -> Aabb {
        match self {
            Content::Memory(m) => m.data.bounds,
            Content::Store(s) => s.bounds(),
            Content::Progressive(p) => p.bounds(),
        }
    }

    pub fn points(&self) -> u64 {
        match self {
            Content::Memory(m) => m.data.len() as u64,
            Content::Store(s) => s.points(),
            Content::Progressive(p) => p.points(),
        }
    }

    /// GPU bytes of point data and tables (the render target not included).
    pub fn gpu_bytes(&self) -> u64 {
        match self {
            Content::Memory(m) => m.cloud.point_bytes(),
            Content::Store(s) => s.gpu_bytes(),
            Content::Progressive(p) => p.gpu_bytes(),
        }
    }

    /// Whether `variant` can draw this content (the point-list baseline draws static clouds).
    pub fn supports(&self, variant: RasterVariant) -> bool {
        match self {
            Content::Memory(_) => true,
            Content::Store(_) => variant != RasterVariant::HwPoints,
            Content::Progressive(_) => variant.accumulates(),
        }
    }

    /// The colouring state to start from: `scale` is already on the GPU. Stores and loading
    /// point files colour by their extra-bytes attributes too (in-memory data keeps no
    /// extra bytes).
    pub fn color_state(&self, scale: ColorScale) -> ColorState {
        let (layout, extras) = match self {
            Content::Memory(m) => return ColorState::new(available_modes(&m.data.layout), scale),
            Content::Store(s) => {
                let h = s.store().header();
                let extras = ExtraAttributes::from_vlrs(&h.vlrs, usize::from(h.layout.extra_bytes));
                (h.layout, extras)
            }
            Content::Progressive(p) => (p.layout(), p.extras().clone()),
        };
        let names: Vec<String> = extras.attributes.iter().map(|a| a.name.clone()).collect();
        let mut state = ColorState::new(available_with_extras(&layout, &names), scale);
        state.extra_names = names;
        state
    }

    /// The data-fitted scale of `mode`.
    pub fn fitted(&self, mode: pointlet_core::color::ColorMode) -> Result<ColorScale, ViewerError> {
        match self {
            Content::Memory(m) => Ok(m.data.fitted(mode)),
            Content::Store(s) => pointlet_engine::fit_scale(s.store(), mode)
                .map_err(|e| ViewerError::Load(e.to_string())),
            // The load thread fits the scale on the file itself: only the mode counts.
            Content::Progressive(p) => Ok(match p.color() {
                Some(c) if c.scale.mode == mode => c.scale,
                _ => {
                    let b = p.bounds();
                    ColorScale::fit(mode, &[], [b.min[2], b.max[2]])
                }
            }),
        }
    }

    pub fn legend(&self) -> Vec<LegendEntry> {
        match self {
            Content::Memory(m) => legend(Some(&m.data.class_counts)),
            Content::Store(_) | Content::Progressive(_) => legend(None),
        }
    }

    /// Puts `scale`'s colours on the GPU: in memory, every colour is recomputed and only the
    /// colour stream uploaded; a store reloads colours through its cache as they are needed
    /// (only the mode can change there: the engine fits ranges itself).
    pub fn apply_color(&mut self, ctx: &GpuContext, scale: &ColorScale) -> Result<(), ViewerError> {
        match self {
            Content::Memory(m) => m
                .cloud
                .recolor(ctx, &m.data.colors(scale))
                .map_err(|e| ViewerError::Gpu(format!("recolouring: {e}"))),
            Content::Store(s) => s
                .set_color_scale(*scale)
                .map_err(|e| ViewerError::Gpu(e.to_string())),
            // The file is read again for the colours alone (loaded points keep their
            // positions): another mode is fitted on the file's sample, an edited scale is
            // taken as it is.
            Content::Progressive(p) => {
                let result = if p.color().is_some_and(|c| c.scale == *scale) {
                    Ok(())
                } else if p.asked_mode() == Some(scale.mode) {
                    p.recolor_with(*scale)
                } else {
                    p.recolor(scale.mode)
                };
                result.map_err(|e| ViewerError::Load(format!("recolouring: {e}")))
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
            Content::Memory(m) => {
                renderer
                    .render(ctx, &mut m.cloud, camera, settings, target)
                    .map_err(|e| ViewerError::Gpu(e.to_string()))?;
                Ok(Drawn {
                    points: m.cloud.points,
                    converged: true,
                    report: None,
                    progressive: None,
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
                    progressive: None,
                })
            }
            Content::Progressive(p) => {
                let report = p
                    .frame(ctx, camera, settings, target)
                    .map_err(|e| ViewerError::Gpu(e.to_string()))?;
                if let Some(f) = &report.failure {
                    // The points read before the damage stay on screen.
                    eprintln!("error: {f}");
                }
                Ok(Drawn {
                    points: report.progress.shown(),
                    converged: report.converged,
                    report: None,
                    progressive: Some(report),
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
            Content::Memory(m) => {
                let hit = renderer
                    .pick(
                        ctx,
                        &mut m.cloud,
                        camera,
                        settings,
                        target,
                        pixel,
                        PICK_RADIUS,
                    )
                    .map_err(gpu)?;
                Ok(hit.and_then(|h| m.data.position(h.id)))
            }
            Content::Store(s) => {
                let hit = s
                    .pick(ctx, renderer, camera, settings, target, pixel, PICK_RADIUS)
                    .map_err(|e| ViewerError::Gpu(format!("picking: {e}")))?;
                Ok(hit.map(|p| p.position))
            }
            // The last frame's index framebuffer names the point under the cursor.
            Content::Progressive(p) => p
                .pick(ctx, pixel, PICK_RADIUS)
                .map_err(|e| ViewerError::Gpu(format!("picking: {e}"))),
        }
    }
}
