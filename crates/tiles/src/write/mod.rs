//! A store written as a 3D Tiles 1.1 tileset of GLB point tiles (`pointlet export-3dtiles`).
//!
//! The tree is an octree over the store's integer (quantized) grid, so every point falls in
//! exactly one cell at each depth without floating-point ties. A point's place in its
//! pointlet's shuffled order is a uniform random number u = (j + φ)/count, independent of where
//! the point lies (φ in (0, 1) is a hash of the pointlet's index, so that rates below one point
//! per pointlet still take r · count points of each on average), so "the points of a cell with
//! u < r" is a uniform subsample of the cell of rate r, read as a prefix of each pointlet. Each tile gets a rate r: min(1, T / its estimated
//! point count), never below its parent's; leaves get 1. With `ADD` a tile holds its cell's
//! points with u in [r(parent), r), so a point is in exactly one tile of its path; with
//! `REPLACE` it holds u < r, so a tile alone shows its cell at its level of detail and the
//! leaves together hold every point once. A tile's children's counts are estimated from its own
//! (uniform) points; its geometric error is the surface spacing of what it shows, leaves 0.
//!
//! Tiles are made level by level, a level in batches whose estimated bytes fit the RAM budget,
//! the tiles of a batch on rayon's threads. Every tile depends only on the store and its cell,
//! so the output is the same for any number of threads. Everything is written into a
//! temporary folder beside the output, renamed onto it at the end.

pub mod georef;
mod glb;
pub mod layout;

use crate::tileset::Refine;
use layout::{ExportLayout, TileColumns};
use pointlet_core::crs::Crs;
use pointlet_core::density::cloud_spacing;
use pointlet_core::Aabb;
use pointlet_store::{Store, StoreError, StreamKind};
use rayon::prelude::*;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use thiserror::Error;

pub use georef::{georeference, local_frame, Georeference, Projection};

/// Deepest tile level; cells this deep are leaves whatever their count (duplicate points).
const MAX_DEPTH: u32 = 24;
/// Points sampled per tile to measure its spacing.
const SPACING_SAMPLE: usize = 16_384;

#[derive(Debug, Error)]
pub enum ExportError {
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("{}: {what}: {source}", path.display())]
    Io {
        path: PathBuf,
        what: &'static str,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: the output folder is not empty (--force replaces it)", .0.display())]
    NotEmpty(PathBuf),
    #[error("{}: the output exists and is not a folder", .0.display())]
    NotAFolder(PathBuf),
    #[error("{}: the store holds no points", .0.display())]
    NoPoints(PathBuf),
}

fn io<'a>(path: &'a Path, what: &'static str) -> impl FnOnce(std::io::Error) -> ExportError + 'a {
    move |source| ExportError::Io {
        path: path.to_path_buf(),
        what,
        source,
    }
}

/// How to export.
#[derive(Clone, Copy, Debug)]
pub struct ExportConfig {
    pub refine: Refine,
    /// T: points a tile aims to hold.
    pub points_per_tile: u64,
    /// Bytes the tiles being made at once may take.
    pub ram_budget: u64,
    /// Replace an output folder that is not empty.
    pub force: bool,
    /// Keep the store's coordinates even when its CRS could place the tileset in ECEF.
    pub local: bool,
    /// Every attribute as per-point metadata (else positions and colours only).
    pub metadata: bool,
}

impl Default for ExportConfig {
    fn default() -> Self {
        ExportConfig {
            refine: Refine::Add,
            points_per_tile: 50_000,
            ram_budget: 1 << 30,
            force: false,
            local: false,
            metadata: true,
        }
    }
}

