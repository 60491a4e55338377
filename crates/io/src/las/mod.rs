//! LAS 1.0–1.4 and LAZ/COPC reading: our own header parser and record decoder; LAZ chunks are
//! decompressed by the `laz` crate, several at a time in parallel.

mod header;
mod laz;
pub(crate) mod record;

pub use header::{parse_header, LasError, LasHeader, MAX_KEPT_EVLR};
pub use record::PointFormat;

use crate::{IoError, PointReader};
use header::FileSource;
use pointlet_core::{PointBatch, SourceMeta};
use record::Decoder;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Raw bytes read per batch at most, whatever the caller asks: bounds memory per batch.
const MAX_BATCH_BYTES: usize = 64 << 20;

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

/// Uncompressed LAS: one `read_exact` per batch into a reused buffer, decoded column by column.
struct LasReader {
    path: PathBuf,
    meta: SourceMeta,
    file: File,
    decoder: Decoder,
    total: u64,
    read: u64,
    buf: Vec<u8>,
}

impl LasReader {
    fn new(path: &Path, mut file: File, h: &LasHeader, meta: SourceMeta) -> Result<Self, IoError> {
        file.seek(SeekFrom::Start(u64::from(h.offset_to_point_data)))
            .map_err(|e| IoError::io(path, e))?;
        Ok(LasReader {
            path: path.to_path_buf(),
            meta,
            file,
            decoder: decoder(path, h)?,
            total: h.point_count,
            read: 0,
            buf: Vec::new(),
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
        if let Err(e) = self.file.read_exact(&mut self.buf) {
            return Err(if e.kind() == std::io::ErrorKind::UnexpectedEof {
                IoError::invalid(
                    &self.path,
                    format!(
                        "the file ends early: point {} of the {} the header claims is missing",
                        self.read + 1,
                        self.total
                    ),
                )
            } else {
                IoError::io(&self.path, e)
            });
        }
        let mut batch = PointBatch::with_capacity(self.decoder.layout(), n);
        self.decoder.decode(&self.buf, &mut batch);
        self.read += n as u64;
        Ok(Some(batch))
    }
}
