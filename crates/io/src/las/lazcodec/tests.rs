//! Our chunk decoder against the `laz` crate, which defines correct: the same records byte for
//! byte from the files of testdata/, from files our writer makes in formats 0–3 (with and
//! without extra bytes), and from random records with extreme values compressed by the crate;
//! and damaged chunks (cut, random, bit flips, too many points claimed) give errors, never a
//! panic or a hang.

use super::{ChunkDecoder, Items};
use crate::las::laz::{chunks_of, uses_our_decoder, RawChunkList};
use laz::laszip::{ChunkTable, ChunkTableEntry};
use laz::{LazItemRecordBuilder, LazItemType, LazVlr, LazVlrBuilder};
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// A small deterministic generator (splitmix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    fn pick<T: Copy>(&mut self, from: &[T]) -> T {
        from[self.below(from.len() as u64) as usize]
    }

    /// A signed value in `-r..=r`.
    fn around(&mut self, r: i64) -> i64 {
        self.below(2 * r as u64 + 1) as i64 - r
    }
}

/// How a field moves from one record to the next.
#[derive(Clone, Copy, PartialEq)]
enum Move {
    Same,
    Small,
    Large,
    Random,
    Extreme,
}

/// A field's move: styles 0–3 lean towards smooth data, random data, extreme values, a mix.
fn next_move(rng: &mut Rng, style: u32) -> Move {
    use Move::*;
    let weights: [u64; 5] = match style {
        0 => [40, 50, 6, 2, 2],
        1 => [5, 5, 5, 80, 5],
        2 => [20, 10, 10, 10, 50],
        _ => [20, 20, 20, 20, 20],
    };
    let mut r = rng.below(weights.iter().sum());
    for (m, w) in [Same, Small, Large, Random, Extreme]
        .into_iter()
        .zip(weights)
    {
        if r < w {
            return m;
        }
        r -= w;
    }
    Random
}

/// State of the record generator: the last record and the GPS time sequences.
struct Gen {
    rec: Vec<u8>,
    /// Ends of up to six time sequences (interleaved flight lines) and the current one.
    tips: Vec<i64>,
    line: usize,
    step: i64,
}

impl Gen {
    fn new(len: usize) -> Self {
        Gen {
            rec: vec![0; len],
            tips: vec![1.0e8f64.to_bits() as i64],
            line: 0,
            step: 12_345,
        }
    }

    fn i32_field(&mut self, rng: &mut Rng, at: usize, style: u32) {
        let old = i32::from_le_bytes(self.rec[at..at + 4].try_into().expect("4 bytes"));
        let new = match next_move(rng, style) {
            Move::Same => old,
            Move::Small => old.wrapping_add(rng.around(100) as i32),
            Move::Large => old.wrapping_add(rng.around(1 << 28) as i32),
            Move::Random => rng.next() as i32,
            Move::Extreme => rng.pick(&[i32::MIN, i32::MAX, 0, -1, 1, i32::MIN + 1]),
        };
        self.rec[at..at + 4].copy_from_slice(&new.to_le_bytes());
    }

    fn u16_field(&mut self, rng: &mut Rng, at: usize, style: u32) {
        let old = u16::from_le_bytes([self.rec[at], self.rec[at + 1]]);
        let new = match next_move(rng, style) {
            Move::Same => old,
            Move::Small => old.wrapping_add(rng.around(40) as u16),
            Move::Large => old ^ (rng.next() as u16 & 0xFF00),
            Move::Random => rng.next() as u16,
            Move::Extreme => rng.pick(&[0, u16::MAX, 1, 0x8000, 0x7FFF, 0x00FF, 0xFF00]),
        };
        self.rec[at..at + 2].copy_from_slice(&new.to_le_bytes());
    }

    fn u8_field(&mut self, rng: &mut Rng, at: usize, style: u32) {
        let old = self.rec[at];
        self.rec[at] = match next_move(rng, style) {
            Move::Same => old,
            Move::Small => old.wrapping_add(rng.around(3) as u8),
            Move::Large | Move::Random => rng.next() as u8,
            Move::Extreme => rng.pick(&[0, 255, 0x80, 0x7F, 0xA6, 0x5A, 1]),
        };
    }

