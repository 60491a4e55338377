//! LAS and LAZ files as parts: decoded in any order and from several threads they give exactly
//! the points `read_batch` gives; damage is an error naming the file and the part, never a panic.

mod common;
use common::*;
use pointlet_core::rows::RowLayout;
use pointlet_core::{PartedSource, PointBatch, PointLayout};
use pointlet_io::generate::{SceneConfig, SceneGenerator};
use pointlet_io::writer::{LasWriter, LasWriterConfig};
use pointlet_io::PointReader;
use std::path::{Path, PathBuf};

/// A generated scene of `points` points written as LAS or LAZ into `dir`.
fn generated(dir: &Path, points: u64, compress: bool) -> PathBuf {
    let scene = SceneGenerator::new(SceneConfig { points, seed: 7 });
    let meta = scene.meta();
    let path = dir.join(format!("scene.{}", if compress { "laz" } else { "las" }));
    let mut w = LasWriter::create(
        &path,
        LasWriterConfig {
            quantization: meta.quantization.expect("quantization"),
            point_format: meta.las_point_format.expect("format"),
            layout: meta.layout,
            vlrs: meta.vlrs.clone(),
            fields: meta.las.clone().unwrap_or_default(),
            compress,
        },
    )
    .expect("create");
    let mut r = scene.reader();
    while let Some(b) = r.read_batch(30_000).expect("generate") {
        w.write_batch(&b).expect("write");
    }
    w.finish().expect("finish");
    path
}

/// The shared files plus generated LAS and LAZ files large enough for several parts.
fn every_file(dir: &Path) -> Vec<PathBuf> {
    let mut files = shared_files();
    files.push(generated(dir, 100_000, false));
    files.push(generated(dir, 120_000, true));
    files
}

fn parts_of(r: &dyn PointReader) -> &dyn PartedSource {
    r.parted()
        .unwrap_or_else(|| panic!("{}: a LAS/LAZ reader must be parted", r.path().display()))
}

fn append(all: &mut PointBatch, b: &PointBatch) {
    for i in 0..b.len() {
        all.push_from(b, i);
    }
}

/// Part `i` decoded into `out` (with whatever it held before) and `scratch`, checked for shape.
fn decode(parts: &dyn PartedSource, i: usize, out: &mut PointBatch, scratch: &mut Vec<u8>) {
    parts
        .decode_part(i, out, scratch)
        .unwrap_or_else(|e| panic!("part {i}: {e}"));
    out.check_shape().expect("part shape");
    assert_eq!(out.len() as u64, parts.part_sizes()[i], "part {i} size");
}

/// Every part in order, each as its own batch.
fn parts_in_order(parts: &dyn PartedSource) -> Vec<PointBatch> {
    let mut scratch = Vec::new();
    (0..parts.part_sizes().len())
        .map(|i| {
            let mut b = PointBatch::default();
            decode(parts, i, &mut b, &mut scratch);
            b
        })
        .collect()
}

#[test]
fn parts_in_order_give_exactly_what_read_batch_gives() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut several = 0;
    for path in every_file(dir.path()) {
        let r = pointlet_io::open(&path).expect("open");
        let parts = parts_of(r.as_ref());
        let sizes = parts.part_sizes();
        assert_eq!(
            sizes.iter().sum::<u64>(),
            r.meta().point_count,
            "{}: part sizes",
            path.display()
        );
        assert!(sizes.iter().all(|&n| n > 0), "{}", path.display());
        several += usize::from(sizes.len() > 1);
        let mut all = PointBatch::new(r.meta().layout);
        for b in parts_in_order(parts) {
            assert_eq!(b.layout, r.meta().layout);
            append(&mut all, &b);
        }
        let mut fresh = pointlet_io::open(&path).expect("open");
        let expected = read_all(fresh.as_mut(), 7_000);
        assert!(
            all == expected,
            "{}: parts differ from read_batch",
            path.display()
        );
    }
    assert!(several >= 3, "too few files with several parts: {several}");
}

