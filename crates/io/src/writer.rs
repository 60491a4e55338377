//! LAS 1.4 / LAZ writer for point formats 0–10.
//!
//! Output goes to a temporary file beside the target, renamed over it by [`LasWriter::finish`];
//! a writer dropped before `finish` (an error, a cancelled export) removes its temporary file,
//! so no partial output is ever left. LAZ goes through the `laz` crate, which compresses the
//! whole chunks of each batch in parallel.
//!
//! The header's bounds and return counts come from the points written; its file source id,
//! project id, system identifier and the global-encoding bits of [`LasFields`] come from the
//! config. The VLRs given are written as they are (as EVLRs when they were EVLRs or exceed a
//! VLR's 65 535 bytes); the global-encoding WKT bit is set when one of them is a WKT CRS
//! (LASF_Projection 2112). Waveform data packets (LASF_Spec 65535) are written as the first
//! EVLR, with the header's pointer to them and the "internal" bit, so descriptors keep their
//! offsets; without that record every wave packet descriptor is written as "no packet".

use crate::las::record::{EncodeStats, Encoder, PointFormat};
use crate::IoError;
use laz::{LazVlr, LazVlrBuilder, ParLasZipCompressor};
use pointlet_core::{LasFields, PointBatch, PointLayout, Quantization, Vlr};
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

const HEADER_SIZE: usize = 375;
const VLR_HEADER: usize = 54;
const MAX_VLR_DATA: usize = u16::MAX as usize;
/// Points per LAZ chunk (LASzip's usual size).
const LAZ_CHUNK_POINTS: u32 = 50_000;

/// What to write.
#[derive(Clone, Debug)]
pub struct LasWriterConfig {
    pub quantization: Quantization,
    /// LAS point data record format, 0–10.
    pub point_format: u8,
    /// Columns written; must fit the point format. `extra_bytes` sets the extra bytes per record.
    pub layout: PointLayout,
    /// Records to carry (CRS, extra-bytes description, ...). LASzip and COPC records are dropped.
    pub vlrs: Vec<Vlr>,
    /// Header fields to write back (GPS time type, file source id, ...).
    pub fields: LasFields,
    /// Write LAZ instead of LAS.
    pub compress: bool,
}

enum Sink {
    Plain(BufWriter<File>),
    Laz(Box<ParLasZipCompressor<BufWriter<File>>>),
}

/// Streams batches into a LAS/LAZ file; see the module documentation.
pub struct LasWriter {
    path: PathBuf,
    tmp: PathBuf,
    /// `None` once finished (or after a failed finish).
    sink: Option<Sink>,
    format: PointFormat,
    layout: PointLayout,
    quantization: Quantization,
    compress: bool,
    /// A WKT CRS record is among the records written.
    wkt: bool,
    fields: LasFields,
    /// The first EVLR is the waveform data packet record.
    waveform_data: bool,
    encoder: Encoder,
    stats: EncodeStats,
    offset_to_point_data: u32,
    number_of_vlrs: u32,
    evlrs: Vec<Vlr>,
    /// Encoded records: one batch for LAS; for LAZ, gathered up to `laz_flush_bytes`.
    buf: Vec<u8>,
    laz_flush_bytes: usize,
    finished: bool,
}

/// Makes temporary names unique within the process.
static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let unique = format!(
        ".{name}.{}-{}.tmp",
        std::process::id(),
        TMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    );
    path.with_file_name(unique)
}

/// NUL-padded fixed-width text (truncated when longer).
fn padded<const N: usize>(s: &str) -> [u8; N] {
    let mut out = [0u8; N];
    for (o, b) in out.iter_mut().zip(s.bytes()) {
        *o = b;
    }
    out
}

fn is_carried(v: &Vlr) -> bool {
    let user = v.user_id.trim_end_matches('\0');
    !(user == LazVlr::USER_ID || user == "copc")
}

