//! LAS point records (formats 0–10) to and from [`PointBatch`] columns.
//!
//! Legacy formats 0–5 code overlap as classification 12 (there is no overlap bit). Reading maps
//! that code to classification 1 (unclassified) plus [`flags::OVERLAP`], as the `las` crate
//! does; writing a legacy format turns the overlap flag back into code 12. A legacy record thus
//! comes back byte for byte, and an extended format written from it keeps the same meaning.

use pointlet_core::rows::{self, RowLayout};
use pointlet_core::{flags, PointBatch, PointLayout, Quantization, WAVEFORM_BYTES};

/// Offsets of the fields of one point data record format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointFormat {
    pub id: u8,
    /// Bytes the format defines (extra bytes come after).
    pub size: usize,
    /// Formats 6–10: 4-bit returns, 8-bit classification, scaled 16-bit scan angle.
    pub extended: bool,
    pub gps_time: Option<usize>,
    pub rgb: Option<usize>,
    pub nir: Option<usize>,
    pub waveform: Option<usize>,
}

/// The classification code legacy formats use for overlap points.
const LEGACY_OVERLAP: u8 = 12;
/// Degrees per step of the extended scan angle.
const SCAN_ANGLE_STEP: f32 = 0.006;
/// Records decoded per column pass: small enough for the raw bytes to stay in L2.
const BLOCK: usize = 2048;

impl PointFormat {
    pub fn new(id: u8) -> Option<PointFormat> {
        let f = |size, extended, gps_time, rgb, nir, waveform| PointFormat {
            id,
            size,
            extended,
            gps_time,
            rgb,
            nir,
            waveform,
        };
        Some(match id {
            0 => f(20, false, None, None, None, None),
            1 => f(28, false, Some(20), None, None, None),
            2 => f(26, false, None, Some(20), None, None),
            3 => f(34, false, Some(20), Some(28), None, None),
            4 => f(57, false, Some(20), None, None, Some(28)),
            5 => f(63, false, Some(20), Some(28), None, Some(34)),
            6 => f(30, true, Some(22), None, None, None),
            7 => f(36, true, Some(22), Some(30), None, None),
            8 => f(38, true, Some(22), Some(30), Some(36), None),
            9 => f(59, true, Some(22), None, None, Some(30)),
            10 => f(67, true, Some(22), Some(30), Some(36), Some(38)),
            _ => return None,
        })
    }

    /// The batch layout of records of this format with `extra_bytes` after the defined fields.
    pub fn layout(&self, extra_bytes: u16) -> PointLayout {
        PointLayout {
            gps_time: self.gps_time.is_some(),
            rgb: self.rgb.is_some(),
            nir: self.nir.is_some(),
            waveform: self.waveform.is_some(),
            extra_bytes,
        }
    }
}

/// `N` bytes at `at`; zeros if the record is shorter (record lengths are validated, so never).
#[inline(always)]
fn arr<const N: usize>(r: &[u8], at: usize) -> [u8; N] {
    r.get(at..at + N)
        .and_then(|s| s.try_into().ok())
        .unwrap_or([0; N])
}

#[inline(always)]
fn byte(r: &[u8], at: usize) -> u8 {
    r.get(at).copied().unwrap_or(0)
}

#[inline(always)]
fn u16_at(r: &[u8], at: usize) -> u16 {
    u16::from_le_bytes(arr(r, at))
}

/// A record's position as stored: x, y, z integers.
#[inline(always)]
fn stored_position(r: &[u8]) -> [i32; 3] {
    [
        i32::from_le_bytes(arr(r, 0)),
        i32::from_le_bytes(arr(r, 4)),
        i32::from_le_bytes(arr(r, 8)),
    ]
}

/// Decodes raw records of one format into batch columns.
#[derive(Clone, Debug)]
pub(crate) struct Decoder {
    format: PointFormat,
    record_len: usize,
    extra: usize,
    q: Quantization,
}

