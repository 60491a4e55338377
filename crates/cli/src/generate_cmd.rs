//! `pointlet generate`: the synthetic benchmark scene as LAS, LAZ or a store.

use anyhow::{bail, Context, Result};
use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Number of points (e.g. 50M, 1G).
    #[arg(long, value_parser = crate::parse_count_arg)]
    pub points: u64,
    /// Output: `.las`, `.laz` or `.pointlet`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Scene seed: the same seed and count always give the same points.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// With a `.pointlet` output: memory for sorting (default: a quarter of the machine's RAM,
    /// at most 4GiB, at least 64MiB).
    #[arg(long, value_parser = crate::parse_bytes_arg)]
    pub ram_budget: Option<u64>,
    /// With a `.pointlet` output: target number of pointlets.
    #[arg(long, default_value_t = 100_000, value_parser = crate::parse_count_arg)]
    pub pointlets: u64,
    /// Leave out GPS time (LAS point format 2): 8 bytes less per point, for the largest
    /// benchmark stores a disk can hold.
    #[arg(long)]
    pub lean: bool,
}

/// Drops the GPS time column (the `--lean` scene).
fn lean_batch(mut b: pointlet_core::PointBatch) -> pointlet_core::PointBatch {
    b.gps_time = Vec::new();
    b.layout.gps_time = false;
    b
}

/// A reader that hands out lean batches of another reader.
struct LeanReader<R> {
    inner: R,
    meta: pointlet_core::SourceMeta,
}

impl<R: pointlet_io::PointReader> pointlet_io::PointReader for LeanReader<R> {
    fn path(&self) -> &std::path::Path {
        self.inner.path()
    }

    fn meta(&self) -> &pointlet_core::SourceMeta {
        &self.meta
    }

    fn read_batch(
        &mut self,
        max: usize,
    ) -> Result<Option<pointlet_core::PointBatch>, pointlet_io::IoError> {
        Ok(self.inner.read_batch(max)?.map(lean_batch))
    }
}

pub fn run(args: Args) -> Result<()> {
    crate::signals::remove_temporaries_on_signals()?;
    if args.points == 0 {
        bail!("--points must be at least 1");
    }
    let ext = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    let generator = SceneGenerator::new(SceneConfig {
        points: args.points,
        seed: args.seed,
    });
    let mut meta = generator.meta();
    if args.lean {
        meta.layout.gps_time = false;
        meta.las_point_format = Some(2);
    }
    let reader = || -> Box<dyn pointlet_io::PointReader> {
        if args.lean {
            Box::new(LeanReader {
                inner: generator.reader(),
                meta: meta.clone(),
            })
        } else {
            Box::new(generator.reader())
        }
    };
    let started = std::time::Instant::now();
    match ext.as_str() {
        "las" | "laz" => {
            let mut writer = LasWriter::create(
                &args.output,
                LasWriterConfig {
                    quantization: meta
                        .quantization
                        .context("the generator gives no quantization")?,
                    point_format: meta.las_point_format.unwrap_or(3),
                    layout: meta.layout,
                    vlrs: meta.vlrs.clone(),
                    fields: meta.las.clone().unwrap_or_default(),
                    compress: ext == "laz",
                },
            )?;
            let bar = crate::progress::bar(args.points, "generating");
            let mut reader = reader();
            while let Some(batch) = reader.read_batch(1 << 20)? {
                writer.write_batch(&batch)?;
                bar.inc(batch.len() as u64);
            }
            bar.finish_and_clear();
            writer.finish()?;
        }
        "pointlet" => {
            let config = crate::convert_cmd::config(args.ram_budget, None, args.pointlets, 0)?;
            crate::convert_cmd::build_store(
                &args.output,
                config,
                &meta,
                vec![format!(
                    "generated: {} points, seed {}",
                    args.points, args.seed
                )],
                vec![reader()],
            )?;
        }
        _ => bail!(
            "unknown output type '{}': use .las, .laz or .pointlet",
            args.output.display()
        ),
    }
    eprintln!(
        "generated {} points into {} in {:.2} s",
        args.points,
        args.output.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