/// What an export did.
#[derive(Clone, Debug)]
pub struct ExportSummary {
    pub tiles: usize,
    pub leaves: usize,
    pub depth: u32,
    /// Points in all tile contents (the store's count for ADD, more for REPLACE).
    pub content_points: u64,
    /// Largest position error of the u16 quantization in any leaf, store units per axis.
    pub leaf_quantization_error: [f64; 3],
    /// Largest in any tile.
    pub quantization_error: [f64; 3],
    pub georeference: Georeference,
    /// What the export left out, one line each.
    pub notes: Vec<String>,
    pub eight_bit_color: bool,
}

/// A tile to make: its cell and its band of the shuffled order.
struct Task {
    path: String,
    depth: u32,
    lo: [i64; 3],
    /// Rates of the parent and of this tile.
    r_lo: f64,
    r_hi: f64,
    /// The parent's estimate of this tile's points.
    estimate: f64,
    parent: Option<usize>,
    parent_error: f64,
    /// Pointlets whose bounds meet the cell.
    pointlets: Vec<u32>,
}

/// A made tile.
struct Node {
    depth: u32,
    parent: Option<usize>,
    children: Vec<usize>,
    /// Bounds of the tile's subtree in store coordinates (the cell cut to its pointlets).
    bounds: Aabb,
    geometric_error: f64,
    content: Option<String>,
    points: usize,
}

struct Made {
    node: Node,
    children: Vec<Task>,
    quantization_error: [f64; 3],
}

/// Everything a tile needs to know of the whole export.
struct Context<'a> {
    store: &'a Store,
    layout: ExportLayout,
    config: ExportConfig,
    /// log2 of the root cell's size on each axis, in quantization steps.
    levels: [u32; 3],
    frame: glb::TileFrame,
    content_dir: PathBuf,
    progress: &'a (dyn Fn(u64) + Sync),
}