#[test]
fn rows_hold_the_files_integers_and_the_columns_decode_part_gives() {
    let dir = tempfile::tempdir().expect("tempdir");
    for path in every_file(dir.path()) {
        let r = pointlet_io::open(&path).expect("open");
        let parts = parts_of(r.as_ref());
        let q = r.meta().quantization.expect("LAS and LAZ are quantized");
        let layout = r.meta().layout;
        let other = pointlet_core::Quantization {
            scale: q.scale,
            offset: [q.offset[0] + q.scale[0], q.offset[1], q.offset[2]],
        };
        // The file's own columns, and a store's with every column (more extra bytes too):
        // what the file lacks must come out zero.
        let wide = PointLayout {
            gps_time: true,
            rgb: true,
            nir: true,
            waveform: true,
            extra_bytes: layout.extra_bytes + 3,
        };
        let narrower = PointLayout {
            gps_time: false,
            rgb: false,
            extra_bytes: layout.extra_bytes.saturating_sub(1),
            ..layout
        };
        let mut scratch = Vec::new();
        for (i, want) in parts_in_order(parts).into_iter().enumerate() {
            for store_layout in [layout, wide] {
                let row = RowLayout::new(&store_layout);
                // Garbage first: every byte must be written.
                let mut rows = vec![0xA5u8; want.len() * row.len];
                for (q2, row2, why) in [
                    (other, row, "another quantization"),
                    (q, RowLayout::new(&narrower), "fewer columns than the file"),
                ] {
                    if row2 == row && q2 == q {
                        continue;
                    }
                    let mut rows2 = vec![0u8; want.len() * row2.len];
                    let taken = parts
                        .decode_part_rows(i, &q2, &row2, &mut rows2, &mut scratch, &mut |_, _| {
                            panic!("{why}: rows handed over")
                        })
                        .expect("decoded");
                    assert!(!taken, "{}: {why} was taken", path.display());
                }
                // The stretches handed over as they were filled: in order, covering every row.
                let mut stretches = Vec::new();
                let taken = parts
                    .decode_part_rows(i, &q, &row, &mut rows, &mut scratch, &mut |at, r| {
                        stretches.push((at, r.to_vec()))
                    })
                    .expect("decoded");
                assert!(taken, "{}: part {i} not decoded into rows", path.display());
                let mut next = 0;
                for (at, r) in &stretches {
                    assert_eq!(*at, next, "{}: part {i} stretches", path.display());
                    assert!(r[..] == rows[at * row.len..][..r.len()]);
                    next += r.len() / row.len;
                }
                assert_eq!(next, want.len(), "{}: part {i} stretches", path.display());
                let quantized: Vec<[i32; 3]> = want
                    .xyz
                    .iter()
                    .map(|p| q.quantize(*p).expect("in range"))
                    .collect();
                let mut packed = vec![0u8; rows.len()];
                row.pack(&want, 0, &quantized, &mut packed);
                assert!(
                    rows == packed,
                    "{}: part {i} rows of {store_layout:?}",
                    path.display()
                );
            }
            // Rows for another number of points are an error, not a partial decode.
            let row = RowLayout::new(&layout);
            let mut short = vec![0u8; (want.len() - 1) * row.len];
            assert!(parts
                .decode_part_rows(i, &q, &row, &mut short, &mut scratch, &mut |_, _| {})
                .is_err());
        }
    }
}

#[test]
fn parts_in_any_order_and_from_several_threads_are_the_same() {
    let dir = tempfile::tempdir().expect("tempdir");
    for path in every_file(dir.path()) {
        let r = pointlet_io::open(&path).expect("open");
        let parts = parts_of(r.as_ref());
        let expected = parts_in_order(parts);
        let n = expected.len();
        // Reverse order, then a fixed shuffle, into one reused batch and scratch buffer.
        let mut order: Vec<usize> = (0..n).rev().collect();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for k in (1..n).rev() {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            order.swap(k, (state >> 33) as usize % (k + 1));
        }
        order.extend((0..n).rev());
        let (mut out, mut scratch) = (PointBatch::default(), Vec::new());
        for &i in &order {
            decode(parts, i, &mut out, &mut scratch);
            assert!(out == expected[i], "{}: part {i}", path.display());
        }
        // Two threads sharing the reader, each taking every other part.
        std::thread::scope(|s| {
            for t in 0..2 {
                let expected = &expected;
                s.spawn(move || {
                    let (mut out, mut scratch) = (PointBatch::default(), Vec::new());
                    for i in (t..n).step_by(2) {
                        decode(parts, i, &mut out, &mut scratch);
                        assert!(out == expected[i], "part {i} on thread {t}");
                    }
                });
            }
        });
    }
}

