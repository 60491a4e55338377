//! The point schema shared by readers, the store and the renderer: a structure-of-arrays batch.
//!
//! Every LAS 1.4 attribute (formats 0–10) has a column; optional columns are empty unless the
//! layout says they are present. Positions stay f64 until the store quantizes them.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Bytes of a LAS wave packet descriptor (formats 4, 5, 9, 10).
pub const WAVEFORM_BYTES: usize = 29;

/// Bits of [`PointBatch::flags`].
pub mod flags {
    pub const SYNTHETIC: u8 = 1 << 0;
    pub const KEY_POINT: u8 = 1 << 1;
    pub const WITHHELD: u8 = 1 << 2;
    pub const OVERLAP: u8 = 1 << 3;
    /// Scan direction: set when positive (left to right).
    pub const SCAN_DIRECTION: u8 = 1 << 4;
    pub const EDGE_OF_FLIGHT_LINE: u8 = 1 << 5;
    /// Scanner channel (0–3) lives in the two top bits.
    pub const CHANNEL_SHIFT: u8 = 6;
}

/// Which optional columns a batch (or store) carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct PointLayout {
    pub gps_time: bool,
    pub rgb: bool,
    pub nir: bool,
    pub waveform: bool,
    /// Extra bytes per point (LAS extra bytes), stored verbatim.
    pub extra_bytes: u16,
}

impl PointLayout {
    /// The smallest layout holding both.
    pub fn union(self, o: PointLayout) -> PointLayout {
        PointLayout {
            gps_time: self.gps_time || o.gps_time,
            rgb: self.rgb || o.rgb,
            nir: self.nir || o.nir,
            waveform: self.waveform || o.waveform,
            extra_bytes: self.extra_bytes.max(o.extra_bytes),
        }
    }

    /// The LAS 1.4 point format that holds every column of this layout.
    pub fn las_point_format(&self) -> u8 {
        match (self.gps_time, self.rgb, self.nir, self.waveform) {
            (_, _, _, true) if self.rgb || self.nir => 10,
            (_, _, _, true) => 9,
            (_, _, true, _) => 8,
            (_, true, _, _) => 7,
            _ => 6,
        }
    }
}

/// Integer quantization of positions: `value = raw * scale + offset`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantization {
    pub scale: [f64; 3],
    pub offset: [f64; 3],
}

#[derive(Debug, Error, PartialEq)]
pub enum QuantizationError {
    #[error("scale {0} on axis {1} is not a positive finite number")]
    BadScale(f64, usize),
    #[error("coordinate {value} on axis {axis} is not finite")]
    NotFinite { value: f64, axis: usize },
    #[error("coordinate {value} on axis {axis} does not fit 32-bit integers with scale {scale} and offset {offset}")]
    OutOfRange {
        value: f64,
        axis: usize,
        scale: f64,
        offset: f64,
    },
}

impl Quantization {
    pub fn validate(&self) -> Result<(), QuantizationError> {
        for (i, s) in self.scale.iter().enumerate() {
            if !(s.is_finite() && *s > 0.0) {
                return Err(QuantizationError::BadScale(*s, i));
            }
        }
        for (i, o) in self.offset.iter().enumerate() {
            if !o.is_finite() {
                return Err(QuantizationError::NotFinite { value: *o, axis: i });
            }
        }
        Ok(())
    }

    #[inline]
    pub fn quantize(&self, p: [f64; 3]) -> Result<[i32; 3], QuantizationError> {
        let mut out = [0i32; 3];
        for i in 0..3 {
            if !p[i].is_finite() {
                return Err(QuantizationError::NotFinite {
                    value: p[i],
                    axis: i,
                });
            }
            let v = (p[i] - self.offset[i]) / self.scale[i];
            let r = round_half_away(v);
            if !(r >= i64::from(i32::MIN) && r <= i64::from(i32::MAX)) {
                return Err(QuantizationError::OutOfRange {
                    value: p[i],
                    axis: i,
                    scale: self.scale[i],
                    offset: self.offset[i],
                });
            }
            out[i] = r as i32;
        }
        Ok(out)
    }

