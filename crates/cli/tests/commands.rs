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

/// Lit pixels of a PNG (any channel above 0).
fn lit_pixels(path: &std::path::Path) -> usize {
    png_rgba(path)
        .chunks_exact(4)
        .filter(|p| p[..3] != [0, 0, 0])
        .count()
}

#[test]
fn data_without_colours_is_drawn_by_its_intensity_or_elevation() {
    let dir = tempfile::tempdir().expect("tempdir");
    let size = ["--width", "160", "--height", "120"];
    // test1_4.las is point format 6 (no RGB); plane.laz has an RGB column that is all zero.
    for (file, reason) in [
        ("test1_4.las", "has no rgb"),
        ("plane.laz", "rgb is black everywhere"),
    ] {
        let store = dir.path().join(format!("{file}.pointlet"));
        ok(&["convert", s(&data(file)), "-o", s(&store)]);
        for input in [data(file), store.clone()] {
            let png = dir.path().join("out.png");
            let mut args = vec!["render", s(&input), "-o", s(&png)];
            args.extend_from_slice(&size);
            let err = ok_stderr(&args).to_lowercase();
            assert!(
                err.contains("note:")
                    && err.contains("colouring by intensity")
                    && err.contains(reason),
                "{input:?}: the chosen colouring is said:\n{err}"
            );
            assert!(lit_pixels(&png) > 100, "{input:?} drawn black");
        }
        let json = dir.path().join("bench.json");
        let err = ok_stderr(&[
            "bench",
            s(&store),
            "--frames",
            "2",
            "--warmup",
            "0",
            "--width",
            "64",
            "--height",
            "48",
            "--json",
            s(&json),
        ]);
        assert!(err.contains("colouring by intensity"), "bench: {err}");
    }
    // Data with colours keeps them; an explicit colouring the data lacks is an error.
    let png = dir.path().join("rgb.png");
    let err = ok_stderr(&[
        "render",
        s(&data("simple.las")),
        "-o",
        s(&png),
        "--width",
        "64",
    ]);
    assert!(err.contains("colouring by rgb"), "{err}");
    let store = dir.path().join("test1_4.las.pointlet");
    for input in [data("test1_4.las"), store] {
        fails(
            &["render", s(&input), "-o", s(&png), "--color", "rgb"],
            &["test1_4.las", "no rgb attribute"],
        );
    }
}

