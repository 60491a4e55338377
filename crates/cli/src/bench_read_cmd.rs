//! `pointlet bench-read`: decode inputs and do nothing else — the baseline `convert` is
//! measured against (conversion should cost at most 2× decoding). Files that come in parts
//! (LAS, LAZ) are decoded part by part on every core, as conversion reads them. A store is
//! read as progressive rendering reads it with `--progressive` (its pointlets as parts).
//! `--color-only MODE` decodes only what colouring by MODE reads, as the progressive loader
//! does (stores keep their columns apart; point files decode whole records anyway).
//! `--staged` reads a store's parts as a progressive load hands them to the GPU: the load's
//! CPU side without the bus.

use anyhow::{anyhow, Result};
use pointlet_core::color::{ColorMode, ColorScale};
use pointlet_core::{PartedSource, PointBatch};
use pointlet_engine::progressive::{read_stored_part, PartScratch};
use pointlet_io::PointReader;
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Input files or folders.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Read every file front to back on one thread, even one that comes in parts.
    #[arg(long)]
    pub sequential: bool,
    /// Decode positions and only what colouring by this mode reads (rgb, intensity, …).
    #[arg(long, value_parser = parse_mode)]
    pub color_only: Option<ColorMode>,
    /// Stores only: each part's positions as stored and its colours (by `--color-only`'s
    /// mode, RGB by default) made from the stored streams, both copied into buffers of their
    /// own, as a progressive load writes them into upload memory.
    #[arg(long, conflicts_with = "sequential")]
    pub staged: bool,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

/// Points decoded and a sum of decoded values (touched so the work cannot be skipped).
#[derive(Clone, Copy, Default)]
struct Tally {
    points: u64,
    checksum: f64,
}

impl Tally {
    fn add(self, o: Tally) -> Tally {
        Tally {
            points: self.points + o.points,
            checksum: self.checksum + o.checksum,
        }
    }

    fn of(batch: &PointBatch) -> Tally {
        Tally {
            points: batch.len() as u64,
            checksum: batch.xyz.last().map_or(0.0, |p| p[0]),
        }
    }
}

pub fn run(args: Args) -> Result<()> {
    let (stores, files): (Vec<PathBuf>, Vec<PathBuf>) = args
        .inputs
        .iter()
        .cloned()
        .partition(|p| crate::load::is_store_path(p));
    let mut readers = Vec::new();
    if !files.is_empty() {
        readers = crate::convert_cmd::open_inputs(&files, &args.read)?;
    }
    for s in &stores {
        readers.push(pointlet_engine::open_points(s, &args.read.options())?);
    }
    let started = Instant::now();
    let mut total = Tally::default();
    let mut parted_files = 0;
    let files = readers.len();
    for mut r in readers {
        let tally = match r.parted().filter(|_| !args.sequential) {
            Some(parts) if args.staged => {
                parted_files += 1;
                let mode = args.color_only.unwrap_or(ColorMode::Rgb);
                stage_parts(r.as_ref(), parts, mode)?
            }
            Some(parts) => {
                parted_files += 1;
                decode_parts(r.as_ref(), parts, args.color_only)?
            }
            None if args.staged => return Err(not_a_store(r.as_ref())),
            None => decode_sequentially(r.as_mut())?,
        };
        total = total.add(tally);
    }
    let secs = started.elapsed().as_secs_f64();
    let threads = match rayon::current_num_threads() {
        1 => "1 thread".to_string(),
        n => format!("{n} threads"),
    };
    let mode = match parted_files {
        0 => "front to back".to_string(),
        n if n == files => format!("in parts on {threads}"),
        n => format!("{n} of {files} files in parts on {threads}"),
    };
    let staged = if args.staged {
        // As `bench --progressive` counts a load: 16 bytes a point (position words, colour).
        format!(
            ", {:.1} GB/s of 16-byte points",
            total.points as f64 * 16.0 / secs.max(1e-9) / 1e9
        )
    } else {
        String::new()
    };
    println!(
        "decoded {} points in {secs:.2} s: {}{staged} (checksum {:.3}; {mode})",
        total.points,
        crate::progress::points_per_second(total.points as f64 / secs.max(1e-9)),
        total.checksum
    );
    Ok(())
}

fn decode_sequentially(r: &mut dyn PointReader) -> Result<Tally> {
    let mut tally = Tally::default();
    while let Some(b) = r.read_batch(crate::convert_cmd::BATCH)? {
        tally = tally.add(Tally::of(&b));
    }
    Ok(tally)
}

/// Every part decoded once, in parallel, each thread reusing its own batch and scratch buffer.
fn decode_parts(
    r: &dyn PointReader,
    parts: &dyn PartedSource,
    color_only: Option<ColorMode>,
) -> Result<Tally> {
    let layout = r.meta().layout;
    (0..parts.part_sizes().len())
        .into_par_iter()
        .map_init(
            || (PointBatch::new(layout), Vec::new()),
            |(batch, scratch), i| {
                match color_only {
                    Some(mode) => parts.decode_part_for(i, batch, scratch, mode),
                    None => parts.decode_part(i, batch, scratch),
                }
                .map(|()| Tally::of(batch))
                .map_err(|e| anyhow!(e))
            },
        )
        .try_reduce(Tally::default, |a, b| Ok(a.add(b)))
}

/// Every part read as a progressive load reads a store's ([`read_stored_part`]), its
/// positions and colours copied into ordinary memory instead of upload memory.
fn stage_parts(r: &dyn PointReader, parts: &dyn PartedSource, mode: ColorMode) -> Result<Tally> {
    if parts.quantized_positions().is_none() {
        return Err(not_a_store(r));
    }
    let sizes = parts.part_sizes();
    // The colouring a load would choose, fitted on the first part.
    let mut sample = PointBatch::new(r.meta().layout);
    if !sizes.is_empty() {
        parts
            .decode_part(0, &mut sample, &mut Vec::new())
            .map_err(|e| anyhow!(e))?;
    }
    let b = r.meta().bounds;
    let scale = ColorScale::fit(mode, &[&sample], [b.min[2], b.max[2]]);
    (0..sizes.len())
        .into_par_iter()
        .map_init(
            || (PartScratch::default(), Vec::new(), Vec::new()),
            |(scratch, positions, colors), i| {
                let copy_positions = |bytes: &[u8]| {
                    positions.clear();
                    positions.extend_from_slice(bytes);
                    Ok(())
                };
                let made = read_stored_part(parts, r.path(), &scale, i, scratch, copy_positions)
                    .map_err(|e| anyhow!(e))?;
                colors.clear();
                colors.extend_from_slice(made);
                Ok(Tally {
                    points: sizes[i],
                    // Both copies are read, so neither can be left out.
                    checksum: colors.last().map_or(0.0, |&c| f64::from(c & 0xff))
                        + positions.last().map_or(0.0, |&b| f64::from(b)),
                })
            },
        )
        .try_reduce(Tally::default, |a, b| Ok(a.add(b)))
}

/// `--staged` given a source without stored positions (the flags' check refuses point files
/// before they are opened).
fn not_a_store(r: &dyn PointReader) -> anyhow::Error {
    anyhow!(
        "{}: --staged reads stores, whose parts go to the GPU as stored; this input is not one",
        r.path().display()
    )
}

fn parse_mode(s: &str) -> Result<ColorMode, String> {
    match crate::view_args::parse_color(s)? {
        crate::view_args::ColorArg::Mode(m) => Ok(m),
        crate::view_args::ColorArg::Extra(_) => {
            Err("an extra-bytes attribute is read with the extra bytes: use --color-only rgb, intensity, …".into())
        }
    }
}