    #[inline]
    pub fn dequantize(&self, q: [i32; 3]) -> [f64; 3] {
        [
            q[0] as f64 * self.scale[0] + self.offset[0],
            q[1] as f64 * self.scale[1] + self.offset[1],
            q[2] as f64 * self.scale[2] + self.offset[2],
        ]
    }
}

/// A variable-length record kept verbatim from a LAS file (CRS, extra-bytes descriptions).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Vlr {
    pub user_id: String,
    pub record_id: u16,
    pub description: String,
    pub data: Vec<u8>,
    /// Stored as an extended VLR (EVLR) in the source.
    pub extended: bool,
}

impl Vlr {
    /// GeoTIFF keys / WKT records: what a CRS is made of.
    pub fn is_crs(&self) -> bool {
        self.user_id.trim_end_matches('\0') == "LASF_Projection"
    }

    /// The extra-bytes description record (LASF_Spec 4).
    pub fn is_extra_bytes(&self) -> bool {
        self.user_id.trim_end_matches('\0') == "LASF_Spec" && self.record_id == 4
    }

    /// The waveform data packets (LASF_Spec 65535), which wave packet descriptors point into.
    pub fn is_waveform_data(&self) -> bool {
        self.user_id.trim_end_matches('\0') == "LASF_Spec" && self.record_id == 65535
    }
}

/// LAS header fields that describe the points rather than the file: a store keeps them and an
/// export writes them back.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LasFields {
    /// The global-encoding bits in [`LasFields::KEPT_ENCODING`]; the others describe the file
    /// (waveform location, WKT) and a writer derives them from what it writes.
    pub global_encoding: u16,
    pub file_source_id: u16,
    /// The project GUID, verbatim.
    pub project_id: [u8; 16],
    pub system_identifier: String,
}

impl LasFields {
    /// Bit 0: GPS time is adjusted standard GPS time (else GPS week time); bit 3: return
    /// numbers were generated synthetically.
    pub const KEPT_ENCODING: u16 = 0b1001;
    pub const ADJUSTED_STANDARD_GPS_TIME: u16 = 1;
    pub const SYNTHETIC_RETURN_NUMBERS: u16 = 1 << 3;
}

/// What a reader knows about its input before the points: from the header, so it may lie;
/// readers validate what they can and the store checks the rest while reading.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SourceMeta {
    /// Human-readable format, e.g. `LAS 1.2 point format 3 (LAZ)`.
    pub format: String,
    /// Points the header claims.
    pub point_count: u64,
    /// Bounds the header claims (empty when the format has none).
    pub bounds: crate::Aabb,
    /// The source's quantization: LAS/LAZ's own; for PLY and text, chosen from the data's
    /// precision and extent.
    pub quantization: Option<Quantization>,
    pub layout: PointLayout,
    /// LAS point format of the source, when it is LAS/LAZ.
    pub las_point_format: Option<u8>,
    /// The records carried into stores and exports: every VLR and EVLR but those a writer
    /// makes itself (LASzip, COPC).
    pub vlrs: Vec<Vlr>,
    /// Header fields of a LAS/LAZ source.
    #[serde(default)]
    pub las: Option<LasFields>,
}

/// A batch of points as parallel columns.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointBatch {
    pub layout: PointLayout,
    pub xyz: Vec<[f64; 3]>,
    pub intensity: Vec<u16>,
    /// Return number in the low nibble, number of returns in the high nibble.
    pub returns: Vec<u8>,
    /// See [`flags`].
    pub flags: Vec<u8>,
    /// ASPRS classification (0–255).
    pub classification: Vec<u8>,
    /// Degrees.
    pub scan_angle: Vec<f32>,
    pub user_data: Vec<u8>,
    pub point_source_id: Vec<u16>,
    pub gps_time: Vec<f64>,
    pub rgb: Vec<[u16; 3]>,
    pub nir: Vec<u16>,
    pub waveform: Vec<[u8; WAVEFORM_BYTES]>,
    /// `layout.extra_bytes` bytes per point, concatenated.
    pub extra_bytes: Vec<u8>,
}

#[derive(Debug, Error, PartialEq)]
#[error("point batch column '{column}' has {got} entries, expected {expected}")]
pub struct BatchShapeError {
    pub column: &'static str,
    pub got: usize,
    pub expected: usize,
}

