//! The validating reader: positioned reads only, so one `Store` serves many threads. Its bytes
//! come from a [`ByteSource`]: a local file, or a remote object over HTTP(S) or S3.

use crate::emit::position_bounds;
use crate::format::{
    self, array, PointletEntry, Preamble, StoreHeader, StreamInfo, StreamKind, PREAMBLE_LEN,
    TABLE_ENTRY_LEN,
};
use crate::source::{is_remote, ByteSource, LocalFile, SourceError};
use crate::StoreError;
use pointlet_core::{PointBatch, WAVEFORM_BYTES};
use rayon::prelude::*;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Bytes read at once by [`Store::verify`].
const VERIFY_CHUNK: u64 = 8 << 20;

/// An open store.
#[derive(Debug)]
pub struct Store {
    path: PathBuf,
    source: Box<dyn ByteSource>,
    header: StoreHeader,
    pointlets: Vec<PointletEntry>,
    /// CRC32 of pointlet i's bytes of stream s at `i * streams + s`.
    checksums: Vec<u32>,
    /// Byte ranges that hold only padding (zeros).
    padding: Vec<Range<u64>>,
}

impl Store {
    /// Opens a store and checks its structure: magic, version, length, section layout, the
    /// header, table and checksum-table CRCs, the header's schema and the pointlet table.
    /// Point data is checked by [`read_pointlet`](Self::read_pointlet) and [`verify`](Self::verify).
    ///
    /// `path` may also be an `http://`, `https://` or `s3://` address (see remote.rs).
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let opened: Result<Box<dyn ByteSource>, SourceError> = if is_remote(path) {
            open_remote(path)
        } else {
            LocalFile::open(path).map(|f| Box::new(f) as Box<dyn ByteSource>)
        };
        let source = opened.map_err(|cause| match cause {
            SourceError::Io(e) => StoreError::io(path, "opening the store", e),
            cause => StoreError::Source {
                path: path.to_path_buf(),
                what: "opening the store".into(),
                cause,
            },
        })?;
        Self::from_source(path, source)
    }

    /// Opens the store whose bytes `source` holds; `path` names it in messages.
    pub fn from_source(path: &Path, source: Box<dyn ByteSource>) -> Result<Store, StoreError> {
        let file = &*source;
        let len = source.size();
        let bad = |m: String| StoreError::damaged(path, m);
        if len < PREAMBLE_LEN {
            return Err(bad(format!(
                "the file has {len} bytes, fewer than the {PREAMBLE_LEN}-byte preamble (truncated?)"
            )));
        }
        let mut pre = [0u8; PREAMBLE_LEN as usize];
        read_at(file, path, &mut pre, 0, "reading the preamble")?;
        let pre = Preamble::decode(&pre).map_err(bad)?;
        if pre.file_len != len {
            return Err(bad(format!(
                "the preamble says the file has {} bytes but it has {len} (truncated or appended to)",
                pre.file_len
            )));
        }
        let h = pre.header;
        if h.offset != PREAMBLE_LEN
            || h.len == 0
            || h.len > format::MAX_HEADER_LEN
            || h.len > len - PREAMBLE_LEN
        {
            return Err(bad(format!(
                "the header section ({} bytes at {}) is out of bounds",
                h.len, h.offset
            )));
        }
        let mut header_bytes = vec![0u8; h.len as usize];
        read_at(
            file,
            path,
            &mut header_bytes,
            h.offset,
            "reading the header",
        )?;
        if crc32fast::hash(&header_bytes) != pre.header_crc {
            return Err(bad("header checksum mismatch".into()));
        }
        let header = format::decode_header(&header_bytes, pre.version).map_err(bad)?;
        drop(header_bytes);
        let plan = format::plan(h.len, header.points, header.pointlets, &header.layout)
            .ok_or_else(|| bad("the header's sizes overflow 64 bits".into()))?;
        if plan.file_len != len {
            return Err(bad(format!(
                "{} points need a file of {} bytes, the file has {len}",
                header.points, plan.file_len
            )));
        }
        let sections = [
            ("pointlet table", pre.table, plan.table),
            ("checksum table", pre.checksums, plan.checksums),
        ];
        for (name, got, want) in sections {
            if got != want {
                return Err(bad(format!(
                    "the {name} is at {} ({} bytes) where the layout puts it at {} ({} bytes)",
                    got.offset, got.len, want.offset, want.len
                )));
            }
        }
        if pre.data_offset != plan.data_offset {
            return Err(bad(format!(
                "the streams start at {} where the layout puts them at {}",
                pre.data_offset, plan.data_offset
            )));
        }
        for (got, want) in header.streams.iter().zip(&plan.streams) {
            if got != want {
                return Err(bad(format!(
                    "the {} stream is at {} ({} bytes) where the layout puts it at {} ({} bytes)",
                    got.kind.name(),
                    got.offset,
                    got.length,
                    want.offset,
                    want.length
                )));
            }
        }
        // The plan lies within the (real) file length, so these allocations are bounded by it.
        let mut table = vec![0u8; plan.table.len as usize];
        read_at(
            file,
            path,
            &mut table,
            plan.table.offset,
            "reading the pointlet table",
        )?;
        if crc32fast::hash(&table) != pre.table_crc {
            return Err(bad("pointlet table checksum mismatch".into()));
        }
        let pointlets = decode_table(&table, &header).map_err(bad)?;
        drop(table);
        let mut checks = vec![0u8; plan.checksums.len as usize];
        read_at(
            file,
            path,
            &mut checks,
            plan.checksums.offset,
            "reading the checksum table",
        )?;
        if crc32fast::hash(&checks) != pre.checksums_crc {
            return Err(bad("checksum table checksum mismatch".into()));
        }
        let checksums = checks
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(array(c)))
            .collect();
        let mut padding = vec![
            plan.header.end()..plan.table.offset,
            plan.checksums.end()..plan.data_offset,
        ];
        for w in plan.streams.windows(2) {
            padding.push(w[0].offset + w[0].length..w[1].offset);
        }
        padding.retain(|r| !r.is_empty());
        Ok(Store {
            path: path.to_path_buf(),
            source,
            header,
            pointlets,
            checksums,
            padding,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn header(&self) -> &StoreHeader {
        &self.header
    }

    pub fn pointlets(&self) -> &[PointletEntry] {
        &self.pointlets
    }

    fn entry(&self, i: usize) -> Result<&PointletEntry, StoreError> {
        self.pointlets.get(i).ok_or_else(|| {
            StoreError::request(
                &self.path,
                format!(
                    "pointlet {i} does not exist (the store has {})",
                    self.pointlets.len()
                ),
            )
        })
    }

    /// Pointlet `i`'s entry, with `range` checked to lie within its points.
    fn entry_with(&self, i: usize, range: &Range<u32>) -> Result<&PointletEntry, StoreError> {
        let e = self.entry(i)?;
        if range.start > range.end || range.end > e.count {
            return Err(StoreError::request(
                &self.path,
                format!(
                    "points {range:?} are outside pointlet {i} of {} points",
                    e.count
                ),
            ));
        }
        Ok(e)
    }

    /// The `kind` stream, an error when the store has none.
    fn stream_of(&self, kind: StreamKind) -> Result<&StreamInfo, StoreError> {
        self.header.stream(kind).ok_or_else(|| {
            StoreError::request(
                &self.path,
                format!("the store has no {} stream", kind.name()),
            )
        })
    }

    /// The raw bytes of points `range` of pointlet `i` in each stream of `kinds`, read
    /// together: a remote store fetches them with the requests in flight at once.
    pub fn read_streams_raw(
        &self,
        i: usize,
        range: Range<u32>,
        kinds: &[StreamKind],
    ) -> Result<Vec<Vec<u8>>, StoreError> {
        let mut all = self.read_streams_raw_many(&[(i, range)], kinds)?;
        Ok(all.pop().unwrap_or_default())
    }

    /// [`read_streams_raw`](Self::read_streams_raw) for many (pointlet, range) requests at
    /// once, as one [`ByteSource::read_ranges`]: a remote store joins neighbouring ranges and
    /// keeps several requests in flight, so a batch costs about one round trip, not one each.
    /// Result k holds request k's streams in the order of `kinds`.
    pub fn read_streams_raw_many(
        &self,
        requests: &[(usize, Range<u32>)],
        kinds: &[StreamKind],
    ) -> Result<Vec<Vec<Vec<u8>>>, StoreError> {
        let streams = kinds
            .iter()
            .map(|k| {
                self.stream_of(*k)
                    .map(|s| (s.offset, s.bytes_per_point as u64))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut offsets = Vec::with_capacity(requests.len() * kinds.len());
        let mut out = Vec::with_capacity(requests.len());
        for (i, range) in requests {
            let e = *self.entry_with(*i, range)?;
            let n = (range.end - range.start) as u64;
            let mut bufs = Vec::with_capacity(kinds.len());
            for (offset, bpp) in &streams {
                offsets.push(offset + (e.first + range.start as u64) * bpp);
                bufs.push(vec![0u8; (n * bpp) as usize]);
            }
            out.push(bufs);
        }
        let mut reads: Vec<(u64, &mut [u8])> = offsets
            .into_iter()
            .zip(out.iter_mut().flatten())
            .map(|(o, b)| (o, b.as_mut_slice()))
            .collect();
        self.source
            .read_ranges(&mut reads)
            .map_err(|e| source_error(&self.path, "reading streams", e))?;
        Ok(out)
    }

    /// Appends the raw bytes of points `range` of pointlet `i`'s `kind` stream to `out`
    /// (one positioned read). Bounds are checked; checksums are not (a range is not the unit
    /// they cover): use [`read_pointlet`](Self::read_pointlet) or [`verify`](Self::verify).
    pub fn read_stream_raw(
        &self,
        kind: StreamKind,
        i: usize,
        range: Range<u32>,
        out: &mut Vec<u8>,
    ) -> Result<(), StoreError> {
        let e = self.entry_with(i, &range)?;
        let s = self.stream_of(kind)?;
        let bpp = s.bytes_per_point as u64;
        let offset = s.offset + (e.first + range.start as u64) * bpp;
        let bytes = (range.end - range.start) as usize * bpp as usize;
        let old = out.len();
        out.resize(old + bytes, 0);
        let r = read_at(
            &*self.source,
            &self.path,
            &mut out[old..],
            offset,
            "reading a stream",
        );
        if r.is_err() {
            out.truncate(old);
        }
        r
    }

    fn read_typed<T, const B: usize>(
        &self,
        kind: StreamKind,
        i: usize,
        range: Range<u32>,
        decode: impl Fn([u8; B]) -> T,
    ) -> Result<Vec<T>, StoreError> {
        let mut raw = Vec::new();
        self.read_stream_raw(kind, i, range, &mut raw)?;
        Ok(raw.chunks_exact(B).map(|c| decode(array(c))).collect())
    }

    /// Quantized positions of points `range` of pointlet `i` (bounds-checked, not checksummed).
    pub fn read_positions(&self, i: usize, range: Range<u32>) -> Result<Vec<[i32; 3]>, StoreError> {
        self.read_typed(StreamKind::Position, i, range, decode_position)
    }

    /// Colours of points `range` of pointlet `i`; an error when the store has no colours.
    pub fn read_rgb(&self, i: usize, range: Range<u32>) -> Result<Vec<[u16; 3]>, StoreError> {
        self.read_typed(StreamKind::Rgb, i, range, decode_rgb)
    }

    pub fn read_intensity(&self, i: usize, range: Range<u32>) -> Result<Vec<u16>, StoreError> {
        self.read_typed(StreamKind::Intensity, i, range, u16::from_le_bytes)
    }

    pub fn read_classification(&self, i: usize, range: Range<u32>) -> Result<Vec<u8>, StoreError> {
        self.read_typed(StreamKind::Classification, i, range, |b: [u8; 1]| b[0])
    }

    /// Every attribute of pointlet `i` in stored (shuffled) order, positions dequantized.
    /// Each stream's bytes are checked against their CRC32.
    pub fn read_pointlet(&self, i: usize) -> Result<PointBatch, StoreError> {
        self.read_pointlets(i..i + 1)
    }

    /// Every attribute of pointlets `range` (consecutive in every stream), one positioned
    /// read per stream; each pointlet's bytes are checked against its CRC32.
    pub fn read_pointlets(&self, range: Range<usize>) -> Result<PointBatch, StoreError> {
        self.read_pointlet_streams(range, &StreamKind::ALL)
    }

    /// Like [`read_pointlets`](Self::read_pointlets), reading only the streams `kinds` names
    /// (positions always); the other columns of the batch stay empty.
    pub fn read_pointlet_streams(
        &self,
        range: Range<usize>,
        kinds: &[StreamKind],
    ) -> Result<PointBatch, StoreError> {
        let mut b = PointBatch::default();
        self.read_pointlet_streams_into(range, kinds, &mut b, &mut Vec::new())?;
        Ok(b)
    }

    /// [`read_pointlet_streams`](Self::read_pointlet_streams) into `b`, whose columns are
    /// cleared and refilled; `raw` holds a stream's bytes. Loaders reuse both: fresh buffers
    /// for every part cost page faults that weigh more than the decoding.
    pub fn read_pointlet_streams_into(
        &self,
        range: Range<usize>,
        kinds: &[StreamKind],
        b: &mut PointBatch,
        raw: &mut Vec<u8>,
    ) -> Result<(), StoreError> {
        self.read_streams_into(range, kinds, true, b, raw)
    }

    /// Like [`read_pointlet_streams_into`](Self::read_pointlet_streams_into) without the
    /// positions: only the streams `kinds` names are read, every other column stays empty
    /// (the batch's `len()` is 0). For readers that take the positions as stored
    /// ([`read_stream_into`](Self::read_stream_into)).
    pub fn read_pointlet_attributes_into(
        &self,
        range: Range<usize>,
        kinds: &[StreamKind],
        b: &mut PointBatch,
        raw: &mut Vec<u8>,
    ) -> Result<(), StoreError> {
        self.read_streams_into(range, kinds, false, b, raw)
    }

    fn read_streams_into(
        &self,
        range: Range<usize>,
        kinds: &[StreamKind],
        positions: bool,
        b: &mut PointBatch,
        raw: &mut Vec<u8>,
    ) -> Result<(), StoreError> {
        b.clear(self.header.layout);
        for info in &self.header.streams {
            let wanted = if info.kind == StreamKind::Position {
                positions
            } else {
                kinds.contains(&info.kind)
            };
            if !wanted {
                continue;
            }
            let bytes = self.read_stream_into(range.clone(), info.kind, raw)?;
            let q = self.header.quantization;
            let raw = &raw[..bytes];
            match info.kind {
                StreamKind::Position => b.xyz.extend(
                    raw.chunks_exact(12)
                        .map(|c| q.dequantize(decode_position(array(c)))),
                ),
                StreamKind::Intensity => decode_into(raw, &mut b.intensity, u16::from_le_bytes),
                StreamKind::Returns => b.returns.extend_from_slice(raw),
                StreamKind::Flags => b.flags.extend_from_slice(raw),
                StreamKind::Classification => b.classification.extend_from_slice(raw),
                StreamKind::ScanAngle => decode_into(raw, &mut b.scan_angle, f32::from_le_bytes),
                StreamKind::UserData => b.user_data.extend_from_slice(raw),
                StreamKind::PointSourceId => {
                    decode_into(raw, &mut b.point_source_id, u16::from_le_bytes)
                }
                StreamKind::GpsTime => decode_into(raw, &mut b.gps_time, f64::from_le_bytes),
                StreamKind::Rgb => decode_into(raw, &mut b.rgb, decode_rgb),
                StreamKind::Nir => decode_into(raw, &mut b.nir, u16::from_le_bytes),
                StreamKind::Waveform => {
                    decode_into::<[u8; WAVEFORM_BYTES], WAVEFORM_BYTES>(raw, &mut b.waveform, |w| w)
                }
                StreamKind::ExtraBytes => b.extra_bytes.extend_from_slice(raw),
            }
        }
        Ok(())
    }

    /// The stored bytes of stream `kind` for pointlets `range` (consecutive), one positioned
    /// read, each pointlet's bytes checked against its CRC32: they fill `raw[..n]`, n
    /// returned (`raw` is grown, never shrunk: zero-filling it again for every part costs a
    /// pass). Positions are 12 bytes a point, x, y, z as little-endian i32 of the header's
    /// quantization (docs/FORMAT.md).
    pub fn read_stream_into(
        &self,
        range: Range<usize>,
        kind: StreamKind,
        raw: &mut Vec<u8>,
    ) -> Result<usize, StoreError> {
        if range.is_empty() {
            return Err(StoreError::request(
                &self.path,
                format!("no pointlets in {range:?}"),
            ));
        }
        let (first, last) = (*self.entry(range.start)?, *self.entry(range.end - 1)?);
        let n = (last.first + last.count as u64 - first.first) as usize;
        let streams = self.header.streams.len();
        let Some((s, info)) = self
            .header
            .streams
            .iter()
            .enumerate()
            .find(|(_, info)| info.kind == kind)
        else {
            return Err(StoreError::request(
                &self.path,
                format!("the store has no {} stream", kind.name()),
            ));
        };
        let bpp = info.bytes_per_point as usize;
        if raw.len() < n * bpp {
            raw.resize(n * bpp, 0);
        }
        let raw = &mut raw[..n * bpp];
        read_at(
            &*self.source,
            &self.path,
            raw,
            info.offset + first.first * bpp as u64,
            "reading a stream",
        )?;
        let mut at = 0;
        for i in range {
            let bytes = self.pointlets[i].count as usize * bpp;
            let stored = self.checksums[i * streams + s];
            let actual = crc32fast::hash(&raw[at..at + bytes]);
            if stored != actual {
                return Err(StoreError::damaged(
                    &self.path,
                    format!(
                        "pointlet {i}: the {} stream's checksum is {actual:08x}, the table says {stored:08x}",
                        info.kind.name()
                    ),
                ));
            }
            at += bytes;
        }
        Ok(n * bpp)
    }

    /// Reads the whole file: every stream checksum of every pointlet, every pointlet's AABB
    /// against its positions, and that all padding is zero. With the checks of `open`, every
    /// byte of the file is covered.
    pub fn verify(&self) -> Result<(), StoreError> {
        let streams = self.header.streams.len();
        // Tasks of whole pointlets up to VERIFY_CHUNK bytes, per stream.
        let mut tasks = Vec::new();
        for (s, info) in self.header.streams.iter().enumerate() {
            let per = (VERIFY_CHUNK / (self.header.pointlet_size * info.bytes_per_point as u64))
                .max(1) as usize;
            let mut p = 0;
            while p < self.pointlets.len() {
                let end = (p + per).min(self.pointlets.len());
                tasks.push((s, p..end));
                p = end;
            }
        }
        let results: Vec<Result<(), StoreError>> = tasks
            .into_par_iter()
            .map(|(s, range)| self.verify_task(s, streams, range))
            .collect();
        results.into_iter().collect::<Result<(), StoreError>>()?;
        for r in &self.padding {
            let mut buf = vec![0u8; (r.end - r.start) as usize];
            read_at(
                &*self.source,
                &self.path,
                &mut buf,
                r.start,
                "reading padding",
            )?;
            if buf.iter().any(|b| *b != 0) {
                return Err(StoreError::damaged(
                    &self.path,
                    format!("padding bytes {r:?} are not zero"),
                ));
            }
        }
        Ok(())
    }

    fn verify_task(
        &self,
        s: usize,
        streams: usize,
        pointlets: Range<usize>,
    ) -> Result<(), StoreError> {
        let info = &self.header.streams[s];
        let bpp = info.bytes_per_point as usize;
        let first = &self.pointlets[pointlets.start];
        let last = &self.pointlets[pointlets.end - 1];
        let points = (last.first + last.count as u64 - first.first) as usize;
        let mut buf = vec![0u8; points * bpp];
        read_at(
            &*self.source,
            &self.path,
            &mut buf,
            info.offset + first.first * bpp as u64,
            "verifying a stream",
        )?;
        let mut at = 0;
        for i in pointlets {
            let e = &self.pointlets[i];
            let bytes = &buf[at..at + e.count as usize * bpp];
            at += bytes.len();
            let actual = crc32fast::hash(bytes);
            let stored = self.checksums[i * streams + s];
            if actual != stored {
                return Err(StoreError::damaged(
                    &self.path,
                    format!(
                        "pointlet {i}: the {} stream's checksum is {actual:08x}, the table says {stored:08x}",
                        info.kind.name()
                    ),
                ));
            }
            if info.kind == StreamKind::Position
                && position_bounds(bytes, &self.header.quantization) != e.aabb
            {
                return Err(StoreError::damaged(
                    &self.path,
                    format!("pointlet {i}: the AABB in the table is not that of its points"),
                ));
            }
        }
        Ok(())
    }
}

fn read_at(
    source: &dyn ByteSource,
    path: &Path,
    buf: &mut [u8],
    offset: u64,
    what: &str,
) -> Result<(), StoreError> {
    source
        .read_exact_at(buf, offset)
        .map_err(|e| source_error(path, what, e))
}

fn source_error(path: &Path, what: &str, cause: SourceError) -> StoreError {
    match cause {
        SourceError::Truncated => {
            StoreError::damaged(path, format!("{what}: the file ends early (truncated?)"))
        }
        SourceError::Io(e) => StoreError::io(path, what, e),
        cause => StoreError::Source {
            path: path.to_path_buf(),
            what: what.into(),
            cause,
        },
    }
}

#[cfg(feature = "remote")]
fn open_remote(path: &Path) -> Result<Box<dyn ByteSource>, SourceError> {
    crate::remote::RemoteObject::open(&path.to_string_lossy())
        .map(|r| Box::new(r) as Box<dyn ByteSource>)
}

/// Built without the `remote` feature (the browser fetches byte ranges itself).
#[cfg(not(feature = "remote"))]
fn open_remote(_path: &Path) -> Result<Box<dyn ByteSource>, SourceError> {
    Err(SourceError::Remote(
        "this build reads no http(s):// or s3:// stores (feature `remote` is off)".into(),
    ))
}

/// Quantized positions from the raw bytes of a position stream (12 bytes per point).
pub fn decode_positions(raw: &[u8]) -> Vec<[i32; 3]> {
    raw.chunks_exact(12)
        .map(|c| decode_position(array(c)))
        .collect()
}

fn decode_position(b: [u8; 12]) -> [i32; 3] {
    [
        i32::from_le_bytes(array(&b[0..4])),
        i32::from_le_bytes(array(&b[4..8])),
        i32::from_le_bytes(array(&b[8..12])),
    ]
}

fn decode_rgb(b: [u8; 6]) -> [u16; 3] {
    [
        u16::from_le_bytes([b[0], b[1]]),
        u16::from_le_bytes([b[2], b[3]]),
        u16::from_le_bytes([b[4], b[5]]),
    ]
}

fn decode_into<T, const B: usize>(raw: &[u8], out: &mut Vec<T>, f: impl Fn([u8; B]) -> T) {
    out.extend(raw.chunks_exact(B).map(|c| f(array(c))));
}

/// Decodes and checks the pointlet table against the header.
fn decode_table(table: &[u8], h: &StoreHeader) -> Result<Vec<PointletEntry>, String> {
    let mut out = Vec::with_capacity(h.pointlets as usize);
    let mut next = 0u64;
    let mut union = pointlet_core::Aabb::EMPTY;
    let last = h.pointlets - 1;
    for (i, raw) in table.chunks_exact(TABLE_ENTRY_LEN as usize).enumerate() {
        let e = PointletEntry::decode(&array(raw))
            .ok_or_else(|| format!("pointlet {i}: reserved table bytes are not zero"))?;
        if e.first != next {
            return Err(format!(
                "pointlet {i} starts at point {} instead of {next}: pointlets must be contiguous",
                e.first
            ));
        }
        let expected = if i as u64 == last {
            h.points - next
        } else {
            h.pointlet_size
        };
        if e.count as u64 != expected {
            return Err(format!(
                "pointlet {i} holds {} points instead of {expected}",
                e.count
            ));
        }
        let b = &e.aabb;
        let finite = b.min.iter().chain(b.max.iter()).all(|v| v.is_finite());
        if !finite || b.is_empty() {
            return Err(format!(
                "pointlet {i} has a bad AABB {:?} to {:?}",
                b.min, b.max
            ));
        }
        union = union.union(b);
        next += e.count as u64;
        out.push(e);
    }
    if next != h.points {
        return Err(format!(
            "the pointlets hold {next} points, the header says {}",
            h.points
        ));
    }
    if union != h.bounds {
        return Err(format!(
            "the header bounds are not the union of the pointlet AABBs {:?} {:?}",
            union, h.bounds
        ));
    }
    Ok(out)
}
