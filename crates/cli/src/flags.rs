//! Flags that do not apply to what a command was given are refused as usage errors, never
//! ignored: which flags each command's inputs and modes use, in one place. A flag counts as
//! given when it was typed (clap's value source), whatever its value.

use crate::view_args::CameraArgs;
use crate::Command;
use clap::parser::ValueSource;
use clap::ArgMatches;
use pointlet_gpu::RasterVariant;
use std::path::Path;

/// Flags of the virtualized renderer, which draws stores only.
const VIRTUAL: [&str; 7] = [
    "bucket",
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

/// The flags of one subcommand typed on the command line.
pub struct Given<'a>(pub &'a ArgMatches);

impl Given<'_> {
    fn has(&self, id: &str) -> bool {
        self.0.value_source(id) == Some(ValueSource::CommandLine)
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
        Some(p) if crate::load::is_store_path(p) => "a store",
        Some(_) => "a point file",
        None => "the demo scene",
    }
}

/// The usage error for the first typed flag that does not apply, if any.
pub fn check(command: &Command, given: &Given) -> Result<(), String> {
    match command {
        Command::Render(a) => {
            camera(given, &a.camera)?;
            let store_only = [&VIRTUAL[..], &["max_frames", "no_converge"]].concat();
            drawing(given, a.input.as_deref(), a.draw.raster, &store_only)
        }
        Command::View(a) => {
            camera(given, &a.camera)?;
            let store_only = ["vram_budget", "ram_budget", "bucket", "converge_timeout"];
            drawing(given, a.input.as_deref(), a.draw.raster, &store_only)
        }
        Command::Bench(a) => {
            store_drawing(given, a.draw.raster)?;
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
            } else {
                given.refuse(&["buckets"], "--quality", "the flight along a path")?;
            }
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
        Command::Info(a) if crate::load::is_store_path(&a.input) => {
            given.refuse(&READING, "point files", "a store")
        }
        Command::Metrics(a) if crate::load::is_store_path(&a.input) => {
            given.refuse(&READING, "point files", "a store")
        }
        _ => Ok(()),
    }
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

/// `render` and `view`: stores and in-memory inputs use different flags.
fn drawing(
    given: &Given,
    input: Option<&Path>,
    raster: RasterVariant,
    store_only: &[&str],
) -> Result<(), String> {
    let kind = input_kind(input);
    if input.is_some() {
        given.refuse(&["demo_points"], "the demo scene (without INPUT)", kind)?;
    }
    match input {
        Some(p) if crate::load::is_store_path(p) => {
            given.refuse(&READING, "point files", kind)?;
            store_drawing(given, raster)
        }
        _ => given.refuse(store_only, "stores", kind),
    }
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