impl PointBatch {
    pub fn new(layout: PointLayout) -> Self {
        Self {
            layout,
            ..Default::default()
        }
    }

    pub fn with_capacity(layout: PointLayout, n: usize) -> Self {
        let opt = |on: bool| if on { n } else { 0 };
        Self {
            layout,
            xyz: Vec::with_capacity(n),
            intensity: Vec::with_capacity(n),
            returns: Vec::with_capacity(n),
            flags: Vec::with_capacity(n),
            classification: Vec::with_capacity(n),
            scan_angle: Vec::with_capacity(n),
            user_data: Vec::with_capacity(n),
            point_source_id: Vec::with_capacity(n),
            gps_time: Vec::with_capacity(opt(layout.gps_time)),
            rgb: Vec::with_capacity(opt(layout.rgb)),
            nir: Vec::with_capacity(opt(layout.nir)),
            waveform: Vec::with_capacity(opt(layout.waveform)),
            extra_bytes: Vec::with_capacity(n * layout.extra_bytes as usize),
        }
    }

    pub fn len(&self) -> usize {
        self.xyz.len()
    }

    /// Empties every column, keeps their memory, and sets the layout.
    pub fn clear(&mut self, layout: PointLayout) {
        self.layout = layout;
        self.xyz.clear();
        self.intensity.clear();
        self.returns.clear();
        self.flags.clear();
        self.classification.clear();
        self.scan_angle.clear();
        self.user_data.clear();
        self.point_source_id.clear();
        self.gps_time.clear();
        self.rgb.clear();
        self.nir.clear();
        self.waveform.clear();
        self.extra_bytes.clear();
    }

    pub fn is_empty(&self) -> bool {
        self.xyz.is_empty()
    }

