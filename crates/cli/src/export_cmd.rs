//! `pointlet export`: a store (or the part of it inside a box) back to LAS/LAZ 1.4, with the
//! records and header fields the store kept (waveform data included, so descriptors stay valid).

use anyhow::{bail, Context, Result};
use pointlet_core::{Aabb, PointBatch};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// The store to export.
    pub store: PathBuf,
    /// `.las` or `.laz`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Only points inside xmin,ymin,zmin,xmax,ymax,zmax (data coordinates, inclusive).
    #[arg(long, value_parser = parse_bbox)]
    pub bbox: Option<Aabb>,
}

fn parse_bbox(s: &str) -> Result<Aabb, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| "expected six numbers xmin,ymin,zmin,xmax,ymax,zmax".to_string())?;
    if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
        return Err("expected six finite numbers xmin,ymin,zmin,xmax,ymax,zmax".to_string());
    }
    let b = Aabb {
        min: [v[0], v[1], v[2]],
        max: [v[3], v[4], v[5]],
    };
    if b.is_empty() {
        return Err("each min must be ≤ its max".to_string());
    }
    Ok(b)
}

pub fn run(args: Args) -> Result<()> {
    crate::signals::remove_temporaries_on_signals()?;
    let ext = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "las" && ext != "laz" {
        bail!(
            "output {} must end in .las or .laz: export writes LAS/LAZ (a store is written by convert)",
            args.output.display()
        );
    }
    let store = crate::load::open_store(&args.store, "export")?;
    let h = store.header();
    let mut writer = LasWriter::create(
        &args.output,
        LasWriterConfig {
            quantization: h.quantization,
            point_format: h.las_point_format,
            layout: h.layout,
            vlrs: h.vlrs.clone(),
            fields: h.las.clone().unwrap_or_default(),
            compress: ext == "laz",
        },
    )?;
    let bar = crate::progress::bar(h.points, "exporting");
    let mut written = 0u64;
    for (i, p) in store.pointlets().iter().enumerate() {
        bar.inc(p.count as u64);
        if let Some(b) = &args.bbox {
            if !b.intersects(&p.aabb) {
                continue;
            }
        }
        let batch = store
            .read_pointlet(i)
            .with_context(|| format!("reading pointlet {i}"))?;
        let batch = match &args.bbox {
            Some(b) => filter(&batch, b),
            None => batch,
        };
        written += batch.len() as u64;
        writer.write_batch(&batch)?;
    }
    bar.finish_and_clear();
    if written == 0 {
        // Dropping the writer removes its temporary file: no empty export presented as good.
        drop(writer);
        bail!("no points of {} lie inside the bbox", args.store.display());
    }
    writer.finish()?;
    eprintln!("exported {written} points to {}", args.output.display());
    Ok(())
}

fn filter(batch: &PointBatch, b: &Aabb) -> PointBatch {
    let mut out = PointBatch::new(batch.layout);
    for (i, p) in batch.xyz.iter().enumerate() {
        if b.contains(*p) {
            out.push_from(batch, i);
        }
    }
    out
}
