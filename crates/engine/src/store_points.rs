//! A store read as a plain point file, for progressive rendering (`--progressive`): its
//! pointlets in stored order, groups of them as parts that threads read at once. Every point
//! is drawn, no LoD: the loader's throughput with nothing to decode but fixed-size columns.

use pointlet_core::color::{class_colors, rgb_colors_from_bytes, ColorMode, ColorScale};
use pointlet_core::{PartError, PartedSource, PointBatch, Quantization, SourceMeta};
use pointlet_io::{IoError, PointReader, ReadOptions};
use pointlet_store::{Store, StreamKind};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Points per part (whole pointlets): one positioned read per stream of this many points
/// costs far more than the part's overhead; a small store still makes 64 parts.
const PART_POINTS: u64 = 65_536;
const MIN_PARTS: u64 = 64;

pub struct StorePoints {
    store: Store,
    path: PathBuf,
    meta: SourceMeta,
    /// Pointlets per part (the last part may hold fewer).
    per_part: usize,
    part_sizes: Vec<u64>,
    /// The first pointlet `read_batch` has not returned.
    next_pointlet: usize,
}

impl StorePoints {
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let store = Store::open(path).map_err(|e| IoError::Named(Box::new(e)))?;
        let h = store.header();
        let meta = SourceMeta {
            format: format!("pointlet store v{}", h.version),
            point_count: h.points,
            bounds: h.bounds,
            quantization: Some(h.quantization),
            layout: h.layout,
            las_point_format: Some(h.las_point_format),
            vlrs: h.vlrs.clone(),
            las: h.las.clone(),
        };
        let part_points = PART_POINTS.min(h.points / MIN_PARTS);
        let per_part = part_points.div_ceil(h.pointlet_size.max(1)).max(1) as usize;
        let part_sizes = store
            .pointlets()
            .chunks(per_part)
            .map(|group| group.iter().map(|e| u64::from(e.count)).sum())
            .collect();
        Ok(Self {
            store,
            path: path.to_path_buf(),
            meta,
            per_part,
            part_sizes,
            next_pointlet: 0,
        })
    }

    /// Part `i`'s points with the streams `kinds` (positions always).
    fn decode(
        &self,
        i: usize,
        out: &mut PointBatch,
        raw: &mut Vec<u8>,
        kinds: &[StreamKind],
    ) -> Result<(), IoError> {
        let range = self.pointlets_of(i)?;
        self.store
            .read_pointlet_streams_into(range, kinds, out, raw)
            .map_err(|e| IoError::Named(Box::new(e)))
    }

    /// The pointlets of part `i`.
    fn pointlets_of(&self, i: usize) -> Result<Range<usize>, IoError> {
        if i >= self.part_sizes.len() {
            return Err(IoError::invalid(
                &self.path,
                format!(
                    "there is no part {i}: the store has {}",
                    self.part_sizes.len()
                ),
            ));
        }
        let start = i * self.per_part;
        Ok(start..(start + self.per_part).min(self.store.pointlets().len()))
    }

    /// Pointlets `range`, checksummed: a damaged pointlet is an error naming it, never wrong
    /// points.
    fn read(&self, range: Range<usize>, kinds: &[StreamKind]) -> Result<PointBatch, IoError> {
        self.store
            .read_pointlet_streams(range, kinds)
            .map_err(|e| IoError::Named(Box::new(e)))
    }
}

impl PointReader for StorePoints {
    fn path(&self) -> &Path {
        &self.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    /// Whole pointlets, as many as `max` points hold (at least one: a pointlet is not split).
    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
        let entries = self.store.pointlets();
        let start = self.next_pointlet;
        let Some(first) = entries.get(start) else {
            return Ok(None);
        };
        let (mut end, mut points) = (start + 1, u64::from(first.count));
        while let Some(e) = entries.get(end) {
            if points + u64::from(e.count) > max as u64 {
                break;
            }
            points += u64::from(e.count);
            end += 1;
        }
        let batch = self.read(start..end, &StreamKind::ALL)?;
        self.next_pointlet = end;
        Ok(Some(batch))
    }

    fn parted(&self) -> Option<&dyn PartedSource> {
        Some(self)
    }
}

impl PartedSource for StorePoints {
    fn part_sizes(&self) -> &[u64] {
        &self.part_sizes
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
    ) -> Result<(), PartError> {
        self.decode(i, out, scratch, &StreamKind::ALL)
            .map_err(|e| Box::new(e) as PartError)
    }

