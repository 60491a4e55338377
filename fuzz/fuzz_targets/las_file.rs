//! Whole-file reading (header, VLRs, LAS records or LAZ chunks) never panics or hangs.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let p = std::env::temp_dir().join(format!("pointlet-fuzz-{}.las", std::process::id()));
    if std::fs::write(&p, data).is_err() {
        return;
    }
    if let Ok(mut r) = pointlet_io::open(&p) {
        while let Ok(Some(_)) = r.read_batch(4096) {}
    }
    let _ = std::fs::remove_file(&p);
});