    fn gps(&mut self, rng: &mut Rng, at: usize, style: u32) {
        let line = self.line;
        let t = self.tips[line];
        let new = match next_move(rng, style) {
            Move::Same => t,
            // Whole multiples of the step, the extreme multiples included.
            Move::Small => t.wrapping_add(self.step * rng.pick(&[1, 1, 1, 2, 3, 0, -1])),
            Move::Large => {
                let k = rng.around(520);
                t.wrapping_add(self.step.wrapping_mul(k) + rng.around(3))
            }
            Move::Random => match rng.below(4) {
                // A new line far away, or back to an earlier one.
                0 if self.tips.len() < 6 => {
                    self.tips.push(t.wrapping_add(rng.around(1 << 40) << 8));
                    self.line = self.tips.len() - 1;
                    self.tips[self.line]
                }
                0 | 1 => {
                    self.line = rng.below(self.tips.len() as u64) as usize;
                    self.tips[self.line].wrapping_add(self.step)
                }
                2 => {
                    self.step = rng.around(1 << 20).max(1);
                    t.wrapping_add(self.step)
                }
                _ => rng.next() as i64,
            },
            Move::Extreme => rng.pick(&[
                i64::MIN,
                i64::MAX,
                0,
                -1,
                f64::NAN.to_bits() as i64,
                t.wrapping_add(i64::from(i32::MAX)),
                t.wrapping_add(i64::from(i32::MIN)),
                t.wrapping_add(1 << 32),
            ]),
        };
        // Within ±2^62: the crate's compressor (built with overflow checks in tests) subtracts
        // times without wrapping.
        let new = (new << 1) >> 1;
        self.tips[self.line] = new;
        self.rec[at..at + 8].copy_from_slice(&new.to_le_bytes());
    }

    fn rgb(&mut self, rng: &mut Rng, at: usize, style: u32) {
        match rng.below(4) {
            0 => {
                // Grey: every channel equal.
                self.u16_field(rng, at, style);
                let (lo, hi) = (self.rec[at], self.rec[at + 1]);
                for c in 1..3 {
                    self.rec[at + 2 * c] = lo;
                    self.rec[at + 2 * c + 1] = hi;
                }
            }
            1 => {
                // One byte of one channel.
                let k = at + rng.below(6) as usize;
                self.u8_field(rng, k, style);
            }
            _ => {
                for c in 0..3 {
                    self.u16_field(rng, at + 2 * c, style);
                }
            }
        }
    }

    /// The next record of `items`, fields moving by `style`.
    fn record(&mut self, rng: &mut Rng, items: Items, style: u32) -> &[u8] {
        for at in [0, 4, 8] {
            self.i32_field(rng, at, style);
        }
        self.u16_field(rng, 12, style);
        for at in 14..18 {
            self.u8_field(rng, at, style);
        }
        self.u16_field(rng, 18, style);
        let mut at = 20;
        if items.gps {
            self.gps(rng, at, style);
            at += 8;
        }
        if items.rgb {
            self.rgb(rng, at, style);
            at += 6;
        }
        for k in 0..usize::from(items.extra) {
            self.u8_field(rng, at + k, style);
        }
        &self.rec
    }
}

fn vlr_of(format: u8, extra: u16, chunk: u32) -> LazVlr {
    LazVlrBuilder::default()
        .with_point_format(format, extra)
        .expect("point format")
        .with_fixed_chunk_size(chunk)
        .build()
}

/// Compresses `records` with the `laz` crate: the chunks' bytes and point counts.
fn compress(records: &[u8], vlr: &LazVlr) -> RawChunkList {
    let mut out = Cursor::new(Vec::new());
    let table: ChunkTable =
        laz::laszip::parallel::par_compress(&mut out, records, vlr).expect("compress");
    let bytes = out.into_inner();
    let (mut at, mut left) = (0usize, records.len() as u64 / vlr.items_size());
    let mut chunks = Vec::new();
    for e in &table {
        let points = left.min(u64::from(vlr.chunk_size()));
        chunks.push((bytes[at..at + e.byte_count as usize].to_vec(), points));
        at += e.byte_count as usize;
        left -= points;
    }
    assert_eq!(at, bytes.len());
    assert_eq!(left, 0);
    chunks
}

/// The `laz` crate's decompression of one chunk; `None` when it panicked.
fn laz_decompress(vlr: &LazVlr, data: &[u8], out: &mut [u8]) -> Option<Result<(), String>> {
    let entry = [ChunkTableEntry {
        point_count: (out.len() as u64) / vlr.items_size(),
        byte_count: data.len() as u64,
    }];
    super::super::laz::guarded(|| laz::par_decompress(data, out, vlr, &entry))
        .ok()
        .map(|r| r.map_err(|e| e.to_string()))
}

