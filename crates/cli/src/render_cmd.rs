//! `pointlet render`: one frame, headless, through the same GPU pipeline as the viewer.

use crate::view_args::{CameraArgs, DrawArgs};
use anyhow::{Context, Result};
use pointlet_core::order::apply;
use pointlet_gpu::{
    AdapterRequest, GpuCloud, GpuContext, PointSet, RenderSettings, RenderTarget, Renderer,
};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A store or any point file; without one, the built-in demo scene.
    pub input: Option<PathBuf>,
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
    /// Points of the demo scene (without INPUT).
    #[arg(long, default_value_t = crate::scene::DEMO_POINTS, value_parser = crate::parse_count_arg)]
    pub demo_points: u64,
}

/// Opens the GPU and picks the variant to draw with, saying so when it must fall back.
pub fn open_gpu(draw: &DrawArgs) -> Result<(GpuContext, pointlet_gpu::RasterVariant)> {
    let ctx = GpuContext::new(&AdapterRequest {
        name: draw.adapter.clone(),
        ..Default::default()
    })?;
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

pub fn run(args: Args) -> Result<()> {
    crate::image_out::check_png_path(&args.output)?;
    let (ctx, variant) = open_gpu(&args.draw)?;
    let scene = crate::scene::load(args.input.as_deref(), args.draw.color, args.demo_points)?;
    let camera = args.camera.camera(&scene.bounds)?;
    let set = reorder(scene.set, args.draw.order);
    let mut cloud = GpuCloud::upload(&ctx, &set, args.draw.encoding, args.draw.page_size)
        .with_context(|| format!("uploading {} to {}", scene.name, ctx.describe()))?;
    drop(set);
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut renderer = Renderer::new(&ctx);
    let settings = RenderSettings {
        variant,
        screen: args.draw.screen(),
        ..Default::default()
    };
    renderer.render(&ctx, &mut cloud, &camera, &settings, &mut target)?;
    let rgba = target.read_rgba(&ctx)?;
    let timing = renderer.timing(&ctx, &target)?;
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
