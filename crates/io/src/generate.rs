//! Deterministic synthetic airborne-LiDAR scene: the benchmark input of `pointlet generate`.
//!
//! The scene is a square of about [`DENSITY_PER_M2`] points per m² (so its area grows with the
//! point count) near UTM 500 000 E / 4 100 000 N: value-noise hills with lakes in the hollows, a
//! grid of roads, and land use that shifts between fields, suburbs (houses with gabled or flat
//! roofs, garden trees) and forest (broadleaf and conifer trees with trunks, shrubs).
//!
//! It is cut into tiles of about 50 m, flown as north–south strips of [`STRIP_TILES`] tile
//! columns (alternately northbound and southbound; `point_source_id` is the strip number). Each
//! tile is generated on its own from `mix_seed(seed, tile)` and the objects of its neighbours,
//! so tiles are made in parallel (rayon) and the output never depends on batch sizes or thread
//! counts; a reader holds only the few tiles in flight. Points come tile by tile in flight
//! order and, inside a tile, scan line by scan line, so the GPS time grows along each strip
//! like a scanner's. Tiles get points in proportion to their area, exactly in integers.
//!
//! Inside a tile, pulses are laid on a jittered scan pattern a little denser than needed; each
//! finds what it hits (roof, wall, crown, shrub, road, water, ground) and gives one to four
//! returns; a uniform selection then keeps exactly the tile's share of the returns (the dropped
//! ones look like weak returns that were not recorded).
//!
//! Exactness: positions are integer millimetres dequantized with the scene's quantization, so
//! every coordinate survives quantization bit for bit; the first point of the south-west tile
//! (a low noise return at the bounds' minimum corner) and the last point of the north-east tile
//! (a high noise return at the maximum corner) make the declared bounds exact.
//!
//! Portability: only SplitMix64 hashing and exactly specified IEEE-754 operations are used
//! (`+ - * /`, `sqrt`, casts, floor/ceil/remainder, whose results are exact); the one
//! transcendental function, atan for the scan angle, is a polynomial written out here because
//! libm's last bit may differ between platforms. So the same (points, seed) gives the same
//! bits everywhere.

use crate::{IoError, PointReader};
use pointlet_core::shuffle::{mix_seed, SplitMix64};
use pointlet_core::{flags, Aabb, PointBatch, PointLayout, Quantization, SourceMeta, Vlr};
use rayon::prelude::*;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Points per square metre: a dense low-altitude survey.
pub const DENSITY_PER_M2: f64 = 20.0;
/// Tile columns per flight strip.
pub const STRIP_TILES: u64 = 6;
/// EPSG code of the CRS written into the GeoKey directory (WGS 84 / UTM zone 11N).
pub const EPSG_UTM: u16 = 32611;

/// Side of a tile the scene aims for; the real side divides the scene evenly (37.5–75 m).
const TILE_TARGET_MM: i64 = 50_000;
/// Sides beyond 1000 km would overflow 32-bit millimetres; larger counts get denser instead.
const MAX_SIDE_MM: i64 = 1_000_000_000;
/// Points a tile may hold (reached only when the side is capped): bounds a reader's memory.
const MAX_TILE_POINTS: u64 = 100_000;
/// Terrain lattice and object-lookup cell size.
const CELL_MM: i64 = 2_000;
const MM: f64 = 0.001;
/// Quantization offset: the scene's south-west corner at the bottom of the height range.
const CORNER: [f64; 3] = [500_000.0, 4_100_000.0, 170.0];
/// Terrain heights above the corner's z: base plus up to the relief.
const TERRAIN_BASE_M: f64 = 10.0;
const TERRAIN_RELIEF_M: f64 = 60.0;
/// Top of the height range above the corner's z: highest ground plus the highest object or noise.
const TOP_M: f64 = 120.0;
/// Terrain below this fraction of the relief is under water.
const WATER_FRACTION: f64 = 0.3;
const ROAD_HALF_WIDTH_M: f64 = 3.5;
/// Building sites per m² where the urban weight is 1 (a dense suburb: ~4 houses per 50 m tile).
const BUILDINGS_PER_M2: f64 = 0.0017;
/// Trees per m²: everywhere, plus times the forest weight, plus times the urban weight.
const TREES_PER_M2: [f64; 3] = [0.002, 0.03, 0.004];
/// Shrubs per m²: everywhere, plus times (1 − forest weight).
const SHRUBS_PER_M2: [f64; 2] = [0.003, 0.006];
const MARKING_HALF_WIDTH_M: f64 = 0.075;
/// Pulses landing this close outside a footprint may hit the wall instead (oblique rays).
const WALL_BAND_M: f64 = 1.2;
const AIRCRAFT_SPEED_M_S: f64 = 60.0;
const TURN_S: f64 = 90.0;
/// Adjusted standard GPS time of the first strip (late 2021).
const FIRST_STRIP_TIME_S: f64 = 320_000_000.0;
const MAX_SCAN_DEG: f64 = 30.0;
const TAN_MAX_SCAN: f64 = 0.577_350_269_189_625_8;
/// Pulses in a tile are over-provisioned by this factor, then returns are thinned to the count.
const PULSE_MARGIN: f64 = 1.04;
/// One pulse in this many (on open ground) is a noise return instead.
const NOISE_ONE_IN: u64 = 5_000;

const TERRAIN_OCTAVES: [(f64, f64); 5] = [
    (900.0, 0.42),
    (350.0, 0.28),
    (130.0, 0.16),
    (45.0, 0.09),
    (14.0, 0.05),
];
const LAND_USE_OCTAVES: [(f64, f64); 2] = [(260.0, 0.65), (90.0, 0.35)];

/// Independent random streams derived from the scene seed.
const STREAM_TERRAIN: u64 = 1;
const STREAM_URBAN: u64 = 2;
const STREAM_FOREST: u64 = 3;
const STREAM_CONIFER: u64 = 4;
const STREAM_FIELDS: u64 = 5;
const STREAM_DETAIL: u64 = 6;
const STREAM_ROADS: u64 = 7;
const STREAM_TILES: u64 = 8;
const STREAM_BUILDINGS: u64 = 1;
const STREAM_VEGETATION: u64 = 2;
const STREAM_PULSES: u64 = 3;
const STREAM_THINNING: u64 = 4;

/// ASPRS classes used by the scene.
mod class {
    pub const GROUND: u8 = 2;
    pub const LOW_VEGETATION: u8 = 3;
    pub const MEDIUM_VEGETATION: u8 = 4;
    pub const HIGH_VEGETATION: u8 = 5;
    pub const BUILDING: u8 = 6;
    pub const LOW_NOISE: u8 = 7;
    pub const WATER: u8 = 9;
    pub const ROAD: u8 = 11;
    pub const HIGH_NOISE: u8 = 18;
}

/// A surface's look: 8-bit RGB and a mean 16-bit intensity.
#[derive(Clone, Copy)]
struct Material {
    rgb: [f32; 3],
    intensity: f32,
}

const fn mat(r: f32, g: f32, b: f32, intensity: f32) -> Material {
    Material {
        rgb: [r, g, b],
        intensity,
    }
}

const GRASS: Material = mat(74.0, 118.0, 50.0, 24_000.0);
const DRY_GRASS: Material = mat(150.0, 146.0, 88.0, 26_000.0);
const SOIL: Material = mat(122.0, 98.0, 72.0, 18_000.0);
const LITTER: Material = mat(78.0, 66.0, 50.0, 14_000.0);
const ASPHALT: Material = mat(68.0, 68.0, 72.0, 9_000.0);
const MARKING: Material = mat(225.0, 225.0, 218.0, 42_000.0);
const WATER: Material = mat(38.0, 58.0, 70.0, 2_000.0);
const WALL: Material = mat(206.0, 196.0, 176.0, 17_000.0);
const TRUNK: Material = mat(92.0, 72.0, 52.0, 12_000.0);
const NOISE: Material = mat(128.0, 128.0, 128.0, 4_000.0);
const ROOFS: [Material; 5] = [
    mat(168.0, 78.0, 56.0, 15_000.0),   // terracotta tiles
    mat(128.0, 62.0, 46.0, 14_000.0),   // dark red tiles
    mat(86.0, 90.0, 98.0, 11_000.0),    // slate
    mat(152.0, 152.0, 146.0, 25_000.0), // gravel / concrete
    mat(192.0, 186.0, 172.0, 30_000.0), // light membrane
];
const BROADLEAF: Material = mat(62.0, 108.0, 44.0, 28_000.0);
const CONIFER: Material = mat(38.0, 72.0, 40.0, 22_000.0);
const SHRUB: Material = mat(90.0, 118.0, 58.0, 25_000.0);

/// What to generate: the same config always gives the same points in the same order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneConfig {
    pub points: u64,
    pub seed: u64,
}

/// The synthetic scene; cheap to create (nothing is generated until a reader asks).
#[derive(Clone)]
pub struct SceneGenerator {
    scene: Arc<Scene>,
}

impl SceneGenerator {
    pub fn new(config: SceneConfig) -> Self {
        Self {
            scene: Arc::new(Scene::new(config)),
        }
    }