#[test]
fn decoding_parts_does_not_move_read_batch() {
    let dir = tempfile::tempdir().expect("tempdir");
    for path in every_file(dir.path()) {
        let mut fresh = pointlet_io::open(&path).expect("open");
        let expected = read_all(fresh.as_mut(), 5_000);
        let mut r = pointlet_io::open(&path).expect("open");
        let mut all = PointBatch::new(r.meta().layout);
        let (mut out, mut scratch) = (PointBatch::default(), Vec::new());
        let mut k = 0;
        loop {
            let parts = parts_of(r.as_ref());
            let last = parts.part_sizes().len() - 1;
            decode(parts, last - k % (last + 1), &mut out, &mut scratch);
            k += 1;
            match r.read_batch(5_000).expect("read_batch") {
                Some(b) => append(&mut all, &b),
                None => break,
            }
        }
        assert!(
            all == expected,
            "{}: read_batch was disturbed",
            path.display()
        );
    }
}

/// The message of part `i`'s error; it must name the file.
fn part_error(parts: &dyn PartedSource, i: usize, path: &Path) -> String {
    let e = parts
        .decode_part(i, &mut PointBatch::default(), &mut Vec::new())
        .expect_err("a damaged part must be an error")
        .to_string();
    let name = path.file_name().and_then(|n| n.to_str()).expect("name");
    assert!(e.contains(name), "the error lacks the file name: {e}");
    e
}

#[test]
fn a_las_file_cut_after_opening_names_the_first_missing_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = generated(dir.path(), 100_000, false);
    let h = pointlet_io::las::parse_header(&std::fs::read(&path).expect("read")).expect("header");
    let (start, len) = (
        u64::from(h.offset_to_point_data),
        u64::from(h.point_record_length),
    );
    let mut r = pointlet_io::open(&path).expect("open");
    let parts = parts_of(r.as_ref());
    let sizes = parts.part_sizes().to_vec();
    assert!(sizes.len() >= 3, "{sizes:?}");
    let expected = parts_in_order(parts);
    // Cut inside a record of the second part.
    let missing = sizes[0] + 1_234;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .expect("open for cutting");
    file.set_len(start + missing * len + len / 2).expect("cut");
    let mut out = PointBatch::default();
    decode(parts, 0, &mut out, &mut Vec::new());
    assert!(out == expected[0], "the part before the cut still decodes");
    let claim = |point: u64| {
        format!(
            "the file ends early: point {} of the 100000 the header claims is missing (its record would start at byte {})",
            point + 1,
            start + point * len
        )
    };
    let e = part_error(parts, 1, &path);
    assert!(e.contains(&claim(missing)), "{e}");
    let e = part_error(parts, 2, &path);
    assert!(e.contains(&claim(sizes[0] + sizes[1])), "{e}");
    // read_batch says the same of the same point.
    let e = loop {
        match r.read_batch(20_000) {
            Ok(Some(_)) => {}
            Ok(None) => panic!("a cut file must not read to the end"),
            Err(e) => break e.to_string(),
        }
    };
    assert!(e.contains(&claim(missing)), "{e}");
}

#[test]
fn a_shared_las_file_cut_after_opening_is_an_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("cut.las");
    std::fs::copy(data("simple.las"), &path).expect("copy");
    let r = pointlet_io::open(&path).expect("open");
    let parts = parts_of(r.as_ref());
    let end = std::fs::metadata(&path).expect("meta").len();
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .expect("open for cutting");
    // simple.las ends with its records: keep all but the last record and a half.
    file.set_len(end - 34 - 17).expect("cut");
    let e = part_error(parts, 0, &path);
    assert!(
        e.contains("the file ends early: point 1064 of the 1065 the header claims is missing"),
        "{e}"
    );
}

