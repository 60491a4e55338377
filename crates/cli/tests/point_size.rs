//! Points with a size through the commands (issue 12): `--point-size` and `--splat-shape` on
//! render for point files and stores, Eye-Dome Lighting on adaptive splats that darkens edges
//! rather than the surface, and sizes that cannot apply refused with a message.

mod common;
use common::*;
use std::path::Path;

const SIZE: [&str; 4] = ["--width", "320", "--height", "200"];

fn render(input: &Path, out: &Path, extra: &[&str]) -> Vec<u8> {
    let mut args = vec!["render", s(input), "-o", s(out)];
    args.extend_from_slice(&SIZE);
    args.extend_from_slice(extra);
    ok(&args);
    png_rgba(out)
}

fn lit(rgba: &[u8]) -> usize {
    rgba.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count()
}

#[test]
fn splats_cover_more_pixels_than_points_for_files_and_stores() {
    let dir = tempfile::tempdir().expect("tempdir");
    let laz = data("autzen_trim.laz");
    let store = dir.path().join("autzen.pointlet");
    ok(&["convert", s(&laz), "-o", s(&store)]);
    let png = dir.path().join("x.png");
    for input in [&laz, &store] {
        let default = lit(&render(input, &png, &["--view", "closeup"]));
        let one = lit(&render(
            input,
            &png,
            &["--view", "closeup", "--point-size", "1"],
        ));
        let square = lit(&render(
            input,
            &png,
            &["--view", "closeup", "--point-size", "3"],
        ));
        let circle = lit(&render(
            input,
            &png,
            &[
                "--view",
                "closeup",
                "--point-size",
                "3",
                "--splat-shape",
                "circle",
            ],
        ));
        let adaptive = lit(&render(
            input,
            &png,
            &["--view", "closeup", "--point-size", "adaptive"],
        ));
        assert!(
            one < circle && circle < square && square < adaptive,
            "{}: lit pixels one {one}, circle {circle}, square {square}, adaptive {adaptive}",
            input.display()
        );
        // Stores are drawn with adaptive splats unless told otherwise, point files one pixel.
        let want = if input == &store { adaptive } else { one };
        assert_eq!(default, want, "{}: the default point size", input.display());
        if input != &store {
            continue;
        }
        // Billboard quads cover the same pixels as the compute footprints (a point file is
        // drawn while it loads, which takes compute splats).
        let quads = lit(&render(
            input,
            &png,
            &[
                "--view",
                "closeup",
                "--point-size",
                "adaptive",
                "--splat-raster",
                "quads",
            ],
        ));
        assert_eq!(quads, adaptive, "{}: quads vs compute", input.display());
    }
}

#[test]
fn eye_dome_lighting_on_adaptive_splats_darkens_edges_not_the_surface() {
    let dir = tempfile::tempdir().expect("tempdir");
    let laz = data("autzen_trim.laz");
    let (plain, edl) = (dir.path().join("plain.png"), dir.path().join("edl.png"));
    let at = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&laz),
            "-o",
            s(out),
            "--view",
            "closeup",
            "--point-size",
            "adaptive",
        ];
        args.extend_from_slice(extra);
        ok(&args);
        png_rgba(out)
    };
    let silhouette = at(&plain, &[]);
    let shaded = at(&edl, &["--edl"]);
    let inside: Vec<usize> = silhouette
        .chunks_exact(4)
        .enumerate()
        .filter(|(_, p)| p[..3] != [0, 0, 0])
        .map(|(i, _)| i)
        .collect();
    // Black: every channel at most 10 of 255.
    let black = inside
        .iter()
        .filter(|i| shaded[*i * 4..*i * 4 + 3].iter().all(|c| *c <= 10))
        .count();
    assert!(
        inside.len() > 500_000,
        "adaptive splats fill the close-up: {}",
        inside.len()
    );
    assert!(
        black * 20 < inside.len(),
        "{black} of {} pixels inside the silhouette are black (at most 5 %)",
        inside.len()
    );
    // EDL still shades: edges darken somewhere.
    let darker = inside
        .iter()
        .filter(|i| {
            let (a, b) = (&silhouette[*i * 4..*i * 4 + 3], &shaded[*i * 4..*i * 4 + 3]);
            b.iter().zip(a).all(|(x, y)| (*x as u32) * 2 < *y as u32)
        })
        .count();
    assert!(
        darker > 1000,
        "EDL darkens edges: {darker} pixels at least halved"
    );
}

#[test]
fn point_sizes_that_cannot_apply_are_refused() {
    let laz = data("autzen_trim.laz");
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("x.png");
    usage_fails(
        &["render", s(&laz), "-o", s(&png), "--point-size", "0"],
        &["point size", "1–32"],
    );
    usage_fails(
        &["render", s(&laz), "-o", s(&png), "--point-size", "40"],
        &["point size"],
    );
    usage_fails(
        &["render", s(&laz), "-o", s(&png), "--splat-shape", "star"],
        &["splat shape", "square", "circle"],
    );
    usage_fails(
        &[
            "render",
            s(&laz),
            "-o",
            s(&png),
            "--raster",
            "hw-points",
            "--point-size",
            "4",
        ],
        &["hw-points", "one-pixel"],
    );
    usage_fails(
        &["render", s(&laz), "-o", s(&png), "--splat-shape", "circle"],
        &["--splat-shape", "larger than a pixel"],
    );
    usage_fails(
        &["render", s(&laz), "-o", s(&png), "--splat-raster", "quads"],
        &["--splat-raster", "larger than a pixel"],
    );
    let store = dir.path().join("autzen.pointlet");
    ok(&["convert", s(&laz), "-o", s(&store)]);
    for (raster, needles) in [
        (&["--raster", "hqs"][..], &["--temporal-reuse", "hqs"][..]),
        (
            &["--splat-raster", "quads"][..],
            &["--temporal-reuse", "quads"][..],
        ),
    ] {
        let mut args = vec!["render", s(&store), "-o", s(&png), "--temporal-reuse"];
        args.extend_from_slice(raster);
        usage_fails(&args, needles);
    }
    usage_fails(
        &[
            "render",
            s(&laz),
            "-o",
            s(&png),
            "--point-size",
            "3",
            "--splat-raster",
            "quads",
        ],
        &["quads", "point file drawn while it loads"],
    );
    usage_fails(
        &[
            "render",
            s(&laz),
            "-o",
            s(&png),
            "--raster",
            "hqs",
            "--point-size",
            "3",
            "--splat-raster",
            "quads",
        ],
        &["quads", "closest-point", "hqs"],
    );
}