    /// Header of the scene: exact count and bounds, LAS point format 3, a UTM CRS record.
    pub fn meta(&self) -> SourceMeta {
        self.scene.meta()
    }

    /// A fresh stream of every point from the first.
    pub fn reader(&self) -> GeneratorReader {
        let s = &self.scene;
        GeneratorReader {
            path: PathBuf::from(format!("generated:{}@seed{}", s.points, s.seed)),
            meta: s.meta(),
            walk: TileWalk::default(),
            ready: VecDeque::new(),
            spare: Vec::new(),
            scene: Arc::clone(s),
        }
    }
}

/// Streams the scene; tiles are generated in parallel (rayon) a few batches ahead at most.
pub struct GeneratorReader {
    scene: Arc<Scene>,
    path: PathBuf,
    meta: SourceMeta,
    walk: TileWalk,
    /// Generated tiles not yet handed out, with how many of their points already were.
    ready: VecDeque<(TileBuffer, usize)>,
    /// Emptied tile buffers, reused so that memory is not allocated and faulted in again.
    spare: Vec<TileBuffer>,
}

/// A tile's points and its scratch pulses.
#[derive(Default)]
struct TileBuffer {
    points: PointBatch,
    pulses: Vec<Pulse>,
}

impl GeneratorReader {
    fn buffered(&self) -> usize {
        self.ready
            .iter()
            .map(|(t, used)| t.points.len() - used)
            .sum()
    }

    /// Generates the next tiles (a multiple of the thread count) in parallel.
    fn refill(&mut self, wanted: usize) -> bool {
        let threads = rayon::current_num_threads().max(1);
        let per_tile = self.scene.mean_tile_points().max(1);
        let needed = wanted.div_ceil(per_tile).max(1);
        let count = needed.div_ceil(threads).saturating_mul(threads);
        let jobs: Vec<TileJob> = (0..count)
            .map_while(|_| self.walk.next(&self.scene))
            .collect();
        if jobs.is_empty() {
            return false;
        }
        let scene = &*self.scene;
        let mut tiles: Vec<TileBuffer> = (0..jobs.len())
            .map(|_| self.spare.pop().unwrap_or_default())
            .collect();
        tiles
            .par_iter_mut()
            .zip(&jobs)
            .for_each(|(t, j)| scene.tile(j, t));
        self.ready.extend(tiles.into_iter().map(|t| (t, 0)));
        true
    }
}

impl PointReader for GeneratorReader {
    fn path(&self) -> &Path {
        &self.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    /// `max == 0` gives an empty batch while points remain.
    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
        if max == 0 {
            let done = self.ready.is_empty() && self.walk.done(&self.scene);
            return Ok((!done).then(|| PointBatch::new(self.meta.layout)));
        }
        let mut have = self.buffered();
        while have < max && self.refill(max - have) {
            have = self.buffered();
        }
        if have == 0 {
            return Ok(None);
        }
        let mut out = PointBatch::with_capacity(self.meta.layout, have.min(max));
        while out.len() < max {
            let Some((tile, used)) = self.ready.front_mut() else {
                break;
            };
            let take = (tile.points.len() - *used).min(max - out.len());
            append(&mut out, &tile.points, *used..*used + take);
            *used += take;
            if *used == tile.points.len() {
                if let Some((t, _)) = self.ready.pop_front() {
                    self.spare.push(t);
                }
            }
        }
        Ok(Some(out))
    }
}

/// Empties every column, keeping the memory.
fn clear(b: &mut PointBatch) {
    b.xyz.clear();
    b.intensity.clear();
    b.returns.clear();
    b.flags.clear();
    b.classification.clear();
    b.scan_angle.clear();
    b.user_data.clear();
    b.point_source_id.clear();
    b.gps_time.clear();
    b.rgb.clear();
}

/// Room for `n` more points in the columns the generator fills.
fn reserve(b: &mut PointBatch, n: usize) {
    b.xyz.reserve(n);
    b.intensity.reserve(n);
    b.returns.reserve(n);
    b.flags.reserve(n);
    b.classification.reserve(n);
    b.scan_angle.reserve(n);
    b.user_data.reserve(n);
    b.point_source_id.reserve(n);
    b.gps_time.reserve(n);
    b.rgb.reserve(n);
}

/// Appends a range of `src` (same layout) column by column.
fn append(out: &mut PointBatch, src: &PointBatch, r: std::ops::Range<usize>) {
    out.xyz.extend_from_slice(&src.xyz[r.clone()]);
    out.intensity.extend_from_slice(&src.intensity[r.clone()]);
    out.returns.extend_from_slice(&src.returns[r.clone()]);
    out.flags.extend_from_slice(&src.flags[r.clone()]);
    out.classification
        .extend_from_slice(&src.classification[r.clone()]);
    out.scan_angle.extend_from_slice(&src.scan_angle[r.clone()]);
    out.user_data.extend_from_slice(&src.user_data[r.clone()]);
    out.point_source_id
        .extend_from_slice(&src.point_source_id[r.clone()]);
    out.gps_time.extend_from_slice(&src.gps_time[r.clone()]);
    out.rgb.extend_from_slice(&src.rgb[r]);
}

/// Scene-wide constants derived from the config.
struct Scene {
    points: u64,
    seed: u64,
    side_mm: i64,
    side_m: f64,
    tiles_per_side: u64,
    strips: u64,
    flying_height_m: f64,
    /// Road center lines every `spacing` metres from `offset`: [north–south roads, east–west].
    road_spacing: [f64; 2],
    road_offset: [f64; 2],
    water_level: f64,
    layout: PointLayout,
    quantization: Quantization,
}

/// One tile to generate, in flight order, with its share of the points.
#[derive(Clone, Copy, Debug)]
struct TileJob {
    col: u64,
    row: u64,
    strip: u64,
    points: u64,
    low_anchor: bool,
    high_anchor: bool,
}

/// Walks the tiles in flight order and hands each its share of the points, proportional to its
/// area (exact in integers, so the shares add up to the total).
#[derive(Default)]
struct TileWalk {
    strip: u64,
    step: u64,
    col_in_strip: u64,
    area_before: u128,
    allotted: u64,
}

impl TileWalk {
    /// Every point was allotted (the remaining tiles would be empty).
    fn done(&self, s: &Scene) -> bool {
        self.strip >= s.strips || self.allotted >= s.points
    }

    fn next(&mut self, s: &Scene) -> Option<TileJob> {
        let n = s.tiles_per_side;
        if self.done(s) {
            return None;
        }
        let (c0, c1) = s.strip_cols(self.strip);
        let col = c0 + self.col_in_strip;
        let row = if s.northbound(self.strip) {
            self.step
        } else {
            n - 1 - self.step
        };
        let job_strip = self.strip;
        self.col_in_strip += 1;
        if c0 + self.col_in_strip >= c1 {
            self.col_in_strip = 0;
            self.step += 1;
            if self.step >= n {
                self.step = 0;
                self.strip += 1;
            }
        }
        let [x0, x1] = s.tile_span(col);
        let [y0, y1] = s.tile_span(row);
        self.area_before += ((x1 - x0) as u128) * ((y1 - y0) as u128);
        let total = (s.side_mm as u128) * (s.side_mm as u128);
        let target = (s.points as u128 * self.area_before / total) as u64;
        let points = target - self.allotted;
        self.allotted = target;
        let low_anchor = col == 0 && row == 0 && points >= 1;
        let high_anchor = col == n - 1 && row == n - 1 && points > low_anchor as u64;
        Some(TileJob {
            col,
            row,
            strip: job_strip,
            points,
            low_anchor,
            high_anchor,
        })
    }
}

impl Scene {
    fn new(config: SceneConfig) -> Self {
        let SceneConfig { points, seed } = config;
        let side_m = (points as f64 / DENSITY_PER_M2).sqrt();
        let side_mm = round_i64(side_m * 1000.0).clamp(1, MAX_SIDE_MM);
        let side_m = side_mm as f64 * MM;
        let by_size = ((side_mm + TILE_TARGET_MM / 2) / TILE_TARGET_MM).max(1) as u64;
        // Only past the side cap: more, smaller tiles keep a tile's memory bounded.
        let by_count = (points as f64 / MAX_TILE_POINTS as f64).sqrt().ceil() as u64;
        let tiles_per_side = by_size.max(by_count).min(side_mm as u64);
        let strips = tiles_per_side.div_ceil(STRIP_TILES);
        let swath_m = side_m * STRIP_TILES.min(tiles_per_side) as f64 / tiles_per_side as f64;
        let mut rng = SplitMix64::new(mix_seed(seed, STREAM_ROADS));
        let mut road = || {
            let spacing = 160.0 + 120.0 * rng.unit_f64();
            (spacing, spacing * rng.unit_f64())
        };
        let (sx, ox) = road();
        let (sy, oy) = road();
        Scene {
            points,
            seed,
            side_mm,
            side_m,
            tiles_per_side,
            strips,
            flying_height_m: 0.5 * swath_m / TAN_MAX_SCAN,
            road_spacing: [sx, sy],
            road_offset: [ox, oy],
            water_level: TERRAIN_BASE_M + TERRAIN_RELIEF_M * WATER_FRACTION,
            layout: PointLayout {
                gps_time: true,
                rgb: true,
                ..Default::default()
            },
            quantization: Quantization {
                scale: [MM; 3],
                offset: CORNER,
            },
        }
    }