impl Decoder {
    /// `record_len` is at least `format.size` (the header parser checks it).
    pub fn new(format: PointFormat, record_len: usize, q: Quantization) -> Self {
        Decoder {
            format,
            record_len,
            extra: record_len.saturating_sub(format.size),
            q,
        }
    }

    pub fn layout(&self) -> PointLayout {
        self.format.layout(self.extra as u16)
    }

    pub fn record_len(&self) -> usize {
        self.record_len
    }

    /// Appends every whole record of `raw` to `out` (whose layout is [`Self::layout`]).
    pub fn decode(&self, raw: &[u8], out: &mut PointBatch) {
        let n = raw.len() / self.record_len;
        out.xyz.reserve(n);
        for block in raw.chunks(BLOCK * self.record_len) {
            self.decode_block(block, out);
        }
    }

    /// Decodes the records of `raw` straight into `rows` (one row of `row` per record; `row`
    /// has every column of [`Self::layout`]): positions as the records store them, integers
    /// of the decoder's quantization, the other columns as [`Self::decode`] gives them, zero
    /// where the records lack a column of `row`.
    pub fn decode_rows(&self, raw: &[u8], row: &RowLayout, rows: &mut [u8]) -> Result<(), String> {
        self.check_rows(raw, row, rows)?;
        let recs = raw.chunks_exact(self.record_len);
        if self.format.extended {
            for (r, o) in recs.zip(rows.chunks_exact_mut(row.len)) {
                self.record_to_row::<true>(r, row, o);
            }
        } else {
            for (r, o) in recs.zip(rows.chunks_exact_mut(row.len)) {
                self.record_to_row::<false>(r, row, o);
            }
        }
        row.zero_absent(&self.layout(), rows);
        Ok(())
    }

    /// Fails unless `rows` holds one row of `row` for each whole record of `raw`.
    fn check_rows(&self, raw: &[u8], row: &RowLayout, rows: &[u8]) -> Result<(), String> {
        let n = raw.len() / self.record_len;
        if n * row.len != rows.len() {
            return Err(format!(
                "{n} records for {} rows of {} bytes",
                rows.len() / row.len.max(1),
                row.len
            ));
        }
        Ok(())
    }

    /// [`Self::decode_rows`] a block of records at a time, handing each block's rows to
    /// `done` (the index of its first row, its bytes) while they are still in the cache.
    pub fn decode_rows_by_block(
        &self,
        raw: &[u8],
        row: &RowLayout,
        rows: &mut [u8],
        done: &mut dyn FnMut(usize, &[u8]),
    ) -> Result<(), String> {
        self.check_rows(raw, row, rows)?;
        let blocks = raw
            .chunks(BLOCK * self.record_len)
            .zip(rows.chunks_mut(BLOCK * row.len.max(1)));
        for (b, (r, o)) in blocks.enumerate() {
            self.decode_rows(r, row, o)?;
            done(b * BLOCK, o);
        }
        Ok(())
    }

    /// One record into one row, field by field (`E`: an extended format).
    #[inline(always)]
    fn record_to_row<const E: bool>(&self, r: &[u8], row: &RowLayout, o: &mut [u8]) {
        // Position and intensity are the same bytes in records and rows.
        o[..14].copy_from_slice(&r[..14]);
        let x = Fixed::of::<E>(r);
        o[rows::RETURNS] = x.returns;
        o[rows::FLAGS] = x.flags;
        o[rows::CLASSIFICATION] = x.classification;
        o[rows::SCAN_ANGLE..rows::SCAN_ANGLE + 4].copy_from_slice(&x.scan_angle.to_le_bytes());
        o[rows::USER_DATA] = x.user_data;
        o[rows::POINT_SOURCE_ID..rows::POINT_SOURCE_ID + 2]
            .copy_from_slice(&x.point_source_id.to_le_bytes());
        let f = &self.format;
        if let (Some(from), Some(to)) = (f.gps_time, row.gps_time) {
            o[to..to + 8].copy_from_slice(&r[from..from + 8]);
        }
        if let (Some(from), Some(to)) = (f.rgb, row.rgb) {
            o[to..to + 6].copy_from_slice(&r[from..from + 6]);
        }
        if let (Some(from), Some(to)) = (f.nir, row.nir) {
            o[to..to + 2].copy_from_slice(&r[from..from + 2]);
        }
        if let (Some(from), Some(to)) = (f.waveform, row.waveform) {
            o[to..to + WAVEFORM_BYTES].copy_from_slice(&r[from..from + WAVEFORM_BYTES]);
        }
        if let Some((to, width)) = row.extra {
            let have = self.extra.min(width);
            o[to..to + have].copy_from_slice(&r[f.size..f.size + have]);
            o[to + have..to + width].fill(0);
        }
    }

