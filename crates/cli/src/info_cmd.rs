//! `pointlet info`: what a store or a point file holds.

use anyhow::{Context, Result};
use pointlet_core::crs::{Crs, CrsId};
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::{Aabb, LasFields, PointLayout, SourceMeta, Vlr};
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A `.pointlet` store or any supported point file.
    pub input: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Read everything: for stores, verify every checksum; for point files, read every point
    /// (LAS/LAZ files of up to 2M points are read anyway) to give their real bounds.
    #[arg(long)]
    pub verify: bool,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

/// Point files up to this many points are read whole to check the header bounds.
const READ_POINTS_UP_TO: u64 = 2_000_000;

pub fn run(args: Args) -> Result<()> {
    let info = if crate::load::is_store_path(&args.input) {
        store_info(&args)?
    } else {
        let mut reader = crate::load::open_point_file(&args.input, &args.read)?;
        let meta = reader.meta().clone();
        // Only LAS bounds are a claim; PLY and text readers measured theirs already.
        let small_las = meta.las.is_some() && meta.point_count <= READ_POINTS_UP_TO;
        let points_bounds = if args.verify || small_las {
            Some(read_bounds(reader.as_mut())?)
        } else {
            None
        };
        file_info(&meta, points_bounds)
    };
    if info["header_bounds_agree"] == Value::Bool(false) {
        eprintln!(
            "warning: the header bounds of {} are not the bounds of its points",
            args.input.display()
        );
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print_text(&args.input, &info);
    }
    Ok(())
}

fn store_info(args: &Args) -> Result<Value> {
    let store = pointlet_store::Store::open(&args.input)?;
    if args.verify {
        store.verify().context("verifying")?;
    }
    let h = store.header();
    let pl = store.pointlets();
    let counts: Vec<u64> = pl.iter().map(|p| p.count as u64).collect();
    let diag: Vec<f64> = pl.iter().map(|p| p.aabb.diagonal()).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / (v.len().max(1) as f64);
    let counts_f: Vec<f64> = counts.iter().map(|c| *c as f64).collect();
    Ok(json!({
        "format": format!("pointlet store v{}", h.version),
        "points": h.points,
        "pointlets": pl.len(),
        "pointlet_size": h.pointlet_size,
        "pointlet_points": {
            "min": counts.iter().min(),
            "max": counts.iter().max(),
            "mean": mean(&counts_f),
        },
        "pointlet_extent": {
            "min": diag.iter().cloned().fold(f64::INFINITY, f64::min),
            "max": diag.iter().cloned().fold(0.0, f64::max),
            "mean": mean(&diag),
        },
        "bounds": bounds_json(&h.bounds, Some(h.quantization.scale)),
        "scale": h.quantization.scale,
        "offset": h.quantization.offset.map(|o| o + 0.0),
        "attributes": attributes(&h.layout, &h.vlrs),
        "las_point_format": h.las_point_format,
        "crs": crs(&h.vlrs),
        "file_source_id": h.las.as_ref().map(|l| l.file_source_id),
        "gps_time_type": gps_time_type(h.las.as_ref(), &h.layout),
        "sources": h.sources,
        "verified": args.verify,
    }))
}

/// The bounds of every point of the file (reading it whole).
fn read_bounds(reader: &mut dyn pointlet_io::PointReader) -> Result<Aabb> {
    let mut bounds = Aabb::EMPTY;
    while let Some(batch) = reader.read_batch(1 << 20)? {
        batch.xyz.iter().for_each(|p| bounds.grow(*p));
    }
    Ok(bounds)
}

/// A point file's info. LAS bounds are the header's claim (`header_bounds`); `bounds` are the
/// points' own when they were read (PLY and text bounds come from reading the points anyway).
fn file_info(m: &SourceMeta, points_bounds: Option<Aabb>) -> Value {
    let claimed = m.las.is_some();
    let scale = m.quantization.map(|q| q.scale);
    let bounds = match (claimed, points_bounds) {
        (_, Some(b)) => bounds_json(&b, scale),
        (false, None) => bounds_json(&m.bounds, scale),
        (true, None) => Value::Null,
    };
    // Within half a quantization step, the header says what the points say.
    let agree = points_bounds.filter(|_| claimed).map(|p| {
        let half = m
            .quantization
            .map_or([0.0; 3], |q| q.scale.map(|s| s / 2.0));
        (0..3).all(|a| {
            (p.min[a] - m.bounds.min[a]).abs() <= half[a] * 1.001
                && (p.max[a] - m.bounds.max[a]).abs() <= half[a] * 1.001
        })
    });
    json!({
        "format": m.format,
        "points": m.point_count,
        "bounds": bounds,
        "header_bounds": if claimed { bounds_json(&m.bounds, scale) } else { Value::Null },
        "header_bounds_agree": agree,
        "file_source_id": m.las.as_ref().map(|l| l.file_source_id),
        "gps_time_type": gps_time_type(m.las.as_ref(), &m.layout),
        "scale": m.quantization.map(|q| q.scale),
        "offset": m.quantization.map(|q| q.offset.map(|o| o + 0.0)),
        "attributes": attributes(&m.layout, &m.vlrs),
        "las_point_format": m.las_point_format,
        "crs": crs(&m.vlrs),
    })
}

