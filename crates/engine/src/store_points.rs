//! A store read as a plain point file, for progressive rendering (`--progressive`): its
//! pointlets in stored order, groups of them as parts that threads read at once. Every point
//! is drawn, no LoD: the loader's throughput with nothing to decode but fixed-size columns.

use crate::source::stream_for;
use pointlet_core::color::ColorMode;
use pointlet_core::{PartError, PartedSource, PointBatch, SourceMeta};
use pointlet_io::{IoError, PointReader, ReadOptions};
use pointlet_store::{Store, StreamKind};
use std::path::{Path, PathBuf};

/// Points per part (whole pointlets): one positioned read per stream of this many points
/// costs far more than the part's overhead; a small store still makes 64 parts.
const PART_POINTS: u64 = 65_536;
const MIN_PARTS: u64 = 64;

pub struct StorePoints {
    store: Store,
    path: PathBuf,
    meta: SourceMeta,
    /// Pointlets of each part: `parts[i]..parts[i + 1]`.
    parts: Vec<usize>,
    part_sizes: Vec<u64>,
    /// Parts `read_batch` has returned.
    next_part: usize,
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
        let entries = store.pointlets();
        let mut parts = Vec::with_capacity(entries.len() / per_part + 2);
        let mut part_sizes = Vec::with_capacity(entries.len() / per_part + 1);
        for (k, group) in entries.chunks(per_part).enumerate() {
            parts.push(k * per_part);
            part_sizes.push(group.iter().map(|e| u64::from(e.count)).sum());
        }
        parts.push(entries.len());
        Ok(Self {
            store,
            path: path.to_path_buf(),
            meta,
            parts,
            part_sizes,
            next_part: 0,
        })
    }

    /// Part `i`'s points with the streams `kinds` (positions always).
    fn decode(&self, i: usize, out: &mut PointBatch, kinds: &[StreamKind]) -> Result<(), IoError> {
        let (Some(&start), Some(&end)) = (self.parts.get(i), self.parts.get(i + 1)) else {
            return Err(IoError::invalid(
                &self.path,
                format!(
                    "there is no part {i}: the store has {}",
                    self.part_sizes.len()
                ),
            ));
        };
        // Checksummed: a damaged pointlet is an error naming it, never wrong points.
        *out = self
            .store
            .read_pointlet_streams(start..end, kinds)
            .map_err(|e| IoError::Named(Box::new(e)))?;
        Ok(())
    }
}

impl PointReader for StorePoints {
    fn path(&self) -> &Path {
        &self.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_batch(&mut self, _max: usize) -> Result<Option<PointBatch>, IoError> {
        if self.next_part == self.part_sizes.len() {
            return Ok(None);
        }
        let mut out = PointBatch::new(self.meta.layout);
        self.decode(self.next_part, &mut out, &StreamKind::ALL)?;
        self.next_part += 1;
        Ok(Some(out))
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
        _scratch: &mut Vec<u8>,
    ) -> Result<(), PartError> {
        self.decode(i, out, &StreamKind::ALL)
            .map_err(|e| Box::new(e) as PartError)
    }

    /// Reads positions, classes (the colours' alpha) and the one stream `mode` colours by.
    fn decode_part_for(
        &self,
        i: usize,
        out: &mut PointBatch,
        _scratch: &mut Vec<u8>,
        mode: ColorMode,
    ) -> Result<(), PartError> {
        let kinds: Vec<StreamKind> = [Some(StreamKind::Classification), stream_for(mode)]
            .into_iter()
            .flatten()
            .collect();
        self.decode(i, out, &kinds)
            .map_err(|e| Box::new(e) as PartError)
    }
}

/// Opens a point file, or a store (`.pointlet`) as one, for progressive loading.
pub fn open_points(path: &Path, read: &ReadOptions) -> Result<Box<dyn PointReader>, IoError> {
    if is_store(path) {
        return Ok(Box::new(StorePoints::open(path)?));
    }
    pointlet_io::open_with(path, read)
}

/// Stores are recognised by their extension, as everywhere else.
pub fn is_store(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("pointlet"))
}
