//! Opening, reading and verifying a (damaged) store never panics.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let p = std::env::temp_dir().join(format!("pointlet-fuzz-{}.pointlet", std::process::id()));
    if std::fs::write(&p, data).is_err() {
        return;
    }
    if let Ok(store) = pointlet_store::Store::open(&p) {
        for i in 0..store.pointlets().len().min(64) {
            let _ = store.read_pointlet(i);
        }
        let _ = store.verify();
    }
    let _ = std::fs::remove_file(&p);
});
