//! What is on screen: in-memory points in a static `GpuCloud`, a store drawn through the
//! virtualized `VirtualScene`, a point file drawn while it loads (`ProgressiveScene`), or a
//! 3D Tiles tileset streamed by screen-space error (`TilesetScene`). One interface for drawing,
//! picking and recolouring each.

use crate::colors::{available_modes, available_with_extras, legend, ColorState, LegendEntry};
use crate::memory::MemoryData;
use crate::ViewerError;
use pointlet_core::color::{ColorMode, ColorScale};
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::{Aabb, Camera};
use pointlet_engine::{
    FrameReport, ProgressiveReport, ProgressiveScene, TilesetFrameReport, TilesetScene,
    VirtualScene,
};
use pointlet_gpu::{
    GpuCloud, GpuContext, PointEncoding, RasterVariant, RenderSettings, RenderTarget, Renderer,
};

/// Pixels around the cursor searched for a point when picking.
pub const PICK_RADIUS: u32 = 6;

/// The colourings a tileset offers: its tiles carry colours (where they have them), positions,
/// and intensity and classification columns (0 where they lack them), nothing else of LAS's.
const TILE_MODES: [ColorMode; 4] = [
    ColorMode::Rgb,
    ColorMode::Elevation,
    ColorMode::Intensity,
    ColorMode::Classification,
];

pub enum Content {
    Memory(Box<InMemory>),
    Store(Box<VirtualScene>),
    Progressive(Box<ProgressiveScene>),
    Tiles(Box<TilesetScene>),
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
    /// The tileset scene's account of the frame (tiles drawn, wanted, requested).
    pub tiles: Option<TilesetFrameReport>,
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
            Content::Tiles(t) => t.name().to_string(),
        }
    }

    pub fn bounds(&self) -> Aabb {
        match self {
            Content::Memory(m) => m.data.bounds,
            Content::Store(s) => s.bounds(),
            Content::Progressive(p) => p.bounds(),
            // The root tile's volume: tiles not fetched yet are inside it.
            Content::Tiles(t) => t.bounds(),
        }
    }

    /// Points of the data (a tileset: of the tiles uploaded so far, its total being unknown
    /// until every tile is read).
    pub fn points(&self) -> u64 {
        match self {
            Content::Memory(m) => m.data.len() as u64,
            Content::Store(s) => s.points(),
            Content::Progressive(p) => p.points(),
            Content::Tiles(t) => t.points_seen(),
        }
    }

    /// GPU bytes of point data and tables (the render target not included).
    pub fn gpu_bytes(&self) -> u64 {
        match self {
            Content::Memory(m) => m.cloud.point_bytes(),
            Content::Store(s) => s.gpu_bytes(),
            Content::Progressive(p) => p.gpu_bytes(),
            Content::Tiles(t) => t.gpu_bytes(),
        }
    }

    /// Whether `variant` can draw this content (the point-list baseline draws static clouds).
    pub fn supports(&self, variant: RasterVariant) -> bool {
        match self {
            Content::Memory(_) => true,
            Content::Store(_) | Content::Tiles(_) => variant != RasterVariant::HwPoints,
            Content::Progressive(_) => variant.accumulates(),
        }
    }

    /// The colouring state to start from: `scale` is already on the GPU. Stores and loading
    /// point files colour by their extra-bytes attributes too (in-memory data keeps no
    /// extra bytes).
    pub fn color_state(&self, scale: ColorScale) -> ColorState {
        let (layout, extras) = match self {
            Content::Memory(m) => return ColorState::new(available_modes(&m.data.layout), scale),
            Content::Tiles(t) => {
                let modes = available_modes(&t.layout())
                    .into_iter()
                    .filter(|m| TILE_MODES.contains(m))
                    .collect();
                return ColorState::new(modes, scale);
            }
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
            // Fitted as the scene fits its own colouring (its first tile with points).
            Content::Tiles(t) => t.fitted(mode).map_err(|e| ViewerError::Load(e.to_string())),
        }
    }

    pub fn legend(&self) -> Vec<LegendEntry> {
        match self {
            Content::Memory(m) => legend(Some(&m.data.class_counts)),
            Content::Store(_) | Content::Progressive(_) | Content::Tiles(_) => legend(None),
        }
    }

    /// Puts `scale`'s colours on the GPU: in memory, every colour is recomputed and only the
    /// colour stream uploaded; a store reloads colours through its cache as they are needed
    /// (only the mode can change there: the engine fits ranges itself); a tileset fetches and
    /// uploads its tiles again, coloured by `scale`.
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
            Content::Tiles(t) => t
                .set_color_scale(*scale)
                .map_err(|e| ViewerError::Load(format!("recolouring: {e}"))),
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
                    ..Default::default()
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
                    ..Default::default()
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
                    progressive: Some(report),
                    ..Default::default()
                })
            }
            Content::Tiles(t) => {
                let report = t
                    .frame(ctx, renderer, camera, settings, target)
                    .map_err(|e| ViewerError::Gpu(e.to_string()))?;
                // A viewer keeps drawing what it has: tiles that could not be read are said once
                // each and left out, as `bench` leaves them out.
                for n in t.take_notes() {
                    eprintln!("note: {n}");
                }
                for e in t.take_errors() {
                    eprintln!("error: {e}");
                }
                Ok(Drawn {
                    points: report.tested_points,
                    converged: report.converged,
                    tiles: Some(report),
                    ..Default::default()
                })
            }
        }
    }

    /// The exact coordinates of the point nearest to `pixel` on screen, if any is near. Tiles
    /// give the surface position under the cursor from the depth buffer of a frame drawn for
    /// `camera`, not a stored point's exact coordinates (their points are not kept on the CPU).
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
            Content::Tiles(t) => {
                // Blending frames leave the resolved depth unwritten: a closest-point frame of
                // the same view writes it.
                let closest = if settings.variant.closest_point() {
                    *settings
                } else {
                    RenderSettings {
                        variant: RasterVariant::ReduceEarlyZ.fallback(&ctx.caps),
                        ..*settings
                    }
                };
                t.frame(ctx, renderer, camera, &closest, target)
                    .map_err(|e| ViewerError::Gpu(format!("picking: {e}")))?;
                let depth = target.read_depth(ctx).map_err(gpu)?;
                let size = (target.width, target.height);
                Ok(nearest_depth(&depth, size, pixel, PICK_RADIUS)
                    .map(|(at, d)| unproject(camera, size, at, d)))
            }
        }
    }
}

