//! LAS 1.0–1.4 and LAZ/COPC reading: our own header parser and record decoder; LAZ chunks are
//! decompressed several at a time in parallel, by our own decoder for the common item sets of
//! formats 0–3 and by the `laz` crate for the others.

mod header;
mod laz;
mod lazcodec;
pub(crate) mod record;

pub use header::{parse_header, LasError, LasHeader, MAX_KEPT_EVLR};
#[doc(hidden)]
pub use lazcodec::raw;
pub use record::PointFormat;

use crate::{IoError, PointReader};
use header::FileSource;
use pointlet_core::rows::RowLayout;
use pointlet_core::{PartError, PartedSource, PointBatch, Quantization, SourceMeta};
use record::Decoder;
use std::fs::File;
use std::path::{Path, PathBuf};

/// Raw bytes read per batch at most, whatever the caller asks: bounds memory per batch.
const MAX_BATCH_BYTES: usize = 64 << 20;
/// Points per part of an uncompressed file: a decoded part stays within a core's cache.
const PART_POINTS: u64 = 32_768;
/// Raw bytes per part at most, for files with very long records.
const MAX_PART_BYTES: u64 = 4 << 20;

/// Reads exactly `buf.len()` bytes at `offset` without using the file's cursor, so threads can
/// share one `File` and parts never move the sequential reader.
#[cfg(unix)]
fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(windows)]
fn read_exact_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_read(buf, offset) {
            Ok(0) => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "file ends before the requested range",
                ))
            }
            Ok(n) => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

pub(crate) fn las_error(path: &Path, e: LasError) -> IoError {
    match e {
        LasError::Io(source) => IoError::io(path, source),
        LasError::NotLas(m) | LasError::Invalid(m) => IoError::invalid(path, m),
        LasError::Unsupported(m) => IoError::unsupported(path, m),
        LasError::NoPoints(m) => IoError::no_points(path, m),
    }
}

/// Opens a LAS, LAZ or COPC file: validates the header, VLRs, EVLRs (and the LAZ chunk table).
pub fn open(path: &Path) -> Result<Box<dyn PointReader>, IoError> {
    let mut file = File::open(path).map_err(|e| IoError::io(path, e))?;
    let len = file.metadata().map_err(|e| IoError::io(path, e))?.len();
    let header = header::parse(&mut FileSource {
        file: &mut file,
        len,
    })
    .map_err(|e| las_error(path, e))?;
    let meta = source_meta(&header);
    if header.compressed {
        Ok(Box::new(laz::LazReader::new(path, file, header, meta)?))
    } else {
        Ok(Box::new(LasReader::new(path, file, &header, meta)?))
    }
}

fn source_meta(h: &LasHeader) -> SourceMeta {
    let format = PointFormat::new(h.point_format);
    SourceMeta {
        format: h.format_name(),
        point_count: h.point_count,
        bounds: h.bounds,
        quantization: Some(h.quantization),
        layout: format
            .map(|f| f.layout(h.extra_bytes()))
            .unwrap_or_default(),
        las_point_format: Some(h.point_format),
        vlrs: h.kept_vlrs.clone(),
        las: Some(h.fields.clone()),
    }
}

fn decoder(path: &Path, h: &LasHeader) -> Result<Decoder, IoError> {
    let format = PointFormat::new(h.point_format).ok_or_else(|| {
        IoError::unsupported(path, format!("unknown point format {}", h.point_format))
    })?;
    Ok(Decoder::new(
        format,
        usize::from(h.point_record_length),
        h.quantization,
    ))
}

/// Points per batch: what the caller asks, within what is left and [`MAX_BATCH_BYTES`].
fn batch_points(max: usize, remaining: u64, record_len: usize) -> usize {
    let cap = (MAX_BATCH_BYTES / record_len.max(1)).max(1);
    max.min(cap)
        .min(usize::try_from(remaining).unwrap_or(usize::MAX))
}

/// Uncompressed LAS: one positioned read per batch into a reused buffer, decoded column by
/// column; parts are fixed ranges of records.
struct LasReader {
    path: PathBuf,
    meta: SourceMeta,
    file: File,
    decoder: Decoder,
    /// Byte where the first record starts.
    data_start: u64,
    total: u64,
    read: u64,
    buf: Vec<u8>,
    /// Points of each part; every part but the last holds `part_sizes[0]`.
    part_sizes: Vec<u64>,
}

