//! Arguments shared by the commands that draw: camera, rasterizer, screen passes, adapter.

use anyhow::{bail, Result};
use pointlet_core::color::ColorMode;
use pointlet_core::order::VertexOrder;
use pointlet_core::{Aabb, Camera};
use pointlet_gpu::{
    EdlSettings, OcclusionSettings, PointEncoding, PointSize, RasterVariant, RenderSettings,
    ScreenSettings, SplatRaster, SplatSettings, SplatShape,
};
use std::path::Path;

#[derive(clap::Args, Clone, Debug)]
pub struct CameraArgs {
    /// Predefined view: `overview` (all data from above at an angle) or `closeup`.
    #[arg(long, default_value = "overview", value_parser = ["overview", "closeup"])]
    pub view: String,
    /// Eye position in the data's coordinates, `x,y,z` (with --target: overrides --view).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<[f64; 3]>,
    /// Point looked at, `x,y,z`.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<[f64; 3]>,
    /// With --eye/--target: up direction, `x,y,z` (data is z-up by default).
    #[arg(
        long,
        value_parser = parse_vec3,
        default_value = "0,0,1",
        allow_hyphen_values = true,
        requires = "eye"
    )]
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 60.0)]
    pub fov: f64,
}

impl CameraArgs {
    /// True when `--eye`/`--target` place the camera (rather than a predefined view).
    pub fn placed(&self) -> bool {
        self.eye.is_some() || self.target.is_some()
    }

    pub fn camera(&self, bounds: &Aabb) -> Result<Camera> {
        let mut cam = match self.view.as_str() {
            "closeup" => Camera::closeup(bounds, self.fov),
            _ => Camera::overview(bounds, self.fov),
        };
        match (self.eye, self.target) {
            (Some(eye), Some(target)) => {
                cam.eye = eye;
                cam.target = target;
                cam.up = self.up;
                cam.fit_planes(bounds);
            }
            (None, None) => {}
            _ => bail!("--eye and --target go together"),
        }
        cam.fov_y_deg = self.fov;
        cam.validate()?;
        Ok(cam)
    }
}

#[derive(clap::Args, Clone, Debug)]
pub struct DrawArgs {
    /// Rasterizer: hw-points, atomic-min, early-z, reduce, reduce-early-z, dedup, hqs, hqs1r,
    /// atomic-min-32.
    #[arg(long, default_value = "reduce-early-z", value_parser = parse_variant)]
    pub raster: RasterVariant,
    /// GPU point encoding: full16 (f32 xyz + RGBA8) or compact8 (quantized, 8 bytes).
    #[arg(long, default_value = "full16", value_parser = parse_encoding)]
    pub encoding: PointEncoding,
    /// Order of the points in GPU memory: original, morton, shuffled, shuffled-morton, hilbert.
    #[arg(long, default_value = "original", value_parser = parse_order)]
    pub order: VertexOrder,
    /// Colour by: rgb, intensity, elevation, classification, return-number, point-source-id,
    /// gps-time, scan-angle, user-data, nir, or extra:NAME (an extra-bytes attribute, as
    /// `info` lists them) (default: RGB where the data has colours, else intensity, else
    /// elevation).
    #[arg(long, value_parser = parse_color)]
    pub color: Option<ColorArg>,
    /// Eye-Dome Lighting.
    #[arg(long)]
    pub edl: bool,
    /// With --edl: how dark the shading gets.
    #[arg(long, default_value_t = 1.0, requires = "edl")]
    pub edl_strength: f32,
    /// With --edl: the radius in pixels of the neighbours it compares depths with.
    #[arg(long, default_value_t = 1.4, requires = "edl")]
    pub edl_radius: f32,
    /// Hole filling radius in pixels (0 = off).
    #[arg(long, default_value_t = 0)]
    pub fill: u32,
    /// Occlusion filter: drop points seen through gaps of nearer surfaces (paper eq. 4).
    #[arg(long)]
    pub occlusion: bool,
    /// With --occlusion: pixels the filter searches in each direction.
    #[arg(long, default_value_t = 3, requires = "occlusion")]
    pub occlusion_radius: u32,
    /// Background colour, `r,g,b` (0–255) or `#rrggbb`.
    #[arg(long, default_value = "0,0,0", value_parser = parse_color_rgb)]
    pub background: [f32; 4],
    /// GPU adapter: an index or part of the name (default: the best one).
    #[arg(long)]
    pub adapter: Option<String>,
    /// Points per GPU page (power of two, 256–65536).
    #[arg(long, default_value_t = 4096)]
    pub page_size: u32,
    /// Draw a store as point files are drawn: every point, read while drawing, no LoD (a
    /// closest-point --raster).
    #[arg(long)]
    pub progressive: bool,
    /// Point size: pixels (1–32), or `adaptive` (the spacing of the points drawn, seen at their
    /// depth: a store's pointlets drawn at a fraction of their points get larger splats;
    /// `adaptive:SCALE` for splats SCALE spacings wide, default 1.25). Default: adaptive for
    /// stores, 1 for point files and the demo scene.
    #[arg(long, value_parser = PointSize::parse)]
    pub point_size: Option<PointSize>,
    /// Shape of points larger than a pixel: square or circle.
    #[arg(long, default_value = "square", value_parser = parse_shape)]
    pub splat_shape: SplatShape,
    /// How points larger than a pixel are drawn: `compute` (each rasterizer walks the
    /// footprint) or `quads` (billboard quads through the render pipeline; closest-point
    /// rasterizers, stores and point files drawn whole).
    #[arg(long, default_value = "compute", value_parser = parse_splat_raster)]
    pub splat_raster: SplatRaster,
}

