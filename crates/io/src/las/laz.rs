//! LAZ and COPC (LAZ 1.4 with variable-size chunks): the chunk table is read and checked when
//! the file opens; reading then decompresses a group of chunks at a time, in parallel on
//! rayon's pool, and hands the records out batch by batch. As parts (see [`PartedSource`]),
//! each chunk is read and decompressed on its own, from any thread.
//!
//! Chunks of the point-wise compressor with the version 2 items of formats 0–3 (and extra
//! bytes) go through our own decoder ([`super::lazcodec`]), which reuses its models from
//! chunk to chunk and decodes about 1.4 times as fast on one core; every other item set
//! (version 1 items, wave packets, the layered items of formats 6–10) goes through the `laz`
//! crate. Which one is decided per file when it opens (`POINTLET_LAZ_DECODER=laz-crate`
//! forces the crate).
//!
//! Everything the `laz` crate would trust blindly is checked first: the LASzip items against
//! the point format, every chunk's range inside the file, point counts against the header, and
//! for layered chunks (formats 6–10) the point count and layer sizes each chunk begins with,
//! so a damaged file cannot make it allocate gigabytes. Damaged compressed bytes can still trip
//! the crate's decoders (assertions, arithmetic overflow); those panics are caught per chunk
//! and reported as errors (see [`guarded`]).

use super::header::LasHeader;
use super::lazcodec::{ChunkDecoder, Items};
use super::record::{Decoder, PointFormat};
use super::{batch_points, decoder, read_exact_at};
use crate::{IoError, PointReader};
use laz::laszip::{ChunkTable, ChunkTableEntry};
use laz::{LazItem, LazItemType, LazVlr};
use pointlet_core::rows::RowLayout;
use pointlet_core::{PartError, PartedSource, PointBatch, Quantization, SourceMeta};
use rayon::prelude::*;
use std::cell::Cell;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, Once};

/// Largest decompressed chunk accepted (real chunks hold 50 000–1 000 000 points).
const MAX_CHUNK_BYTES: u64 = 512 << 20;
/// Decompressed bytes per group of chunks, unless one chunk alone is larger.
const MAX_GROUP_BYTES: u64 = 96 << 20;
/// LASzip compressor types: point-wise chunked (formats 0–5) and layered chunked (6–10).
const POINTWISE_CHUNKED: u16 = 2;
const LAYERED_CHUNKED: u16 = 3;

#[derive(Clone, Copy, Debug)]
struct Chunk {
    /// Absolute file offset of the compressed bytes.
    offset: u64,
    bytes: u64,
    points: u64,
}

/// What decompressing any one chunk needs besides its bytes.
struct ChunkCodec {
    vlr: LazVlr,
    layered: bool,
    record_len: u64,
    /// Points the header claims, for error messages.
    total: u64,
    /// The item set when our own decoder handles it; otherwise the `laz` crate does.
    ours: Option<Items>,
}

/// Our decoders not in use, for the next chunk of any file with the same items: about one per
/// thread and item set, so reading many files allocates and initializes them only once.
static IDLE_DECODERS: Mutex<Vec<Box<ChunkDecoder>>> = Mutex::new(Vec::new());
/// Idle decoders kept at most (each takes a few hundred KiB).
const MAX_IDLE_DECODERS: usize = 64;

pub(super) struct LazReader {
    path: PathBuf,
    meta: SourceMeta,
    file: File,
    codec: ChunkCodec,
    decoder: Decoder,
    chunks: Vec<Chunk>,
    /// Points of each chunk, the parts.
    part_sizes: Vec<u64>,
    next_chunk: usize,
    compressed: Vec<u8>,
    decompressed: Vec<u8>,
    /// Bytes of `decompressed` already handed out.
    consumed: usize,
    total: u64,
    read: u64,
}

