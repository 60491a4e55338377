//! Turning Hilbert-sorted points into the store's bytes: per pointlet, shuffle, split the
//! records into the attribute streams, bound and checksum them, and write them in place.
//!
//! While sorting, a point is one fixed-size *record*: the concatenation of its stream values in
//! stream order and in stream encoding, so splitting a record into streams is plain byte copies.

use crate::format::{Plan, PointletEntry, StreamKind, TABLE_ENTRY_LEN};
use crate::{pio, StoreError};
use pointlet_core::shuffle::{mix_seed, permutation};
use pointlet_core::{Aabb, PointBatch, PointLayout, Quantization};
use rayon::prelude::*;
use std::fs::File;
use std::path::Path;

/// Where each stream's value sits inside a record.
#[derive(Clone, Debug)]
pub(crate) struct RecordLayout {
    /// Bytes per record.
    pub len: usize,
    /// (stream, offset in the record, bytes), in stream order; position is first at offset 0.
    pub fields: Vec<(StreamKind, usize, usize)>,
    gps_time: Option<usize>,
    rgb: Option<usize>,
    nir: Option<usize>,
    waveform: Option<usize>,
    extra: Option<(usize, usize)>,
}

// The always-present fields lead every record at fixed offsets.
const INTENSITY: usize = 12;
const RETURNS: usize = 14;
const FLAGS: usize = 15;
const CLASSIFICATION: usize = 16;
const SCAN_ANGLE: usize = 17;
const USER_DATA: usize = 21;
const POINT_SOURCE_ID: usize = 22;

impl RecordLayout {
    pub fn new(layout: &PointLayout) -> RecordLayout {
        let mut fields = Vec::new();
        let mut at = 0;
        for (kind, bpp) in StreamKind::present(layout) {
            fields.push((kind, at, bpp));
            at += bpp;
        }
        let find = |k: StreamKind| fields.iter().find(|f| f.0 == k).map(|f| f.1);
        RecordLayout {
            len: at,
            gps_time: find(StreamKind::GpsTime),
            rgb: find(StreamKind::Rgb),
            nir: find(StreamKind::Nir),
            waveform: find(StreamKind::Waveform),
            extra: find(StreamKind::ExtraBytes).map(|o| (o, layout.extra_bytes as usize)),
            fields,
        }
    }

    /// Writes point `i` of `batch` (whose layout is a subset of this one) into `rec`.
    /// Columns the batch lacks are zero; shorter extra bytes are zero-padded.
    #[inline]
    pub fn pack(&self, batch: &PointBatch, i: usize, raw: [i32; 3], rec: &mut [u8]) {
        rec[0..4].copy_from_slice(&raw[0].to_le_bytes());
        rec[4..8].copy_from_slice(&raw[1].to_le_bytes());
        rec[8..12].copy_from_slice(&raw[2].to_le_bytes());
        rec[INTENSITY..INTENSITY + 2].copy_from_slice(&batch.intensity[i].to_le_bytes());
        rec[RETURNS] = batch.returns[i];
        rec[FLAGS] = batch.flags[i];
        rec[CLASSIFICATION] = batch.classification[i];
        rec[SCAN_ANGLE..SCAN_ANGLE + 4].copy_from_slice(&batch.scan_angle[i].to_le_bytes());
        rec[USER_DATA] = batch.user_data[i];
        rec[POINT_SOURCE_ID..POINT_SOURCE_ID + 2]
            .copy_from_slice(&batch.point_source_id[i].to_le_bytes());
        let l = &batch.layout;
        if let Some(o) = self.gps_time {
            let v = if l.gps_time { batch.gps_time[i] } else { 0.0 };
            rec[o..o + 8].copy_from_slice(&v.to_le_bytes());
        }
        if let Some(o) = self.rgb {
            let c = if l.rgb { batch.rgb[i] } else { [0; 3] };
            for (j, v) in c.iter().enumerate() {
                rec[o + 2 * j..o + 2 * j + 2].copy_from_slice(&v.to_le_bytes());
            }
        }
        if let Some(o) = self.nir {
            let v = if l.nir { batch.nir[i] } else { 0 };
            rec[o..o + 2].copy_from_slice(&v.to_le_bytes());
        }
        if let Some(o) = self.waveform {
            let dst = &mut rec[o..o + pointlet_core::WAVEFORM_BYTES];
            if l.waveform {
                dst.copy_from_slice(&batch.waveform[i]);
            } else {
                dst.fill(0);
            }
        }
        if let Some((o, n)) = self.extra {
            let have = l.extra_bytes as usize;
            let dst = &mut rec[o..o + n];
            dst[..have].copy_from_slice(&batch.extra_bytes[i * have..(i + 1) * have]);
            dst[have..].fill(0);
        }
    }
}

