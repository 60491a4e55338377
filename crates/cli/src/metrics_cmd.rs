//! `pointlet metrics`: Table I of the virtualized paper on the same points.

use anyhow::{bail, Result};
use pointlet_core::partition::{measure, Partitioner};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A store or any supported point file (all points are held in memory: 24 bytes each).
    pub input: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Target number of pointlets M (pointlet size as `convert` would choose it).
    #[arg(long, default_value_t = 100_000, value_parser = crate::parse_count_arg)]
    pub pointlets: u64,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

pub fn run(args: Args) -> Result<()> {
    let (points, bounds) = crate::load::load_positions(&args.input, &args.read)?;
    if points.is_empty() {
        bail!("{} holds no points", args.input.display());
    }
    let k = pointlet_store::pointlet_size(points.len() as u64, args.pointlets.max(1)) as usize;
    let stats: Vec<_> = Partitioner::ALL
        .iter()
        .map(|how| measure(&points, &bounds, k, *how))
        .collect();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "input": args.input.display().to_string(),
                "points": points.len(),
                "pointlet_size": k,
                "results": stats,
            }))?
        );
        return Ok(());
    }
    println!(
        "{}: {} points, pointlets of {} points",
        args.input.display(),
        points.len(),
        k
    );
    println!(
        "{:<10} {:>10} {:>14} {:>14} {:>14} {:>16} {:>10}",
        "approach",
        "pointlets",
        "max extent",
        "mean extent",
        "std dev",
        "mean squareness",
        "seconds"
    );
    for s in &stats {
        println!(
            "{:<10} {:>10} {:>14.3} {:>14.3} {:>14.3} {:>16.3} {:>10.3}",
            s.partitioner.name(),
            s.pointlets,
            s.max_extent,
            s.mean_extent,
            s.std_extent,
            s.mean_squareness,
            s.seconds
        );
    }
    println!("extent = AABB diagonal; squareness = |dx - dy| of the AABB (data units)");
    Ok(())
}
