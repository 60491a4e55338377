//! Our LAZ chunk decoder on arbitrary bytes: the first byte picks the item set (formats 0–3,
//! up to 3 extra bytes) and the points claimed; it returns an error or records, never panics,
//! hangs or allocates beyond the records claimed.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = pointlet_io::las::raw::fuzz_chunk(data);
});
