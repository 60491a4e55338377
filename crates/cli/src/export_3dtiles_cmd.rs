//! `pointlet export-3dtiles`: a store as a 3D Tiles 1.1 tileset of GLB point tiles (the writer
//! is `pointlet_tiles::write`; this parses flags, shows progress and says where the tileset is).

use anyhow::{Context, Result};
use pointlet_tiles::write::{export, ExportConfig};
use pointlet_tiles::Refine;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// The store to export.
    pub store: PathBuf,
    /// The tileset's folder (tileset.json and content/); must be missing or empty.
    #[arg(short, long)]
    pub output: PathBuf,
    /// `add` (default): each point is in one tile and deeper tiles add points, so the tileset
    /// is the size of the data and nothing is sent twice. `replace`: a tile alone shows its
    /// region (its children replace it), costing more tiles' worth of points.
    #[arg(long, default_value = "add", value_parser = ["add", "replace"])]
    pub refine: String,
    /// Points a tile aims to hold.
    #[arg(long, default_value = "50K", value_parser = crate::parse_count_arg)]
    pub points_per_tile: u64,
    /// Memory for tiles being made at once (e.g. 512MiB). Default: a quarter of the
    /// machine's RAM, at most 4GiB, at least 64MiB.
    #[arg(long, value_parser = crate::parse_bytes_arg)]
    pub ram_budget: Option<u64>,
    /// Replace an output folder that is not empty.
    #[arg(long)]
    pub force: bool,
    /// Keep the store's own coordinates (a local tileset) even when its CRS could place the
    /// tileset on the globe.
    #[arg(long)]
    pub local: bool,
    /// Positions and colours only, no per-point metadata: the smallest tileset for viewing.
    #[arg(long)]
    pub no_metadata: bool,
}

pub fn run(args: Args) -> Result<()> {
    crate::signals::remove_temporaries_on_signals()?;
    let store = crate::load::open_store(&args.store, "export-3dtiles")?;
    let config = ExportConfig {
        refine: if args.refine == "replace" {
            Refine::Replace
        } else {
            Refine::Add
        },
        points_per_tile: args.points_per_tile.max(1),
        ram_budget: args
            .ram_budget
            .unwrap_or_else(crate::convert_cmd::default_ram_budget),
        force: args.force,
        local: args.local,
        metadata: !args.no_metadata,
    };
    let bar = crate::progress::bar(store.header().points, "tiling");
    let started = Instant::now();
    let summary = export(&store, &args.output, &config, &|n| bar.inc(n))
        .with_context(|| format!("exporting {} as 3D Tiles", args.store.display()))?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let g = &summary.georeference;
    if g.epsg.is_none() {
        eprintln!("note: {}", g.note);
    }
    for note in &summary.notes {
        eprintln!("note: {note}");
    }
    eprintln!(
        "exported {} points into {} tiles ({} points in all, {} leaves, depth {}, {} refinement) in {:.2} s ({}): {}",
        store.header().points,
        summary.tiles,
        summary.content_points,
        summary.leaves,
        summary.depth,
        args.refine.to_uppercase(),
        seconds,
        crate::progress::points_per_second(store.header().points as f64 / seconds.max(1e-9)),
        args.output.join("tileset.json").display(),
    );
    if g.epsg.is_some() {
        eprintln!("{}", g.note);
    }
    Ok(())
}
