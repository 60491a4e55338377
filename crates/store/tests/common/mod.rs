//! Synthetic points and helpers shared by the store's integration tests.
#![allow(dead_code)]

pub mod range_server;

use pointlet_core::shuffle::SplitMix64;
use pointlet_core::{
    Aabb, LasFields, PointBatch, PointLayout, Quantization, SourceMeta, Vlr, WAVEFORM_BYTES,
};
use pointlet_store::{BuildConfig, BuildSummary, StoreBuilder};
use std::path::{Path, PathBuf};

pub const Q: Quantization = Quantization {
    scale: [0.01, 0.01, 0.001],
    offset: [1000.0, -2000.0, 0.0],
};

/// Every optional column, with 3 extra bytes.
pub const FULL: PointLayout = PointLayout {
    gps_time: true,
    rgb: true,
    nir: true,
    waveform: true,
    extra_bytes: 3,
};

/// GPS time, colours and 5 extra bytes (LAS format 7-like).
pub const RGB_GPS_EXTRA: PointLayout = PointLayout {
    gps_time: true,
    rgb: true,
    nir: false,
    waveform: false,
    extra_bytes: 5,
};

/// The claimed bounds: most points lie inside, a few outside (their keys are clamped).
pub fn claimed_bounds() -> Aabb {
    Aabb {
        min: [1000.0, -2000.0, 0.0],
        max: [1500.0, -1700.0, 40.0],
    }
}

pub fn meta(layout: PointLayout, points: u64) -> SourceMeta {
    SourceMeta {
        format: "synthetic".into(),
        point_count: points,
        bounds: claimed_bounds(),
        quantization: Some(Q),
        layout,
        las_point_format: None,
        vlrs: vec![Vlr {
            user_id: "LASF_Projection".into(),
            record_id: 2112,
            description: "test CRS".into(),
            data: b"PROJCS[\"test\"]\0".to_vec(),
            extended: false,
        }],
        las: Some(LasFields {
            global_encoding: LasFields::ADJUSTED_STANDARD_GPS_TIME,
            file_source_id: 42,
            project_id: *b"0123456789abcdef",
            system_identifier: "test scanner".into(),
        }),
    }
}

/// Point `id` of a deterministic scene: clustered terrain with some outliers. `gps_time` is
/// the id, so tests can tell points apart.
pub fn batches(layout: PointLayout, points: usize, batch: usize, seed: u64) -> Vec<PointBatch> {
    let mut rng = SplitMix64::new(seed);
    let mut out = Vec::new();
    let mut id = 0usize;
    while id < points {
        let n = batch.min(points - id);
        let mut b = PointBatch::with_capacity(layout, n);
        for _ in 0..n {
            let cx = rng.below(5) as f64 * 100.0;
            let raw_x = ((cx + rng.unit_f64() * 100.0) / Q.scale[0]).round() as i32;
            let raw_y = ((rng.unit_f64() * 300.0) / Q.scale[1]).round() as i32;
            let raw_z = ((rng.unit_f64() * 40.0) / Q.scale[2]).round() as i32;
            let mut raw = [raw_x, raw_y, raw_z];
            if rng.below(100) == 0 {
                // Outside the claimed bounds: clamped keys.
                raw[0] += 100_000;
                raw[2] -= 50_000;
            }
            b.xyz.push(Q.dequantize(raw));
            b.intensity.push(rng.next_u64() as u16);
            b.returns.push(0x11 + rng.below(3) as u8);
            b.flags.push(rng.next_u64() as u8);
            b.classification.push(rng.below(20) as u8);
            b.scan_angle.push((rng.unit_f64() * 60.0 - 30.0) as f32);
            b.user_data.push(rng.next_u64() as u8);
            b.point_source_id.push(rng.below(7) as u16);
            if layout.gps_time {
                b.gps_time.push(id as f64);
            }
            if layout.rgb {
                b.rgb.push([
                    rng.next_u64() as u16,
                    rng.next_u64() as u16,
                    rng.next_u64() as u16,
                ]);
            }
            if layout.nir {
                b.nir.push(rng.next_u64() as u16);
            }
            if layout.waveform {
                let mut w = [0u8; WAVEFORM_BYTES];
                w.iter_mut().for_each(|x| *x = rng.next_u64() as u8);
                b.waveform.push(w);
            }
            for _ in 0..layout.extra_bytes {
                b.extra_bytes.push(rng.next_u64() as u8);
            }
            id += 1;
        }
        out.push(b);
    }
    out
}

pub fn build(
    out: &Path,
    config: BuildConfig,
    meta: &SourceMeta,
    batches: &[PointBatch],
) -> BuildSummary {
    let mut b = StoreBuilder::create(out, config, meta, vec!["synthetic".into()]).expect("create");
    for batch in batches {
        b.push(batch).expect("push");
    }
    b.finish().expect("finish")
}

/// Every attribute of point `i` as comparable bits.
pub fn fingerprint(b: &PointBatch, i: usize) -> Vec<u64> {
    let mut v = vec![
        b.xyz[i][0].to_bits(),
        b.xyz[i][1].to_bits(),
        b.xyz[i][2].to_bits(),
        b.intensity[i] as u64,
        b.returns[i] as u64,
        b.flags[i] as u64,
        b.classification[i] as u64,
        b.scan_angle[i].to_bits() as u64,
        b.user_data[i] as u64,
        b.point_source_id[i] as u64,
    ];
    let l = b.layout;
    if l.gps_time {
        v.push(b.gps_time[i].to_bits());
    }
    if l.rgb {
        v.extend(b.rgb[i].iter().map(|c| *c as u64));
    }
    if l.nir {
        v.push(b.nir[i] as u64);
    }
    if l.waveform {
        v.extend(b.waveform[i].iter().map(|c| *c as u64));
    }
    let e = l.extra_bytes as usize;
    v.extend(b.extra_bytes[i * e..(i + 1) * e].iter().map(|c| *c as u64));
    v
}

pub fn multiset<'a>(batches: impl IntoIterator<Item = &'a PointBatch>) -> Vec<Vec<u64>> {
    let mut v: Vec<Vec<u64>> = batches
        .into_iter()
        .flat_map(|b| (0..b.len()).map(move |i| fingerprint(b, i)))
        .collect();
    v.sort();
    v
}

/// Files in a folder, sorted.
pub fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("read_dir")
        .map(|e| e.expect("entry").path())
        .collect();
    v.sort();
    v
}
