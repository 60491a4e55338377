//! A streamed 3D Tiles tileset on the render thread (WebGPU-engine paper §4–6): each frame the
//! screen-space-error plan of the view (`pointlet_tiles::select`) says which tiles to draw and
//! which to fetch, `TileStream` fetches and decodes on its workers within the RAM budget, the
//! decoded tiles the plan wants go to the GPU's [`TilePool`] (its suballocator) within the VRAM
//! budget, least recently drawn first out, and the pool's continuous-LoD filter and the
//! rasterizers draw the plan.

use crate::EngineError;
use pointlet_core::camera::LocalFrame;
use pointlet_core::color::{default_color, point_color, ColorMode, ColorScale, DefaultColor};
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::size::format_bytes;
use pointlet_core::{Aabb, Camera, PointBatch, PointLayout};
use pointlet_gpu::box_spacing;
use pointlet_gpu::tile_pool::encode_tile;
use pointlet_gpu::{
    GpuContext, RenderSettings, RenderTarget, Renderer, TileDraw, TilePool, CONTENT_PAGE_BYTES,
};
use pointlet_tiles::points::append_points;
use pointlet_tiles::{
    plan, LocalSource, TileData, TilePlan, TilePoints, TileSource, TileStream, TileStreamConfig,
    TileStreamStats, TileView, Tileset,
};
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;

#[derive(Clone, Debug, PartialEq)]
pub struct TilesetConfig {
    /// Tiles are refined while their screen-space error exceeds this (pixels).
    pub max_sse: f64,
    /// Continuous LoD across tiles (paper eq. 6–9); off: every point of a drawn tile.
    pub clod: bool,
    /// GPU memory for tile content and the frame's output points.
    pub vram_budget: u64,
    /// RAM for decoded tiles.
    pub ram_budget: u64,
    /// Tiles fetched at once.
    pub workers: usize,
    /// Points per output page.
    pub page_size: u32,
    /// Tile content moved to the GPU per frame at most (bytes; keeps frames steady).
    pub upload_per_frame: u64,
    /// `None`: the data's default (RGB when the tiles have colours, else elevation).
    pub color: Option<ColorMode>,
}

impl Default for TilesetConfig {
    fn default() -> Self {
        Self {
            max_sse: 16.0,
            clod: true,
            vram_budget: 2 << 30,
            ram_budget: 1 << 30,
            workers: 8,
            page_size: 256,
            upload_per_frame: 32 << 20,
            color: None,
        }
    }
}

/// What one frame drew and streamed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TilesetFrameReport {
    pub frame: u64,
    /// Tiles drawn and the points the filter tested in them.
    pub drawn_tiles: u32,
    pub tested_points: u64,
    /// Tiles the settled view of this camera draws, and how many of them this frame drew.
    pub wanted_tiles: u32,
    pub wanted_drawn: u32,
    /// Tiles the view asked for and did not have.
    pub requested_tiles: u32,
    pub uploaded_tiles: u32,
    pub uploaded_bytes: u64,
    pub evicted_tiles: u32,
    /// Drawn tiles left out for lack of output room.
    pub skipped_tiles: u32,
    /// Nothing requested and everything planned drawn: the image of this camera is final.
    pub converged: bool,
    pub stream: TileStreamStats,
    /// GPU bytes of tile content and tables.
    pub gpu_bytes: u64,
}

struct Resident {
    last_drawn: u64,
    spacing: f32,
}

/// A tile as the fetch workers leave it: GPU words ready to copy.
struct EncodedTile {
    origin: [f64; 3],
    /// f32 xyz relative to `origin`, as bits ([`pointlet_gpu::tile_pool::encode_tile`]).
    positions: Vec<u32>,
    colors: Vec<u32>,
    spacing: f32,
}

impl TileData for EncodedTile {
    fn bytes(&self) -> u64 {
        (self.positions.len() + self.colors.len()) as u64 * 4
    }
}

/// World positions and RGBA8 colours of a tile's contents, coloured by `scale`.
fn encode(contents: &[TilePoints], rgb: bool, scale: &ColorScale) -> EncodedTile {
    let mut batch = PointBatch {
        layout: PointLayout {
            rgb,
            ..PointLayout::default()
        },
        ..PointBatch::default()
    };
    for c in contents {
        append_points(c, 0..c.len(), rgb, &mut batch);
    }
    let colors = (0..batch.len())
        .map(|i| point_color(&batch, i, scale))
        .collect();
    let origin = batch.xyz.first().copied().unwrap_or([0.0; 3]);
    EncodedTile {
        origin,
        positions: encode_tile(&batch.xyz, origin),
        spacing: tile_spacing(&batch.xyz),
        colors,
    }
}

