//! The byte layout of a `.pointlet` file (specified in `docs/FORMAT.md`).
//!
//! ```text
//! preamble (128 B) | JSON header | pad to 8 | pointlet table | checksum table | pad to 4 KiB |
//! stream 0 | pad to 4 KiB | stream 1 | ... | last stream (the file ends with it)
//! ```
//! Every offset follows from the header length, the layout and the counts ([`plan`]), so the
//! reader can demand that the file is laid out exactly as the builder would have laid it out.

use pointlet_core::{Aabb, LasFields, PointLayout, Quantization, Vlr, WAVEFORM_BYTES};
use serde::{Deserialize, Serialize};

/// First eight bytes: a non-ASCII byte, a name, and CR LF / EOF / LF to catch text-mode mangling.
pub const MAGIC: [u8; 8] = *b"\x89PLT\r\n\x1a\n";
/// The format version this build writes.
pub const VERSION: u32 = 2;
/// The oldest version this build reads: version 1 lacks the LAS header fields (`las`) and its
/// key grid came from the input headers' bounds; the layout is the same.
pub const OLDEST_READ_VERSION: u32 = 1;
/// Bytes of the fixed preamble; the JSON header starts right after it.
pub const PREAMBLE_LEN: u64 = 128;
/// Bytes of one pointlet table entry.
pub const TABLE_ENTRY_LEN: u64 = 64;
/// Alignment of every stream (and so of any pointlet range's first byte, up to the point size).
pub const STREAM_ALIGN: u64 = 4096;
/// Largest JSON header a reader accepts (it holds VLRs and source names, not points).
pub const MAX_HEADER_LEN: u64 = 64 << 20;

/// One attribute column of the store, in the order streams appear in a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StreamKind {
    /// Quantized position: `[i32; 3]` (x, y, z); value = raw × scale + offset.
    Position,
    Intensity,
    /// Return number in the low nibble, number of returns in the high nibble.
    Returns,
    /// See `pointlet_core::flags`.
    Flags,
    Classification,
    /// Degrees, `f32`.
    ScanAngle,
    UserData,
    PointSourceId,
    GpsTime,
    /// `[u16; 3]`: red, green, blue.
    Rgb,
    Nir,
    /// The 29-byte LAS wave packet descriptor, verbatim.
    Waveform,
    /// `layout.extra_bytes` bytes per point, verbatim.
    ExtraBytes,
}

impl StreamKind {
    /// The stream colouring by `mode` reads besides positions (none for elevation).
    pub fn for_color(mode: pointlet_core::color::ColorMode) -> Option<StreamKind> {
        use pointlet_core::color::ColorMode;
        match mode {
            ColorMode::Rgb => Some(StreamKind::Rgb),
            ColorMode::Intensity => Some(StreamKind::Intensity),
            ColorMode::Elevation => None,
            ColorMode::Classification => Some(StreamKind::Classification),
            ColorMode::ReturnNumber => Some(StreamKind::Returns),
            ColorMode::PointSourceId => Some(StreamKind::PointSourceId),
            ColorMode::GpsTime => Some(StreamKind::GpsTime),
            ColorMode::ScanAngle => Some(StreamKind::ScanAngle),
            ColorMode::UserData => Some(StreamKind::UserData),
            ColorMode::Nir => Some(StreamKind::Nir),
            ColorMode::Extra(_) => Some(StreamKind::ExtraBytes),
        }
    }

    pub const ALL: [StreamKind; 13] = [
        StreamKind::Position,
        StreamKind::Intensity,
        StreamKind::Returns,
        StreamKind::Flags,
        StreamKind::Classification,
        StreamKind::ScanAngle,
        StreamKind::UserData,
        StreamKind::PointSourceId,
        StreamKind::GpsTime,
        StreamKind::Rgb,
        StreamKind::Nir,
        StreamKind::Waveform,
        StreamKind::ExtraBytes,
    ];

