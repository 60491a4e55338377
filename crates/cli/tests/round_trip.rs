//! convert → export gives back exactly the points that went in, checked with an independent
//! reader (the `las` crate), for every real file in testdata/ and for generated data.

mod common;
use common::*;

/// Every attribute of a point as comparable bits; the multiset is the sorted list of these.
fn fingerprint(p: &las::Point) -> Vec<u64> {
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
        (p.scan_angle as f64 * 1000.0).round() as i64 as u64,
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

fn multiset(path: &std::path::Path) -> Vec<Vec<u64>> {
    use las::Reader;
    let mut r = Reader::from_path(path)
        .unwrap_or_else(|e| panic!("las crate reading {}: {e}", path.display()));
    let data = r
        .read_all()
        .unwrap_or_else(|e| panic!("las crate reading {}: {e}", path.display()));
    let mut v: Vec<Vec<u64>> = data
        .points()
        .map(|p| fingerprint(&p.expect("point")))
        .collect();
    v.sort();
    v
}

fn round_trip(input: &std::path::Path, ext: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    let back = dir.path().join(format!("back.{ext}"));
    ok(&["convert", s(input), "-o", s(&store)]);
    ok(&["export", s(&store), "-o", s(&back)]);
    let a = multiset(input);
    let b = multiset(&back);
    assert_eq!(a.len(), b.len(), "{}: point count", input.display());
    assert!(
        a == b,
        "{}: points or attributes differ after convert → export",
        input.display()
    );
}

#[test]
fn every_shared_file_round_trips() {
    let mut n = 0;
    for e in std::fs::read_dir(data_dir()).expect("testdata/") {
        let p = e.expect("entry").path();
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext == "las" || ext == "laz" {
            round_trip(&p, "las");
            n += 1;
        }
    }
    assert!(n >= 10, "expected the 10 files of testdata/, found {n}");
}

#[test]
fn laz_export_round_trips() {
    round_trip(&data("autzen_trim.laz"), "laz");
}

#[test]
fn generated_data_round_trips_and_budget_does_not_change_the_store() {
    let dir = tempfile::tempdir().expect("tempdir");
    let laz = dir.path().join("gen.laz");
    ok(&["generate", "--points", "300k", "--seed", "5", "-o", s(&laz)]);
    round_trip(&laz, "las");
    // Out of core (budget far below the ~15 MB of points) equals in memory, byte for byte.
    let mem = dir.path().join("mem.pointlet");
    let ooc = dir.path().join("ooc.pointlet");
    ok(&["convert", s(&laz), "-o", s(&mem)]);
    ok(&["convert", s(&laz), "-o", s(&ooc), "--ram-budget", "1MiB"]);
    let a = std::fs::read(&mem).expect("mem store");
    let b = std::fs::read(&ooc).expect("ooc store");
    assert!(a == b, "out-of-core store differs from the in-memory one");
    // Generating straight into a store gives the same store as generate → convert.
    let direct = dir.path().join("direct.pointlet");
    ok(&[
        "generate",
        "--points",
        "300k",
        "--seed",
        "5",
        "-o",
        s(&direct),
    ]);
    let info_a: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&mem), "--json"])).expect("json");
    let info_b: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&direct), "--json"])).expect("json");
    assert_eq!(info_a["points"], info_b["points"]);
    assert_eq!(info_a["bounds"], info_b["bounds"]);
}

#[test]
fn several_inputs_merge_into_one_store() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("m.pointlet");
    ok(&[
        "convert",
        s(&data("simple.las")),
        s(&data("simple.laz")),
        "-o",
        s(&store),
    ]);
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&store), "--json"])).expect("json");
    assert_eq!(v["points"], 2130);
    let back = dir.path().join("m.las");
    ok(&["export", s(&store), "-o", s(&back)]);
    let mut both = multiset(&data("simple.las"));
    both.extend(multiset(&data("simple.laz")));
    both.sort();
    assert!(multiset(&back) == both);
}

#[test]
fn bbox_export_keeps_exactly_the_points_inside() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("a.pointlet");
    let input = data("autzen_trim.laz");
    ok(&["convert", s(&input), "-o", s(&store)]);
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&store), "--json"])).expect("json");
    let min: Vec<f64> = serde_json::from_value(v["bounds"]["min"].clone()).expect("min");
    let max: Vec<f64> = serde_json::from_value(v["bounds"]["max"].clone()).expect("max");
    let mid = [(min[0] + max[0]) / 2.0, (min[1] + max[1]) / 2.0];
    let bbox = format!(
        "{},{},{},{},{},{}",
        min[0], min[1], min[2], mid[0], mid[1], max[2]
    );
    let out = dir.path().join("part.las");
    ok(&["export", s(&store), "-o", s(&out), "--bbox", &bbox]);
    let expected: Vec<Vec<u64>> = multiset(&input)
        .into_iter()
        .filter(|f| f64::from_bits(f[0]) <= mid[0] && f64::from_bits(f[1]) <= mid[1])
        .collect();
    let got = multiset(&out);
    assert!(!got.is_empty() && got.len() < 110_000);
    assert!(
        got == expected,
        "bbox export differs: {} vs {}",
        got.len(),
        expected.len()
    );
}
