//! The LAS/LAZ writer: real files read by us, written by us, read back by the `las` crate with
//! every field equal; every point format 0–10 as LAS and LAZ; no partial output ever left.

mod common;
use common::*;
use pointlet_core::{flags, PointBatch, PointLayout, Quantization, SourceMeta, WAVEFORM_BYTES};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use std::path::Path;

fn config(meta: &SourceMeta, compress: bool) -> LasWriterConfig {
    LasWriterConfig {
        quantization: meta.quantization.expect("quantization"),
        point_format: meta.las_point_format.expect("format"),
        layout: meta.layout,
        vlrs: meta.vlrs.clone(),
        fields: meta.las.clone().unwrap_or_default(),
        compress,
    }
}

/// Writes `points` in batches of `batch`; returns the count `finish` reports.
fn write(path: &Path, cfg: LasWriterConfig, points: &PointBatch, batch: usize) -> u64 {
    let mut w = LasWriter::create(path, cfg).expect("create");
    let mut i = 0;
    while i < points.len() {
        let mut b = PointBatch::new(points.layout);
        for k in i..(i + batch).min(points.len()) {
            b.push_from(points, k);
        }
        w.write_batch(&b).expect("write_batch");
        i += batch;
    }
    w.finish().expect("finish")
}

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("listing")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn every_shared_file_round_trips_through_las_and_laz() {
    let dir = tempfile::tempdir().expect("tempdir");
    for path in shared_files() {
        let mut r = pointlet_io::open(&path).expect("open");
        let meta = r.meta().clone();
        let points = read_all(r.as_mut(), 1 << 20);
        let expected = las_points(&path);
        for compress in [false, true] {
            let out = dir
                .path()
                .join(format!("back.{}", if compress { "laz" } else { "las" }));
            let n = write(&out, config(&meta, compress), &points, 40_000);
            assert_eq!(n, points.len() as u64);
            let name = format!("{} → {}", path.display(), out.display());
            let got = las_points(&out);
            assert_eq!(got.len(), expected.len(), "{name}");
            for (i, (g, e)) in got.iter().zip(expected.iter()).enumerate() {
                assert_eq!(g, e, "{name}: point {i}");
            }
            // The header says what was written, and the records carried are there.
            let l = las::Reader::from_path(&out).expect("las");
            let h = l.header();
            assert_eq!(h.number_of_points(), points.len() as u64, "{name}");
            assert_eq!((h.version().major, h.version().minor), (1, 4), "{name}");
            let b = h.bounds();
            let mut ours = pointlet_core::Aabb::EMPTY;
            points.xyz.iter().for_each(|p| ours.grow(*p));
            assert_eq!([b.min.x, b.min.y, b.min.z], ours.min, "{name}");
            assert_eq!([b.max.x, b.max.y, b.max.z], ours.max, "{name}");
            for n in 1..=15u8 {
                let want = points.returns.iter().filter(|r| *r & 0x0F == n).count() as u64;
                assert_eq!(
                    h.number_of_points_by_return(n).unwrap_or(0),
                    want,
                    "{name}: return {n}"
                );
            }
            let mut carried: Vec<_> = h
                .vlrs()
                .iter()
                .chain(h.evlrs().iter())
                .filter(|v| v.user_id != "laszip encoded")
                .map(|v| (v.user_id.clone(), v.record_id, v.data.clone()))
                .collect();
            let mut given: Vec<_> = meta
                .vlrs
                .iter()
                .map(|v| (v.user_id.clone(), v.record_id, v.data.clone()))
                .collect();
            carried.sort();
            given.sort();
            assert_eq!(carried, given, "{name}");
            assert_eq!(
                h.file_source_id(),
                meta.las.as_ref().unwrap().file_source_id
            );
            // Our own reader agrees too, and the waveform pointer leads to the waveform data.
            let mut back = pointlet_io::open(&out).expect("reopen");
            let mut again_vlrs = back.meta().vlrs.clone();
            let mut meta_vlrs = meta.vlrs.clone();
            again_vlrs.sort_by_key(|v| (v.user_id.clone(), v.record_id));
            meta_vlrs.sort_by_key(|v| (v.user_id.clone(), v.record_id));
            assert_eq!(again_vlrs, meta_vlrs, "{name}");
            assert_eq!(back.meta().las, meta.las, "{name}");
            let bytes = std::fs::read(&out).expect("read back");
            let waveform_at = u64::from_le_bytes(bytes[227..235].try_into().unwrap()) as usize;
            let has_waveform_data = meta.vlrs.iter().any(|v| v.is_waveform_data());
            assert_eq!(waveform_at != 0, has_waveform_data, "{name}");
            assert_eq!(
                bytes[6] & 2 != 0,
                has_waveform_data,
                "{name}: global encoding"
            );
            if has_waveform_data {
                assert_eq!(bytes[waveform_at + 18..waveform_at + 20], [0xFF, 0xFF]);
            }
            let again = read_all(back.as_mut(), 5000);
            assert!(again == points, "{name}: our reader sees other points");
        }
    }
    assert!(
        listing(dir.path()).iter().all(|n| !n.ends_with(".tmp")),
        "temporary files left: {:?}",
        listing(dir.path())
    );
}

