//! The viewer's state and frame logic without a window: GPU objects, content, camera
//! controller, render settings, colouring and tools. The window (app.rs) feeds it input and
//! presents its image; tests drive it headless.

use crate::colors::ColorState;
use crate::content::{Content, Drawn};
use crate::navigation::Navigator;
use crate::stats::FrameStats;
use crate::tools::{Bookmarks, Measure, PathRecorder};
use crate::ViewerError;
use pointlet_core::color::ColorScale;
use pointlet_core::Camera;
use pointlet_gpu::{GpuContext, RenderSettings, RenderTarget, Renderer};
use std::path::PathBuf;

/// Seconds between two keyframes of a recorded camera path.
const RECORD_INTERVAL: f64 = 0.1;

pub struct View {
    pub ctx: GpuContext,
    pub renderer: Renderer,
    pub target: RenderTarget,
    pub content: Content,
    pub nav: Navigator,
    pub settings: RenderSettings,
    pub colors: ColorState,
    pub measure: Measure,
    pub bookmarks: Bookmarks,
    pub recorder: PathRecorder,
    pub stats: FrameStats,
    /// What the last frame drew.
    pub drawn: Drawn,
    /// Several inputs drawn together: each with whether it is shown (empty for one input).
    pub datasets: Vec<(PathBuf, bool)>,
    /// How in-memory content of several inputs is read again when one is hidden or shown.
    pub reread: Option<Reread>,
    /// Camera and settings of the last frame: an unchanged view of in-memory data needs no
    /// new frame.
    last_view: Option<(Camera, RenderSettings, (u32, u32))>,
}

/// What reading in-memory content again takes.
#[derive(Clone, Debug)]
pub struct Reread {
    pub read: pointlet_io::ReadOptions,
    pub order: pointlet_core::order::VertexOrder,
    pub encoding: pointlet_gpu::PointEncoding,
    pub page_size: u32,
}

impl View {
    /// `scale` is the colouring `content` was uploaded with.
    pub fn new(
        ctx: GpuContext,
        content: Content,
        camera: Camera,
        settings: RenderSettings,
        scale: ColorScale,
        size: (u32, u32),
    ) -> Result<Self, ViewerError> {
        let target =
            RenderTarget::new(&ctx, size.0, size.1).map_err(|e| ViewerError::Gpu(e.to_string()))?;
        let renderer = Renderer::new(&ctx);
        let nav = Navigator::new(camera, content.bounds());
        let colors = content.color_state(scale);
        let datasets = match &content {
            Content::Progressive(p) if p.inputs().len() > 1 => {
                p.inputs().iter().map(|i| (i.clone(), true)).collect()
            }
            _ => Vec::new(),
        };
        Ok(Self {
            datasets,
            reread: None,
            ctx,
            renderer,
            target,
            nav,
            settings,
            colors,
            content,
            measure: Measure::default(),
            bookmarks: Bookmarks::default(),
            recorder: PathRecorder::new(RECORD_INTERVAL),
            stats: FrameStats::default(),
            drawn: Drawn::default(),
            last_view: None,
        })
    }

    pub fn size(&self) -> (u32, u32) {
        (self.target.width, self.target.height)
    }

