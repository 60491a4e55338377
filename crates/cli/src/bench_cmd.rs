//! `pointlet bench`: a store along a camera path through the virtualized renderer — frame-time
//! statistics (the virtualized paper's Table II), the stage breakdown (its Fig. 15), memory and
//! streaming counters per frame, a plot; with `--quality`, PSNR of the LoD image against the
//! full-detail image for several buckets (its Fig. 16–17).

use crate::render_cmd::open_gpu;
use crate::view_args::{DrawArgs, VirtualArgs};
use anyhow::{bail, Context, Result};
use pointlet_core::path::CameraPath;
use pointlet_core::Camera;
use pointlet_engine::{FrameReport, VirtualScene};
use pointlet_gpu::{GpuContext, PointSize, RenderSettings, RenderTarget, Renderer, SplatSettings};
use pointlet_report::{FrameStats, Series, StageBreakdown};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// The store to fly through, or a point file (drawn progressively while it loads).
    pub store: PathBuf,
    /// `orbit` (the paper's path: one turn around the data, zooming in and out) or a camera
    /// path JSON file (as the viewer records).
    #[arg(long, default_value = "orbit")]
    pub path: String,
    /// Frames along the path (evenly spaced in time).
    #[arg(long, default_value_t = 1000)]
    pub frames: u32,
    /// Follow the path in wall-clock time instead, as a user flying it sees it: each frame
    /// shows the camera of the moment it starts, until the path ends (`--frames` only sets the
    /// orbit's keyframe density). Faster frames then do not outrun the loading.
    #[arg(long)]
    pub realtime: bool,
    /// Seconds one orbit takes (with `--path orbit`).
    #[arg(long, default_value_t = 30.0)]
    pub orbit_seconds: f64,
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    /// Frames drawn before measuring (pipeline compilation, first requests), not counted.
    #[arg(long, default_value_t = 1)]
    pub warmup: u32,
    /// Frames the GPU may run behind the CPU (a swap chain's depth).
    #[arg(long, default_value_t = 2)]
    pub in_flight: usize,
    /// Per-frame measurements and the summary as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Frame times and stages over the path: `.svg` or `.png`.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Measure image quality instead: PSNR of LoD images against the full-detail image.
    #[arg(long)]
    pub quality: bool,
    /// Fly the path by frames and at this many frames along it measure the PSNR of the moving
    /// frame against the full-detail image of its camera (with and without
    /// `--temporal-reuse` to compare them).
    #[arg(long)]
    pub path_quality: Option<u32>,
    /// Buckets for `--quality` (default 1M,2.5M,5M,10M,25M,50M up to the store's size).
    #[arg(long, value_delimiter = ',', value_parser = crate::parse_bucket_arg)]
    pub buckets: Vec<u64>,
    /// Point files: the frame rate the adaptive fill budget aims at.
    #[arg(long, value_parser = crate::parse_fps_arg)]
    pub target_fps: Option<f64>,
    #[command(flatten)]
    pub draw: DrawArgs,
    #[command(flatten)]
    pub virtual_args: VirtualArgs,
    #[command(flatten)]
    pub tiles: crate::view_args::TileArgs,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

/// The camera path of a bench flight (`--path`, `--frames`, `--realtime`) around `bounds`.
pub(crate) struct Flight {
    pub path: CameraPath,
    /// The path sampled at `--frames` evenly spaced times.
    pub cameras: Vec<Camera>,
    bounds: pointlet_core::Aabb,
    realtime: bool,
}

impl Flight {
    pub fn new(args: &Args, bounds: pointlet_core::Aabb) -> Result<Self> {
        let path = if args.path == "orbit" {
            CameraPath::orbit(
                &bounds,
                args.orbit_seconds,
                args.frames as f64 / args.orbit_seconds,
            )?
        } else {
            CameraPath::load(Path::new(&args.path))?
        };
        let cameras = path.sample(args.frames, &bounds);
        Ok(Self {
            path,
            cameras,
            bounds,
            realtime: args.realtime,
        })
    }