    fn meta(&self) -> SourceMeta {
        let q = &self.quantization;
        let min = q.dequantize([0, 0, 0]);
        // The corner anchors exist from two points on; a single point is the low anchor alone.
        let max = if self.points >= 2 {
            q.dequantize([self.side_mm as i32, self.side_mm as i32, top_mm() as i32])
        } else {
            min
        };
        SourceMeta {
            format: "synthetic scene".to_string(),
            point_count: self.points,
            bounds: Aabb { min, max },
            quantization: Some(*q),
            layout: self.layout,
            las_point_format: Some(3),
            vlrs: vec![geokey_vlr()],
            las: None,
        }
    }

    fn mean_tile_points(&self) -> usize {
        let tiles = (self.tiles_per_side as u128) * (self.tiles_per_side as u128);
        usize::try_from(self.points as u128 / tiles).unwrap_or(usize::MAX)
    }

    /// Millimetre span [start, end) of tile column (or row) `i`.
    fn tile_span(&self, i: u64) -> [i64; 2] {
        let n = self.tiles_per_side as i128;
        let at = |k: u64| (self.side_mm as i128 * k as i128 / n) as i64;
        [at(i), at(i + 1)]
    }

    fn strip_cols(&self, strip: u64) -> (u64, u64) {
        let c0 = strip * STRIP_TILES;
        (c0, (c0 + STRIP_TILES).min(self.tiles_per_side))
    }

    fn northbound(&self, strip: u64) -> bool {
        strip.is_multiple_of(2)
    }

    fn tile_seed(&self, col: u64, row: u64) -> u64 {
        mix_seed(mix_seed(self.seed, STREAM_TILES), (row << 32) | col)
    }

    fn stream(&self, stream: u64) -> u64 {
        mix_seed(self.seed, stream)
    }

    /// Ground height above the corner's z: hills with bumps down to 14 m across.
    fn terrain(&self, x: f64, y: f64) -> f64 {
        TERRAIN_BASE_M + TERRAIN_RELIEF_M * fbm(self.stream(STREAM_TERRAIN), x, y, &TERRAIN_OCTAVES)
    }

    /// (urban, forest) weights in [0, 1] at a place; forest gives way to town.
    fn land_use(&self, x: f64, y: f64) -> (f64, f64) {
        let u = fbm(self.stream(STREAM_URBAN), x, y, &LAND_USE_OCTAVES);
        let f = fbm(self.stream(STREAM_FOREST), x, y, &LAND_USE_OCTAVES);
        let urban = smoothstep((u - 0.47) / 0.14);
        (urban, smoothstep((f - 0.43) / 0.14) * (1.0 - urban))
    }

    fn road_distance(&self, v: f64, axis: usize) -> f64 {
        let m = (v - self.road_offset[axis]).rem_euclid(self.road_spacing[axis]);
        m.min(self.road_spacing[axis] - m)
    }

    /// Road center lines crossing [lo, hi] along one axis.
    fn roads_between(&self, lo: f64, hi: f64, axis: usize) -> Vec<f64> {
        let (sp, off) = (self.road_spacing[axis], self.road_offset[axis]);
        let mut c = off + ((lo - ROAD_HALF_WIDTH_M - off) / sp).ceil() * sp;
        let mut out = Vec::new();
        while c <= hi + ROAD_HALF_WIDTH_M {
            out.push(c);
            c += sp;
        }
        out
    }

    fn tile_rect_m(&self, col: u64, row: u64) -> [f64; 4] {
        let [x0, x1] = self.tile_span(col);
        let [y0, y1] = self.tile_span(row);
        [
            x0 as f64 * MM,
            y0 as f64 * MM,
            x1 as f64 * MM,
            y1 as f64 * MM,
        ]
    }

    /// Buildings of one tile: kept 2 m inside it, off roads, water and each other. Candidate
    /// sites are thinned by the local urban weight, so towns fade out smoothly across tiles.
    fn buildings_of(&self, col: u64, row: u64) -> Vec<Building> {
        let [x0, y0, x1, y1] = self.tile_rect_m(col, row);
        let mut rng = SplitMix64::new(mix_seed(self.tile_seed(col, row), STREAM_BUILDINGS));
        let sites = stochastic_round((x1 - x0) * (y1 - y0) * BUILDINGS_PER_M2, &mut rng);
        let mut out: Vec<Building> = Vec::new();
        for _ in 0..sites {
            let (px, py) = (
                x0 + (x1 - x0) * rng.unit_f64(),
                y0 + (y1 - y0) * rng.unit_f64(),
            );
            let (urban, _) = self.land_use(px, py);
            if rng.unit_f64() >= urban {
                continue;
            }
            for _attempt in 0..4 {
                let b = Building::random(&mut rng, urban);
                let r = b.radius();
                let (lo_x, hi_x) = (x0 + 2.0 + r, x1 - 2.0 - r);
                let (lo_y, hi_y) = (y0 + 2.0 + r, y1 - 2.0 - r);
                if lo_x > hi_x || lo_y > hi_y {
                    continue;
                }
                let (cx, cy) = (px.clamp(lo_x, hi_x), py.clamp(lo_y, hi_y));
                let clear = r + ROAD_HALF_WIDTH_M + 3.0;
                if self.road_distance(cx, 0) < clear || self.road_distance(cy, 1) < clear {
                    continue;
                }
                let crowded = out
                    .iter()
                    .any(|o| dist2(o.cx, o.cy, cx, cy) < sq(o.radius() + r + 3.0));
                if crowded {
                    continue;
                }
                let base = self.terrain(cx, cy);
                if base < self.water_level + 1.0 {
                    continue;
                }
                out.push(Building { cx, cy, base, ..b });
                break;
            }
        }
        out
    }

    /// Trees and shrubs rooted in one tile; crowns may reach into the neighbours, so placement
    /// avoids the buildings of the 3×3 tiles around (`near`). Candidates are thinned by the
    /// local densities (forest, gardens, open land), so woods have no tile-shaped edges.
    fn vegetation_of(&self, col: u64, row: u64, near: &[&Vec<Building>]) -> Vec<Veg> {
        let [x0, y0, x1, y1] = self.tile_rect_m(col, row);
        let mut rng = SplitMix64::new(mix_seed(self.tile_seed(col, row), STREAM_VEGETATION));
        // Forest and urban weights add up to at most 1, so this bounds every local density.
        let max_density = TREES_PER_M2[0]
            + TREES_PER_M2[1].max(TREES_PER_M2[2])
            + SHRUBS_PER_M2[0]
            + SHRUBS_PER_M2[1];
        let candidates = stochastic_round((x1 - x0) * (y1 - y0) * max_density, &mut rng);
        let mut out = Vec::new();
        for _ in 0..candidates {
            let (x, y) = (
                x0 + (x1 - x0) * rng.unit_f64(),
                y0 + (y1 - y0) * rng.unit_f64(),
            );
            let pick = rng.unit_f64() * max_density;
            let (urban, forest) = self.land_use(x, y);
            let trees = TREES_PER_M2[0] + TREES_PER_M2[1] * forest + TREES_PER_M2[2] * urban;
            let shrubs = SHRUBS_PER_M2[0] + SHRUBS_PER_M2[1] * (1.0 - forest);
            let kind = if pick < trees {
                let conifers = fbm(self.stream(STREAM_CONIFER), x, y, &LAND_USE_OCTAVES);
                if rng.unit_f64() < smoothstep((conifers - 0.35) / 0.3) {
                    VegKind::Conifer
                } else {
                    VegKind::Broadleaf
                }
            } else if pick < trees + shrubs {
                VegKind::Shrub
            } else {
                continue;
            };
            let v = Veg::random(&mut rng, kind, x, y);
            if self.road_distance(x, 0) < ROAD_HALF_WIDTH_M + 1.5
                || self.road_distance(y, 1) < ROAD_HALF_WIDTH_M + 1.5
            {
                continue;
            }
            let blocked = near
                .iter()
                .flat_map(|b| b.iter())
                .any(|b| dist2(b.cx, b.cy, x, y) < sq(b.radius() + v.radius + WALL_BAND_M + 0.3));
            if blocked {
                continue;
            }
            let ground = self.terrain(x, y);
            if ground < self.water_level + 0.3 {
                continue;
            }
            out.push(Veg { ground, ..v });
        }
        out
    }

    /// Generates one tile into `buf`: exactly `job.points` points in scan order.
    fn tile(&self, job: &TileJob, buf: &mut TileBuffer) {
        let out = &mut buf.points;
        clear(out);
        out.layout = self.layout;
        if job.points == 0 {
            return;
        }
        reserve(out, job.points as usize);
        let plan = Plan::build(self, job);
        let anchors = job.low_anchor as u64 + job.high_anchor as u64;
        let wanted = job.points - anchors;
        if job.low_anchor {
            plan.push_anchor(out, false);
        }
        if wanted > 0 {
            plan.scan(out, wanted, &mut buf.pulses);
        }
        if job.high_anchor {
            plan.push_anchor(out, true);
        }
    }
}