/// The covered pixel of a depth image (`size`, rows top to bottom, 0 = empty) nearest to
/// `pixel` within `radius`, the closer in depth on equal distance, with its depth.
fn nearest_depth(
    depth: &[f32],
    (width, height): (u32, u32),
    pixel: [u32; 2],
    radius: u32,
) -> Option<([u32; 2], f32)> {
    if pixel[0] >= width || pixel[1] >= height {
        return None;
    }
    let mut best: Option<(u64, f32, [u32; 2])> = None;
    for y in pixel[1].saturating_sub(radius)..=(pixel[1] + radius).min(height - 1) {
        for x in pixel[0].saturating_sub(radius)..=(pixel[0] + radius).min(width - 1) {
            let dist = (x.abs_diff(pixel[0]) as u64).pow(2) + (y.abs_diff(pixel[1]) as u64).pow(2);
            if dist > (radius as u64).pow(2) {
                continue;
            }
            let d = depth
                .get(y as usize * width as usize + x as usize)
                .copied()
                .unwrap_or(0.0);
            if !(d > 0.0 && d.is_finite()) {
                continue;
            }
            if best.is_none_or(|(bd, bdepth, _)| (dist, d) < (bd, bdepth)) {
                best = Some((dist, d, [x, y]));
            }
        }
    }
    best.map(|(_, d, at)| (at, d))
}

/// The world position seen through the centre of pixel `at` at view depth `depth`.
fn unproject(camera: &Camera, (width, height): (u32, u32), at: [u32; 2], depth: f32) -> [f64; 3] {
    let [right, up, back] = camera.basis();
    let focal = camera.focal_px(height);
    let depth = f64::from(depth);
    // Lateral offsets in view space: pixels from the image centre, scaled by depth / focal.
    let x = (at[0] as f64 + 0.5 - 0.5 * width as f64) * depth / focal;
    let y = (0.5 * height as f64 - (at[1] as f64 + 0.5)) * depth / focal;
    std::array::from_fn(|a| camera.eye[a] + right[a] * x + up[a] * y - back[a] * depth)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_and_its_depth_unproject_to_the_point_seen_there() {
        let camera = Camera {
            eye: [637_010.0, 851_020.0, 180.0],
            target: [637_100.0, 851_090.0, 120.0],
            up: [0.0, 0.0, 1.0],
            fov_y_deg: 55.0,
            near: 0.1,
            far: 1000.0,
        };
        let size = (320, 240);
        for p in [
            [637_100.0, 851_090.0, 120.0],
            [637_080.5, 851_101.25, 126.0],
        ] {
            let (k, depth) =
                pointlet_gpu::reference::project(&camera, size.0, size.1, p).expect("in view");
            let at = [k as u32 % size.0, k as u32 / size.0];
            let q = unproject(&camera, size, at, depth);
            // Within half a pixel's diagonal of the point, at its depth.
            let pixel = f64::from(depth) / camera.focal_px(size.1);
            let off = (0..3).map(|a| (q[a] - p[a]).powi(2)).sum::<f64>().sqrt();
            assert!(off <= 0.75 * pixel, "{q:?} is {off} from {p:?}");
        }
    }

    #[test]
    fn the_nearest_covered_pixel_wins_then_the_closer_depth() {
        let (w, h) = (8, 6);
        let mut depth = vec![0.0f32; (w * h) as usize];
        let at = |x: u32, y: u32| (y * w + x) as usize;
        // Beyond the radius, however close in depth.
        depth[at(0, 2)] = 1.0;
        // At the same distance: the closer in depth.
        depth[at(5, 2)] = 9.0;
        depth[at(3, 4)] = 7.0;
        assert_eq!(
            nearest_depth(&depth, (w, h), [3, 2], 2),
            Some(([3, 4], 7.0))
        );
        depth[at(4, 3)] = 8.0;
        assert_eq!(
            nearest_depth(&depth, (w, h), [3, 2], 2),
            Some(([4, 3], 8.0))
        );
        assert_eq!(
            nearest_depth(&depth, (w, h), [7, 5], 1),
            None,
            "nothing near"
        );
        assert_eq!(
            nearest_depth(&depth, (w, h), [8, 0], 3),
            None,
            "outside the image"
        );
    }
}
