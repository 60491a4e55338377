//! Where the cache reads points from: a store on disk, or anything else that can hand out
//! ranges of a pointlet's shuffled order.

use std::ops::Range;
use thiserror::Error;

#[derive(Debug, Error)]
#[error("reading points {range:?} of pointlet {pointlet}: {message}")]
pub struct SourceError {
    pub pointlet: usize,
    pub range: Range<u32>,
    pub message: String,
}

/// A run of one pointlet's points as the GPU wants them: three position words per point, in
/// whatever encoding the source and its consumer agree on (encoding in the loader threads keeps
/// that work off the render thread), and one packed 32-bit attribute (an RGBA colour, or any
/// attribute in four bytes, as in the paper). In the cache, `start` is the index of the first
/// held point (the run is a window of the pointlet's shuffled order: a prefix until
/// already-drawn points are dropped).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointletData {
    pub start: u32,
    pub positions: Vec<[u32; 3]>,
    pub attribute: Vec<u32>,
}

/// Bytes one cached point costs.
pub const BYTES_PER_POINT: u64 = 16;

impl PointletData {
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Bytes held, by capacity: what the allocator really gave us.
    pub fn bytes(&self) -> u64 {
        (self.positions.capacity() * 12 + self.attribute.capacity() * 4) as u64
    }

    /// One past the last held point.
    pub fn end(&self) -> u32 {
        self.start + self.positions.len() as u32
    }

    /// Keeps the first `n` held points.
    pub fn truncate(&mut self, n: usize) {
        self.positions.truncate(n);
        self.attribute.truncate(n);
        self.positions.shrink_to_fit();
        self.attribute.shrink_to_fit();
    }

    /// Drops held points before point `from` of the pointlet.
    pub fn drop_before(&mut self, from: u32) {
        let n = (from.saturating_sub(self.start) as usize).min(self.positions.len());
        self.positions.drain(..n);
        self.attribute.drain(..n);
        self.positions.shrink_to_fit();
        self.attribute.shrink_to_fit();
        self.start += n as u32;
    }
}

/// Random access to pointlet prefixes. Implementations must be cheap to call from many
/// threads at once (positioned reads, no shared cursor).
pub trait PointletSource: Send + Sync + 'static {
    fn pointlet_count(&self) -> usize;
    /// Points in pointlet `i`.
    fn pointlet_len(&self, i: usize) -> u32;
    /// Appends points `range` of pointlet `i` to `out`.
    fn read(&self, i: usize, range: Range<u32>, out: &mut PointletData) -> Result<(), SourceError>;

    /// Appends points `requests[k].1` of pointlet `requests[k].0` to `outs[k]`, one result per
    /// request. Sources whose reads cost a round trip (a store over the network) override it to
    /// fetch the whole batch at once.
    fn read_many(
        &self,
        requests: &[(usize, Range<u32>)],
        outs: &mut [PointletData],
    ) -> Vec<Result<(), SourceError>> {
        requests
            .iter()
            .zip(outs.iter_mut())
            .map(|((i, r), out)| self.read(*i, r.clone(), out))
            .collect()
    }
}
