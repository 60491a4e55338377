//! The LAS header, its VLRs and EVLRs: parsed and validated without trusting any field.
//!
//! Parsing reads through a [`Source`] (a byte slice or an open file) so the same code checks a
//! fuzzer's bytes and a multi-gigabyte file; only the records worth keeping are read whole.

use super::record::PointFormat;
use pointlet_core::{Aabb, LasFields, Quantization, Vlr};
use std::io::{Read, Seek, SeekFrom};
use thiserror::Error;

/// Bytes of the fixed header each LAS minor version requires at least.
const HEADER_SIZE_1_0: u16 = 227;
const HEADER_SIZE_1_3: u16 = 235;
const HEADER_SIZE_1_4: u16 = 375;
const VLR_HEADER: u64 = 54;
const EVLR_HEADER: u64 = 60;
/// The largest EVLR this reader keeps: records travel in a store's JSON header, so a larger one
/// (in practice only waveform data) is left behind.
pub const MAX_KEPT_EVLR: u64 = 16 << 20;
/// Global-encoding bit: the waveform data packets are inside the file.
const WAVEFORM_INTERNAL: u16 = 1 << 1;

/// What is wrong with a LAS file, without the path (the reader adds it).
#[derive(Debug, Error)]
pub enum LasError {
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("not a LAS/LAZ file: {0}")]
    NotLas(String),
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    Unsupported(String),
    /// The header says there are no points (a folder merge skips such files).
    #[error("{0}")]
    NoPoints(String),
}

fn invalid(msg: impl Into<String>) -> LasError {
    LasError::Invalid(msg.into())
}

/// Random-access bytes: a slice or a file.
pub(crate) trait Source {
    fn len(&self) -> u64;
    /// Fills `buf` from `offset`; the caller has checked that the range lies inside `len`.
    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> Result<(), LasError>;
}

pub(crate) struct SliceSource<'a>(pub &'a [u8]);

impl Source for SliceSource<'_> {
    fn len(&self) -> u64 {
        self.0.len() as u64
    }

    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> Result<(), LasError> {
        let start = usize::try_from(offset).map_err(|_| invalid("offset beyond the data"))?;
        let bytes = start
            .checked_add(buf.len())
            .and_then(|end| self.0.get(start..end))
            .ok_or_else(|| invalid(format!("the data ends before byte {}", offset)))?;
        buf.copy_from_slice(bytes);
        Ok(())
    }
}

pub(crate) struct FileSource<'a> {
    pub file: &'a mut std::fs::File,
    pub len: u64,
}

impl Source for FileSource<'_> {
    fn len(&self) -> u64 {
        self.len
    }

    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> Result<(), LasError> {
        self.file.seek(SeekFrom::Start(offset))?;
        self.file.read_exact(buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                invalid(format!(
                    "the file ends early: reading {} bytes at byte {offset}",
                    buf.len()
                ))
            } else {
                LasError::Io(e)
            }
        })
    }
}

/// A parsed, validated LAS header with the records this project keeps.
#[derive(Clone, Debug, PartialEq)]
pub struct LasHeader {
    pub version: (u8, u8),
    pub global_encoding: u16,
    pub header_size: u16,
    pub offset_to_point_data: u32,
    /// Point data record format (0–10), without the LAZ marker bits.
    pub point_format: u8,
    /// The format byte carried the LAZ marker (bit 7 or 6).
    pub compressed: bool,
    pub point_record_length: u16,
    /// Points the header claims (the 64-bit count of LAS 1.4 when it is set).
    pub point_count: u64,
    /// Points by return number 1–15 (only 1–5 before LAS 1.4).
    pub points_by_return: [u64; 15],
    pub quantization: Quantization,
    pub bounds: Aabb,
    pub start_of_first_evlr: u64,
    pub number_of_evlrs: u32,
    /// Where the waveform data packet record starts (LAS 1.3 and later; 0 when none).
    pub start_of_waveform_data: u64,
    /// The header fields a store keeps (file source id, project id, GPS time type, ...).
    pub fields: LasFields,
    /// Every VLR and EVLR but the LASzip and COPC records, verbatim; the waveform data packets
    /// are among them when they are inside the file and at most [`MAX_KEPT_EVLR`] bytes.
    pub kept_vlrs: Vec<Vlr>,
    /// The record data of the LASzip VLR, when there is one.
    pub laszip: Option<Vec<u8>>,
    /// A COPC info VLR is present.
    pub copc: bool,
    /// Size of the whole file (or byte slice) the header was parsed from.
    pub file_len: u64,
}

