//! A point as one fixed-size row: every column's value, little-endian, at a fixed offset. This
//! is how conversion holds points between decoding and writing a store's streams, so that
//! splitting rows into streams is plain byte copies. Positions are the stored integers of the
//! store's quantization; the always-present columns follow at fixed offsets, then the optional
//! ones a layout has, in layout order.

use crate::{PointBatch, PointLayout, WAVEFORM_BYTES};

pub const POSITION: usize = 0;
pub const INTENSITY: usize = 12;
pub const RETURNS: usize = 14;
pub const FLAGS: usize = 15;
pub const CLASSIFICATION: usize = 16;
/// Degrees, as f32.
pub const SCAN_ANGLE: usize = 17;
pub const USER_DATA: usize = 21;
pub const POINT_SOURCE_ID: usize = 22;
/// Bytes of the always-present columns.
const FIXED: usize = 24;

/// Where each column of one point layout sits inside a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowLayout {
    /// The columns the rows hold.
    pub layout: PointLayout,
    /// Bytes per row.
    pub len: usize,
    pub gps_time: Option<usize>,
    pub rgb: Option<usize>,
    pub nir: Option<usize>,
    pub waveform: Option<usize>,
    /// Offset and width of the extra bytes.
    pub extra: Option<(usize, usize)>,
}

impl RowLayout {
    pub fn new(layout: &PointLayout) -> RowLayout {
        let mut len = FIXED;
        let mut next = |on: bool, bytes: usize| {
            on.then(|| {
                len += bytes;
                len - bytes
            })
        };
        let gps_time = next(layout.gps_time, 8);
        let rgb = next(layout.rgb, 6);
        let nir = next(layout.nir, 2);
        let waveform = next(layout.waveform, WAVEFORM_BYTES);
        let width = usize::from(layout.extra_bytes);
        let extra = next(width > 0, width).map(|at| (at, width));
        RowLayout {
            layout: *layout,
            len,
            gps_time,
            rgb,
            nir,
            waveform,
            extra,
        }
    }

    /// Writes `values`, `W` bytes each, at offset `at` of consecutive rows of `rows`.
    #[inline(always)]
    pub fn put<const W: usize>(
        &self,
        rows: &mut [u8],
        at: usize,
        values: impl IntoIterator<Item = [u8; W]>,
    ) {
        for (row, v) in rows.chunks_exact_mut(self.len).zip(values) {
            row[at..at + W].copy_from_slice(&v);
        }
    }

    /// Writes extra bytes (one slice per row, at most as wide as the rows' extra bytes; the
    /// rest of each row's extra bytes zero). Nothing when the rows have none.
    pub fn put_extra<'v>(&self, rows: &mut [u8], values: impl IntoIterator<Item = &'v [u8]>) {
        let Some((at, width)) = self.extra else {
            return;
        };
        for (row, v) in rows.chunks_exact_mut(self.len).zip(values) {
            let dst = &mut row[at..at + width];
            let have = v.len().min(width);
            dst[..have].copy_from_slice(&v[..have]);
            dst[have..].fill(0);
        }
    }

    /// Zeroes the optional columns of `rows` that `present` (what was written) lacks.
    pub fn zero_absent(&self, present: &PointLayout, rows: &mut [u8]) {
        let absent = [
            (self.gps_time, present.gps_time, 8),
            (self.rgb, present.rgb, 6),
            (self.nir, present.nir, 2),
            (self.waveform, present.waveform, WAVEFORM_BYTES),
            (
                self.extra.map(|e| e.0),
                present.extra_bytes > 0,
                self.extra.map_or(0, |e| e.1),
            ),
        ];
        for (at, written, width) in absent {
            if let (Some(at), false) = (at, written) {
                for row in rows.chunks_exact_mut(self.len) {
                    row[at..at + width].fill(0);
                }
            }
        }
    }

    /// Writes points `from..from + positions.len()` of `batch` (whose layout is a subset of
    /// this one) into consecutive rows, with `positions` their stored integers. Column by
    /// column: tight loops without a branch per point. Columns the batch lacks are zero.
    pub fn pack(&self, batch: &PointBatch, from: usize, positions: &[[i32; 3]], rows: &mut [u8]) {
        let to = from + positions.len();
        self.put(rows, POSITION, positions.iter().map(position_bytes));
        self.put(
            rows,
            INTENSITY,
            batch.intensity[from..to].iter().map(|v| v.to_le_bytes()),
        );
        self.put(rows, RETURNS, batch.returns[from..to].iter().map(|v| [*v]));
        self.put(rows, FLAGS, batch.flags[from..to].iter().map(|v| [*v]));
        self.put(
            rows,
            CLASSIFICATION,
            batch.classification[from..to].iter().map(|v| [*v]),
        );
        self.put(
            rows,
            SCAN_ANGLE,
            batch.scan_angle[from..to].iter().map(|v| v.to_le_bytes()),
        );
        self.put(
            rows,
            USER_DATA,
            batch.user_data[from..to].iter().map(|v| [*v]),
        );
        self.put(
            rows,
            POINT_SOURCE_ID,
            batch.point_source_id[from..to]
                .iter()
                .map(|v| v.to_le_bytes()),
        );
        let l = &batch.layout;
        if let (Some(at), true) = (self.gps_time, l.gps_time) {
            self.put(
                rows,
                at,
                batch.gps_time[from..to].iter().map(|v| v.to_le_bytes()),
            );
        }
        if let (Some(at), true) = (self.rgb, l.rgb) {
            self.put(rows, at, batch.rgb[from..to].iter().map(rgb_bytes));
        }
        if let (Some(at), true) = (self.nir, l.nir) {
            self.put(
                rows,
                at,
                batch.nir[from..to].iter().map(|v| v.to_le_bytes()),
            );
        }
        if let (Some(at), true) = (self.waveform, l.waveform) {
            self.put(rows, at, batch.waveform[from..to].iter().copied());
        }
        let have = usize::from(l.extra_bytes);
        if have > 0 {
            let extra = &batch.extra_bytes[from * have..to * have];
            self.put_extra(rows, extra.chunks_exact(have));
        }
        self.zero_absent(l, rows);
    }
}

