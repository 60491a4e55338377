//! Flags that do not apply to what a command was given are refused as usage errors, never
//! ignored: which flags each command's inputs and modes use, in one place. A flag counts as
//! given when it was typed (clap's value source), whatever its value.

use crate::view_args::{CameraArgs, DrawArgs};
use crate::Command;
use clap::parser::ValueSource;
use clap::ArgMatches;
use pointlet_gpu::RasterVariant;
use std::path::Path;

/// Flags of the virtualized renderer, which draws stores only.
const VIRTUAL: [&str; 8] = [
    "bucket",
    "temporal_reuse",
    "vram_budget",
    "ram_budget",
    "upload_per_frame",
    "pool_page_size",
    "loaders",
    "residency_threads",
];
/// Flags of in-memory drawing: a store keeps the order and pages it was built with.
const IN_MEMORY: [&str; 2] = ["order", "page_size"];
/// Flags of the point-file readers: a store carries its attributes.
const READING: [&str; 1] = ["columns"];
/// Flags that a point file drawn while it loads cannot use: its buffer keeps the shuffled
/// order and the full16 encoding.
const SHUFFLED: [&str; 2] = ["order", "encoding"];
/// Flags of the progressive path only.
const PROGRESSIVE: [&str; 1] = ["target_fps"];
/// Flags of a streamed tileset only.
const TILES: [&str; 3] = ["max_sse", "no_clod", "tile_requests"];
/// What a streamed tileset does not take: the store's LoD and pages, the progressive path's
/// loading, point-file reading, in-memory order and encodings (tiles are drawn as full16),
/// and the store-only measurements of `bench`.
const NOT_TILES: [&str; 18] = [
    "bucket",
    "temporal_reuse",
    "upload_per_frame",
    "pool_page_size",
    "loaders",
    "residency_threads",
    "no_converge",
    "progressive",
    "target_fps",
    "columns",
    "order",
    "page_size",
    "encoding",
    "demo_points",
    "quality",
    "buckets",
    "path_quality",
    "warmup",
];

/// A streamed tileset: its own flags, none of the other inputs'.
fn tileset(given: &Given, input: Option<&Path>, draw: &DrawArgs) -> Result<(), String> {
    given.refuse(
        &NOT_TILES,
        "stores, point files and the demo scene",
        "a tileset (streamed by screen-space error)",
    )?;
    if draw.raster == RasterVariant::HwPoints {
        return Err("--raster hw-points draws point files and the demo scene only; a tileset is drawn by the compute rasterizers (any other --raster)".into());
    }
    point_size(given, input, draw)
}

/// The flags of one subcommand typed on the command line.
pub struct Given<'a>(pub &'a ArgMatches);

impl Given<'_> {
    fn has(&self, id: &str) -> bool {
        // Subcommands share these checks without sharing every flag: an absent id is not given.
        self.0.try_contains_id(id).unwrap_or(false)
            && self.0.value_source(id) == Some(ValueSource::CommandLine)
    }

    /// Refuses any of `ids` that was typed: they apply to `to` only, not to `not_to`.
    fn refuse(&self, ids: &[&str], to: &str, not_to: &str) -> Result<(), String> {
        match ids.iter().find(|id| self.has(id)) {
            Some(id) => Err(format!(
                "--{} applies to {to} only, not to {not_to}",
                id.replace('_', "-")
            )),
            None => Ok(()),
        }
    }
}

/// What a drawing command was given to draw.
fn input_kind(input: Option<&Path>) -> &'static str {
    match input {
        Some(p) if crate::load::is_several(p) => {
            "several inputs (drawn together as one point file)"
        }
        Some(p) if crate::load::is_store_path(p) => "a store",
        Some(_) => "a point file",
        None => "the demo scene",
    }
}

