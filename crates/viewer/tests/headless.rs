//! Headless (no window): picking through the viewer's `View` on a small georeferenced cloud
//! returns the exact stored point, the measuring tool gives the exact distance, hidden classes
//! cannot be picked, switching the colouring re-uploads colours that the image then shows, and
//! the actions of keys and buttons (bookmarks, path recording, speed, fit) do what they say.

use pointlet_core::color::{classification_color, ColorMode};
use pointlet_core::order::VertexOrder;
use pointlet_core::{Camera, PointBatch, PointLayout};
use pointlet_gpu::{AdapterRequest, GpuContext, PointEncoding, RasterVariant, RenderSettings};
use pointlet_viewer::commands::{perform, Action, UiState};
use pointlet_viewer::content::Content;
use pointlet_viewer::memory::MemoryData;
use pointlet_viewer::view::View;

const SIZE: (u32, u32) = (320, 240);
/// UTM-like coordinates: f32 would lose centimetres here.
const ORIGIN: [f64; 3] = [637_000.0, 851_000.0, 120.0];

fn cloud() -> PointBatch {
    let mut b = PointBatch::new(PointLayout {
        rgb: true,
        ..Default::default()
    });
    let offsets = [
        [0.0, 0.0, 0.0],
        [12.345, 3.21, 1.5],
        [-8.5, 9.75, -0.25],
        [5.5, -11.125, 2.0],
    ];
    for (k, o) in offsets.iter().enumerate() {
        b.xyz
            .push([ORIGIN[0] + o[0], ORIGIN[1] + o[1], ORIGIN[2] + o[2]]);
        b.intensity.push(1000 * k as u16);
        b.returns.push(0x11);
        b.flags.push(0);
        b.classification.push(2 + k as u8);
        b.scan_angle.push(0.0);
        b.user_data.push(0);
        b.point_source_id.push(1);
        b.rgb.push([200, 200, 200]);
    }
    b
}

fn view(variant: RasterVariant) -> View {
    let ctx = GpuContext::new(&AdapterRequest::default()).expect("a GPU adapter (lavapipe)");
    let variant = variant.fallback(&ctx.caps);
    let data =
        MemoryData::from_batch("test".into(), &cloud(), VertexOrder::Shuffled).expect("points");
    let scale = data.fitted(ColorMode::Rgb);
    let content = Content::upload(&ctx, data, &scale, PointEncoding::Full16, 256).expect("upload");
    let settings = RenderSettings {
        variant,
        ..Default::default()
    };
    View::new(ctx, content, camera_over_the_cloud(), settings, scale, SIZE).expect("view")
}

/// The pixel a world point lands on.
fn pixel_of(view: &View, p: [f64; 3]) -> [u32; 2] {
    let cam = &view.nav.camera;
    let q = pointlet_core::lod::transform(&cam.view_projection(SIZE.0 as f64 / SIZE.1 as f64), p);
    let x = (q[0] / q[3] + 1.0) * 0.5 * SIZE.0 as f64;
    let y = (1.0 - q[1] / q[3]) * 0.5 * SIZE.1 as f64;
    [x as u32, y as u32]
}

#[test]
fn pick_returns_the_exact_point_and_measure_the_exact_distance() {
    let mut v = view(RasterVariant::ReduceEarlyZ);
    v.frame(0.0, 0.0).expect("frame");
    let points = cloud().xyz;
    for p in &points {
        let px = pixel_of(&v, *p);
        // Two pixels off: the pick searches around the cursor.
        let hit = v.pick([px[0] + 2, px[1]]).expect("pick");
        assert_eq!(hit, Some(*p), "pick near {px:?}");
    }
    assert_eq!(v.pick([2, 2]).expect("pick"), None, "empty corner");
    for p in &points[1..3] {
        let hit = v.pick(pixel_of(&v, *p)).expect("pick").expect("a point");
        v.measure.add(hit);
    }
    let (a, b) = (points[1], points[2]);
    let exact = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    assert_eq!(v.measure.distance(), Some(exact));
    // A hidden class is neither drawn nor picked.
    v.settings.set_class_hidden(3, true);
    v.frame(0.1, 0.1).expect("frame");
    assert_eq!(v.pick(pixel_of(&v, points[1])).expect("pick"), None);
}