/// Both decoders on every chunk of `chunks`: the same records (and `expect`, when given).
fn same_as_laz(vlr: &LazVlr, chunks: &RawChunkList, expect: Option<&[u8]>, what: &str) {
    let items = Items::supported(vlr.items()).expect("supported items");
    let len = items.record_len();
    assert_eq!(len as u64, vlr.items_size());
    let mut ours = ChunkDecoder::new(items);
    let mut at = 0;
    for (k, (data, points)) in chunks.iter().enumerate() {
        let n = *points as usize * len;
        let mut want = vec![0; n];
        laz_decompress(vlr, data, &mut want)
            .expect("the laz crate does not panic")
            .expect("the laz crate decompresses");
        let mut got = vec![0xAB; n];
        ours.decompress(data, &mut got)
            .unwrap_or_else(|e| panic!("{what}: chunk {k}: {e}"));
        if got != want {
            let bad = got.iter().zip(&want).position(|(a, b)| a != b).unwrap_or(0);
            panic!(
                "{what}: chunk {k} differs first in point {} byte {}: {:?} instead of {:?}",
                bad / len,
                bad % len,
                &got[bad / len * len..][..len],
                &want[bad / len * len..][..len]
            );
        }
        if let Some(e) = expect {
            assert!(got == e[at..at + n], "{what}: chunk {k} lost data");
        }
        at += n;
    }
}

#[test]
fn random_records_of_every_item_set_match_the_laz_crate() {
    let mut rng = Rng(7);
    for format in 0..=3u8 {
        for extra in [0u16, 1, 7] {
            for style in 0..4 {
                for (chunk, points) in [(1u32, 5usize), (2, 9), (997, 6000), (50_000, 3000)] {
                    let vlr = vlr_of(format, extra, chunk);
                    let items = Items::supported(vlr.items()).expect("supported");
                    let mut g = Gen::new(items.record_len());
                    let mut records = Vec::new();
                    for _ in 0..points {
                        records.extend_from_slice(g.record(&mut rng, items, style));
                    }
                    let chunks = compress(&records, &vlr);
                    let what = format!(
                        "format {format} + {extra} bytes, style {style}, chunks of {chunk}"
                    );
                    same_as_laz(&vlr, &chunks, Some(&records), &what);
                }
            }
        }
    }
}

fn testdata(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
}

