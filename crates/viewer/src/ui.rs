//! The egui overlay: the side panel (navigation, colouring, rendering, tools), the stats window,
//! the key help and the measurement drawn over the image. Widgets edit the view's settings in
//! place; anything with consequences beyond a value is returned as an [`Action`].

use crate::colors::knobs;
use crate::commands::{Action, Tool, UiState};
use crate::navigation::NavMode;
use crate::view::View;
use egui::{Color32, RichText};
use pointlet_core::color::{ColorMode, Ramp};
use pointlet_core::size::format_bytes;
use pointlet_gpu::{
    EdlSettings, OcclusionSettings, PointSize, RasterVariant, RenderSettings, SplatShape, MAX_SPLAT,
};

/// The keys, for the help window and the README.
pub const CONTROLS: &[(&str, &str)] = &[
    (
        "left drag",
        "orbit around the target (fly mode: look around)",
    ),
    ("right / middle drag, shift + left drag", "pan"),
    ("wheel", "zoom towards the cursor"),
    ("double-click", "focus the picked point"),
    ("W A S D", "move forward / left / back / right"),
    ("Q / E", "move down / up"),
    ("shift (held)", "move 4× faster"),
    ("+ / -", "movement speed up / down"),
    ("V", "switch orbit / fly mode"),
    ("F", "zoom to fit"),
    ("M", "measure tool: clicks pick two points"),
    ("Esc", "clear the measurement, leave the measure tool"),
    ("P", "screenshot (PNG)"),
    ("B", "bookmark this view"),
    ("1 … 9", "go to bookmark 1 … 9"),
    ("R", "start / stop recording the camera path"),
    ("H", "hide / show the overlay"),
    ("F1 or ?", "this help"),
];