/// A position's row bytes.
#[inline(always)]
pub fn position_bytes(p: &[i32; 3]) -> [u8; 12] {
    let mut b = [0u8; 12];
    for (dst, v) in b.chunks_exact_mut(4).zip(p) {
        dst.copy_from_slice(&v.to_le_bytes());
    }
    b
}

/// A colour's row bytes.
#[inline(always)]
pub fn rgb_bytes(c: &[u16; 3]) -> [u8; 6] {
    let mut b = [0u8; 6];
    for (dst, v) in b.chunks_exact_mut(2).zip(c) {
        dst.copy_from_slice(&v.to_le_bytes());
    }
    b
}

/// The stored position of a row (its first 12 bytes).
#[inline(always)]
pub fn row_position(row: &[u8]) -> [i32; 3] {
    let mut p = [0i32; 3];
    for (v, b) in p.iter_mut().zip(row[..12].chunks_exact(4)) {
        *v = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layouts() -> Vec<PointLayout> {
        let mut all = Vec::new();
        for bits in 0..16u8 {
            for extra_bytes in [0u16, 3] {
                all.push(PointLayout {
                    gps_time: bits & 1 != 0,
                    rgb: bits & 2 != 0,
                    nir: bits & 4 != 0,
                    waveform: bits & 8 != 0,
                    extra_bytes,
                });
            }
        }
        all
    }

    #[test]
    fn columns_tile_the_row_without_gaps_or_overlaps() {
        for layout in layouts() {
            let row = RowLayout::new(&layout);
            let mut spans = vec![(0, FIXED)];
            let optional = [
                (row.gps_time, 8),
                (row.rgb, 6),
                (row.nir, 2),
                (row.waveform, WAVEFORM_BYTES),
                (row.extra.map(|e| e.0), row.extra.map_or(0, |e| e.1)),
            ];
            spans.extend(optional.iter().filter_map(|(at, w)| at.map(|a| (a, a + w))));
            spans.sort_unstable();
            for w in spans.windows(2) {
                assert_eq!(w[0].1, w[1].0, "{layout:?}");
            }
            assert_eq!(spans.last().map(|s| s.1), Some(row.len), "{layout:?}");
            assert_eq!(row.gps_time.is_some(), layout.gps_time);
            assert_eq!(row.extra.is_some(), layout.extra_bytes > 0);
        }
    }

    #[test]
    fn packing_writes_every_column_and_zeroes_what_the_batch_lacks() {
        let wide = PointLayout {
            gps_time: true,
            rgb: true,
            nir: true,
            waveform: true,
            extra_bytes: 3,
        };
        let row = RowLayout::new(&wide);
        let narrow = PointLayout {
            rgb: true,
            extra_bytes: 1,
            ..PointLayout::default()
        };
        let mut b = PointBatch::new(narrow);
        for i in 0..5u8 {
            b.xyz.push([0.0; 3]);
            b.intensity.push(1000 + u16::from(i));
            b.returns.push(0x21);
            b.flags.push(i);
            b.classification.push(2 + i);
            b.scan_angle.push(-1.5);
            b.user_data.push(7);
            b.point_source_id.push(300);
            b.rgb.push([1, 2, 3 + u16::from(i)]);
            b.extra_bytes.push(0xAB);
        }
        let positions: Vec<[i32; 3]> = (0..4).map(|i| [i, -i, 1 << 20]).collect();
        // Rows full of garbage: every byte must be written.
        let mut rows = vec![0xEEu8; 4 * row.len];
        row.pack(&b, 1, &positions, &mut rows);
        for (j, r) in rows.chunks_exact(row.len).enumerate() {
            let i = j + 1;
            assert_eq!(row_position(r), positions[j]);
            assert_eq!(r[INTENSITY..INTENSITY + 2], (1000 + i as u16).to_le_bytes());
            assert_eq!(r[FLAGS], i as u8);
            assert_eq!(r[SCAN_ANGLE..SCAN_ANGLE + 4], (-1.5f32).to_le_bytes());
            let gps = row.gps_time.unwrap();
            assert_eq!(r[gps..gps + 8], [0; 8]);
            let rgb = row.rgb.unwrap();
            assert_eq!(r[rgb..rgb + 6], rgb_bytes(&[1, 2, 3 + i as u16]));
            let nir = row.nir.unwrap();
            assert_eq!(r[nir..nir + 2], [0; 2]);
            let wf = row.waveform.unwrap();
            assert!(r[wf..wf + WAVEFORM_BYTES].iter().all(|&v| v == 0));
            let (at, _) = row.extra.unwrap();
            assert_eq!(r[at..at + 3], [0xAB, 0, 0]);
        }
    }
}