/// A legacy source written in its extended counterpart reads back with the same meaning.
#[test]
fn legacy_files_written_as_extended_formats_keep_every_attribute() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Extended scan angles step by 0.006°: integer legacy angles come back within 0.003°.
    let coarse = |mut f: Vec<u64>| {
        f[14] = (f32::from_bits(f[14] as u32) as f64 * 100.0).round() as i64 as u64;
        f
    };
    for name in [
        "simple.las",
        "simple1_1.las",
        "simple1_3.las",
        "extrabytes.las",
    ] {
        let path = data(name);
        let mut r = pointlet_io::open(&path).expect("open");
        let meta = r.meta().clone();
        let points = read_all(r.as_mut(), 1 << 20);
        let mut cfg = config(&meta, true);
        cfg.point_format = meta.layout.las_point_format();
        let out = dir.path().join("ext.laz");
        write(&out, cfg, &points, 1 << 20);
        let got: Vec<_> = las_points(&out).into_iter().map(coarse).collect();
        let want: Vec<_> = las_points(&path).into_iter().map(coarse).collect();
        assert_eq!(got.len(), want.len());
        for (i, (g, w)) in got.iter().zip(want.iter()).enumerate() {
            assert_eq!(
                g,
                w,
                "{name} as point format {}: point {i}",
                meta.layout.las_point_format()
            );
        }
    }
}