impl LasWriter {
    pub fn create(path: &Path, config: LasWriterConfig) -> Result<Self, IoError> {
        config.quantization.validate().map_err(|e| {
            IoError::invalid(path, format!("cannot write with this quantization: {e}"))
        })?;
        let format = PointFormat::new(config.point_format).ok_or_else(|| {
            IoError::unsupported(
                path,
                format!(
                    "unknown point format {} (LAS defines formats 0 to 10)",
                    config.point_format
                ),
            )
        })?;
        let layout = config.layout;
        for (wanted, has, what) in [
            (layout.gps_time, format.gps_time.is_some(), "GPS time"),
            (layout.rgb, format.rgb.is_some(), "colour"),
            (layout.nir, format.nir.is_some(), "near infrared"),
            (
                layout.waveform,
                format.waveform.is_some(),
                "waveform packets",
            ),
        ] {
            if wanted && !has {
                return Err(IoError::invalid(
                    path,
                    format!("point format {} cannot hold {what}", format.id),
                ));
            }
        }
        let encoder = Encoder::new(format, layout.extra_bytes, config.quantization);
        let encoder_len = encoder.record_len();
        let record_len = u16::try_from(encoder.record_len()).map_err(|_| {
            IoError::invalid(
                path,
                format!("{} extra bytes make records too long", layout.extra_bytes),
            )
        })?;
        let mut vlrs = Vec::new();
        let mut evlrs: Vec<Vlr> = config
            .vlrs
            .iter()
            .filter(|v| v.is_waveform_data())
            .take(1)
            .cloned()
            .collect();
        let waveform_data = !evlrs.is_empty();
        let encoder = if waveform_data {
            encoder
        } else {
            encoder.without_waveforms()
        };
        let carried = config
            .vlrs
            .iter()
            .filter(|v| is_carried(v) && !v.is_waveform_data());
        for v in carried {
            if v.extended || v.data.len() > MAX_VLR_DATA {
                evlrs.push(v.clone());
            } else {
                vlrs.push(v.clone());
            }
        }
        let laz_vlr = if config.compress {
            let vlr = LazVlrBuilder::default()
                .with_point_format(format.id, layout.extra_bytes)
                .map_err(|e| IoError::unsupported(path, format!("LAZ: {e}")))?
                .with_fixed_chunk_size(LAZ_CHUNK_POINTS)
                .build();
            let mut data = Vec::new();
            vlr.write_to(&mut data).map_err(|e| IoError::io(path, e))?;
            vlrs.push(Vlr {
                user_id: LazVlr::USER_ID.into(),
                record_id: LazVlr::RECORD_ID,
                description: LazVlr::DESCRIPTION.into(),
                data,
                extended: false,
            });
            Some(vlr)
        } else {
            None
        };
        let wkt = vlrs
            .iter()
            .chain(evlrs.iter())
            .any(|v| v.is_crs() && v.record_id == 2112);
        let offset = HEADER_SIZE
            + vlrs
                .iter()
                .map(|v| VLR_HEADER + v.data.len())
                .sum::<usize>();
        let offset_to_point_data = u32::try_from(offset)
            .map_err(|_| IoError::invalid(path, "the VLRs are too large for a LAS header"))?;
        let tmp = temp_path(path);
        let file =
            pointlet_core::cleanup::create(&tmp, File::options().write(true).create_new(true))
                .map_err(|e| IoError::io(path, e))?;
        let mut writer = LasWriter {
            path: path.to_path_buf(),
            tmp,
            sink: None,
            format,
            layout,
            encoder,
            stats: EncodeStats::default(),
            offset_to_point_data,
            number_of_vlrs: vlrs.len() as u32,
            evlrs,
            buf: Vec::new(),
            laz_flush_bytes: LAZ_CHUNK_POINTS as usize
                * encoder_len
                * 4
                * rayon::current_num_threads().max(1),
            finished: false,
            quantization: config.quantization,
            compress: config.compress,
            wkt,
            fields: config.fields,
            waveform_data,
        };
        let mut out = BufWriter::with_capacity(1 << 20, file);
        // The header is rewritten with the final counts and bounds by `finish`.
        let head = writer.header_bytes(record_len);
        let io = |e| IoError::io(path, e);
        out.write_all(&head).map_err(io)?;
        for v in &vlrs {
            out.write_all(&vlr_header(v)).map_err(io)?;
            out.write_all(&v.data).map_err(io)?;
        }
        writer.sink = Some(match laz_vlr {
            Some(vlr) => Sink::Laz(Box::new(
                ParLasZipCompressor::new(out, vlr)
                    .map_err(|e| IoError::unsupported(path, format!("LAZ: {e}")))?,
            )),
            None => Sink::Plain(out),
        });
        Ok(writer)
    }