impl LazReader {
    pub fn new(
        path: &Path,
        mut file: File,
        h: LasHeader,
        meta: SourceMeta,
    ) -> Result<Self, IoError> {
        let bad = |m: String| IoError::invalid(path, m);
        let data = h.laszip.as_deref().ok_or_else(|| {
            bad("the point format is marked compressed but there is no LASzip VLR".into())
        })?;
        let vlr = LazVlr::from_buffer(data).map_err(|e| bad(format!("LASzip VLR: {e}")))?;
        let compressor = data.first_chunk::<2>().map(|b| u16::from_le_bytes(*b));
        let format = PointFormat::new(h.point_format).ok_or_else(|| {
            IoError::unsupported(path, format!("unknown point format {}", h.point_format))
        })?;
        check_items(&vlr, compressor, format, h.extra_bytes()).map_err(bad)?;
        let chunks = read_chunk_table(&mut file, &h, &vlr).map_err(|e| match e {
            TableError::Io(e) => IoError::io(path, e),
            TableError::Invalid(m) => bad(m),
        })?;
        Ok(LazReader {
            path: path.to_path_buf(),
            meta,
            file,
            codec: ChunkCodec {
                ours: Items::supported(vlr.items())
                    .filter(|i| i.record_len() == usize::from(h.point_record_length))
                    .filter(|_| !laz_crate_forced()),
                vlr,
                layered: format.extended,
                record_len: u64::from(h.point_record_length),
                total: h.point_count,
            },
            decoder: decoder(path, &h)?,
            part_sizes: chunks.iter().map(|c| c.points).collect(),
            chunks,
            next_chunk: 0,
            compressed: Vec::new(),
            decompressed: Vec::new(),
            consumed: 0,
            total: h.point_count,
            read: 0,
        })
    }

    /// Decompresses the next group of chunks (at least one, at least one per thread when
    /// there are enough, about `want` points) into `self.decompressed`.
    fn decompress_group(&mut self, want: u64) -> Result<(), IoError> {
        let len = self.decoder.record_len() as u64;
        let threads = rayon::current_num_threads();
        let first = self.next_chunk;
        let (mut end, mut points) = (first, 0u64);
        while let Some(c) = self.chunks.get(end) {
            let bytes = (points + c.points) * len;
            if end > first && bytes > MAX_GROUP_BYTES {
                break;
            }
            points += c.points;
            end += 1;
            if points >= want && end - first >= threads {
                break;
            }
        }
        let group = self.chunks.get(first..end).unwrap_or_default();
        let (Some(head), Some(tail)) = (group.first(), group.last()) else {
            return Ok(());
        };
        let range = head.offset..tail.offset + tail.bytes;
        self.compressed
            .resize((range.end - range.start) as usize, 0);
        read_exact_at(&self.file, &mut self.compressed, range.start)
            .map_err(|e| IoError::io(&self.path, e))?;
        self.decompressed.clear();
        self.decompressed.resize((points * len) as usize, 0);
        // One job per chunk: its compressed bytes, its share of the output.
        let mut jobs = Vec::with_capacity(group.len());
        let (mut src, mut dst) = (&self.compressed[..], &mut self.decompressed[..]);
        for (k, c) in group.iter().enumerate() {
            // The buffers were sized from these very chunks, so the splits always succeed.
            let (Some((cin, rest_in)), Some((cout, rest_out))) = (
                src.split_at_checked(c.bytes as usize),
                std::mem::take(&mut dst).split_at_mut_checked((c.points * len) as usize),
            ) else {
                return Err(IoError::invalid(
                    &self.path,
                    format!(
                        "LAZ chunk {} does not fit the buffers sized for it",
                        first + k
                    ),
                ));
            };
            (src, dst) = (rest_in, rest_out);
            jobs.push((first + k, *c, cin, cout));
        }
        let (codec, path) = (&self.codec, &self.path);
        let failed = jobs
            .into_par_iter()
            .map(|(index, c, cin, cout)| {
                codec
                    .decompress(path, index, c, cin, cout)
                    .map_err(|e| (index, e))
            })
            .filter_map(Result::err)
            .min_by_key(|(index, _)| *index);
        if let Some((_, e)) = failed {
            return Err(e);
        }
        self.consumed = 0;
        self.next_chunk = end;
        Ok(())
    }
}