/// The usage error for the first typed flag that does not apply, if any.
pub fn check(command: &Command, given: &Given) -> Result<(), String> {
    match command {
        Command::Render(a) if crate::tiles_cmd::is_streamed(&a.inputs) => {
            camera(given, &a.camera)?;
            tileset(given, a.input(), &a.draw)
        }
        Command::Bench(a) if crate::tiles_cmd::is_streamed(std::slice::from_ref(&a.store)) => {
            tileset(given, Some(&a.store), &a.draw)?;
            bench_flight(given, a)
        }
        Command::Render(a) => {
            given.refuse(&TILES, "a tileset", input_kind(a.input()))?;
            camera(given, &a.camera)?;
            let store_only = [&VIRTUAL[..], &["max_frames", "no_converge"]].concat();
            // Point files drawn while loading also take a VRAM budget and a frame limit.
            let also_progressive = ["vram_budget", "max_frames"];
            drawing(given, a.input(), &a.draw, &store_only, &also_progressive)
        }
        Command::View(a) if crate::tiles_cmd::is_streamed(&a.inputs) => {
            camera(given, &a.camera)?;
            tileset(given, a.input(), &a.draw)
        }
        Command::View(a) => {
            given.refuse(&TILES, "a tileset", input_kind(a.input()))?;
            camera(given, &a.camera)?;
            let store_only = ["vram_budget", "ram_budget", "bucket", "converge_timeout"];
            if !crate::progressive_cmd::is_progressive(a.input(), &a.draw) {
                given.refuse(
                    &PROGRESSIVE,
                    "point files drawn while they load",
                    input_kind(a.input()),
                )?;
            }
            drawing(
                given,
                a.input(),
                &a.draw,
                &store_only,
                &["vram_budget", "converge_timeout"],
            )
        }
        Command::Bench(a) if !crate::load::is_store_path(&a.store) || a.draw.progressive => {
            given.refuse(&TILES, "a tileset", input_kind(Some(&a.store)))?;
            progressive_flag(given, Some(&a.store), &a.draw)?;
            point_size(given, Some(&a.store), &a.draw)?;
            if crate::load::is_store_path(&a.store) {
                given.refuse(&READING, "point files", "a store")?;
            }
            let kind = "a point file (drawn while it loads)";
            given.refuse(
                &SHUFFLED,
                "point files drawn whole and the demo scene",
                kind,
            )?;
            given.refuse(
                &["quality", "buckets", "warmup", "path_quality"],
                "stores",
                kind,
            )?;
            let store_only: Vec<&str> = VIRTUAL
                .iter()
                .copied()
                .filter(|f| *f != "vram_budget")
                .collect();
            given.refuse(&store_only, "stores", kind)?;
            bench_flight(given, a)
        }
        Command::Bench(a) => {
            given.refuse(&TILES, "a tileset", "a store")?;
            store_drawing(given, a.draw.raster)?;
            point_size(given, Some(&a.store), &a.draw)?;
            temporal_reuse(given, Some(&a.store), &a.draw)?;
            given.refuse(&READING, "point files", "a store")?;
            given.refuse(&PROGRESSIVE, "point files", "a store")?;
            if a.quality {
                let flight = [
                    "path",
                    "frames",
                    "realtime",
                    "orbit_seconds",
                    "warmup",
                    "in_flight",
                    "plot",
                ];
                given.refuse(&flight, "the flight along a path", "--quality")?;
                given.refuse(&["path_quality"], "the flight along a path", "--quality")?;
            } else {
                given.refuse(&["buckets"], "--quality", "the flight along a path")?;
            }
            if a.path_quality.is_some() {
                given.refuse(
                    &["realtime", "warmup", "in_flight", "plot"],
                    "the timed flight",
                    "--path-quality (frames by number, each compared with full detail)",
                )?;
            }
            bench_flight(given, a)
        }
        Command::BenchRaster(a) if a.input.is_some() => given.refuse(
            &["points"],
            "the generated scene (without INPUT)",
            "a given input",
        ),
        Command::Generate(a) if is_las_path(&a.output) => given.refuse(
            &["ram_budget", "pointlets"],
            "a .pointlet output",
            "a LAS/LAZ output",
        ),
        Command::BenchRead(a) => {
            if a.inputs.iter().any(|p| !crate::load::is_store_path(p)) {
                given.refuse(&["staged"], "stores", "point files")?;
            }
            if a.color_only == Some(pointlet_core::color::ColorMode::Elevation) {
                given.refuse(
                    &["staged"],
                    "colourings made from stored columns",
                    "--color-only elevation (which needs decoded positions)",
                )?;
            }
            Ok(())
        }
        Command::Info(a) if crate::load::is_store_path(&a.input) => {
            given.refuse(&READING, "point files", "a store")
        }
        Command::Metrics(a) if crate::load::is_store_path(&a.input) => {
            given.refuse(&READING, "point files", "a store")
        }
        _ => Ok(()),
    }
}

/// The flight along a path: orbit flags only for the orbit, frames not with a realtime path.
fn bench_flight(given: &Given, a: &crate::bench_cmd::Args) -> Result<(), String> {
    if a.path != "orbit" {
        given.refuse(&["orbit_seconds"], "--path orbit", "a camera path file")?;
        if a.realtime {
            given.refuse(
                &["frames"],
                "the orbit and by-frame flights",
                "a camera path file flown with --realtime (its keyframes are used)",
            )?;
        }
    }
    Ok(())
}

fn is_las_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("las") || e.eq_ignore_ascii_case("laz"))
}

/// A camera placed by --eye/--target is not one of the predefined views.
fn camera(given: &Given, camera: &CameraArgs) -> Result<(), String> {
    if camera.eye.is_some() || camera.target.is_some() {
        given.refuse(
            &["view"],
            "the predefined views",
            "a camera placed by --eye/--target",
        )?;
    }
    Ok(())
}

/// `--progressive` draws stores only, with a closest-point rasterizer.
fn progressive_flag(given: &Given, input: Option<&Path>, draw: &DrawArgs) -> Result<(), String> {
    if !given.has("progressive") {
        return Ok(());
    }
    match input {
        Some(p) if crate::load::is_store_path(p) && !draw.raster.accumulates() => Err(format!(
            "--progressive draws a store with a closest-point --raster (atomic-min, early-z, \
             reduce, reduce-early-z, dedup), not {}",
            draw.raster.name()
        )),
        Some(p) if crate::load::is_store_path(p) => Ok(()),
        _ => Err(format!(
            "--progressive applies to stores only, not to {} (point files are always drawn \
             while they load)",
            input_kind(input)
        )),
    }
}

