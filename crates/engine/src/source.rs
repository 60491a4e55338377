//! Reads pointlet ranges from a store for the RAM cache: positions already encoded for the GPU
//! (relative to the pointlet's box, in the pool's encoding) plus one RGBA8 colour per point,
//! computed from the attribute the user colours by. Encoding here, in the loader threads, leaves
//! the render thread nothing but copies.

use pointlet_core::color::{point_colors, sample_parts, ColorMode, ColorScale};
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::PointBatch;
use pointlet_gpu::{compact_step, encode_point, PointEncoding};
use pointlet_store::{Store, StreamKind};
use pointlet_stream::{PointletData, PointletSource, SourceError};
use std::ops::Range;
use std::sync::{Arc, RwLock};

/// Quantized positions (empty unless asked for) and colours of a read range.
type PointsRead = (Vec<[i32; 3]>, Vec<u32>);

pub struct StoreSource {
    store: Arc<Store>,
    encoding: PointEncoding,
    /// Swapped when the user colours by another attribute; loaders read it per range.
    scale: RwLock<ColorScale>,
}

impl StoreSource {
    /// Colours by `mode`, with ranges fitted by [`fit_scale`].
    pub fn new(
        store: Arc<Store>,
        mode: ColorMode,
        encoding: PointEncoding,
    ) -> Result<Self, pointlet_store::StoreError> {
        let scale = fit_scale(&store, mode)?;
        Ok(Self {
            store,
            encoding,
            scale: RwLock::new(scale),
        })
    }

    pub fn scale(&self) -> ColorScale {
        match self.scale.read() {
            Ok(s) => *s,
            Err(poisoned) => *poisoned.into_inner(),
        }
    }

    pub fn set_scale(&self, scale: ColorScale) {
        match self.scale.write() {
            Ok(mut s) => *s = scale,
            Err(poisoned) => *poisoned.into_inner() = scale,
        }
    }

    /// Colours of points `range` of pointlet `i` under the current scale, reading only the
    /// attribute's stream (and positions only for elevation).
    pub fn colors(&self, i: usize, range: Range<u32>) -> Result<Vec<u32>, SourceError> {
        Ok(self.read_with_colors(i, range, false)?.1)
    }

    /// The streams colouring by the current scale reads: the attribute's (if the store has it)
    /// and the classes (hidden classes are decided on them), positions for elevation.
    fn color_streams(&self, scale: &ColorScale) -> Vec<StreamKind> {
        let header = self.store.header();
        let mut kinds = Vec::new();
        match StreamKind::for_color(scale.mode) {
            None => kinds.push(StreamKind::Position),
            Some(kind) if header.stream(kind).is_some() => kinds.push(kind),
            // The store lacks the attribute: every point draws grey.
            Some(_) => {}
        }
        if header.stream(StreamKind::Classification).is_some()
            && scale.mode != ColorMode::Classification
        {
            kinds.push(StreamKind::Classification);
        }
        kinds
    }

    /// Positions (when `positions`) and colours of points `range` of pointlet `i`, every
    /// stream read at once.
    fn read_with_colors(
        &self,
        i: usize,
        range: Range<u32>,
        positions: bool,
    ) -> Result<PointsRead, SourceError> {
        let requests = [(i, range.clone())];
        self.read_many_with_colors(&requests, positions)
            .map_err(|e| self.error(i, &range, e))?
            .pop()
            .ok_or_else(|| self.error(i, &range, "nothing read"))
    }

    /// [`read_with_colors`](Self::read_with_colors) for many requests, their streams read as
    /// one batch of ranges.
    fn read_many_with_colors(
        &self,
        requests: &[(usize, Range<u32>)],
        positions: bool,
    ) -> Result<Vec<PointsRead>, pointlet_store::StoreError> {
        let scale = self.scale();
        let mut kinds = self.color_streams(&scale);
        if positions && !kinds.contains(&StreamKind::Position) {
            kinds.push(StreamKind::Position);
        }
        let raws = self.store.read_streams_raw_many(requests, &kinds)?;
        let q = self.store.header().quantization;
        let extra_bytes = self.store.header().layout.extra_bytes;
        Ok(requests
            .iter()
            .zip(raws)
            .map(|((_, range), raws)| {
                let n = (range.end - range.start) as usize;
                let mut batch = PointBatch::default();
                let mut xyz = Vec::new();
                for (kind, raw) in kinds.iter().zip(&raws) {
                    if *kind == StreamKind::Position {
                        xyz = pointlet_store::decode_positions(raw);
                    } else {
                        fill_column(&mut batch, *kind, raw);
                    }
                }
                if scale.mode == ColorMode::Elevation {
                    batch.xyz = xyz.iter().map(|p| q.dequantize(*p)).collect();
                }
                // Extra bytes are read point by point at the store's width.
                batch.layout.extra_bytes = extra_bytes;
                let mut colors = vec![0; n];
                point_colors(&batch, &scale, &mut colors);
                (xyz, colors)
            })
            .collect())
    }