pub struct TilesetScene {
    name: String,
    tileset: Arc<Tileset>,
    /// Where tiles are read from: a recolouring starts fetchers of its own on it.
    source: Arc<dyn TileSource>,
    stream: TileStream<EncodedTile>,
    pool: TilePool,
    config: TilesetConfig,
    scale: ColorScale,
    /// The points the colouring is fitted on (the first tile with points).
    sample: PointBatch,
    bounds: Aabb,
    resident: HashMap<usize, Resident>,
    /// Tiles whose content could not be read or drawn (reported once, then left out).
    failed: HashSet<usize>,
    notes: Vec<String>,
    /// Tiles that could not be read (not merely of an unsupported kind): the picture lacks them.
    errors: Vec<pointlet_tiles::TilesError>,
    content_budget: u64,
    frame: u64,
    points_seen: u64,
}

/// The GPU share of the budget the output points take (the rest holds tile content).
const OUTPUT_SHARE: u64 = 4;

impl TilesetScene {
    /// Opens the tileset at `path` (a local `tileset.json` or an `http(s)://`/`s3://` URL).
    pub fn open(ctx: &GpuContext, path: &Path, config: TilesetConfig) -> Result<Self, EngineError> {
        let (tileset, source): (Tileset, Arc<dyn TileSource>) = if pointlet_store::is_remote(path) {
            let url = path.to_string_lossy().to_string();
            let source = crate::remote_tiles::RemoteTiles;
            let t = Tileset::load(&source, &url)?;
            (t, Arc::new(source))
        } else {
            let (source, uri) = LocalSource::for_file(path);
            let t = Tileset::load(&source, &uri)?;
            (t, Arc::new(source))
        };
        let tileset = Arc::new(tileset);
        let bounds = tileset.root().volume.aabb();
        // The colouring is fitted on the first tile with points (breadth first).
        let sample = first_content(&tileset, source.as_ref())?;
        let layout = PointLayout {
            rgb: sample
                .iter()
                .any(|c| c.colors.iter().any(|rgba| rgba[..3] != [255, 255, 255])),
            ..PointLayout::default()
        };
        let mut batch = PointBatch {
            layout,
            ..PointBatch::default()
        };
        for c in &sample {
            append_points(c, 0..c.len(), layout.rgb, &mut batch);
        }
        let mode = match config.color {
            Some(m) if m.available_in(&layout) => m,
            Some(m) => return Err(no_attribute(&path.display().to_string(), m)),
            None => default_color(&layout, &[&batch]).mode,
        };
        let z = if bounds.is_empty() {
            [0.0, 1.0]
        } else {
            [bounds.min[2], bounds.max[2]]
        };
        let scale = ColorScale::fit_in(mode, &[&batch], z, &ExtraAttributes::default());
        let output_points = (config.vram_budget / OUTPUT_SHARE / 16).max(1 << 16);
        // Pages of a sixteenth of the content's share: a page partly used is little of it.
        let page_bytes = (config.vram_budget / 16).clamp(1 << 20, CONTENT_PAGE_BYTES);
        let pool = TilePool::new(ctx, output_points, config.page_size, page_bytes)?;
        let content_budget = config.vram_budget.saturating_sub(pool.gpu_bytes());
        if content_budget < page_bytes {
            return Err(EngineError::Config(format!(
                "--vram-budget {} leaves no room for tiles beside the frame's output ({})",
                format_bytes(config.vram_budget),
                format_bytes(pool.gpu_bytes())
            )));
        }
        let stream = start_stream(&tileset, &source, &config, layout.rgb, scale)?;
        Ok(Self {
            name: path.display().to_string(),
            tileset,
            source,
            stream,
            pool,
            config,
            scale,
            sample: batch,
            bounds,
            resident: HashMap::new(),
            failed: HashSet::new(),
            notes: Vec::new(),
            errors: Vec::new(),
            content_budget,
            frame: 0,
            points_seen: 0,
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The root tile's bounding box (world coordinates).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The east–north–up frame at the root's centre when the tileset is in ECEF (a globe
    /// tileset), where views of it are made; `None` for a local tileset.
    pub fn local_frame(&self) -> Option<LocalFrame> {
        LocalFrame::at_ecef(self.tileset.root().volume.sphere.center)
    }

    /// The root's box in the coordinates views are made in: its [`local_frame`](Self::local_frame)
    /// if any, else the world's.
    pub fn view_bounds(&self) -> Aabb {
        let Some(frame) = self.local_frame() else {
            return self.bounds;
        };
        let b = &self.tileset.root().volume.oriented_box;
        let mut out = Aabb::EMPTY;
        for k in 0..8 {
            let corner = [0, 1, 2].map(|i| {
                (0..3).fold(b.center[i], |v, a| {
                    let sign = if k & (1 << a) != 0 { 1.0 } else { -1.0 };
                    v + sign * b.half_axes[a][i]
                })
            });
            out.grow(frame.to_local(corner));
        }
        out
    }

    pub fn tiles(&self) -> usize {
        self.tileset.tiles.len()
    }

    pub fn color_mode(&self) -> ColorMode {
        self.scale.mode
    }

    /// What was skipped since the last call (content of a kind not read, a tile too large to
    /// draw), one line each naming the tile.
    pub fn take_notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notes)
    }

    /// Tiles that could not be read since the last call (missing, truncated, damaged, a server
    /// error), each error naming its tile. The view draws without them.
    pub fn take_errors(&mut self) -> Vec<pointlet_tiles::TilesError> {
        std::mem::take(&mut self.errors)
    }

    pub fn gpu_bytes(&self) -> u64 {
        self.pool.gpu_bytes()
    }

    /// Points of the tiles uploaded so far (tiles uploaded again count again).
    pub fn points_seen(&self) -> u64 {
        self.points_seen
    }

    pub fn config(&self) -> &TilesetConfig {
        &self.config
    }

    /// The attributes the tiles are coloured by: RGB when the first tile with points has
    /// colours other than white (intensity and classification are always there, 0 where the
    /// tiles lack them).
    pub fn layout(&self) -> PointLayout {
        self.sample.layout
    }

    pub fn color_scale(&self) -> ColorScale {
        self.scale
    }

    /// The colouring chosen when none is asked for, and why (from the first tile with points).
    pub fn default_color(&self) -> DefaultColor {
        default_color(&self.sample.layout, &[&self.sample])
    }

    /// The scale of `mode` fitted as [`open`](Self::open) fits it: ranges from the first tile
    /// with points, elevation over the root volume's heights.
    pub fn fitted(&self, mode: ColorMode) -> Result<ColorScale, EngineError> {
        if !mode.available_in(&self.sample.layout) {
            return Err(no_attribute(&self.name, mode));
        }
        let z = if self.bounds.is_empty() {
            [0.0, 1.0]
        } else {
            [self.bounds.min[2], self.bounds.max[2]]
        };
        Ok(ColorScale::fit_in(
            mode,
            &[&self.sample],
            z,
            &ExtraAttributes::default(),
        ))
    }

    /// Colours by `mode`, its scale fitted as [`open`](Self::open) fits it.
    pub fn recolor(&mut self, mode: ColorMode) -> Result<(), EngineError> {
        let scale = self.fitted(mode)?;
        self.set_color_scale(scale)
    }

    /// Colours by `scale` as it is (a range or ramp edited by hand). Colours are encoded by the
    /// fetch workers, so every tile is fetched and uploaded again: the GPU's tiles and those
    /// held in RAM are dropped, and new workers encode with `scale` (the old ones are joined,
    /// which waits for the tiles they are fetching).
    pub fn set_color_scale(&mut self, scale: ColorScale) -> Result<(), EngineError> {
        if !scale.mode.available_in(&self.sample.layout) {
            return Err(no_attribute(&self.name, scale.mode));
        }
        if scale == self.scale {
            return Ok(());
        }
        // Started before the old workers go: if it fails, the scene keeps its colouring.
        let stream = start_stream(
            &self.tileset,
            &self.source,
            &self.config,
            self.sample.layout.rgb,
            scale,
        )?;
        self.stream = stream;
        for (tile, _) in self.resident.drain() {
            self.pool.remove(tile as u64);
        }
        self.scale = scale;
        Ok(())
    }

    fn drawable(&self, t: usize) -> bool {
        self.resident.contains_key(&t) || self.failed.contains(&t)
    }

    fn plan(&self, view: &TileView) -> TilePlan {
        plan(&self.tileset, view, self.config.max_sse, &|t| {
            self.drawable(t)
        })
    }

    /// Plans, streams and draws one frame of `camera` into `target`.
    pub fn frame(
        &mut self,
        ctx: &GpuContext,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
    ) -> Result<TilesetFrameReport, EngineError> {
        self.frame += 1;
        let view = TileView {
            camera: *camera,
            width: target.width,
            height: target.height,
        };
        let mut report = TilesetFrameReport {
            frame: self.frame,
            ..Default::default()
        };
        for (tile, error) in self.stream.take_failures() {
            self.failed.insert(tile);
            if matches!(
                error.root_cause(),
                pointlet_tiles::TilesError::Unsupported { .. }
            ) {
                self.notes.push(format!("skipped: {error}"));
            } else {
                self.errors.push(error);
            }
        }
        let first = self.plan(&view);
        self.stream.update(&first);
        self.upload(ctx, &first, &mut report);
        // Planned again: tiles uploaded just now draw this frame.
        let plan = self.plan(&view);
        let focal = camera.focal_px(target.height);
        let mut draws = Vec::with_capacity(plan.draw.len());
        for w in &plan.draw {
            let Some(r) = self.resident.get_mut(&w.tile) else {
                continue;
            };
            r.last_drawn = self.frame;
            let tile = &self.tileset.tiles[w.tile];
            // s_native / k with k = max_sse / focal: a point keeps with probability
            // SSE(d) / max_sse. Tiles without children keep all (nothing finer takes over),
            // and so does full detail (max SSE 0) and a tile that claims no error.
            let filtered = self.config.clod
                && !tile.children.is_empty()
                && self.config.max_sse > 0.0
                && tile.geometric_error > 0.0;
            let clod = filtered.then(|| tile.geometric_error * focal / self.config.max_sse);
            let kept = clod.map_or(1.0, |c| (c / w.distance.max(1e-9)).clamp(1e-3, 1.0));
            draws.push(TileDraw {
                key: w.tile as u64,
                clod,
                spacing: (r.spacing as f64 / kept.sqrt()) as f32,
            });
        }
        // Nearest first: if the output fills up, the far tiles are the ones left out.
        let mut order: Vec<usize> = (0..draws.len()).collect();
        order.sort_by(|a, b| plan.draw[*a].distance.total_cmp(&plan.draw[*b].distance));
        let draws: Vec<TileDraw> = order.into_iter().map(|k| draws[k]).collect();
        let laid = self
            .pool
            .prepare(ctx, camera, (target.width, target.height), settings, &draws);
        renderer.render_tiles(ctx, &self.pool, camera, settings, target)?;
        let wanted = plan_all(&self.tileset, &view, self.config.max_sse);
        let drawn: HashSet<usize> = draws.iter().map(|d| d.key as usize).collect();
        report.drawn_tiles = laid.tiles;
        report.tested_points = laid.points;
        report.skipped_tiles = laid.skipped;
        report.wanted_tiles = wanted.len() as u32;
        report.wanted_drawn = wanted
            .iter()
            .filter(|t| drawn.contains(t) || self.failed.contains(t))
            .count() as u32;
        report.requested_tiles = plan.requests.len() as u32;
        report.converged = plan.requests.is_empty() && laid.skipped == 0;
        report.stream = self.stream.stats();
        report.gpu_bytes = self.pool.gpu_bytes();
        Ok(report)
    }

    /// Moves decoded tiles the plan wants from RAM to the GPU, most important first, making
    /// room by dropping the least recently drawn tiles the plan does not draw.
    fn upload(&mut self, ctx: &GpuContext, plan: &TilePlan, report: &mut TilesetFrameReport) {
        let keep: HashSet<usize> = plan.draw.iter().map(|w| w.tile).collect();
        // Eviction candidates, listed once a frame when first needed: newest first, so the
        // least recently drawn pops off the end.
        let mut victims: Option<Vec<(u64, usize)>> = None;
        for w in &plan.requests {
            if report.uploaded_bytes >= self.config.upload_per_frame {
                break;
            }
            if self.drawable(w.tile) {
                continue;
            }
            let Some(tile) = self.stream.get(w.tile) else {
                continue;
            };
            if tile.colors.is_empty() {
                self.failed.insert(w.tile);
                continue;
            }
            let n = tile.colors.len();
            if !self.make_room(n, &keep, &mut victims, report) {
                // The budget holds no more with what this view draws: the view stays coarser.
                break;
            }
            let uploaded = self.pool.upload_encoded(
                ctx,
                w.tile as u64,
                tile.origin,
                &tile.positions,
                &tile.colors,
            );
            match uploaded {
                Ok(()) => {
                    self.resident.insert(
                        w.tile,
                        Resident {
                            last_drawn: self.frame,
                            spacing: tile.spacing,
                        },
                    );
                    self.points_seen += n as u64;
                    report.uploaded_tiles += 1;
                    report.uploaded_bytes += TilePool::tile_bytes(n);
                }
                Err(e) => {
                    let path = &self.tileset.tiles[w.tile].path;
                    self.notes.push(format!("tile {path}: not drawn: {e}"));
                    self.failed.insert(w.tile);
                }
            }
        }
    }

    /// Evicts until a tile of `points` points fits the content budget; false when only tiles
    /// of `keep` are left to evict.
    fn make_room(
        &mut self,
        points: usize,
        keep: &HashSet<usize>,
        victims: &mut Option<Vec<(u64, usize)>>,
        report: &mut TilesetFrameReport,
    ) -> bool {
        // Pages are made as needed: a tile that needs a new page needs its bytes in the budget.
        let fits = |pool: &TilePool| {
            pool.content_reserved() + pool.growth_for(points) <= self.content_budget
        };
        if fits(&self.pool) {
            return true;
        }
        let victims = victims.get_or_insert_with(|| {
            let mut v: Vec<(u64, usize)> = self
                .resident
                .iter()
                .filter(|(t, _)| !keep.contains(t))
                .map(|(t, r)| (r.last_drawn, *t))
                .collect();
            v.sort_unstable_by(|a, b| b.cmp(a));
            v
        });
        while let Some((_, t)) = victims.pop() {
            if self.resident.remove(&t).is_some() {
                self.pool.remove(t as u64);
                report.evicted_tiles += 1;
            }
            if fits(&self.pool) {
                return true;
            }
        }
        fits(&self.pool)
    }
}

fn no_attribute(tileset: &str, mode: ColorMode) -> EngineError {
    EngineError::Config(format!(
        "{tileset}: the tileset has no {} attribute to colour by",
        mode.name()
    ))
}

/// The fetch workers of `tileset`, each tile encoded for the GPU coloured by `scale`.
fn start_stream(
    tileset: &Arc<Tileset>,
    source: &Arc<dyn TileSource>,
    config: &TilesetConfig,
    rgb: bool,
    scale: ColorScale,
) -> Result<TileStream<EncodedTile>, EngineError> {
    TileStream::with_prepare(
        Arc::clone(tileset),
        Arc::clone(source),
        TileStreamConfig {
            workers: config.workers,
            ram_budget: config.ram_budget,
        },
        move |_, contents| Ok(encode(&contents, rgb, &scale)),
    )
    .map_err(|e| EngineError::Config(format!("starting the tile fetchers: {e}")))
}

/// The tiles a settled view of `view` draws (every tile loaded).
fn plan_all(tileset: &Tileset, view: &TileView, max_sse: f64) -> Vec<usize> {
    plan(tileset, view, max_sse, &|_| true)
        .draw
        .iter()
        .map(|w| w.tile)
        .collect()
}

/// Surface spacing of a tile's points (adaptive splats), as the LoD computes a pointlet's.
fn tile_spacing(positions: &[[f64; 3]]) -> f32 {
    let mut b = Aabb::EMPTY;
    for p in positions {
        b.grow(*p);
    }
    box_spacing(b.extent(), positions.len() as u64) as f32
}

/// The contents of the first tile with points, breadth first from the root.
fn first_content(
    tileset: &Tileset,
    source: &dyn TileSource,
) -> Result<Vec<TilePoints>, EngineError> {
    let mut queue = std::collections::VecDeque::from([0usize]);
    let mut failures = 0;
    while let Some(t) = queue.pop_front() {
        let Some(tile) = tileset.tiles.get(t) else {
            continue;
        };
        if !tile.contents.is_empty() {
            match tileset.read_tile(source, t) {
                Ok(c) if c.iter().any(|c| !c.is_empty()) => return Ok(c),
                Ok(_) => {}
                // A broken tile is reported when drawn; the colouring looks further.
                Err(_) if failures < 8 => failures += 1,
                Err(e) => return Err(e.into()),
            }
        }
        queue.extend(tile.children.iter().copied());
    }
    Err(EngineError::Config(
        "the tileset's tiles hold no points".to_string(),
    ))
}