    /// The stream's name in the JSON header.
    pub fn name(self) -> &'static str {
        match self {
            StreamKind::Position => "position",
            StreamKind::Intensity => "intensity",
            StreamKind::Returns => "returns",
            StreamKind::Flags => "flags",
            StreamKind::Classification => "classification",
            StreamKind::ScanAngle => "scan_angle",
            StreamKind::UserData => "user_data",
            StreamKind::PointSourceId => "point_source_id",
            StreamKind::GpsTime => "gps_time",
            StreamKind::Rgb => "rgb",
            StreamKind::Nir => "nir",
            StreamKind::Waveform => "waveform",
            StreamKind::ExtraBytes => "extra_bytes",
        }
    }

    /// Bytes per point in a store of `layout`; `None` when the layout has no such column.
    pub fn bytes_per_point(self, layout: &PointLayout) -> Option<usize> {
        let opt = |on: bool, n: usize| on.then_some(n);
        match self {
            StreamKind::Position => Some(12),
            StreamKind::Intensity => Some(2),
            StreamKind::Returns => Some(1),
            StreamKind::Flags => Some(1),
            StreamKind::Classification => Some(1),
            StreamKind::ScanAngle => Some(4),
            StreamKind::UserData => Some(1),
            StreamKind::PointSourceId => Some(2),
            StreamKind::GpsTime => opt(layout.gps_time, 8),
            StreamKind::Rgb => opt(layout.rgb, 6),
            StreamKind::Nir => opt(layout.nir, 2),
            StreamKind::Waveform => opt(layout.waveform, WAVEFORM_BYTES),
            StreamKind::ExtraBytes => opt(layout.extra_bytes > 0, layout.extra_bytes as usize),
        }
    }

    /// The streams a store of `layout` has, in file order, with their bytes per point.
    pub fn present(layout: &PointLayout) -> Vec<(StreamKind, usize)> {
        StreamKind::ALL
            .iter()
            .filter_map(|k| k.bytes_per_point(layout).map(|b| (*k, b)))
            .collect()
    }
}

/// Where one stream lies in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamInfo {
    pub kind: StreamKind,
    /// Byte offset of the stream's first point (a multiple of [`STREAM_ALIGN`]).
    pub offset: u64,
    pub bytes_per_point: u32,
    /// Bytes: points × bytes per point.
    pub length: u64,
}

/// The store's JSON header, decoded and validated.
#[derive(Clone, Debug, PartialEq)]
pub struct StoreHeader {
    pub version: u32,
    pub points: u64,
    pub pointlets: u64,
    /// k: every pointlet but the last holds exactly k points; the last holds 1..=k.
    pub pointlet_size: u64,
    /// M of paper eq. 1, as asked for when building.
    pub target_pointlets: u64,
    /// Seed of the per-pointlet shuffles.
    pub seed: u64,
    /// Union of the pointlet AABBs (dequantized points).
    pub bounds: Aabb,
    /// Box whose bounding cube defines the Hilbert key grid: `bounds` since version 2, the
    /// merged input header bounds before.
    pub key_bounds: Aabb,
    pub quantization: Quantization,
    pub layout: PointLayout,
    pub las_point_format: u8,
    pub vlrs: Vec<Vlr>,
    /// The LAS header fields an export writes back; `None` when no input was LAS/LAZ.
    pub las: Option<LasFields>,
    pub sources: Vec<String>,
    pub streams: Vec<StreamInfo>,
}

impl StoreHeader {
    pub fn stream(&self, kind: StreamKind) -> Option<&StreamInfo> {
        self.streams.iter().find(|s| s.kind == kind)
    }
}

/// One pointlet: points `[first, first + count)` of every stream.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointletEntry {
    pub first: u64,
    pub count: u32,
    /// Bounds of the pointlet's dequantized positions.
    pub aabb: Aabb,
}

