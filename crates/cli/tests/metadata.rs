//! What a file says about its points besides the points: header fields, records, waveform
//! data, CRS and bounds survive convert → export, `info` reports them, and merges check them.
//! Variants of testdata files are made by patching copies in a temporary folder.

mod common;
use common::*;
use pointlet_io::las::{parse_header, LasHeader};
use std::path::{Path, PathBuf};

fn header(path: &Path) -> LasHeader {
    parse_header(&std::fs::read(path).expect("read")).expect("header")
}

/// Records as (user id, record id, data), sorted; LASzip's and COPC's are the writer's own.
fn records(h: &LasHeader) -> Vec<(String, u16, Vec<u8>)> {
    let mut r: Vec<_> = h
        .kept_vlrs
        .iter()
        .map(|v| (v.user_id.clone(), v.record_id, v.data.clone()))
        .collect();
    r.sort();
    r
}

fn info(path: &Path) -> serde_json::Value {
    serde_json::from_str(&ok(&["info", s(path), "--json"])).expect("json")
}

/// A copy of `name` in `dir` with `edit` applied to its bytes.
fn patched(dir: &Path, name: &str, copy: &str, edit: impl Fn(&mut Vec<u8>)) -> PathBuf {
    let mut bytes = std::fs::read(data(name)).expect("read");
    edit(&mut bytes);
    let out = dir.join(copy);
    std::fs::write(&out, bytes).expect("write");
    out
}

/// Sets GeoTIFF keys (`key` = `value`, stored in place) in the key directory VLR.
fn set_geokeys(bytes: &mut [u8], keys: &[(u16, u16)]) {
    let u16_at = |b: &[u8], at: usize| u16::from_le_bytes([b[at], b[at + 1]]);
    let count = u32::from_le_bytes(bytes[100..104].try_into().unwrap());
    let mut pos = u16_at(bytes, 94) as usize;
    for _ in 0..count {
        let len = u16_at(bytes, pos + 20) as usize;
        if u16_at(bytes, pos + 18) == 34735 {
            let data = pos + 54;
            for entry in (data + 8..data + len).step_by(8) {
                for (key, value) in keys {
                    if u16_at(bytes, entry) == *key && u16_at(bytes, entry + 2) == 0 {
                        bytes[entry + 6..entry + 8].copy_from_slice(&value.to_le_bytes());
                    }
                }
            }
        }
        pos += 54 + len;
    }
}

#[test]
fn export_writes_back_the_header_fields_and_records_of_every_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    let las = dir.path().join("back.las");
    for entry in std::fs::read_dir(data_dir()).expect("testdata") {
        let input = entry.expect("entry").path();
        if !matches!(
            input.extension().and_then(|e| e.to_str()),
            Some("las" | "laz")
        ) {
            continue;
        }
        ok(&["convert", s(&input), "-o", s(&store)]);
        ok(&["export", s(&store), "-o", s(&las)]);
        let (a, b) = (header(&input), header(&las));
        let name = input.display();
        let v = info(&store);
        assert_eq!(v["file_source_id"], a.fields.file_source_id, "{name}");
        assert_eq!(a.fields, b.fields, "{name}: header fields");
        assert_eq!(records(&a), records(&b), "{name}: records");
        // The las crate reads the GPS time type and file source id alike.
        let (la, lb) = (
            las::Reader::from_path(&input).expect("las"),
            las::Reader::from_path(&las).expect("las"),
        );
        assert_eq!(la.header().gps_time_type(), lb.header().gps_time_type());
        assert_eq!(la.header().file_source_id(), lb.header().file_source_id());
        // Waveform data is where the header says, so the descriptors point into it.
        let waveform = a.kept_vlrs.iter().any(|v| v.is_waveform_data());
        let bytes = std::fs::read(&las).expect("read");
        let at = b.start_of_waveform_data as usize;
        assert_eq!(at != 0, waveform, "{name}: waveform pointer");
        assert_eq!(b.global_encoding & 2 != 0, waveform, "{name}: internal bit");
        if waveform {
            let record = a.kept_vlrs.iter().find(|v| v.is_waveform_data()).unwrap();
            assert_eq!(bytes[at + 18..at + 20], [0xFF, 0xFF], "{name}");
            assert_eq!(
                &bytes[at + 60..at + 60 + record.data.len()],
                &record.data[..]
            );
        }
    }
}

#[test]
fn without_their_waveform_data_descriptors_are_cleared() {
    let dir = tempfile::tempdir().expect("tempdir");
    // The copy says its packets are in an external file, which a store cannot carry.
    let external = patched(dir.path(), "simple1_3.las", "external.las", |b| b[6] = 4);
    let store = dir.path().join("m.pointlet");
    let back = dir.path().join("m.las");
    ok(&["convert", s(&external), "-o", s(&store)]);
    ok(&["export", s(&store), "-o", s(&back)]);
    assert_descriptors_cleared(&back);
    // Merged with a file without the packets, the packets are not common to the inputs.
    ok(&[
        "convert",
        s(&data("simple1_3.las")),
        s(&external),
        "-o",
        s(&store),
    ]);
    ok(&["export", s(&store), "-o", s(&back)]);
    assert_descriptors_cleared(&back);
}