/// Exports `store` as a tileset into the folder `out`; `progress` gets the count of points
/// placed by each tile (they add up to the store's count).
pub fn export(
    store: &Store,
    out: &Path,
    config: &ExportConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<ExportSummary, ExportError> {
    let header = store.header();
    if header.points == 0 {
        return Err(ExportError::NoPoints(store.path().to_path_buf()));
    }
    check_output(out, config.force)?;
    let partial = PartialDir::create(out)?;

    let eight_bit_color = header.layout.rgb && colors_are_8_bit(store)?;
    let layout = ExportLayout::new(header, eight_bit_color, config.metadata);
    let crs = Crs::from_vlrs(&header.vlrs);
    let georeference = if config.local {
        local_frame(&header.bounds, "asked for (--local)")
    } else {
        georeference(crs.as_ref(), &header.bounds)
    };
    let q = header.quantization;
    let raw = |v: f64, a: usize| ((v - q.offset[a]) / q.scale[a]).round() as i64;
    let root_lo: [i64; 3] = std::array::from_fn(|a| raw(header.bounds.min[a], a));
    let root_hi: [i64; 3] = std::array::from_fn(|a| raw(header.bounds.max[a], a));
    let m = georeference.metres_per_unit;
    let largest = (0..3)
        .map(|a| (root_hi[a] - root_lo[a] + 1) as f64 * q.scale[a] * m[a])
        .fold(0.0, f64::max);
    // Cells about as long on every axis in metres, and covering every point of the store.
    let levels: [u32; 3] = std::array::from_fn(|a| {
        let steps =
            ((root_hi[a] - root_lo[a] + 1) as f64).max((largest / (q.scale[a] * m[a])).ceil());
        (steps.max(1.0).log2().ceil() as u32).min(40)
    });
    let content_dir = partial.path.join("content");
    std::fs::create_dir(&content_dir).map_err(io(&content_dir, "creating the content folder"))?;
    let ctx = Context {
        store,
        layout,
        config: *config,
        levels,
        frame: glb::TileFrame {
            scale: q.scale,
            offset: q.offset,
            origin: georeference.origin,
            metres_per_unit: m,
        },
        content_dir,
        progress,
    };

    let n = header.points as f64;
    let t = config.points_per_tile.max(1) as f64;
    let root = Task {
        path: "r".into(),
        depth: 0,
        lo: root_lo,
        r_lo: 0.0,
        r_hi: if n <= t || ctx.unsplittable(0) {
            1.0
        } else {
            t / n
        },
        estimate: n,
        parent: None,
        parent_error: f64::INFINITY,
        pointlets: (0..store.pointlets().len() as u32).collect(),
    };
    let mut nodes: Vec<Node> = Vec::new();
    let mut quantization_error = [0.0f64; 3];
    let mut leaf_quantization_error = [0.0f64; 3];
    let mut level = vec![root];
    while !level.is_empty() {
        let mut next = Vec::new();
        let mut start = 0;
        while start < level.len() {
            let mut end = start;
            let mut bytes = 0u64;
            while end < level.len()
                && (end == start || bytes + ctx.cost(&level[end]) <= config.ram_budget)
            {
                bytes += ctx.cost(&level[end]);
                end += 1;
            }
            let made: Vec<Result<Made, ExportError>> = level[start..end]
                .par_iter()
                .map(|task| ctx.make(task))
                .collect();
            for made in made {
                let made = made?;
                let index = nodes.len();
                let leaf = made.children.is_empty();
                for a in 0..3 {
                    quantization_error[a] = quantization_error[a].max(made.quantization_error[a]);
                    if leaf {
                        leaf_quantization_error[a] =
                            leaf_quantization_error[a].max(made.quantization_error[a]);
                    }
                }
                if let Some(parent) = made.node.parent {
                    nodes[parent].children.push(index);
                }
                nodes.push(made.node);
                next.extend(made.children.into_iter().map(|mut c| {
                    c.parent = Some(index);
                    c
                }));
            }
            start = end;
        }
        level = next;
    }

    let summary = ExportSummary {
        tiles: nodes.len(),
        leaves: nodes.iter().filter(|n| n.children.is_empty()).count(),
        depth: nodes.iter().map(|n| n.depth).max().unwrap_or(0),
        content_points: nodes.iter().map(|n| n.points as u64).sum(),
        leaf_quantization_error,
        quantization_error,
        georeference,
        notes: ctx.layout.notes.clone(),
        eight_bit_color,
    };
    let tileset = tileset_json(&ctx, &nodes, &summary, crs.as_ref());
    let tileset_path = partial.path.join("tileset.json");
    let text = serde_json::to_vec_pretty(&tileset).map_err(|e| ExportError::Io {
        path: tileset_path.clone(),
        what: "encoding the tileset",
        source: e.into(),
    })?;
    std::fs::write(&tileset_path, text).map_err(io(&tileset_path, "writing the tileset"))?;
    partial.finish(out)?;
    Ok(summary)
}

impl Context<'_> {
    /// Side of a cell at `depth` on `axis`, in quantization steps.
    fn size(&self, depth: u32, axis: usize) -> i64 {
        1i64 << self.levels[axis].saturating_sub(depth)
    }

    fn unsplittable(&self, depth: u32) -> bool {
        depth >= MAX_DEPTH || (0..3).all(|a| self.size(depth, a) == 1)
    }

    /// The cell's box in store coordinates (inclusive, as pointlet bounds are).
    fn cell_box(&self, lo: [i64; 3], depth: u32) -> Aabb {
        let q = self.store.header().quantization;
        Aabb {
            min: std::array::from_fn(|a| lo[a] as f64 * q.scale[a] + q.offset[a]),
            max: std::array::from_fn(|a| {
                (lo[a] + self.size(depth, a) - 1) as f64 * q.scale[a] + q.offset[a]
            }),
        }
    }

    /// Estimated bytes a tile takes while being made: read bytes, its columns and its GLB.
    fn cost(&self, task: &Task) -> u64 {
        let band = match self.config.refine {
            Refine::Add => task.r_hi - task.r_lo,
            Refine::Replace => task.r_hi,
        };
        let per_point: usize = self.layout.bytes_per_point.iter().sum::<usize>() + 64;
        // Pointlets cut by the cell are read whole: count twice the estimate.
        (2.0 * task.estimate * band * 3.0 * per_point as f64) as u64 + (1 << 16)
    }

    fn make(&self, task: &Task) -> Result<Made, ExportError> {
        let store = self.store;
        let cell = self.cell_box(task.lo, task.depth);
        let size: [i64; 3] = std::array::from_fn(|a| self.size(task.depth, a));
        let half: [i64; 3] = std::array::from_fn(|a| if size[a] > 1 { size[a] / 2 } else { 0 });
        let inside = |p: [i32; 3]| {
            (0..3).all(|a| {
                let v = p[a] as i64;
                v >= task.lo[a] && v < task.lo[a] + size[a]
            })
        };
        let mut columns = TileColumns::new(&self.layout);
        let mut band_points = 0u64;
        let mut octants = [0u64; 8];
        let mut reach = Aabb::EMPTY;
        for &i in &task.pointlets {
            let entry = store.pointlets()[i as usize];
            reach = reach.union(&entry.aabb);
            let phase = phase_of(i);
            let j_lo = prefix(task.r_lo, entry.count, phase);
            let j_hi = prefix(task.r_hi, entry.count, phase);
            let from = match self.config.refine {
                Refine::Add => j_lo,
                Refine::Replace => 0,
            };
            if from >= j_hi {
                continue;
            }
            let raw = store.read_streams_raw(i as usize, from..j_hi, &self.layout.kinds)?;
            for (k, p) in raw[0].chunks_exact(12).enumerate() {
                let p = position(p);
                if !inside(p) {
                    continue;
                }
                columns.push_from(&self.layout, &raw, k);
                if from + k as u32 >= j_lo {
                    band_points += 1;
                }
                let octant = (0..3).fold(0, |o, a| {
                    o | (usize::from(half[a] > 0 && p[a] as i64 >= task.lo[a] + half[a]) << a)
                });
                octants[octant] += 1;
            }
        }
        (self.progress)(band_points);
        let bounds = intersection(&cell, &reach);

        let leaf = task.r_hi >= 1.0;
        let shown = match self.config.refine {
            Refine::Add if task.r_hi > task.r_lo => {
                band_points as f64 * task.r_hi / (task.r_hi - task.r_lo)
            }
            Refine::Add => 0.0,
            Refine::Replace => columns.len() as f64,
        };
        let geometric_error = if leaf {
            0.0
        } else {
            self.spacing(&columns, shown, &bounds)
                .min(task.parent_error)
        };

        let mut children = Vec::new();
        if !leaf {
            let rate = match self.config.refine {
                Refine::Add => task.r_hi - task.r_lo,
                Refine::Replace => task.r_hi,
            };
            let t = self.config.points_per_tile.max(1) as f64;
            for (octant, sampled) in octants.iter().enumerate() {
                if (0..3).any(|a| octant & (1 << a) != 0 && half[a] == 0) {
                    continue;
                }
                let lo: [i64; 3] = std::array::from_fn(|a| {
                    task.lo[a] + if octant & (1 << a) != 0 { half[a] } else { 0 }
                });
                let child_cell = self.cell_box(lo, task.depth + 1);
                let pointlets: Vec<u32> = task
                    .pointlets
                    .iter()
                    .copied()
                    .filter(|&i| store.pointlets()[i as usize].aabb.intersects(&child_cell))
                    .collect();
                if pointlets.is_empty() {
                    continue;
                }
                let estimate = if rate > 0.0 {
                    *sampled as f64 / rate
                } else {
                    0.0
                };
                let r_hi = if estimate <= t || self.unsplittable(task.depth + 1) {
                    1.0
                } else {
                    (t / estimate).max(task.r_hi)
                };
                children.push(Task {
                    path: format!("{}{octant}", task.path),
                    depth: task.depth + 1,
                    lo,
                    r_lo: task.r_hi,
                    r_hi,
                    estimate: estimate.max(1.0),
                    parent: None,
                    parent_error: geometric_error,
                    pointlets,
                });
            }
        }

        let mut quantization_error = [0.0; 3];
        let content = if columns.is_empty() {
            None
        } else {
            let (bytes, error) = glb::encode(&columns, &self.layout, &self.frame);
            quantization_error = error;
            let name = format!("{}.glb", task.path);
            let path = self.content_dir.join(&name);
            std::fs::write(&path, bytes).map_err(io(&path, "writing a tile"))?;
            Some(format!("content/{name}"))
        };
        Ok(Made {
            node: Node {
                depth: task.depth,
                parent: task.parent,
                children: Vec::new(),
                bounds,
                geometric_error,
                content,
                points: columns.len(),
            },
            children,
            quantization_error,
        })
    }

    /// The surface spacing (metres of the local frame) of `shown` points spread like `columns`.
    fn spacing(&self, columns: &TileColumns, shown: f64, bounds: &Aabb) -> f64 {
        let q = self.store.header().quantization;
        let m = self.frame.metres_per_unit;
        let positions: Vec<[f64; 3]> = columns
            .positions()
            .into_iter()
            .map(|p| std::array::from_fn(|a| (p[a] as f64 * q.scale[a] + q.offset[a]) * m[a]))
            .collect();
        let shown = shown.max(1.0);
        cloud_spacing(&positions, shown as u64, SPACING_SAMPLE).unwrap_or_else(|| {
            let e = bounds.extent();
            let largest = (0..3).map(|a| e[a] * m[a]).fold(0.0, f64::max);
            largest / shown.sqrt()
        })
    }
}

