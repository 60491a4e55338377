//! `pointlet bench scan.laz`: a point file flown along a camera path while it loads through the
//! progressive path. Besides the frame statistics of a store's bench: time to the first frame
//! with points, load throughput, time until fully loaded, time to converge once the path ends,
//! and the share of the points drawn per frame (S / N).

use crate::bench_cmd::{write_series, Args, Flight};
use crate::progressive_cmd;
use anyhow::{bail, Context, Result};
use pointlet_engine::progressive::LoadProgress;
use pointlet_gpu::shuffle::{bus_time, BusTime};
use pointlet_gpu::{GpuContext, RenderTarget};
use pointlet_report::{FrameStats, Series, StageBreakdown};
use serde::Serialize;
use std::path::Path;
use std::time::{Duration, Instant};

/// Longest wait for a still camera to converge after the path.
const CONVERGE_LIMIT: Duration = Duration::from_secs(600);

#[derive(Serialize)]
struct Row {
    frame: u32,
    /// Seconds since the file was opened.
    time_s: f64,
    frame_ms: f64,
    reproject_ms: f64,
    fill_ms: f64,
    screen_ms: f64,
    /// S: slots the Fill pass drew.
    fill_budget: u64,
    /// S / N.
    share_drawn: f64,
    points_uploaded: u64,
    points_loaded: u64,
    loading: bool,
}

#[derive(Serialize)]
struct Summary<'a> {
    file: String,
    file_bytes: u64,
    points: u64,
    /// Slots of the shuffled buffer (fewer than `points` past the VRAM budget).
    slots: u64,
    adapter: String,
    variant: &'static str,
    width: u32,
    height: u32,
    vram_budget: u64,
    target_fps: f64,
    realtime: bool,
    /// From opening the file to the end of the first frame that showed points.
    first_frame_s: f64,
    /// Points per second uploaded between the first frame and the end of loading.
    after_first_points_per_s: f64,
    /// From opening the file until its last point was in the shuffled buffer.
    loaded_s: f64,
    load_points_per_s: f64,
    load_mb_per_s: f64,
    /// From the end of the path until the still camera's image was final.
    converge_s: f64,
    converge_frames: u64,
    /// Mean of S / N over the path.
    share_drawn: f64,
    /// Bytes of the upload measurement, threads writing into mapped upload memory (GB/s) and
    /// the GPU copying it into device memory (GB/s): the speed loading can reach at most.
    upload_bytes: u64,
    upload_write_gbs: f64,
    upload_copy_gbs: f64,
    /// The same from host memory (system RAM the GPU reads over the bus), where there is such.
    upload_host_write_gbs: Option<f64>,
    upload_host_copy_gbs: Option<f64>,
    upload_host_make_gbs: Option<f64>,
    /// Batches staged in newly made upload memory (of which made by Vulkan directly), and in
    /// reused memory.
    staged_new: u64,
    staged_direct: u64,
    staged_reused: u64,
    /// Making the passes and the GPU buffers (s), part of the time to the first frame.
    open_passes_s: f64,
    open_buffers_s: f64,
    gpu_bytes: u64,
    /// The load threads making new upload memory, and the load thread waiting for the render
    /// thread to take batches (s): which side bounded loading.
    staging_s: f64,
    /// The threads copying into upload memory over the load and after the first frame (none
    /// where no point went through upload memory, or the first frame showed everything).
    bus: Option<BusUse>,
    bus_after_first: Option<BusUse>,
    queue_waited_s: f64,
    /// Frame statistics of the frames drawn while loading.
    loading_stats: Option<FrameStats>,
    stats: &'a FrameStats,
    stages: &'a [pointlet_report::StageSummary],
    frames: &'a [Row],
}

/// How the threads copying into upload memory used the bus over a stretch of loading.
#[derive(Serialize)]
struct BusUse {
    /// Share of the stretch with at least one copy going on.
    busy_share: f64,
    /// Copies going on at once, on average while there was any.
    writers_mean: f64,
    /// GB/s of one copy, and of all of them while any went on.
    writer_gbs: f64,
    busy_gbs: f64,
}

impl BusUse {
    fn new(time: &BusTime, seconds: f64) -> BusUse {
        let (busy, writing) = (time.busy.as_secs_f64(), time.writing.as_secs_f64());
        let bytes = time.bytes as f64;
        BusUse {
            busy_share: busy / seconds,
            writers_mean: writing / busy,
            writer_gbs: bytes / writing / 1e9,
            busy_gbs: bytes / busy / 1e9,
        }
    }
}

