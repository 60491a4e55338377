//! Reading any input (store or point file) into memory for the commands that need it whole.

use anyhow::{Context, Result};
use pointlet_core::Aabb;
use std::path::Path;

/// Stores are recognised by their extension; anything else goes to the point-file readers.
pub fn is_store_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.eq_ignore_ascii_case("pointlet"))
        .unwrap_or(false)
}

/// All positions of a store or point file, with their bounds.
pub fn load_positions(path: &Path) -> Result<(Vec<[f64; 3]>, Aabb)> {
    let mut pts = Vec::new();
    let mut bounds = Aabb::EMPTY;
    if is_store_path(path) {
        let store = pointlet_store::Store::open(path)?;
        let q = store.header().quantization;
        pts.reserve(store.header().points as usize);
        for (i, p) in store.pointlets().iter().enumerate() {
            for raw in store
                .read_positions(i, 0..p.count)
                .with_context(|| format!("reading pointlet {i}"))?
            {
                let v = q.dequantize(raw);
                bounds.grow(v);
                pts.push(v);
            }
        }
    } else {
        let mut r = pointlet_io::open(path)?;
        while let Some(b) = r.read_batch(1 << 20)? {
            for p in &b.xyz {
                bounds.grow(*p);
            }
            pts.extend_from_slice(&b.xyz);
        }
    }
    Ok((pts, bounds))
}