impl PointletEntry {
    pub(crate) fn encode(&self) -> [u8; TABLE_ENTRY_LEN as usize] {
        let mut out = [0u8; TABLE_ENTRY_LEN as usize];
        out[0..8].copy_from_slice(&self.first.to_le_bytes());
        out[8..12].copy_from_slice(&self.count.to_le_bytes());
        out[12..16].copy_from_slice(&0u32.to_le_bytes());
        let values = self.aabb.min.iter().chain(self.aabb.max.iter());
        for (i, v) in values.enumerate() {
            out[16 + 8 * i..24 + 8 * i].copy_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Decodes an entry; `None` when the reserved word is not zero.
    pub(crate) fn decode(b: &[u8; TABLE_ENTRY_LEN as usize]) -> Option<PointletEntry> {
        let u64_at = |o: usize| u64::from_le_bytes(array(&b[o..o + 8]));
        let u32_at = |o: usize| u32::from_le_bytes(array(&b[o..o + 4]));
        let f64_at = |o: usize| f64::from_le_bytes(array(&b[o..o + 8]));
        if u32_at(12) != 0 {
            return None;
        }
        Some(PointletEntry {
            first: u64_at(0),
            count: u32_at(8),
            aabb: Aabb {
                min: [f64_at(16), f64_at(24), f64_at(32)],
                max: [f64_at(40), f64_at(48), f64_at(56)],
            },
        })
    }
}

/// A fixed-size array from a slice whose length the caller guarantees.
#[inline]
pub(crate) fn array<const N: usize>(s: &[u8]) -> [u8; N] {
    let mut a = [0u8; N];
    a.copy_from_slice(s);
    a
}

/// From the preamble alone: the file's length and where its streams start. Every byte a
/// reader checks at open lies before that offset, so a client fetching byte ranges (the
/// browser) reads `0..data_offset` once and opens the store from those bytes.
pub fn metadata_extent(preamble: &[u8; PREAMBLE_LEN as usize]) -> Result<(u64, u64), String> {
    let pre = Preamble::decode(preamble)?;
    Ok((pre.file_len, pre.data_offset))
}

/// A region of the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) struct Section {
    pub offset: u64,
    pub len: u64,
}

impl Section {
    pub fn end(&self) -> u64 {
        self.offset + self.len
    }
}

/// The fixed preamble at offset 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) struct Preamble {
    pub version: u32,
    pub file_len: u64,
    pub header: Section,
    pub table: Section,
    pub checksums: Section,
    pub data_offset: u64,
    pub header_crc: u32,
    pub table_crc: u32,
    pub checksums_crc: u32,
}

impl Preamble {
    pub fn encode(&self) -> [u8; PREAMBLE_LEN as usize] {
        let mut b = [0u8; PREAMBLE_LEN as usize];
        b[0..8].copy_from_slice(&MAGIC);
        b[8..12].copy_from_slice(&self.version.to_le_bytes());
        b[12..16].copy_from_slice(&(PREAMBLE_LEN as u32).to_le_bytes());
        let words = [
            self.file_len,
            self.header.offset,
            self.header.len,
            self.table.offset,
            self.table.len,
            self.checksums.offset,
            self.checksums.len,
            self.data_offset,
        ];
        for (i, w) in words.iter().enumerate() {
            b[16 + 8 * i..24 + 8 * i].copy_from_slice(&w.to_le_bytes());
        }
        b[80..84].copy_from_slice(&self.header_crc.to_le_bytes());
        b[84..88].copy_from_slice(&self.table_crc.to_le_bytes());
        b[88..92].copy_from_slice(&self.checksums_crc.to_le_bytes());
        // 92..124 reserved, zero.
        let crc = crc32fast::hash(&b[0..124]);
        b[124..128].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Decodes and checks magic, version, declared length, reserved bytes and the preamble CRC.
    pub fn decode(b: &[u8; PREAMBLE_LEN as usize]) -> Result<Preamble, String> {
        if b[0..8] != MAGIC {
            return Err("bad magic (the file does not start like a .pointlet store)".into());
        }
        let u32_at = |o: usize| u32::from_le_bytes(array(&b[o..o + 4]));
        let u64_at = |o: usize| u64::from_le_bytes(array(&b[o..o + 8]));
        let crc = crc32fast::hash(&b[0..124]);
        if crc != u32_at(124) {
            return Err("preamble checksum mismatch".into());
        }
        let version = u32_at(8);
        if !(OLDEST_READ_VERSION..=VERSION).contains(&version) {
            return Err(format!(
                "format version {version} is not supported (this build reads versions \
                 {OLDEST_READ_VERSION} to {VERSION}; a newer build may read it)"
            ));
        }
        if u32_at(12) as u64 != PREAMBLE_LEN {
            return Err(format!(
                "preamble length {} is not {PREAMBLE_LEN}",
                u32_at(12)
            ));
        }
        if b[92..124].iter().any(|x| *x != 0) {
            return Err("reserved preamble bytes are not zero".into());
        }
        let section = |o: usize| Section {
            offset: u64_at(o),
            len: u64_at(o + 8),
        };
        Ok(Preamble {
            version,
            file_len: u64_at(16),
            header: section(24),
            table: section(40),
            checksums: section(56),
            data_offset: u64_at(72),
            header_crc: u32_at(80),
            table_crc: u32_at(84),
            checksums_crc: u32_at(88),
        })
    }
}

/// Every offset of a store, derived from the header length, counts and layout.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Plan {
    pub header: Section,
    pub table: Section,
    pub checksums: Section,
    pub data_offset: u64,
    pub streams: Vec<StreamInfo>,
    pub file_len: u64,
}