/// Where the records of sorted positions come from.
pub(crate) enum Source<'a> {
    /// An in-memory run: `order[s].1` is the run index of the s-th sorted point.
    Run {
        records: &'a [u8],
        order: &'a [(u64, u32)],
    },
    /// A block of already sorted records starting at sorted position `first`.
    Sorted { records: &'a [u8], first: u64 },
}

impl Source<'_> {
    /// The records of sorted positions `[first, first + count)`, contiguous.
    fn records<'s>(
        &'s self,
        first: u64,
        count: usize,
        rb: usize,
        scratch: &'s mut Vec<u8>,
    ) -> &'s [u8] {
        match self {
            Source::Run { records, order } => {
                scratch.clear();
                let start = first as usize;
                for (_, idx) in &order[start..start + count] {
                    let at = *idx as usize * rb;
                    scratch.extend_from_slice(&records[at..at + rb]);
                }
                scratch
            }
            Source::Sorted {
                records,
                first: base,
            } => {
                let at = (first - base) as usize * rb;
                &records[at..at + count * rb]
            }
        }
    }
}

/// Copies field `(offset, B bytes)` of records `perm[j]` into slot j of `out`.
fn gather<const B: usize>(out: &mut [u8], src: &[u8], rb: usize, offset: usize, perm: &[u32]) {
    for (o, &j) in out.chunks_exact_mut(B).zip(perm) {
        let s = j as usize * rb + offset;
        o.copy_from_slice(&src[s..s + B]);
    }
}

fn gather_any(out: &mut [u8], src: &[u8], rb: usize, offset: usize, bytes: usize, perm: &[u32]) {
    for (o, &j) in out.chunks_exact_mut(bytes).zip(perm) {
        let s = j as usize * rb + offset;
        o.copy_from_slice(&src[s..s + bytes]);
    }
}

/// One block's stream bytes waiting to be written at sorted position `first`.
struct Pending {
    first: u64,
    buffers: Vec<Vec<u8>>,
}

/// Writes the streams, pointlet table and checksum table of a store being built, block by
/// block in pointlet order. A block's streams are written while the next block is computed.
pub(crate) struct Emitter<'a> {
    file: &'a File,
    path: &'a Path,
    plan: &'a Plan,
    rl: &'a RecordLayout,
    k: u64,
    points: u64,
    seed: u64,
    quantization: Quantization,
    table_crc: crc32fast::Hasher,
    checksums_crc: crc32fast::Hasher,
    /// Pointlets emitted so far; blocks must come in order.
    next_pointlet: u64,
    pending: Option<Pending>,
    /// Stream buffers to reuse.
    spare: Vec<Vec<u8>>,
}

/// What the emitter computed for one pointlet: its table entry and stream checksums.
type PointletResult = (PointletEntry, Vec<u32>);

