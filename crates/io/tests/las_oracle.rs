//! Our LAS/LAZ/COPC reader against the `las` crate: every point, every attribute, every file
//! of testdata/; and the header metadata (counts, bounds, quantization, kept records).

mod common;
use common::*;
use pointlet_core::LasFields;

#[test]
fn every_shared_file_matches_the_las_crate_point_for_point() {
    for path in shared_files() {
        let expected = las_points(&path);
        // An odd batch size crosses LAZ chunk and block boundaries at awkward places.
        for batch in [777, 1 << 20] {
            let mut r = pointlet_io::open(&path).expect("open");
            let ours = read_all(r.as_mut(), batch);
            assert_eq!(ours.len(), expected.len(), "{}", path.display());
            for (i, e) in expected.iter().enumerate() {
                assert_eq!(
                    &our_fingerprint(&ours, i),
                    e,
                    "{} point {i} (batch {batch})",
                    path.display()
                );
            }
            assert!(r.read_batch(10).expect("after the end").is_none());
        }
    }
}

#[test]
fn header_metadata_matches_the_las_crate() {
    for path in shared_files() {
        let r = pointlet_io::open(&path).expect("open");
        let m = r.meta();
        let l = las::Reader::from_path(&path).expect("las");
        let h = l.header();
        let name = path.display();
        assert_eq!(m.point_count, h.number_of_points(), "{name}");
        let b = h.bounds();
        assert_eq!(m.bounds.min, [b.min.x, b.min.y, b.min.z], "{name}");
        assert_eq!(m.bounds.max, [b.max.x, b.max.y, b.max.z], "{name}");
        let q = m.quantization.expect("LAS has quantization");
        let t = h.transforms();
        assert_eq!(q.scale, [t.x.scale, t.y.scale, t.z.scale], "{name}");
        assert_eq!(q.offset, [t.x.offset, t.y.offset, t.z.offset], "{name}");
        let f = h.point_format();
        assert_eq!(
            m.las_point_format,
            Some(f.to_u8().expect("format") & 0x3F),
            "{name}"
        );
        assert_eq!(m.layout.gps_time, f.has_gps_time, "{name}");
        assert_eq!(m.layout.rgb, f.has_color, "{name}");
        assert_eq!(m.layout.nir, f.has_nir, "{name}");
        assert_eq!(m.layout.waveform, f.has_waveform, "{name}");
        assert_eq!(m.layout.extra_bytes, f.extra_bytes, "{name}");
        let v = h.version();
        let kind = if f.is_compressed { "LAZ" } else { "LAS" };
        assert!(
            m.format.starts_with(&format!(
                "{kind} {}.{} point format {}",
                v.major,
                v.minor,
                f.to_u8().expect("format") & 0x3F
            )),
            "{name}: {}",
            m.format
        );
        // Kept records: every one but LASzip's and COPC's, verbatim, VLRs then EVLRs (the las
        // crate keeps the bytes of a user id after its NUL; the waveform data is checked below).
        let want: Vec<(String, u16, Vec<u8>, bool)> = h
            .vlrs()
            .iter()
            .map(|v| (v, false))
            .chain(h.evlrs().iter().map(|v| (v, true)))
            .map(|(v, e)| {
                let user = v.user_id.split('\0').next().unwrap_or_default().to_string();
                (user, v.record_id, v.data.clone(), e)
            })
            .filter(|(u, id, _, _)| u != "laszip encoded" && u != "copc" && *id != 65535)
            .collect();
        let got: Vec<(String, u16, Vec<u8>, bool)> = m
            .vlrs
            .iter()
            .filter(|v| !v.is_waveform_data())
            .map(|v| (v.user_id.clone(), v.record_id, v.data.clone(), v.extended))
            .collect();
        assert_eq!(got, want, "{name}");
        let fields = m.las.as_ref().expect("LAS header fields");
        assert_eq!(fields.file_source_id, h.file_source_id(), "{name}");
        let adjusted = h.gps_time_type() == las::GpsTimeType::Standard;
        assert_eq!(
            fields.global_encoding & LasFields::ADJUSTED_STANDARD_GPS_TIME != 0,
            adjusted,
            "{name}"
        );
    }
}

#[test]
fn format_names() {
    let name = |f: &str| {
        pointlet_io::open(&data(f))
            .expect("open")
            .meta()
            .format
            .clone()
    };
    assert_eq!(name("simple.las"), "LAS 1.2 point format 3");
    assert_eq!(name("simple.laz"), "LAZ 1.2 point format 3");
    assert_eq!(name("simple.copc.laz"), "LAZ 1.4 point format 7 (COPC)");
    assert_eq!(name("test1_4.las"), "LAS 1.4 point format 6");
}

#[test]
fn parse_header_reads_the_whole_file_bytes() {
    let bytes = std::fs::read(data("simple1_4.las")).expect("read");
    let h = pointlet_io::las::parse_header(&bytes).expect("header");
    assert_eq!(h.version, (1, 4));
    assert_eq!(h.point_format, 7);
    assert_eq!(h.point_count, 22_600);
    assert!(!h.compressed);
    let copc = std::fs::read(data("simple.copc.laz")).expect("read");
    let h = pointlet_io::las::parse_header(&copc).expect("header");
    assert!(h.compressed && h.copc && h.laszip.is_some());
    assert_eq!(h.kept_vlrs.len(), 1, "the WKT record");
}

/// LAS 1.3 keeps its waveform data packets outside the EVLR count, behind a header pointer.
#[test]
fn the_waveform_data_of_a_las_1_3_file_is_kept_verbatim() {
    let bytes = std::fs::read(data("simple1_3.las")).expect("read");
    let h = pointlet_io::las::parse_header(&bytes).expect("header");
    let start = h.start_of_waveform_data as usize;
    assert!(
        start > 0 && h.global_encoding & 2 != 0,
        "internal waveform data"
    );
    let record = h
        .kept_vlrs
        .iter()
        .find(|v| v.is_waveform_data())
        .expect("the waveform data record");
    let len = u64::from_le_bytes(bytes[start + 20..start + 28].try_into().unwrap()) as usize;
    assert_eq!(record.data, bytes[start + 60..start + 60 + len]);
    assert!(record.extended);
    assert!(
        h.kept_vlrs.iter().any(|v| v.record_id == 100),
        "its descriptor"
    );
}