fn top_mm() -> i64 {
    (TOP_M * 1000.0) as i64
}

/// GeoTIFF key directory (LASF_Projection 34735) naming a projected UTM CRS in metres.
fn geokey_vlr() -> Vlr {
    let keys: [[u16; 4]; 6] = [
        [1, 1, 0, 5],           // directory version 1.1.0, five keys
        [1024, 0, 1, 1],        // GTModelTypeGeoKey: projected
        [1025, 0, 1, 1],        // GTRasterTypeGeoKey: pixel is area
        [3072, 0, 1, EPSG_UTM], // ProjectedCSTypeGeoKey
        [3076, 0, 1, 9001],     // ProjLinearUnitsGeoKey: metre
        [4099, 0, 1, 9001],     // VerticalUnitsGeoKey: metre
    ];
    Vlr {
        user_id: "LASF_Projection".to_string(),
        record_id: 34735,
        description: "GeoKeyDirectoryTag".to_string(),
        data: keys
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
        extended: false,
    }
}

#[derive(Clone, Copy)]
struct Building {
    cx: f64,
    cy: f64,
    cos: f64,
    sin: f64,
    /// Half length along the ridge (local x) and half width (local y).
    hx: f64,
    hy: f64,
    base: f64,
    eave: f64,
    /// Roof rise per metre from the long walls to the ridge; 0 for a flat roof.
    slope: f64,
    roof: Material,
}

impl Building {
    /// Shape, height and roof; placement is the caller's.
    fn random(rng: &mut SplitMix64, urban: f64) -> Building {
        let block = rng.unit_f64() < 0.25 * urban;
        let (hx, hy, eave, slope) = if block {
            let hx = 10.0 + 6.0 * rng.unit_f64();
            (
                hx,
                7.0 + 4.0 * rng.unit_f64(),
                9.0 + 12.0 * rng.unit_f64(),
                0.0,
            )
        } else {
            let hx = 4.5 + 4.5 * rng.unit_f64();
            let hy = 3.5 + (hx.min(6.0) - 3.5) * rng.unit_f64();
            let gabled = rng.unit_f64() < 0.7;
            let slope = if gabled {
                0.45 + 0.5 * rng.unit_f64()
            } else {
                0.0
            };
            (hx, hy, 2.8 + 3.7 * rng.unit_f64(), slope)
        };
        // Rotation from t = tan(angle / 2) (no trigonometry): mostly along the road grid.
        let t = if rng.unit_f64() < 0.7 {
            let jitter = 0.06 * (rng.unit_f64() - 0.5);
            if rng.unit_f64() < 0.5 {
                jitter
            } else {
                1.0 + jitter
            }
        } else {
            2.0 * rng.unit_f64() - 1.0
        };
        let d = 1.0 / (1.0 + t * t);
        let roof = if slope > 0.0 {
            ROOFS[rng.below(3) as usize]
        } else {
            ROOFS[3 + rng.below(2) as usize]
        };
        Building {
            cx: 0.0,
            cy: 0.0,
            cos: (1.0 - t * t) * d,
            sin: 2.0 * t * d,
            hx,
            hy,
            base: 0.0,
            eave,
            slope,
            roof,
        }
    }

    fn radius(&self) -> f64 {
        (self.hx * self.hx + self.hy * self.hy).sqrt()
    }

    fn local_of(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.cx, y - self.cy);
        (dx * self.cos + dy * self.sin, dy * self.cos - dx * self.sin)
    }

    fn world_of(&self, lx: f64, ly: f64) -> (f64, f64) {
        (
            self.cx + lx * self.cos - ly * self.sin,
            self.cy + lx * self.sin + ly * self.cos,
        )
    }

    /// Roof height at a local position inside the footprint.
    fn roof_z(&self, ly: f64) -> f64 {
        self.base + self.eave + self.slope * (self.hy - ly.abs())
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum VegKind {
    Broadleaf,
    Conifer,
    Shrub,
}

#[derive(Clone, Copy)]
struct Veg {
    cx: f64,
    cy: f64,
    radius: f64,
    inv_r2: f64,
    kind: VegKind,
    ground: f64,
    /// Top and crown base above the ground.
    height: f64,
    crown_base: f64,
    trunk_radius: f64,
    look: Material,
}

impl Veg {
    fn random(rng: &mut SplitMix64, kind: VegKind, cx: f64, cy: f64) -> Veg {
        let (height, radius, crown_base, look) = match kind {
            VegKind::Broadleaf => {
                let h = 8.0 + 16.0 * rng.unit_f64();
                let r = (h * (0.2 + 0.1 * rng.unit_f64())).min(6.0);
                (h, r, h * (0.3 + 0.2 * rng.unit_f64()), BROADLEAF)
            }
            VegKind::Conifer => {
                let h = 10.0 + 20.0 * rng.unit_f64();
                let r = (h * (0.12 + 0.08 * rng.unit_f64())).min(5.0);
                (h, r, h * (0.15 + 0.2 * rng.unit_f64()), CONIFER)
            }
            VegKind::Shrub => {
                let r = 0.5 + rng.unit_f64();
                (0.4 + 2.1 * rng.unit_f64(), r, 0.0, SHRUB)
            }
        };
        // Each plant has its own shade.
        let shade = (0.85 + 0.3 * rng.unit_f64()) as f32;
        let warm = (12.0 * (rng.unit_f64() - 0.5)) as f32;
        Veg {
            cx,
            cy,
            radius,
            inv_r2: 1.0 / (radius * radius),
            kind,
            ground: 0.0,
            height,
            crown_base,
            trunk_radius: 0.012 * height + 0.05,
            look: Material {
                rgb: [
                    look.rgb[0] * shade + warm,
                    look.rgb[1] * shade,
                    look.rgb[2] * shade - warm,
                ],
                intensity: look.intensity * shade,
            },
        }
    }

    /// Height of the crown's upper surface at squared distance `d2` (< r²) from the stem.
    fn top_z(&self, d2: f64) -> f64 {
        let depth = self.height - self.crown_base;
        let t = d2 * self.inv_r2;
        self.ground
            + match self.kind {
                VegKind::Broadleaf => {
                    self.crown_base + 0.5 * depth * (1.0 + (1.0 - t).max(0.0).sqrt())
                }
                VegKind::Conifer => self.height - depth * t.sqrt(),
                VegKind::Shrub => self.height * (1.0 - t).max(0.0).sqrt(),
            }
    }
}

/// What a pulse's ray meets first, found per 2 m cell.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Hit {
    /// Bare surface: ground, road or water.
    Ground,
    /// A stray return (bird, multipath) above or below the ground.
    Noise,
    Roof(u32),
    /// Roof within 25 cm of its edge: a second return on the ground.
    RoofEdge(u32),
    /// Ground just outside a footprint, where an oblique ray meets the wall first.
    Wall(u32),
    /// The highest crown over the spot.
    Veg(u32),
}

#[derive(Clone, Copy)]
struct Pulse {
    x: i32,
    y: i32,
    hit: Hit,
    returns: u8,
}

/// One return before it is written.
#[derive(Clone, Copy, Default)]
struct Return {
    mm: [i64; 3],
    class: u8,
    /// Random bits for the color and intensity jitter.
    bits: u64,
    rgb: [f32; 3],
    intensity: f32,
}

/// Attributes shared by a pulse's returns.
#[derive(Clone, Copy)]
struct PulseInfo {
    time: f64,
    angle: f32,
    flags: u8,
    /// Intensity falloff with the incidence angle.
    falloff: f32,
}

/// Everything needed to generate one tile: its objects, terrain lattice and lookup cells.
struct Plan<'a> {
    scene: &'a Scene,
    seed: u64,
    x: [i64; 2],
    y: [i64; 2],
    cell0: [i64; 2],
    cells: [usize; 2],
    /// Terrain heights at the cell corners, (cells + 1)² row-major.
    nodes: Vec<f64>,
    /// Ground material per cell (fields, dry grass, bare soil).
    ground: Vec<Material>,
    /// Objects over each cell: `cell_start[c]..cell_start[c + 1]` in `cands`; a set top bit
    /// marks a building.
    cell_start: Vec<u32>,
    cands: Vec<u32>,
    buildings: Vec<Building>,
    vegs: Vec<Veg>,
    roads_x: Vec<f64>,
    roads_y: Vec<f64>,
    strip_center_m: f64,
    strip_edge: [bool; 2],
    north: bool,
    /// GPS time when the aircraft started the strip.
    strip_time: f64,
    inv_flying_height: f64,
    source: u16,
}

const BUILDING_BIT: u32 = 1 << 31;

