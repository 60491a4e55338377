//! The LAS header + VLR/EVLR parser must return Ok or a typed error for any bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = pointlet_io::las::parse_header(data);
});