/// How many of a pointlet's `count` shuffled points have u = (j + ½)/count below `rate`.
/// Points j of a pointlet of `count` with u = (j + phase)/count < rate.
fn prefix(rate: f64, count: u32, phase: f64) -> u32 {
    if rate >= 1.0 {
        return count;
    }
    ((rate * count as f64 - phase).ceil().max(0.0) as u32).min(count)
}

/// φ of pointlet `i`: in (0, 1), fixed by the index alone (the output stays the same for any
/// number of threads).
fn phase_of(i: u32) -> f64 {
    let h = pointlet_core::shuffle::SplitMix64::new(0x7113_5eed ^ u64::from(i)).next_u64();
    ((h >> 11) as f64 + 0.5) / (1u64 << 53) as f64
}

fn position(b: &[u8]) -> [i32; 3] {
    let at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    [at(0), at(4), at(8)]
}

fn intersection(a: &Aabb, b: &Aabb) -> Aabb {
    Aabb {
        min: std::array::from_fn(|i| a.min[i].max(b.min[i])),
        max: std::array::from_fn(|i| a.max[i].min(b.max[i])),
    }
}

/// Whether every colour of a sample of pointlets fits 8 bits (LAS files often store 8-bit
/// colours in their 16-bit fields).
fn colors_are_8_bit(store: &Store) -> Result<bool, ExportError> {
    for i in pointlet_core::color::sample_indices(store.pointlets().len()) {
        let count = store.pointlets()[i].count;
        let rgb = store.read_streams_raw(i, 0..count, &[StreamKind::Rgb])?;
        if rgb[0]
            .chunks_exact(2)
            .any(|c| u16::from_le_bytes([c[0], c[1]]) > 255)
        {
            return Ok(false);
        }
    }
    Ok(true)
}