pub fn draw(root: &mut egui::Ui, view: &mut View, ui: &mut UiState, now: f64) -> Vec<Action> {
    let mut actions = Vec::new();
    if ui.show_ui {
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(290.0)
            .show(root, |p| {
                egui::ScrollArea::vertical().show(p, |p| {
                    header(p, view);
                    datasets(p, view, &mut actions);
                    navigation(p, view, &mut actions);
                    coloring(p, view, &mut actions);
                    rendering(p, view);
                    tools(p, view, ui, &mut actions);
                });
            });
        stats(root.ctx(), view, ui);
    }
    let ctx = root.ctx().clone();
    if ui.show_help {
        let mut open = true;
        egui::Window::new("Keys")
            .open(&mut open)
            .collapsible(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(&ctx, |w| {
                egui::Grid::new("keys").striped(true).show(w, |g| {
                    for (key, what) in CONTROLS {
                        g.label(RichText::new(*key).strong());
                        g.label(*what);
                        g.end_row();
                    }
                });
            });
        ui.show_help = open;
    }
    if let Some(message) = ui.status(now) {
        let message = message.to_string();
        egui::Area::new(egui::Id::unique("status"))
            .anchor(egui::Align2::CENTER_BOTTOM, [0.0, -12.0])
            .show(&ctx, |a| {
                egui::Frame::popup(a.style()).show(a, |f| f.label(message));
            });
    }
    measurement_overlay(&ctx, view);
    actions
}

fn header(p: &mut egui::Ui, view: &View) {
    p.heading("Pointlet");
    p.label(view.content.name());
    let points = match &view.content {
        // A tileset's total is known once every tile was read: its tiles and the points so far.
        crate::content::Content::Tiles(t) => {
            format!("{} tiles, {} points loaded", t.tiles(), t.points_seen())
        }
        content => format!("{} points", content.points()),
    };
    p.label(format!("{points} · {}", view.ctx.describe()));
    p.horizontal(|h| {
        h.label("F1 / ? shows the keys");
    });
    p.separator();
}

/// Several inputs: one visibility toggle each.
fn datasets(p: &mut egui::Ui, view: &View, actions: &mut Vec<Action>) {
    if view.datasets.is_empty() {
        return;
    }
    egui::CollapsingHeader::new(format!("Inputs ({})", view.datasets.len()))
        .default_open(true)
        .show(p, |s| {
            for (i, (path, shown)) in view.datasets.iter().enumerate() {
                let name = path.file_name().map_or_else(
                    || path.display().to_string(),
                    |n| n.to_string_lossy().into(),
                );
                let mut on = *shown;
                if s.checkbox(&mut on, name)
                    .on_hover_text(path.display().to_string())
                    .changed()
                {
                    actions.push(Action::ShowInput(i, on));
                }
            }
        });
}

fn navigation(p: &mut egui::Ui, view: &mut View, actions: &mut Vec<Action>) {
    egui::CollapsingHeader::new("Navigation")
        .default_open(true)
        .show(p, |s| {
            s.horizontal(|h| {
                h.radio_value(&mut view.nav.mode, NavMode::Orbit, "orbit");
                h.radio_value(&mut view.nav.mode, NavMode::Fly, "fly");
                if h.button("zoom to fit").clicked() {
                    actions.push(Action::Fit);
                }
            });
            s.add(
                egui::Slider::new(&mut view.nav.speed, 0.01..=100.0)
                    .logarithmic(true)
                    .text("speed"),
            );
            s.label(format!(
                "{:.3} units/s (shift: ×4)",
                view.nav.units_per_second()
            ));
            let mut fov = view.nav.camera.fov_y_deg;
            if s.add(egui::Slider::new(&mut fov, 10.0..=120.0).text("field of view °"))
                .changed()
            {
                let mut cam = view.nav.camera;
                cam.fov_y_deg = fov;
                view.nav.set_camera(cam);
            }
            let e = view.nav.camera.eye;
            s.label(RichText::new(format!("eye {:.3}, {:.3}, {:.3}", e[0], e[1], e[2])).small());
        });
}

fn coloring(p: &mut egui::Ui, view: &mut View, actions: &mut Vec<Action>) {
    egui::CollapsingHeader::new("Colour")
        .default_open(true)
        .show(p, |s| {
            let current = view.colors.mode();
            egui::ComboBox::from_label("colour by")
                .selected_text(view.colors.label(current))
                .show_ui(s, |c| {
                    for mode in view.colors.available.clone() {
                        let label = view.colors.label(mode);
                        if c.selectable_label(mode == current, label).clicked() {
                            actions.push(Action::SelectColor(mode));
                        }
                    }
                });
            let k = knobs(current);
            {
                let scale = &mut view.colors.scale;
                if k.range {
                    s.horizontal(|h| {
                        h.label("range");
                        let speed = ((scale.range[1] - scale.range[0]).abs() * 0.005).max(1e-6);
                        h.add(egui::DragValue::new(&mut scale.range[0]).speed(speed));
                        h.add(egui::DragValue::new(&mut scale.range[1]).speed(speed));
                    });
                }
                if k.gamma {
                    s.add(
                        egui::Slider::new(&mut scale.gamma, 0.1..=5.0)
                            .logarithmic(true)
                            .text("gamma"),
                    );
                }
                if k.ramp {
                    egui::ComboBox::from_label("colour map")
                        .selected_text(scale.ramp.name())
                        .show_ui(s, |c| {
                            for r in Ramp::ALL {
                                c.selectable_value(&mut scale.ramp, r, r.name());
                            }
                        });
                }
                if (k.range || k.gamma) && s.button("fit to data").clicked() {
                    actions.push(Action::ResetColorScale);
                }
            }
            if current == ColorMode::Classification {
                legend(s, view);
            }
        });
}

fn legend(s: &mut egui::Ui, view: &mut View) {
    let entries = view.content.legend();
    s.horizontal(|h| {
        if h.small_button("show all").clicked() {
            for e in &entries {
                view.settings.set_class_hidden(e.class, false);
            }
        }
        if h.small_button("hide all").clicked() {
            for e in &entries {
                view.settings.set_class_hidden(e.class, true);
            }
        }
    });
    for e in entries {
        s.horizontal(|h| {
            let mut shown = !view.settings.class_hidden(e.class);
            if h.checkbox(&mut shown, "").changed() {
                view.settings.set_class_hidden(e.class, !shown);
            }
            let (rect, _) = h.allocate_exact_size(egui::vec2(14.0, 14.0), egui::Sense::hover());
            h.painter().rect_filled(
                rect,
                2.0,
                Color32::from_rgb(e.color[0], e.color[1], e.color[2]),
            );
            let count = e.count.map(|c| format!(" ({c})")).unwrap_or_default();
            h.label(format!("{} {}{count}", e.class, e.name));
        });
    }
}

/// Point size (fixed pixels or adaptive to the drawn spacing) and the splats' shape; the
/// hardware point-list baseline draws one-pixel points only.
fn point_size(s: &mut egui::Ui, settings: &mut RenderSettings) {
    let hw = settings.variant == RasterVariant::HwPoints;
    let splats = &mut settings.splats;
    s.add_enabled_ui(!hw, |s| {
        let mut adaptive = splats.is_adaptive();
        egui::ComboBox::from_label("point size")
            .selected_text(if adaptive { "adaptive" } else { "fixed" })
            .show_ui(s, |c| {
                c.selectable_value(&mut adaptive, false, "fixed");
                c.selectable_value(&mut adaptive, true, "adaptive");
            })
            .response
            .on_hover_text("adaptive: each point as wide as the spacing of the points drawn");
        match (adaptive, splats.size) {
            (true, PointSize::Fixed(_)) => splats.size = PointSize::adaptive(),
            (false, PointSize::Adaptive { .. }) => splats.size = PointSize::Fixed(1),
            _ => {}
        }
        match &mut splats.size {
            PointSize::Fixed(px) => {
                s.add(egui::Slider::new(px, 1..=MAX_SPLAT).text("point size (px)"));
            }
            PointSize::Adaptive { scale } => {
                s.add(egui::Slider::new(scale, 0.5..=4.0).text("size × spacing"));
            }
        }
        s.add_enabled_ui(!splats.is_pixel(), |s| {
            egui::ComboBox::from_label("splat shape")
                .selected_text(splats.shape.name())
                .show_ui(s, |c| {
                    for shape in SplatShape::ALL {
                        c.selectable_value(&mut splats.shape, shape, shape.name());
                    }
                });
        });
    });
    if hw {
        s.label("hw-points draws one-pixel points");
    }
}

fn rendering(p: &mut egui::Ui, view: &mut View) {
    egui::CollapsingHeader::new("Rendering")
        .default_open(true)
        .show(p, |s| {
            let caps = view.ctx.caps;
            let current = view.settings.variant;
            egui::ComboBox::from_label("rasterizer")
                .selected_text(current.name())
                .show_ui(s, |c| {
                    for v in RasterVariant::ALL {
                        // The point-list baseline has no point size.
                        let sized = v != RasterVariant::HwPoints || view.settings.splats.is_pixel();
                        let usable = v.unsupported_reason(&caps).is_none()
                            && view.content.supports(v)
                            && sized;
                        c.add_enabled_ui(usable, |c| {
                            c.selectable_value(&mut view.settings.variant, v, v.name());
                        });
                    }
                });
            // HQS blends the points near the closest one instead of keeping only the closest.
            let mut hqs = matches!(current, RasterVariant::Hqs | RasterVariant::Hqs1r);
            let blendable = view.content.supports(RasterVariant::Hqs1r);
            if blendable && s.checkbox(&mut hqs, "high-quality shading (HQS)").changed() {
                let wanted = if hqs {
                    RasterVariant::Hqs1r
                } else {
                    RasterVariant::ReduceEarlyZ
                };
                view.settings.variant = wanted.fallback(&caps);
            }
            if let crate::content::Content::Store(scene) = &mut view.content {
                let mut millions = scene.bucket() / 1e6;
                if s.add(
                    egui::Slider::new(&mut millions, 0.1..=200.0)
                        .logarithmic(true)
                        .text("bucket B (M points)"),
                )
                .changed()
                {
                    scene.set_bucket(millions * 1e6);
                }
                let mut reuse = scene.temporal_reuse();
                if s.checkbox(&mut reuse, "temporal reuse while moving")
                    .on_hover_text("moving frames start from the last frame reprojected")
                    .changed()
                {
                    scene.set_temporal_reuse(reuse);
                }
            }
            point_size(s, &mut view.settings);
            let screen = &mut view.settings.screen;
            s.add(egui::Slider::new(&mut screen.fill_radius, 0..=8).text("hole filling (px)"));
            let mut edl = screen.edl.is_some();
            if s.checkbox(&mut edl, "Eye-Dome Lighting").changed() {
                screen.edl = edl.then(EdlSettings::default);
            }
            if let Some(e) = &mut screen.edl {
                s.add(egui::Slider::new(&mut e.strength, 0.0..=5.0).text("EDL strength"));
                s.add(egui::Slider::new(&mut e.radius, 0.5..=4.0).text("EDL radius (px)"));
            }
            // Removes far points seen through gaps of nearer surfaces before hole filling.
            let mut occlusion = screen.occlusion.is_some();
            if s.checkbox(&mut occlusion, "occlusion filter").changed() {
                screen.occlusion = occlusion.then(OcclusionSettings::default);
            }
            if let Some(o) = &mut screen.occlusion {
                s.add(egui::Slider::new(&mut o.radius, 1..=8).text("occlusion radius (px)"));
                s.add(egui::Slider::new(&mut o.threshold, 0.01..=0.5).text("occlusion β"));
            }
            s.horizontal(|h| {
                let bg = &mut screen.background;
                let mut rgb = [bg[0], bg[1], bg[2]];
                if h.color_edit_button_rgb(&mut rgb).changed() {
                    *bg = [rgb[0], rgb[1], rgb[2], 1.0];
                }
                h.label("background");
            });
        });
}

fn tools(p: &mut egui::Ui, view: &mut View, ui: &mut UiState, actions: &mut Vec<Action>) {
    egui::CollapsingHeader::new("Tools")
        .default_open(true)
        .show(p, |s| {
            let mut measuring = ui.tool == Tool::Measure;
            if s.checkbox(&mut measuring, "measure (M): click two points")
                .changed()
            {
                actions.push(Action::ToggleMeasure);
            }
            for (k, pt) in view.measure.points().iter().enumerate() {
                s.label(format!(
                    "{}: {:.3}, {:.3}, {:.3}",
                    k + 1,
                    pt[0],
                    pt[1],
                    pt[2]
                ));
            }
            if let (Some(d), Some((horizontal, dz))) =
                (view.measure.distance(), view.measure.components())
            {
                s.label(RichText::new(format!("distance {d:.3}")).strong());
                s.label(format!("horizontal {horizontal:.3}, height {dz:+.3}"));
            }
            s.separator();
            s.horizontal(|h| {
                h.label("screenshot");
                h.text_edit_singleline(&mut ui.screenshot_stem);
            });
            if s.button("save screenshot (P)").clicked() {
                actions.push(Action::Screenshot);
            }
            s.separator();
            s.horizontal(|h| {
                if h.button("bookmark view (B)").clicked() {
                    actions.push(Action::AddBookmark);
                }
            });
            for (i, b) in view.bookmarks.list.iter().enumerate() {
                s.horizontal(|h| {
                    if h.button(&b.name).clicked() {
                        actions.push(Action::GoBookmark(i));
                    }
                    if h.small_button("✖").clicked() {
                        actions.push(Action::RemoveBookmark(i));
                    }
                });
            }
            s.horizontal(|h| {
                h.text_edit_singleline(&mut ui.bookmarks_file);
            });
            s.horizontal(|h| {
                if h.button("save").clicked() {
                    actions.push(Action::SaveBookmarks);
                }
                if h.button("load").clicked() {
                    actions.push(Action::LoadBookmarks);
                }
            });
            s.separator();
            s.horizontal(|h| {
                h.label("path");
                h.text_edit_singleline(&mut ui.path_file);
            });
            let label = if view.recorder.recording() {
                format!(
                    "stop recording (R) · {} keyframes",
                    view.recorder.keyframes()
                )
            } else {
                "record camera path (R)".to_string()
            };
            if s.button(label).clicked() {
                actions.push(Action::ToggleRecording);
            }
        });
}

fn stats(ctx: &egui::Context, view: &View, ui: &mut UiState) {
    egui::Window::new("Stats")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .default_width(260.0)
        .resizable(false)
        .show(ctx, |w| {
            let fps = view.stats.fps().map_or("–".into(), |f| format!("{f:.1}"));
            w.label(format!("{fps} FPS · frame {}", view.stats.frames));
            frame_graph(w, view);
            w.checkbox(&mut ui.continuous, "redraw continuously");
            let c = view.stats.cpu;
            w.label(format!(
                "CPU: overlay {:.1} · draw {:.1} · present {:.1} ms",
                c.ui_ms, c.draw_ms, c.present_ms
            ));
            if let Some(t) = view.stats.gpu {
                let (first, fill) = if view.drawn.progressive.is_some() {
                    ("reproject", "fill")
                } else if view.drawn.tiles.is_some() {
                    // A tileset's first pass is the continuous-LoD filter of its tiles.
                    ("filter", "raster")
                } else {
                    ("LoD", "raster")
                };
                w.label(format!(
                    "GPU: {first} {:.2} · {fill} {:.2} · screen {:.2} ms",
                    t.lod_ms, t.raster_ms, t.screen_ms
                ));
            }
            let refining = if view.drawn.converged {
                ""
            } else {
                " (refining)"
            };
            let drawn = view.drawn.points;
            w.label(match &view.content {
                // A tileset's total is not known; coarse tiles' points are uploaded too.
                crate::content::Content::Tiles(t) => format!(
                    "{drawn} points drawn, {} uploaded{refining}",
                    t.points_seen()
                ),
                content => format!("{drawn} of {} points drawn{refining}", content.points()),
            });
            let target =
                pointlet_gpu::RenderTarget::bytes_for(view.target.width, view.target.height);
            let vram = view.content.gpu_bytes() + target;
            match (&view.content, &view.drawn.report) {
                (crate::content::Content::Store(scene), Some(r)) => {
                    let c = scene.config();
                    w.label(format!(
                        "VRAM {} / {}",
                        format_bytes(vram),
                        format_bytes(c.vram_budget)
                    ));
                    w.label(format!(
                        "RAM {} / {} (peak {})",
                        format_bytes(r.cache.ram_used),
                        format_bytes(c.ram_budget),
                        format_bytes(r.cache.ram_peak)
                    ));
                    w.label(format!(
                        "loader queue {} · {} pages resident",
                        r.cache.queued, r.pages_resident
                    ));
                    let progress = if r.requested_points == 0 {
                        1.0
                    } else {
                        (r.drawn_points as f64 / r.requested_points as f64).min(1.0)
                    };
                    w.add(
                        egui::ProgressBar::new(progress as f32)
                            .text(format!("loaded {:.0} % of the view", progress * 100.0)),
                    );
                }
                (crate::content::Content::Memory(m), _) => {
                    w.label(format!("VRAM {} (all points resident)", format_bytes(vram)));
                    w.label(format!(
                        "RAM {} (attributes held for recolouring and picking)",
                        format_bytes(m.data.ram_bytes())
                    ));
                }
                (crate::content::Content::Store(_), None) => {
                    w.label(format!("VRAM {}", format_bytes(vram)));
                }
                (crate::content::Content::Progressive(scene), _) => {
                    progressive_status(w, scene, view.drawn.progressive.as_ref(), vram);
                }
                (crate::content::Content::Tiles(scene), _) => {
                    tiles_status(w, scene, view.drawn.tiles.as_ref(), vram);
                }
            }
        });
}

/// Loading of a point file drawn while it loads: points in / total, throughput, the fill
/// budget, and what a file larger than the VRAM budget shows.
fn progressive_status(
    w: &mut egui::Ui,
    scene: &pointlet_engine::ProgressiveScene,
    report: Option<&pointlet_engine::ProgressiveReport>,
    vram: u64,
) {
    use pointlet_core::size::format_count;
    let p = scene.progress();
    w.label(format!(
        "VRAM {} (shuffled buffer and frame)",
        format_bytes(vram)
    ));
    let share = p.uploaded as f64 / p.total.max(1) as f64;
    let text = if p.is_finished() {
        format!(
            "loaded {} points in {:.1} s ({:.1} M points/s)",
            format_count(p.uploaded),
            p.elapsed.as_secs_f64(),
            p.points_per_s() / 1e6
        )
    } else {
        format!(
            "loading {} / {} points · {:.1} M points/s",
            format_count(p.uploaded),
            format_count(p.total),
            p.points_per_s() / 1e6
        )
    };
    w.add(egui::ProgressBar::new(share.min(1.0) as f32).text(text));
    if let Some(r) = report {
        w.label(format!(
            "fill budget {} points per frame ({:.1} % of the buffer){}",
            format_count(r.fill_budget),
            100.0 * r.fill_budget as f64 / scene.slots().max(1) as f64,
            if r.recoloring { " · recolouring" } else { "" }
        ));
    }
    if scene.slots() < scene.points() {
        w.label(
            RichText::new(format!(
                "showing {} of {} points; convert for full detail",
                format_count(scene.slots()),
                format_count(scene.points())
            ))
            .color(Color32::YELLOW),
        );
    }
    if let Some(f) = scene.failure() {
        w.label(RichText::new(format!("read error: {f}")).color(Color32::LIGHT_RED));
    }
}

/// Streaming of a tileset: of the tiles the settled view of this camera draws, those drawn;
/// tiles still requested; GPU and RAM memory against their budgets.
fn tiles_status(
    w: &mut egui::Ui,
    scene: &pointlet_engine::TilesetScene,
    report: Option<&pointlet_engine::TilesetFrameReport>,
    vram: u64,
) {
    let budgets = scene.config();
    w.label(format!(
        "VRAM {} · tiles {} / {}",
        format_bytes(vram),
        format_bytes(scene.gpu_bytes()),
        format_bytes(budgets.vram_budget)
    ));
    let Some(r) = report else {
        return;
    };
    w.label(format!(
        "RAM {} / {} · {} fetching",
        format_bytes(r.stream.bytes),
        format_bytes(budgets.ram_budget),
        r.stream.in_flight
    ));
    let progress = r.wanted_drawn as f64 / f64::from(r.wanted_tiles.max(1));
    w.add(
        egui::ProgressBar::new(progress.min(1.0) as f32).text(format!(
            "tiles drawn {} / {} wanted · {} requested",
            r.wanted_drawn, r.wanted_tiles, r.requested_tiles
        )),
    );
}

/// Frame times of the history as a bar graph, scaled to the slowest frame (at least 33 ms),
/// with the 60 FPS line.
fn frame_graph(w: &mut egui::Ui, view: &View) {
    let top_ms = view
        .stats
        .worst()
        .map_or(33.3, |t| (t * 1000.0 * 1.1).max(33.3));
    w.label(RichText::new(format!("frame times, 0–{top_ms:.0} ms")).small());
    let (rect, _) = w.allocate_exact_size(egui::vec2(240.0, 48.0), egui::Sense::hover());
    let painter = w.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_black_alpha(120));
    let bar = rect.width() / crate::stats::HISTORY as f32;
    let height = |ms: f64| ((ms / top_ms) as f32).clamp(0.0, 1.0) * rect.height();
    for (i, t) in view.stats.frame_times().enumerate() {
        let ms = t * 1000.0;
        let x = rect.left() + i as f32 * bar;
        let color = if ms > 1000.0 / 30.0 {
            Color32::from_rgb(230, 90, 60)
        } else {
            Color32::from_rgb(90, 200, 120)
        };
        let top = egui::pos2(x, rect.bottom() - height(ms));
        let bottom = egui::pos2(x + bar, rect.bottom());
        painter.rect_filled(egui::Rect::from_min_max(top, bottom), 0.0, color);
    }
    let y = rect.bottom() - height(1000.0 / 60.0);
    painter.hline(
        rect.x_range(),
        y,
        egui::Stroke::new(1.0, Color32::from_gray(200)),
    );
}

