//! Headless (no window): a 3D Tiles tileset streamed through the viewer's `View` converges to
//! an image of its points, picking gives the surface under the cursor (within a pixel's width
//! of a point of the tileset's source file), and switching the colouring fetches the tiles
//! again in the new colours.

use pointlet_core::color::{classification_color, ColorMode};
use pointlet_core::order::VertexOrder;
use pointlet_core::Camera;
use pointlet_engine::{TilesetConfig, TilesetScene};
use pointlet_gpu::{AdapterRequest, GpuContext, RasterVariant, RenderSettings};
use pointlet_viewer::commands::{perform, Action, UiState};
use pointlet_viewer::content::{Content, PICK_RADIUS};
use pointlet_viewer::memory::{MemoryData, Source};
use pointlet_viewer::view::View;
use std::path::PathBuf;
use std::time::{Duration, Instant};

const SIZE: (u32, u32) = (320, 240);

fn data(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata")).join(name)
}

/// Draws frames until the view has every tile it wants (the fetchers work between frames).
fn converge(v: &mut View) {
    let started = Instant::now();
    let mut now = 0.0;
    loop {
        now += 0.02;
        v.frame(now, 0.02).expect("frame");
        if v.drawn.converged {
            return;
        }
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "the tileset did not converge: {:?}",
            v.drawn.tiles
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn lit(image: &[u8]) -> Vec<bool> {
    image.chunks_exact(4).map(|p| p[..3] != [0, 0, 0]).collect()
}

#[test]
fn a_streamed_tileset_is_drawn_picked_and_recoloured() {
    let ctx = GpuContext::new(&AdapterRequest::default()).expect("a GPU adapter (lavapipe)");
    let variant = RasterVariant::ReduceEarlyZ.fallback(&ctx.caps);
    // Full detail, every point of each tile, within budgets a CPU device allocates quickly.
    let config = TilesetConfig {
        max_sse: 0.0,
        clod: false,
        vram_budget: 64 << 20,
        ram_budget: 64 << 20,
        workers: 2,
        ..Default::default()
    };
    let scene = TilesetScene::open(&ctx, &data("tiles/simple_pnts/tileset.json"), config)
        .expect("open the tileset");
    assert_eq!(scene.color_mode(), ColorMode::Rgb, "the tiles have colours");
    let scale = scene.color_scale();
    let camera = Camera::closeup(&scene.bounds(), 60.0);
    let settings = RenderSettings {
        variant,
        ..Default::default()
    };
    let content = Content::Tiles(Box::new(scene));
    let mut v = View::new(ctx, content, camera, settings, scale, SIZE).expect("view");
    assert_eq!(
        v.colors.available,
        [
            ColorMode::Rgb,
            ColorMode::Intensity,
            ColorMode::Elevation,
            ColorMode::Classification
        ]
    );
    converge(&mut v);
    let rgb = v.image().expect("image");
    let covered = lit(&rgb);
    let (w, h) = SIZE;
    assert!(covered.iter().filter(|l| **l).count() > 200, "points drawn");
    let report = v.drawn.tiles.clone().expect("a tileset's report");
    assert_eq!(report.wanted_drawn, report.wanted_tiles);
    assert!(v.content.points() > 0 && v.drawn.points > 0);

    // The lit pixel nearest the image's centre: the pick unprojects the depth drawn there.
    let centre = [w / 2, h / 2];
    let at = (0..w * h)
        .filter(|k| covered[*k as usize])
        .map(|k| [k % w, k / w])
        .min_by_key(|p| p[0].abs_diff(centre[0]).pow(2) + p[1].abs_diff(centre[1]).pow(2))
        .expect("a lit pixel");
    let picked = v
        .pick(at)
        .expect("pick")
        .expect("a surface under a lit pixel");
    let read = Default::default();
    let source_file = [data("simple.las")];
    let source = MemoryData::load(
        Source::Files {
            paths: &source_file,
            read: &read,
        },
        VertexOrder::Original,
    )
    .expect("simple.las");
    let nearest = (0..source.len() as u32)
        .filter_map(|i| source.position(i))
        .map(|p| {
            (0..3)
                .map(|a| (p[a] - picked[a]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    // The pixel's closest point lies at the depth read back, within half the pixel's diagonal
    // (0.71 pixel widths) of the ray through its centre.
    let cam = &v.nav.camera;
    let depth = (0..3)
        .map(|a| (picked[a] - cam.eye[a]) * -cam.basis()[2][a])
        .sum::<f64>();
    let pixel_width = depth / cam.focal_px(h);
    assert!(
        nearest <= 0.75 * pixel_width,
        "picked {picked:?}: the nearest point of the source is {nearest} away (a pixel is \
         {pixel_width} wide there)"
    );
    // Blending leaves no resolved depth: the pick draws a closest-point frame of its own (a
    // new render target holds no depth from earlier frames).
    v.settings.variant = RasterVariant::Hqs.fallback(&v.ctx.caps);
    v.resize(w / 2, h / 2).expect("resize");
    v.resize(w, h).expect("resize");
    v.frame(0.5, 0.02).expect("a blended frame");
    assert_eq!(
        v.pick(at).expect("pick"),
        Some(picked),
        "HQS picks the same"
    );
    v.settings.variant = variant;
    // Far from every lit pixel, nothing is picked.
    let r = PICK_RADIUS as i64;
    let empty = (0..w * h).map(|k| [k % w, k / w]).find(|p| {
        (-r..=r).all(|dy| {
            (-r..=r).all(|dx| {
                let (x, y) = (p[0] as i64 + dx, p[1] as i64 + dy);
                x < 0
                    || y < 0
                    || x >= w as i64
                    || y >= h as i64
                    || !covered[(y * w as i64 + x) as usize]
            })
        })
    });
    let p = empty.expect("a part of the image without points");
    assert_eq!(v.pick(p).expect("pick"), None, "nothing near {p:?}");

    // Classification colours: the tiles are fetched again and drawn in them, where they were.
    let mut ui = UiState::default();
    perform(
        Action::SelectColor(ColorMode::Classification),
        &mut v,
        &mut ui,
        1.0,
    )
    .expect("switch");
    assert!(v.needs_frame(), "pending colours call for a frame");
    converge(&mut v);
    let classes = v.image().expect("image");
    assert_eq!(lit(&classes), covered, "the same pixels, other colours");
    assert!(classes
        .chunks_exact(4)
        .all(|p| p[..3] == [0, 0, 0] || (0..=255u8).any(|c| p[..3] == classification_color(c))));
    assert_ne!(classes, rgb);
    // And back: the first picture again, pixel for pixel.
    perform(Action::SelectColor(ColorMode::Rgb), &mut v, &mut ui, 2.0).expect("switch back");
    converge(&mut v);
    assert_eq!(v.image().expect("image"), rgb);
    if let Content::Tiles(t) = &mut v.content {
        assert!(
            t.recolor(ColorMode::GpsTime).is_err(),
            "tiles have no GPS time"
        );
        assert_eq!(
            t.color_mode(),
            ColorMode::Rgb,
            "a refused colouring changes nothing"
        );
    }
}