impl<'a> Plan<'a> {
    fn build(scene: &'a Scene, job: &TileJob) -> Plan<'a> {
        let (col, row) = (job.col, job.row);
        let x = scene.tile_span(col);
        let y = scene.tile_span(row);
        let cell0 = [x[0].div_euclid(CELL_MM), y[0].div_euclid(CELL_MM)];
        let cells = [
            ((x[1] - 1).div_euclid(CELL_MM) - cell0[0] + 1) as usize,
            ((y[1] - 1).div_euclid(CELL_MM) - cell0[1] + 1) as usize,
        ];
        let cell_m = CELL_MM as f64 * MM;
        let mut nodes = Vec::with_capacity((cells[0] + 1) * (cells[1] + 1));
        for j in 0..=cells[1] {
            for i in 0..=cells[0] {
                let (gx, gy) = ((cell0[0] + i as i64) as f64, (cell0[1] + j as i64) as f64);
                nodes.push(scene.terrain(gx * cell_m, gy * cell_m));
            }
        }
        let (fields, detail) = (scene.stream(STREAM_FIELDS), scene.stream(STREAM_DETAIL));
        let mut ground = Vec::with_capacity(cells[0] * cells[1]);
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                let gx = ((cell0[0] + i as i64) as f64 + 0.5) * cell_m;
                let gy = ((cell0[1] + j as i64) as f64 + 0.5) * cell_m;
                let f = value_noise(fields, gx / 80.0, gy / 80.0);
                let d = value_noise(detail, gx / 9.0, gy / 9.0);
                let grass = mix(GRASS, DRY_GRASS, smoothstep((f - 0.35) / 0.35));
                let m = mix(grass, SOIL, smoothstep((f - 0.7) / 0.1));
                ground.push(Material {
                    rgb: m.rgb.map(|c| c * (0.9 + 0.2 * d as f32)),
                    intensity: m.intensity * (0.9 + 0.2 * d as f32),
                });
            }
        }

        // Buildings of the 5×5 tiles around: trees of the 3×3 neighbours must avoid theirs.
        let n = scene.tiles_per_side as i64;
        let inside = |c: i64, r: i64| c >= 0 && r >= 0 && c < n && r < n;
        let mut near_buildings: Vec<Vec<Building>> = Vec::with_capacity(25);
        for dr in -2..=2i64 {
            for dc in -2..=2i64 {
                let (c, r) = (col as i64 + dc, row as i64 + dr);
                near_buildings.push(if inside(c, r) {
                    scene.buildings_of(c as u64, r as u64)
                } else {
                    Vec::new()
                });
            }
        }
        let block = |dc: i64, dr: i64| &near_buildings[((dr + 2) * 5 + dc + 2) as usize];
        let buildings = block(0, 0).clone();
        let [tx0, ty0, tx1, ty1] = scene.tile_rect_m(col, row);
        let mut vegs = Vec::new();
        for dr in -1..=1i64 {
            for dc in -1..=1i64 {
                let (c, r) = (col as i64 + dc, row as i64 + dr);
                if !inside(c, r) {
                    continue;
                }
                let mut near = Vec::with_capacity(9);
                for er in -1..=1 {
                    for ec in -1..=1 {
                        near.push(block(dc + ec, dr + er));
                    }
                }
                vegs.extend(
                    scene
                        .vegetation_of(c as u64, r as u64, &near)
                        .into_iter()
                        .filter(|v| {
                            v.cx + v.radius > tx0
                                && v.cx - v.radius < tx1
                                && v.cy + v.radius > ty0
                                && v.cy - v.radius < ty1
                        }),
                );
            }
        }