#[test]
fn every_laz_file_of_testdata_with_these_items_matches_the_laz_crate() {
    let mut checked = Vec::new();
    let mut dir: Vec<PathBuf> = std::fs::read_dir(testdata(""))
        .expect("testdata/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "laz"))
        .collect();
    dir.sort();
    for path in dir {
        let (vlr, chunks) = chunks_of(&path).expect("readable LAZ");
        if Items::supported(vlr.items()).is_some() {
            same_as_laz(&vlr, &chunks, None, &path.display().to_string());
            checked.push(
                path.file_name()
                    .expect("name")
                    .to_string_lossy()
                    .into_owned(),
            );
            assert!(uses_our_decoder(&path).expect("open"), "{}", path.display());
        } else {
            assert!(
                !uses_our_decoder(&path).expect("open"),
                "{}",
                path.display()
            );
        }
    }
    assert_eq!(checked, ["autzen_trim.laz", "plane.laz", "simple.laz"]);
}

#[test]
fn the_reader_decompresses_with_one_decoder_only() {
    use crate::las::laz::LAZ_CRATE_CHUNKS;
    for (name, ours) in [
        ("autzen_trim.laz", true),
        ("simple.laz", true),
        ("simple.copc.laz", false),
    ] {
        let r = crate::open(&testdata(name)).expect("open");
        let parts = r.parted().expect("LAZ comes in parts");
        let before = LAZ_CRATE_CHUNKS.with(|n| n.get());
        let mut batch = pointlet_core::PointBatch::new(r.meta().layout);
        let mut scratch = Vec::new();
        let mut points = 0;
        for i in 0..parts.part_sizes().len() {
            parts
                .decode_part(i, &mut batch, &mut scratch)
                .expect("decode");
            points += batch.len() as u64;
        }
        assert_eq!(points, r.meta().point_count, "{name}");
        let crate_chunks = LAZ_CRATE_CHUNKS.with(|n| n.get()) - before;
        let expect = if ours { 0 } else { parts.part_sizes().len() };
        assert_eq!(
            crate_chunks, expect,
            "{name}: chunks the laz crate decompressed"
        );
    }
}

#[test]
fn files_our_writer_makes_in_formats_0_to_3_match_the_laz_crate() {
    use crate::generate::{SceneConfig, SceneGenerator};
    use crate::writer::{LasWriter, LasWriterConfig};
    use crate::PointReader;
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = SceneGenerator::new(SceneConfig {
        points: 110_000,
        seed: 3,
    });
    let meta = scene.meta();
    let mut reader = scene.reader();
    let mut points = pointlet_core::PointBatch::new(meta.layout);
    while let Some(b) = reader.read_batch(1 << 20).expect("generated") {
        for i in 0..b.len() {
            points.push_from(&b, i);
        }
    }
    for format in 0..=3u8 {
        for extra in [0u16, 3] {
            let mut b = points.clone();
            let f = crate::las::PointFormat::new(format).expect("format");
            b.layout = f.layout(extra);
            if !b.layout.gps_time {
                b.gps_time.clear();
            }
            if !b.layout.rgb {
                b.rgb.clear();
            }
            b.extra_bytes = (0..b.len() * usize::from(extra))
                .map(|i| (i / 5) as u8)
                .collect();
            let path = dir.path().join(format!("f{format}e{extra}.laz"));
            let mut w = LasWriter::create(
                &path,
                LasWriterConfig {
                    quantization: meta.quantization.expect("quantization"),
                    point_format: format,
                    layout: b.layout,
                    vlrs: Vec::new(),
                    fields: Default::default(),
                    compress: true,
                },
            )
            .expect("writer");
            w.write_batch(&b).expect("write");
            w.finish().expect("finish");
            let (vlr, chunks) = chunks_of(&path).expect("readable LAZ");
            assert!(chunks.len() >= 3);
            same_as_laz(&vlr, &chunks, None, &path.display().to_string());
        }
    }
}

#[test]
fn other_item_sets_are_left_to_the_laz_crate() {
    use laz::las::{Point0, Point3};
    let v1 = LazItemRecordBuilder::version_1_of::<Point3>(0);
    assert_eq!(Items::supported(&v1), None);
    let v1 = LazItemRecordBuilder::version_1_of::<Point0>(2);
    assert_eq!(Items::supported(&v1), None);
    for format in [4u8, 5, 6, 7, 8, 9, 10] {
        assert_eq!(
            Items::supported(vlr_of(format, 0, 100).items()),
            None,
            "{format}"
        );
    }
    for format in 0..=3u8 {
        let items = Items::supported(vlr_of(format, 4, 100).items()).expect("v2");
        assert_eq!(
            items.record_len() as u64,
            vlr_of(format, 4, 100).items_size()
        );
    }
    // Out of LASzip's order.
    let odd = LazItemRecordBuilder::new()
        .add_item(LazItemType::Point10)
        .add_item(LazItemType::RGB12)
        .add_item(LazItemType::GpsTime)
        .build();
    assert_eq!(Items::supported(&odd), None);
    let huge = LazItemRecordBuilder::new()
        .add_item(LazItemType::Point10)
        .add_item(LazItemType::Byte(super::MAX_EXTRA_BYTES + 1))
        .build();
    assert_eq!(Items::supported(&huge), None);
}

/// A few valid chunks of format 3 with extra bytes, for damaging.
fn sample_chunks() -> (LazVlr, RawChunkList, Vec<u8>) {
    let vlr = vlr_of(3, 2, 400);
    let items = Items::supported(vlr.items()).expect("supported");
    let mut rng = Rng(99);
    let mut g = Gen::new(items.record_len());
    let mut records = Vec::new();
    for i in 0..1000 {
        records.extend_from_slice(g.record(&mut rng, items, (i / 250) as u32));
    }
    let chunks = compress(&records, &vlr);
    (vlr, chunks, records)
}

/// Runs both decoders on damaged `data` for `points` points: ours never panics, and whenever
/// the `laz` crate neither panics nor fails, ours gives the same records.
fn damaged(vlr: &LazVlr, ours: &mut ChunkDecoder, data: &[u8], points: usize) -> bool {
    let len = vlr.items_size() as usize;
    let mut got = vec![0; points * len];
    let result = ours.decompress(data, &mut got);
    let mut want = vec![0; points * len];
    // The crate recurses on GPS sequence switches: give it room on damaged data.
    let laz = std::thread::scope(|s| {
        std::thread::Builder::new()
            .stack_size(256 << 20)
            .spawn_scoped(s, || laz_decompress(vlr, data, &mut want))
            .expect("thread")
            .join()
            .expect("no abort")
    });
    if let Some(Ok(())) = laz {
        // Ours gives up on a point that keeps switching GPS sequences (which valid data
        // never does); the crate follows the switches. Without overflow checks (release
        // builds: they go with debug assertions here) the crate wraps where it would panic,
        // and its bytes for such damage are no reference: only checked builds compare them.
        match &result {
            Ok(()) => assert!(
                got == want || !cfg!(debug_assertions),
                "ours decoded damaged data differently"
            ),
            Err(e) => assert!(
                e.contains("GPS"),
                "ours failed where the laz crate did not: {e}"
            ),
        }
    }
    if let Some(Err(_)) = laz {
        assert!(result.is_err(), "ours succeeded where the laz crate failed");
    }
    result.is_err()
}

#[test]
fn cut_chunks_are_errors() {
    let (vlr, chunks, _) = sample_chunks();
    let items = Items::supported(vlr.items()).expect("supported");
    let mut ours = ChunkDecoder::new(items);
    let (data, points) = &chunks[0];
    let mut failed = 0;
    for cut in 0..data.len() {
        failed += usize::from(damaged(&vlr, &mut ours, &data[..cut], *points as usize));
    }
    // Only the last few bytes LASzip's encoder flushes may go unread.
    assert!(
        failed + 4 >= data.len(),
        "{failed} of {} cuts failed",
        data.len()
    );
    // A chunk claiming more points than it holds.
    for more in [1, 2, 100, 100_000] {
        assert!(damaged(&vlr, &mut ours, data, *points as usize + more));
    }
    // Still decodes valid chunks after all that.
    same_as_laz(&vlr, &chunks, None, "after damage");
}

#[test]
fn chunks_decompressed_a_block_at_a_time_are_the_same_records() {
    let (vlr, chunks, records) = sample_chunks();
    let items = Items::supported(vlr.items()).expect("supported");
    let len = items.record_len();
    let mut ours = ChunkDecoder::new(items);
    // One record, a few, a block's worth, the whole chunk of 400 and more.
    for per_block in [1, 7, 64, 399, 400, 1000] {
        let mut got = Vec::new();
        for (data, points) in &chunks {
            let mut block = vec![0xAB; per_block * len + 3];
            let mut next = 0;
            ours.decompress_blocks(data, *points as usize, &mut block, |at, recs| {
                assert_eq!(at, next, "blocks of {per_block} come in order");
                assert!(recs.len() <= per_block * len && recs.len().is_multiple_of(len));
                next += recs.len() / len;
                got.extend_from_slice(recs);
                Ok(())
            })
            .unwrap_or_else(|e| panic!("blocks of {per_block}: {e}"));
            assert_eq!(next, *points as usize);
        }
        assert!(got == records, "blocks of {per_block}");
        // A chunk cut short fails in blocks too, and an error of the caller's stops it.
        let (data, points) = &chunks[0];
        let mut block = vec![0; per_block * len];
        let cut = ours.decompress_blocks(
            &data[..data.len() / 2],
            *points as usize,
            &mut block,
            |_, _| Ok(()),
        );
        assert!(cut.is_err(), "blocks of {per_block}: a cut chunk decoded");
        let mut calls = 0;
        let stopped = ours.decompress_blocks(data, *points as usize, &mut block, |_, _| {
            calls += 1;
            Err("stop".into())
        });
        assert_eq!((stopped, calls), (Err("stop".to_string()), 1));
    }
    // A block too small for one record is an error, not a loop.
    let (data, points) = &chunks[0];
    let mut small = vec![0; len - 1];
    assert!(ours
        .decompress_blocks(data, *points as usize, &mut small, |_, _| Ok(()))
        .is_err());
}

#[test]
fn random_and_flipped_bytes_never_panic() {
    let (vlr, chunks, _) = sample_chunks();
    let items = Items::supported(vlr.items()).expect("supported");
    let mut ours = ChunkDecoder::new(items);
    let mut rng = Rng(5);
    for round in 0..300 {
        let (data, points) = &chunks[round % chunks.len()];
        let mut bad = data.clone();
        match round % 3 {
            0 => {
                let at = rng.below(bad.len() as u64) as usize;
                bad[at] ^= 1 << rng.below(8);
            }
            1 => {
                for _ in 0..1 + rng.below(20) {
                    let at = rng.below(bad.len() as u64) as usize;
                    bad[at] = rng.next() as u8;
                }
            }
            _ => {
                let from = rng.below(bad.len() as u64) as usize;
                for b in &mut bad[from..] {
                    *b = rng.next() as u8;
                }
            }
        }
        damaged(&vlr, &mut ours, &bad, *points as usize);
    }
    // Bytes that were never a chunk, of every item set; long claims end quickly.
    for format in 0..=3u8 {
        let vlr = vlr_of(format, 3, 100);
        let mut ours = ChunkDecoder::new(Items::supported(vlr.items()).expect("supported"));
        for size in [0usize, 1, 20, 40, 64, 300, 5000] {
            for fill in [0x00u8, 0xFF, 0x55] {
                let data = vec![fill; size];
                let _ = ours.decompress(&data, &mut vec![0; 2000 * vlr.items_size() as usize]);
            }
            let data: Vec<u8> = (0..size).map(|_| rng.next() as u8).collect();
            damaged(&vlr, &mut ours, &data, 50);
            let _ = ours.decompress(&data, &mut vec![0; 100_000 * vlr.items_size() as usize]);
        }
    }
}

/// Decoding speed of single models (run with `--release --ignored --nocapture`).
#[test]
#[ignore]
fn symbol_speed() {
    use super::arith::{Arith, ByteModel, Model};
    use laz::encoders::ArithmeticEncoder;
    use laz::models::ArithmeticModelBuilder;
    let mut rng = Rng(1);
    let n = 4_000_000;
    for spread in [1u64, 4, 16, 64, 256] {
        let syms: Vec<u32> = (0..n)
            .map(|_| ((rng.below(spread) + rng.below(spread)) % 256) as u32)
            .collect();
        let mut enc = ArithmeticEncoder::new(Cursor::new(Vec::new()));
        let mut m = ArithmeticModelBuilder::new(256)
            .with_compression(true)
            .build();
        for s in &syms {
            enc.encode_symbol(&mut m, *s).expect("encode");
        }
        enc.done().expect("done");
        let bytes = enc.into_inner().into_inner();
        let t = std::time::Instant::now();
        let mut ac = Arith::new(&bytes);
        let mut m: Box<ByteModel> = Box::new(Model::INIT);
        let mut sum = 0u64;
        for _ in 0..n {
            sum += u64::from(ac.symbol(&mut m));
        }
        let ns = t.elapsed().as_secs_f64() * 1e9 / n as f64;
        let want: u64 = syms.iter().map(|s| u64::from(*s)).sum();
        assert_eq!(sum, want);
        println!(
            "256 symbols, spread {spread}: {ns:.2} ns per symbol, {:.2} bits",
            bytes.len() as f64 * 8.0 / n as f64
        );
    }
}

#[test]
fn the_fuzz_entry_decodes_real_chunks_and_survives_noise() {
    let (_, chunks) = chunks_of(&testdata("simple.laz")).expect("readable LAZ");
    // Format 3, no extra bytes: 1 point, then 98 (of the chunk's 1065), twice each; whole
    // and in blocks of 7 records, the same records.
    for pick in [0x03u8, 0x13, 0x03, 0x13] {
        let mut input = vec![pick];
        input.extend_from_slice(&chunks[0].0);
        let whole = super::raw::fuzz_chunk(&input, usize::MAX).expect("a real chunk decodes");
        assert_eq!(whole.len(), (1 + usize::from(pick >> 4) * 97) * 34);
        let blocks = super::raw::fuzz_chunk(&input, 7).expect("a real chunk decodes");
        assert!(whole == blocks, "pick {pick:#x}: blocks of 7 differ");
    }
    let mut rng = Rng(11);
    for len in [0usize, 1, 2, 30, 200, 3000] {
        let input: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
        let whole = super::raw::fuzz_chunk(&input, usize::MAX);
        assert_eq!(
            whole,
            super::raw::fuzz_chunk(&input, 7),
            "{len} bytes of noise"
        );
    }
}
