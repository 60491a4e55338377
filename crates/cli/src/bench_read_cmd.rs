//! `pointlet bench-read`: decode inputs and do nothing else — the baseline `convert` is
//! measured against (conversion should cost at most 2× decoding).

use anyhow::Result;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Input files or folders.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
}

pub fn run(args: Args) -> Result<()> {
    let readers = crate::convert_cmd::open_inputs(&args.inputs, &args.read)?;
    let started = Instant::now();
    let mut points = 0u64;
    // Touch the decoded values so the work cannot be skipped.
    let mut checksum = 0f64;
    for mut r in readers {
        while let Some(b) = r.read_batch(crate::convert_cmd::BATCH)? {
            points += b.len() as u64;
            if let Some(p) = b.xyz.last() {
                checksum += p[0];
            }
        }
    }
    let secs = started.elapsed().as_secs_f64();
    println!(
        "decoded {points} points in {secs:.2} s: {} (checksum {checksum:.3})",
        crate::progress::points_per_second(points as f64 / secs.max(1e-9))
    );
    Ok(())
}
