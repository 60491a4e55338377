//! Our own decompressor for LASzip's point-wise chunked compressor (compressor type 2, point
//! formats 0–3 of LAS 1.0–1.4) with the version 2 items POINT10, GPSTIME11, RGB12 and BYTE:
//! the items nearly every LAZ file of those formats uses. Its output is byte for byte what
//! the `laz` crate (and LASzip) decompress; every other item set stays with the `laz` crate
//! (see [`Items::supported`]).
//!
//! A chunk holds its first record raw, then one arithmetic-coded stream (see [`arith`]) with
//! every further record, item after item; each item predicts its fields from the previous
//! record and its own adaptive models, all starting afresh with each chunk. The decoder is
//! generic over the item set, so the loop over a chunk's points is one monomorphic function
//! per combination, with no dispatch per point or item. Its models are allocated once and
//! reset at the start of each chunk, so a decoder is meant to be reused for many chunks.
//!
//! Damaged data cannot make it panic, loop or allocate: a chunk too short for its points is
//! noticed after the point where the decoder ran out of bytes, and reported as an error.

mod arith;
mod bytes;
mod gps;
mod integer;
mod point10;
pub mod raw;
mod rgb;
#[cfg(test)]
mod tests;

use arith::Arith;
use bytes::Bytes;
use gps::Gps;
use laz::{LazItem, LazItemType};
use point10::Point10;
use rgb::Rgb;

/// More extra bytes than this are left to the `laz` crate: each takes a 1.5 KiB model per
/// decoder, and real files have a few.
const MAX_EXTRA_BYTES: u16 = 1024;

/// An item set this decoder handles: POINT10, then GPS time, colour and extra bytes if present.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Items {
    gps: bool,
    rgb: bool,
    extra: u16,
}

impl Items {
    /// The item set of `items` (in record order) when they are all version 2 items this
    /// decoder handles, in the order LASzip writes them; `None` otherwise.
    pub fn supported(items: &[LazItem]) -> Option<Items> {
        let mut it = items.iter().peekable();
        let mut next_is =
            |want: fn(LazItemType) -> bool| it.next_if(|i| want(i.item_type()) && i.version() == 2);
        next_is(|t| t == LazItemType::Point10)?;
        let gps = next_is(|t| t == LazItemType::GpsTime).is_some();
        let rgb = next_is(|t| t == LazItemType::RGB12).is_some();
        let extra = match next_is(|t| matches!(t, LazItemType::Byte(_))) {
            Some(i) => match i.item_type() {
                LazItemType::Byte(n) if n > 0 && n <= MAX_EXTRA_BYTES && n == i.size() => n,
                _ => return None,
            },
            None => 0,
        };
        it.next().is_none().then_some(Items { gps, rgb, extra })
    }

    /// Bytes of one record.
    pub fn record_len(&self) -> usize {
        Point10::LEN
            + if self.gps { Gps::LEN } else { 0 }
            + if self.rgb { Rgb::LEN } else { 0 }
            + usize::from(self.extra)
    }
}

/// Decompresses chunks of one item set; reusable from chunk to chunk.
pub(crate) struct ChunkDecoder {
    items: Items,
    point: Point10,
    gps: Gps,
    rgb: Rgb,
    bytes: Bytes,
}

impl ChunkDecoder {
    pub fn new(items: Items) -> Self {
        ChunkDecoder {
            items,
            point: Point10::new(),
            gps: Gps::new(),
            rgb: Rgb::new(),
            bytes: Bytes::new(usize::from(items.extra)),
        }
    }

    pub fn items(&self) -> Items {
        self.items
    }

    /// Decompresses the chunk `data` into `out`, whose length (a whole number of records)
    /// says how many points the chunk holds. The error says what is wrong, for a message
    /// that names the chunk.
    pub fn decompress(&mut self, data: &[u8], out: &mut [u8]) -> Result<(), String> {
        let len = self.items.record_len();
        if out.is_empty() || !out.len().is_multiple_of(len) {
            return Err(format!(
                "{} bytes of output are no whole number of {len}-byte records",
                out.len()
            ));
        }
        self.decompress_blocks(data, out.len() / len, out, |_, _| Ok(()))
    }