impl PointReader for LazReader {
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
        if self.consumed >= self.decompressed.len() {
            self.decompress_group(n as u64)?;
        }
        let avail = (self.decompressed.len() - self.consumed) / len;
        let n = n.min(avail);
        if n == 0 {
            return Err(IoError::invalid(
                &self.path,
                format!(
                    "the LAZ chunks end after {} of the {} points the header claims",
                    self.read, self.total
                ),
            ));
        }
        let raw = self
            .decompressed
            .get(self.consumed..self.consumed + n * len)
            .unwrap_or_default();
        let mut batch = PointBatch::with_capacity(self.decoder.layout(), n);
        self.decoder.decode(raw, &mut batch);
        self.consumed += n * len;
        self.read += n as u64;
        Ok(Some(batch))
    }

    fn parted(&self) -> Option<&dyn PartedSource> {
        Some(self)
    }
}

impl PartedSource for LazReader {
    fn part_sizes(&self) -> &[u64] {
        &self.part_sizes
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
    ) -> Result<(), PartError> {
        let records = self.decompress_part(i, scratch)?;
        out.clear(self.decoder.layout());
        self.decoder.decode(records, out);
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
        let bad_rows = |e: String| IoError::invalid(&self.path, format!("LAZ chunk {i}: {e}"));
        let Some(items) = self.codec.ours else {
            let records = self.decompress_part(i, scratch)?;
            self.decoder
                .decode_rows_by_block(records, row, rows, done)
                .map_err(bad_rows)?;
            return Ok(true);
        };
        if let Some(&n) = self.part_sizes.get(i) {
            if n as usize * row.len != rows.len() {
                return Err(Box::new(bad_rows(format!(
                    "{} rows for its {n} points",
                    rows.len() / row.len.max(1)
                ))));
            }
        }
        // Our decoder hands over a block of records at a time: each becomes rows while it is
        // in the cache, and the rows go to `done` while they are.
        let (c, compressed, block) = self.read_chunk(i, scratch, ROW_BLOCK * items.record_len())?;
        let mut unfit = None;
        let decompressed = self.codec.decompress_ours(items, |d| {
            d.decompress_blocks(compressed, c.points as usize, block, |at, records| {
                let n = records.len() / items.record_len();
                let out = rows
                    .get_mut(at * row.len..(at + n) * row.len)
                    .ok_or_else(|| format!("too few rows for its {} points", c.points))
                    .and_then(|out| self.decoder.decode_rows(records, row, out).map(|()| out));
                match out {
                    Ok(out) => {
                        done(at, out);
                        Ok(())
                    }
                    Err(e) => {
                        unfit = Some(e);
                        Err("its rows do not fit".into())
                    }
                }
            })
        });
        if let Some(e) = unfit {
            return Err(Box::new(bad_rows(e)));
        }
        decompressed.map_err(|m| Box::new(self.codec.damaged(&self.path, i, c, m)))?;
        Ok(true)
    }
}

/// Records of a LAZ chunk decompressed, and rows made of them, at a time (70 KiB of both with
/// time and colour): they stay in the L2 cache until used.
const ROW_BLOCK: usize = 1024;