    /// Checks that every column has the length the layout implies.
    pub fn check_shape(&self) -> Result<(), BatchShapeError> {
        let n = self.len();
        let opt = |on: bool| if on { n } else { 0 };
        let cols: [(&'static str, usize, usize); 12] = [
            ("intensity", self.intensity.len(), n),
            ("returns", self.returns.len(), n),
            ("flags", self.flags.len(), n),
            ("classification", self.classification.len(), n),
            ("scan_angle", self.scan_angle.len(), n),
            ("user_data", self.user_data.len(), n),
            ("point_source_id", self.point_source_id.len(), n),
            ("gps_time", self.gps_time.len(), opt(self.layout.gps_time)),
            ("rgb", self.rgb.len(), opt(self.layout.rgb)),
            ("nir", self.nir.len(), opt(self.layout.nir)),
            ("waveform", self.waveform.len(), opt(self.layout.waveform)),
            (
                "extra_bytes",
                self.extra_bytes.len(),
                n * self.layout.extra_bytes as usize,
            ),
        ];
        for (column, got, expected) in cols {
            if got != expected {
                return Err(BatchShapeError {
                    column,
                    got,
                    expected,
                });
            }
        }
        Ok(())
    }

    /// Widens the batch to `layout` (a superset), filling new columns with zeros.
    pub fn widen(&mut self, layout: PointLayout) {
        let n = self.len();
        if layout.gps_time && !self.layout.gps_time {
            self.gps_time = vec![0.0; n];
        }
        if layout.rgb && !self.layout.rgb {
            self.rgb = vec![[0; 3]; n];
        }
        if layout.nir && !self.layout.nir {
            self.nir = vec![0; n];
        }
        if layout.waveform && !self.layout.waveform {
            self.waveform = vec![[0; WAVEFORM_BYTES]; n];
        }
        if layout.extra_bytes > self.layout.extra_bytes {
            let (old, new) = (
                self.layout.extra_bytes as usize,
                layout.extra_bytes as usize,
            );
            let mut eb = vec![0u8; n * new];
            for i in 0..n {
                eb[i * new..i * new + old]
                    .copy_from_slice(&self.extra_bytes[i * old..(i + 1) * old]);
            }
            self.extra_bytes = eb;
        }
        self.layout = layout;
    }

    /// Appends point `i` of `other` (same layout).
    pub fn push_from(&mut self, other: &PointBatch, i: usize) {
        self.xyz.push(other.xyz[i]);
        self.intensity.push(other.intensity[i]);
        self.returns.push(other.returns[i]);
        self.flags.push(other.flags[i]);
        self.classification.push(other.classification[i]);
        self.scan_angle.push(other.scan_angle[i]);
        self.user_data.push(other.user_data[i]);
        self.point_source_id.push(other.point_source_id[i]);
        if self.layout.gps_time {
            self.gps_time.push(other.gps_time[i]);
        }
        if self.layout.rgb {
            self.rgb.push(other.rgb[i]);
        }
        if self.layout.nir {
            self.nir.push(other.nir[i]);
        }
        if self.layout.waveform {
            self.waveform.push(other.waveform[i]);
        }
        let e = self.layout.extra_bytes as usize;
        if e > 0 {
            self.extra_bytes
                .extend_from_slice(&other.extra_bytes[i * e..(i + 1) * e]);
        }
    }
}

/// `v.round()` as an integer (halves away from zero), saturating far outside the i64 range:
/// the same result without the libm call that `round` is on baseline x86-64 (no SSE4.1),
/// which was a measurable share of converting a LAS file.
#[inline]
fn round_half_away(v: f64) -> i64 {
    // Truncation saturates (NaN gives 0, refused by the caller's finiteness check first).
    let t = v as i64;
    if v.abs() >= 4_503_599_627_370_496.0 {
        return t; // 2^52 and beyond: every f64 is an integer already
    }
    // Below 2^52 the fraction v - t is exact. No branches on it: values read back from integers
    // fall just below or just above one at random, and mispredicted branches were a large share
    // of keying points (measured).
    let f = v - t as f64;
    t + i64::from(f >= 0.5) - i64::from(f <= -0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_matches_f64_round() {
        let mut rng = crate::shuffle::SplitMix64::new(11);
        let mut cases = vec![
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.0,
            1e15 + 0.5,
        ];
        cases.extend(
            (0..100_000).map(|_| (rng.next_u64() as i64 as f64) / 2f64.powi(rng.below(60) as i32)),
        );
        cases.extend((0..10_000).map(|i| i as f64 * 0.5 - 2500.0));
        for v in cases {
            assert_eq!(super::round_half_away(v), v.round() as i64, "{v}");
        }
    }

    #[test]
    fn quantize_round_trip_and_errors() {
        let q = Quantization {
            scale: [0.01; 3],
            offset: [635_000.0, 848_000.0, 0.0],
        };
        let p = [635_600.12, 848_900.57, 406.59];
        let r = q.quantize(p).unwrap();
        assert_eq!(q.quantize(q.dequantize(r)).unwrap(), r);
        assert!(matches!(
            q.quantize([f64::NAN, 0.0, 0.0]),
            Err(QuantizationError::NotFinite { .. })
        ));
        assert!(matches!(
            q.quantize([1e12, 0.0, 0.0]),
            Err(QuantizationError::OutOfRange { .. })
        ));
        let bad = Quantization {
            scale: [0.0, 1.0, 1.0],
            offset: [0.0; 3],
        };
        assert_eq!(bad.validate(), Err(QuantizationError::BadScale(0.0, 0)));
    }

    #[test]
    fn widen_and_shape() {
        let mut b = PointBatch::new(PointLayout::default());
        b.xyz.push([0.0; 3]);
        b.intensity.push(1);
        b.returns.push(0x11);
        b.flags.push(0);
        b.classification.push(2);
        b.scan_angle.push(0.0);
        b.user_data.push(0);
        b.point_source_id.push(0);
        b.check_shape().unwrap();
        b.widen(PointLayout {
            rgb: true,
            extra_bytes: 2,
            ..Default::default()
        });
        b.check_shape().unwrap();
        assert_eq!(b.extra_bytes, vec![0, 0]);
        b.intensity.clear();
        assert!(b.check_shape().is_err());
    }

    #[test]
    fn las_format_for_layout() {
        let l = PointLayout {
            gps_time: true,
            rgb: true,
            ..Default::default()
        };
        assert_eq!(l.las_point_format(), 7);
        assert_eq!(PointLayout::default().las_point_format(), 6);
    }
}