/// "adjusted standard" or "week" (the LAS global-encoding bit), for LAS data with GPS times.
fn gps_time_type(las: Option<&LasFields>, layout: &PointLayout) -> Option<&'static str> {
    let las = las.filter(|_| layout.gps_time)?;
    Some(
        if las.global_encoding & LasFields::ADJUSTED_STANDARD_GPS_TIME != 0 {
            "adjusted standard"
        } else {
            "week"
        },
    )
}

/// Bounds to the data's precision (its quantization `scale`), as the header's doubles would
/// print 848899.7000000001.
fn bounds_json(b: &Aabb, scale: Option<[f64; 3]>) -> Value {
    let round = |p: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|k| round_to_step(p[k], scale.map_or(0.0, |s| s[k])))
    };
    json!({ "min": round(b.min), "max": round(b.max) })
}

/// `v` with the decimals of `step` (0.01 → 2; none for a step ≤ 0), never -0.0 (adding 0.0
/// turns it into 0.0).
fn round_to_step(v: f64, step: f64) -> f64 {
    if !(step > 0.0 && v.is_finite()) {
        return v + 0.0;
    }
    let factor = 10f64.powi((-step.log10()).ceil().clamp(0.0, 15.0) as i32);
    (v * factor).round() / factor + 0.0
}

/// Attribute names in the order the store keeps its streams; the extra bytes by the names
/// and types their record gives (`height (i16, extra)`), what it leaves undescribed as
/// `extra_bytes[N]`.
pub fn attributes(l: &PointLayout, vlrs: &[Vlr]) -> Vec<String> {
    let mut a: Vec<String> = [
        "position",
        "intensity",
        "return_number",
        "number_of_returns",
        "classification",
        "classification_flags",
        "scan_direction",
        "edge_of_flight_line",
        "scanner_channel",
        "scan_angle",
        "user_data",
        "point_source_id",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    if l.gps_time {
        a.push("gps_time".into());
    }
    if l.rgb {
        a.push("rgb".into());
    }
    if l.nir {
        a.push("nir".into());
    }
    if l.waveform {
        a.push("waveform".into());
    }
    if l.extra_bytes > 0 {
        let extra = ExtraAttributes::from_vlrs(vlrs, usize::from(l.extra_bytes));
        for x in &extra.attributes {
            a.push(format!("{} ({}, extra)", x.name, x.kind.name()));
        }
        match (&extra.problem, extra.undocumented) {
            (Some(why), n) => a.push(format!("extra_bytes[{n}] ({why})")),
            (None, 0) => {}
            (None, n) => a.push(format!("extra_bytes[{n}]")),
        }
    }
    a
}

/// The CRS the records name (see `pointlet_core::crs`): `name` like `EPSG:2994`,
/// `EPSG:2994 + EPSG:5703 vertical` or `user-defined (citation)`; null without CRS records.
pub fn crs(vlrs: &[Vlr]) -> Value {
    let Some(c) = Crs::from_vlrs(vlrs) else {
        return Value::Null;
    };
    let epsg = |id: &Option<CrsId>| match id {
        Some(CrsId::Epsg(code)) => Some(*code),
        _ => None,
    };
    json!({
        "name": c.to_string(),
        "epsg": epsg(&c.horizontal),
        "vertical_epsg": epsg(&c.vertical),
        "user_defined": matches!(c.horizontal, Some(CrsId::UserDefined(_))),
        "encoding": c.encoding,
        "wkt": c.wkt,
    })
}

fn print_text(path: &std::path::Path, v: &Value) {
    println!("{}", path.display());
    let get = |k: &str| v.get(k).cloned().unwrap_or(Value::Null);
    println!("  format      {}", get("format").as_str().unwrap_or("?"));
    println!("  points      {}", get("points"));
    if let Some(p) = v.get("pointlets") {
        println!(
            "  pointlets   {} of {} points (min {}, mean {:.1}, max {})",
            p,
            get("pointlet_size"),
            v["pointlet_points"]["min"],
            v["pointlet_points"]["mean"].as_f64().unwrap_or(0.0),
            v["pointlet_points"]["max"]
        );
        println!(
            "  extent      pointlet AABB diagonal min {:.3}, mean {:.3}, max {:.3}",
            v["pointlet_extent"]["min"].as_f64().unwrap_or(0.0),
            v["pointlet_extent"]["mean"].as_f64().unwrap_or(0.0),
            v["pointlet_extent"]["max"].as_f64().unwrap_or(0.0)
        );
    }
    if !v["header_bounds"].is_null() {
        println!("  header bounds min  {}", v["header_bounds"]["min"]);
        println!("  header bounds max  {}", v["header_bounds"]["max"]);
    }
    if v["bounds"].is_null() {
        println!("  bounds      not read (--verify reads every point)");
    } else {
        println!("  bounds min  {}", v["bounds"]["min"]);
        println!("  bounds max  {}", v["bounds"]["max"]);
    }

    if !get("scale").is_null() {
        println!("  scale       {}", get("scale"));
        println!("  offset      {}", get("offset"));
    }
    let attrs: Vec<String> = get("attributes")
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|s| s.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();
    println!("  attributes  {}", attrs.join(", "));
    let crs = get("crs");
    let crs_text = match (crs["name"].as_str(), crs["encoding"].as_str()) {
        (Some(name), Some(encoding)) => format!("{name} ({encoding})"),
        _ => "none".to_string(),
    };
    println!("  crs         {crs_text}");
    if v.get("verified").and_then(|b| b.as_bool()) == Some(true) {
        println!("  checksums   all verified");
    }
}
