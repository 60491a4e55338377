//! info / metrics / generate behave as documented.

mod common;
use common::*;

#[test]
fn info_json_has_the_documented_fields() {
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&data("simple.las")), "--json"])).expect("json");
    assert_eq!(v["points"], 1065);
    assert!(v["bounds"]["min"].as_array().map(|a| a.len()) == Some(3));
    let attrs = v["attributes"].as_array().expect("attributes");
    assert!(attrs.iter().any(|a| a == "rgb") && attrs.iter().any(|a| a == "gps_time"));
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    ok(&[
        "convert",
        s(&data("autzen_trim.laz")),
        "-o",
        s(&store),
        "--pointlets",
        "100",
    ]);
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&store), "--json", "--verify"])).expect("json");
    assert_eq!(v["points"], 110_000);
    // k = 2^round(log2(110000/100)) = 1024
    assert_eq!(v["pointlet_size"], 1024);
    assert_eq!(v["pointlets"], 110_000u64.div_ceil(1024));
    let text = ok(&["info", s(&store)]);
    assert!(
        text.contains("pointlets") && text.contains("110000"),
        "{text}"
    );
}

#[test]
fn info_reports_crs() {
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["info", s(&data("autzen_trim.laz")), "--json"])).expect("json");
    assert!(!v["crs"].is_null(), "autzen has a CRS: {v}");
}

#[test]
fn metrics_table_for_three_partitioners() {
    let v: serde_json::Value = serde_json::from_str(&ok(&[
        "metrics",
        s(&data("autzen_trim.laz")),
        "--json",
        "--pointlets",
        "200",
    ]))
    .expect("json");
    let r = v["results"].as_array().expect("results");
    assert_eq!(r.len(), 3);
    let mean = |i: usize| r[i]["mean_extent"].as_f64().expect("mean");
    // Hilbert pointlets are tighter than Morton ones on real airborne data (paper, Table I).
    assert!(mean(1) < mean(0), "{v}");
    let text = ok(&["metrics", s(&data("simple.las"))]);
    assert!(
        text.contains("Hilbert") && text.contains("k-d tree"),
        "{text}"
    );
}

#[test]
fn generate_is_deterministic() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = dir.path().join("a.las");
    let b = dir.path().join("b.las");
    ok(&["generate", "--points", "50000", "--seed", "3", "-o", s(&a)]);
    ok(&["generate", "--points", "50000", "--seed", "3", "-o", s(&b)]);
    assert_eq!(std::fs::read(&a).expect("a"), std::fs::read(&b).expect("b"));
    let v: serde_json::Value = serde_json::from_str(&ok(&["info", s(&a), "--json"])).expect("json");
    assert_eq!(v["points"], 50000);
}