/// Byte offsets of the chunks of a LAZ file, from its chunk table.
fn chunk_offsets(bytes: &[u8]) -> Vec<u64> {
    let h = pointlet_io::las::parse_header(bytes).expect("header");
    let vlr = laz::LazVlr::from_buffer(h.laszip.as_deref().expect("LASzip VLR")).expect("vlr");
    let mut cursor = std::io::Cursor::new(bytes);
    cursor.set_position(u64::from(h.offset_to_point_data));
    let table = laz::laszip::ChunkTable::read_from(&mut cursor, &vlr).expect("chunk table");
    let mut at = u64::from(h.offset_to_point_data) + 8;
    table
        .as_ref()
        .iter()
        .map(|e| {
            let offset = at;
            at += e.byte_count;
            offset
        })
        .collect()
}

#[test]
fn a_damaged_laz_chunk_is_an_error_naming_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = generated(dir.path(), 120_000, true);
    let cases = [
        // Layered chunks (format 7) begin with their point count: a wrong one is always caught.
        (data("simple.copc.laz"), "points but the chunk table says"),
        // Point-wise chunks: every compressed byte of the chunk overwritten.
        (scene, "cannot be decompressed"),
    ];
    for (source, why) in cases {
        let mut bytes = std::fs::read(&source).expect("read");
        let offsets = chunk_offsets(&bytes);
        let h = pointlet_io::las::parse_header(&bytes).expect("header");
        let k = offsets.len() / 2;
        let at = offsets[k] as usize;
        if h.point_format >= 6 {
            let count = at + usize::from(h.point_record_length);
            bytes[count..count + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        } else {
            let end = offsets.get(k + 1).map_or(at + 64, |&e| e as usize);
            bytes[at..end].fill(0xA5);
        }
        let name = source.file_name().and_then(|n| n.to_str()).expect("name");
        let path = dir.path().join(format!("damaged-{name}"));
        std::fs::write(&path, &bytes).expect("write");
        let r = pointlet_io::open(&path).expect("open");
        let parts = parts_of(r.as_ref());
        let e = part_error(parts, k, &path);
        assert!(
            e.contains(&format!(
                "LAZ chunk {k} (at byte {at}) cannot be decompressed"
            )),
            "{e}"
        );
        assert!(e.contains(why), "{e}");
        let (mut out, mut scratch) = (PointBatch::default(), Vec::new());
        for i in (0..offsets.len()).filter(|&i| i != k) {
            decode(parts, i, &mut out, &mut scratch);
        }
    }
}

#[test]
fn a_laz_file_cut_after_opening_names_the_chunk() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("cut.laz");
    std::fs::copy(data("autzen_trim.laz"), &path).expect("copy");
    let offsets = chunk_offsets(&std::fs::read(&path).expect("read"));
    assert!(offsets.len() >= 2, "{offsets:?}");
    let r = pointlet_io::open(&path).expect("open");
    let parts = parts_of(r.as_ref());
    let last = offsets.len() - 1;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .expect("open for cutting");
    file.set_len(offsets[last] + 10).expect("cut");
    let e = part_error(parts, last, &path);
    assert!(
        e.contains(&format!("LAZ chunk {last} ("))
            && e.contains(&format!("at byte {})", offsets[last])),
        "{e}"
    );
    assert!(e.contains("the file ends inside it"), "{e}");
    decode(parts, 0, &mut PointBatch::default(), &mut Vec::new());
}

#[test]
fn a_part_that_does_not_exist_is_an_error() {
    for name in ["simple.las", "simple.laz"] {
        let path = data(name);
        let r = pointlet_io::open(&path).expect("open");
        let parts = parts_of(r.as_ref());
        let e = part_error(parts, parts.part_sizes().len(), &path);
        assert!(e.contains("there is no"), "{e}");
    }
}
