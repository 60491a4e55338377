//! `pointlet convert`: readers → store builder, decoding on its own thread.

use anyhow::{anyhow, bail, Result};
use pointlet_core::PointBatch;
use pointlet_io::PointReader;
use pointlet_store::{BuildConfig, StoreBuilder};
use std::path::{Path, PathBuf};
use std::sync::mpsc::sync_channel;

#[derive(clap::Args)]
pub struct Args {
    /// Input files or folders (LAS, LAZ, COPC, PLY, XYZ/CSV/TXT); all merge into one store.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The store to write (`.pointlet`).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Memory for sorting (e.g. 2GiB); larger inputs sort out of core through runs on disk.
    /// Default: a quarter of the machine's RAM, at most 4GiB, at least 64MiB.
    #[arg(long, value_parser = crate::parse_bytes_arg)]
    pub ram_budget: Option<u64>,
    /// Folder for the temporary runs of an out-of-core build (default: beside the output).
    #[arg(long)]
    pub tmp: Option<PathBuf>,
    /// Target number of pointlets M: pointlet size k = 2^round(log2(n/M)).
    #[arg(long, default_value_t = 100_000, value_parser = crate::parse_count_arg)]
    pub pointlets: u64,
    /// Seed of the shuffle inside each pointlet.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Step of the store's integer positions on every axis (e.g. 0.001). Default: the inputs'
    /// own scale (LAS), or the precision of PLY/text data, as fine as the extent allows.
    #[arg(long, value_parser = parse_scale)]
    pub scale: Option<f64>,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

fn parse_scale(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("not a positive number".to_string()),
    }
}

/// Opens every input (folders expanded): a `note:` line for each file of a folder left out
/// and for what a reader has to say.
pub fn open_inputs(
    inputs: &[PathBuf],
    read: &crate::load::ReadArgs,
) -> Result<Vec<Box<dyn PointReader>>> {
    let mut readers = Vec::new();
    let mut skipped = Vec::new();
    for input in inputs {
        if pointlet_tiles::points::is_tileset_path(input) {
            readers.push(pointlet_engine::open_points(input, &read.options())?);
        } else {
            let opened = pointlet_io::open_inputs(std::slice::from_ref(input), &read.options())?;
            readers.extend(opened.readers);
            skipped.extend(opened.skipped);
        }
    }
    for s in &skipped {
        eprintln!("note: skipped {}: {}", s.path.display(), s.reason);
    }
    for r in &readers {
        crate::load::print_notes(r.as_ref());
    }
    if readers.is_empty() {
        bail!("no supported point files in {}", list_files(inputs));
    }
    Ok(readers)
}

/// Points per batch handed from the decoder thread to the builder: enough for every core, few
/// enough that the batches in flight (~15 MB each) stay a small constant beside the budget.
pub const BATCH: usize = 1 << 18;

pub fn run(args: Args) -> Result<()> {
    if !crate::load::is_store_path(&args.output) {
        bail!(
            "output {} must end in .pointlet: convert writes a pointlet store (to write LAS/LAZ, convert to a store, then `pointlet export` it)",
            args.output.display()
        );
    }
    crate::signals::remove_temporaries_on_signals()?;
    let readers = open_inputs(&args.inputs, &args.read)?;
    let files: Vec<PathBuf> = readers.iter().map(|r| r.path().to_path_buf()).collect();
    refuse_overwriting_inputs(&files, &args.output)?;
    let metas: Vec<_> = readers.iter().map(|r| r.meta().clone()).collect();
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    let mut meta = pointlet_store::merge_meta(&metas, &names).map_err(|e| {
        // Conflicts between inputs name them already; other errors need the list.
        let named = names.iter().any(|n| e.to_string().contains(n.as_str()));
        let context = if named {
            "merging the input headers".to_string()
        } else {
            format!("merging the headers of {}", list_files(&files))
        };
        anyhow::Error::new(e).context(context)
    })?;
    if let Some(scale) = args.scale {
        let b = meta.bounds;
        let q = pointlet_io::scale::quantization_with_scale(&b, scale).map_err(|axis| {
            anyhow!(
                "--scale {scale} cannot span the inputs: {} runs from {} to {}, more than \
                 32-bit integers hold at that step",
                ["x", "y", "z"][axis],
                b.min[axis],
                b.max[axis]
            )
        })?;
        meta.quantization = Some(q);
    }
    let started = std::time::Instant::now();
    let summary = build_store(
        &args.output,
        config(args.ram_budget, args.tmp, args.pointlets, args.seed)?,
        &meta,
        files.iter().map(|f| f.display().to_string()).collect(),
        readers,
    )?;
    let secs = started.elapsed().as_secs_f64();
    let mut writes = match summary.timings.writer_busy {
        Some(busy) => format!("the writers were busy {:.2} s in all", busy.as_secs_f64()),
        None => "written through a mapping of the file".to_string(),
    };
    if let Some(s) = summary.timings.spills {
        writes += &format!(
            "; {} runs spilled: reading waited {:.2} s for the spilling threads, which bucketed \
             {:.2} s and wrote {:.2} s in all",
            summary.runs,
            s.waited.as_secs_f64(),
            s.bucketing.as_secs_f64(),
            s.writing.as_secs_f64()
        );
    }
    eprintln!(
        "wrote {}: {} points in {} pointlet{} of {} in {:.2} s ({}; reading {:.2} s, sorting \
         {:.2} s, writing {:.2} s; {writes})",
        args.output.display(),
        summary.points,
        summary.pointlets,
        if summary.pointlets == 1 { "" } else { "s" },
        summary.pointlet_size,
        secs,
        crate::progress::points_per_second(summary.points as f64 / secs.max(1e-9)),
        summary.timings.reading.as_secs_f64(),
        summary.timings.sorting.as_secs_f64(),
        summary.timings.writing.as_secs_f64(),
    );
    Ok(())
}