impl LasReader {
    fn new(path: &Path, file: File, h: &LasHeader, meta: SourceMeta) -> Result<Self, IoError> {
        let decoder = decoder(path, h)?;
        let len = decoder.record_len() as u64;
        let per_part = (MAX_PART_BYTES / len.max(1)).clamp(1, PART_POINTS);
        // The header parser checked that the file holds every record, which bounds this list.
        let part_sizes = (0..h.point_count.div_ceil(per_part))
            .map(|k| per_part.min(h.point_count - k * per_part))
            .collect();
        Ok(LasReader {
            path: path.to_path_buf(),
            meta,
            file,
            decoder,
            data_start: u64::from(h.offset_to_point_data),
            total: h.point_count,
            read: 0,
            buf: Vec::new(),
            part_sizes,
        })
    }

    /// Reads the records of points `first..first + buf.len() / record_len` into `buf`; a file
    /// that ends before them is an error naming the first missing point and its byte.
    fn read_records(&self, first: u64, buf: &mut [u8]) -> Result<(), IoError> {
        let len = self.decoder.record_len() as u64;
        let at = self.data_start + first * len;
        read_exact_at(&self.file, buf, at).map_err(|e| {
            if e.kind() != std::io::ErrorKind::UnexpectedEof {
                return IoError::io(&self.path, e);
            }
            // The file may have shrunk since it was opened: find the first record cut off.
            let end = self.file.metadata().map_or(at, |m| m.len());
            let whole = end.saturating_sub(self.data_start) / len;
            let last = first + (buf.len() as u64 / len).max(1) - 1;
            let missing = whole.clamp(first, last);
            IoError::invalid(
                &self.path,
                format!(
                    "the file ends early: point {} of the {} the header claims is missing (its record would start at byte {})",
                    missing + 1,
                    self.total,
                    self.data_start + missing * len
                ),
            )
        })
    }
}

impl PointReader for LasReader {
    fn path(&self) -> &Path {
        &self.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
        let len = self.decoder.record_len();
        if self.read == self.total {
            return Ok(None);
        }
        let n = batch_points(max, self.total - self.read, len);
        if n == 0 {
            return Ok(Some(PointBatch::new(self.decoder.layout())));
        }
        self.buf.resize(n * len, 0);
        let mut buf = std::mem::take(&mut self.buf);
        let read = self.read_records(self.read, &mut buf);
        self.buf = buf;
        read?;
        let mut batch = PointBatch::with_capacity(self.decoder.layout(), n);
        self.decoder.decode(&self.buf, &mut batch);
        self.read += n as u64;
        Ok(Some(batch))
    }

    fn parted(&self) -> Option<&dyn PartedSource> {
        Some(self)
    }
}

impl PartedSource for LasReader {
    fn part_sizes(&self) -> &[u64] {
        &self.part_sizes
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
    ) -> Result<(), PartError> {
        self.read_part(i, scratch)?;
        out.clear(self.decoder.layout());
        self.decoder.decode(scratch, out);
        Ok(())
    }

    fn decode_part_rows(
        &self,
        i: usize,
        q: &Quantization,
        row: &RowLayout,
        rows: &mut [u8],
        scratch: &mut Vec<u8>,
        done: &mut dyn FnMut(usize, &[u8]),
    ) -> Result<bool, PartError> {
        if !self.decoder.fits_rows(q, row) {
            return Ok(false);
        }
        self.read_part(i, scratch)?;
        self.decoder
            .decode_rows_by_block(scratch, row, rows, done)
            .map_err(|e| IoError::invalid(&self.path, format!("part {i}: {e}")))?;
        Ok(true)
    }
}

impl LasReader {
    /// Reads the records of part `i` into `scratch`.
    fn read_part(&self, i: usize, scratch: &mut Vec<u8>) -> Result<(), PartError> {
        let (Some(&first_size), Some(&points)) = (self.part_sizes.first(), self.part_sizes.get(i))
        else {
            return Err(Box::new(IoError::invalid(
                &self.path,
                format!(
                    "there is no part {i}: the file has {} parts",
                    self.part_sizes.len()
                ),
            )));
        };
        let len = self.decoder.record_len();
        // Part sizes fit in memory: they are bounded by PART_POINTS and MAX_PART_BYTES.
        scratch.resize(points as usize * len, 0);
        self.read_records(i as u64 * first_size, scratch)?;
        Ok(())
    }
}
