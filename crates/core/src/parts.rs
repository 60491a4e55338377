//! Point files that many threads decode at once, part by part.
//!
//! A LAS file's records and a LAZ file's chunks can be decoded independently, so conversion
//! hands parts to every core instead of reading the file front to back on one thread.

use crate::color::ColorMode;
use crate::rows::RowLayout;
use crate::{PointBatch, Quantization};

/// Why a part could not be decoded: the reader's own error (it names the file and offset).
pub type PartError = Box<dyn std::error::Error + Send + Sync>;

/// A point file split into parts (LAS record ranges, LAZ chunks). Parts in order give the
/// file's points in order; each can be decoded from any thread, in any order.
pub trait PartedSource: Sync {
    /// Points in each part, in file order.
    fn part_sizes(&self) -> &[u64];

    /// Decodes part `i` into `out` (cleared first; its layout becomes the file's).
    /// `scratch` is a buffer the caller keeps per thread to save allocations.
    fn decode_part(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
    ) -> Result<(), PartError>;

    /// Decodes part `i` as [`decode_part`](Self::decode_part) does, but only the positions and
    /// what colouring by `mode` reads need to be complete: a source that stores columns apart
    /// may leave the others empty. Sources that decode whole records keep this default.
    fn decode_part_for(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
        mode: ColorMode,
    ) -> Result<(), PartError> {
        let _ = mode;
        self.decode_part(i, out, scratch)
    }

    /// The quantization of the positions [`read_quantized_positions`] gives: `Some` for
    /// sources that keep positions as stored integers in a column of their own (stores), so
    /// that a loader can hand them to the GPU as they are.
    ///
    /// [`read_quantized_positions`]: Self::read_quantized_positions
    fn quantized_positions(&self) -> Option<Quantization> {
        None
    }

    /// Part `i`'s positions as stored: x, y, z as little-endian i32 of
    /// [`quantized_positions`](Self::quantized_positions), 12 bytes a point, in `raw[..n]`
    /// (`raw` grown as needed; n returned), checked as the source checks its data.
    fn read_quantized_positions(&self, i: usize, raw: &mut Vec<u8>) -> Result<usize, PartError> {
        let _ = (i, raw);
        Err("this source keeps no quantized positions".into())
    }

    /// [`decode_part_for`](Self::decode_part_for) without the positions, for a loader that
    /// takes them from [`read_quantized_positions`](Self::read_quantized_positions): only
    /// what colouring by `mode` reads is complete (`mode` must not read positions).
    fn decode_attributes_for(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
        mode: ColorMode,
    ) -> Result<(), PartError> {
        self.decode_part_for(i, out, scratch, mode)
    }

    /// The RGBA8 colours of part `i` under `scale` (`out` holds one per point) straight from
    /// the stored bytes, for sources that keep columns apart when `scale` takes them as they
    /// are (RGB, classification): `Ok(false)` otherwise, and the caller decodes the part and
    /// colours it. `bytes` and `classes` are scratch the caller keeps per thread.
    fn stored_colors(
        &self,
        i: usize,
        scale: &crate::color::ColorScale,
        out: &mut [u32],
        bytes: &mut Vec<u8>,
        classes: &mut Vec<u8>,
    ) -> Result<bool, PartError> {
        let _ = (i, scale, out, bytes, classes);
        Ok(false)
    }

    /// Decodes part `i` straight into rows of `row` for a store quantized as `q` (`rows` holds
    /// one per point of the part), when the part stores its positions as integers of exactly
    /// `q` and `row` has every column it has (a LAS or LAZ file of that scale and offset): each
    /// row's position is the stored integers (no round trip through f64), its other columns
    /// what [`decode_part`] gives, zero where the part lacks a column of `row`. `Ok(false)`,
    /// with nothing written, for any other quantization, layout or source. Each stretch of
    /// rows goes to `done` (the index of its first row, its bytes) as soon as it is filled,
    /// while still in the cache; together the stretches cover `rows` once, in order.
    ///
    /// [`decode_part`]: Self::decode_part
    fn decode_part_rows(
        &self,
        i: usize,
        q: &Quantization,
        row: &RowLayout,
        rows: &mut [u8],
        scratch: &mut Vec<u8>,
        done: &mut dyn FnMut(usize, &[u8]),
    ) -> Result<bool, PartError> {
        let _ = (i, q, row, rows, scratch, done);
        Ok(false)
    }

    /// `Some(k)` when the points come in groups of k (a power of two; the last group may be
    /// shorter), each group in random order, so that the first points of a group are a uniform
    /// sample of it: a store's pointlets. A progressive loader may then interleave the groups
    /// instead of permuting every point ([`crate::progressive::GroupRows`]).
    fn shuffled_groups(&self) -> Option<u64> {
        None
    }
}