    /// The camera of frame `k`, started `t` seconds into the flight: the k-th sample, or with
    /// `--realtime` the path at time t; `None` once the flight is over.
    pub fn camera(&self, k: usize, t: f64) -> Option<Camera> {
        if self.realtime {
            (t < self.path.duration()).then(|| self.path.camera_at(t, &self.bounds))
        } else {
            self.cameras.get(k).copied()
        }
    }
}

#[derive(Serialize)]
struct FrameRow {
    frame: u32,
    /// Seconds since the first measured frame started.
    time_s: f64,
    frame_ms: f64,
    /// Render thread: handing feedback to the residency thread and queueing its batch.
    handoff_ms: f64,
    /// Residency thread: the step whose batch this frame queued (0: none finished).
    residency_ms: f64,
    /// See `pointlet_engine::RESIDENCY_PARTS`.
    residency_parts_ms: [f64; 5],
    upload_ms: f64,
    lod_ms: f64,
    raster_ms: f64,
    screen_ms: f64,
    points_drawn: u64,
    points_requested: u64,
    points_uploaded: u64,
    upload_runs: u64,
    bytes_uploaded: u64,
    gpu_pages: u32,
    gpu_points: u64,
    ram_bytes: u64,
    disk_bytes_read: u64,
    loader_queue: usize,
}

#[derive(Serialize)]
struct Summary<'a> {
    store: String,
    points: u64,
    adapter: String,
    width: u32,
    height: u32,
    bucket: u64,
    vram_budget: u64,
    ram_budget: u64,
    vram_allocated: u64,
    ram_peak: u64,
    /// The camera followed the path in wall-clock time.
    realtime: bool,
    /// Of the points the LoD requested over the path, the share drawn.
    request_drawn: f64,
    stats: &'a FrameStats,
    stages: &'a [pointlet_report::StageSummary],
    /// Mean CPU time per frame of the render graph besides its passes.
    graph_overhead_ms: f64,
    frames: &'a [FrameRow],
}