impl LasHeader {
    /// Bytes of a point record the format itself defines; the rest are extra bytes.
    pub fn extra_bytes(&self) -> u16 {
        let base = PointFormat::new(self.point_format).map_or(0, |f| f.size);
        self.point_record_length.saturating_sub(base as u16)
    }

    /// E.g. `LAS 1.2 point format 3` or `LAZ 1.4 point format 7 (COPC)`.
    pub fn format_name(&self) -> String {
        format!(
            "{} {}.{} point format {}{}",
            if self.compressed { "LAZ" } else { "LAS" },
            self.version.0,
            self.version.1,
            self.point_format,
            if self.copc { " (COPC)" } else { "" }
        )
    }
}

/// Parses and validates the header, VLRs and EVLRs of a whole LAS/LAZ file held in `bytes`.
/// Never panics; every inconsistency is an error.
pub fn parse_header(bytes: &[u8]) -> Result<LasHeader, LasError> {
    parse(&mut SliceSource(bytes))
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes(arr(b, at))
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(arr(b, at))
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(arr(b, at))
}
fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(arr(b, at))
}
/// `N` bytes at `at`, zeros where `b` is too short (callers size `b` before reading).
fn arr<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    at.checked_add(N)
        .and_then(|end| b.get(at..end))
        .and_then(|s| s.try_into().ok())
        .unwrap_or([0; N])
}

/// A fixed-width, NUL-padded text field.
fn text(b: &[u8]) -> String {
    let end = b.iter().position(|c| *c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end]).into_owned()
}

