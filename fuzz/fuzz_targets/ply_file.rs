//! PLY reading (header, every encoding, lists, the pre-pass and the batches) never panics or
//! hangs, through the entry point the commands use.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let p = std::env::temp_dir().join(format!("pointlet-fuzz-{}.ply", std::process::id()));
    if std::fs::write(&p, data).is_err() {
        return;
    }
    if let Ok(mut r) = pointlet_io::open(&p) {
        while let Ok(Some(b)) = r.read_batch(4096) {
            assert!(b.check_shape().is_ok());
        }
    }
    let _ = std::fs::remove_file(&p);
});
