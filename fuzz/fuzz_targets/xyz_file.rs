//! Text point reading (column detection, headers, `--columns`, the pre-pass and the batches)
//! never panics or hangs. An input starting with `@` names the columns in its first line, as
//! `--columns` does (`@x,y,z,r,g,b,intensity`); the rest is the file.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut options = pointlet_io::ReadOptions::default();
    let mut file = data;
    if let Some(rest) = data.strip_prefix(b"@") {
        let end = rest.iter().position(|b| *b == b'\n').unwrap_or(rest.len());
        let names = String::from_utf8_lossy(&rest[..end]);
        options.columns = Some(names.split(',').map(String::from).collect());
        file = rest.get(end + 1..).unwrap_or_default();
    }
    let p = std::env::temp_dir().join(format!("pointlet-fuzz-{}.xyz", std::process::id()));
    if std::fs::write(&p, file).is_err() {
        return;
    }
    if let Ok(mut r) = pointlet_io::open_with(&p, &options) {
        while let Ok(Some(b)) = r.read_batch(4096) {
            assert!(b.check_shape().is_ok());
        }
    }
    let _ = std::fs::remove_file(&p);
});