pub(crate) fn parse(src: &mut dyn Source) -> Result<LasHeader, LasError> {
    let len = src.len();
    if len < 4 {
        return Err(LasError::NotLas(format!(
            "only {len} bytes, no LASF signature"
        )));
    }
    let mut sig = [0u8; 4];
    src.read_at(0, &mut sig)?;
    if &sig != b"LASF" {
        return Err(LasError::NotLas(format!(
            "the signature is {:?}, not \"LASF\"",
            String::from_utf8_lossy(&sig)
        )));
    }
    if len < u64::from(HEADER_SIZE_1_0) {
        return Err(invalid(format!(
            "the file ends inside the header ({len} bytes, a LAS header has at least {HEADER_SIZE_1_0})"
        )));
    }
    let mut h = vec![0u8; (HEADER_SIZE_1_4 as usize).min(len as usize)];
    src.read_at(0, &mut h)?;
    let version = (h[24], h[25]);
    if version.0 != 1 || version.1 > 4 {
        return Err(LasError::Unsupported(format!(
            "LAS version {}.{} (this reader knows 1.0 to 1.4)",
            version.0, version.1
        )));
    }
    let required = match version.1 {
        0..=2 => HEADER_SIZE_1_0,
        3 => HEADER_SIZE_1_3,
        _ => HEADER_SIZE_1_4,
    };
    let header_size = u16_at(&h, 94);
    if header_size < required {
        return Err(invalid(format!(
            "header size {header_size} is smaller than the {required} bytes LAS {}.{} requires",
            version.0, version.1
        )));
    }
    if u64::from(header_size) > len {
        return Err(invalid(format!(
            "header size {header_size} lies beyond the end of the file ({len} bytes)"
        )));
    }
    let offset_to_point_data = u32_at(&h, 96);
    if offset_to_point_data < u32::from(header_size) {
        return Err(invalid(format!(
            "offset to point data {offset_to_point_data} lies inside the {header_size}-byte header"
        )));
    }
    if u64::from(offset_to_point_data) > len {
        return Err(invalid(format!(
            "offset to point data {offset_to_point_data} lies beyond the end of the file ({len} bytes)"
        )));
    }
    let number_of_vlrs = u32_at(&h, 100);
    let format_byte = h[104];
    let compressed = format_byte & 0xC0 != 0;
    let point_format = format_byte & 0x3F;
    let format = PointFormat::new(point_format).ok_or_else(|| {
        LasError::Unsupported(format!(
            "unknown point format {point_format} (LAS defines formats 0 to 10)"
        ))
    })?;
    let point_record_length = u16_at(&h, 105);
    if usize::from(point_record_length) < format.size {
        return Err(invalid(format!(
            "point record length {point_record_length} is smaller than the {} bytes point format {point_format} needs",
            format.size
        )));
    }
    let legacy_count = u32_at(&h, 107);
    let mut points_by_return = [0u64; 15];
    for (i, n) in points_by_return.iter_mut().take(5).enumerate() {
        *n = u64::from(u32_at(&h, 111 + 4 * i));
    }
    let scale = [f64_at(&h, 131), f64_at(&h, 139), f64_at(&h, 147)];
    let offset = [f64_at(&h, 155), f64_at(&h, 163), f64_at(&h, 171)];
    for (axis, s) in scale.iter().enumerate() {
        if !(s.is_finite() && *s > 0.0) {
            return Err(invalid(format!(
                "scale factor {s} of {} is not a positive finite number",
                AXES[axis]
            )));
        }
    }
    for (axis, o) in offset.iter().enumerate() {
        if !o.is_finite() {
            return Err(invalid(format!(
                "offset {o} of {} is not finite",
                AXES[axis]
            )));
        }
    }
    let max = [f64_at(&h, 179), f64_at(&h, 195), f64_at(&h, 211)];
    let min = [f64_at(&h, 187), f64_at(&h, 203), f64_at(&h, 219)];
    if max.iter().chain(min.iter()).any(|v| !v.is_finite()) {
        return Err(invalid(format!(
            "header bounds min {min:?} max {max:?} are not finite"
        )));
    }
    let (mut start_of_first_evlr, mut number_of_evlrs) = (0, 0);
    let start_of_waveform_data = if version.1 >= 3 { u64_at(&h, 227) } else { 0 };
    let mut point_count = u64::from(legacy_count);
    if version.1 >= 4 {
        start_of_first_evlr = u64_at(&h, 235);
        number_of_evlrs = u32_at(&h, 243);
        let count = u64_at(&h, 247);
        if count != 0 {
            point_count = count;
        }
        for (i, n) in points_by_return.iter_mut().enumerate() {
            *n = u64_at(&h, 255 + 8 * i);
        }
    }

    // File source id and global encoding were reserved bytes before LAS 1.1 and 1.2.
    let global_encoding = if version.1 >= 2 { u16_at(&h, 6) } else { 0 };
    let fields = LasFields {
        global_encoding: global_encoding & LasFields::KEPT_ENCODING,
        file_source_id: if version.1 >= 1 { u16_at(&h, 4) } else { 0 },
        project_id: arr(&h, 8),
        system_identifier: text(&h[26..58]),
    };
    let mut header = LasHeader {
        version,
        global_encoding,
        header_size,
        offset_to_point_data,
        point_format,
        compressed,
        point_record_length,
        point_count,
        points_by_return,
        quantization: Quantization { scale, offset },
        bounds: Aabb { min, max },
        start_of_first_evlr,
        number_of_evlrs,
        start_of_waveform_data,
        fields,
        kept_vlrs: Vec::new(),
        laszip: None,
        copc: false,
        file_len: len,
    };
    read_vlrs(src, &mut header, number_of_vlrs)?;
    if point_count == 0 {
        return Err(LasError::NoPoints(
            "no points: the header says the file holds none".into(),
        ));
    }
    if !compressed {
        let data = len - u64::from(offset_to_point_data);
        let holds = data / u64::from(point_record_length);
        if point_count > holds {
            return Err(invalid(format!(
                "header claims {point_count} points but the file holds {holds}"
            )));
        }
    }
    if number_of_evlrs > 0 && start_of_first_evlr > 0 {
        // Uncompressed records end at a known byte; EVLRs must not overlap them.
        let points_end = if compressed {
            u64::from(offset_to_point_data)
        } else {
            u64::from(offset_to_point_data) + point_count * u64::from(point_record_length)
        };
        if start_of_first_evlr < points_end {
            return Err(invalid(format!(
                "EVLRs start at byte {start_of_first_evlr}, inside the point records (which end at byte {points_end})"
            )));
        }
        read_evlrs(src, &mut header)?;
    }
    read_waveform_data(src, &mut header)?;
    Ok(header)
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// The records a writer makes itself, which no longer apply once the points are rewritten.
fn regenerated(user_id: &str, record_id: u16) -> bool {
    (user_id == "laszip encoded" && record_id == 22204) || user_id == "copc"
}

fn read_vlrs(src: &mut dyn Source, h: &mut LasHeader, count: u32) -> Result<(), LasError> {
    let end = u64::from(h.offset_to_point_data);
    let mut pos = u64::from(h.header_size);
    let mut raw = [0u8; VLR_HEADER as usize];
    for i in 0..count {
        if pos + VLR_HEADER > end {
            return Err(invalid(format!(
                "VLR {} of {count} starts at byte {pos} and runs past the start of the point data (byte {end})",
                i + 1
            )));
        }
        src.read_at(pos, &mut raw)?;
        let user_id = text(&raw[2..18]);
        let record_id = u16_at(&raw, 18);
        let data_len = u64::from(u16_at(&raw, 20));
        let description = text(&raw[22..54]);
        let data_start = pos + VLR_HEADER;
        if data_start + data_len > end {
            return Err(invalid(format!(
                "VLR {} of {count} ('{user_id}' {record_id}) runs past the start of the point data (byte {end})",
                i + 1
            )));
        }
        let mut data = vec![0u8; data_len as usize];
        src.read_at(data_start, &mut data)?;
        if user_id == "laszip encoded" && record_id == 22204 {
            h.laszip = Some(data);
        } else if user_id == "copc" && record_id == 1 {
            h.copc = true;
        } else if !regenerated(&user_id, record_id) {
            h.kept_vlrs.push(Vlr {
                user_id,
                record_id,
                description,
                data,
                extended: false,
            });
        }
        pos = data_start + data_len;
    }
    Ok(())
}

fn read_evlrs(src: &mut dyn Source, h: &mut LasHeader) -> Result<(), LasError> {
    let len = src.len();
    let count = h.number_of_evlrs;
    let mut pos = h.start_of_first_evlr;
    let mut raw = [0u8; EVLR_HEADER as usize];
    for i in 0..count {
        if pos.checked_add(EVLR_HEADER).is_none_or(|e| e > len) {
            return Err(invalid(format!(
                "EVLR {} of {count} starts at byte {pos}, past the end of the file ({len} bytes)",
                i + 1
            )));
        }
        src.read_at(pos, &mut raw)?;
        let record_id = u16_at(&raw, 18);
        // The record the waveform pointer leads to is the waveform data, however it is spelt.
        let user_id = if pos == h.start_of_waveform_data && record_id == 65535 {
            "LASF_Spec".to_string()
        } else {
            text(&raw[2..18])
        };
        let data_len = u64_at(&raw, 20);
        let description = text(&raw[28..60]);
        let data_start = pos + EVLR_HEADER;
        let data_end = data_start.checked_add(data_len).filter(|e| *e <= len);
        let Some(data_end) = data_end else {
            return Err(invalid(format!(
                "EVLR {} of {count} ('{user_id}' {record_id}) claims {data_len} bytes, past the end of the file ({len} bytes)",
                i + 1
            )));
        };
        if !regenerated(&user_id, record_id) && data_len <= MAX_KEPT_EVLR {
            let mut data = vec![0u8; data_len as usize];
            src.read_at(data_start, &mut data)?;
            h.kept_vlrs.push(Vlr {
                user_id,
                record_id,
                description,
                data,
                extended: true,
            });
        }
        pos = data_end;
    }
    Ok(())
}

/// LAS 1.3 keeps its waveform data packets in a record that is not counted among EVLRs; this
/// keeps it (once) when the global encoding says the packets are inside the file. A pointer
/// that leads nowhere keeps nothing: the descriptors are then written as "no packet".
fn read_waveform_data(src: &mut dyn Source, h: &mut LasHeader) -> Result<(), LasError> {
    let at = h.start_of_waveform_data;
    if at == 0
        || h.global_encoding & WAVEFORM_INTERNAL == 0
        || h.kept_vlrs.iter().any(Vlr::is_waveform_data)
        || at.checked_add(EVLR_HEADER).is_none_or(|e| e > src.len())
    {
        return Ok(());
    }
    let mut raw = [0u8; EVLR_HEADER as usize];
    src.read_at(at, &mut raw)?;
    let data_len = u64_at(&raw, 20);
    let fits = (at + EVLR_HEADER)
        .checked_add(data_len)
        .is_some_and(|e| e <= src.len());
    // The record id is checked, not the user id: writers misspell it (testdata/simple1_3.las
    // says "LAS_Spec").
    if u16_at(&raw, 18) != 65535 || !fits || data_len > MAX_KEPT_EVLR {
        return Ok(());
    }
    let mut data = vec![0u8; data_len as usize];
    src.read_at(at + EVLR_HEADER, &mut data)?;
    h.kept_vlrs.push(Vlr {
        user_id: "LASF_Spec".into(),
        record_id: 65535,
        description: text(&raw[28..60]),
        data,
        extended: true,
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_and_foreign_bytes_are_errors() {
        assert!(matches!(parse_header(b""), Err(LasError::NotLas(_))));
        assert!(matches!(parse_header(b"PLY\n"), Err(LasError::NotLas(_))));
        assert!(matches!(
            parse_header(b"LASF and then nothing"),
            Err(LasError::Invalid(_))
        ));
    }
}
