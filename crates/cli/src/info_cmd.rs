//! `pointlet info`: what a store or a point file holds.

use anyhow::{Context, Result};
use pointlet_core::{Aabb, PointLayout, SourceMeta, Vlr};
use serde_json::{json, Value};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A `.pointlet` store or any supported point file.
    pub input: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// For stores: verify every checksum (reads the whole file).
    #[arg(long)]
    pub verify: bool,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

pub fn run(args: Args) -> Result<()> {
    let info = if crate::load::is_store_path(&args.input) {
        args.read.refuse_for_store(&args.input)?;
        store_info(&args)?
    } else {
        let reader = crate::load::open_point_file(&args.input, &args.read)?;
        file_info(reader.meta())
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        print_text(&args.input, &info);
    }
    Ok(())
}

fn store_info(args: &Args) -> Result<Value> {
    let store = pointlet_store::Store::open(&args.input)
        .with_context(|| format!("opening store {}", args.input.display()))?;
    if args.verify {
        store
            .verify()
            .with_context(|| format!("verifying {}", args.input.display()))?;
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
        "bounds": bounds_json(&h.bounds),
        "scale": h.quantization.scale,
        "offset": h.quantization.offset,
        "attributes": attributes(&h.layout),
        "las_point_format": h.las_point_format,
        "crs": crs(&h.vlrs),
        "sources": h.sources,
        "verified": args.verify,
    }))
}

fn file_info(m: &SourceMeta) -> Value {
    json!({
        "format": m.format,
        "points": m.point_count,
        "bounds": bounds_json(&m.bounds),
        "scale": m.quantization.map(|q| q.scale),
        "offset": m.quantization.map(|q| q.offset),
        "attributes": attributes(&m.layout),
        "las_point_format": m.las_point_format,
        "crs": crs(&m.vlrs),
    })
}

fn bounds_json(b: &Aabb) -> Value {
    json!({ "min": b.min, "max": b.max })
}

/// Attribute names in the order the store keeps its streams.
pub fn attributes(l: &PointLayout) -> Vec<String> {
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
        a.push(format!("extra_bytes[{}]", l.extra_bytes));
    }
    a
}

/// The CRS as well as the records allow: WKT text, or the EPSG code of the GeoTIFF keys.
pub fn crs(vlrs: &[Vlr]) -> Value {
    for v in vlrs.iter().filter(|v| v.is_crs()) {
        if v.record_id == 2112 {
            let wkt = String::from_utf8_lossy(&v.data)
                .trim_end_matches('\0')
                .to_string();
            return json!({ "wkt": wkt });
        }
    }
    if let Some(v) = vlrs.iter().find(|v| v.is_crs() && v.record_id == 34735) {
        let keys: Vec<u16> = v
            .data
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        // Entries of 4 u16 after a 4 u16 header: projected (3072) or geographic (2048) EPSG code.
        let epsg = keys
            .chunks_exact(4)
            .skip(1)
            .find(|e| (e[0] == 3072 || e[0] == 2048) && e[1] == 0)
            .map(|e| e[3]);
        return json!({ "geotiff_keys": keys.len().saturating_sub(4) / 4, "epsg": epsg });
    }
    Value::Null
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
    println!("  bounds min  {}", v["bounds"]["min"]);
    println!("  bounds max  {}", v["bounds"]["max"]);
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
    let crs_text = if let Some(w) = crs.get("wkt").and_then(|w| w.as_str()) {
        w.chars().take(100).collect::<String>()
    } else if let Some(e) = crs.get("epsg").and_then(|e| e.as_u64()) {
        format!("EPSG:{e} (GeoTIFF keys)")
    } else if crs.is_null() {
        "none".to_string()
    } else {
        "GeoTIFF keys".to_string()
    };
    println!("  crs         {crs_text}");
    if v.get("verified").and_then(|b| b.as_bool()) == Some(true) {
        println!("  checksums   all verified");
    }
}
