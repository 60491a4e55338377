//! Our LAZ chunk decoder on arbitrary bytes: the first byte picks the item set (formats 0–3,
//! up to 3 extra bytes) and the points claimed; it returns an error or records, never panics,
//! hangs or allocates beyond the records claimed. Decoded whole or a few records at a time
//! (the conversion decodes 1,024 at a time), a chunk gives the same records or the same error.
#![no_main]
use libfuzzer_sys::fuzz_target;
use pointlet_io::las::raw::fuzz_chunk;

fuzz_target!(|data: &[u8]| {
    let whole = fuzz_chunk(data, usize::MAX);
    let blocks = fuzz_chunk(data, 7);
    assert!(
        whole == blocks,
        "whole: {whole:?}, in blocks of 7: {blocks:?}"
    );
});
