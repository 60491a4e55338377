//! Helpers shared by the integration tests: the shared data folder and the `las` crate oracle.
#![allow(dead_code)]

use pointlet_core::{flags, PointBatch, WAVEFORM_BYTES};
use pointlet_io::PointReader;
use std::path::{Path, PathBuf};

pub fn data_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata"))
}

pub fn data(name: &str) -> PathBuf {
    let p = data_dir().join(name);
    assert!(p.exists(), "test data {} is missing", p.display());
    p
}

/// Every LAS/LAZ file of the shared data folder, sorted.
pub fn shared_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(data_dir())
        .expect("testdata/")
        .map(|e| e.expect("entry").path())
        .filter(|p| {
            let e = p.extension().and_then(|e| e.to_str()).unwrap_or("");
            e == "las" || e == "laz"
        })
        .collect();
    v.sort();
    assert!(
        v.len() >= 10,
        "expected the 10 files of testdata/, found {}",
        v.len()
    );
    v
}

/// All points of a reader, batch by batch of `batch` points.
pub fn read_all(r: &mut dyn PointReader, batch: usize) -> PointBatch {
    let mut all = PointBatch::new(r.meta().layout);
    while let Some(b) = r.read_batch(batch).expect("read_batch") {
        b.check_shape().expect("batch shape");
        assert!(b.len() <= batch && !b.is_empty());
        for i in 0..b.len() {
            all.push_from(&b, i);
        }
    }
    all
}

/// One point as the `las` crate sees it, every attribute as comparable bits.
pub fn las_fingerprint(p: &las::Point) -> Vec<u64> {
    let mut v = vec![
        p.x.to_bits(),
        p.y.to_bits(),
        p.z.to_bits(),
        p.intensity as u64,
        p.return_number as u64,
        p.number_of_returns as u64,
        u8::from(p.classification) as u64,
        p.is_synthetic as u64,
        p.is_key_point as u64,
        p.is_withheld as u64,
        p.is_overlap as u64,
        p.scanner_channel as u64,
        (p.scan_direction == las::point::ScanDirection::LeftToRight) as u64,
        p.is_edge_of_flight_line as u64,
        p.scan_angle.to_bits() as u64,
        p.user_data as u64,
        p.point_source_id as u64,
        p.gps_time.map(|t| t.to_bits()).unwrap_or(u64::MAX),
        p.nir.map(u64::from).unwrap_or(u64::MAX),
    ];
    if let Some(c) = p.color {
        v.extend([c.red as u64, c.green as u64, c.blue as u64]);
    }
    if let Some(w) = &p.waveform {
        v.extend([
            w.wave_packet_descriptor_index as u64,
            w.byte_offset_to_waveform_data,
            w.waveform_packet_size_in_bytes as u64,
            w.return_point_waveform_location.to_bits() as u64,
            w.x_t.to_bits() as u64,
            w.y_t.to_bits() as u64,
            w.z_t.to_bits() as u64,
        ]);
    }
    v.extend(p.extra_bytes.iter().map(|b| *b as u64));
    v
}

/// Point `i` of our batch in the same terms as [`las_fingerprint`].
pub fn our_fingerprint(b: &PointBatch, i: usize) -> Vec<u64> {
    let f = b.flags[i];
    let bit = |m: u8| u64::from(f & m != 0);
    let mut v = vec![
        b.xyz[i][0].to_bits(),
        b.xyz[i][1].to_bits(),
        b.xyz[i][2].to_bits(),
        b.intensity[i] as u64,
        (b.returns[i] & 0x0F) as u64,
        (b.returns[i] >> 4) as u64,
        b.classification[i] as u64,
        bit(flags::SYNTHETIC),
        bit(flags::KEY_POINT),
        bit(flags::WITHHELD),
        bit(flags::OVERLAP),
        (f >> flags::CHANNEL_SHIFT) as u64,
        bit(flags::SCAN_DIRECTION),
        bit(flags::EDGE_OF_FLIGHT_LINE),
        b.scan_angle[i].to_bits() as u64,
        b.user_data[i] as u64,
        b.point_source_id[i] as u64,
        if b.layout.gps_time {
            b.gps_time[i].to_bits()
        } else {
            u64::MAX
        },
        if b.layout.nir {
            b.nir[i] as u64
        } else {
            u64::MAX
        },
    ];
    if b.layout.rgb {
        v.extend(b.rgb[i].iter().map(|c| *c as u64));
    }
    if b.layout.waveform {
        let w: &[u8; WAVEFORM_BYTES] = &b.waveform[i];
        let u32_at = |a: usize| u32::from_le_bytes(w[a..a + 4].try_into().unwrap()) as u64;
        v.extend([
            w[0] as u64,
            u64::from_le_bytes(w[1..9].try_into().unwrap()),
            u32_at(9),
            u32_at(13),
            u32_at(17),
            u32_at(21),
            u32_at(25),
        ]);
    }
    let e = b.layout.extra_bytes as usize;
    v.extend(b.extra_bytes[i * e..(i + 1) * e].iter().map(|x| *x as u64));
    v
}

/// Every point of `path` through the `las` crate, in file order.
pub fn las_points(path: &Path) -> Vec<Vec<u64>> {
    let mut r = las::Reader::from_path(path)
        .unwrap_or_else(|e| panic!("las crate reading {}: {e}", path.display()));
    let all = r
        .read_all()
        .unwrap_or_else(|e| panic!("las crate reading {}: {e}", path.display()));
    all.points()
        .map(|p| las_fingerprint(&p.expect("las point")))
        .collect()
}
