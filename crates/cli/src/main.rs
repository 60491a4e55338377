//! `pointlet`: the command-line front end. Thin by design: it parses arguments and wires the
//! crates' stages together (io → store → gpu); every real decision lives in a library crate.

mod bench_alloc_cmd;
mod bench_cmd;
mod bench_progressive;
mod bench_raster_cmd;
mod bench_read_cmd;
mod convert_cmd;
mod export_3dtiles_cmd;
mod export_cmd;
mod flags;
mod generate_cmd;
mod image_out;
mod info_cmd;
mod load;
mod metrics_cmd;
mod progress;
mod progressive_cmd;
mod render_cmd;
mod scene;
mod serve_cmd;
mod signals;
mod tiles_cmd;
mod view_args;
mod view_cmd;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "pointlet",
    version,
    about = "Real-time rendering of point clouds of any size"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Convert LAS/LAZ/COPC/PLY/XYZ files (or folders) into one pointlet store.
    Convert(convert_cmd::Args),
    /// Generate a deterministic synthetic LiDAR scene (LAS, LAZ or a pointlet store).
    Generate(generate_cmd::Args),
    /// Describe a store or any supported point file.
    Info(info_cmd::Args),
    /// Export a store (or part of it) back to LAS/LAZ 1.4.
    Export(export_cmd::Args),
    /// Export a store as a 3D Tiles 1.1 tileset (GLB points, metadata, ECEF when the CRS is known).
    #[command(name = "export-3dtiles")]
    Export3dTiles(export_3dtiles_cmd::Args),
    /// Pointlet quality of Morton, Hilbert and k-d tree partitions (the paper's Table I).
    Metrics(metrics_cmd::Args),
    /// Render one frame headless into a PNG (no INPUT: the built-in demo scene).
    Render(render_cmd::Args),
    /// Open the interactive viewer (no INPUT: the built-in demo scene).
    View(view_cmd::Args),
    /// Time every rasterizer × vertex order × encoding against a copy kernel (paper Table 1).
    BenchRaster(bench_raster_cmd::Args),
    /// Time the GPU buffer suballocator against a buffer per allocation (WebGPU paper Table 2–3).
    BenchAlloc(bench_alloc_cmd::Args),
    /// Fly a store along a camera path: FPS statistics, stage breakdown, memory; or --quality.
    Bench(bench_cmd::Args),
    /// Only decode inputs and report points/s (the baseline for `convert`).
    BenchRead(bench_read_cmd::Args),
    /// Serve stores over HTTP (byte ranges, ETags, CORS) for the web viewer and remote readers.
    Serve(serve_cmd::Args),
}

/// Output piped into `head` and closed early ends the program quietly, as Unix tools do,
/// instead of a panic on the failed print.
fn default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Mesa's Vulkan device-select layer asks the Wayland server which GPU drives the screen, and
/// without a session runtime folder (headless machines) libwayland prints `error:
/// XDG_RUNTIME_DIR is invalid or not set` instead. No Wayland server can be reached then, so
/// the layer is turned off there, unless the user configured it.
fn quiet_device_select() {
    let runtime_dir = std::env::var_os("XDG_RUNTIME_DIR");
    let wayland_reachable = runtime_dir.is_some_and(|d| std::path::Path::new(&d).is_absolute());
    let configured = ["NODEVICE_SELECT", "MESA_VK_DEVICE_SELECT", "DRI_PRIME"];
    if !wayland_reachable && configured.iter().all(|v| std::env::var_os(v).is_none()) {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

fn main() -> ExitCode {
    default_sigpipe();
    quiet_device_select();
    // Named, so that profiles and thread samples tell the pool from the other threads; a pool
    // already built (never, here) keeps its names.
    let _ = rayon::ThreadPoolBuilder::new()
        .thread_name(|i| format!("pool-{i}"))
        .build_global();
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Some((name, sub)) = matches.subcommand() {
        if let Err(message) = flags::check(&cli.command, &flags::Given(sub)) {
            let mut cmd = Cli::command();
            cmd.build();
            if let Some(sub_cmd) = cmd.find_subcommand_mut(name) {
                sub_cmd
                    .error(clap::error::ErrorKind::ArgumentConflict, message)
                    .exit();
            }
        }
    }
    let result = match cli.command {
        Command::Convert(a) => convert_cmd::run(a),
        Command::Generate(a) => generate_cmd::run(a),
        Command::Info(a) => info_cmd::run(a),
        Command::Export(a) => export_cmd::run(a),
        Command::Export3dTiles(a) => export_3dtiles_cmd::run(a),
        Command::Metrics(a) => metrics_cmd::run(a),
        Command::Render(a) => render_cmd::run(a),
        Command::View(a) => view_cmd::run(a),
        Command::BenchRaster(a) => bench_raster_cmd::run(a),
        Command::BenchAlloc(a) => bench_alloc_cmd::run(a),
        Command::Bench(a) => bench_cmd::run(a),
        Command::BenchRead(a) => bench_read_cmd::run(a),
        Command::Serve(a) => serve_cmd::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// The whole context chain on one line ("converting x: reading y: ..."), each cause once: an
/// error that prints its source in its own message (as many libraries' do) would repeat it.
fn chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let message = cause.to_string();
        if line.ends_with(&format!(": {message}")) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&message);
    }
    line
}

/// Bytes of memory available now (`MemAvailable` of /proc/meminfo), where the system says.
pub(crate) fn available_memory() -> Option<u64> {
    meminfo_bytes("MemAvailable:")
}

/// Bytes of memory the machine has (`MemTotal` of /proc/meminfo), where the system says.
pub(crate) fn total_memory() -> Option<u64> {
    meminfo_bytes("MemTotal:")
}

/// One kB field of /proc/meminfo, in bytes.
fn meminfo_bytes(field: &str) -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = meminfo.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Clap value parser for byte sizes such as `512MiB`.
pub(crate) fn parse_bytes_arg(s: &str) -> Result<u64, String> {
    pointlet_core::size::parse_bytes(s).map_err(|e| e.reason())
}

/// Clap value parser for the LoD's point bucket B (a count of at least 1; the engine refuses 0
/// too, but a usage error comes before any work).
pub(crate) fn parse_bucket_arg(s: &str) -> Result<u64, String> {
    match parse_count_arg(s)? {
        0 => Err("the point bucket B must be at least 1 point".into()),
        b => Ok(b),
    }
}

/// Clap value parser for a frame rate (1–1000 frames per second).
pub(crate) fn parse_fps_arg(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (1.0..=1000.0).contains(&v) => Ok(v),
        _ => Err("expected a frame rate between 1 and 1000".into()),
    }
}

/// Clap value parser for counts such as `25M`.
pub(crate) fn parse_count_arg(s: &str) -> Result<u64, String> {
    pointlet_core::size::parse_count(s).map_err(|e| e.reason())
}