    /// Whether [`Self::decode_rows`] can fill rows of `row` for a store quantized as `q`: the
    /// records store positions of `q`, and `row` has every column they have.
    pub fn fits_rows(&self, q: &Quantization, row: &RowLayout) -> bool {
        self.q == *q && self.layout().union(row.layout) == row.layout
    }

    fn decode_block(&self, block: &[u8], out: &mut PointBatch) {
        let recs = block.chunks_exact(self.record_len);
        let (s, o) = (self.q.scale, self.q.offset);
        out.xyz.extend(recs.map(|r| {
            let [x, y, z] = stored_position(r);
            // Same expression as the `las` crate, so both give identical f64 values.
            [
                s[0] * f64::from(x) + o[0],
                s[1] * f64::from(y) + o[1],
                s[2] * f64::from(z) + o[2],
            ]
        }));
        self.decode_attributes(block, out);
    }

    /// Every column but the positions, into `out`.
    fn decode_attributes(&self, block: &[u8], out: &mut PointBatch) {
        if self.format.extended {
            self.decode_fixed::<true>(block, out);
        } else {
            self.decode_fixed::<false>(block, out);
        }
        let recs = || block.chunks_exact(self.record_len);
        if let Some(at) = self.format.gps_time {
            out.gps_time
                .extend(recs().map(|r| f64::from_le_bytes(arr(r, at))));
        }
        if let Some(at) = self.format.rgb {
            out.rgb
                .extend(recs().map(|r| [u16_at(r, at), u16_at(r, at + 2), u16_at(r, at + 4)]));
        }
        if let Some(at) = self.format.nir {
            out.nir.extend(recs().map(|r| u16_at(r, at)));
        }
        if let Some(at) = self.format.waveform {
            out.waveform
                .extend(recs().map(|r| arr::<WAVEFORM_BYTES>(r, at)));
        }
        if self.extra > 0 {
            let (from, to) = (self.format.size, self.format.size + self.extra);
            for r in recs() {
                out.extra_bytes
                    .extend_from_slice(r.get(from..to).unwrap_or_default());
            }
        }
    }

    /// Intensity and the fixed fields after it, column by column: tight loops, each keeping
    /// one field of [`Fixed`] (the rest is not computed).
    fn decode_fixed<const E: bool>(&self, block: &[u8], out: &mut PointBatch) {
        let recs = || block.chunks_exact(self.record_len);
        out.intensity.extend(recs().map(|r| u16_at(r, 12)));
        out.returns
            .extend(recs().map(|r| Fixed::of::<E>(r).returns));
        out.flags.extend(recs().map(|r| Fixed::of::<E>(r).flags));
        out.classification
            .extend(recs().map(|r| Fixed::of::<E>(r).classification));
        out.scan_angle
            .extend(recs().map(|r| Fixed::of::<E>(r).scan_angle));
        out.user_data
            .extend(recs().map(|r| Fixed::of::<E>(r).user_data));
        out.point_source_id
            .extend(recs().map(|r| Fixed::of::<E>(r).point_source_id));
    }
}

/// A record's fields between intensity and the optional ones, as batches and rows hold them.
struct Fixed {
    returns: u8,
    flags: u8,
    classification: u8,
    /// Degrees.
    scan_angle: f32,
    user_data: u8,
    point_source_id: u16,
}

