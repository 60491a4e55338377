//! Raw LAZ chunks decompressed by our decoder or by the `laz` crate, chosen by the caller: for
//! the decoder benchmark (`examples/laz_decode.rs`) and the fuzz target. Not a stable API.

use super::{ChunkDecoder, Items};
use crate::IoError;
use laz::laszip::ChunkTableEntry;
use laz::LazVlr;
use std::path::Path;

/// Which decoder decompresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Codec {
    Ours,
    LazCrate,
}

/// Every chunk of a LAZ file, compressed, in memory.
pub struct RawChunks {
    vlr: LazVlr,
    chunks: crate::las::laz::RawChunkList,
}

/// A decoder kept from chunk to chunk (one per thread).
#[derive(Default)]
pub struct RawDecoder(Option<Box<ChunkDecoder>>);

impl RawChunks {
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let (vlr, chunks) = crate::las::laz::chunks_of(path)?;
        Ok(RawChunks { vlr, chunks })
    }

    /// Our decoder handles this file's items.
    pub fn ours_supported(&self) -> bool {
        Items::supported(self.vlr.items()).is_some()
    }

    pub fn len(&self) -> usize {
        self.chunks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    pub fn record_len(&self) -> usize {
        self.vlr.items_size() as usize
    }

    pub fn points(&self) -> u64 {
        self.chunks.iter().map(|c| c.1).sum()
    }

    /// Decompresses chunk `i` into `out` (resized to its records).
    pub fn decompress(
        &self,
        i: usize,
        codec: Codec,
        decoder: &mut RawDecoder,
        out: &mut Vec<u8>,
    ) -> Result<(), String> {
        let (data, points) = self.chunks.get(i).ok_or("no such chunk")?;
        out.resize(*points as usize * self.record_len(), 0);
        match codec {
            Codec::Ours => {
                let items = Items::supported(self.vlr.items()).ok_or("items not supported")?;
                decoder
                    .0
                    .get_or_insert_with(|| Box::new(ChunkDecoder::new(items)))
                    .decompress(data, out)
            }
            Codec::LazCrate => {
                let entry = [ChunkTableEntry {
                    point_count: *points,
                    byte_count: data.len() as u64,
                }];
                laz::par_decompress(data, out, &self.vlr, &entry).map_err(|e| e.to_string())
            }
        }
    }
}

/// For the fuzz target: the first byte picks an item set (format 0–3, 0–3 extra bytes) and
/// how many points to claim; our decoder decompresses the rest `per_block` records at a time
/// (as the conversion does) and returns the records. Decoders are kept per item set and
/// thread, so the fuzzer also checks that nothing leaks from one chunk to the next.
pub fn fuzz_chunk(data: &[u8], per_block: usize) -> Result<Vec<u8>, String> {
    thread_local! {
        static DECODERS: std::cell::RefCell<Vec<Option<Box<ChunkDecoder>>>> =
            std::cell::RefCell::new((0..16).map(|_| None).collect());
    }
    let Some((&pick, chunk)) = data.split_first() else {
        return Ok(Vec::new());
    };
    let items = Items {
        gps: pick & 1 != 0,
        rgb: pick & 2 != 0,
        extra: u16::from((pick >> 2) & 3),
    };
    let points = 1 + usize::from(pick >> 4) * 97;
    let len = items.record_len();
    let mut block = vec![0; per_block.clamp(1, points) * len];
    let mut out = Vec::with_capacity(points * len);
    DECODERS.with(|d| {
        let mut d = d.borrow_mut();
        let slot = d.get_mut(usize::from(pick & 15)).ok_or("no decoder slot")?;
        slot.get_or_insert_with(|| Box::new(ChunkDecoder::new(items)))
            .decompress_blocks(chunk, points, &mut block, |at, recs| {
                if at * len != out.len() {
                    return Err(format!("a block for record {at} after {} bytes", out.len()));
                }
                out.extend_from_slice(recs);
                Ok(())
            })
    })?;
    Ok(out)
}