#[test]
fn switching_the_colouring_reuploads_colours() {
    let mut v = view(RasterVariant::AtomicMin32);
    let mut ui = UiState::default();
    v.frame(0.0, 0.0).expect("frame");
    let p = cloud().xyz[0];
    let px = pixel_of(&v, p);
    let colour_near = |img: &[u8], want: [u8; 3]| {
        (px[1].saturating_sub(1)..=px[1] + 1).any(|y| {
            (px[0].saturating_sub(1)..=px[0] + 1).any(|x| {
                let k = ((y * SIZE.0 + x) * 4) as usize;
                img[k..k + 3] == want
            })
        })
    };
    assert!(colour_near(&v.image().expect("image"), [200, 200, 200]));
    perform(
        Action::SelectColor(ColorMode::Classification),
        &mut v,
        &mut ui,
        0.0,
    )
    .expect("switch");
    assert!(v.needs_frame(), "pending colours call for a frame");
    v.frame(0.1, 0.1).expect("frame");
    assert!(!v.needs_frame());
    assert!(colour_near(
        &v.image().expect("image"),
        classification_color(2)
    ));
}

#[test]
fn actions_bookmark_record_and_move_the_camera() {
    let mut v = view(RasterVariant::ReduceEarlyZ);
    let mut ui = UiState::default();
    let dir = tempfile::tempdir().expect("tempdir");
    ui.path_file = dir.path().join("flight.json").display().to_string();
    ui.bookmarks_file = dir.path().join("marks.json").display().to_string();
    let start = v.nav.camera;
    perform(Action::AddBookmark, &mut v, &mut ui, 0.0).expect("bookmark");
    perform(Action::ToggleRecording, &mut v, &mut ui, 0.0).expect("record");
    for k in 1..=5 {
        v.nav.drag(
            pointlet_viewer::navigation::Drag::Rotate,
            [20.0, 0.0],
            [SIZE.0, SIZE.1],
        );
        v.frame(k as f64 * 0.2, 0.2).expect("frame");
    }
    perform(Action::ToggleRecording, &mut v, &mut ui, 1.2).expect("save path");
    let path = pointlet_core::path::CameraPath::load(std::path::Path::new(&ui.path_file))
        .expect("a path bench can read");
    assert_eq!(path.keyframes.len(), 6, "the start and one per moved frame");
    assert_eq!(path.keyframes[0].eye, start.eye);
    assert_ne!(v.nav.camera, start);
    perform(Action::SaveBookmarks, &mut v, &mut ui, 1.3).expect("save");
    v.bookmarks = Default::default();
    perform(Action::LoadBookmarks, &mut v, &mut ui, 1.4).expect("load");
    perform(Action::GoBookmark(0), &mut v, &mut ui, 1.5).expect("go");
    assert_eq!(v.nav.camera.eye, start.eye, "back at the bookmarked view");
    let speed = v.nav.speed;
    perform(Action::Faster, &mut v, &mut ui, 1.6).expect("faster");
    assert!(v.nav.speed > speed);
    perform(Action::Fit, &mut v, &mut ui, 1.7).expect("fit");
    assert_eq!(v.nav.camera.target, v.content.bounds().center());
    // A bookmark that does not exist is a message, not an error.
    perform(Action::GoBookmark(7), &mut v, &mut ui, 1.8).expect("no bookmark 8");
    assert!(ui.status(1.9).is_some_and(|m| m.contains("no bookmark 8")));
}

/// Two LAS files in `dir`: the cloud's first two points and its last two.
fn two_parts(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let all = cloud();
    let mut paths = Vec::new();
    for (k, range) in [0..2, 2..4].into_iter().enumerate() {
        let mut part = PointBatch::new(all.layout);
        range.for_each(|i| part.push_from(&all, i));
        let path = dir.join(format!("part{k}.las"));
        let mut w = pointlet_io::writer::LasWriter::create(
            &path,
            pointlet_io::writer::LasWriterConfig {
                quantization: pointlet_core::Quantization {
                    scale: [0.001; 3],
                    offset: ORIGIN,
                },
                point_format: 2,
                layout: part.layout,
                vlrs: Vec::new(),
                fields: Default::default(),
                compress: false,
            },
        )
        .expect("create");
        w.write_batch(&part).expect("write");
        w.finish().expect("finish");
        paths.push(path);
    }
    paths
}