pub(crate) fn align_up(v: u64, a: u64) -> Option<u64> {
    v.checked_add(a - 1).map(|x| x / a * a)
}

/// Lays a store out; `None` when a size overflows 64 bits.
pub(crate) fn plan(
    header_len: u64,
    points: u64,
    pointlets: u64,
    layout: &PointLayout,
) -> Option<Plan> {
    let streams = StreamKind::present(layout);
    let header = Section {
        offset: PREAMBLE_LEN,
        len: header_len,
    };
    let table = Section {
        offset: align_up(header.offset.checked_add(header_len)?, 8)?,
        len: pointlets.checked_mul(TABLE_ENTRY_LEN)?,
    };
    let checksums = Section {
        offset: table.offset.checked_add(table.len)?,
        len: pointlets
            .checked_mul(4)?
            .checked_mul(streams.len() as u64)?,
    };
    let data_offset = align_up(checksums.offset.checked_add(checksums.len)?, STREAM_ALIGN)?;
    let mut infos = Vec::with_capacity(streams.len());
    let mut at = data_offset;
    let last = streams.len() - 1;
    for (i, (kind, bpp)) in streams.into_iter().enumerate() {
        let length = points.checked_mul(bpp as u64)?;
        infos.push(StreamInfo {
            kind,
            offset: at,
            bytes_per_point: bpp as u32,
            length,
        });
        let end = at.checked_add(length)?;
        // The file ends with the last stream: no trailing padding.
        at = if i == last {
            end
        } else {
            align_up(end, STREAM_ALIGN)?
        };
    }
    Some(Plan {
        header,
        table,
        checksums,
        data_offset,
        streams: infos,
        file_len: at,
    })
}

// The JSON header's schema. Local mirrors of the core types so unknown fields are refused.

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct HeaderJson {
    version: u32,
    points: u64,
    pointlets: u64,
    pointlet_size: u64,
    target_pointlets: u64,
    seed: u64,
    bounds: AabbJson,
    key_bounds: AabbJson,
    quantization: QuantizationJson,
    layout: LayoutJson,
    las_point_format: u8,
    vlrs: Vec<VlrJson>,
    /// Absent in version 1; `null` when no input was LAS/LAZ.
    #[serde(default, skip_serializing_if = "Absent::is_absent")]
    las: Absent<LasJson>,
    sources: Vec<String>,
    streams: Vec<StreamJson>,
}

/// A field that version 1 lacks and version 2 requires (possibly as `null`).
#[derive(Default)]
enum Absent<T> {
    #[default]
    Absent,
    Present(Option<T>),
}

impl<T> Absent<T> {
    fn is_absent(&self) -> bool {
        matches!(self, Absent::Absent)
    }
}

