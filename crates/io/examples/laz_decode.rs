//! LAZ chunk decompression speed: our decoder against the `laz` crate on the same chunks, in
//! the same process, alternating, on one thread and on every thread of rayon's pool; first
//! checks that both give the same bytes.
//!
//!     cargo run --release -p pointlet-io --example laz_decode -- FILE.laz [ROUNDS]
//!     cargo run --release -p pointlet-io --example laz_decode -- --generate POINTS FILE.laz
//!     cargo run --release -p pointlet-io --example laz_decode -- FILE.laz ROUNDS ours|laz
//!
//! The last form only decompresses, on one thread, with one decoder (for profilers and
//! `time`).

use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::las::raw::{Codec, RawChunks, RawDecoder};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use pointlet_io::PointReader;
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

type Error = Box<dyn std::error::Error>;

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.as_slice() {
        [flag, points, path] if flag == "--generate" => generate(points.parse()?, Path::new(path)),
        [path] => bench(Path::new(path), 3),
        [path, rounds] => bench(Path::new(path), rounds.parse()?),
        [path, rounds, codec] => {
            let codec = match codec.as_str() {
                "ours" => Codec::Ours,
                "laz" => Codec::LazCrate,
                _ => return Err("the decoder is ours or laz".into()),
            };
            let chunks = RawChunks::open(Path::new(path))?;
            let (mut d, mut out) = (RawDecoder::default(), Vec::new());
            for _ in 0..rounds.parse::<usize>()? {
                let t = Instant::now();
                for i in 0..chunks.len() {
                    chunks.decompress(i, codec, &mut d, &mut out)?;
                }
                let r = chunks.points() as f64 / t.elapsed().as_secs_f64();
                println!("{codec:?}: {:.2} M points/s", r / 1e6);
            }
            Ok(())
        }
        _ => Err(
            "usage: laz_decode FILE.laz [ROUNDS] | laz_decode --generate POINTS FILE.laz".into(),
        ),
    }
}

/// Writes the synthetic scene (point format 3) as LAZ.
fn generate(points: u64, path: &Path) -> Result<(), Error> {
    let scene = SceneGenerator::new(SceneConfig { points, seed: 1 });
    let meta = scene.meta();
    let mut w = LasWriter::create(
        path,
        LasWriterConfig {
            quantization: meta.quantization.ok_or("no quantization")?,
            point_format: 3,
            layout: meta.layout,
            vlrs: meta.vlrs.clone(),
            fields: Default::default(),
            compress: true,
        },
    )?;
    let mut r = scene.reader();
    while let Some(b) = r.read_batch(1 << 20)? {
        w.write_batch(&b)?;
    }
    println!("{}: {} points", path.display(), w.finish()?);
    Ok(())
}

/// Points per second decompressing every chunk once, on one thread or on all.
fn rate(chunks: &RawChunks, codec: Codec, parallel: bool) -> Result<f64, Error> {
    let t = Instant::now();
    if parallel {
        (0..chunks.len()).into_par_iter().try_for_each_init(
            || (RawDecoder::default(), Vec::new()),
            |(d, out), i| chunks.decompress(i, codec, d, out),
        )?;
    } else {
        let (mut d, mut out) = (RawDecoder::default(), Vec::new());
        for i in 0..chunks.len() {
            chunks.decompress(i, codec, &mut d, &mut out)?;
        }
    }
    Ok(chunks.points() as f64 / t.elapsed().as_secs_f64())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn bench(path: &Path, rounds: usize) -> Result<(), Error> {
    let chunks = RawChunks::open(path)?;
    println!(
        "{}: {} points in {} chunks of {}-byte records; {} threads",
        path.display(),
        chunks.points(),
        chunks.len(),
        chunks.record_len(),
        rayon::current_num_threads()
    );
    if !chunks.ours_supported() {
        return Err("our decoder does not handle this file's LAZ items".into());
    }
    let (mut a, mut b) = (RawDecoder::default(), RawDecoder::default());
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in 0..chunks.len() {
        chunks.decompress(i, Codec::LazCrate, &mut a, &mut x)?;
        chunks.decompress(i, Codec::Ours, &mut b, &mut y)?;
        if x != y {
            return Err(format!("chunk {i}: the decoders disagree").into());
        }
    }
    println!("both decoders give the same bytes for every chunk");
    let mut results = [[Vec::new(), Vec::new()], [Vec::new(), Vec::new()]];
    for round in 1..=rounds {
        for (p, parallel) in [false, true].into_iter().enumerate() {
            for (c, codec) in [Codec::LazCrate, Codec::Ours].into_iter().enumerate() {
                let r = rate(&chunks, codec, parallel)?;
                println!(
                    "round {round} {:>8} {codec:?}: {:.2} M points/s",
                    if parallel { "parallel" } else { "1 thread" },
                    r / 1e6
                );
                results[p][c].push(r);
            }
        }
    }
    for (p, name) in ["1 thread", "parallel"].into_iter().enumerate() {
        let [laz, ours] = [median(results[p][0].clone()), median(results[p][1].clone())];
        println!(
            "median {name}: laz crate {:.2}, ours {:.2} M points/s: {:.2}x",
            laz / 1e6,
            ours / 1e6,
            ours / laz
        );
    }
    Ok(())
}