impl Fixed {
    /// The fields of record `r` of a legacy (`E` false) or extended format.
    #[inline(always)]
    fn of<const E: bool>(r: &[u8]) -> Fixed {
        let (b, c) = (byte(r, 14), byte(r, 15));
        if E {
            Fixed {
                returns: b,
                flags: (c & 0x0F)
                    | ((c >> 6) & 1) << 4
                    | ((c >> 7) & 1) << 5
                    | ((c >> 4) & 3) << flags::CHANNEL_SHIFT,
                classification: byte(r, 16),
                scan_angle: f32::from(i16::from_le_bytes(arr(r, 18))) * SCAN_ANGLE_STEP,
                user_data: byte(r, 17),
                point_source_id: u16_at(r, 20),
            }
        } else {
            let overlap = u8::from(c & 0x1F == LEGACY_OVERLAP);
            Fixed {
                returns: (b & 7) | ((b >> 3) & 7) << 4,
                flags: ((c >> 5) & 7) | overlap << 3 | ((b >> 6) & 1) << 4 | ((b >> 7) & 1) << 5,
                classification: match c & 0x1F {
                    LEGACY_OVERLAP => 1,
                    c => c,
                },
                scan_angle: f32::from(byte(r, 16) as i8),
                user_data: byte(r, 17),
                point_source_id: u16_at(r, 18),
            }
        }
    }
}

/// Integer bounds and return counts of what an [`Encoder`] wrote.
#[derive(Clone, Debug)]
pub(crate) struct EncodeStats {
    pub points: u64,
    pub min: [i32; 3],
    pub max: [i32; 3],
    /// Points with return number 1–15.
    pub by_return: [u64; 15],
}

impl Default for EncodeStats {
    fn default() -> Self {
        EncodeStats {
            points: 0,
            min: [i32::MAX; 3],
            max: [i32::MIN; 3],
            by_return: [0; 15],
        }
    }
}

/// Encodes batch columns as raw records of one format.
#[derive(Clone, Debug)]
pub(crate) struct Encoder {
    format: PointFormat,
    record_len: usize,
    extra: usize,
    q: Quantization,
    /// Wave packet descriptors are copied; otherwise written as zeros ("no packet").
    waveform: bool,
}

#[inline(always)]
fn put(rec: &mut [u8], at: usize, bytes: &[u8]) {
    if let Some(dst) = rec.get_mut(at..at + bytes.len()) {
        dst.copy_from_slice(bytes);
    }
}

impl Encoder {
    pub fn new(format: PointFormat, extra: u16, q: Quantization) -> Self {
        Encoder {
            format,
            record_len: format.size + usize::from(extra),
            extra: usize::from(extra),
            q,
            waveform: true,
        }
    }

    /// An encoder that writes every wave packet descriptor as "no packet", for files that
    /// do not carry the waveform data the descriptors point into.
    pub fn without_waveforms(self) -> Self {
        Encoder {
            waveform: false,
            ..self
        }
    }

    pub fn record_len(&self) -> usize {
        self.record_len
    }