#[test]
fn flags_that_do_not_apply_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    ok(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    let png = dir.path().join("x.png");
    let (file, store, png) = (
        s(&data("simple.las")).to_string(),
        s(&store).to_string(),
        s(&png),
    );
    let store_only = [
        ["--bucket", "10"],
        ["--vram-budget", "1GiB"],
        ["--ram-budget", "1GiB"],
        ["--upload-per-frame", "1k"],
        ["--pool-page-size", "512"],
        ["--loaders", "2"],
        ["--residency-threads", "2"],
        ["--max-frames", "5"],
    ];
    for input in [Some(file.as_str()), None] {
        let kind = if input.is_some() {
            "a point file"
        } else {
            "the demo scene"
        };
        for flag in store_only
            .iter()
            .map(|f| &f[..])
            .chain([&["--no-converge"][..]])
        {
            let mut args = vec!["render", "-o", png];
            args.extend(input);
            args.extend_from_slice(flag);
            // A point file drawn while it loads takes a VRAM budget and a frame limit too.
            let loading_too = ["--vram-budget", "--max-frames"].contains(&flag[0]);
            match (input, loading_too) {
                (Some(_), true) => {
                    let elsewhere = tempfile::tempdir().expect("tempdir");
                    let out = elsewhere.path().join("ok.png");
                    args[2] = s(&out);
                    args.extend(["--width", "32", "--height", "32"]);
                    ok(&args);
                }
                (None, true) => usage_fails(
                    &args,
                    &[
                        flag[0],
                        "stores and point files drawn while they load",
                        kind,
                    ],
                ),
                (_, false) => usage_fails(&args, &[flag[0], "applies to stores only", kind]),
            }
        }
    }
    // Read whole (a blending rasterizer), a point file takes neither.
    for flag in [["--vram-budget", "1GiB"], ["--max-frames", "5"]] {
        usage_fails(
            &[
                "render", "-o", png, &file, "--raster", "hqs", flag[0], flag[1],
            ],
            &[flag[0], "not to a point file"],
        );
    }
    for flag in [["--order", "morton"], ["--page-size", "1024"]] {
        usage_fails(
            &["render", &store, "-o", png, flag[0], flag[1]],
            &[
                flag[0],
                "point files and the demo scene only, not to a store",
            ],
        );
        usage_fails(
            &["view", &store, flag[0], flag[1]],
            &[flag[0], "not to a store"],
        );
        usage_fails(
            &["bench", &store, flag[0], flag[1]],
            &[flag[0], "not to a store"],
        );
    }
    for cmd in ["render", "view", "bench"] {
        let mut args = vec![cmd, &store, "--raster", "hw-points"];
        if cmd == "render" {
            args.extend(["-o", png]);
        }
        usage_fails(
            &args,
            &["hw-points draws point files and the demo scene only"],
        );
    }
    for flag in [["--bucket", "10"], ["--ram-budget", "1GiB"]] {
        usage_fails(
            &["view", &file, "--frames", "1", flag[0], flag[1]],
            &[flag[0], "stores only"],
        );
    }
    for flag in [["--vram-budget", "1GiB"], ["--converge-timeout", "3"]] {
        usage_fails(
            &[
                "view", &file, "--raster", "hqs", "--frames", "1", flag[0], flag[1],
            ],
            &[flag[0], "not to a point file"],
        );
    }
    usage_fails(&["view", &store, "--converge-timeout", "3"], &["--frames"]);
    usage_fails(
        &["render", &file, "-o", png, "--demo-points", "1000"],
        &["--demo-points", "the demo scene"],
    );
    usage_fails(
        &["render", &file, "-o", png, "--edl-strength", "2"],
        &["--edl"],
    );
    usage_fails(
        &["render", &file, "-o", png, "--occlusion-radius", "2"],
        &["--occlusion"],
    );
    usage_fails(&["render", &file, "-o", png, "--up", "0,1,0"], &["--eye"]);
    usage_fails(
        &[
            "render", &file, "-o", png, "--view", "closeup", "--eye", "0,0,9", "--target", "0,0,0",
        ],
        &["--view", "not to a camera placed by --eye/--target"],
    );
    usage_fails(
        &["bench", &store, "--quality", "--frames", "10"],
        &["--frames", "not to --quality"],
    );
    usage_fails(
        &["bench", &store, "--buckets", "1k"],
        &["--buckets", "applies to --quality"],
    );
    usage_fails(
        &["bench", &store, "--path", "p.json", "--orbit-seconds", "3"],
        &["--orbit-seconds", "--path orbit"],
    );
    usage_fails(
        &["bench-raster", &file, "--points", "1k"],
        &["--points", "the generated scene"],
    );
    let las = dir.path().join("g.las");
    usage_fails(
        &[
            "generate",
            "--points",
            "1k",
            "-o",
            s(&las),
            "--pointlets",
            "10",
        ],
        &["--pointlets", ".pointlet output"],
    );
    assert!(
        !las.exists() && !std::path::Path::new(png).exists(),
        "nothing written"
    );
}