/// Hides and shows the second of the view's two inputs (4 points, 2 each).
fn toggle_inputs(mut v: View, paths: &[std::path::PathBuf]) {
    let names: Vec<_> = v.datasets.iter().map(|d| (d.0.clone(), d.1)).collect();
    assert_eq!(
        names,
        vec![(paths[0].clone(), true), (paths[1].clone(), true)]
    );
    assert_eq!(v.content.points(), 4);
    let mut ui = UiState::default();
    perform(Action::ShowInput(1, false), &mut v, &mut ui, 0.0).expect("hide");
    assert_eq!(v.content.points(), 2);
    assert!(!v.datasets[1].1);
    // The last shown input stays: a message, not an error.
    perform(Action::ShowInput(0, false), &mut v, &mut ui, 0.1).expect("refused");
    assert!(v.datasets[0].1 && v.content.points() == 2);
    assert!(ui.status(0.2).is_some_and(|m| m.contains("stays shown")));
    perform(Action::ShowInput(1, true), &mut v, &mut ui, 0.3).expect("show");
    assert_eq!(v.content.points(), 4);
    v.frame(0.4, 0.1).expect("a frame of both");
}

fn camera_over_the_cloud() -> Camera {
    Camera {
        eye: [ORIGIN[0] + 2.0, ORIGIN[1] - 30.0, ORIGIN[2] + 40.0],
        target: ORIGIN,
        up: [0.0, 0.0, 1.0],
        fov_y_deg: 60.0,
        near: 0.1,
        far: 1000.0,
    }
}

#[test]
fn inputs_loading_while_drawn_are_shown_and_hidden_one_by_one() {
    use pointlet_engine::{ProgressiveConfig, ProgressiveScene};
    let ctx = GpuContext::new(&AdapterRequest::default()).expect("a GPU adapter (lavapipe)");
    let dir = tempfile::tempdir().expect("tempdir");
    let paths = two_parts(dir.path());
    let variant = RasterVariant::ReduceEarlyZ.fallback(&ctx.caps);
    let config = ProgressiveConfig {
        variant,
        ..Default::default()
    };
    let scene = ProgressiveScene::open_many(&ctx, &paths, config).expect("open both");
    let scale = scene
        .color_within(std::time::Duration::from_secs(10))
        .expect("a colouring")
        .scale;
    let content = Content::Progressive(Box::new(scene));
    let settings = RenderSettings {
        variant,
        ..Default::default()
    };
    let v = View::new(ctx, content, camera_over_the_cloud(), settings, scale, SIZE).expect("view");
    toggle_inputs(v, &paths);
}

#[test]
fn inputs_read_whole_are_shown_and_hidden_one_by_one() {
    use pointlet_viewer::memory::Source;
    let ctx = GpuContext::new(&AdapterRequest::default()).expect("a GPU adapter (lavapipe)");
    let dir = tempfile::tempdir().expect("tempdir");
    let paths = two_parts(dir.path());
    let read = Default::default();
    let source = Source::Files {
        paths: &paths,
        read: &read,
    };
    let data = MemoryData::load(source, VertexOrder::Shuffled).expect("both read");
    let scale = data.fitted(ColorMode::Rgb);
    let content = Content::upload(&ctx, data, &scale, PointEncoding::Full16, 256).expect("upload");
    let settings = RenderSettings {
        variant: RasterVariant::Hqs.fallback(&ctx.caps),
        ..Default::default()
    };
    let mut v =
        View::new(ctx, content, camera_over_the_cloud(), settings, scale, SIZE).expect("view");
    v.list_inputs(
        &paths,
        pointlet_viewer::view::Reread {
            read,
            order: VertexOrder::Shuffled,
            encoding: PointEncoding::Full16,
            page_size: 256,
        },
    );
    toggle_inputs(v, &paths);
}
