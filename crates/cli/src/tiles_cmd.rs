//! `render` and `bench` of one 3D Tiles tileset, streamed (engine `TilesetScene`): tiles chosen
//! by screen-space error, fetched on worker threads, kept within the RAM and VRAM budgets, and
//! drawn through the continuous-LoD filter.

use crate::bench_cmd::{write_series, Flight};
use crate::render_cmd::open_gpu;
use anyhow::{bail, Context, Result};
use pointlet_engine::{TilesetFrameReport, TilesetScene};
use pointlet_gpu::{GpuContext, RenderTarget, Renderer};
use pointlet_report::{FrameStats, Series};
use serde::Serialize;
use std::path::Path;
use std::time::{Duration, Instant};

/// True when `inputs` is one tileset (`tileset.json`, local or a URL): it is streamed.
pub fn is_streamed(inputs: &[std::path::PathBuf]) -> bool {
    matches!(inputs, [one] if pointlet_tiles::points::is_tileset_path(one))
}

/// Longest wait for a still camera's tiles to arrive.
const SETTLE_LIMIT: Duration = Duration::from_secs(600);

fn color_of(
    asked: Option<&crate::view_args::ColorArg>,
) -> Result<Option<pointlet_core::color::ColorMode>> {
    match asked {
        None => Ok(None),
        Some(crate::view_args::ColorArg::Mode(m)) => Ok(Some(*m)),
        Some(crate::view_args::ColorArg::Extra(name)) => {
            bail!("a tileset has no LAS extra-bytes attribute '{name}' to colour by")
        }
    }
}

fn open(
    ctx: &GpuContext,
    path: &Path,
    tiles: &crate::view_args::TileArgs,
    virtual_args: &crate::view_args::VirtualArgs,
    asked: Option<&crate::view_args::ColorArg>,
) -> Result<TilesetScene> {
    let config = tiles.config(virtual_args, color_of(asked)?);
    TilesetScene::open(ctx, path, config).with_context(|| format!("opening {}", path.display()))
}

/// The camera of `--view`/`--eye`: a predefined view of a globe tileset is made in its local
/// east–north–up frame (up is the local vertical), placed cameras are world coordinates.
fn view_camera(
    args: &crate::view_args::CameraArgs,
    scene: &TilesetScene,
) -> Result<pointlet_core::Camera> {
    match scene.local_frame() {
        Some(frame) if !args.placed() => {
            Ok(frame.camera_to_world(&args.camera(&scene.view_bounds())?))
        }
        _ => args.camera(&scene.bounds()),
    }
}

fn print_notes(scene: &mut TilesetScene) {
    for n in scene.take_notes() {
        eprintln!("note: {n}");
    }
}

/// Notes and errors of the tiles so far: a picture without a tile it should show is no
/// picture of the tileset, so `render` fails on the first error.
fn check_tiles(scene: &mut TilesetScene) -> Result<()> {
    print_notes(scene);
    let mut errors = scene.take_errors().into_iter();
    match errors.next() {
        None => Ok(()),
        Some(first) => {
            for e in errors {
                eprintln!("error: {e}");
            }
            Err(first).context(format!("drawing {}", scene.name()))
        }
    }
}

/// Notes, and errors as notes: a flight goes on without the tiles that failed.
fn report_tiles(scene: &mut TilesetScene, failed: &mut u64) {
    print_notes(scene);
    for e in scene.take_errors() {
        *failed += 1;
        eprintln!("note: not drawn: {e}");
    }
}