/// Deterministic varied points of `layout` (every attribute exercised).
fn synthetic(layout: PointLayout, n: usize, extended: bool) -> PointBatch {
    let mut b = PointBatch::new(layout);
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    for i in 0..n {
        let r = next();
        b.xyz.push([
            1000.0 + (r % 100_000) as f64 * 0.01,
            2000.0 + ((r >> 17) % 100_000) as f64 * 0.01,
            ((r >> 34) % 10_000) as f64 * 0.01,
        ]);
        b.intensity.push((r >> 8) as u16);
        let (max_r, class_mod) = if extended { (15, 256) } else { (7, 32) };
        let nr = 1 + (r >> 40) as u8 % max_r;
        let rn = 1 + (r >> 44) as u8 % nr;
        b.returns.push(rn | nr << 4);
        let mut f = (r >> 48) as u8;
        if !extended {
            f &= !(3 << flags::CHANNEL_SHIFT);
        }
        b.flags.push(f);
        let mut class = ((r >> 52) % class_mod) as u8;
        // Codes the las crate misreads: legacy 28 as overlap (it tests 4 bits, not 5) and
        // extended 12 as class 1.
        if (!extended && class == 28) || (extended && class == 12) {
            class = 27;
        }
        // Legacy formats code overlap as class 12, read back as class 1 + the overlap flag.
        let legacy_overlap = !extended && (class == 12 || f & flags::OVERLAP != 0);
        if legacy_overlap {
            b.flags[i] |= flags::OVERLAP;
        }
        b.classification
            .push(if legacy_overlap { 1 } else { class });
        b.scan_angle.push(if extended {
            ((r >> 20) % 30_000) as f32 * 0.006 - 90.0
        } else {
            ((r >> 20) % 181) as f32 - 90.0
        });
        b.user_data.push((r >> 3) as u8);
        b.point_source_id.push((r >> 5) as u16);
        if layout.gps_time {
            b.gps_time.push(i as f64 * 0.001 + 1.0e8);
        }
        if layout.rgb {
            b.rgb.push([r as u16, (r >> 16) as u16, (r >> 32) as u16]);
        }
        if layout.nir {
            b.nir.push((r >> 24) as u16);
        }
        if layout.waveform {
            // Descriptor index, byte offset, packet size, location, x(t), y(t), z(t).
            let mut w = [0u8; WAVEFORM_BYTES];
            w[0] = 1 + (r % 3) as u8;
            w[1..9].copy_from_slice(&(i as u64 * 256).to_le_bytes());
            w[9..13].copy_from_slice(&256u32.to_le_bytes());
            w[13..17].copy_from_slice(&((r >> 10) as f32).to_le_bytes());
            w[17..29].copy_from_slice(&(r as u128 * 0x1_0001).to_le_bytes()[..12]);
            b.waveform.push(w);
        }
        for k in 0..layout.extra_bytes {
            b.extra_bytes.push((r >> k) as u8);
        }
    }
    b
}

#[test]
fn every_point_format_round_trips_as_las_and_laz() {
    let dir = tempfile::tempdir().expect("tempdir");
    let q = Quantization {
        scale: [0.01; 3],
        offset: [1000.0, 2000.0, 0.0],
    };
    for format in 0..=10u8 {
        let f = pointlet_io::las::PointFormat::new(format).expect("format");
        let layout = PointLayout {
            extra_bytes: 5,
            ..f.layout(5)
        };
        let points = synthetic(layout, 120_000, f.extended);
        for compress in [false, true] {
            let out = dir.path().join(format!(
                "f{format}.{}",
                if compress { "laz" } else { "las" }
            ));
            // Descriptors are written only with the waveform data they point into.
            let waveform_data = pointlet_core::Vlr {
                user_id: "LASF_Spec".into(),
                record_id: 65535,
                description: "Waveform Data Packets".into(),
                data: vec![7; 1024],
                extended: true,
            };
            let cfg = LasWriterConfig {
                quantization: q,
                point_format: format,
                layout,
                vlrs: [waveform_data]
                    .into_iter()
                    .filter(|_| layout.waveform)
                    .collect(),
                fields: Default::default(),
                compress,
            };
            write(&out, cfg, &points, 33_333);
            // Ours and the las crate agree on the file; ours gives back what was written
            // (scan angles once quantized to the record's resolution).
            let mut r = pointlet_io::open(&out).expect("open");
            let back = read_all(r.as_mut(), 10_000);
            assert_eq!(back.len(), points.len());
            let oracle = las_points(&out);
            for i in (0..back.len()).step_by(7) {
                assert_eq!(
                    our_fingerprint(&back, i),
                    oracle[i],
                    "format {format} point {i}"
                );
            }
            let mut expect = points.clone();
            expect.scan_angle = back.scan_angle.clone();
            assert!(back == expect, "format {format}, compress {compress}");
            for (a, b) in points.scan_angle.iter().zip(back.scan_angle.iter()) {
                assert!(
                    (a - b).abs() <= 0.0031,
                    "format {format}: scan angle {a} → {b}"
                );
            }
        }
    }
}

