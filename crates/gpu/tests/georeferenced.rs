//! Far from the origin: the same points and camera moved by a large offset draw the same image.
//! The view is applied camera-relative in f64 and pages hold f32 positions relative to their own
//! origin, so georeferenced (~1e6 m) and ECEF (~6.4e6 m) coordinates neither jitter nor band.

mod common;
use common::*;
use pointlet_core::shuffle::SplitMix64;
use pointlet_core::{Aabb, Camera};
use pointlet_gpu::{PointEncoding, PointSet, RasterVariant, ScreenSettings};
use std::path::Path;

fn moved(set: &PointSet, by: [f64; 3]) -> PointSet {
    PointSet {
        positions: set
            .positions
            .iter()
            .map(|p| [p[0] + by[0], p[1] + by[1], p[2] + by[2]])
            .collect(),
        colors: set.colors.clone(),
    }
}

fn moved_camera(cam: &Camera, by: [f64; 3]) -> Camera {
    let add = |p: [f64; 3]| [p[0] + by[0], p[1] + by[1], p[2] + by[2]];
    Camera {
        eye: add(cam.eye),
        target: add(cam.target),
        ..*cam
    }
}

fn covered(image: &[u8]) -> usize {
    image.chunks(4).filter(|p| *p != [0, 0, 0, 255]).count()
}

#[test]
fn a_cloud_at_ecef_coordinates_draws_the_image_it_draws_at_the_origin() {
    let ctx = context();
    let scene = layered_scene(7, false);
    let cam = camera();
    // Earth-centred coordinates of places on the surface, |p| ≈ 6.37e6 m.
    let offsets = [
        [6_378_137.0, 0.0, 0.0],
        [-2_694_892.5, -4_297_418.25, 3_854_579.75],
    ];
    for encoding in PointEncoding::ALL {
        let at_origin = render(
            &ctx,
            &scene.set,
            encoding,
            RasterVariant::ReduceEarlyZ,
            ScreenSettings::default(),
            &cam,
        );
        assert!(covered(&at_origin) > 1000, "the scene covers most pixels");
        for by in offsets {
            let far = render(
                &ctx,
                &moved(&scene.set, by),
                encoding,
                RasterVariant::ReduceEarlyZ,
                ScreenSettings::default(),
                &moved_camera(&cam, by),
            );
            let (max, n) = diff(&far, &at_origin);
            assert_eq!(
                (max, n),
                (0, 0),
                "{} at {by:?}: {n} pixels differ (max {max})",
                encoding.name()
            );
        }
    }
    // The test can tell: positions rounded to f32 at that distance (0.5 m steps) draw another
    // image.
    let by = offsets[1];
    let rounded = PointSet {
        positions: moved(&scene.set, by)
            .positions
            .iter()
            .map(|p| [0, 1, 2].map(|i| (p[i] as f32) as f64 - by[i]))
            .collect(),
        colors: scene.set.colors.clone(),
    };
    let at_origin = render(
        &ctx,
        &scene.set,
        PointEncoding::Full16,
        RasterVariant::ReduceEarlyZ,
        ScreenSettings::default(),
        &cam,
    );
    let naive = render(
        &ctx,
        &rounded,
        PointEncoding::Full16,
        RasterVariant::ReduceEarlyZ,
        ScreenSettings::default(),
        &cam,
    );
    assert!(diff(&naive, &at_origin).1 > 100);
}

/// The points of a real LAS/LAZ file, each with a colour of its own (so that any change of the
/// closest point shows).
fn read_points(path: &Path) -> PointSet {
    let mut reader = pointlet_io::open(path)
        .unwrap_or_else(|e| panic!("{} (tests read testdata/): {e}", path.display()));
    let mut set = PointSet::default();
    let mut rng = SplitMix64::new(11);
    while let Some(batch) = reader.read_batch(1 << 16).expect("read") {
        for p in &batch.xyz {
            set.positions.push(*p);
            set.colors.push(rng.next_u64() as u32 | 0xff00_0000);
        }
    }
    set
}

#[test]
fn a_georeferenced_file_draws_the_image_it_draws_moved_to_the_origin() {
    let ctx = context();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/autzen_trim.laz");
    let set = read_points(&path);
    let bounds: Aabb = set.bounds();
    let c = bounds.center();
    assert!(
        c[0] > 6e5 && c[1] > 8e5,
        "Autzen lies in state-plane feet: {c:?}"
    );
    // A whole-metre shift keeps every difference exact in f64.
    let by = [-c[0].round(), -c[1].round(), -c[2].round()];
    for cam in [
        Camera::overview(&bounds, 60.0),
        Camera::closeup(&bounds, 60.0),
    ] {
        for encoding in PointEncoding::ALL {
            let georeferenced = render(
                &ctx,
                &set,
                encoding,
                RasterVariant::ReduceEarlyZ,
                ScreenSettings::default(),
                &cam,
            );
            let n = covered(&georeferenced);
            assert!(
                n > 300,
                "the view shows the data: {n} pixels of {} points",
                set.len()
            );
            let at_origin = render(
                &ctx,
                &moved(&set, by),
                encoding,
                RasterVariant::ReduceEarlyZ,
                ScreenSettings::default(),
                &moved_camera(&cam, by),
            );
            let (max, n) = diff(&at_origin, &georeferenced);
            assert_eq!(
                (max, n),
                (0, 0),
                "{}: {n} pixels differ (max {max})",
                encoding.name()
            );
        }
    }
}