/// One image of a still camera once the tiles it wants have arrived.
pub fn render(args: &crate::render_cmd::Args, path: &Path) -> Result<()> {
    let (ctx, variant) = open_gpu(&args.draw)?;
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut scene = open(
        &ctx,
        path,
        &args.tiles,
        &args.virtual_args,
        args.draw.color.as_ref(),
    )?;
    let camera = view_camera(&args.camera, &scene)?;
    let settings = args.draw.settings_for(variant, Some(path));
    let mut renderer = Renderer::new(&ctx);
    let started = Instant::now();
    let mut last: Option<TilesetFrameReport> = None;
    for _ in 0..args.max_frames {
        let report = scene.frame(&ctx, &mut renderer, &camera, &settings, &mut target)?;
        check_tiles(&mut scene)?;
        let done = report.converged;
        last = Some(report);
        if done {
            break;
        }
        if started.elapsed() > SETTLE_LIMIT {
            break;
        }
        // Let the fetchers work between frames, as display refresh would.
        std::thread::sleep(Duration::from_millis(2));
    }
    let report = last.context("--max-frames must be at least 1")?;
    if !report.converged {
        eprintln!(
            "note: {} tiles still requested after {} frames; writing the image as it is",
            report.requested_tiles, report.frame
        );
    }
    let rgba = target.read_rgba(&ctx)?;
    crate::image_out::write_png(&args.output, args.width, args.height, &rgba)?;
    eprintln!(
        "rendered {} ({} tiles, coloured by {}) with {} on {} into {} after {} frames in {:.2} s: {} tiles drawn, {} points tested, {} tiles fetched",
        path.display(),
        scene.tiles(),
        scene.color_mode().name(),
        variant.name(),
        ctx.describe(),
        args.output.display(),
        report.frame,
        started.elapsed().as_secs_f64(),
        report.drawn_tiles,
        report.tested_points,
        report.stream.loaded
    );
    Ok(())
}

#[derive(Serialize)]
struct Row {
    frame: u32,
    time_s: f64,
    frame_ms: f64,
    filter_ms: f64,
    raster_ms: f64,
    screen_ms: f64,
    drawn_tiles: u32,
    tested_points: u64,
    wanted_tiles: u32,
    wanted_drawn: u32,
    requested_tiles: u32,
    uploaded_tiles: u32,
    uploaded_bytes: u64,
    evicted_tiles: u32,
    gpu_bytes: u64,
    ram_bytes: u64,
}

#[derive(Serialize)]
struct Summary<'a> {
    tileset: String,
    tiles: usize,
    adapter: String,
    variant: &'static str,
    width: u32,
    height: u32,
    max_sse: f64,
    clod: bool,
    vram_budget: u64,
    ram_budget: u64,
    realtime: bool,
    /// Of the tiles the settled view of each frame's camera draws, the share drawn.
    wanted_drawn: f64,
    tiles_fetched: u64,
    tiles_failed: u64,
    peak_in_flight: usize,
    stats: &'a FrameStats,
    frames: &'a [Row],
}