#[test]
fn an_unfinished_writer_leaves_no_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut r = pointlet_io::open(&data("simple.las")).expect("open");
    let meta = r.meta().clone();
    let points = read_all(r.as_mut(), 1 << 20);
    for compress in [false, true] {
        let out = dir.path().join("partial.laz");
        let mut w = LasWriter::create(&out, config(&meta, compress)).expect("create");
        w.write_batch(&points).expect("write");
        assert_eq!(listing(dir.path()).len(), 1, "only the temporary file");
        assert!(!out.exists(), "the target appears only on finish");
        drop(w);
        assert!(
            listing(dir.path()).is_empty(),
            "left: {:?}",
            listing(dir.path())
        );
    }
}

#[test]
fn a_coordinate_that_does_not_fit_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("huge.las");
    let layout = PointLayout::default();
    let mut b = synthetic(layout, 3, false);
    b.xyz[2] = [1e300, 0.0, 0.0];
    let mut w = LasWriter::create(
        &out,
        LasWriterConfig {
            quantization: Quantization {
                scale: [0.01; 3],
                offset: [0.0; 3],
            },
            point_format: 0,
            layout,
            vlrs: Vec::new(),
            fields: Default::default(),
            compress: false,
        },
    )
    .expect("create");
    let e = w
        .write_batch(&b)
        .expect_err("1e300 does not fit")
        .to_string();
    assert!(e.contains("huge.las") && e.contains("point 2"), "{e}");
    drop(w);
    assert!(listing(dir.path()).is_empty());
}

#[test]
fn bad_configurations_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.las");
    let base = LasWriterConfig {
        quantization: Quantization {
            scale: [0.01; 3],
            offset: [0.0; 3],
        },
        point_format: 3,
        layout: PointLayout {
            gps_time: true,
            rgb: true,
            ..Default::default()
        },
        vlrs: Vec::new(),
        fields: Default::default(),
        compress: false,
    };
    let mut c = base.clone();
    c.quantization.scale[1] = 0.0;
    let e = LasWriter::create(&out, c)
        .err()
        .expect("scale 0")
        .to_string();
    assert!(e.contains("scale") && e.contains("x.las"), "{e}");
    let mut c = base.clone();
    c.point_format = 42;
    let e = LasWriter::create(&out, c)
        .err()
        .expect("format 42")
        .to_string();
    assert!(e.contains("42"), "{e}");
    let mut c = base.clone();
    c.layout.nir = true;
    assert!(LasWriter::create(&out, c).is_err(), "format 3 has no NIR");
    let e = LasWriter::create(Path::new("/nonexistent-dir/x.las"), base)
        .err()
        .expect("no folder")
        .to_string();
    assert!(e.contains("x.las"), "{e}");
    assert!(listing(dir.path()).is_empty());
}

/// Enough points for the LAZ writer to hand whole chunks to the compressor several times, in
/// batches that never align with chunks.
#[test]
fn large_laz_in_small_batches_round_trips() {
    let dir = tempfile::tempdir().expect("tempdir");
    let f = pointlet_io::las::PointFormat::new(3).expect("format");
    let points = synthetic(f.layout(0), 1_700_000, false);
    let out = dir.path().join("large.laz");
    let cfg = LasWriterConfig {
        quantization: Quantization {
            scale: [0.01; 3],
            offset: [1000.0, 2000.0, 0.0],
        },
        point_format: 3,
        layout: f.layout(0),
        vlrs: Vec::new(),
        fields: Default::default(),
        compress: true,
    };
    assert_eq!(write(&out, cfg, &points, 7_777), points.len() as u64);
    let oracle = las_points(&out);
    assert_eq!(oracle.len(), points.len());
    for (i, o) in oracle.iter().enumerate() {
        assert_eq!(&our_fingerprint(&points, i), o, "point {i}");
    }
}