fn tileset_json(
    ctx: &Context,
    nodes: &[Node],
    summary: &ExportSummary,
    crs: Option<&Crs>,
) -> Value {
    let g = &summary.georeference;
    let refine = match ctx.config.refine {
        Refine::Add => "ADD",
        Refine::Replace => "REPLACE",
    };
    let boxed = |b: &Aabb| -> Value {
        let c = b.center();
        let e = b.extent();
        let m = g.metres_per_unit;
        let centre: [f64; 3] = std::array::from_fn(|a| (c[a] - g.origin[a]) * m[a]);
        // A flat cell still needs a box with volume for some runtimes: at least a millimetre.
        let half: [f64; 3] = std::array::from_fn(|a| (e[a] * m[a] / 2.0).max(5e-4));
        json!([centre[0], centre[1], centre[2], half[0], 0, 0, 0, half[1], 0, 0, 0, half[2]])
    };
    fn tile(nodes: &[Node], i: usize, boxed: &dyn Fn(&Aabb) -> Value) -> Value {
        let n = &nodes[i];
        let mut t = json!({
            "boundingVolume": { "box": boxed(&n.bounds) },
            "geometricError": n.geometric_error,
        });
        if let Some(uri) = &n.content {
            t["content"] = json!({ "uri": uri });
        }
        if !n.children.is_empty() {
            t["children"] =
                Value::Array(n.children.iter().map(|&c| tile(nodes, c, boxed)).collect());
        }
        t
    }
    let mut root = tile(nodes, 0, &boxed);
    root["refine"] = json!(refine);
    root["transform"] = json!(g.root_transform.0);
    let m = g.metres_per_unit;
    let e = nodes[0].bounds.extent();
    let diagonal = (0..3).map(|a| (e[a] * m[a]).powi(2)).sum::<f64>().sqrt();
    json!({
        "asset": {
            "version": "1.1",
            "generator": "pointlet export-3dtiles",
            "extras": {
                "pointlet": {
                    "store": ctx.store.path().display().to_string(),
                    "points": ctx.store.header().points,
                    "refine": refine,
                    "pointsPerTile": ctx.config.points_per_tile,
                    "crs": crs.map(|c| c.to_string()),
                    "georeferenced": g.epsg.is_some(),
                    "epsg": g.epsg,
                    "placement": g.note,
                    "origin": g.origin,
                    "metresPerUnit": g.metres_per_unit,
                    "colorDepth": if summary.eight_bit_color { 8 } else { 16 },
                    "notExported": summary.notes,
                }
            }
        },
        "geometricError": (diagonal / 2.0).max(nodes[0].geometric_error),
        "root": root,
    })
}

