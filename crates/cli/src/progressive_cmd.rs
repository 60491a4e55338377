//! Point files drawn while they load (the progressive-rendering paper, issue 11): the pieces
//! `render`, `bench` and `view` share, and `render`'s loop (frames of a still camera until
//! every point is loaded and drawn).

use crate::load::ReadArgs;
use crate::view_args::{ColorArg, DrawArgs};
use anyhow::{bail, Context, Result};
use pointlet_core::color::ColorMode;
use pointlet_engine::progressive::LoadConfig;
use pointlet_engine::{ProgressiveConfig, ProgressiveScene};
use pointlet_gpu::{GpuContext, RasterVariant, RenderTarget};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Default GPU memory for a point file's shuffled buffer.
pub const DEFAULT_VRAM_BUDGET: u64 = 2 << 30;

/// Point files (and stores with `--progressive`) are drawn progressively by the closest-point
/// rasterizers; the blending ones (HQS, HQS1R), the 32-bit path and hardware points need the
/// whole file in memory.
pub fn is_progressive(input: Option<&Path>, draw: &DrawArgs) -> bool {
    input.is_some_and(|p| !crate::load::is_store_path(p) || draw.progressive)
        && draw.raster.accumulates()
}

/// The colouring asked for, resolved against the file for `extra:NAME` (the load thread picks
/// the default when none was asked for).
pub fn resolve_color(
    inputs: &[PathBuf],
    read: &ReadArgs,
    asked: Option<&ColorArg>,
) -> Result<Option<ColorMode>> {
    match asked {
        None => Ok(None),
        Some(ColorArg::Mode(m)) => Ok(Some(*m)),
        Some(extra @ ColorArg::Extra(_)) => {
            let reader = pointlet_engine::open_inputs(inputs, &read.options())?;
            let meta = reader.meta();
            let extras = crate::scene::extras_of(&meta.vlrs, &meta.layout);
            let name = reader.path().display().to_string();
            let mode =
                crate::scene::choose_color(Some(extra), &meta.layout, &extras, &name, || {
                    bail!("no default needed")
                })?;
            Ok(Some(mode))
        }
    }
}

/// The engine's settings for a point file drawn with `variant`.
pub fn config(
    draw: &DrawArgs,
    read: &ReadArgs,
    variant: RasterVariant,
    color: Option<ColorMode>,
    vram_budget: Option<u64>,
    target_fps: f64,
) -> ProgressiveConfig {
    ProgressiveConfig {
        load: LoadConfig {
            color,
            read: read.options(),
            ..Default::default()
        },
        variant,
        page_size: draw.page_size,
        vram_budget: vram_budget.unwrap_or(DEFAULT_VRAM_BUDGET),
        target_frame_ms: 1000.0 / target_fps,
        ..Default::default()
    }
}

/// Opens `inputs` progressively and says what the readers noted.
pub fn open(
    ctx: &GpuContext,
    inputs: &[PathBuf],
    config: ProgressiveConfig,
) -> Result<ProgressiveScene> {
    // The engine's errors name the file already.
    let scene = ProgressiveScene::open_many(ctx, inputs, config)?;
    for n in scene.notes() {
        match inputs {
            [one] => eprintln!("note: {}: {n}", one.display()),
            // Several inputs' notes name their file.
            _ => eprintln!("note: {n}"),
        }
    }
    if scene.slots() < scene.points() {
        eprintln!("note: {}", subset_note(&scene));
    }
    Ok(scene)
}

/// "showing 412 M of 1.2 G points …" for a file larger than the VRAM budget.
pub fn subset_note(scene: &ProgressiveScene) -> String {
    format!(
        "{}: showing a uniform subset of {} of its {} points (the VRAM budget holds {}); \
         `pointlet convert` it for full detail",
        scene.path().display(),
        pointlet_core::size::format_count(scene.slots()),
        pointlet_core::size::format_count(scene.points()),
        pointlet_core::size::format_bytes(scene.gpu_bytes())
    )
}

/// `render` of a point file: frames of the still camera while the file loads, each drawing
/// every slot, until all points are in and drawn; the image is then the one of drawing every
/// point at once.
pub fn render(args: &crate::render_cmd::Args, inputs: &[PathBuf]) -> Result<()> {
    let (ctx, variant) = crate::render_cmd::open_gpu(&args.draw)?;
    let color = resolve_color(inputs, &args.read, args.draw.color.as_ref())?;
    let mut config = config(
        &args.draw,
        &args.read,
        variant,
        color,
        args.virtual_args.vram_budget,
        60.0,
    );
    config.fixed_budget = Some(u64::MAX);
    // The image size is checked before the buffer is sized for the file.
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let started = Instant::now();
    let mut scene = open(&ctx, inputs, config)?;
    let path = scene.path().to_path_buf();
    let camera = args.camera.camera(&scene.bounds())?;
    let settings = args.draw.settings_for(variant, args.input());
    let mut noted = false;
    let mut last = None;
    for _ in 0..args.max_frames {
        let report = scene.frame(&ctx, &camera, &settings, &mut target)?;
        if let Some(failure) = &report.failure {
            bail!("{failure}");
        }
        if let (false, Some(d)) = (noted, scene.color().and_then(|c| c.default)) {
            eprintln!("note: {}: {d}", path.display());
            noted = true;
        }
        let done = report.converged;
        last = Some(report);
        if done {
            break;
        }
        // Nothing new to draw until the load thread hands over more.
        while !scene.wait_ready(std::time::Duration::from_millis(100)) {}
    }
    let report = last.context("--max-frames must be at least 1")?;
    if !report.converged {
        bail!(
            "{}: not loaded and drawn after {} frames (--max-frames); {} of {} points were in",
            path.display(),
            args.max_frames,
            report.progress.uploaded,
            report.progress.total
        );
    }
    let rgba = target.read_rgba(&ctx)?;
    crate::image_out::write_png(&args.output, args.width, args.height, &rgba)?;
    let p = report.progress;
    eprintln!(
        "rendered {} points of {} with {} on {} into {} after {} frames in {:.2} s \
         (loaded in {:.2} s, {:.1} M points/s)",
        p.shown(),
        path.display(),
        variant.name(),
        ctx.describe(),
        args.output.display(),
        report.frame,
        started.elapsed().as_secs_f64(),
        p.elapsed.as_secs_f64(),
        p.points_per_s() / 1e6
    );
    Ok(())
}