pub fn run(args: Args) -> Result<()> {
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    // Checked before flying, not minutes later when the plot is written.
    if let Some(p) = &args.plot {
        plot_format(p)?;
    }
    if crate::tiles_cmd::is_streamed(std::slice::from_ref(&args.store)) {
        return crate::tiles_cmd::bench(&args);
    }
    let point_file = !crate::load::is_store_path(&args.store) && args.store.is_file();
    if point_file || args.draw.progressive {
        if !args.draw.raster.accumulates() {
            bail!(
                "{}: bench draws point files progressively, which needs a closest-point \
                 --raster (atomic-min, early-z, reduce, reduce-early-z, dedup); `pointlet \
                 convert` it to bench {}",
                args.store.display(),
                args.draw.raster.name()
            );
        }
        return crate::bench_progressive::run(&args);
    }
    let store = crate::load::open_store(&args.store, "bench")?;
    let color = crate::scene::store_color(args.draw.color.as_ref(), &store)?;
    drop(store);
    let (ctx, variant) = open_gpu(&args.draw)?;
    let config = args.virtual_args.config(&args.draw, color);
    let mut scene =
        VirtualScene::open(&ctx, &args.store, config.clone(), (args.width, args.height))
            .with_context(|| format!("opening {}", args.store.display()))?;
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut renderer = Renderer::new(&ctx);
    let settings = args.draw.settings_for(variant, Some(&args.store));
    let bounds = scene.bounds();
    if args.quality {
        return quality(
            &args,
            &ctx,
            &mut scene,
            &mut renderer,
            &mut target,
            &settings,
        );
    }
    let flight = Flight::new(&args, bounds)?;
    let cameras = &flight.cameras;
    if let Some(samples) = args.path_quality {
        return path_quality(
            &args,
            &ctx,
            &mut scene,
            &mut renderer,
            &mut target,
            &settings,
            cameras,
            samples,
        );
    }
    if let Some(first) = cameras.first() {
        for _ in 0..args.warmup {
            scene.frame(&ctx, &mut renderer, first, &settings, &mut target)?;
        }
        ctx.wait()?;
        renderer.poll_timings(&ctx, &mut target);
    }
    renderer.take_graph_overhead();
    let mut rows: Vec<FrameRow> = Vec::with_capacity(cameras.len());
    let mut read_before = 0u64;
    let began = Instant::now();
    let mut last_start = began;
    let mut first_frame = renderer.frames() + 1;
    for k in 0.. {
        renderer.limit_frames_in_flight(&ctx, args.in_flight)?;
        let start = Instant::now();
        let t = (start - began).as_secs_f64();
        let Some(camera) = flight.camera(k as usize, t) else {
            break;
        };
        if k == 0 {
            first_frame = renderer.frames() + 1;
        } else if let Some(prev) = rows.last_mut() {
            // A frame lasts from its start to the next one's, as a display would see it.
            prev.frame_ms = (start - last_start).as_secs_f64() * 1e3;
        }
        last_start = start;
        let report = scene.frame(&ctx, &mut renderer, &camera, &settings, &mut target)?;
        let mut r = row(k, &report, &mut read_before);
        r.time_s = t;
        rows.push(r);
        attach_timings(
            &mut rows,
            renderer.poll_timings(&ctx, &mut target),
            first_frame,
        );
    }
    ctx.wait()?;
    if let Some(prev) = rows.last_mut() {
        prev.frame_ms = last_start.elapsed().as_secs_f64() * 1e3;
    }
    attach_timings(
        &mut rows,
        renderer.poll_timings(&ctx, &mut target),
        first_frame,
    );
    let times: Vec<f64> = rows.iter().map(|r| r.frame_ms.max(1e-6)).collect();
    let stats = FrameStats::from_frame_times_ms(&times)?;
    let graph_ms = renderer
        .take_graph_overhead()
        .map_or(0.0, |d| d.as_secs_f64() * 1e3);
    let graphs = renderer.frame_graphs();
    let mut stages = StageBreakdown::new([
        "handoff (render)",
        "residency (thread)",
        "upload (GPU)",
        "lod (GPU)",
        "raster (GPU)",
        "screen (GPU)",
    ])?;
    for r in &rows {
        stages.push_frame(&[
            r.handoff_ms,
            r.residency_ms,
            r.upload_ms,
            r.lod_ms,
            r.raster_ms,
            r.screen_ms,
        ])?;
    }
    let stage_table = stages.summary();
    let cache = scene.cache_stats();
    println!(
        "{}: {} points, {}×{}, bucket {}, {} on {}",
        args.store.display(),
        scene.points(),
        args.width,
        args.height,
        args.virtual_args.bucket,
        variant.name(),
        ctx.describe()
    );
    println!("{stats}");
    let mean_ms = times.iter().sum::<f64>() / times.len().max(1) as f64;
    println!(
        "render graph: {:.1} µs of CPU per frame besides its passes ({:.2} % of the mean frame)",
        graph_ms * 1e3,
        graph_ms / mean_ms.max(1e-9) * 100.0
    );
    for g in &graphs {
        println!(
            "  passes {}{}; transients {} B/pixel",
            g.passes.join(" → "),
            if g.culled.is_empty() {
                String::new()
            } else {
                format!(" (culled: {})", g.culled.join(", "))
            },
            g.transient_bytes_per_pixel
        );
    }
    println!("stage breakdown (ms per frame):");
    for s in &stage_table {
        println!(
            "  {:<18} avg {:>8.3}  median {:>8.3}  max {:>8.3}",
            s.name, s.avg_ms, s.median_ms, s.max_ms
        );
    }
    for (k, name) in pointlet_engine::RESIDENCY_PARTS.iter().enumerate() {
        let v: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.residency_parts_ms.get(k).copied())
            .collect();
        let avg = v.iter().sum::<f64>() / v.len().max(1) as f64;
        let max = v.iter().cloned().fold(0.0, f64::max);
        println!("    residency: {name:<14} avg {avg:>8.3}  max {max:>8.3}");
    }
    // How sharp the frames were: of the points the LoD asked for, the share drawn.
    let requested: u64 = rows.iter().map(|r| r.points_requested).sum();
    let drawn: u64 = rows
        .iter()
        .map(|r| r.points_drawn.min(r.points_requested))
        .sum();
    let request_drawn = drawn as f64 / requested.max(1) as f64;
    let seconds = rows.iter().map(|r| r.frame_ms).sum::<f64>() / 1e3;
    println!(
        "streaming: {:.1} % of the requested points drawn over the path ({:.2} s, {} frames); {} points uploaded",
        request_drawn * 100.0,
        seconds,
        rows.len(),
        rows.iter().map(|r| r.points_uploaded).sum::<u64>()
    );
    println!(
        "memory: GPU {} allocated of a {} budget; RAM cache peak {} of {}; {} read from disk",
        pointlet_core::size::format_bytes(
            scene.gpu_bytes() + pointlet_engine::target_bytes(args.width, args.height)
        ),
        pointlet_core::size::format_bytes(config.vram_budget),
        pointlet_core::size::format_bytes(cache.ram_peak),
        pointlet_core::size::format_bytes(config.ram_budget),
        pointlet_core::size::format_bytes(cache.bytes_read)
    );
    if let Some(p) = &args.plot {
        write_plot(p, &rows)?;
    }
    if let Some(p) = &args.json {
        let summary = Summary {
            store: args.store.display().to_string(),
            points: scene.points(),
            adapter: ctx.describe(),
            width: args.width,
            height: args.height,
            bucket: args.virtual_args.bucket,
            vram_budget: config.vram_budget,
            ram_budget: config.ram_budget,
            realtime: args.realtime,
            request_drawn,
            vram_allocated: scene.gpu_bytes()
                + pointlet_engine::target_bytes(args.width, args.height),
            ram_peak: cache.ram_peak,
            stats: &stats,
            stages: &stage_table,
            graph_overhead_ms: graph_ms,
            frames: &rows,
        };
        std::fs::write(p, serde_json::to_string_pretty(&summary)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

fn row(frame: u32, r: &FrameReport, read_before: &mut u64) -> FrameRow {
    let read = r.cache.bytes_read.saturating_sub(*read_before);
    *read_before = r.cache.bytes_read;
    let step = r.step.clone().unwrap_or_default();
    FrameRow {
        frame,
        time_s: 0.0,
        frame_ms: 0.0,
        handoff_ms: r.handoff_ms,
        residency_ms: step.ms,
        residency_parts_ms: step.parts_ms,
        upload_ms: 0.0,
        lod_ms: 0.0,
        raster_ms: 0.0,
        screen_ms: 0.0,
        points_drawn: r.drawn_points,
        points_requested: r.requested_points,
        points_uploaded: step.points_uploaded,
        upload_runs: step.upload_runs,
        bytes_uploaded: step.bytes_uploaded,
        gpu_pages: r.pages_resident,
        gpu_points: r.gpu_points,
        ram_bytes: r.cache.ram_used,
        disk_bytes_read: read,
        loader_queue: r.cache.queued,
    }
}

/// Puts GPU timings (numbered by the renderer from `first`) into their frames' rows.
fn attach_timings(
    rows: &mut [FrameRow],
    timings: Vec<(u64, pointlet_gpu::FrameTiming)>,
    first: u64,
) {
    for (frame, t) in timings {
        if let Some(r) = frame
            .checked_sub(first)
            .and_then(|k| rows.get_mut(k as usize))
        {
            r.upload_ms = t.upload_ms;
            r.lod_ms = t.lod_ms;
            r.raster_ms = t.raster_ms;
            r.screen_ms = t.screen_ms;
        }
    }
}

fn write_plot(path: &Path, rows: &[FrameRow]) -> Result<()> {
    let series = |name: &str, k: usize, f: &dyn Fn(&FrameRow) -> f64| Series {
        name: name.to_string(),
        color: pointlet_report::palette(k),
        points: rows.iter().map(|r| (r.frame as f64, f(r))).collect(),
    };
    let all = [
        series("frame", 0, &|r| r.frame_ms),
        series("raster (GPU)", 1, &|r| r.raster_ms),
        series("LoD (GPU)", 2, &|r| r.lod_ms),
        series("upload (GPU)", 5, &|r| r.upload_ms),
        series("residency (thread)", 3, &|r| r.residency_ms),
        series("handoff (render)", 6, &|r| r.handoff_ms),
        series("screen (GPU)", 4, &|r| r.screen_ms),
    ];
    write_series(path, "frame time along the path", &all)
}

/// Frame-time series as an SVG or PNG plot, by the path's extension.
pub(crate) fn write_series(path: &Path, title: &str, all: &[Series]) -> Result<()> {
    let bytes = match plot_format(path)? {
        PlotFormat::Svg => pointlet_report::plot_svg(title, all, "frame", "ms").into_bytes(),
        PlotFormat::Png => pointlet_report::plot_png(title, all, "frame", "ms", 1600, 900)?,
    };
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

enum PlotFormat {
    Svg,
    Png,
}

fn plot_format(path: &Path) -> Result<PlotFormat> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("svg") => Ok(PlotFormat::Svg),
        Some("png") => Ok(PlotFormat::Png),
        _ => bail!("plot {} must end in .svg or .png", path.display()),
    }
}

/// Renders frames of a still `camera` until `done` says so; the last report.
fn settle(
    ctx: &GpuContext,
    scene: &mut VirtualScene,
    renderer: &mut Renderer,
    target: &mut RenderTarget,
    camera: &Camera,
    settings: &RenderSettings,
    done: impl Fn(&FrameReport, u32) -> bool,
) -> Result<FrameReport> {
    let mut quiet = 0;
    for _ in 0..20_000 {
        let r = scene.frame(ctx, renderer, camera, settings, target)?;
        // Quiet: residency steps in a row that moved nothing and found the loaders idle.
        if let Some(step) = &r.step {
            quiet = if step.points_uploaded == 0 && r.cache.queued == 0 && r.requested_points > 0 {
                quiet + 1
            } else {
                0
            };
        }
        if done(&r, quiet) {
            return Ok(r);
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    bail!("the view did not settle within 20 000 frames")
}

#[derive(Serialize)]
struct PathQualityRow {
    frame: usize,
    psnr_db: f64,
    /// The moving frame's wall time.
    frame_ms: f64,
}

/// `--path-quality N`: the path flown by frames; at N frames spread over it, the moving
/// frame's image against the full-detail image of the same camera (drawn by a second scene).
#[allow(clippy::too_many_arguments)]
fn path_quality(
    args: &Args,
    ctx: &GpuContext,
    scene: &mut VirtualScene,
    renderer: &mut Renderer,
    target: &mut RenderTarget,
    settings: &RenderSettings,
    cameras: &[Camera],
    samples: u32,
) -> Result<()> {
    if samples == 0 {
        bail!("--path-quality needs at least 1 sample");
    }
    let store = crate::load::open_store(&args.store, "bench")?;
    let color = crate::scene::store_color(args.draw.color.as_ref(), &store)?;
    drop(store);
    let mut truth_config = args.virtual_args.config(&args.draw, color);
    truth_config.temporal_reuse = false;
    let mut truth = VirtualScene::open(ctx, &args.store, truth_config, (args.width, args.height))?;
    let mut truth_target = RenderTarget::new(ctx, args.width, args.height)?;
    let mut truth_renderer = Renderer::new(ctx);
    let every = (cameras.len() / samples as usize).max(1);
    let mut rows = Vec::new();
    for (k, camera) in cameras.iter().enumerate() {
        let start = Instant::now();
        scene.frame(ctx, renderer, camera, settings, target)?;
        if k % every != every - 1 {
            continue;
        }
        let image = target.read_rgba(ctx)?;
        let frame_ms = start.elapsed().as_secs_f64() * 1e3;
        settle(
            ctx,
            &mut truth,
            &mut truth_renderer,
            &mut truth_target,
            camera,
            settings,
            |r, _| r.converged,
        )?;
        let psnr = pointlet_report::psnr(&image, &truth_target.read_rgba(ctx)?)?;
        println!("frame {k:>6}: PSNR {psnr:>6.2} dB against full detail");
        rows.push(PathQualityRow {
            frame: k,
            psnr_db: psnr,
            frame_ms,
        });
    }
    let finite: Vec<f64> = rows
        .iter()
        .map(|r| r.psnr_db)
        .filter(|p| p.is_finite())
        .collect();
    let mean = finite.iter().sum::<f64>() / finite.len().max(1) as f64;
    println!(
        "{}: mean PSNR {mean:.2} dB over {} frames along the path (bucket {}, temporal reuse {})",
        args.store.display(),
        rows.len(),
        args.virtual_args.bucket,
        if args.virtual_args.temporal_reuse {
            "on"
        } else {
            "off"
        }
    );
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

#[derive(Serialize)]
struct QualityRow {
    view: &'static str,
    bucket: u64,
    /// LoD image vs full detail.
    psnr_db: f64,
    /// Hole-filled LoD image vs hole-filled full detail.
    psnr_filled_db: f64,
    /// LoD image with adaptive splats vs full detail with adaptive splats.
    psnr_adaptive_db: f64,
}

fn quality(
    args: &Args,
    ctx: &GpuContext,
    scene: &mut VirtualScene,
    renderer: &mut Renderer,
    target: &mut RenderTarget,
    settings: &RenderSettings,
) -> Result<()> {
    let bounds = scene.bounds();
    let plain = RenderSettings {
        screen: pointlet_gpu::ScreenSettings {
            fill_radius: 0,
            ..settings.screen
        },
        ..*settings
    };
    let filled = RenderSettings {
        screen: pointlet_gpu::ScreenSettings {
            fill_radius: args.draw.fill.max(1),
            ..settings.screen
        },
        ..*settings
    };
    let adaptive = RenderSettings {
        splats: SplatSettings {
            size: PointSize::adaptive(),
            ..settings.splats
        },
        ..plain
    };
    let columns = [&plain, &filled, &adaptive];
    let buckets: Vec<u64> = if args.buckets.is_empty() {
        [
            1_000_000u64,
            2_500_000,
            5_000_000,
            10_000_000,
            25_000_000,
            50_000_000,
        ]
        .into_iter()
        .filter(|b| *b < scene.points())
        .collect()
    } else {
        args.buckets.clone()
    };
    let mut rows = Vec::new();
    for (view, camera) in [
        ("overview", Camera::overview(&bounds, 60.0)),
        ("closeup", Camera::closeup(&bounds, 60.0)),
    ] {
        // Ground truth: full detail, plain, hole-filled and with adaptive splats (filling and
        // splats change the truth too, so each LoD image is compared with its own truth).
        scene.set_accumulation(true);
        let mut truth = Vec::new();
        for s in columns {
            settle(ctx, scene, renderer, target, &camera, s, |r, _| r.converged)?;
            truth.push(target.read_rgba(ctx)?);
        }
        scene.set_accumulation(false);
        for b in &buckets {
            scene.set_bucket(*b as f64);
            let mut psnr = [0.0; 3];
            for (k, s) in columns.into_iter().enumerate() {
                settle(ctx, scene, renderer, target, &camera, s, |_, quiet| {
                    quiet >= 8
                })?;
                psnr[k] = pointlet_report::psnr(&target.read_rgba(ctx)?, &truth[k])?;
            }
            println!(
                "{view:<9} bucket {:>12}: PSNR {:>6.2} dB, with hole filling {:>6.2} dB, with adaptive splats {:>6.2} dB",
                b, psnr[0], psnr[1], psnr[2]
            );
            rows.push(QualityRow {
                view,
                bucket: *b,
                psnr_db: psnr[0],
                psnr_filled_db: psnr[1],
                psnr_adaptive_db: psnr[2],
            });
        }
        scene.set_bucket(args.virtual_args.bucket as f64);
    }
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_string_pretty(&rows)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}