    /// Appends the records of every point of `b` to `out`. `b` has a valid shape; columns the
    /// format has but the batch lacks are written as zeros. An error names the batch index of
    /// the point that does not fit the format.
    pub fn encode(
        &self,
        b: &PointBatch,
        out: &mut Vec<u8>,
        stats: &mut EncodeStats,
    ) -> Result<(), (usize, String)> {
        let n = b.len();
        let start = out.len();
        out.resize(start + n * self.record_len, 0);
        let eb_in = usize::from(b.layout.extra_bytes);
        let f = self.format;
        for (i, rec) in out[start..].chunks_exact_mut(self.record_len).enumerate() {
            let p = b.xyz.get(i).copied().unwrap_or_default();
            let q = self
                .q
                .quantize(p)
                .map_err(|e| (i, format!("position {p:?}: {e}")))?;
            for ((lo, hi), v) in stats.min.iter_mut().zip(stats.max.iter_mut()).zip(q) {
                *lo = (*lo).min(v);
                *hi = (*hi).max(v);
            }
            put(rec, 0, &q[0].to_le_bytes());
            put(rec, 4, &q[1].to_le_bytes());
            put(rec, 8, &q[2].to_le_bytes());
            put(
                rec,
                12,
                &b.intensity.get(i).copied().unwrap_or(0).to_le_bytes(),
            );
            let returns = b.returns.get(i).copied().unwrap_or(0);
            let fl = b.flags.get(i).copied().unwrap_or(0);
            let class = b.classification.get(i).copied().unwrap_or(0);
            let angle = b.scan_angle.get(i).copied().unwrap_or(0.0);
            let (rn, nr) = (returns & 0x0F, returns >> 4);
            if rn > 0 {
                stats.by_return[usize::from(rn) - 1] += 1;
            }
            if f.extended {
                let b15 = (fl & 0x0F)
                    | ((fl >> flags::CHANNEL_SHIFT) & 3) << 4
                    | ((fl >> 4) & 1) << 6
                    | ((fl >> 5) & 1) << 7;
                let steps = (f64::from(angle) / f64::from(SCAN_ANGLE_STEP)).round();
                if !(steps >= f64::from(i16::MIN) && steps <= f64::from(i16::MAX)) {
                    return Err((
                        i,
                        format!("scan angle {angle}° does not fit point format {}", f.id),
                    ));
                }
                put(
                    rec,
                    14,
                    &[
                        returns,
                        b15,
                        class,
                        b.user_data.get(i).copied().unwrap_or(0),
                    ],
                );
                put(rec, 18, &(steps as i16).to_le_bytes());
                put(
                    rec,
                    20,
                    &b.point_source_id.get(i).copied().unwrap_or(0).to_le_bytes(),
                );
            } else {
                if rn > 7 || nr > 7 {
                    return Err((
                        i,
                        format!(
                            "return {rn} of {nr} does not fit the 3-bit fields of point format {}",
                            f.id
                        ),
                    ));
                }
                if fl >> flags::CHANNEL_SHIFT != 0 {
                    return Err((i, format!(
                        "scanner channel {} does not fit point format {} (formats 6–10 have channels)",
                        fl >> flags::CHANNEL_SHIFT,
                        f.id
                    )));
                }
                let class5 = if fl & flags::OVERLAP != 0 {
                    LEGACY_OVERLAP
                } else if class > 31 {
                    return Err((
                        i,
                        format!(
                            "classification {class} does not fit the 5 bits of point format {}",
                            f.id
                        ),
                    ));
                } else {
                    class
                };
                let rank = angle.round();
                if !(-128.0..=127.0).contains(&rank) {
                    return Err((
                        i,
                        format!("scan angle {angle}° does not fit point format {}", f.id),
                    ));
                }
                let b14 = rn | nr << 3 | ((fl >> 4) & 1) << 6 | ((fl >> 5) & 1) << 7;
                let b15 = class5 | (fl & 7) << 5;
                put(
                    rec,
                    14,
                    &[
                        b14,
                        b15,
                        rank as i8 as u8,
                        b.user_data.get(i).copied().unwrap_or(0),
                    ],
                );
                put(
                    rec,
                    18,
                    &b.point_source_id.get(i).copied().unwrap_or(0).to_le_bytes(),
                );
            }
            if let (Some(at), true) = (f.gps_time, b.layout.gps_time) {
                put(
                    rec,
                    at,
                    &b.gps_time.get(i).copied().unwrap_or(0.0).to_le_bytes(),
                );
            }
            if let (Some(at), true) = (f.rgb, b.layout.rgb) {
                let c = b.rgb.get(i).copied().unwrap_or_default();
                put(rec, at, &c[0].to_le_bytes());
                put(rec, at + 2, &c[1].to_le_bytes());
                put(rec, at + 4, &c[2].to_le_bytes());
            }
            if let (Some(at), true) = (f.nir, b.layout.nir) {
                put(rec, at, &b.nir.get(i).copied().unwrap_or(0).to_le_bytes());
            }
            if let (Some(at), true) = (f.waveform, b.layout.waveform && self.waveform) {
                if let Some(w) = b.waveform.get(i) {
                    put(rec, at, w);
                }
            }
            let keep = eb_in.min(self.extra);
            if keep > 0 {
                if let Some(src) = b.extra_bytes.get(i * eb_in..i * eb_in + keep) {
                    put(rec, f.size, src);
                }
            }
        }
        stats.points += n as u64;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q() -> Quantization {
        Quantization {
            scale: [0.01; 3],
            offset: [0.0; 3],
        }
    }

    /// Every bit pattern of the flag/return/classification bytes survives decode → encode.
    #[test]
    fn records_round_trip_bit_exactly() {
        for id in 0..=10u8 {
            let f = PointFormat::new(id).expect("format");
            let extra = 3u16;
            let len = f.size + usize::from(extra);
            let mut raw = Vec::new();
            for v in 0..=255u8 {
                let mut r: Vec<u8> = (0..len).map(|k| (k as u8).wrapping_mul(31) ^ v).collect();
                r[14] = v;
                r[15] = v.rotate_left(3);
                r[16] = if f.extended { v } else { (v % 90) as i8 as u8 };
                if f.extended {
                    // Scan angle steps within ±180°.
                    r[18..20].copy_from_slice(&(i16::from(v) * 100 - 12_000).to_le_bytes());
                } else {
                    // Return numbers 0–7; channel bits do not exist in legacy records.
                    r[14] = v;
                }
                raw.extend_from_slice(&r);
            }
            let dec = Decoder::new(f, len, q());
            let mut batch = PointBatch::new(dec.layout());
            dec.decode(&raw, &mut batch);
            batch.check_shape().expect("shape");
            assert_eq!(batch.len(), 256);
            let enc = Encoder::new(f, extra, q());
            let mut back = Vec::new();
            enc.encode(&batch, &mut back, &mut EncodeStats::default())
                .expect("encode");
            for (i, (a, b)) in raw.chunks(len).zip(back.chunks(len)).enumerate() {
                assert_eq!(a, b, "format {id}, record {i}");
            }
        }
    }

    #[test]
    fn legacy_overlap_becomes_a_flag_and_comes_back() {
        let f = PointFormat::new(1).expect("format");
        let mut r = vec![0u8; f.size];
        r[15] = LEGACY_OVERLAP | 0x20;
        let dec = Decoder::new(f, f.size, q());
        let mut b = PointBatch::new(dec.layout());
        dec.decode(&r, &mut b);
        assert_eq!(b.classification, vec![1]);
        assert_eq!(b.flags, vec![flags::OVERLAP | flags::SYNTHETIC]);
        let mut back = Vec::new();
        Encoder::new(f, 0, q())
            .encode(&b, &mut back, &mut EncodeStats::default())
            .expect("encode");
        assert_eq!(back, r);
    }

    #[test]
    fn values_a_legacy_format_cannot_hold_are_errors() {
        let f = PointFormat::new(0).expect("format");
        let mut b = PointBatch::new(f.layout(0));
        b.xyz.push([0.0; 3]);
        b.intensity.push(0);
        b.returns.push(0x11);
        b.flags.push(0);
        b.classification.push(40);
        b.scan_angle.push(0.0);
        b.user_data.push(0);
        b.point_source_id.push(0);
        let enc = Encoder::new(f, 0, q());
        let err = enc
            .encode(&b, &mut Vec::new(), &mut EncodeStats::default())
            .expect_err("class 40");
        assert!(err.1.contains("classification 40"), "{}", err.1);
        b.classification[0] = 2;
        b.returns[0] = 0x9A;
        assert!(enc
            .encode(&b, &mut Vec::new(), &mut EncodeStats::default())
            .is_err());
    }
}
