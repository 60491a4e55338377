//! Build throughput of the store builder on synthetic airborne-like points.
//!
//! ```sh
//! cargo run --release -p pointlet-store --example build_bench -- \
//!     --points 20000000 --budget 128MiB --out /tmp/bench.pointlet
//! ```
//! Points come in batches of 2^20 (as `pointlet convert` hands them over) with GPS time and
//! colours (LAS format 3 columns). Generating a batch is not timed; pushing and finishing are.
//! Peak memory: run under `/usr/bin/time -v` (one generated batch, ~50 MiB, comes on top).

use pointlet_core::shuffle::SplitMix64;
use pointlet_core::size::{format_bytes, parse_bytes, parse_count};
use pointlet_core::{Aabb, PointBatch, PointLayout, Quantization, SourceMeta};
use pointlet_store::{BuildConfig, Store, StoreBuilder};
use std::path::PathBuf;
use std::time::{Duration, Instant};

const BATCH: usize = 1 << 20;

struct Args {
    points: u64,
    budget: u64,
    out: PathBuf,
    verify: bool,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        points: 20_000_000,
        budget: 4 << 30,
        out: std::env::temp_dir().join("build_bench.pointlet"),
        verify: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--points" => a.points = parse_count(&value()?).map_err(|e| e.to_string())?,
            "--budget" => a.budget = parse_bytes(&value()?).map_err(|e| e.to_string())?,
            "--out" => a.out = PathBuf::from(value()?),
            "--verify" => a.verify = true,
            _ => return Err(format!("unknown argument {flag}")),
        }
    }
    Ok(a)
}

/// A flight over 10 km × 10 km: strips along x, scan lines across each strip, rolling terrain;
/// consecutive points are neighbours, as in real scans.
struct Scene {
    rng: SplitMix64,
    made: u64,
    total: u64,
}

const LAYOUT: PointLayout = PointLayout {
    gps_time: true,
    rgb: true,
    nir: false,
    waveform: false,
    extra_bytes: 0,
};

impl Scene {
    fn meta(total: u64) -> SourceMeta {
        SourceMeta {
            format: "synthetic flight".into(),
            point_count: total,
            bounds: Aabb {
                min: [500_000.0, 4_000_000.0, 0.0],
                max: [510_000.0, 4_010_000.0, 200.0],
            },
            quantization: Some(Quantization {
                scale: [0.001; 3],
                offset: [500_000.0, 4_000_000.0, 0.0],
            }),
            layout: LAYOUT,
            las_point_format: Some(3),
            vlrs: Vec::new(),
            las: None,
        }
    }

    fn batch(&mut self) -> Option<PointBatch> {
        let n = (self.total - self.made).min(BATCH as u64) as usize;
        if n == 0 {
            return None;
        }
        let q = Scene::meta(0).quantization?;
        let mut b = PointBatch::with_capacity(LAYOUT, n);
        // Points per scan line and scan lines per strip fill the area once with `total` points.
        let per_line = 2000u64;
        let lines = (self.total / per_line).max(1);
        let strips = ((lines as f64).sqrt() / 40.0).ceil().max(1.0) as u64;
        let lines_per_strip = lines.div_ceil(strips);
        for _ in 0..n {
            let i = self.made;
            let line = i / per_line;
            let strip = line / lines_per_strip;
            let u = (i % per_line) as f64 / per_line as f64;
            let v = (line % lines_per_strip) as f64 / lines_per_strip as f64;
            let x = 500_000.0 + v * 10_000.0;
            let y = 4_000_000.0 + (strip as f64 + u) * 10_000.0 / strips as f64;
            let z =
                100.0 + 40.0 * (x * 0.001).sin() * (y * 0.0013).cos() + self.rng.unit_f64() * 2.0;
            let p = [x + self.rng.unit_f64() * 0.5, y, z];
            b.xyz.push(q.dequantize(q.quantize(p).ok()?));
            b.intensity.push(self.rng.next_u64() as u16);
            b.returns.push(0x11);
            b.flags.push(0);
            b.classification.push(2 + (self.rng.below(4) as u8));
            b.scan_angle.push((u * 40.0 - 20.0) as f32);
            b.user_data.push(0);
            b.point_source_id.push(strip as u16);
            b.gps_time.push(i as f64 * 1e-5);
            let c = (z * 600.0) as u16;
            b.rgb.push([c, c / 2, 65535 - c]);
            self.made += 1;
        }
        Some(b)
    }
}

fn main() {
    let a = match args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    };
    let meta = Scene::meta(a.points);
    let config = BuildConfig {
        ram_budget: a.budget,
        ..Default::default()
    };
    let mut scene = Scene {
        rng: SplitMix64::new(1),
        made: 0,
        total: a.points,
    };
    let run = || -> Result<(), pointlet_store::StoreError> {
        let mut builder = StoreBuilder::create(&a.out, config, &meta, vec!["synthetic".into()])?;
        let mut push = Duration::ZERO;
        while let Some(b) = scene.batch() {
            let t = Instant::now();
            builder.push(&b)?;
            push += t.elapsed();
        }
        let t = Instant::now();
        let s = builder.finish()?;
        let finish = t.elapsed();
        let total = (push + finish).as_secs_f64();
        println!(
            "{} points, budget {}, {} runs: push {:.2} s + finish {:.2} s = {:.2} s, {:.2} M points/s; \
             {} pointlets of {}, {}",
            s.points,
            format_bytes(a.budget),
            s.runs,
            push.as_secs_f64(),
            finish.as_secs_f64(),
            total,
            s.points as f64 / total / 1e6,
            s.pointlets,
            s.pointlet_size,
            format_bytes(s.bytes)
        );
        if a.verify {
            let t = Instant::now();
            Store::open(&a.out)?.verify()?;
            println!("verified in {:.2} s", t.elapsed().as_secs_f64());
        }
        Ok(())
    };
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