/// Refuses an output that is a file, or a folder that is not empty unless forced.
fn check_output(out: &Path, force: bool) -> Result<(), ExportError> {
    match std::fs::metadata(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io(out, "checking the output")(e)),
        Ok(m) if !m.is_dir() => Err(ExportError::NotAFolder(out.to_path_buf())),
        Ok(_) => {
            let mut entries = std::fs::read_dir(out).map_err(io(out, "listing the output"))?;
            if entries.next().is_some() && !force {
                Err(ExportError::NotEmpty(out.to_path_buf()))
            } else {
                Ok(())
            }
        }
    }
}

/// The folder an export writes into, beside the output; removed unless renamed onto it.
struct PartialDir {
    path: PathBuf,
    done: bool,
}

impl PartialDir {
    fn create(out: &Path) -> Result<PartialDir, ExportError> {
        let name = out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "tileset".into());
        let parent = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let path = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if path.exists() {
            std::fs::remove_dir_all(&path).map_err(io(&path, "removing an old partial export"))?;
        }
        std::fs::create_dir(&path).map_err(io(&path, "creating the export folder"))?;
        Ok(PartialDir { path, done: false })
    }

    /// Puts the finished tileset at `out`, replacing what a forced export may replace.
    fn finish(mut self, out: &Path) -> Result<(), ExportError> {
        if out.exists() {
            std::fs::remove_dir_all(out).map_err(io(out, "removing the old output"))?;
        }
        std::fs::rename(&self.path, out).map_err(io(out, "moving the tileset into place"))?;
        self.done = true;
        Ok(())
    }
}

impl Drop for PartialDir {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}
