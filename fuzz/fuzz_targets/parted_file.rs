//! A LAS or LAZ file's parts decoded as the conversion decodes them (records straight into
//! rows of the file's own quantization, a block at a time) and as points: never a panic or a
//! hang, and both ways give the same points or both fail.
#![no_main]
use libfuzzer_sys::fuzz_target;
use pointlet_core::rows::{row_position, RowLayout};
use pointlet_core::PointBatch;

/// Parts claiming more points than this are left to `las_file` (its batches bound what they
/// allocate).
const MAX_PART: u64 = 1 << 20;

fuzz_target!(|data: &[u8]| {
    let p = std::env::temp_dir().join(format!("pointlet-fuzz-{}.las", std::process::id()));
    if std::fs::write(&p, data).is_err() {
        return;
    }
    if let Ok(r) = pointlet_io::open(&p) {
        if let (Some(parts), Some(q)) = (r.parted(), r.meta().quantization) {
            let row = RowLayout::new(&r.meta().layout);
            let mut scratch = Vec::new();
            for (i, &n) in parts.part_sizes().iter().enumerate() {
                if n > MAX_PART {
                    continue;
                }
                let mut batch = PointBatch::default();
                let points = parts.decode_part(i, &mut batch, &mut scratch);
                let mut rows = vec![0xA5u8; n as usize * row.len];
                let mut next = 0;
                let by_rows =
                    parts.decode_part_rows(i, &q, &row, &mut rows, &mut scratch, &mut |at, r| {
                        assert_eq!(at, next, "part {i}: stretches out of order");
                        next += r.len() / row.len;
                    });
                match (points, by_rows) {
                    (Ok(()), Ok(true)) => {
                        assert_eq!(next as u64, n, "part {i}: stretches");
                        assert_eq!(batch.len() as u64, n, "part {i}: points");
                        let stored: Vec<[i32; 3]> =
                            rows.chunks_exact(row.len).map(row_position).collect();
                        for (k, (s, p)) in stored.iter().zip(&batch.xyz).enumerate() {
                            let d = q.dequantize(*s);
                            assert!(
                                (0..3).all(|a| d[a].to_bits() == p[a].to_bits()),
                                "part {i} point {k}: rows hold {d:?}, the points {p:?}"
                            );
                        }
                        let mut packed = vec![0u8; rows.len()];
                        row.pack(&batch, 0, &stored, &mut packed);
                        assert!(
                            rows == packed,
                            "part {i}: rows differ from the packed points"
                        );
                    }
                    (Err(_), Err(_)) => {}
                    // The file's own quantization and columns always fit its rows.
                    (_, Ok(false)) => panic!("part {i}: rows of the file's own layout declined"),
                    (a, b) => panic!("part {i}: as points {a:?}, as rows {b:?}"),
                }
            }
        }
    }
    let _ = std::fs::remove_file(&p);
});