impl LazReader {
    /// Reads and decompresses chunk `i` in `scratch`; its records.
    fn decompress_part<'s>(
        &self,
        i: usize,
        scratch: &'s mut Vec<u8>,
    ) -> Result<&'s [u8], PartError> {
        let out_len = self
            .chunks
            .get(i)
            .map_or(0, |c| (c.points * self.codec.record_len) as usize);
        let (c, compressed, records) = self.read_chunk(i, scratch, out_len)?;
        self.codec
            .decompress(&self.path, i, c, compressed, records)?;
        Ok(records)
    }

    /// Reads chunk `i`'s compressed bytes into `scratch`, followed by `room` bytes more; the
    /// chunk, its bytes and the room.
    fn read_chunk<'s>(
        &self,
        i: usize,
        scratch: &'s mut Vec<u8>,
        room: usize,
    ) -> Result<(Chunk, &'s mut [u8], &'s mut [u8]), PartError> {
        let Some(&c) = self.chunks.get(i) else {
            return Err(Box::new(IoError::invalid(
                &self.path,
                format!(
                    "there is no LAZ chunk {i}: the file has {}",
                    self.chunks.len()
                ),
            )));
        };
        // The chunk's size was bounded when the chunk table was checked at open.
        let in_len = c.bytes as usize;
        scratch.resize(in_len + room, 0);
        let (compressed, room) = scratch.split_at_mut(in_len);
        read_exact_at(&self.file, compressed, c.offset).map_err(|e| {
            let why = if e.kind() == std::io::ErrorKind::UnexpectedEof {
                "the file ends inside it".to_string()
            } else {
                e.to_string()
            };
            IoError::invalid(
                &self.path,
                format!(
                    "LAZ chunk {i} ({} bytes at byte {}) cannot be read: {why}",
                    c.bytes, c.offset
                ),
            )
        })?;
        Ok((c, compressed, room))
    }
}

/// `POINTLET_LAZ_DECODER=laz-crate` sends every LAZ file through the `laz` crate: for
/// comparing the decoders on whole loads, and as a way out should ours ever misread a file.
fn laz_crate_forced() -> bool {
    std::env::var_os("POINTLET_LAZ_DECODER").is_some_and(|v| v == "laz-crate")
}

impl ChunkCodec {
    /// Decompresses chunk `index` (`c`, whose bytes are `compressed`) into `out`, exactly its
    /// records, with our decoder or (after checking what the `laz` crate would trust) the
    /// crate; an error, or a panic of the crate on damaged data, becomes an error naming the
    /// file, the chunk and its offset.
    fn decompress(
        &self,
        path: &Path,
        index: usize,
        c: Chunk,
        compressed: &[u8],
        out: &mut [u8],
    ) -> Result<(), IoError> {
        let decompressed = match self.ours {
            Some(items) => self.decompress_ours(items, |d| d.decompress(compressed, out)),
            None => self.decompress_laz_crate(c, compressed, out),
        };
        decompressed.map_err(|m| self.damaged(path, index, c, m))
    }

    /// The error for chunk `index` (`c`) that could not be decompressed, `m` saying why.
    fn damaged(&self, path: &Path, index: usize, c: Chunk, m: String) -> IoError {
        IoError::invalid(
            path,
            format!(
                "LAZ chunk {index} (at byte {}) cannot be decompressed ({m}): the file is damaged or holds fewer points than its header claims ({})",
                c.offset, self.total
            ),
        )
    }

    /// Decompresses a chunk with the `laz` crate, its panics caught (see [`guarded`]).
    fn decompress_laz_crate(
        &self,
        c: Chunk,
        compressed: &[u8],
        out: &mut [u8],
    ) -> Result<(), String> {
        #[cfg(test)]
        LAZ_CRATE_CHUNKS.with(|n| n.set(n.get() + 1));
        if self.layered {
            check_layered_chunk(compressed, self.vlr.items(), self.record_len, c.points)?;
        }
        let entry = [ChunkTableEntry {
            point_count: c.points,
            byte_count: c.bytes,
        }];
        guarded(|| laz::par_decompress(compressed, out, &self.vlr, &entry))?
            .map_err(|e| e.to_string())
    }

    /// Runs `decompress` with one of our decoders for `items`, reusing an idle one when there
    /// is one.
    fn decompress_ours(
        &self,
        items: Items,
        decompress: impl FnOnce(&mut ChunkDecoder) -> Result<(), String>,
    ) -> Result<(), String> {
        let idle = || IDLE_DECODERS.lock().unwrap_or_else(|p| p.into_inner());
        let reused = {
            let mut idle = idle();
            let found = idle.iter().rposition(|d| d.items() == items);
            found.map(|i| idle.swap_remove(i))
        };
        let mut decoder = reused.unwrap_or_else(|| Box::new(ChunkDecoder::new(items)));
        let result = decompress(&mut decoder);
        let mut idle = idle();
        if idle.len() == MAX_IDLE_DECODERS {
            // Keep the most recent ones: drop the oldest.
            idle.remove(0);
        }
        idle.push(decoder);
        result
    }
}