impl<T: Serialize> Serialize for Absent<T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Absent::Absent | Absent::Present(None) => s.serialize_none(),
            Absent::Present(Some(v)) => s.serialize_some(v),
        }
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Absent<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Option::<T>::deserialize(d).map(Absent::Present)
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LasJson {
    global_encoding: u16,
    file_source_id: u16,
    /// The project GUID's 16 bytes as lowercase hexadecimal.
    project_id_hex: String,
    system_identifier: String,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AabbJson {
    min: [f64; 3],
    max: [f64; 3],
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct QuantizationJson {
    scale: [f64; 3],
    offset: [f64; 3],
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayoutJson {
    gps_time: bool,
    rgb: bool,
    nir: bool,
    waveform: bool,
    extra_bytes: u16,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct VlrJson {
    user_id: String,
    record_id: u16,
    description: String,
    extended: bool,
    /// The record's payload as lowercase hexadecimal.
    data_hex: String,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct StreamJson {
    name: String,
    offset: u64,
    bytes_per_point: u32,
    length: u64,
}

fn to_hex(data: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut s = String::with_capacity(data.len() * 2);
    for b in data {
        s.push(DIGITS[(b >> 4) as usize] as char);
        s.push(DIGITS[(b & 15) as usize] as char);
    }
    s
}

fn from_hex(s: &str) -> Option<Vec<u8>> {
    let digit = |c: u8| match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        _ => None,
    };
    let b = s.as_bytes();
    if !b.len().is_multiple_of(2) {
        return None;
    }
    b.chunks_exact(2)
        .map(|p| Some(digit(p[0])? << 4 | digit(p[1])?))
        .collect()
}

/// The header as JSON bytes.
pub(crate) fn encode_header(h: &StoreHeader) -> Result<Vec<u8>, String> {
    let aabb = |b: &Aabb| AabbJson {
        min: b.min,
        max: b.max,
    };
    let json = HeaderJson {
        version: h.version,
        points: h.points,
        pointlets: h.pointlets,
        pointlet_size: h.pointlet_size,
        target_pointlets: h.target_pointlets,
        seed: h.seed,
        bounds: aabb(&h.bounds),
        key_bounds: aabb(&h.key_bounds),
        quantization: QuantizationJson {
            scale: h.quantization.scale,
            offset: h.quantization.offset,
        },
        layout: LayoutJson {
            gps_time: h.layout.gps_time,
            rgb: h.layout.rgb,
            nir: h.layout.nir,
            waveform: h.layout.waveform,
            extra_bytes: h.layout.extra_bytes,
        },
        las_point_format: h.las_point_format,
        vlrs: h
            .vlrs
            .iter()
            .map(|v| VlrJson {
                user_id: v.user_id.clone(),
                record_id: v.record_id,
                description: v.description.clone(),
                extended: v.extended,
                data_hex: to_hex(&v.data),
            })
            .collect(),
        las: Absent::Present(h.las.as_ref().map(|l| LasJson {
            global_encoding: l.global_encoding,
            file_source_id: l.file_source_id,
            project_id_hex: to_hex(&l.project_id),
            system_identifier: l.system_identifier.clone(),
        })),
        sources: h.sources.clone(),
        streams: h
            .streams
            .iter()
            .map(|s| StreamJson {
                name: s.kind.name().to_string(),
                offset: s.offset,
                bytes_per_point: s.bytes_per_point,
                length: s.length,
            })
            .collect(),
    };
    serde_json::to_vec(&json).map_err(|e| format!("encoding the header: {e}"))
}

fn finite_box(b: &AabbJson) -> bool {
    b.min.iter().chain(b.max.iter()).all(|v| v.is_finite()) && (0..3).all(|i| b.min[i] <= b.max[i])
}

/// Parses the JSON header of a store of format `version` (from the preamble) and checks
/// everything that does not need the rest of the file.
pub(crate) fn decode_header(bytes: &[u8], version: u32) -> Result<StoreHeader, String> {
    let j: HeaderJson =
        serde_json::from_slice(bytes).map_err(|e| format!("the JSON header is invalid: {e}"))?;
    if j.version != version {
        return Err(format!(
            "the JSON header says version {}, the preamble {version}",
            j.version
        ));
    }
    let las = match (j.las, version) {
        (Absent::Absent, 1) => None,
        (Absent::Absent, _) => return Err("the JSON header lacks the field `las`".into()),
        (Absent::Present(_), 1) => {
            return Err("the JSON header of a version 1 store has the field `las`".into())
        }
        (Absent::Present(None), _) => None,
        (Absent::Present(Some(l)), _) => {
            let project_id = from_hex(&l.project_id_hex)
                .and_then(|b| <[u8; 16]>::try_from(b).ok())
                .ok_or("the LAS project id is not 16 bytes of hexadecimal")?;
            Some(LasFields {
                global_encoding: l.global_encoding,
                file_source_id: l.file_source_id,
                project_id,
                system_identifier: l.system_identifier,
            })
        }
    };
    if j.points == 0 {
        return Err("the header claims no points".into());
    }
    let k = j.pointlet_size;
    if !k.is_power_of_two() || !(crate::MIN_POINTLET_SIZE..=crate::MAX_POINTLET_SIZE).contains(&k) {
        return Err(format!(
            "pointlet size {k} is not a power of two in [{}, {}]",
            crate::MIN_POINTLET_SIZE,
            crate::MAX_POINTLET_SIZE
        ));
    }
    if j.pointlets != j.points.div_ceil(k) {
        return Err(format!(
            "{} pointlets cannot hold {} points in pointlets of {k}",
            j.pointlets, j.points
        ));
    }
    if !finite_box(&j.bounds) || !finite_box(&j.key_bounds) {
        return Err("the bounds are not finite boxes".into());
    }
    let quantization = Quantization {
        scale: j.quantization.scale,
        offset: j.quantization.offset,
    };
    quantization
        .validate()
        .map_err(|e| format!("bad quantization: {e}"))?;
    if j.las_point_format > 10 {
        return Err(format!(
            "LAS point format {} does not exist",
            j.las_point_format
        ));
    }
    let layout = PointLayout {
        gps_time: j.layout.gps_time,
        rgb: j.layout.rgb,
        nir: j.layout.nir,
        waveform: j.layout.waveform,
        extra_bytes: j.layout.extra_bytes,
    };
    let mut vlrs = Vec::with_capacity(j.vlrs.len());
    for v in j.vlrs {
        let data = from_hex(&v.data_hex).ok_or_else(|| {
            format!(
                "VLR '{}' {}: data is not hexadecimal",
                v.user_id, v.record_id
            )
        })?;
        vlrs.push(Vlr {
            user_id: v.user_id,
            record_id: v.record_id,
            description: v.description,
            data,
            extended: v.extended,
        });
    }
    let expected = StreamKind::present(&layout);
    if j.streams.len() != expected.len() {
        return Err(format!(
            "the header lists {} streams, the layout needs {}",
            j.streams.len(),
            expected.len()
        ));
    }
    let mut streams = Vec::with_capacity(expected.len());
    for (s, (kind, bpp)) in j.streams.iter().zip(expected) {
        if s.name != kind.name() || s.bytes_per_point as usize != bpp {
            return Err(format!(
                "stream '{}' of {} bytes per point where '{}' of {bpp} belongs",
                s.name,
                s.bytes_per_point,
                kind.name()
            ));
        }
        streams.push(StreamInfo {
            kind,
            offset: s.offset,
            bytes_per_point: s.bytes_per_point,
            length: s.length,
        });
    }
    Ok(StoreHeader {
        version: j.version,
        points: j.points,
        pointlets: j.pointlets,
        pointlet_size: k,
        target_pointlets: j.target_pointlets,
        seed: j.seed,
        bounds: Aabb {
            min: j.bounds.min,
            max: j.bounds.max,
        },
        key_bounds: Aabb {
            min: j.key_bounds.min,
            max: j.key_bounds.max,
        },
        quantization,
        layout,
        las_point_format: j.las_point_format,
        vlrs,
        las,
        sources: j.sources,
        streams,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trip() {
        let data: Vec<u8> = (0..=255).collect();
        assert_eq!(from_hex(&to_hex(&data)).unwrap(), data);
        assert!(from_hex("abc").is_none());
        assert!(from_hex("zz").is_none());
        assert!(from_hex("AB").is_none());
    }

    #[test]
    fn plan_aligns_streams_and_ends_with_the_last() {
        let layout = PointLayout {
            rgb: true,
            ..Default::default()
        };
        let p = plan(1000, 1000, 4, &layout).unwrap();
        assert_eq!(p.table.offset, 1128);
        assert_eq!(p.checksums.offset, 1128 + 256);
        assert_eq!(p.data_offset, 4096);
        for s in &p.streams {
            assert_eq!(s.offset % STREAM_ALIGN, 0);
            assert_eq!(s.length, 1000 * s.bytes_per_point as u64);
        }
        let last = p.streams.last().unwrap();
        assert_eq!(last.kind, StreamKind::Rgb);
        assert_eq!(p.file_len, last.offset + last.length);
        assert!(plan(10, u64::MAX / 2, 1, &layout).is_none());
    }

    #[test]
    fn preamble_round_trip_and_checks() {
        let p = Preamble {
            version: VERSION,
            file_len: 12345,
            header: Section {
                offset: 128,
                len: 77,
            },
            data_offset: 4096,
            header_crc: 7,
            ..Default::default()
        };
        let mut b = p.encode();
        assert_eq!(Preamble::decode(&b).unwrap(), p);
        b[20] ^= 1;
        assert!(Preamble::decode(&b).unwrap_err().contains("checksum"));
        b[0] = b'P';
        assert!(Preamble::decode(&b).unwrap_err().contains("magic"));
    }
}