    /// Appends the GPU encoding of `positions` of pointlet `i` and their colours to `out`.
    fn encode_into(
        &self,
        i: usize,
        range: &Range<u32>,
        (positions, colors): PointsRead,
        out: &mut PointletData,
    ) -> Result<(), SourceError> {
        let Some(entry) = self.store.pointlets().get(i) else {
            return Err(self.error(i, range, "no such pointlet"));
        };
        let q = self.store.header().quantization;
        let (origin, step) = (entry.aabb.min, compact_step(entry.aabb.extent()));
        out.positions.extend(
            positions
                .iter()
                .map(|p| encode_point(q.dequantize(*p), origin, step, self.encoding)),
        );
        out.attribute.extend_from_slice(&colors);
        Ok(())
    }

    fn error(&self, i: usize, range: &Range<u32>, e: impl std::fmt::Display) -> SourceError {
        SourceError {
            pointlet: i,
            range: range.clone(),
            message: format!("{}: {e}", self.store.path().display()),
        }
    }
}

impl PointletSource for StoreSource {
    fn pointlet_count(&self) -> usize {
        self.store.pointlets().len()
    }

    fn pointlet_len(&self, i: usize) -> u32 {
        self.store.pointlets().get(i).map_or(0, |p| p.count)
    }

    fn read(&self, i: usize, range: Range<u32>, out: &mut PointletData) -> Result<(), SourceError> {
        let read = self.read_with_colors(i, range.clone(), true)?;
        self.encode_into(i, &range, read, out)
    }

    fn read_many(
        &self,
        requests: &[(usize, Range<u32>)],
        outs: &mut [PointletData],
    ) -> Vec<Result<(), SourceError>> {
        match self.read_many_with_colors(requests, true) {
            Ok(reads) => requests
                .iter()
                .zip(reads)
                .zip(outs.iter_mut())
                .map(|(((i, range), read), out)| self.encode_into(*i, range, read, out))
                .collect(),
            // One failed fetch fails the batch: every pointlet in it reports the error.
            Err(e) => requests
                .iter()
                .map(|(i, range)| Err(self.error(*i, range, &e)))
                .collect(),
        }
    }
}

/// A colour scale for `mode` fitted on a few pointlets spread over the store.
pub fn fit_scale(store: &Store, mode: ColorMode) -> Result<ColorScale, pointlet_store::StoreError> {
    let sample = sample_parts(store.pointlets().len(), |i| store.read_pointlet(i))?;
    let h = store.header();
    let extras = ExtraAttributes::from_vlrs(&h.vlrs, usize::from(h.layout.extra_bytes));
    Ok(ColorScale::fit_in(
        mode,
        &sample.iter().collect::<Vec<_>>(),
        [h.bounds.min[2], h.bounds.max[2]],
        &extras,
    ))
}

/// Decodes one little-endian stream into the matching column of `batch`.
fn fill_column(batch: &mut PointBatch, kind: StreamKind, raw: &[u8]) {
    let u16s = || {
        raw.chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
    };
    match kind {
        StreamKind::Rgb => {
            batch.rgb = raw
                .chunks_exact(6)
                .map(|c| [0, 1, 2].map(|k| u16::from_le_bytes([c[2 * k], c[2 * k + 1]])))
                .collect()
        }
        StreamKind::Intensity => batch.intensity = u16s().collect(),
        StreamKind::PointSourceId => batch.point_source_id = u16s().collect(),
        StreamKind::Classification => batch.classification = raw.to_vec(),
        StreamKind::UserData => batch.user_data = raw.to_vec(),
        StreamKind::ExtraBytes => batch.extra_bytes = raw.to_vec(),
        StreamKind::Nir => batch.nir = u16s().collect(),
        StreamKind::ScanAngle => {
            batch.scan_angle = raw
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        }
        StreamKind::Returns => batch.returns = raw.to_vec(),
        StreamKind::GpsTime => {
            batch.gps_time = raw
                .chunks_exact(8)
                .map(|c| {
                    let mut b = [0u8; 8];
                    b.copy_from_slice(c);
                    f64::from_le_bytes(b)
                })
                .collect()
        }
        _ => {}
    }
}