#[cfg(test)]
thread_local! {
    /// Chunks this thread handed to the `laz` crate (tests check which decoder ran).
    pub(super) static LAZ_CRATE_CHUNKS: Cell<usize> = const { Cell::new(0) };
}

thread_local! {
    /// Set while this thread runs `laz` code under [`guarded`].
    static GUARDED: Cell<bool> = const { Cell::new(false) };
}
static QUIET_HOOK: Once = Once::new();

/// Runs `f` (a call into the `laz` crate), turning a panic into an error message. The crate's
/// decoders assert and index on the data they decode, so damaged chunks can make them panic;
/// such panics are caught here, and the panic hook stays silent for them (other panics are
/// reported as before).
pub(super) fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !GUARDED.with(Cell::get) {
                previous(info);
            }
        }));
    });
    let was = GUARDED.with(|g| g.replace(true));
    let result = std::panic::catch_unwind(AssertUnwindSafe(f));
    GUARDED.with(|g| g.set(was));
    result.map_err(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown failure".into());
        format!("the LAZ decoder failed: {what}")
    })
}

/// The item types LASzip must list for `format` with `extra` extra bytes, in record order.
fn expected_items(format: PointFormat, extra: u16) -> Vec<LazItemType> {
    let mut v = Vec::new();
    if format.extended {
        v.push(LazItemType::Point14);
        match (format.rgb.is_some(), format.nir.is_some()) {
            (_, true) => v.push(LazItemType::RGBNIR14),
            (true, false) => v.push(LazItemType::RGB14),
            _ => {}
        }
        if format.waveform.is_some() {
            v.push(LazItemType::WavePacket14);
        }
        if extra > 0 {
            v.push(LazItemType::Byte14(extra));
        }
    } else {
        v.push(LazItemType::Point10);
        if format.gps_time.is_some() {
            v.push(LazItemType::GpsTime);
        }
        if format.rgb.is_some() {
            v.push(LazItemType::RGB12);
        }
        if format.waveform.is_some() {
            v.push(LazItemType::WavePacket13);
        }
        if extra > 0 {
            v.push(LazItemType::Byte(extra));
        }
    }
    v
}

/// Bytes an item decompresses to.
fn item_size(t: LazItemType) -> u16 {
    match t {
        LazItemType::Byte(n) | LazItemType::Byte14(n) => n,
        LazItemType::Point10 => 20,
        LazItemType::GpsTime => 8,
        LazItemType::RGB12 | LazItemType::RGB14 => 6,
        LazItemType::RGBNIR14 => 8,
        LazItemType::WavePacket13 | LazItemType::WavePacket14 => 29,
        LazItemType::Point14 => 30,
    }
}

/// The LASzip items must describe exactly the records of the header's point format.
fn check_items(
    vlr: &LazVlr,
    compressor: Option<u16>,
    format: PointFormat,
    extra: u16,
) -> Result<(), String> {
    let items = vlr.items();
    let found: Vec<LazItemType> = items.iter().map(LazItem::item_type).collect();
    let expected = expected_items(format, extra);
    if found != expected {
        return Err(format!(
            "the LASzip items {found:?} do not match point format {} with {extra} extra bytes (expected {expected:?})",
            format.id
        ));
    }
    for item in items {
        if item.size() != item_size(item.item_type()) {
            return Err(format!(
                "LASzip item {:?} declares {} bytes instead of {}",
                item.item_type(),
                item.size(),
                item_size(item.item_type())
            ));
        }
        let ok = if format.extended {
            matches!(item.version(), 3 | 4)
        } else {
            matches!(item.version(), 1 | 2)
        };
        if !ok {
            return Err(format!(
                "LASzip item {:?} has compression version {}, which this reader does not decompress",
                item.item_type(),
                item.version()
            ));
        }
    }
    let want = if format.extended {
        LAYERED_CHUNKED
    } else {
        POINTWISE_CHUNKED
    };
    if compressor != Some(want) {
        return Err(format!(
            "LASzip compressor type {compressor:?} is not the chunked compressor ({want}) point format {} needs",
            format.id
        ));
    }
    if vlr.chunk_size() == 0 {
        return Err("LASzip chunk size is 0".into());
    }
    Ok(())
}