impl DrawArgs {
    /// The renderer's settings for `variant` (the resolved `--raster`) and these screen passes.
    /// The renderer's settings for `variant` (the resolved `--raster`) drawing `input`.
    pub fn settings_for(&self, variant: RasterVariant, input: Option<&Path>) -> RenderSettings {
        RenderSettings {
            variant,
            screen: self.screen(),
            splats: self.splats_for(input),
            ..Default::default()
        }
    }

    /// Point size and shape for `input`: `--point-size` (default: adaptive for a store drawn
    /// through its LoD, whose pointlets are drawn at a fraction of their points, and for a
    /// streamed tileset, whose coarse tiles and filtered points are sparse; one pixel for
    /// point files, which are drawn whole) and `--splat-shape`.
    pub fn splats_for(&self, input: Option<&Path>) -> SplatSettings {
        let store = input.is_some_and(crate::load::is_store_path) && !self.progressive;
        let tileset = input.is_some_and(|p| {
            !crate::load::is_several(p) && pointlet_tiles::points::is_tileset_path(p)
        });
        let default = if store || tileset {
            PointSize::adaptive()
        } else {
            PointSize::Fixed(1)
        };
        SplatSettings {
            size: self.point_size.unwrap_or(default),
            shape: self.splat_shape,
            raster: self.splat_raster,
        }
    }

    pub fn screen(&self) -> ScreenSettings {
        ScreenSettings {
            occlusion: self.occlusion.then_some(OcclusionSettings {
                radius: self.occlusion_radius,
                ..Default::default()
            }),
            fill_radius: self.fill,
            edl: self.edl.then_some(EdlSettings {
                strength: self.edl_strength,
                radius: self.edl_radius,
            }),
            background: self.background,
        }
    }
}

/// Budgets and LoD of the virtualized renderer (stores).
#[derive(clap::Args, Clone, Debug)]
pub struct VirtualArgs {
    /// The LoD's point bucket B: points drawn per frame while the camera moves.
    #[arg(long, default_value = "25M", value_parser = crate::parse_bucket_arg)]
    pub bucket: u64,
    /// GPU memory for points, tables and framebuffers (default 2GiB).
    #[arg(long, value_parser = crate::parse_bytes_arg)]
    pub vram_budget: Option<u64>,
    /// RAM for cached points (default: a quarter of the available memory).
    #[arg(long, value_parser = crate::parse_bytes_arg)]
    pub ram_budget: Option<u64>,
    /// Points moved from RAM to the GPU per frame at most.
    #[arg(long, default_value = "1M", value_parser = crate::parse_count_arg)]
    pub upload_per_frame: u64,
    /// Points per GPU page of the virtualized pool.
    #[arg(long, default_value_t = 256)]
    pub pool_page_size: u32,
    /// Loader threads reading from disk.
    #[arg(long, default_value_t = 4)]
    pub loaders: usize,
    /// Threads of the per-frame residency work (0: half the cores).
    #[arg(long, default_value_t = 0)]
    pub residency_threads: usize,
    /// A moving camera's frame starts from the last frame reprojected, the LoD filling in.
    #[arg(long)]
    pub temporal_reuse: bool,
}

impl VirtualArgs {
    /// The engine's settings, colouring by `color`.
    pub fn config(&self, draw: &DrawArgs, color: ColorMode) -> pointlet_engine::SceneConfig {
        pointlet_engine::SceneConfig {
            vram_budget: self.vram_budget.unwrap_or(2 << 30),
            ram_budget: self.ram_budget.unwrap_or_else(default_ram_budget),
            bucket: self.bucket as f64,
            encoding: draw.encoding,
            page_size: self.pool_page_size,
            loaders: self.loaders,
            threads: self.residency_threads,
            upload_per_frame: self.upload_per_frame,
            color,
            temporal_reuse: self.temporal_reuse,
        }
    }
}