    /// Reads positions, classes (the colours' alpha) and the one stream `mode` colours by.
    fn decode_part_for(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
        mode: ColorMode,
    ) -> Result<(), PartError> {
        self.decode(i, out, scratch, &color_streams(mode))
            .map_err(|e| Box::new(e) as PartError)
    }

    fn quantized_positions(&self) -> Option<Quantization> {
        Some(self.store.header().quantization)
    }

    /// RGB and classification colours from the streams' bytes, without decoding a batch.
    fn stored_colors(
        &self,
        i: usize,
        scale: &ColorScale,
        out: &mut [u32],
        bytes: &mut Vec<u8>,
        classes: &mut Vec<u8>,
    ) -> Result<bool, PartError> {
        let has = |kind| self.store.header().stream(kind).is_some();
        let rgb = match scale.mode {
            ColorMode::Rgb if has(StreamKind::Rgb) => true,
            ColorMode::Classification => false,
            _ => return Ok(false),
        };
        if !has(StreamKind::Classification) {
            return Ok(false);
        }
        let range = self.pointlets_of(i).map_err(|e| Box::new(e) as PartError)?;
        let read = |kind, raw: &mut Vec<u8>, width: usize| -> Result<usize, PartError> {
            let n = self
                .store
                .read_stream_into(range.clone(), kind, raw)
                .map_err(|e| Box::new(IoError::Named(Box::new(e))) as PartError)?;
            if n != out.len() * width {
                return Err(format!(
                    "{}: part {i} holds {n} bytes of {}, not {} points' worth",
                    self.path.display(),
                    StreamKind::name(kind),
                    out.len()
                )
                .into());
            }
            Ok(n)
        };
        let n = read(StreamKind::Classification, classes, 1)?;
        if rgb {
            let m = read(StreamKind::Rgb, bytes, 6)?;
            rgb_colors_from_bytes(&bytes[..m], &classes[..n], scale.rgb_8bit, out);
        } else {
            class_colors(&classes[..n], out);
        }
        Ok(true)
    }

    /// Pointlets: shuffled inside when the store was built.
    fn shuffled_groups(&self) -> Option<u64> {
        Some(self.store.header().pointlet_size)
    }

    fn read_quantized_positions(&self, i: usize, raw: &mut Vec<u8>) -> Result<usize, PartError> {
        let range = self.pointlets_of(i).map_err(|e| Box::new(e) as PartError)?;
        self.store
            .read_stream_into(range, StreamKind::Position, raw)
            .map_err(|e| Box::new(IoError::Named(Box::new(e))) as PartError)
    }

    /// Reads classes (the colours' alpha) and the one stream `mode` colours by.
    fn decode_attributes_for(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
        mode: ColorMode,
    ) -> Result<(), PartError> {
        let range = self.pointlets_of(i).map_err(|e| Box::new(e) as PartError)?;
        self.store
            .read_pointlet_attributes_into(range, &color_streams(mode), out, scratch)
            .map_err(|e| Box::new(IoError::Named(Box::new(e))) as PartError)
    }
}

/// The streams colouring by `mode` reads: classes (the colours' alpha) and its own.
fn color_streams(mode: ColorMode) -> Vec<StreamKind> {
    [
        Some(StreamKind::Classification),
        StreamKind::for_color(mode),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// Opens a point file, or a store (`.pointlet`) or a 3D Tiles tileset (`.json`) as one.
pub fn open_points(path: &Path, read: &ReadOptions) -> Result<Box<dyn PointReader>, IoError> {
    if is_store(path) {
        return Ok(Box::new(StorePoints::open(path)?));
    }
    if pointlet_tiles::points::is_tileset_path(path) {
        if !pointlet_store::is_remote(path) {
            return pointlet_tiles::points::open(path);
        }
        let url = path.to_string_lossy();
        let source = crate::remote_tiles::RemoteTiles;
        let tileset = pointlet_tiles::Tileset::load(&source, &url)
            .map_err(|e| IoError::Named(Box::new(e)))?;
        let reader = pointlet_tiles::points::TilesetPoints::new(path, tileset, Box::new(source))?;
        return Ok(Box::new(reader));
    }
    pointlet_io::open_with(path, read)
}

/// Stores are recognised by their extension, as everywhere else.
pub fn is_store(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("pointlet"))
}