/// `bench tileset.json`: the flight of a store's bench over a streamed tileset.
pub fn bench(args: &crate::bench_cmd::Args) -> Result<()> {
    let (ctx, variant) = open_gpu(&args.draw)?;
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut scene = open(
        &ctx,
        &args.store,
        &args.tiles,
        &args.virtual_args,
        args.draw.color.as_ref(),
    )?;
    let settings = args.draw.settings_for(variant, Some(&args.store));
    let mut renderer = Renderer::new(&ctx);
    // The orbit of a globe tileset circles its local vertical; a recorded path is in world
    // coordinates.
    let frame = scene.local_frame().filter(|_| args.path == "orbit");
    let flight = Flight::new(
        args,
        if frame.is_some() {
            scene.view_bounds()
        } else {
            scene.bounds()
        },
    )?;
    let config = args.tiles.config(&args.virtual_args, None);
    let mut rows: Vec<Row> = Vec::new();
    let mut stream = pointlet_tiles::TileStreamStats::default();
    let mut failed = 0u64;
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
        let camera = frame.map_or(camera, |f| f.camera_to_world(&camera));
        if k == 0 {
            first_frame = renderer.frames() + 1;
        } else if let Some(prev) = rows.last_mut() {
            prev.frame_ms = (start - last_start).as_secs_f64() * 1e3;
        }
        last_start = start;
        let r = scene.frame(&ctx, &mut renderer, &camera, &settings, &mut target)?;
        report_tiles(&mut scene, &mut failed);
        stream = r.stream;
        rows.push(Row {
            frame: k,
            time_s: t,
            frame_ms: 0.0,
            filter_ms: 0.0,
            raster_ms: 0.0,
            screen_ms: 0.0,
            drawn_tiles: r.drawn_tiles,
            tested_points: r.tested_points,
            wanted_tiles: r.wanted_tiles,
            wanted_drawn: r.wanted_drawn,
            requested_tiles: r.requested_tiles,
            uploaded_tiles: r.uploaded_tiles,
            uploaded_bytes: r.uploaded_bytes,
            evicted_tiles: r.evicted_tiles,
            gpu_bytes: r.gpu_bytes,
            ram_bytes: r.stream.bytes,
        });
        attach(
            &mut rows,
            renderer.poll_timings(&ctx, &mut target),
            first_frame,
        );
    }
    ctx.wait()?;
    if let Some(prev) = rows.last_mut() {
        prev.frame_ms = last_start.elapsed().as_secs_f64() * 1e3;
    }
    attach(
        &mut rows,
        renderer.poll_timings(&ctx, &mut target),
        first_frame,
    );
    let times: Vec<f64> = rows.iter().map(|r| r.frame_ms.max(1e-6)).collect();
    let stats = FrameStats::from_frame_times_ms(&times)?;
    let wanted: u64 = rows.iter().map(|r| r.wanted_tiles as u64).sum();
    let drawn: u64 = rows.iter().map(|r| r.wanted_drawn as u64).sum();
    let share = drawn as f64 / wanted.max(1) as f64;
    let avg = |f: fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len().max(1) as f64;
    println!(
        "{}: {} tiles coloured by {}, {}×{}, max SSE {} px, CLOD {}, {} on {}",
        args.store.display(),
        scene.tiles(),
        scene.color_mode().name(),
        args.width,
        args.height,
        args.tiles.max_sse,
        if args.tiles.no_clod { "off" } else { "on" },
        variant.name(),
        ctx.describe()
    );
    println!("{stats}");
    println!(
        "stages (GPU, ms per frame): filter avg {:.3}, raster avg {:.3}, screen avg {:.3}",
        avg(|r| r.filter_ms),
        avg(|r| r.raster_ms),
        avg(|r| r.screen_ms)
    );
    println!(
        "streaming: {:.1} % of the tiles each camera's settled view draws were drawn ({} frames); {:.2} M points tested per frame on average",
        share * 100.0,
        rows.len(),
        avg(|r| r.tested_points as f64) / 1e6
    );
    let fetched = rows.iter().map(|r| r.uploaded_tiles as u64).sum::<u64>();
    println!(
        "memory: GPU peak {} of a {} budget; RAM peak {} of {}; {} tiles uploaded, {} evicted",
        pointlet_core::size::format_bytes(rows.iter().map(|r| r.gpu_bytes).max().unwrap_or(0)),
        pointlet_core::size::format_bytes(config.vram_budget),
        pointlet_core::size::format_bytes(rows.iter().map(|r| r.ram_bytes).max().unwrap_or(0)),
        pointlet_core::size::format_bytes(config.ram_budget),
        fetched,
        rows.iter().map(|r| r.evicted_tiles as u64).sum::<u64>()
    );
    if let Some(p) = &args.plot {
        let series = Series {
            name: "frame time (ms)".into(),
            color: [31, 119, 180],
            points: rows.iter().map(|r| (r.time_s, r.frame_ms)).collect(),
        };
        write_series(p, "frame time along the path (tileset)", &[series])?;
    }
    if let Some(p) = &args.json {
        let summary = Summary {
            tileset: args.store.display().to_string(),
            tiles: scene.tiles(),
            adapter: ctx.describe(),
            variant: variant.name(),
            width: args.width,
            height: args.height,
            max_sse: args.tiles.max_sse,
            clod: !args.tiles.no_clod,
            vram_budget: config.vram_budget,
            ram_budget: config.ram_budget,
            realtime: args.realtime,
            wanted_drawn: share,
            tiles_fetched: fetched,
            tiles_failed: failed,
            peak_in_flight: stream.peak_in_flight,
            stats: &stats,
            frames: &rows,
        };
        std::fs::write(p, serde_json::to_string_pretty(&summary)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

/// GPU timings of frames that have come back, by frame number.
fn attach(rows: &mut [Row], timings: Vec<(u64, pointlet_gpu::FrameTiming)>, first: u64) {
    for (frame, t) in timings {
        if let Some(r) = frame
            .checked_sub(first)
            .and_then(|k| rows.get_mut(k as usize))
        {
            r.filter_ms = t.lod_ms;
            r.raster_ms = t.raster_ms;
            r.screen_ms = t.screen_ms;
        }
    }
}