/// A quarter of the memory available now (at least 256 MiB).
pub fn default_ram_budget() -> u64 {
    crate::available_memory()
        .map(|a| a / 4)
        .unwrap_or(1 << 30)
        .max(256 << 20)
}

pub fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| "expected three numbers x,y,z".to_string())?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err("expected three finite numbers x,y,z".to_string()),
    }
}

fn names<T: Copy>(all: &[T], name: fn(T) -> &'static str) -> String {
    all.iter().map(|v| name(*v)).collect::<Vec<_>>().join(", ")
}

pub fn parse_variant(s: &str) -> Result<RasterVariant, String> {
    RasterVariant::parse(s).ok_or_else(|| {
        format!(
            "unknown rasterizer (one of: {})",
            names(&RasterVariant::ALL, RasterVariant::name)
        )
    })
}

pub fn parse_shape(s: &str) -> Result<SplatShape, String> {
    SplatShape::parse(s).ok_or_else(|| {
        format!(
            "unknown splat shape (one of: {})",
            names(&SplatShape::ALL, SplatShape::name)
        )
    })
}

pub fn parse_splat_raster(s: &str) -> Result<SplatRaster, String> {
    SplatRaster::parse(s).ok_or_else(|| {
        format!(
            "unknown splat rasterizer (one of: {})",
            names(&SplatRaster::ALL, SplatRaster::name)
        )
    })
}

pub fn parse_encoding(s: &str) -> Result<PointEncoding, String> {
    PointEncoding::parse(s).ok_or_else(|| {
        format!(
            "unknown encoding (one of: {})",
            names(&PointEncoding::ALL, PointEncoding::name)
        )
    })
}

pub fn parse_order(s: &str) -> Result<VertexOrder, String> {
    VertexOrder::parse(s).ok_or_else(|| {
        format!(
            "unknown order (one of: {})",
            names(&VertexOrder::ALL, VertexOrder::name)
        )
    })
}

/// What `--color` asks for: a colour mode, or an extra-bytes attribute by name, which only
/// the data can resolve ([`crate::scene::choose_color`]).
#[derive(Clone, Debug, PartialEq)]
pub enum ColorArg {
    Mode(ColorMode),
    Extra(String),
}

pub fn parse_color(s: &str) -> Result<ColorArg, String> {
    if let Some(name) = s.strip_prefix("extra:") {
        if name.is_empty() {
            return Err("extra: needs the attribute's name, as `info` lists it".into());
        }
        return Ok(ColorArg::Extra(name.to_string()));
    }
    ColorMode::parse(s).map(ColorArg::Mode).ok_or_else(|| {
        format!(
            "unknown colouring (one of: {}, extra:NAME)",
            names(&ColorMode::ALL, ColorMode::name)
        )
    })
}

pub fn parse_color_rgb(s: &str) -> Result<[f32; 4], String> {
    let err = || "expected r,g,b (0–255) or #rrggbb".to_string();
    let rgb: Vec<u8> = if let Some(hex) = s.strip_prefix('#') {
        if hex.len() != 6 {
            return Err(err());
        }
        (0..3)
            .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16))
            .collect::<Result<_, _>>()
            .map_err(|_| err())?
    } else {
        s.split(',')
            .map(|t| t.trim().parse::<u8>())
            .collect::<Result<_, _>>()
            .map_err(|_| err())?
    };
    match rgb.as_slice() {
        [r, g, b] => Ok([*r as f32 / 255.0, *g as f32 / 255.0, *b as f32 / 255.0, 1.0]),
        _ => Err(err()),
    }
}

/// Streaming of a 3D Tiles tileset (one tileset input).
#[derive(clap::Args, Clone, Debug)]
pub struct TileArgs {
    /// Tiles are refined while their screen-space error exceeds this many pixels (0: every
    /// tile down to full detail).
    #[arg(long, default_value_t = 16.0, value_parser = parse_sse)]
    pub max_sse: f64,
    /// Draw every point of a drawn tile instead of the continuous-LoD filter's share.
    #[arg(long)]
    pub no_clod: bool,
    /// Tiles fetched and decoded at once.
    #[arg(long, default_value_t = 8)]
    pub tile_requests: usize,
}

fn parse_sse(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!(
            "'{s}' is not a screen-space error in pixels (a number ≥ 0)"
        )),
    }
}

impl TileArgs {
    pub fn config(
        &self,
        virtual_args: &VirtualArgs,
        color: Option<ColorMode>,
    ) -> pointlet_engine::TilesetConfig {
        pointlet_engine::TilesetConfig {
            max_sse: self.max_sse,
            clod: !self.no_clod,
            vram_budget: virtual_args.vram_budget.unwrap_or(2 << 30),
            ram_budget: virtual_args.ram_budget.unwrap_or_else(default_ram_budget),
            workers: self.tile_requests.max(1),
            color,
            ..Default::default()
        }
    }
}