/// `render` and `view`: stores, point files drawn while they load and inputs drawn whole use
/// different flags; `progressive_too` of `store_only` apply to loading point files as well.
fn drawing(
    given: &Given,
    input: Option<&Path>,
    draw: &DrawArgs,
    store_only: &[&str],
    progressive_too: &[&str],
) -> Result<(), String> {
    let kind = input_kind(input);
    if input.is_some() {
        given.refuse(&["demo_points"], "the demo scene (without INPUT)", kind)?;
    }
    progressive_flag(given, input, draw)?;
    kind_flags(given, input, draw, store_only, progressive_too)?;
    point_size(given, input, draw)
}

/// The flags of the kind of input `drawing` was given.
fn kind_flags(
    given: &Given,
    input: Option<&Path>,
    draw: &DrawArgs,
    store_only: &[&str],
    progressive_too: &[&str],
) -> Result<(), String> {
    let kind = input_kind(input);
    match input {
        Some(p) if crate::load::is_store_path(p) && !draw.progressive => {
            given.refuse(&READING, "point files", kind)?;
            store_drawing(given, draw.raster)?;
            temporal_reuse(given, input, draw)
        }
        Some(p) if crate::progressive_cmd::is_progressive(Some(p), draw) => {
            if crate::load::is_store_path(p) {
                given.refuse(&READING, "point files", "a store")?;
            }
            let kind = if crate::load::is_several(p) {
                "several inputs drawn together while they load (a closest-point --raster)"
            } else {
                "a point file drawn while it loads (a closest-point --raster)"
            };
            given.refuse(
                &SHUFFLED,
                "the demo scene and point files drawn whole (--raster hqs, hqs1r, \
                 atomic-min-32, hw-points)",
                kind,
            )?;
            let refused: Vec<&str> = store_only
                .iter()
                .copied()
                .filter(|f| !progressive_too.contains(f))
                .collect();
            given.refuse(&refused, "stores", kind)
        }
        _ => {
            let (both, stores): (Vec<&str>, Vec<&str>) =
                store_only.iter().partition(|f| progressive_too.contains(f));
            given.refuse(&stores, "stores", kind)?;
            given.refuse(&both, "stores and point files drawn while they load", kind)
        }
    }
}

/// `--temporal-reuse` moves the last frame's 64-bit keys: a single-atomic closest-point
/// rasterizer drawing with compute (not billboard quads).
fn temporal_reuse(given: &Given, input: Option<&Path>, draw: &DrawArgs) -> Result<(), String> {
    if !given.has("temporal_reuse") {
        return Ok(());
    }
    if !draw.raster.accumulates() {
        return Err(format!(
            "--temporal-reuse reprojects the last frame's closest points: it takes atomic-min, early-z, reduce, reduce-early-z or dedup, not --raster {}",
            draw.raster.name()
        ));
    }
    if draw.splats_for(input).quads() {
        return Err("--temporal-reuse reprojects the compute rasterizers' keys, which billboard quads (--splat-raster quads) do not write".into());
    }
    Ok(())
}

/// `--point-size` beyond one pixel needs a compute rasterizer; `--splat-shape` needs points
/// larger than a pixel.
fn point_size(given: &Given, input: Option<&Path>, draw: &DrawArgs) -> Result<(), String> {
    let splats = draw.splats_for(input);
    if draw.raster == RasterVariant::HwPoints && !splats.is_pixel() {
        return Err(format!(
            "--raster hw-points draws one-pixel points (the point-list baseline), not --point-size {}: larger points need a compute --raster",
            splats.size.name()
        ));
    }
    for flag in ["splat_shape", "splat_raster"] {
        if given.has(flag) && splats.is_pixel() {
            return Err(format!(
                "--{} applies to points larger than a pixel (--point-size 2–32 or adaptive)",
                flag.replace('_', "-")
            ));
        }
    }
    if splats.quads() {
        if !draw.raster.accumulates() {
            return Err(format!(
                "--splat-raster quads keeps the closest splat per pixel: it takes a closest-point --raster (atomic-min, early-z, reduce, reduce-early-z, dedup), not {}",
                draw.raster.name()
            ));
        }
        if crate::progressive_cmd::is_progressive(input, draw) {
            return Err(
                "--splat-raster quads draws stores and point files read whole; a point file drawn while it loads takes compute splats"
                    .into(),
            );
        }
    }
    Ok(())
}

/// A store is drawn by the virtualized renderer: compute rasterizers, its own order and pages.
fn store_drawing(given: &Given, raster: RasterVariant) -> Result<(), String> {
    given.refuse(&IN_MEMORY, "point files and the demo scene", "a store")?;
    if raster == RasterVariant::HwPoints {
        return Err(
            "--raster hw-points draws point files and the demo scene only; a store is drawn by the compute rasterizers (any other --raster)"
                .into(),
        );
    }
    Ok(())
}
