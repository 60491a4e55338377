//! `pointlet bench-raster`: every rasterizer × vertex order × encoding × view, timed with GPU
//! timestamp queries, beside a copy kernel measured in the same process (the paper's Table 1).

use crate::render_cmd::reorder;
use crate::view_args::{parse_encoding, parse_order, parse_shape, parse_variant};
use anyhow::{bail, Context, Result};
use pointlet_core::order::VertexOrder;
use pointlet_core::Camera;
use pointlet_gpu::{
    copy_bandwidth, GpuCloud, PointEncoding, PointSize, RasterVariant, RenderSettings,
    RenderTarget, Renderer, SplatRaster, SplatSettings, SplatShape,
};
use serde::Serialize;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A store or any point file; without one, the demo scene of --points points.
    pub input: Option<PathBuf>,
    /// Points of the generated scene (without INPUT).
    #[arg(long, default_value_t = 20_000_000, value_parser = crate::parse_count_arg)]
    pub points: u64,
    /// Timed frames per configuration (after 2 warm-up frames); the median is reported.
    #[arg(long, default_value_t = 20)]
    pub frames: u32,
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    /// Rasterizers to time (default: all the adapter supports).
    #[arg(long, value_delimiter = ',', value_parser = parse_variant)]
    pub variants: Vec<RasterVariant>,
    /// Vertex orders (default: all).
    #[arg(long, value_delimiter = ',', value_parser = parse_order)]
    pub orders: Vec<VertexOrder>,
    /// Encodings (default: both).
    #[arg(long, value_delimiter = ',', value_parser = parse_encoding)]
    pub encodings: Vec<PointEncoding>,
    #[arg(long, default_value_t = 4096)]
    pub page_size: u32,
    #[arg(long)]
    pub adapter: Option<String>,
    /// Point size of every rasterizer: pixels (1–32) or `adaptive`. Beyond one pixel the
    /// billboard-quad pipeline is timed too (row `quads`), and hw-points is left out.
    #[arg(long, default_value = "1", value_parser = PointSize::parse)]
    pub point_size: PointSize,
    /// Shape of points larger than a pixel: square or circle.
    #[arg(long, default_value = "square", value_parser = parse_shape)]
    pub splat_shape: SplatShape,
    /// Write every measurement as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

#[derive(Serialize)]
struct Row {
    variant: &'static str,
    order: &'static str,
    encoding: &'static str,
    view: &'static str,
    median_ms: f64,
    min_ms: f64,
    /// Median wall-clock time of the whole frame (submit to completion): a sanity bound.
    wall_ms: f64,
    points_per_s: f64,
    /// Nominal: every byte of every point per geometry pass (early-z reads fewer colours).
    gb_per_s: f64,
    /// The positions alone, which every rasterizer reads: this cannot exceed the copy kernel.
    position_gb_per_s: f64,
    fraction_of_copy: Option<f64>,
}