/// The measured points and the line between them, projected from their f64 coordinates.
fn measurement_overlay(ctx: &egui::Context, view: &View) {
    let points = view.measure.points();
    if points.is_empty() {
        return;
    }
    let (w, h) = view.size();
    let ppp = ctx.pixels_per_point();
    let vp = view.nav.camera.view_projection(w as f64 / h.max(1) as f64);
    let project = |p: [f64; 3]| {
        let q = pointlet_core::lod::transform(&vp, p);
        (q[3] > 0.0).then(|| {
            egui::pos2(
                ((q[0] / q[3] + 1.0) * 0.5 * w as f64) as f32 / ppp,
                ((1.0 - q[1] / q[3]) * 0.5 * h as f64) as f32 / ppp,
            )
        })
    };
    let painter = ctx.layer_painter(egui::LayerId::background());
    let stroke = egui::Stroke::new(2.0, Color32::from_rgb(255, 220, 0));
    let screen: Vec<Option<egui::Pos2>> = points.iter().map(|p| project(*p)).collect();
    if let [Some(a), Some(b)] = screen.as_slice() {
        painter.line_segment([*a, *b], stroke);
        if let Some(d) = view.measure.distance() {
            painter.text(
                egui::pos2((a.x + b.x) * 0.5, (a.y + b.y) * 0.5 - 10.0),
                egui::Align2::CENTER_BOTTOM,
                format!("{d:.3}"),
                egui::FontId::proportional(16.0),
                Color32::from_rgb(255, 220, 0),
            );
        }
    }
    for s in screen.into_iter().flatten() {
        painter.circle(
            s,
            4.0,
            Color32::from_rgb(255, 220, 0),
            egui::Stroke::new(1.0, Color32::BLACK),
        );
    }
}