    /// Follows the window's size (a new render target; nothing happens for the same size).
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), ViewerError> {
        if (width, height) == self.size() || width == 0 || height == 0 {
            return Ok(());
        }
        self.target = RenderTarget::new(&self.ctx, width, height)
            .map_err(|e| ViewerError::Gpu(e.to_string()))?;
        self.last_view = None;
        Ok(())
    }

    /// True when a new frame would differ from the last one: the view changed, colours are
    /// pending, keys are held, or a store is still loading/accumulating.
    pub fn needs_frame(&self) -> bool {
        let view = (self.nav.camera, self.settings, self.size());
        self.last_view != Some(view)
            || self.colors.pending().is_some()
            || self.nav.moving()
            || !self.drawn.converged
    }

    /// Advances key movement, uploads pending colours and draws one frame at clock `now`.
    pub fn frame(&mut self, now: f64, dt: f64) -> Result<&Drawn, ViewerError> {
        self.nav.update(dt);
        if let Some(scale) = self.colors.pending() {
            self.content.apply_color(&self.ctx, &scale)?;
            self.colors.mark_applied(scale);
        }
        if self.recorder.recording() {
            self.recorder.sample(now, &self.nav.camera);
        }
        let camera = self.nav.camera;
        self.drawn = self.content.frame(
            &self.ctx,
            &mut self.renderer,
            &camera,
            &self.settings,
            &mut self.target,
        )?;
        self.last_view = Some((camera, self.settings, self.size()));
        // A loading file fits a new mode's scale on its own sample: the UI shows that one.
        if let crate::content::Content::Progressive(p) = &self.content {
            let loaded = p.color().map(|c| c.scale);
            let fitted_there = p.asked_scale().is_none();
            if let Some(scale) = loaded.filter(|s| {
                fitted_there && s.mode == self.colors.mode() && Some(*s) != self.colors.applied()
            }) {
                self.colors.adopt(scale);
            }
        }
        self.stats.frame(now);
        if let Some((_, t)) = self.drawn.progressive.as_ref().and_then(|r| r.timing) {
            // The progressive scene reads its own timestamps (its fill budget needs them).
            self.stats.gpu = Some(pointlet_gpu::FrameTiming {
                lod_ms: t.reproject_ms,
                raster_ms: t.fill_ms,
                screen_ms: t.screen_ms,
                upload_ms: 0.0,
            });
        } else if self.drawn.progressive.is_none() && self.stats.timing_due(now) {
            // Waits for this frame's GPU work, a few times a second only.
            self.stats.gpu = self
                .renderer
                .timing(&self.ctx, &mut self.target)
                .map_err(|e| ViewerError::Gpu(e.to_string()))?;
        }
        Ok(&self.drawn)
    }

    /// Shows or hides input `i` of several: the shown ones load again from the start (the
    /// camera stays). The last shown input cannot be hidden.
    pub fn set_visible(&mut self, i: usize, visible: bool) -> Result<(), ViewerError> {
        let Some(was) = self.datasets.get(i).map(|d| d.1) else {
            return Ok(());
        };
        if was == visible {
            return Ok(());
        }
        self.datasets[i].1 = visible;
        let shown: Vec<PathBuf> = self
            .datasets
            .iter()
            .filter(|d| d.1)
            .map(|d| d.0.clone())
            .collect();
        if shown.is_empty() {
            self.datasets[i].1 = true;
            return Err(ViewerError::Config(
                "one input at least stays shown".to_string(),
            ));
        }
        match (&mut self.content, &self.reread) {
            (Content::Progressive(p), _) => {
                p.reopen(&self.ctx, &shown)
                    .map_err(|e| ViewerError::Load(e.to_string()))?;
            }
            (Content::Memory(_), Some(r)) => {
                let source = crate::memory::Source::Files {
                    paths: &shown,
                    read: &r.read,
                };
                let data = crate::memory::MemoryData::load(source, r.order)?;
                let scale = data.fitted(self.colors.mode());
                self.content = Content::upload(&self.ctx, data, &scale, r.encoding, r.page_size)?;
                self.colors = self.content.color_state(scale);
            }
            _ => {}
        }
        self.last_view = None;
        Ok(())
    }

    /// Lists `paths` with a visibility toggle each, for in-memory content read from them with
    /// `reread`'s settings.
    pub fn list_inputs(&mut self, paths: &[PathBuf], reread: Reread) {
        if paths.len() > 1 && matches!(self.content, Content::Memory(_)) {
            self.datasets = paths.iter().map(|p| (p.clone(), true)).collect();
            self.reread = Some(reread);
        }
    }

    /// The exact coordinates of the point under `pixel` (None: nothing there).
    pub fn pick(&mut self, pixel: [u32; 2]) -> Result<Option<[f64; 3]>, ViewerError> {
        let camera = self.nav.camera;
        let hit = self.content.pick(
            &self.ctx,
            &mut self.renderer,
            &camera,
            &self.settings,
            &mut self.target,
            pixel,
        )?;
        // The pick pass reused the frame's pixel buffers: draw afresh next time.
        self.last_view = None;
        Ok(hit)
    }

    /// The last frame's image, RGBA8 rows top to bottom (what `pointlet render` writes).
    pub fn image(&self) -> Result<Vec<u8>, ViewerError> {
        self.target
            .read_rgba(&self.ctx)
            .map_err(|e| ViewerError::Gpu(format!("reading the image back: {e}")))
    }
}