    /// Appends the points of `batch`. Columns the point format has but the batch lacks are
    /// written as zeros; columns the format cannot hold are an error.
    pub fn write_batch(&mut self, batch: &PointBatch) -> Result<(), IoError> {
        let path = self.path.clone();
        batch
            .check_shape()
            .map_err(|e| IoError::invalid(&path, format!("malformed batch: {e}")))?;
        let (l, f) = (batch.layout, self.format);
        for (has, fits, what) in [
            (l.gps_time, f.gps_time.is_some(), "GPS time"),
            (l.rgb, f.rgb.is_some(), "colour"),
            (l.nir, f.nir.is_some(), "near infrared"),
            (l.waveform, f.waveform.is_some(), "waveform packets"),
            (
                l.extra_bytes > self.layout.extra_bytes,
                false,
                "more extra bytes",
            ),
        ] {
            if has && !fits {
                return Err(IoError::invalid(
                    &path,
                    format!(
                        "points carry {what} but the writer was created for point format {} with {} extra bytes",
                        f.id, self.layout.extra_bytes
                    ),
                ));
            }
        }
        if matches!(self.sink, Some(Sink::Plain(_))) {
            self.buf.clear();
        }
        let before = self.stats.points;
        self.encoder
            .encode(batch, &mut self.buf, &mut self.stats)
            .map_err(|(i, m)| {
                IoError::invalid(&path, format!("point {}: {m}", before + i as u64))
            })?;
        let io = |e| IoError::io(&path, e);
        match self.sink.as_mut() {
            Some(Sink::Plain(w)) => w.write_all(&self.buf).map_err(io),
            // Records gather until every thread gets whole chunks; only whole chunks go to the
            // compressor, which would compress a partial one alone, on one thread.
            Some(Sink::Laz(c)) if self.buf.len() >= self.laz_flush_bytes => {
                let chunk = LAZ_CHUNK_POINTS as usize * self.encoder.record_len();
                let whole = self.buf.len() / chunk * chunk;
                c.compress_many(self.buf.get(..whole).unwrap_or_default())
                    .map_err(io)?;
                self.buf.drain(..whole);
                Ok(())
            }
            Some(Sink::Laz(_)) => Ok(()),
            None => Err(IoError::invalid(&path, "the writer was already finished")),
        }
    }

    /// Completes the file (chunk table, EVLRs, final header), syncs it and renames it over the
    /// target. Returns the number of points written.
    pub fn finish(mut self) -> Result<u64, IoError> {
        let path = self.path.clone();
        let io = |e| IoError::io(&path, e);
        let mut out = match self.sink.take() {
            Some(Sink::Plain(w)) => w,
            Some(Sink::Laz(mut c)) => {
                c.compress_many(&self.buf).map_err(io)?;
                c.done()
                    .map_err(|e| IoError::invalid(&path, format!("LAZ: {e}")))?;
                c.into_inner()
            }
            None => return Err(IoError::invalid(&path, "the writer was already finished")),
        };
        let evlr_start = out.stream_position().map_err(io)?;
        for v in &self.evlrs {
            out.write_all(&evlr_header(v)).map_err(io)?;
            out.write_all(&v.data).map_err(io)?;
        }
        let record_len = self.encoder.record_len() as u16;
        let mut head = self.header_bytes(record_len);
        if !self.evlrs.is_empty() {
            head[235..243].copy_from_slice(&evlr_start.to_le_bytes());
            head[243..247].copy_from_slice(&(self.evlrs.len() as u32).to_le_bytes());
        }
        if self.waveform_data {
            head[227..235].copy_from_slice(&evlr_start.to_le_bytes());
        }
        out.seek(SeekFrom::Start(0)).map_err(io)?;
        out.write_all(&head).map_err(io)?;
        let file = out.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        pointlet_core::cleanup::persist(&self.tmp, &self.path).map_err(io)?;
        self.finished = true;
        Ok(self.stats.points)
    }