#[test]
fn bench_raster_never_reports_impossible_timings() {
    let dir = tempfile::tempdir().expect("tempdir");
    let json = dir.path().join("r.json");
    let out = pointlet(&[
        "bench-raster",
        s(&data("autzen_trim.laz")),
        "--frames",
        "3",
        "--width",
        "320",
        "--height",
        "240",
        "--orders",
        "original",
        "--encodings",
        "full16",
        "--json",
        s(&json),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    let rows = v["rows"].as_array().expect("rows");
    match v["unreliable"].as_str() {
        // A driver whose timestamps cannot be trusted (lavapipe's): said, and no figures.
        Some(why) => {
            assert!(rows.is_empty(), "{v}");
            assert!(
                text.contains("timings unreliable") && text.contains(why),
                "{text}"
            );
            assert!(
                !text.contains("% of copy") && !text.contains("speed-up"),
                "{text}"
            );
            // The progress lines on stderr mark the times they show as implausible too.
            let err = String::from_utf8_lossy(&out.stderr);
            let timed = err.lines().any(|l| l.trim_end().ends_with(" ms"));
            assert!(!timed || err.contains("(implausible)"), "{err}");
        }
        // Else no rasterizer reads even its positions faster than the copy kernel moves memory.
        None => {
            let copy = v["copy_gb_per_s"].as_f64().expect("copy kernel");
            for r in rows {
                let read = r["position_gb_per_s"].as_f64().expect("position GB/s");
                assert!(
                    read <= copy && r["median_ms"].as_f64() > Some(0.0),
                    "impossible: {r}"
                );
            }
        }
    }
}

#[test]
fn convert_writes_stores_only_and_export_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    for name in ["out.las", "out.laz", "out"] {
        let out = dir.path().join(name);
        fails(
            &["convert", s(&data("simple.las")), "-o", s(&out)],
            &[name, "must end in .pointlet", "export"],
        );
    }
    let store = dir.path().join("s.pointlet");
    ok(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    let again = dir.path().join("again.pointlet");
    fails(
        &["export", s(&store), "-o", s(&again)],
        &["again.pointlet", ".las or .laz", "convert"],
    );
    assert_eq!(listing(dir.path()), ["s.pointlet"], "nothing else written");
}

#[test]
fn a_successful_render_prints_no_error_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("x.png");
    // As on a headless machine: no session runtime folder (libwayland's complaint).
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_pointlet"))
        .args([
            "render",
            s(&data("simple.las")),
            "-o",
            s(&png),
            "--width",
            "64",
            "--height",
            "48",
        ])
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .output()
        .expect("running pointlet");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        !err.lines().any(|l| l.starts_with("error")),
        "an error line on success:\n{err}"
    );
}

#[test]
fn rates_and_info_numbers_read_as_people_write_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    let err = ok_stderr(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    // "(25.4 k points/s; reading …)": three significant digits and a unit, then stage times.
    let rate = err
        .rsplit('(')
        .next()
        .and_then(|r| r.split_once(" points/s; reading "))
        .map(|(rate, _)| rate)
        .unwrap_or_else(|| panic!("no rate: {err}"));
    for stage in ["reading", "sorting", "writing"] {
        assert!(err.contains(&format!("{stage} ")), "no {stage} time: {err}");
    }
    let number = rate.split(' ').next().expect("number");
    let digits = number.chars().filter(|c| c.is_ascii_digit()).count();
    assert!(
        digits <= 3 && number.parse::<f64>().is_ok_and(|v| v > 0.0),
        "rate '{rate}' in: {err}"
    );
    for input in [data("simple.las"), store] {
        let text = ok(&["info", s(&input)]);
        assert!(text.contains("[635619.85,848899.7,406.59]"), "{text}");
        assert!(!text.contains("-0.0") && !text.contains("00000"), "{text}");
        let json = ok(&["info", s(&input), "--json"]);
        assert!(
            json.contains("848899.7") && !json.contains("848899.70000"),
            "{json}"
        );
        assert!(!json.contains("-0.0"), "{json}");
    }
}

#[test]
fn render_of_the_demo_scene_says_its_point_count_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("demo.png");
    let args = [
        "render",
        "-o",
        s(&png),
        "--demo-points",
        "1234",
        "--width",
        "64",
        "--height",
        "48",
    ];
    let out = pointlet(&args);
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{said}");
    assert_eq!(said.matches("1234").count(), 1, "{said}");
}

#[test]
fn export_of_a_point_file_says_to_convert_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = data("simple.las");
    let out = dir.path().join("x.las");
    let err = fails(
        &["export", s(&las), "-o", s(&out)],
        &["simple.las", "export", "pointlet convert"],
    );
    assert!(!err.contains("damaged"), "{err}");
    assert!(listing(dir.path()).is_empty(), "nothing written");
}

#[test]
fn bench_quality_refuses_a_zero_bucket_as_render_does() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("g.pointlet");
    ok(&["generate", "--points", "5000", "-o", s(&store)]);
    usage_fails(
        &["bench", s(&store), "--quality", "--buckets", "1000,0"],
        &["--buckets", "at least 1"],
    );
}

#[test]
fn info_names_extra_bytes_attributes_from_their_record() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("eb.pointlet");
    ok(&["convert", s(&data("extrabytes.las")), "-o", s(&store)]);
    for input in [data("extrabytes.las"), store] {
        let text = ok(&["info", s(&input)]);
        // The record describes 20 of the 27 bytes: a u16 triple, an i8 pair, a u32, a u64,
        // and 7 undocumented bytes between them.
        for a in [
            "Colors[0] (u16, extra), Colors[1] (u16, extra), Colors[2] (u16, extra)",
            "Flags[0] (i8, extra), Flags[1] (i8, extra)",
            "Intensity (u32, extra), Time (u64, extra), extra_bytes[7]",
        ] {
            assert!(text.contains(a), "{a} missing in:\n{text}");
        }
    }
}

