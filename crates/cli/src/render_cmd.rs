//! `pointlet render`: one frame, headless, through the same GPU pipeline as the viewer.

use crate::view_args::{CameraArgs, DrawArgs, VirtualArgs};
use anyhow::{Context, Result};
use pointlet_core::order::apply;
use pointlet_gpu::{AdapterRequest, GpuCloud, GpuContext, PointSet, RenderTarget, Renderer};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// A store, any point file or a tileset; several are drawn together in one coordinate
    /// frame (as one point file: stores among them are read whole); without one, the built-in
    /// demo scene.
    pub inputs: Vec<PathBuf>,
    /// The PNG to write.
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub draw: DrawArgs,
    #[command(flatten)]
    pub virtual_args: VirtualArgs,
    #[command(flatten)]
    pub tiles: crate::view_args::TileArgs,
    /// Stores and point files: frames at most to reach the full-detail image of the still
    /// camera.
    #[arg(long, default_value_t = 10_000)]
    pub max_frames: u32,
    /// Stores: stop at the LoD image of the bucket instead of converging to full detail.
    #[arg(long)]
    pub no_converge: bool,
    /// Points of the demo scene (without INPUT).
    #[arg(long, default_value_t = crate::scene::DEMO_POINTS, value_parser = crate::parse_count_arg)]
    pub demo_points: u64,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

/// Opens the GPU and picks the variant to draw with, saying so when it must fall back.
pub fn open_gpu(draw: &DrawArgs) -> Result<(GpuContext, pointlet_gpu::RasterVariant)> {
    let ctx = open_adapter(&draw.adapter)?;
    let variant = draw.raster.fallback(&ctx.caps);
    if variant != draw.raster {
        eprintln!(
            "note: {} is not available on {} ({}); drawing with {}",
            draw.raster.name(),
            ctx.describe(),
            draw.raster
                .unsupported_reason(&ctx.caps)
                .unwrap_or("unsupported"),
            variant.name()
        );
    }
    Ok((ctx, variant))
}

pub fn open_adapter(name: &Option<String>) -> Result<GpuContext> {
    Ok(GpuContext::new(&AdapterRequest {
        name: name.clone(),
        ..Default::default()
    })?)
}

/// Puts a point set into a vertex order.
pub fn reorder(set: PointSet, order: pointlet_core::order::VertexOrder) -> PointSet {
    if order == pointlet_core::order::VertexOrder::Original {
        return set;
    }
    let perm = order.permutation(&set.positions, &set.bounds(), 0x5eed);
    PointSet {
        positions: apply(&set.positions, &perm),
        colors: apply(&set.colors, &perm),
    }
}

impl Args {
    /// The input as the flag checks see it ([`crate::load::drawn_input`]).
    pub fn input(&self) -> Option<&Path> {
        crate::load::drawn_input(&self.inputs)
    }
}

pub fn run(args: Args) -> Result<()> {
    crate::image_out::check_png_path(&args.output)?;
    if let [tileset] = &args.inputs[..] {
        if crate::tiles_cmd::is_streamed(&args.inputs) {
            return crate::tiles_cmd::render(&args, tileset);
        }
    }
    if crate::progressive_cmd::is_progressive(args.input(), &args.draw) {
        return crate::progressive_cmd::render(&args, &args.inputs);
    }
    if let [store] = &args.inputs[..] {
        if crate::load::is_store_path(store) {
            return render_store(&args, store);
        }
    }
    let (ctx, variant) = open_gpu(&args.draw)?;
    let scene = crate::scene::load(
        &args.inputs,
        &args.read,
        args.draw.color.as_ref(),
        args.demo_points,
    )?;
    let camera = args.camera.camera(&scene.bounds)?;
    let set = reorder(scene.set, args.draw.order);
    let mut cloud = GpuCloud::upload(&ctx, &set, args.draw.encoding, args.draw.page_size)
        .with_context(|| format!("uploading {} to {}", scene.name, ctx.describe()))?;
    drop(set);
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut renderer = Renderer::new(&ctx);
    let settings = args.draw.settings_for(variant, args.input());
    renderer.render(&ctx, &mut cloud, &camera, &settings, &mut target)?;
    let rgba = target.read_rgba(&ctx)?;
    let timing = renderer.timing(&ctx, &mut target)?;
    crate::image_out::write_png(&args.output, args.width, args.height, &rgba)?;
    eprintln!(
        "rendered {} points of {} with {} on {} into {}{}",
        cloud.points,
        scene.name,
        variant.name(),
        ctx.describe(),
        args.output.display(),
        timing
            .map(|t| format!(
                " (raster {:.3} ms, screen {:.3} ms GPU)",
                t.raster_ms, t.screen_ms
            ))
            .unwrap_or_default()
    );
    Ok(())
}

/// A store through the virtualized renderer: frames with a still camera until the image is the
/// full-detail image (or, with --no-converge, until the LoD's request is resident).
fn render_store(args: &Args, path: &std::path::Path) -> Result<()> {
    let store = pointlet_store::Store::open(path)?;
    let color = crate::scene::store_color(args.draw.color.as_ref(), &store)?;
    drop(store);
    let (ctx, variant) = open_gpu(&args.draw)?;
    let config = args.virtual_args.config(&args.draw, color);
    // The image size is checked before the scene sizes its pool for that frame.
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut scene =
        pointlet_engine::VirtualScene::open(&ctx, path, config, (args.width, args.height))
            .with_context(|| format!("opening {}", path.display()))?;
    let camera = args.camera.camera(&scene.bounds())?;
    let mut renderer = Renderer::new(&ctx);
    let settings = args.draw.settings_for(variant, Some(path));
    if args.no_converge {
        scene.set_accumulation(false);
    }
    let started = std::time::Instant::now();
    let mut last = None;
    let mut settled = 0;
    for _ in 0..args.max_frames {
        let report = scene.frame(&ctx, &mut renderer, &camera, &settings, &mut target)?;
        // Without convergence: done once a few residency steps in a row moved nothing to the
        // GPU and the requests arrived.
        if let Some(step) = &report.step {
            settled = if step.points_uploaded == 0
                && report.requested_points > 0
                && report.cache.queued == 0
            {
                settled + 1
            } else {
                0
            };
        }
        let done = report.converged || (args.no_converge && settled >= 8);
        last = Some(report);
        if done {
            break;
        }
        // Let loader threads work between frames, as display refresh would.
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let report = last.context("--max-frames must be at least 1")?;
    if !report.converged && !args.no_converge {
        eprintln!(
            "note: not converged after {} frames; writing the image as it is",
            args.max_frames
        );
    }
    let rgba = target.read_rgba(&ctx)?;
    crate::image_out::write_png(&args.output, args.width, args.height, &rgba)?;
    eprintln!(
        "rendered {} ({} points) with {} on {} into {} after {} frames in {:.2} s: {} points drawn, {} read from disk",
        path.display(),
        scene.points(),
        variant.name(),
        ctx.describe(),
        args.output.display(),
        report.frame,
        started.elapsed().as_secs_f64(),
        report.drawn_points,
        pointlet_core::size::format_bytes(report.cache.bytes_read)
    );
    Ok(())
}