    /// The 375-byte LAS 1.4 header for what was written so far.
    fn header_bytes(&self, record_len: u16) -> [u8; HEADER_SIZE] {
        let mut h = [0u8; HEADER_SIZE];
        let s = &self.stats;
        let q = &self.quantization;
        let (day, year) = creation_date();
        let legacy_ok = !self.format.extended && s.points <= u64::from(u32::MAX);
        let mut put = |at: usize, bytes: &[u8]| h[at..at + bytes.len()].copy_from_slice(bytes);
        let encoding = self.fields.global_encoding & LasFields::KEPT_ENCODING
            | u16::from(self.waveform_data) << 1
            | u16::from(self.wkt) << 4;
        put(0, b"LASF");
        put(4, &self.fields.file_source_id.to_le_bytes());
        put(6, &encoding.to_le_bytes());
        put(8, &self.fields.project_id);
        put(24, &[1, 4]);
        put(26, &padded::<32>(&self.fields.system_identifier));
        put(
            58,
            &padded::<32>(concat!("pointlet-io ", env!("CARGO_PKG_VERSION"))),
        );
        put(90, &day.to_le_bytes());
        put(92, &year.to_le_bytes());
        put(94, &(HEADER_SIZE as u16).to_le_bytes());
        put(96, &self.offset_to_point_data.to_le_bytes());
        put(100, &self.number_of_vlrs.to_le_bytes());
        let marker = if self.compress { 0x80 } else { 0 };
        put(104, &[self.format.id | marker]);
        put(105, &record_len.to_le_bytes());
        if legacy_ok {
            put(107, &(s.points as u32).to_le_bytes());
            for (i, n) in s.by_return.iter().take(5).enumerate() {
                put(111 + 4 * i, &(*n as u32).to_le_bytes());
            }
        }
        for a in 0..3 {
            put(131 + 8 * a, &q.scale[a].to_le_bytes());
            put(155 + 8 * a, &q.offset[a].to_le_bytes());
        }
        let (min, max) = if s.points == 0 {
            ([0.0; 3], [0.0; 3])
        } else {
            (q.dequantize(s.min), q.dequantize(s.max))
        };
        for a in 0..3 {
            put(179 + 16 * a, &max[a].to_le_bytes());
            put(187 + 16 * a, &min[a].to_le_bytes());
        }
        put(247, &s.points.to_le_bytes());
        for (i, n) in s.by_return.iter().enumerate() {
            put(255 + 8 * i, &n.to_le_bytes());
        }
        h
    }
}

impl Drop for LasWriter {
    fn drop(&mut self) {
        if !self.finished {
            // Close before removing; removal failing leaves nothing worse than a hidden file.
            self.sink = None;
            pointlet_core::cleanup::remove(&self.tmp);
        }
    }
}

fn vlr_header(v: &Vlr) -> [u8; VLR_HEADER] {
    let mut h = [0u8; VLR_HEADER];
    h[2..18].copy_from_slice(&padded::<16>(&v.user_id));
    h[18..20].copy_from_slice(&v.record_id.to_le_bytes());
    h[20..22].copy_from_slice(&(v.data.len() as u16).to_le_bytes());
    h[22..54].copy_from_slice(&padded::<32>(&v.description));
    h
}

fn evlr_header(v: &Vlr) -> [u8; 60] {
    let mut h = [0u8; 60];
    h[2..18].copy_from_slice(&padded::<16>(&v.user_id));
    h[18..20].copy_from_slice(&v.record_id.to_le_bytes());
    h[20..28].copy_from_slice(&(v.data.len() as u64).to_le_bytes());
    h[28..60].copy_from_slice(&padded::<32>(&v.description));
    h
}

/// Today as (day of year starting at 1, year), in UTC.
fn creation_date() -> (u16, u16) {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let mut days = secs / 86_400;
    let mut year = 1970u64;
    loop {
        let leap =
            (year.is_multiple_of(4) && !year.is_multiple_of(100)) || year.is_multiple_of(400);
        let len = if leap { 366 } else { 365 };
        if days < len {
            return ((days + 1) as u16, year as u16);
        }
        days -= len;
        year += 1;
    }
}