#[test]
fn every_standard_attribute_can_colour_files_and_stores() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.pointlet");
    ok(&["convert", s(&data("simple.las")), "-o", s(&store)]);
    for (k, input) in [data("simple.las"), store].iter().enumerate() {
        let render = |mode: &str| {
            let png = dir.path().join(format!("{k}-{mode}.png"));
            let args = ["render", s(input), "-o", s(&png), "--width", "64"];
            ok(&[&args[..], &["--color", mode]].concat());
            std::fs::read(&png).expect("png")
        };
        let elevation = render("elevation");
        for mode in ["scan-angle", "user-data"] {
            assert!(render(mode) != elevation, "{mode} draws like elevation");
        }
        fails(
            &[
                "render",
                s(input),
                "-o",
                s(&dir.path().join("n.png")),
                "--color",
                "nir",
            ],
            &["no nir attribute"],
        );
    }
}

#[test]
fn extra_bytes_attributes_colour_files_and_stores_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("eb.pointlet");
    ok(&["convert", s(&data("extrabytes.las")), "-o", s(&store)]);
    for (k, input) in [data("extrabytes.las"), store].iter().enumerate() {
        let render = |color: &str| {
            let png = dir
                .path()
                .join(format!("{k}-{}.png", color.replace(':', "-")));
            let args = ["render", s(input), "-o", s(&png), "--width", "64"];
            ok(&[&args[..], &["--color", color]].concat());
            std::fs::read(&png).expect("png")
        };
        let intensity = render("extra:Intensity");
        // Names match ignoring case when that is unambiguous.
        assert!(render("extra:intensity") == intensity);
        assert!(
            render("extra:Time") != intensity,
            "two attributes draw alike"
        );
        assert!(
            render("elevation") != intensity,
            "extra:Intensity draws like elevation"
        );
        fails(
            &[
                "render",
                s(input),
                "-o",
                s(&dir.path().join("n.png")),
                "--color",
                "extra:nope",
            ],
            &["no extra-bytes attribute 'nope'", "Colors[0]", "Time"],
        );
    }
    fails(
        &[
            "render",
            s(&data("simple.las")),
            "-o",
            s(&dir.path().join("n.png")),
            "--color",
            "extra:x",
        ],
        &["attributes: none"],
    );
    usage_fails(
        &["render", s(&data("simple.las")), "--color", "extra:"],
        &["extra: needs"],
    );
}

#[test]
fn the_viewer_resolves_extra_bytes_names_before_opening_a_window() {
    fails(
        &["view", s(&data("extrabytes.las")), "--color", "extra:nope"],
        &["no extra-bytes attribute 'nope'", "Time"],
    );
    fails(
        &[
            "view",
            s(&data("extrabytes.las")),
            "--color",
            "extra:Time",
            "--raster",
            "hqs",
        ],
        &["read whole", "cannot be coloured by extra-bytes attributes"],
    );
}

#[test]
fn bench_path_quality_compares_moving_frames_with_full_detail() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("g.pointlet");
    ok(&["generate", "--points", "60k", "-o", s(&store)]);
    for reuse in [false, true] {
        let json = dir.path().join(format!("q{reuse}.json"));
        let mut args = vec![
            "bench",
            s(&store),
            "--frames",
            "24",
            "--path-quality",
            "3",
            "--bucket",
            "5k",
            "--width",
            "96",
            "--height",
            "64",
            "--json",
            s(&json),
        ];
        if reuse {
            args.push("--temporal-reuse");
        }
        let out = ok(&args);
        assert!(out.contains("mean PSNR"), "{out}");
        let rows: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
        assert_eq!(rows.as_array().map(Vec::len), Some(3), "{rows}");
    }
    usage_fails(
        &["bench", s(&store), "--path-quality", "3", "--realtime"],
        &["--realtime", "--path-quality"],
    );
    usage_fails(
        &[
            "render",
            s(&data("simple.las")),
            "-o",
            "x.png",
            "--temporal-reuse",
        ],
        &["--temporal-reuse", "stores"],
    );
}