pub fn config(
    ram_budget: Option<u64>,
    tmp: Option<PathBuf>,
    pointlets: u64,
    seed: u64,
) -> Result<BuildConfig> {
    Ok(BuildConfig {
        ram_budget: ram_budget.unwrap_or_else(default_ram_budget),
        tmp_dir: tmp,
        target_pointlets: pointlets.max(1),
        seed,
        progress: crate::progress::build_bar(),
    })
}

/// The sorting budget when none is given, from the machine's RAM (1 GiB where unknown).
pub fn default_ram_budget() -> u64 {
    crate::total_memory().map_or(1 << 30, ram_budget_for_total)
}

/// A quarter of the RAM, at most 4 GiB (more crowds out the page cache and the rest of the
/// system, issue 15), at least 64 MiB.
fn ram_budget_for_total(total: u64) -> u64 {
    (total / 4).clamp(64 << 20, 4 << 30)
}

/// Feeds every reader into a builder: parted files (LAS, LAZ) are decoded on all cores by the
/// builder itself; other files are decoded on a thread of their own while the builder keys
/// the previous batch.
pub fn build_store(
    output: &Path,
    config: BuildConfig,
    meta: &pointlet_core::SourceMeta,
    sources: Vec<String>,
    readers: Vec<Box<dyn pointlet_io::PointReader>>,
) -> Result<pointlet_store::BuildSummary> {
    // An error drops the builder, which removes its temporary files and partial output.
    let mut builder = StoreBuilder::create(output, config, meta, sources)?;
    for reader in readers {
        match reader.parted() {
            Some(parts) => builder.push_parts(parts)?,
            None => push_sequential(&mut builder, reader)?,
        }
    }
    Ok(builder.finish()?)
}

/// Decodes one reader front to back on a thread of its own, pushing each batch.
fn push_sequential(
    builder: &mut StoreBuilder,
    mut reader: Box<dyn pointlet_io::PointReader>,
) -> Result<()> {
    let (tx, rx) = sync_channel::<Result<PointBatch>>(2);
    std::thread::scope(|scope| {
        let decoder = scope.spawn(move || loop {
            let batch = reader.read_batch(BATCH).map_err(anyhow::Error::from);
            let end = !matches!(batch, Ok(Some(_)));
            let sent = match batch {
                Ok(Some(b)) => tx.send(Ok(b)),
                Ok(None) => return,
                Err(e) => tx.send(Err(e)),
            };
            if end || sent.is_err() {
                return;
            }
        });
        for batch in rx {
            builder.push(&batch?)?;
        }
        if decoder.join().is_err() {
            bail!("the decoder thread panicked");
        }
        Ok(())
    })
}

/// Names for messages: all files when few, else the first ones and how many more.
pub fn list_files(files: &[PathBuf]) -> String {
    let shown: Vec<String> = files
        .iter()
        .take(3)
        .map(|f| f.display().to_string())
        .collect();
    match files.len() {
        0..=3 => shown.join(", "),
        n => format!("{} and {} more", shown.join(", "), n - 3),
    }
}

fn refuse_overwriting_inputs(files: &[PathBuf], output: &Path) -> Result<()> {
    let Ok(out) = output.canonicalize() else {
        return Ok(()); // does not exist yet
    };
    for f in files {
        if f.canonicalize().map(|c| c == out).unwrap_or(false) {
            bail!(
                "output {} is also an input: refusing to overwrite an input file",
                output.display()
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn default_budget_is_a_quarter_of_ram_within_64_mib_and_4_gib() {
        let f = super::ram_budget_for_total;
        const MIB: u64 = 1 << 20;
        const GIB: u64 = 1 << 30;
        assert_eq!(f(8 * GIB), 2 * GIB);
        assert_eq!(f(16 * GIB), 4 * GIB);
        assert_eq!(f(24 * GIB), 4 * GIB);
        assert_eq!(f(512 * GIB), 4 * GIB);
        assert_eq!(f(1000 * MIB), 250 * MIB);
        assert_eq!(f(128 * MIB), 64 * MIB);
        assert_eq!(f(0), 64 * MIB);
    }
}
