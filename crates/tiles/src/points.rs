//! A tileset read as a point file: the points of its full-detail tiles, tile after tile, so
//! that everything that draws or converts point files (the progressive renderer, `render`,
//! `view`, `bench`, `convert`) takes a `tileset.json` too. Full detail follows refinement: a
//! tile's content counts when the tile is a leaf or refines by `ADD`; a `REPLACE` parent's
//! content is a preview its children replace. Opening decodes every such tile once, on every
//! core, for the exact count and bounds (as PLY and text files get a pre-pass), keeping the
//! decoded contents while they fit [`CACHE_BYTES`] so that reading them does not fetch them
//! again; each tile is a part that the progressive loader's threads decode at once. Streaming
//! by screen-space error is a different path. Content this crate cannot decode (Draco, meshes) is skipped with
//! one note naming the tile; content that is missing or broken is an error naming the tile.

use crate::content::TilePoints;
use crate::{LocalSource, Refine, TileSource, TilesError, Tileset};
use pointlet_core::{Aabb, PointBatch, PointLayout, SourceMeta};
use pointlet_io::scale::fit_quantization;
use pointlet_io::{IoError, PointReader};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Decoded tile contents kept from the opening pass for the reads after it (beyond this, the
/// rest are decoded again when read).
pub const CACHE_BYTES: u64 = 512 << 20;

/// Decimals of the grid the points are stored on (millimetres): finer than the float32
/// positions of tile content carry far from their tile's origin.
const DECIMALS: i32 = 3;

/// True for files [`open`] reads: `.json` tileset files.
pub fn is_tileset_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// The tiles whose contents together are the tileset at full detail, root first.
pub fn full_detail_tiles(tileset: &Tileset) -> Vec<usize> {
    let mut out = Vec::new();
    let mut stack = vec![0usize];
    while let Some(t) = stack.pop() {
        let Some(tile) = tileset.tiles.get(t) else {
            continue;
        };
        if tile.children.is_empty() || tile.refine == Refine::Add {
            out.push(t);
        }
        stack.extend(tile.children.iter().rev());
    }
    out
}

/// The points of a tileset's full-detail tiles.
pub struct TilesetPoints {
    path: PathBuf,
    tileset: Tileset,
    source: Box<dyn TileSource>,
    meta: SourceMeta,
    /// Tiles with points, in order, and the points of each.
    tiles: Vec<usize>,
    sizes: Vec<u64>,
    /// Contents decoded by the opening pass, taken by the first read of their tile.
    cache: Vec<Mutex<Option<Vec<TilePoints>>>>,
    next_tile: usize,
    /// The contents of the tile being read, and the next point of them.
    pending: Vec<TilePoints>,
    cursor: (usize, usize),
    notes: Vec<String>,
}

/// What the opening pass keeps of one tile.
struct TileSummary {
    tile: usize,
    points: u64,
    bounds: Aabb,
    has_color: bool,
    /// Single-component attributes that are neither intensity nor classification.
    undrawn: Vec<String>,
    notes: Vec<String>,
    contents: Option<Vec<TilePoints>>,
}

impl TileSummary {
    fn of(tile: usize, contents: Vec<TilePoints>, cached: &AtomicU64, limit: u64) -> Self {
        let mut s = TileSummary {
            tile,
            points: 0,
            bounds: Aabb::EMPTY,
            has_color: false,
            undrawn: Vec::new(),
            notes: Vec::new(),
            contents: None,
        };
        let mut bytes = 0u64;
        for c in &contents {
            s.points += c.len() as u64;
            for p in &c.positions {
                s.bounds.grow(*p);
            }
            s.has_color |= c.colors.iter().any(|rgba| rgba[..3] != [255, 255, 255]);
            for a in c.attributes.iter().filter(|a| a.components == 1) {
                let drawn = is_intensity(&a.name) || is_classification(&a.name);
                if !drawn && !s.undrawn.contains(&a.name) {
                    s.undrawn.push(a.name.clone());
                }
            }
            s.notes
                .extend(c.notes.iter().map(|n| format!("{}: {n}", c.uri)));
            bytes += c.len() as u64 * (28 + 8 * c.attributes.len() as u64);
        }
        if cached.fetch_add(bytes, Ordering::Relaxed) + bytes <= limit {
            s.contents = Some(contents);
        } else {
            cached.fetch_sub(bytes, Ordering::Relaxed);
        }
        s
    }
}

/// Opens the tileset file at `path` for reading its points.
pub fn open(path: &Path) -> Result<Box<dyn PointReader>, IoError> {
    let (source, uri) = LocalSource::for_file(path);
    let tileset = Tileset::load(&source, &uri).map_err(|e| named(path, e))?;
    Ok(Box::new(TilesetPoints::new(
        path,
        tileset,
        Box::new(source),
    )?))
}

/// Tileset errors name their file and tile themselves.
fn named(_path: &Path, e: TilesError) -> IoError {
    IoError::Named(Box::new(e))
}

/// Names under which producers store intensity and classification per point.
fn is_intensity(name: &str) -> bool {
    matches!(
        name.trim_start_matches('_').to_ascii_lowercase().as_str(),
        "intensity"
    )
}

fn is_classification(name: &str) -> bool {
    matches!(
        name.trim_start_matches('_').to_ascii_lowercase().as_str(),
        "classification"
    )
}

impl TilesetPoints {
    pub fn new(
        path: &Path,
        tileset: Tileset,
        source: Box<dyn TileSource>,
    ) -> Result<Self, IoError> {
        Self::with_cache(path, tileset, source, CACHE_BYTES)
    }

    /// [`new`](Self::new) keeping at most `cache_bytes` of decoded contents from the opening
    /// pass.
    pub fn with_cache(
        path: &Path,
        tileset: Tileset,
        source: Box<dyn TileSource>,
        cache_bytes: u64,
    ) -> Result<Self, IoError> {
        // Every tile decoded at once; errors come back in tile order.
        let cached = AtomicU64::new(0);
        let decoded: Vec<Result<TileSummary, TilesError>> = full_detail_tiles(&tileset)
            .into_par_iter()
            .map(|t| {
                let contents = tileset.read_tile(source.as_ref(), t)?;
                Ok(TileSummary::of(t, contents, &cached, cache_bytes))
            })
            .collect();
        let mut notes = Vec::new();
        let mut bounds = Aabb::EMPTY;
        let mut count = 0u64;
        let (mut kept, mut sizes, mut cache) = (Vec::new(), Vec::new(), Vec::new());
        let mut has_color = false;
        let mut skipped_attributes: Vec<String> = Vec::new();
        for d in decoded {
            let s = match d {
                Ok(s) => s,
                Err(e) if matches!(e.root_cause(), TilesError::Unsupported { .. }) => {
                    notes.push(format!("skipped: {e}"));
                    continue;
                }
                Err(e) => return Err(named(path, e)),
            };
            count += s.points;
            bounds = bounds.union(&s.bounds);
            has_color |= s.has_color;
            for name in s.undrawn {
                if !skipped_attributes.contains(&name) {
                    skipped_attributes.push(name);
                }
            }
            notes.extend(s.notes);
            if s.points > 0 {
                kept.push(s.tile);
                sizes.push(s.points);
                cache.push(Mutex::new(s.contents));
            }
        }
        if count == 0 {
            return Err(IoError::no_points(
                path,
                "the tileset's full-detail tiles hold no points",
            ));
        }
        if !skipped_attributes.is_empty() {
            notes.push(format!(
                "per-point properties not drawn: {}",
                skipped_attributes.join(", ")
            ));
        }
        let quantization = fit_quantization(&bounds, [DECIMALS; 3]);
        if quantization.is_none() {
            return Err(IoError::invalid(
                path,
                "the tileset's points span more than 32-bit integers hold at 1 cm",
            ));
        }
        let version = tileset
            .files
            .first()
            .map_or("?".to_string(), |f| f.version.clone());
        let meta = SourceMeta {
            format: format!(
                "3D Tiles {version} tileset ({} tiles at full detail)",
                kept.len()
            ),
            point_count: count,
            bounds,
            quantization,
            layout: PointLayout {
                rgb: has_color,
                ..PointLayout::default()
            },
            las_point_format: None,
            vlrs: Vec::new(),
            las: None,
        };
        Ok(Self {
            path: path.to_path_buf(),
            tileset,
            source,
            meta,
            tiles: kept,
            sizes,
            cache,
            next_tile: 0,
            pending: Vec::new(),
            cursor: (0, 0),
            notes,
        })
    }

    /// The contents of the `k`-th tile with points: the opening pass's, or decoded again.
    fn contents(&self, k: usize) -> Result<Vec<TilePoints>, IoError> {
        let kept = self
            .cache
            .get(k)
            .and_then(|c| c.lock().ok().and_then(|mut c| c.take()));
        if let Some(contents) = kept {
            return Ok(contents);
        }
        let tile = *self
            .tiles
            .get(k)
            .ok_or_else(|| IoError::invalid(&self.path, format!("there is no part {k}")))?;
        self.tileset
            .read_tile(self.source.as_ref(), tile)
            .map_err(|e| named(&self.path, e))
    }

    /// Appends points `range` of `content` to `batch`, every column filled.
    fn append(&self, content: &TilePoints, range: std::ops::Range<usize>, batch: &mut PointBatch) {
        append_points(content, range, self.meta.layout.rgb, batch);
    }
}

/// Appends points `range` of `content` to `batch`: positions, colours (with `rgb`), and the
/// intensity and classification a content carries under those names; the other columns get
/// their defaults.
pub fn append_points(
    content: &TilePoints,
    range: std::ops::Range<usize>,
    rgb: bool,
    batch: &mut PointBatch,
) {
    batch
        .xyz
        .extend_from_slice(&content.positions[range.clone()]);
    if rgb {
        // 8-bit sRGB spread over LAS's 16-bit range (x 257: 255 becomes 65535).
        batch.rgb.extend(
            content.colors[range.clone()]
                .iter()
                .map(|c| [c[0] as u16 * 257, c[1] as u16 * 257, c[2] as u16 * 257]),
        );
    }
    let column = |pick: fn(&str) -> bool| {
        content
            .attributes
            .iter()
            .find(|a| a.components == 1 && pick(&a.name))
    };
    let (intensity, classes) = (column(is_intensity), column(is_classification));
    let at = |a: Option<&crate::PointAttribute>, i: usize, max: f64| {
        a.and_then(|a| a.values.get_f64(i))
            .map_or(0.0, |v| v.clamp(0.0, max))
    };
    for i in range {
        batch.intensity.push(at(intensity, i, 65535.0) as u16);
        // push_defaults also pushes class 0: the tile's own class replaces it.
        pointlet_io::push_defaults(batch);
        if let Some(last) = batch.classification.last_mut() {
            *last = at(classes, i, 255.0) as u8;
        }
    }
}

impl PointReader for TilesetPoints {
    fn path(&self) -> &Path {
        &self.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn notes(&self) -> &[String] {
        &self.notes
    }

    fn parted(&self) -> Option<&dyn pointlet_core::PartedSource> {
        Some(self)
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
        let mut batch = PointBatch {
            layout: self.meta.layout,
            ..PointBatch::default()
        };
        while batch.xyz.len() < max {
            let (c, p) = self.cursor;
            if c >= self.pending.len() {
                if self.next_tile >= self.tiles.len() {
                    break;
                }
                self.pending = self.contents(self.next_tile)?;
                self.next_tile += 1;
                self.cursor = (0, 0);
                continue;
            }
            let content = &self.pending[c];
            let take = (content.len() - p).min(max - batch.xyz.len());
            self.append(content, p..p + take, &mut batch);
            self.cursor = if p + take == content.len() {
                (c + 1, 0)
            } else {
                (c, p + take)
            };
        }
        if batch.xyz.is_empty() {
            return Ok(None);
        }
        Ok(Some(batch))
    }
}

impl pointlet_core::PartedSource for TilesetPoints {
    fn part_sizes(&self) -> &[u64] {
        &self.sizes
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut PointBatch,
        _scratch: &mut Vec<u8>,
    ) -> Result<(), pointlet_core::parts::PartError> {
        *out = PointBatch {
            layout: self.meta.layout,
            ..PointBatch::default()
        };
        for content in self.contents(i)? {
            let n = content.len();
            self.append(&content, 0..n, out);
        }
        if out.len() as u64 != self.sizes[i] {
            return Err(Box::new(IoError::invalid(
                &self.path,
                format!(
                    "tile {} changed while being read: {} points, {} before",
                    self.tiles[i],
                    out.len(),
                    self.sizes[i]
                ),
            )));
        }
        Ok(())
    }
}