    /// Decompresses the chunk `data` of `points` records a block at a time into `block` (as
    /// many records as it holds whole), handing each filled block to `f` with the index of
    /// its first record: the records are used while still in the cache, where a whole
    /// chunk's (1.7 MB for 50,000 points with time and colour) would have left it.
    pub fn decompress_blocks(
        &mut self,
        data: &[u8],
        points: usize,
        block: &mut [u8],
        mut f: impl FnMut(usize, &[u8]) -> Result<(), String>,
    ) -> Result<(), String> {
        let len = self.items.record_len();
        let per_block = block.len() / len;
        if points == 0 || per_block == 0 {
            return Err(format!(
                "{points} points into blocks of {} bytes: no whole {len}-byte record",
                block.len()
            ));
        }
        let first = data.get(..len).ok_or_else(|| {
            format!(
                "its {} bytes are too few for the first {len}-byte record",
                data.len()
            )
        })?;
        let mut ac = Arith::new(&data[len..]);
        if ac.overrun() {
            return Err(format!(
                "its {} bytes end before the coded points start",
                data.len()
            ));
        }
        self.reset(first)
            .ok_or("records shorter than their items")?;
        let extra = self.items.extra > 0;
        let mut at = 0;
        while at < points {
            let out = &mut block[..per_block.min(points - at) * len];
            if at == 0 {
                out[..len].copy_from_slice(first);
            }
            let ac = &mut ac;
            match (self.items.gps, self.items.rgb, extra) {
                (false, false, false) => self.run::<false, false, false>(ac, out, at, points),
                (false, false, true) => self.run::<false, false, true>(ac, out, at, points),
                (false, true, false) => self.run::<false, true, false>(ac, out, at, points),
                (false, true, true) => self.run::<false, true, true>(ac, out, at, points),
                (true, false, false) => self.run::<true, false, false>(ac, out, at, points),
                (true, false, true) => self.run::<true, false, true>(ac, out, at, points),
                (true, true, false) => self.run::<true, true, false>(ac, out, at, points),
                (true, true, true) => self.run::<true, true, true>(ac, out, at, points),
            }?;
            f(at, out)?;
            at += out.len() / len;
        }
        Ok(())
    }

    /// Starts every item from the chunk's first record.
    fn reset(&mut self, first: &[u8]) -> Option<()> {
        let (p, mut rest) = first.split_first_chunk::<{ Point10::LEN }>()?;
        self.point.reset(p);
        if self.items.gps {
            let (g, r) = rest.split_first_chunk::<{ Gps::LEN }>()?;
            self.gps.reset(g);
            rest = r;
        }
        if self.items.rgb {
            let (c, r) = rest.split_first_chunk::<{ Rgb::LEN }>()?;
            self.rgb.reset(c);
            rest = r;
        }
        self.bytes.reset(rest);
        Some(())
    }

    /// The records of `out`, records `first..` of the chunk's `points` (the chunk's first,
    /// kept raw, already in place when `first` is 0), for one item set (`G`PS time, `C`olour,
    /// e`X`tra bytes).
    fn run<const G: bool, const C: bool, const X: bool>(
        &mut self,
        ac: &mut Arith,
        out: &mut [u8],
        first: usize,
        points: usize,
    ) -> Result<(), String> {
        let len = self.items.record_len();
        let skip = usize::from(first == 0);
        for (i, rec) in (first..).zip(out.chunks_exact_mut(len)).skip(skip) {
            let Some((p, rest)) = rec.split_first_chunk_mut::<{ Point10::LEN }>() else {
                return Err("records shorter than their items".into());
            };
            self.point.decode(ac, p);
            let rest = if G {
                let Some((g, rest)) = rest.split_first_chunk_mut::<{ Gps::LEN }>() else {
                    return Err("records shorter than their items".into());
                };
                if !self.gps.decode(ac, g) {
                    return Err(format!(
                        "point {} of {points} switches GPS time sequences too often",
                        i + 1
                    ));
                }
                rest
            } else {
                rest
            };
            let rest = if C {
                let Some((c, rest)) = rest.split_first_chunk_mut::<{ Rgb::LEN }>() else {
                    return Err("records shorter than their items".into());
                };
                self.rgb.decode(ac, c);
                rest
            } else {
                rest
            };
            if X {
                self.bytes.decode(ac, rest);
            }
            if ac.overrun() {
                return Err(format!(
                    "its bytes end inside point {} of the {points} it should hold",
                    i + 1
                ));
            }
        }
        Ok(())
    }
}