        let (c0, c1) = scene.strip_cols(job.strip);
        let strip_x0 = scene.tile_span(c0)[0] as f64 * MM;
        let strip_x1 = scene.tile_span(c1 - 1)[1] as f64 * MM;
        let mut plan = Plan {
            scene,
            seed: scene.tile_seed(col, row),
            x,
            y,
            cell0,
            cells,
            nodes,
            ground,
            cell_start: Vec::new(),
            cands: Vec::new(),
            buildings,
            vegs,
            roads_x: scene.roads_between(tx0, tx1, 0),
            roads_y: scene.roads_between(ty0, ty1, 1),
            strip_center_m: 0.5 * (strip_x0 + strip_x1),
            strip_edge: [col == c0, col == c1 - 1],
            north: scene.northbound(job.strip),
            strip_time: FIRST_STRIP_TIME_S
                + job.strip as f64 * (scene.side_m / AIRCRAFT_SPEED_M_S + TURN_S),
            inv_flying_height: 1.0 / scene.flying_height_m,
            source: (job.strip % u16::MAX as u64) as u16 + 1,
        };
        plan.index_objects();
        plan
    }

    /// Fills the per-cell candidate lists (counting pass, then placement).
    fn index_objects(&mut self) {
        let mut boxes: Vec<(u32, [f64; 4])> = Vec::new();
        for (i, b) in self.buildings.iter().enumerate() {
            let r = b.radius() + WALL_BAND_M;
            boxes.push((
                i as u32 | BUILDING_BIT,
                [b.cx - r, b.cy - r, b.cx + r, b.cy + r],
            ));
        }
        for (i, v) in self.vegs.iter().enumerate() {
            let r = v.radius;
            boxes.push((i as u32, [v.cx - r, v.cy - r, v.cx + r, v.cy + r]));
        }
        let ncells = self.cells[0] * self.cells[1];
        let mut counts = vec![0u32; ncells + 1];
        let ranges: Vec<_> = boxes.iter().map(|(_, b)| self.cell_range(b)).collect();
        for r in &ranges {
            for j in r[1]..r[3] {
                for i in r[0]..r[2] {
                    counts[j * self.cells[0] + i + 1] += 1;
                }
            }
        }
        for c in 1..=ncells {
            counts[c] += counts[c - 1];
        }
        let mut fill = counts.clone();
        self.cands = vec![0; counts[ncells] as usize];
        for ((id, _), r) in boxes.iter().zip(&ranges) {
            for j in r[1]..r[3] {
                for i in r[0]..r[2] {
                    let slot = &mut fill[j * self.cells[0] + i];
                    self.cands[*slot as usize] = *id;
                    *slot += 1;
                }
            }
        }
        self.cell_start = counts;
    }

    /// Cells [i0, j0, i1, j1) of this tile overlapped by a box in metres.
    fn cell_range(&self, b: &[f64; 4]) -> [usize; 4] {
        let cell_m = CELL_MM as f64 * MM;
        let to = |v: f64, axis: usize| -> usize {
            let c = floor_i64(v / cell_m) - self.cell0[axis];
            c.clamp(0, self.cells[axis] as i64) as usize
        };
        [
            to(b[0], 0),
            to(b[1], 1),
            (to(b[2], 0) + 1).min(self.cells[0]),
            (to(b[3], 1) + 1).min(self.cells[1]),
        ]
    }

    /// The lookup cell of a millimetre position (clamped into the tile).
    fn cell_of(&self, x: i64, y: i64) -> Cell {
        let i = (x.div_euclid(CELL_MM) - self.cell0[0]).clamp(0, self.cells[0] as i64 - 1);
        let j = (y.div_euclid(CELL_MM) - self.cell0[1]).clamp(0, self.cells[1] as i64 - 1);
        Cell {
            i: i as usize,
            j: j as usize,
            index: j as usize * self.cells[0] + i as usize,
        }
    }

    /// Terrain height (bilinear in the 2 m lattice) at a millimetre position in the tile.
    fn ground_z(&self, x: i64, y: i64, c: Cell) -> f64 {
        const INV_CELL: f64 = 1.0 / CELL_MM as f64;
        let fx = ((x - (self.cell0[0] + c.i as i64) * CELL_MM) as f64 * INV_CELL).clamp(0.0, 1.0);
        let fy = ((y - (self.cell0[1] + c.j as i64) * CELL_MM) as f64 * INV_CELL).clamp(0.0, 1.0);
        let w = self.cells[0] + 1;
        let k = c.j * w + c.i;
        let (a, b) = (self.nodes[k], self.nodes[k + 1]);
        let (c, d) = (self.nodes[k + w], self.nodes[k + w + 1]);
        let lo = a + (b - a) * fx;
        let hi = c + (d - c) * fx;
        lo + (hi - lo) * fy
    }

    /// What is first under a pulse at (x, y) mm, before any random choice.
    fn lookup(&self, x: i64, y: i64) -> Hit {
        let c = self.cell_of(x, y).index;
        let (xm, ym) = (x as f64 * MM, y as f64 * MM);
        let mut best = Hit::Ground;
        let mut best_z = f64::NEG_INFINITY;
        for &id in &self.cands[self.cell_start[c] as usize..self.cell_start[c + 1] as usize] {
            if id & BUILDING_BIT != 0 {
                let id = id & !BUILDING_BIT;
                let b = &self.buildings[id as usize];
                let (lx, ly) = b.local_of(xm, ym);
                let (ex, ey) = (b.hx - lx.abs(), b.hy - ly.abs());
                if ex >= 0.0 && ey >= 0.0 {
                    // Buildings never lie under crowns or other buildings.
                    return if ex.min(ey) < 0.25 {
                        Hit::RoofEdge(id)
                    } else {
                        Hit::Roof(id)
                    };
                }
                if ex > -WALL_BAND_M && ey > -WALL_BAND_M && best == Hit::Ground {
                    best = Hit::Wall(id);
                }
            } else {
                let v = &self.vegs[id as usize];
                let d2 = dist2(v.cx, v.cy, xm, ym);
                if d2 * v.inv_r2 < 1.0 {
                    let z = v.top_z(d2);
                    if z > best_z {
                        best_z = z;
                        best = Hit::Veg(id);
                    }
                }
            }
        }
        best
    }

    /// What a pulse at (x, y) hits and how many returns it gives, from one random word.
    fn pulse(&self, x: i64, y: i64, bits: u64) -> (Hit, u8) {
        let hit = self.lookup(x, y);
        let low = bits & 0xFFFF_FFFF;
        match hit {
            Hit::Ground if low.is_multiple_of(NOISE_ONE_IN) => (Hit::Noise, 1),
            Hit::Ground | Hit::Noise | Hit::Roof(_) => (hit, 1),
            Hit::RoofEdge(_) => (hit, 2),
            // Oblique rays near a wall hit it about half the time; the rest reach the ground.
            Hit::Wall(_) if low < (1 << 31) => (hit, 1),
            Hit::Wall(_) => (Hit::Ground, 1),
            Hit::Veg(v) => {
                let v = &self.vegs[v as usize];
                let u = (bits >> 32) & 0xFFFF;
                let n = if v.kind == VegKind::Shrub {
                    1 + (u < 0x6000) as u8
                } else {
                    // 25 % one return, 35 % two, 25 % three, 15 % four.
                    match u {
                        0..0x4000 => 1,
                        0x4000..0x9999 => 2,
                        0x9999..0xD999 => 3,
                        _ => 4,
                    }
                };
                let d2 = dist2(v.cx, v.cy, x as f64 * MM, y as f64 * MM);
                // Rays through the thin crown rim rarely split more than once.
                (hit, if d2 * v.inv_r2 > 0.81 { n.min(2) } else { n })
            }
        }
    }

    /// Mean returns per pulse without randomness (16×16 probe grid), to size the pulse count.
    fn mean_returns(&self) -> f64 {
        let mut sum = 0.0;
        for j in 0..16 {
            for i in 0..16 {
                let x = self.x[0] + (self.x[1] - self.x[0]) * (2 * i + 1) / 32;
                let y = self.y[0] + (self.y[1] - self.y[0]) * (2 * j + 1) / 32;
                sum += match self.lookup(x, y) {
                    Hit::RoofEdge(_) => 2.0,
                    Hit::Veg(v) if self.vegs[v as usize].kind == VegKind::Shrub => 1.375,
                    Hit::Veg(_) => 2.2,
                    _ => 1.0,
                };
            }
        }
        sum / 256.0
    }

    /// Random stream of pulse `p`: two words for `lay_pulses`, the rest for its returns.
    fn pulse_rng(&self, p: u64) -> SplitMix64 {
        SplitMix64::new(mix_seed(self.seed ^ STREAM_PULSES, p))
    }

    /// Lays the `count` pulses of the scan pattern in order; gives their total returns.
    fn lay_pulses(&self, pattern: &Pattern, pulses: &mut Vec<Pulse>) -> u64 {
        pulses.clear();
        pulses.reserve(pattern.count as usize);
        let mut total = 0u64;
        pattern.for_each(|p, line, k| {
            let mut rng = self.pulse_rng(p);
            let (x, y) = pattern.position(self, line, k, rng.next_u64());
            let (hit, returns) = self.pulse(x, y, rng.next_u64());
            total += returns as u64;
            pulses.push(Pulse {
                x: x as i32,
                y: y as i32,
                hit,
                returns,
            });
        });
        total
    }

    /// Scans the tile: lays pulses until they give at least `wanted` returns, then keeps a
    /// uniform selection of exactly `wanted` returns (dropped ones read as weak returns).
    fn scan(&self, out: &mut PointBatch, wanted: u64, pulses: &mut Vec<Pulse>) {
        let estimate = wanted as f64 / self.mean_returns() * PULSE_MARGIN;
        let mut pattern = Pattern::new(self, (estimate as u64 + 16).min(wanted));
        let mut total = self.lay_pulses(&pattern, pulses);
        // Every pulse gives at least one return, so `wanted` pulses always suffice.
        while total < wanted {
            let more = pattern.count + pattern.count / 8 + 16;
            pattern = Pattern::new(self, more.min(wanted));
            total = self.lay_pulses(&pattern, pulses);
        }
        let mut thin = SplitMix64::new(mix_seed(self.seed, STREAM_THINNING));
        let (mut left, mut need) = (total, wanted);
        let mut rets = [Return::default(); 4];
        pattern.for_each(|p, line, k| {
            let pulse = pulses[p as usize];
            let mut keep = 0u8;
            for r in 0..pulse.returns {
                if thin.below(left) < need {
                    keep |= 1 << r;
                    need -= 1;
                }
                left -= 1;
            }
            if keep == 0 {
                return;
            }
            let mut rng = self.pulse_rng(p);
            rng.next_u64();
            rng.next_u64();
            let n = self.returns(&pulse, &mut rng, &mut rets) as usize;
            let info = pattern.info(self, line, k);
            let kept = keep.count_ones() as u8;
            let mut number = 0u8;
            for (r, ret) in rets.iter().take(n).enumerate() {
                if keep & (1 << r) != 0 {
                    number += 1;
                    self.push(out, ret, &info, [number, kept]);
                }
            }
        });
    }

    /// The returns of one pulse, first to last; gives how many.
    fn returns(&self, p: &Pulse, rng: &mut SplitMix64, rets: &mut [Return; 4]) -> u8 {
        let (x, y) = (p.x as i64, p.y as i64);
        let cell = self.cell_of(x, y);
        let g = self.ground_z(x, y, cell);
        let bits = rng.next_u64();
        let jitter = |shift: u32| ((bits >> shift) & 0xFFFF) as f64 / 65536.0;
        let mut ret = |i: usize, mm: [i64; 3], class: u8, m: Material| {
            rets[i] = Return {
                mm,
                class,
                bits: rng.next_u64(),
                rgb: m.rgb,
                intensity: m.intensity,
            };
        };
        let at = |z: f64| [x, y, to_mm(z)];
        match p.hit {
            Hit::Ground => {
                let (class, m, z) = self.surface(x, y, cell, g, jitter(0));
                ret(0, at(z), class, m);
                1
            }
            Hit::Noise => {
                let (class, z) = if jitter(0) < 0.7 {
                    (class::LOW_NOISE, g - 1.0 - 7.0 * jitter(16))
                } else {
                    (class::HIGH_NOISE, g + 15.0 + 33.0 * jitter(16))
                };
                ret(0, at(z), class, NOISE);
                1
            }
            Hit::Roof(b) | Hit::RoofEdge(b) => {
                let b = &self.buildings[b as usize];
                let (_, ly) = b.local_of(x as f64 * MM, y as f64 * MM);
                let roughness = if b.slope > 0.0 { 0.03 } else { 0.015 };
                let z = b.roof_z(ly) + roughness * (jitter(0) - 0.5);
                ret(0, at(z), class::BUILDING, b.roof);
                if p.returns < 2 {
                    return 1;
                }
                let (class, m, z) = self.surface(x, y, cell, g, jitter(16));
                ret(1, at(z), class, m);
                2
            }
            Hit::Wall(b) => {
                let b = &self.buildings[b as usize];
                let (lx, ly) = b.local_of(x as f64 * MM, y as f64 * MM);
                let (wx, wy) = (lx.clamp(-b.hx, b.hx), ly.clamp(-b.hy, b.hy));
                let (xw, yw) = b.world_of(wx, wy);
                let foot = g.min(b.base);
                let z = foot + (b.roof_z(wy) - foot) * jitter(0);
                ret(0, [to_mm(xw), to_mm(yw), to_mm(z)], class::BUILDING, WALL);
                1
            }
            Hit::Veg(v) => {
                let under = Spot { x, y, cell, g };
                self.veg_returns(&self.vegs[v as usize], p.returns, under, bits, rng, rets)
            }
        }
    }

    /// Crown, inner canopy, trunk and ground returns of a pulse through a plant.
    fn veg_returns(
        &self,
        v: &Veg,
        n: u8,
        at: Spot,
        bits: u64,
        rng: &mut SplitMix64,
        rets: &mut [Return; 4],
    ) -> u8 {
        let Spot { x, y, cell, g } = at;
        let (xm, ym) = (x as f64 * MM, y as f64 * MM);
        let jitter = |shift: u32| ((bits >> shift) & 0xFFFF) as f64 / 65536.0;
        let d2 = dist2(v.cx, v.cy, xm, ym);
        let n = n as usize;
        let veg_class = |z: f64| {
            let above = z - g;
            if above < 0.5 {
                class::LOW_VEGETATION
            } else if above < 2.0 {
                class::MEDIUM_VEGETATION
            } else {
                class::HIGH_VEGETATION
            }
        };
        let mut z = (v.top_z(d2) - 0.4 * jitter(0)).max(g + 0.05);
        rets[0] = Return {
            mm: [x, y, to_mm(z)],
            class: veg_class(z),
            bits: rng.next_u64(),
            rgb: v.look.rgb,
            intensity: v.look.intensity,
        };
        if n == 1 {
            return 1;
        }
        // The last return reaches the ground 70 % of the time, else stops in the undergrowth.
        let last_on_ground = v.kind == VegKind::Shrub || jitter(16) < 0.7;
        let floor = g + v.crown_base.max(0.3);
        let inner = n - 1 - last_on_ground as usize;
        let near_stem = d2 < sq(v.trunk_radius + 0.6) && v.kind != VegKind::Shrub;
        for (i, r) in rets.iter_mut().enumerate().take(inner + 1).skip(1) {
            let u = ((bits >> (32 + 8 * i)) & 0xFF) as f64 / 256.0;
            let bits = rng.next_u64();
            if near_stem && i == inner {
                // The trunk: on the stem's surface, facing the pulse, under the crown.
                let s = v.trunk_radius / d2.sqrt().max(1e-3);
                let tz = v.ground + 0.3 + (v.crown_base - 0.3).max(0.0) * u;
                *r = Return {
                    mm: [
                        to_mm(v.cx + (xm - v.cx) * s),
                        to_mm(v.cy + (ym - v.cy) * s),
                        to_mm(tz),
                    ],
                    class: class::HIGH_VEGETATION,
                    bits,
                    rgb: TRUNK.rgb,
                    intensity: TRUNK.intensity,
                };
                continue;
            }
            // Descending through the canopy (or undergrowth below it for the last one).
            let low = if i == n - 1 { g + 0.2 } else { floor };
            z = (z - (z - low).max(0.0) * (0.25 + 0.5 * u)).max(low);
            *r = Return {
                mm: [x, y, to_mm(z)],
                class: veg_class(z),
                bits,
                rgb: v.look.rgb,
                intensity: v.look.intensity * 0.6,
            };
        }
        if last_on_ground {
            let bits = rng.next_u64();
            let u = (bits >> 40) as f64 / 16_777_216.0;
            let (class, m, gz) = self.surface(x, y, cell, g, u);
            rets[n - 1] = Return {
                mm: [x, y, to_mm(gz)],
                class,
                bits,
                rgb: if class == class::GROUND {
                    LITTER.rgb
                } else {
                    m.rgb
                },
                intensity: m.intensity * 0.5,
            };
        }
        n as u8
    }

    /// The bare surface at a spot: water, road (with its center line) or ground.
    fn surface(&self, x: i64, y: i64, cell: Cell, g: f64, u: f64) -> (u8, Material, f64) {
        let (xm, ym) = (x as f64 * MM, y as f64 * MM);
        let on_road = |centers: &[f64], v: f64| {
            centers
                .iter()
                .map(|c| (v - c).abs())
                .find(|d| *d <= ROAD_HALF_WIDTH_M)
        };
        let road = on_road(&self.roads_x, xm)
            .map(|d| (d, ym))
            .or_else(|| on_road(&self.roads_y, ym).map(|d| (d, xm)));
        if let Some((d, along)) = road {
            let m = if d < MARKING_HALF_WIDTH_M && along.rem_euclid(9.0) < 3.0 {
                MARKING
            } else {
                ASPHALT
            };
            // Roads cross lakes on causeways.
            let deck = g.max(self.scene.water_level + 0.5);
            return (class::ROAD, m, deck + 0.01 * (u - 0.5));
        }
        if g < self.scene.water_level {
            return (
                class::WATER,
                WATER,
                self.scene.water_level + 0.04 * (u - 0.5),
            );
        }
        (class::GROUND, self.ground[cell.index], g + 0.06 * (u - 0.5))
    }

    /// Writes return `number[0]` of `number[1]`, clamped into the scene's bounds.
    fn push(&self, out: &mut PointBatch, r: &Return, p: &PulseInfo, number: [u8; 2]) {
        let side = self.scene.side_mm;
        // Stay strictly inside the corners, which belong to the anchor points.
        let raw = [
            r.mm[0].clamp(0, side - 1) as i32,
            r.mm[1].clamp(0, side - 1) as i32,
            r.mm[2].clamp(1, top_mm() - 1) as i32,
        ];
        out.xyz.push(self.scene.quantization.dequantize(raw));
        let b = r.bits;
        let unit = |shift: u32| ((b >> shift) & 0xFF) as f32 * (1.0 / 255.0);
        let bright = 0.88 + 0.24 * ((b & 0xFFFF) as f32 * (1.0 / 65535.0));
        let rgb = [0, 1, 2].map(|c| {
            let v = r.rgb[c] * bright + 8.0 * (unit(16 + 8 * c as u32) - 0.5);
            (v.clamp(0.0, 255.0) * 257.0) as u16
        });
        // Later returns carry less of the pulse's energy.
        let fade = if number[0] > 1 { 0.7 } else { 1.0 };
        let noise = 0.85 + 0.3 * ((b >> 48) as f32 * (1.0 / 65535.0));
        let intensity = (r.intensity * noise * p.falloff * fade).clamp(0.0, 65535.0) as u16;
        out.intensity.push(intensity);
        out.returns.push((number[1] << 4) | number[0]);
        out.flags.push(p.flags);
        out.classification.push(r.class);
        out.scan_angle.push(p.angle);
        out.user_data.push(0);
        out.point_source_id.push(self.source);
        out.gps_time.push(p.time);
        out.rgb.push(rgb);
    }

    /// The scene's corner points: low noise at the bounds' minimum, high noise at the maximum,
    /// timed at the tile's first and last instant.
    fn push_anchor(&self, out: &mut PointBatch, high: bool) {
        let q = &self.scene.quantization;
        let side = self.scene.side_mm as i32;
        let (raw, class) = if high {
            ([side, side, top_mm() as i32], class::HIGH_NOISE)
        } else {
            ([0, 0, 0], class::LOW_NOISE)
        };
        let y = if high == self.north {
            self.y[1]
        } else {
            self.y[0]
        };
        let (angle, _) = self.scan_angle(raw[0] as i64);
        out.xyz.push(q.dequantize(raw));
        out.intensity.push(NOISE.intensity as u16);
        out.returns.push(0x11);
        out.flags.push(0);
        out.classification.push(class);
        out.scan_angle.push(angle);
        out.user_data.push(0);
        out.point_source_id.push(self.source);
        out.gps_time.push(self.time_at(y as f64 * MM));
        out.rgb.push(NOISE.rgb.map(|c| (c * 257.0) as u16));
    }

    /// GPS time when the aircraft passes northing `y` (metres from the corner) on this strip.
    fn time_at(&self, y: f64) -> f64 {
        let along = if self.north { y } else { self.scene.side_m - y };
        self.strip_time + along / AIRCRAFT_SPEED_M_S
    }

    /// Scan angle (whole degrees, negative left of the aircraft) at easting `x_mm`, and the
    /// intensity falloff that comes with it.
    fn scan_angle(&self, x_mm: i64) -> (f32, f32) {
        let cross = (x_mm as f64 * MM - self.strip_center_m) * self.inv_flying_height;
        let deg = atan_deg(cross.clamp(-TAN_MAX_SCAN, TAN_MAX_SCAN));
        let deg = if self.north { deg } else { -deg };
        let deg = (round_i64(deg) as f64).clamp(-MAX_SCAN_DEG, MAX_SCAN_DEG);
        let falloff = 1.0 - 0.3 * deg * deg * (1.0 / (MAX_SCAN_DEG * MAX_SCAN_DEG));
        (deg as f32, falloff as f32)
    }
}