enum TableError {
    Io(std::io::Error),
    Invalid(String),
}

impl From<std::io::Error> for TableError {
    fn from(e: std::io::Error) -> Self {
        TableError::Io(e)
    }
}

fn read_i64_at(file: &mut File, at: u64) -> std::io::Result<i64> {
    let mut b = [0u8; 8];
    file.seek(SeekFrom::Start(at))?;
    file.read_exact(&mut b)?;
    Ok(i64::from_le_bytes(b))
}

/// Reads and validates the chunk table: every chunk inside the file, counts matching the header.
fn read_chunk_table(
    file: &mut File,
    h: &LasHeader,
    vlr: &LazVlr,
) -> Result<Vec<Chunk>, TableError> {
    let inv = |m: String| TableError::Invalid(m);
    let len = h.file_len;
    let data_start = u64::from(h.offset_to_point_data);
    let first_chunk = data_start + 8;
    if first_chunk > len {
        return Err(inv(format!(
            "the file ends at byte {len}, before the LAZ chunk table offset at byte {data_start}"
        )));
    }
    let mut table_at = read_i64_at(file, data_start)?;
    if table_at <= data_start as i64 && len >= first_chunk + 8 {
        // Writers that cannot seek back leave -1 here and put the offset in the last 8 bytes.
        table_at = read_i64_at(file, len - 8)?;
    }
    let table_at = u64::try_from(table_at).unwrap_or(0);
    if table_at < first_chunk || table_at.saturating_add(8) > len {
        return Err(inv(format!(
            "the LAZ chunk table offset {table_at} lies outside the file ({len} bytes): the file is truncated or damaged"
        )));
    }
    let mut head = [0u8; 8];
    file.seek(SeekFrom::Start(table_at))?;
    file.read_exact(&mut head)?;
    let n_chunks = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
    let space = table_at - first_chunk;
    let variable = vlr.uses_variable_size_chunks();
    let chunk_size = u64::from(vlr.chunk_size());
    let claims = |detail: String| {
        inv(format!(
            "header claims {} points but {detail}",
            h.point_count
        ))
    };
    if n_chunks == 0 {
        return Err(claims("the LAZ chunk table lists no chunks".into()));
    }
    // Each chunk takes at least one byte: bounds the table before anything is allocated.
    if n_chunks > space {
        return Err(inv(format!(
            "the LAZ chunk table lists {n_chunks} chunks, more than the {space} bytes of compressed data can hold"
        )));
    }
    if !variable {
        let most = n_chunks.saturating_mul(chunk_size);
        let least = (n_chunks - 1).saturating_mul(chunk_size) + 1;
        if h.point_count > most || h.point_count < least {
            return Err(claims(format!(
                "the LAZ chunk table lists {n_chunks} chunks of {chunk_size} points, which hold {least} to {most}"
            )));
        }
    }
    file.seek(SeekFrom::Start(table_at))?;
    let table = guarded(|| ChunkTable::read(&mut BufReader::new(&mut *file), variable))
        .and_then(|r| r.map_err(|e| e.to_string()))
        .map_err(|e| {
            inv(format!(
                "the LAZ chunk table cannot be read ({e}): the file is truncated or damaged"
            ))
        })?;
    let record_len = u64::from(h.point_record_length);
    let mut chunks = Vec::with_capacity(table.len());
    let (mut offset, mut total) = (first_chunk, 0u64);
    let last = table.len().saturating_sub(1);
    for (k, e) in table.as_ref().iter().enumerate() {
        let points = if variable {
            e.point_count
        } else if k == last {
            h.point_count - (n_chunks - 1) * chunk_size
        } else {
            chunk_size
        };
        if points.saturating_mul(record_len) > MAX_CHUNK_BYTES {
            return Err(inv(format!(
                "LAZ chunk {k} holds {points} points, more than the {} MiB this reader decompresses at once",
                MAX_CHUNK_BYTES >> 20
            )));
        }
        // Arithmetic coding never inflates a record much: a larger chunk is damage.
        let most_bytes = points * record_len * 2 + 1024;
        let end = offset.saturating_add(e.byte_count);
        if e.byte_count == 0 || e.byte_count > most_bytes || end > table_at {
            return Err(inv(format!(
                "LAZ chunk {k} ({} bytes at byte {offset}, {points} points) does not fit before the chunk table at byte {table_at}: the file is truncated or damaged",
                e.byte_count
            )));
        }
        if points == 0 {
            return Err(inv(format!("LAZ chunk {k} holds no points")));
        }
        chunks.push(Chunk {
            offset,
            bytes: e.byte_count,
            points,
        });
        offset = end;
        total += points;
    }
    if total != h.point_count {
        return Err(claims(format!("the LAZ chunk table holds {total}")));
    }
    Ok(chunks)
}