impl<'a> Emitter<'a> {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        file: &'a File,
        path: &'a Path,
        plan: &'a Plan,
        rl: &'a RecordLayout,
        k: u64,
        points: u64,
        seed: u64,
        quantization: Quantization,
    ) -> Self {
        Emitter {
            file,
            path,
            plan,
            rl,
            k,
            points,
            seed,
            quantization,
            table_crc: crc32fast::Hasher::new(),
            checksums_crc: crc32fast::Hasher::new(),
            next_pointlet: 0,
            pending: None,
            spare: Vec::new(),
        }
    }

    pub fn path(&self) -> &Path {
        self.path
    }

    pub fn k(&self) -> u64 {
        self.k
    }

    pub fn points(&self) -> u64 {
        self.points
    }

    pub fn record_len(&self) -> usize {
        self.rl.len
    }

    pub fn next_pointlet(&self) -> u64 {
        self.next_pointlet
    }

    pub fn pointlet_count(&self) -> u64 {
        self.points.div_ceil(self.k)
    }

    /// First sorted position of pointlet `p`.
    fn first_point(&self, p: u64) -> u64 {
        p * self.k
    }

    /// Emits pointlets `[p0, p1)` (the next ones) whose records `source` supplies.
    pub fn block(&mut self, p0: u64, p1: u64, source: &Source<'_>) -> Result<(), StoreError> {
        if p0 != self.next_pointlet || p1 <= p0 || p1 > self.pointlet_count() {
            return Err(StoreError::build(
                self.path,
                format!("internal error: pointlets {p0}..{p1} emitted out of order"),
            ));
        }
        let a = self.first_point(p0);
        let n = (self.first_point(p1).min(self.points) - a) as usize;
        let rl = self.rl;
        let mut buffers = std::mem::take(&mut self.spare);
        buffers.resize_with(rl.fields.len(), Vec::new);
        for (buf, (_, _, bpp)) in buffers.iter_mut().zip(&rl.fields) {
            buf.clear();
            buf.resize(n * bpp, 0);
        }
        let pending = self.pending.take();
        let (written, results) = rayon::join(
            || self.write_streams(pending),
            || self.compute(p0, p1, source, &mut buffers),
        );
        if let Some(reuse) = written? {
            self.spare = reuse;
        }
        self.pending = Some(Pending { first: a, buffers });
        let mut table = vec![0u8; results.len() * TABLE_ENTRY_LEN as usize];
        let mut checks = Vec::with_capacity(results.len() * rl.fields.len() * 4);
        for ((entry, crcs), out) in results
            .iter()
            .zip(table.chunks_exact_mut(TABLE_ENTRY_LEN as usize))
        {
            out.copy_from_slice(&entry.encode());
            for c in crcs {
                checks.extend_from_slice(&c.to_le_bytes());
            }
        }
        self.table_crc.update(&table);
        self.checksums_crc.update(&checks);
        let table_at = self.plan.table.offset + p0 * TABLE_ENTRY_LEN;
        pio::write_all_at(self.file, &table, table_at)
            .map_err(|e| StoreError::io(self.path, "writing the pointlet table", e))?;
        let checks_at = self.plan.checksums.offset + p0 * 4 * rl.fields.len() as u64;
        pio::write_all_at(self.file, &checks, checks_at)
            .map_err(|e| StoreError::io(self.path, "writing the checksum table", e))?;
        self.next_pointlet = p1;
        Ok(())
    }

    /// Writes the last block and returns the CRC32s of the pointlet and checksum tables.
    pub fn finish(mut self) -> Result<(u32, u32), StoreError> {
        let pending = self.pending.take();
        self.write_streams(pending)?;
        Ok((self.table_crc.finalize(), self.checksums_crc.finalize()))
    }

    /// Writes a block's streams in place; gives the buffers back for reuse.
    fn write_streams(&self, pending: Option<Pending>) -> Result<Option<Vec<Vec<u8>>>, StoreError> {
        let Some(p) = pending else {
            return Ok(None);
        };
        for (buf, info) in p.buffers.iter().zip(&self.plan.streams) {
            let at = info.offset + p.first * info.bytes_per_point as u64;
            pio::write_all_at(self.file, buf, at).map_err(|e| {
                StoreError::io(
                    self.path,
                    format!("writing the {} stream", info.kind.name()),
                    e,
                )
            })?;
        }
        Ok(Some(p.buffers))
    }

    /// Shuffles, splits, bounds and checksums pointlets `[p0, p1)` into `buffers`.
    fn compute(
        &self,
        p0: u64,
        p1: u64,
        source: &Source<'_>,
        buffers: &mut [Vec<u8>],
    ) -> Vec<PointletResult> {
        let rl = self.rl;
        let k = self.k as usize;
        // Each pointlet's slice of every stream buffer, so pointlets can be filled in parallel.
        let mut slices: Vec<Vec<&mut [u8]>> = (p0..p1)
            .map(|_| Vec::with_capacity(rl.fields.len()))
            .collect();
        for (buf, (_, _, bpp)) in buffers.iter_mut().zip(&rl.fields) {
            for (s, chunk) in slices.iter_mut().zip(buf.chunks_mut(k * bpp)) {
                s.push(chunk);
            }
        }
        let (seed, q) = (self.seed, self.quantization);
        slices
            .into_par_iter()
            .enumerate()
            .map_init(Vec::new, |scratch, (j, mut outs)| {
                let p = p0 + j as u64;
                let first = self.first_point(p);
                let count = (self.points - first).min(self.k) as usize;
                let records = source.records(first, count, rl.len, scratch);
                let perm = permutation(count, mix_seed(seed, p));
                for ((_, offset, bpp), out) in rl.fields.iter().zip(outs.iter_mut()) {
                    let (o, b) = (*offset, *bpp);
                    match b {
                        1 => gather::<1>(out, records, rl.len, o, &perm),
                        2 => gather::<2>(out, records, rl.len, o, &perm),
                        4 => gather::<4>(out, records, rl.len, o, &perm),
                        6 => gather::<6>(out, records, rl.len, o, &perm),
                        8 => gather::<8>(out, records, rl.len, o, &perm),
                        12 => gather::<12>(out, records, rl.len, o, &perm),
                        _ => gather_any(out, records, rl.len, o, b, &perm),
                    }
                }
                let aabb = position_bounds(outs[0], &q);
                let crcs = outs.iter().map(|o| crc32fast::hash(o)).collect();
                (
                    PointletEntry {
                        first,
                        count: count as u32,
                        aabb,
                    },
                    crcs,
                )
            })
            .collect()
    }
}