/// A lookup cell: its column, row and index.
#[derive(Clone, Copy)]
struct Cell {
    i: usize,
    j: usize,
    index: usize,
}

/// Where a pulse meets the ground.
#[derive(Clone, Copy)]
struct Spot {
    x: i64,
    y: i64,
    cell: Cell,
    g: f64,
}

/// The tile's scan pattern: `lines` scan lines across the tile in flight order, each with
/// `base` or `base + 1` pulses, alternating direction like an oscillating mirror.
struct Pattern {
    count: u64,
    lines: u64,
    base: u64,
    extra: u64,
    north: bool,
    /// Millimetres between lines, and between pulses of a line of `base` or `base + 1` pulses.
    line_mm: f64,
    pulse_mm: [f64; 2],
    /// GPS time of the first line's first pulse, then steps per line and per pulse.
    time0: f64,
    line_s: f64,
    pulse_s: [f64; 2],
    /// Scan angle and intensity falloff per column of a line of `base` or `base + 1` pulses:
    /// the mirror's angle at the nominal position of the pulse.
    angles: [Vec<(f32, f32)>; 2],
}

impl Pattern {
    fn new(plan: &Plan, count: u64) -> Pattern {
        let w = (plan.x[1] - plan.x[0]) as f64;
        let h = (plan.y[1] - plan.y[0]) as f64;
        let spacing = (w * h / count.max(1) as f64).sqrt();
        let lines = (round_i64(h / spacing).max(1) as u64).min(count.max(1));
        let base = count / lines;
        let line_mm = h / lines as f64;
        let line_s = line_mm * MM / AIRCRAFT_SPEED_M_S;
        let per_line = [base.max(1) as f64, (base + 1) as f64];
        let first_y = if plan.north {
            plan.y[0] as f64 + 0.5 * line_mm
        } else {
            plan.y[1] as f64 - 0.5 * line_mm
        };
        let pulse_mm = per_line.map(|n| w / n);
        let angles = [0, 1].map(|long| {
            (0..base + long)
                .map(|col| {
                    let x = plan.x[0] as f64 + (col as f64 + 0.5) * pulse_mm[long as usize];
                    plan.scan_angle(round_i64(x))
                })
                .collect()
        });
        Pattern {
            count,
            lines,
            base,
            extra: count % lines,
            north: plan.north,
            line_mm,
            pulse_mm,
            time0: plan.time_at(first_y * MM),
            line_s,
            pulse_s: per_line.map(|n| line_s / n),
            angles,
        }
    }