/// When loading reached the screen and when it ended, in seconds since opening.
#[derive(Default)]
struct LoadMarks {
    /// The first frame that showed points, and the points on the GPU then (the rest streamed
    /// while drawing).
    first_frame: Option<(f64, u64)>,
    loaded_s: Option<f64>,
    /// The upload bus's time at the first frame and once loaded.
    bus_at_first: Option<BusTime>,
    bus_at_loaded: Option<BusTime>,
}

impl LoadMarks {
    /// Marks what the frame just drawn with `progress` reached, once each.
    fn note(&mut self, ctx: &GpuContext, began: Instant, progress: &LoadProgress) -> Result<()> {
        if self.first_frame.is_none() && progress.uploaded > 0 {
            // The frame must have reached the screen to count.
            ctx.wait()?;
            self.first_frame = Some((began.elapsed().as_secs_f64(), progress.uploaded));
            self.bus_at_first = Some(bus_time());
        }
        if self.loaded_s.is_none() && progress.is_finished() {
            self.loaded_s = Some(began.elapsed().as_secs_f64());
            self.bus_at_loaded = Some(bus_time());
        }
        Ok(())
    }
}

pub fn run(args: &Args) -> Result<()> {
    let file = args.store.as_path();
    let inputs = [args.store.clone()];
    let (ctx, variant) = crate::render_cmd::open_gpu(&args.draw)?;
    let color = progressive_cmd::resolve_color(&inputs, &args.read, args.draw.color.as_ref())?;
    let target_fps = args.target_fps.unwrap_or(60.0);
    let config = progressive_cmd::config(
        &args.draw,
        &args.read,
        variant,
        color,
        args.virtual_args.vram_budget,
        target_fps,
    );
    let vram_budget = config.vram_budget;
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let bus_at_open = bus_time();
    let began = Instant::now();
    let mut scene = progressive_cmd::open(&ctx, &inputs, config)?;
    let bounds = scene.bounds();
    let flight = Flight::new(args, bounds)?;
    let (path, cameras) = (&flight.path, &flight.cameras);
    let settings = args.draw.settings_for(variant, Some(file));
    let slots = scene.slots().max(1);
    let mut rows: Vec<Row> = Vec::with_capacity(cameras.len());
    let mut marks = LoadMarks::default();
    let mut failure = None;
    let flown = Instant::now();
    let mut last_start = flown;
    // Timings arrive frames later; frame ids count from 1 like the rows.
    let record = |rows: &mut Vec<Row>, report: &pointlet_engine::ProgressiveReport| {
        if let Some((frame, t)) = report.timing {
            if let Some(r) = frame.checked_sub(1).and_then(|k| rows.get_mut(k as usize)) {
                r.reproject_ms = t.reproject_ms;
                r.fill_ms = t.fill_ms;
                r.screen_ms = t.screen_ms;
            }
        }
    };
    for k in 0u32.. {
        scene.limit_frames_in_flight(&ctx, args.in_flight)?;
        let start = Instant::now();
        let t = (start - flown).as_secs_f64();
        let Some(camera) = flight.camera(k as usize, t) else {
            break;
        };
        if let Some(prev) = rows.last_mut() {
            prev.frame_ms = (start - last_start).as_secs_f64() * 1e3;
        }
        last_start = start;
        let report = scene.frame(&ctx, &camera, &settings, &mut target)?;
        if report.failure.is_some() {
            failure = report.failure.clone();
        }
        let loading = !report.progress.is_finished();
        marks.note(&ctx, began, &report.progress)?;
        rows.push(Row {
            frame: k,
            time_s: (start - began).as_secs_f64(),
            frame_ms: 0.0,
            reproject_ms: 0.0,
            fill_ms: 0.0,
            screen_ms: 0.0,
            fill_budget: report.fill_budget,
            share_drawn: report.fill_budget as f64 / slots as f64,
            points_uploaded: report.uploaded_points,
            points_loaded: report.progress.uploaded,
            loading,
        });
        record(&mut rows, &report);
    }
    if let Some(prev) = rows.last_mut() {
        prev.frame_ms = last_start.elapsed().as_secs_f64() * 1e3;
    }
    if let Some(f) = failure {
        bail!("{f}");
    }
    // The path ended: the last camera stays still until the image is final (loading first,
    // if the path was shorter than the load).
    let still = cameras
        .last()
        .copied()
        .unwrap_or_else(|| path.camera_at(path.duration(), &bounds));
    let settle = Instant::now();
    let mut converge_frames = 0u64;
    loop {
        scene.limit_frames_in_flight(&ctx, args.in_flight)?;
        let report = scene.frame(&ctx, &still, &settings, &mut target)?;
        converge_frames += 1;
        if let Some(f) = report.failure {
            bail!("{f}");
        }
        marks.note(&ctx, began, &report.progress)?;
        if report.converged {
            break;
        }
        if settle.elapsed() > CONVERGE_LIMIT {
            bail!(
                "{}: the still view did not converge within {} s",
                file.display(),
                CONVERGE_LIMIT.as_secs()
            );
        }
    }
    ctx.wait()?;
    let converge_s = settle.elapsed().as_secs_f64();
    let progress = scene.progress();
    let times: Vec<f64> = rows.iter().map(|r| r.frame_ms.max(1e-6)).collect();
    let stats = FrameStats::from_frame_times_ms(&times)?;
    let loading_times: Vec<f64> = rows
        .iter()
        .filter(|r| r.loading)
        .map(|r| r.frame_ms.max(1e-6))
        .collect();
    let loading_stats = (!loading_times.is_empty())
        .then(|| FrameStats::from_frame_times_ms(&loading_times))
        .transpose()?;
    let mut stages = StageBreakdown::new(["reproject (GPU)", "fill (GPU)", "screen (GPU)"])?;
    for r in &rows {
        stages.push_frame(&[r.reproject_ms, r.fill_ms, r.screen_ms])?;
    }
    let stage_table = stages.summary();
    let share_drawn = rows.iter().map(|r| r.share_drawn).sum::<f64>() / rows.len().max(1) as f64;
    let (first_frame_s, first_frame_points) = marks.first_frame.unwrap_or((f64::NAN, 0));
    let loaded_s = marks.loaded_s.unwrap_or(f64::NAN);
    // The streaming rate once drawing began (opening and the first batches left out); NaN
    // where everything was there for the first frame.
    let streamed = progress.uploaded.saturating_sub(first_frame_points);
    let after_first_points_per_s = if streamed > 0 && loaded_s > first_frame_s {
        streamed as f64 / (loaded_s - first_frame_s)
    } else {
        f64::NAN
    };
    println!(
        "{}: {} points ({} in the GPU buffer), {}×{}, {} on {}, target {target_fps} fps",
        file.display(),
        scene.points(),
        scene.slots(),
        args.width,
        args.height,
        variant.name(),
        ctx.describe()
    );
    println!("{stats}");
    if let Some(s) = &loading_stats {
        println!("while loading: {s}");
    }
    println!("stage breakdown (ms per frame):");
    for s in &stage_table {
        println!(
            "  {:<18} avg {:>8.3}  median {:>8.3}  max {:>8.3}",
            s.name, s.avg_ms, s.median_ms, s.max_ms
        );
    }
    println!(
        "loading: first frame after {:.3} s, fully loaded after {:.3} s ({:.1} M points/s, {:.0} MB/s)",
        first_frame_s,
        loaded_s,
        progress.points_per_s() / 1e6,
        progress.mb_per_s()
    );
    println!(
        "after the first frame: {} points in {:.3} s ({:.1} M points/s, {:.1} GB/s of 16-byte points)",
        streamed,
        loaded_s - first_frame_s,
        after_first_points_per_s / 1e6,
        after_first_points_per_s * 16.0 / 1e9
    );
    // Over the whole load, and once drawing began.
    let bus_use = |from: Option<BusTime>, from_s: f64| match (from, marks.bus_at_loaded) {
        (Some(a), Some(b)) if loaded_s > from_s && b.bytes > a.bytes => {
            Some(BusUse::new(&b.since(&a), loaded_s - from_s))
        }
        _ => None,
    };
    let bus = bus_use(Some(bus_at_open), 0.0);
    let bus_after_first = bus_use(marks.bus_at_first, first_frame_s);
    for (when, b) in [
        ("loading", &bus),
        ("after the first frame", &bus_after_first),
    ] {
        if let Some(b) = b {
            println!(
                "upload bus, {when}: copies going on {:.1} % of the time, {:.2} at once on \
                 average, each at {:.1} GB/s, {:.1} GB/s while any was",
                b.busy_share * 100.0,
                b.writers_mean,
                b.writer_gbs,
                b.busy_gbs
            );
        }
    }
    println!(
        "converged {converge_s:.3} s ({converge_frames} frames) after the path ended; \
         {:.2} % of the points drawn per frame on average",
        share_drawn * 100.0
    );
    // The path to the GPU alone, after the flight so that it does not disturb it: as many
    // bytes as the buffer's points take (16 each), 16 MiB to 2 GiB.
    let upload = pointlet_gpu::upload_bandwidth(
        &ctx,
        (16 * scene.slots()).clamp(16 << 20, 2 << 30),
        64 << 20,
        3,
    )
    .context("measuring the upload path")?;
    let open = scene.open_times();
    println!(
        "opening: passes {:.1} ms, GPU buffers {:.1} ms ({} of {} chunks; {} in all)",
        open.passes.as_secs_f64() * 1e3,
        open.buffers.as_secs_f64() * 1e3,
        open.chunks_made,
        open.chunks,
        pointlet_core::size::format_bytes(scene.gpu_bytes())
    );
    println!(
        "upload memory: {} batches staged, {} newly made in {:.3} s ({} by Vulkan directly), {} \
         reused; the load thread waited {:.3} s for the render thread to take batches",
        progress.staged_new + progress.staged_reused,
        progress.staged_new,
        progress.staging.as_secs_f64(),
        progress.staged_direct,
        progress.staged_reused,
        progress.queue_waited.as_secs_f64()
    );
    println!(
        "upload path ({} MB): threads write mapped upload memory at {:.1} GB/s, the GPU copies it at {:.1} GB/s; loading moved {:.1} GB/s of 16-byte points",
        upload.bytes / 1_000_000,
        upload.write_gbs,
        upload.copy_gbs,
        progress.points_per_s() * 16.0 / 1e9
    );
    if let (Some(w), Some(c), Some(m)) = (
        upload.host_write_gbs,
        upload.host_copy_gbs,
        upload.host_make_gbs,
    ) {
        println!(
            "from host memory instead: threads write it at {w:.1} GB/s, the GPU pulls it over \
             the bus at {c:.1} GB/s; the driver makes it at {m:.2} GB/s"
        );
    }
    if let Some(p) = &args.plot {
        write_plot(p, &rows)?;
    }
    if let Some(p) = &args.json {
        let summary = Summary {
            file: file.display().to_string(),
            file_bytes: progress.file_bytes,
            points: scene.points(),
            slots: scene.slots(),
            adapter: ctx.describe(),
            variant: variant.name(),
            width: args.width,
            height: args.height,
            vram_budget,
            target_fps,
            realtime: args.realtime,
            first_frame_s,
            after_first_points_per_s,
            loaded_s,
            load_points_per_s: progress.points_per_s(),
            load_mb_per_s: progress.mb_per_s(),
            converge_s,
            converge_frames,
            share_drawn,
            upload_bytes: upload.bytes,
            upload_write_gbs: upload.write_gbs,
            upload_copy_gbs: upload.copy_gbs,
            upload_host_write_gbs: upload.host_write_gbs,
            upload_host_copy_gbs: upload.host_copy_gbs,
            upload_host_make_gbs: upload.host_make_gbs,
            staged_new: progress.staged_new,
            staged_reused: progress.staged_reused,
            staged_direct: progress.staged_direct,
            open_passes_s: open.passes.as_secs_f64(),
            open_buffers_s: open.buffers.as_secs_f64(),
            gpu_bytes: scene.gpu_bytes(),
            staging_s: progress.staging.as_secs_f64(),
            bus,
            bus_after_first,
            queue_waited_s: progress.queue_waited.as_secs_f64(),
            loading_stats,
            stats: &stats,
            stages: &stage_table,
            frames: &rows,
        };
        std::fs::write(p, serde_json::to_string_pretty(&summary)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

fn write_plot(path: &Path, rows: &[Row]) -> Result<()> {
    let series = |name: &str, k: usize, f: &dyn Fn(&Row) -> f64| Series {
        name: name.to_string(),
        color: pointlet_report::palette(k),
        points: rows.iter().map(|r| (r.frame as f64, f(r))).collect(),
    };
    let all = [
        series("frame", 0, &|r| r.frame_ms),
        series("fill (GPU)", 1, &|r| r.fill_ms),
        series("reproject (GPU)", 2, &|r| r.reproject_ms),
        series("screen (GPU)", 4, &|r| r.screen_ms),
    ];
    write_series(path, "frame time along the path (progressive)", &all)
}