#[derive(Serialize)]
struct Report {
    adapter: String,
    input: String,
    points: u64,
    width: u32,
    height: u32,
    frames: u32,
    page_size: u32,
    point_size: String,
    splat_shape: &'static str,
    copy_gb_per_s: Option<f64>,
    /// Why the timings cannot be true (then `rows` is empty): see [`implausible`].
    unreliable: Option<String>,
    rows: Vec<Row>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

pub fn run(args: Args) -> Result<()> {
    let ctx = crate::render_cmd::open_adapter(&args.adapter)?;
    if !ctx.caps.timestamps {
        bail!(
            "{} has no timestamp queries: cannot time GPU passes",
            ctx.describe()
        );
    }
    // Read before the copy kernel is timed: a bad input fails at once.
    let scene = crate::scene::load(
        args.input.as_slice(),
        &crate::load::ReadArgs::default(),
        None,
        args.points,
    )?;
    let variants: Vec<RasterVariant> = if args.variants.is_empty() {
        RasterVariant::ALL.to_vec()
    } else {
        args.variants.clone()
    };
    let splats = SplatSettings {
        size: args.point_size,
        shape: args.splat_shape,
        ..Default::default()
    };
    let mut configs: Vec<(&'static str, RenderSettings)> = variants
        .into_iter()
        .filter(|v| match v.unsupported_reason(&ctx.caps) {
            Some(why) => {
                eprintln!("skipping {}: {why}", v.name());
                false
            }
            None if *v == RasterVariant::HwPoints && !splats.is_pixel() => {
                eprintln!("skipping hw-points: it draws one-pixel points");
                false
            }
            None => true,
        })
        .map(|v| {
            let settings = RenderSettings {
                variant: v,
                splats,
                ..Default::default()
            };
            (v.name(), settings)
        })
        .collect();
    if !splats.is_pixel() {
        // The same splats as billboard quads, with the fastest closest-point rasterizer's rules.
        let settings = RenderSettings {
            variant: RasterVariant::ReduceEarlyZ.fallback(&ctx.caps),
            splats: SplatSettings {
                raster: SplatRaster::Quads,
                ..splats
            },
            ..Default::default()
        };
        if settings.variant.accumulates() {
            configs.push(("quads", settings));
        }
    }
    let names: Vec<&'static str> = configs.iter().map(|(n, _)| *n).collect();
    let orders = if args.orders.is_empty() {
        VertexOrder::ALL.to_vec()
    } else {
        args.orders.clone()
    };
    let encodings = if args.encodings.is_empty() {
        PointEncoding::ALL.to_vec()
    } else {
        args.encodings.clone()
    };
    let copy = copy_bandwidth(&ctx, 1 << 30, 10)?;
    eprintln!(
        "{}: copy kernel {}",
        ctx.describe(),
        copy.map(|g| format!("{g:.1} GB/s"))
            .unwrap_or_else(|| "n/a".into())
    );
    let views: [(&'static str, Camera); 2] = [
        ("overview", Camera::overview(&scene.bounds, 60.0)),
        ("closeup", Camera::closeup(&scene.bounds, 60.0)),
    ];
    let points = scene.set.len() as u64;
    eprintln!("{}: {points} points", scene.name);
    let mut target = RenderTarget::new(&ctx, args.width, args.height)?;
    let mut renderer = Renderer::new(&ctx);
    let mut rows = Vec::new();
    for order in &orders {
        let set = reorder(scene.set.clone(), *order);
        for encoding in &encodings {
            let mut cloud = GpuCloud::upload(&ctx, &set, *encoding, args.page_size)
                .with_context(|| format!("uploading {} points", points))?;
            for (view, camera) in &views {
                for (name, settings) in &configs {
                    let variant = &settings.variant;
                    let mut times = Vec::new();
                    let mut walls = Vec::new();
                    for frame in 0..args.frames + 2 {
                        let started = std::time::Instant::now();
                        renderer.render(&ctx, &mut cloud, camera, settings, &mut target)?;
                        let t = renderer
                            .timing(&ctx, &mut target)?
                            .context("timestamps vanished")?;
                        if frame >= 2 {
                            times.push(t.raster_ms);
                            walls.push(started.elapsed().as_secs_f64() * 1e3);
                        }
                    }
                    let passes = if settings.quads() {
                        1
                    } else {
                        variant.geometry_passes()
                    };
                    let bytes = (cloud.points * encoding.bytes_per_point()
                        + cloud.fine_points() * 4)
                        * passes as u64;
                    let med = median(times.clone());
                    let gbs = bytes as f64 / (med * 1e6);
                    rows.push(Row {
                        variant: name,
                        order: order.name(),
                        encoding: encoding.name(),
                        view,
                        median_ms: med,
                        min_ms: times.iter().cloned().fold(f64::INFINITY, f64::min),
                        wall_ms: median(walls),
                        points_per_s: points as f64 / (med * 1e-3),
                        gb_per_s: gbs,
                        position_gb_per_s: (cloud.points * encoding.position_bytes()) as f64
                            / (med * 1e6),
                        fraction_of_copy: copy.map(|c| gbs / c),
                    });
                    // Progress only; a time no GPU could reach is marked as it is shown.
                    let doubt = if implausible(&rows[rows.len() - 1..], copy).is_some() {
                        " (implausible)"
                    } else {
                        ""
                    };
                    eprintln!(
                        "  {:<9} {:<15} {:<8} {:<14} {:>9.3} ms{doubt}",
                        encoding.name(),
                        order.name(),
                        view,
                        name,
                        med
                    );
                }
            }
        }
    }
    let unreliable = implausible(&rows, copy);
    match &unreliable {
        Some(why) => {
            println!(
                "timings unreliable on {}: {why}. This driver's GPU timestamps do not measure the work; no results are reported.",
                ctx.describe()
            );
            rows.clear();
        }
        None => {
            print_tables(&rows, &names, &orders, &encodings);
            print_summary(&rows, copy);
        }
    }
    if let Some(path) = &args.json {
        let report = Report {
            adapter: ctx.describe(),
            input: scene.name.clone(),
            points,
            width: args.width,
            height: args.height,
            frames: args.frames,
            page_size: args.page_size,
            point_size: args.point_size.name(),
            splat_shape: args.splat_shape.name(),
            copy_gb_per_s: copy,
            unreliable,
            rows,
        };
        std::fs::write(path, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Why timings cannot be true, if they cannot: a time that is not positive, or a rasterizer
/// reading the points' positions alone faster than the copy kernel moves memory.
fn implausible(rows: &[Row], copy: Option<f64>) -> Option<String> {
    let name = |r: &Row| format!("{} ({} {} {})", r.variant, r.encoding, r.order, r.view);
    if let Some(c) = copy.filter(|c| !(c.is_finite() && *c > 0.0)) {
        return Some(format!("the copy kernel timed at {c} GB/s"));
    }
    let positive = |ms: f64| ms.is_finite() && ms > 0.0;
    if let Some(r) = rows
        .iter()
        .find(|r| !positive(r.median_ms) || !positive(r.min_ms))
    {
        return Some(format!(
            "{} timed at {} ms (median), {} ms (min)",
            name(r),
            r.median_ms,
            r.min_ms
        ));
    }
    let fastest = rows
        .iter()
        .max_by(|a, b| a.position_gb_per_s.total_cmp(&b.position_gb_per_s))?;
    let copy = copy?;
    (fastest.position_gb_per_s > copy).then(|| {
        format!(
            "{} would read the positions alone at {:.1} GB/s, {:.0} % of the {:.1} GB/s the copy kernel reaches",
            name(fastest),
            fastest.position_gb_per_s,
            fastest.position_gb_per_s / copy * 100.0,
            copy
        )
    })
}

fn print_tables(
    rows: &[Row],
    variants: &[&'static str],
    orders: &[VertexOrder],
    encodings: &[PointEncoding],
) {
    for encoding in encodings {
        for view in ["overview", "closeup"] {
            println!("\n{} / {view}: median raster time (ms)", encoding.name());
            print!("{:<15}", "");
            for o in orders {
                print!("{:>16}", o.name());
            }
            println!();
            for v in variants {
                print!("{:<15}", v);
                for o in orders {
                    let cell = rows.iter().find(|r| {
                        r.variant == *v
                            && r.order == o.name()
                            && r.encoding == encoding.name()
                            && r.view == view
                    });
                    match cell {
                        Some(r) => print!("{:>16.3}", r.median_ms),
                        None => print!("{:>16}", "-"),
                    }
                }
                println!();
            }
        }
    }
}

fn print_summary(rows: &[Row], copy: Option<f64>) {
    let best = |view: &str, compute: bool| {
        rows.iter()
            .filter(|r| r.view == view && (r.variant != "hw-points") == compute)
            .min_by(|a, b| a.median_ms.total_cmp(&b.median_ms))
    };
    println!();
    if let Some(c) = copy {
        println!("copy kernel: {c:.1} GB/s");
    }
    for view in ["overview", "closeup"] {
        if let (Some(c), Some(h)) = (best(view, true), best(view, false)) {
            println!(
                "{view}: best compute {} ({} {}) {:.3} ms = {:.2} G points/s, {:.1} GB/s{}; best hw-points {:.3} ms ({}); speed-up {:.1}×",
                c.variant,
                c.encoding,
                c.order,
                c.median_ms,
                c.points_per_s / 1e9,
                c.gb_per_s,
                c.fraction_of_copy
                    .map(|f| format!(" ({:.0} % of copy)", f * 100.0))
                    .unwrap_or_default(),
                h.median_ms,
                h.order,
                h.median_ms / c.median_ms
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(median_ms: f64, position_gb_per_s: f64) -> Row {
        Row {
            variant: "early-z",
            order: "original",
            encoding: "full16",
            view: "overview",
            median_ms,
            min_ms: median_ms,
            wall_ms: 1.0,
            points_per_s: 1e9,
            gb_per_s: position_gb_per_s * 1.25,
            position_gb_per_s,
            fraction_of_copy: Some(position_gb_per_s * 1.25 / 100.0),
        }
    }

    #[test]
    fn faster_than_copy_or_timeless_is_implausible() {
        // Nominal bytes may pass the copy kernel's figure (colours read by winners only).
        assert_eq!(implausible(&[row(1.0, 95.0)], Some(100.0)), None);
        let why = implausible(&[row(1.0, 80.0), row(0.01, 9620.0)], Some(100.0)).expect("96×");
        assert!(why.contains("9620 %"), "{why}");
        assert!(implausible(&[row(0.0, 50.0)], Some(100.0)).is_some());
        assert!(implausible(&[row(1.0, 50.0)], Some(f64::INFINITY)).is_some());
    }
}