    /// Calls `f(pulse index, line, index in line)` in scan order.
    fn for_each(&self, mut f: impl FnMut(u64, Line, u64)) {
        let mut p = 0;
        for index in 0..self.lines {
            let long = index < self.extra;
            let line = Line {
                index,
                pulses: self.base + long as u64,
                long,
            };
            for k in 0..line.pulses {
                f(p, line, k);
                p += 1;
            }
        }
    }

    /// Column (west to east) of pulse `k` of `line`.
    fn column(line: Line, k: u64) -> u64 {
        if line.left_to_right() {
            k
        } else {
            line.pulses - 1 - k
        }
    }

    /// Jittered position (mm) of pulse `k` of `line`.
    fn position(&self, plan: &Plan, line: Line, k: u64, bits: u64) -> (i64, i64) {
        let row = if self.north {
            line.index
        } else {
            self.lines - 1 - line.index
        };
        let col = Self::column(line, k);
        let jx = (bits & 0xFFFF_FFFF) as f64 * (1.0 / 4_294_967_296.0) - 0.5;
        let jy = (bits >> 32) as f64 * (1.0 / 4_294_967_296.0) - 0.5;
        let x =
            plan.x[0] as f64 + (col as f64 + 0.5 + 0.7 * jx) * self.pulse_mm[line.long as usize];
        let y = plan.y[0] as f64 + (row as f64 + 0.5 + 0.7 * jy) * self.line_mm;
        (
            round_i64(x).clamp(plan.x[0], plan.x[1] - 1),
            round_i64(y).clamp(plan.y[0], plan.y[1] - 1),
        )
    }

    /// Time, angle and flags of pulse `k` of `line`.
    fn info(&self, plan: &Plan, line: Line, k: u64) -> PulseInfo {
        let ltr = line.left_to_right();
        let mut flags = 0;
        // Scan direction is positive when the mirror sweeps left to right of the aircraft.
        if ltr == self.north {
            flags |= flags::SCAN_DIRECTION;
        }
        // The last pulse before the mirror turns, at the swath's edge.
        if k + 1 == line.pulses && plan.strip_edge[ltr as usize] {
            flags |= flags::EDGE_OF_FLIGHT_LINE;
        }
        let angles = &self.angles[line.long as usize];
        let (angle, falloff) = angles[(Self::column(line, k) as usize).min(angles.len() - 1)];
        PulseInfo {
            time: self.time0
                + line.index as f64 * self.line_s
                + k as f64 * self.pulse_s[line.long as usize],
            angle,
            flags,
            falloff,
        }
    }
}

/// One scan line of a tile's pattern.
#[derive(Clone, Copy)]
struct Line {
    index: u64,
    pulses: u64,
    /// Has `base + 1` pulses.
    long: bool,
}

impl Line {
    fn left_to_right(&self) -> bool {
        self.index.is_multiple_of(2)
    }
}

fn to_mm(v: f64) -> i64 {
    round_i64(v * 1000.0)
}

/// Nearest integer (ties to even) for |v| < 2^51, by the exact IEEE-754 add-and-subtract of
/// 1.5 · 2^52: libm's `round` is a function call on baseline x86-64.
fn round_i64(v: f64) -> i64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    ((v + SHIFT) - SHIFT) as i64
}

/// `floor(v)` without a libm call.
fn floor_i64(v: f64) -> i64 {
    let i = v as i64;
    i - (v < i as f64) as i64
}

fn sq(v: f64) -> f64 {
    v * v
}

fn dist2(ax: f64, ay: f64, bx: f64, by: f64) -> f64 {
    sq(ax - bx) + sq(ay - by)
}

fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn mix(a: Material, b: Material, t: f64) -> Material {
    let t = t as f32;
    Material {
        rgb: [0, 1, 2].map(|c| a.rgb[c] + (b.rgb[c] - a.rgb[c]) * t),
        intensity: a.intensity + (b.intensity - a.intensity) * t,
    }
}

/// `floor(v)` or `floor(v) + 1` with probability `frac(v)`.
fn stochastic_round(v: f64, rng: &mut SplitMix64) -> u64 {
    let v = v.max(0.0);
    let f = floor_i64(v);
    f as u64 + (rng.unit_f64() < v - f as f64) as u64
}

/// Degrees of atan(z) for |z| ≤ tan 30°, by its Taylor series (error < 0.002°), so the result
/// does not depend on a platform's libm.
fn atan_deg(z: f64) -> f64 {
    const INV_ODD: [f64; 8] = [
        1.0,
        1.0 / 3.0,
        1.0 / 5.0,
        1.0 / 7.0,
        1.0 / 9.0,
        1.0 / 11.0,
        1.0 / 13.0,
        1.0 / 15.0,
    ];
    let z2 = z * z;
    let s = INV_ODD.iter().rev().fold(0.0, |s, c| c - z2 * s);
    z * s * (180.0 / std::f64::consts::PI)
}

/// A uniform value in [0, 1) for a lattice point.
fn lattice(seed: u64, i: i64, j: i64) -> f64 {
    let h = mix_seed(
        seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        j as u64,
    );
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Value noise in [0, 1): lattice values blended with a smooth (C1) weight.
fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (i, j) = (floor_i64(x), floor_i64(y));
    let (tx, ty) = (smoothstep(x - i as f64), smoothstep(y - j as f64));
    let a = lattice(seed, i, j);
    let b = lattice(seed, i + 1, j);
    let c = lattice(seed, i, j + 1);
    let d = lattice(seed, i + 1, j + 1);
    let lo = a + (b - a) * tx;
    let hi = c + (d - c) * tx;
    lo + (hi - lo) * ty
}

/// Octaves of value noise, `(wavelength m, weight)` with weights summing to 1: in [0, 1).
fn fbm(seed: u64, x: f64, y: f64, octaves: &[(f64, f64)]) -> f64 {
    octaves
        .iter()
        .enumerate()
        .map(|(k, (wl, w))| w * value_noise(seed.wrapping_add(k as u64), x / wl, y / wl))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan_matches_std_within_a_hundredth_of_a_degree() {
        for i in -100..=100 {
            let z = TAN_MAX_SCAN * i as f64 / 100.0;
            let want = z.atan().to_degrees();
            assert!(
                (atan_deg(z) - want).abs() < 0.01,
                "{z}: {} vs {want}",
                atan_deg(z)
            );
        }
        assert!((atan_deg(TAN_MAX_SCAN) - 30.0).abs() < 0.01);
    }

    #[test]
    fn noise_stays_in_unit_range_and_is_continuous() {
        let mut prev = value_noise(9, 0.0, 3.3);
        for i in 1..2000 {
            let x = i as f64 * 0.01;
            let v = value_noise(9, x, 3.3);
            assert!((0.0..1.0).contains(&v));
            assert!((v - prev).abs() < 0.03, "jump at {x}");
            prev = v;
            let f = fbm(4, x * 50.0, -x * 70.0, &TERRAIN_OCTAVES);
            assert!((0.0..1.0).contains(&f));
        }
    }

    #[test]
    fn tiles_share_points_by_area_and_cover_the_scene_once() {
        for points in [1u64, 2, 999, 123_457, 3_000_000] {
            let s = Scene::new(SceneConfig { points, seed: 1 });
            let mut walk = TileWalk::default();
            let mut seen = std::collections::HashSet::new();
            let mut sum = 0;
            while let Some(j) = walk.next(&s) {
                assert!(seen.insert((j.col, j.row)), "tile visited twice");
                sum += j.points;
            }
            assert_eq!(sum, points);
            assert_eq!(seen.len() as u64, s.tiles_per_side * s.tiles_per_side);
        }
    }

    #[test]
    fn absurd_counts_keep_tiles_small() {
        let s = Scene::new(SceneConfig {
            points: u64::MAX,
            seed: 1,
        });
        assert_eq!(s.side_mm, MAX_SIDE_MM);
        assert!(s.mean_tile_points() as u64 <= MAX_TILE_POINTS);
        let job = TileWalk::default().next(&s).expect("a first tile");
        assert!(job.points <= MAX_TILE_POINTS + 1, "{job:?}");
        let g = SceneGenerator::new(SceneConfig {
            points: u64::MAX,
            seed: 1,
        });
        let batch = g.reader().read_batch(1000).expect("batch").expect("points");
        assert_eq!(batch.len(), 1000);
        assert!(batch.xyz.iter().all(|p| g.meta().bounds.contains(*p)));
    }

    #[test]
    fn geokeys_name_the_utm_code() {
        let v = geokey_vlr();
        assert!(v.is_crs());
        let words: Vec<u16> = v
            .data
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        assert_eq!(words[3] as usize, words.len() / 4 - 1);
        assert!(words.chunks(4).any(|k| k[0] == 3072 && k[3] == EPSG_UTM));
    }
}