/// A layered chunk starts with the first record raw, its point count, then one byte count per
/// layer; the layers must fit in the chunk and the count must match the chunk table.
fn check_layered_chunk(
    bytes: &[u8],
    items: &[LazItem],
    record_len: u64,
    points: u64,
) -> Result<(), String> {
    let at = record_len as usize;
    let count = bytes
        .get(at..at + 4)
        .and_then(|b| b.try_into().ok())
        .map(u32::from_le_bytes)
        .ok_or("too short for its first point and point count")?;
    if u64::from(count) != points {
        return Err(format!(
            "holds {count} points but the chunk table says {points}"
        ));
    }
    let layers: usize = items
        .iter()
        .map(|i| match i.item_type() {
            LazItemType::Point14 => 9,
            LazItemType::RGBNIR14 => 2,
            LazItemType::Byte14(n) => usize::from(n),
            _ => 1,
        })
        .sum();
    let sizes_at = at + 4;
    let sizes = bytes
        .get(sizes_at..sizes_at + 4 * layers)
        .ok_or("too short for its layer sizes")?;
    let layer_bytes: u64 = sizes
        .chunks_exact(4)
        .map(|b| u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
        .sum();
    let room = (bytes.len() - sizes.len() - sizes_at) as u64;
    if layer_bytes > room {
        return Err(format!(
            "its layers claim {layer_bytes} bytes but only {room} follow"
        ));
    }
    Ok(())
}

/// The reader of the LAZ file `path` (for tests and the decoder benchmark).
fn open_reader(path: &Path) -> Result<LazReader, IoError> {
    let mut file = File::open(path).map_err(|e| IoError::io(path, e))?;
    let len = file.metadata().map_err(|e| IoError::io(path, e))?.len();
    let h = super::header::parse(&mut super::header::FileSource {
        file: &mut file,
        len,
    })
    .map_err(|e| super::las_error(path, e))?;
    let meta = super::source_meta(&h);
    LazReader::new(path, file, h, meta)
}

/// Whether the reader of the LAZ file `path` decompresses with our decoder.
#[cfg(test)]
pub(super) fn uses_our_decoder(path: &Path) -> Result<bool, IoError> {
    Ok(open_reader(path)?.codec.ours.is_some())
}

/// Each chunk of a LAZ file: its compressed bytes and point count.
pub(super) type RawChunkList = Vec<(Vec<u8>, u64)>;

/// The LASzip VLR of a LAZ file and its chunks as the reader finds them (for tests and the
/// decoder benchmark).
pub(super) fn chunks_of(path: &Path) -> Result<(LazVlr, RawChunkList), IoError> {
    let r = open_reader(path)?;
    let mut chunks = Vec::new();
    for c in &r.chunks {
        let mut bytes = vec![0; c.bytes as usize];
        read_exact_at(&r.file, &mut bytes, c.offset).map_err(|e| IoError::io(path, e))?;
        chunks.push((bytes, c.points));
    }
    Ok((r.codec.vlr, chunks))
}