/// Bounds of dequantized positions given as little-endian `[i32; 3]` records.
pub(crate) fn position_bounds(bytes: &[u8], q: &Quantization) -> Aabb {
    let mut lo = [i32::MAX; 3];
    let mut hi = [i32::MIN; 3];
    for p in bytes.chunks_exact(12) {
        for a in 0..3 {
            let v = i32::from_le_bytes(crate::format::array(&p[4 * a..4 * a + 4]));
            lo[a] = lo[a].min(v);
            hi[a] = hi[a].max(v);
        }
    }
    // Dequantizing is monotonic, so the box of the dequantized points is that of its corners.
    Aabb {
        min: q.dequantize(lo),
        max: q.dequantize(hi),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_offsets_match_the_stream_order() {
        let rl = RecordLayout::new(&PointLayout::default());
        let at = |k: StreamKind| rl.fields.iter().find(|f| f.0 == k).map(|f| f.1);
        assert_eq!(at(StreamKind::Position), Some(0));
        assert_eq!(at(StreamKind::Intensity), Some(INTENSITY));
        assert_eq!(at(StreamKind::Returns), Some(RETURNS));
        assert_eq!(at(StreamKind::Flags), Some(FLAGS));
        assert_eq!(at(StreamKind::Classification), Some(CLASSIFICATION));
        assert_eq!(at(StreamKind::ScanAngle), Some(SCAN_ANGLE));
        assert_eq!(at(StreamKind::UserData), Some(USER_DATA));
        assert_eq!(at(StreamKind::PointSourceId), Some(POINT_SOURCE_ID));
        assert_eq!(rl.len, POINT_SOURCE_ID + 2);
    }

    #[test]
    fn packing_a_narrower_batch_zero_fills() {
        let wide = PointLayout {
            gps_time: true,
            rgb: true,
            nir: true,
            waveform: true,
            extra_bytes: 3,
        };
        let narrow = PointLayout {
            extra_bytes: 1,
            ..Default::default()
        };
        let mut b = PointBatch::new(narrow);
        b.xyz.push([0.0; 3]);
        b.intensity.push(0x0102);
        b.returns.push(3);
        b.flags.push(4);
        b.classification.push(5);
        b.scan_angle.push(1.5);
        b.user_data.push(6);
        b.point_source_id.push(0x0708);
        b.extra_bytes.push(9);
        let rl = RecordLayout::new(&wide);
        let mut rec = vec![0xFF; rl.len];
        rl.pack(&b, 0, [1, -1, 2], &mut rec);
        assert_eq!(&rec[0..4], &1i32.to_le_bytes());
        assert_eq!(&rec[4..8], &(-1i32).to_le_bytes());
        assert_eq!(&rec[INTENSITY..INTENSITY + 2], &[2, 1]);
        assert_eq!(&rec[SCAN_ANGLE..SCAN_ANGLE + 4], &1.5f32.to_le_bytes());
        let extra = rl.extra.unwrap().0;
        assert_eq!(&rec[extra..], &[9, 0, 0]);
        // gps, rgb, nir and waveform lie between the fixed fields and the extra bytes.
        assert!(rec[POINT_SOURCE_ID + 2..extra].iter().all(|x| *x == 0));
    }
}