fn assert_descriptors_cleared(back: &Path) {
    let h = header(back);
    assert_eq!(h.start_of_waveform_data, 0);
    assert_eq!(h.global_encoding & 0b110, 0, "no waveform bits");
    assert!(!h.kept_vlrs.iter().any(|v| v.is_waveform_data()));
    let mut r = las::Reader::from_path(back).expect("las");
    let all = r.read_all().expect("points");
    let mut with_packets = 0;
    for p in all.points() {
        let p = p.expect("point");
        let w = p.waveform.expect("format with waveforms");
        with_packets +=
            usize::from(w.wave_packet_descriptor_index != 0 || w.byte_offset_to_waveform_data != 0);
    }
    assert_eq!(with_packets, 0, "descriptors pointing at nothing");
}

#[test]
fn info_names_the_crs() {
    let dir = tempfile::tempdir().expect("tempdir");
    // autzen_trim's own keys are user-defined (32767) LCC parameters, cited by name.
    let v = info(&data("autzen_trim.laz"));
    assert_eq!(v["crs"]["user_defined"], true, "{v}");
    assert_eq!(
        v["crs"]["name"],
        "user-defined (NAD_1983_HARN_Lambert_Conformal_Conic)"
    );
    // With EPSG codes in both keys, the projected one is the CRS, not its geographic base.
    let coded = patched(dir.path(), "autzen_trim.laz", "coded.laz", |b| {
        set_geokeys(b, &[(2048, 4152), (3072, 2994)])
    });
    let v = info(&coded);
    assert_eq!(v["crs"]["epsg"], 2994, "{v}");
    assert_eq!(v["crs"]["name"], "EPSG:2994");
    let v = info(&data("plane.laz"));
    assert_eq!(v["crs"]["user_defined"], true, "{v}");
    assert_eq!(v["crs"]["epsg"], serde_json::Value::Null);
    assert!(!v["crs"]["name"].as_str().unwrap().contains("32767"));
    let v = info(&data("test1_4.las"));
    assert_eq!(v["crs"]["name"], "EPSG:2903 + EPSG:5703 vertical", "{v}");
    let text = ok(&["info", s(&coded)]);
    assert!(text.contains("EPSG:2994 (GeoTIFF keys)"), "{text}");
}

#[test]
fn merging_inputs_in_different_crss_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = patched(dir.path(), "autzen_trim.laz", "a.laz", |b| {
        set_geokeys(b, &[(3072, 2994)])
    });
    let b = patched(dir.path(), "autzen_trim.laz", "b.laz", |b| {
        set_geokeys(b, &[(3072, 2992)])
    });
    let out = dir.path().join("m.pointlet");
    let err = fails(
        &["convert", s(&a), s(&b), "-o", s(&out)],
        &["a.laz", "b.laz", "EPSG:2994", "EPSG:2992", "different CRSs"],
    );
    assert_eq!(
        err.matches(s(&a)).count(),
        1,
        "each input named once: {err}"
    );
    assert!(!out.exists());
    assert_eq!(listing(dir.path()).len(), 2, "{:?}", listing(dir.path()));
    // The same CRS twice, and a file without CRS records, merge.
    ok(&[
        "convert",
        s(&a),
        s(&a),
        s(&data("simple.las")),
        "-o",
        s(&out),
    ]);
    assert_eq!(info(&out)["crs"]["name"], "EPSG:2994");
}

/// Mean pointlet AABB diagonal and bounds of a store converted from `input`.
fn quality(input: &Path, store: &Path) -> (serde_json::Value, serde_json::Value) {
    ok(&["convert", s(input), "-o", s(store), "--pointlets", "200"]);
    let v = info(store);
    (v["pointlet_extent"].clone(), v["bounds"].clone())
}

#[test]
fn wrong_header_bounds_make_the_same_pointlets() {
    let dir = tempfile::tempdir().expect("tempdir");
    let put_bounds = |b: &mut Vec<u8>, f: &dyn Fn(f64) -> f64| {
        for at in (179..227).step_by(8) {
            let v = f64::from_le_bytes(b[at..at + 8].try_into().unwrap());
            b[at..at + 8].copy_from_slice(&f(v).to_le_bytes());
        }
    };
    let zeroed = patched(dir.path(), "autzen_trim.laz", "zero.laz", |b| {
        put_bounds(b, &|_| 0.0)
    });
    let scaled = patched(dir.path(), "autzen_trim.laz", "scaled.laz", |b| {
        put_bounds(b, &|v| v * 1000.0)
    });
    let want = quality(&data("autzen_trim.laz"), &dir.path().join("a.pointlet"));
    for input in [zeroed, scaled] {
        let got = quality(&input, &dir.path().join("b.pointlet"));
        assert_eq!(got, want, "{}", input.display());
        // info warns about such headers and gives the points' bounds.
        let out = pointlet(&["info", s(&input), "--json"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("warning: the header bounds"), "{err}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        assert_eq!(v["header_bounds_agree"], false);
        assert_eq!(v["bounds"], want.1);
    }
}

#[test]
fn info_reports_the_points_bounds_beside_the_header_ones() {
    let v = info(&data("simple1_3.las"));
    let min = |k: &str| v[k]["min"][0].as_f64().expect("min x");
    // The header of laspy's simple1_3.las is off by 10^3.
    assert_eq!(min("header_bounds"), -235434519.0);
    assert!((min("bounds") - -235434.519).abs() < 1e-6, "{v}");
    assert_eq!(v["header_bounds_agree"], false);
    let v = info(&data("autzen_trim.laz"));
    assert_eq!(v["header_bounds_agree"], true);
    let text = ok(&["info", s(&data("simple1_3.las"))]);
    assert!(text.contains("header bounds min") && text.contains("bounds min"));
}
