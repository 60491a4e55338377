//! The winit event loop: opens the window and GPU, turns window events into camera motion and
//! actions, and draws a frame when something changed (or every frame under automation).

use crate::commands::{perform, Action, Tool, UiState};
use crate::content::Content;
use crate::memory::{MemoryData, Source};
use crate::navigation::{Drag, MoveKey};
use crate::present::{Overlay, Presented, Presenter};
use crate::view::View;
use crate::{Automation, Input, ViewerConfig, ViewerError};
use pointlet_core::color::{default_color_of_parts, ColorMode, DefaultColor};
use pointlet_core::PointLayout;
use pointlet_engine::progressive::{LoadColor, LoadConfig, ProgressiveLoad};
use pointlet_engine::{
    ProgressiveConfig, ProgressiveScene, SceneConfig, TilesetConfig, TilesetScene, VirtualScene,
};
use pointlet_gpu::{AdapterRequest, GpuContext, RasterVariant};
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, KeyCode, NamedKey, PhysicalKey};
use winit::window::{Window, WindowId};

/// A press and release closer than this (pixels) is a click, not a drag.
const CLICK_SLOP: f64 = 4.0;
/// Two clicks within this many seconds are a double-click.
const DOUBLE_CLICK_S: f64 = 0.4;
/// Pixels of a precise (touchpad) scroll that make one wheel step.
const PIXELS_PER_STEP: f64 = 50.0;

pub fn run(config: ViewerConfig) -> Result<(), ViewerError> {
    let begun = Instant::now();
    let (w, h) = config.size;
    if w == 0 || h == 0 {
        return Err(ViewerError::Config(format!(
            "window size {w}×{h}: width and height must be at least 1 pixel"
        )));
    }
    if let Some(a) = &config.automation {
        for p in a.screenshot.iter().chain(&a.window_screenshot) {
            crate::png_out::check_png_path(p)?;
        }
        if !(a.converge_timeout_s.is_finite() && a.converge_timeout_s >= 0.0) {
            return Err(ViewerError::Config(format!(
                "the convergence timeout must be a number of seconds ≥ 0, not {}",
                a.converge_timeout_s
            )));
        }
    }
    // Point files drawn by a closest-point rasterizer load while they are drawn (once the
    // window is open); for the others they are read before it opens.
    let mut loading = None;
    let memory = match &config.input {
        Input::Files { paths, read } if config.settings.variant.accumulates() => {
            // Loading starts now; the window and GPU open meanwhile.
            let progressive = progressive_config(&config, read, config.settings.variant);
            let load = ProgressiveScene::start_load_many(paths, &progressive)
                .map_err(|e| ViewerError::Load(e.to_string()))?;
            loading = Some((load, progressive));
            None
        }
        Input::Files { paths, read } => Some(MemoryData::load(
            Source::Files { paths, read },
            config.order,
        )?),
        Input::Demo { points, seed } => Some(MemoryData::load(
            Source::Demo {
                points: *points,
                seed: *seed,
            },
            config.order,
        )?),
        Input::Store(_) | Input::Tileset { .. } => None,
    };
    let event_loop = open_event_loop()?;
    let mut app = App {
        config,
        memory,
        loading,
        state: None,
        error: None,
        started: Instant::now(),
        begun,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewerError::Window(e.to_string()))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The window system's event loop. winit panics where the X server or the keyboard data it
/// needs is missing (`XKBNotFound` without /usr/share/X11/xkb): that is an error here too.
fn open_event_loop() -> Result<EventLoop<()>, ViewerError> {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let opened = std::panic::catch_unwind(EventLoop::new);
    std::panic::set_hook(hook);
    let cannot = |why: String| {
        ViewerError::Window(format!(
            "cannot connect to a display ({why}); the viewer needs X11 or Wayland (is DISPLAY \
             or WAYLAND_DISPLAY set?)"
        ))
    };
    match opened {
        Ok(Ok(event_loop)) => Ok(event_loop),
        Ok(Err(e)) => Err(cannot(e.to_string())),
        Err(panic) => {
            let why = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "the window system failed to start".into());
            Err(cannot(format!(
                "{why}; X11 also needs the keyboard data of xkb-data (XKB_CONFIG_ROOT)"
            )))
        }
    }
}

struct App {
    config: ViewerConfig,
    /// In-memory points waiting for the GPU (taken when the window opens).
    memory: Option<MemoryData>,
    /// A point file loading for the progressive scene (taken when the window opens).
    loading: Option<(ProgressiveLoad, ProgressiveConfig)>,
    state: Option<Running>,
    error: Option<ViewerError>,
    started: Instant,
    /// When `run` was called (before any file was read).
    begun: Instant,
}

/// Mouse button held down, where and when it went down.
struct Press {
    drag: Drag,
    button: MouseButton,
    from: [f64; 2],
    moved: bool,
}

struct Running {
    window: Arc<Window>,
    view: View,
    presenter: Presenter,
    egui_ctx: egui::Context,
    egui: egui_winit::State,
    ui: UiState,
    cursor: [f64; 2],
    press: Option<Press>,
    shift: bool,
    last_click: Option<(f64, [f64; 2])>,
    last_frame: Option<f64>,
    frames: u32,
    /// Automation: when the N frames were done (the convergence wait starts).
    frames_done_at: Option<f64>,
    begun: Instant,
    /// Seconds from `run` until the first frame that showed points was presented.
    first_points_s: Option<f64>,
}

impl App {
    fn now(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: ViewerError) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<Running, ViewerError> {
        let c = &self.config;
        let (w, h) = c.size;
        let attrs = Window::default_attributes()
            .with_title("Pointlet")
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|e| ViewerError::Window(format!("creating the window: {e}")))?,
        );
        let request = AdapterRequest {
            name: c.adapter.clone(),
            ..Default::default()
        };
        let (ctx, surface, caps) = GpuContext::for_surface(&request, window.clone())
            .map_err(|e| ViewerError::Gpu(e.to_string()))?;
        let size = window.inner_size();
        let size = (size.width.max(1), size.height.max(1));
        if c.automation.is_some() && size != c.size {
            return Err(ViewerError::Window(format!(
                "the window is {}×{}, not the requested {w}×{h} (is the screen large enough?)",
                size.0, size.1
            )));
        }
        let (content, color) = match (&c.input, self.memory.take()) {
            (Input::Store(path), _) => {
                let store = pointlet_store::Store::open(path)
                    .map_err(|e| ViewerError::Load(e.to_string()))?;
                let layout = store.header().layout;
                let color = usable_color(&layout, c.color, &path.display().to_string(), || {
                    default_color_of_parts(&layout, store.pointlets().len(), |i| {
                        store.read_pointlet(i)
                    })
                    .map_err(|e| ViewerError::Load(e.to_string()))
                })?;
                let scene = VirtualScene::open(
                    &ctx,
                    path,
                    SceneConfig {
                        vram_budget: c.store.vram,
                        ram_budget: c.store.ram,
                        bucket: c.store.bucket,
                        encoding: c.encoding,
                        color,
                        ..Default::default()
                    },
                    size,
                )
                .map_err(|e| ViewerError::Load(format!("opening {}: {e}", path.display())))?;
                (Content::Store(Box::new(scene)), color)
            }
            (Input::Tileset { path, config }, _) => {
                // The tileset's own colour, else the viewer's (both come from --color).
                let config = TilesetConfig {
                    color: config.color.or(c.color),
                    ..config.clone()
                };
                let asked = config.color;
                let scene = TilesetScene::open(&ctx, path, config)
                    .map_err(|e| ViewerError::Load(format!("opening {}: {e}", path.display())))?;
                if asked.is_none() {
                    eprintln!("note: {}: {}", scene.name(), scene.default_color());
                }
                let color = scene.color_mode();
                (Content::Tiles(Box::new(scene)), color)
            }
            (Input::Files { .. }, None) => {
                let Some((load, mut config)) = self.loading.take() else {
                    return Err(ViewerError::Load("the file was not opened".into()));
                };
                let wanted = c.settings.variant.fallback(&ctx.caps);
                config.variant = if wanted.accumulates() {
                    wanted
                } else {
                    RasterVariant::ReduceEarlyZ.fallback(&ctx.caps)
                };
                // The engine's errors name the file already.
                let scene = ProgressiveScene::with_load(&ctx, load, config)
                    .map_err(|e| ViewerError::Load(e.to_string()))?;
                let path = scene.path().to_path_buf();
                for n in scene.notes() {
                    match scene.inputs() {
                        [_] => eprintln!("note: {}: {n}", path.display()),
                        // Several inputs' notes name their file.
                        _ => eprintln!("note: {n}"),
                    }
                }
                // The load thread picks the default colouring from its first sample.
                let color = match scene.color_within(std::time::Duration::from_secs(10)) {
                    Some(LoadColor {
                        default: Some(d), ..
                    }) => {
                        eprintln!("note: {}: {d}", path.display());
                        d.mode
                    }
                    Some(l) => l.scale.mode,
                    None => c.color.unwrap_or(ColorMode::Elevation),
                };
                (Content::Progressive(Box::new(scene)), color)
            }
            (_, Some(data)) => {
                let color =
                    usable_color(&data.layout, c.color, &data.name, || Ok(data.default_color))?;
                let scale = data.fitted(color);
                (
                    Content::upload(&ctx, data, &scale, c.encoding, c.page_size)?,
                    color,
                )
            }
            (_, None) => return Err(ViewerError::Load("the points were not loaded".into())),
        };
        let scale = content.fitted(color)?;
        let camera = (c.camera)(&content.bounds()).map_err(ViewerError::Config)?;
        let mut settings = c.settings;
        settings.variant = usable_variant(&ctx, &content, settings.variant);
        let presenter = Presenter::new(&ctx, surface, &caps, size, c.vsync)?;
        let max_texture = ctx.device.limits().max_texture_dimension_2d as usize;
        let mut view = View::new(ctx, content, camera, settings, scale, size)?;
        if let Input::Files { paths, read } = &c.input {
            view.list_inputs(
                paths,
                crate::view::Reread {
                    read: read.clone(),
                    order: c.order,
                    encoding: c.encoding,
                    page_size: c.page_size,
                },
            );
        }
        let egui_ctx = egui::Context::default();
        let egui = egui_winit::State::new(
            egui_ctx.clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            window.theme(),
            Some(max_texture),
        );
        window.request_redraw();
        Ok(Running {
            window,
            view,
            presenter,
            egui_ctx,
            egui,
            ui: UiState::default(),
            cursor: [0.0; 2],
            press: None,
            shift: false,
            last_click: None,
            last_frame: None,
            frames: 0,
            frames_done_at: None,
            begun: self.begun,
            first_points_s: None,
        })
    }
}

/// How the viewer draws a point file while it loads.
fn progressive_config(
    c: &ViewerConfig,
    read: &pointlet_io::ReadOptions,
    variant: RasterVariant,
) -> ProgressiveConfig {
    ProgressiveConfig {
        load: LoadConfig {
            color: c.color,
            read: read.clone(),
            ..Default::default()
        },
        variant,
        page_size: c.page_size,
        vram_budget: c.store.vram,
        target_frame_ms: 1000.0 / c.target_fps,
        ..Default::default()
    }
}

/// The requested colouring, which the data must have, or without one the data's default
/// (said on stderr, as `pointlet render` says it).
fn usable_color(
    layout: &PointLayout,
    wanted: Option<ColorMode>,
    name: &str,
    default: impl FnOnce() -> Result<DefaultColor, ViewerError>,
) -> Result<ColorMode, ViewerError> {
    match wanted {
        Some(mode) if mode.available_in(layout) => Ok(mode),
        Some(mode) => Err(ViewerError::Config(format!(
            "{name} has no {} attribute to colour by",
            mode.name()
        ))),
        None => {
            let d = default()?;
            eprintln!("note: {name}: {d}");
            Ok(d.mode)
        }
    }
}

/// The requested variant, or what replaces it on this adapter/content (said on stderr).
fn usable_variant(ctx: &GpuContext, content: &Content, wanted: RasterVariant) -> RasterVariant {
    let mut v = wanted.fallback(&ctx.caps);
    if !content.supports(v) {
        v = RasterVariant::ReduceEarlyZ.fallback(&ctx.caps);
    }
    if v != wanted {
        eprintln!(
            "note: {} is not available here ({}); drawing with {}",
            wanted.name(),
            wanted
                .unsupported_reason(&ctx.caps)
                .unwrap_or("stores are drawn by the compute rasterizers"),
            v.name()
        );
    }
    v
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(s) => self.state = Some(s),
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let now = self.now();
        let automation = self.config.automation.clone();
        let Some(s) = self.state.as_mut() else {
            return;
        };
        let response = s.egui.on_window_event(&s.window, &event);
        if response.repaint {
            s.window.request_redraw();
        }
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                s.presenter.resize(&s.view.ctx, size.width, size.height);
                let r = s.view.resize(size.width, size.height);
                s.window.request_redraw();
                r
            }
            WindowEvent::Focused(false) => {
                s.view.nav.release_keys();
                Ok(())
            }
            WindowEvent::ModifiersChanged(m) => {
                s.shift = m.state().shift_key();
                s.view.nav.set_fast(s.shift);
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } => {
                // Releases always count: a movement key let go while typing must not stick.
                let typing = response.consumed || s.egui_ctx.egui_wants_keyboard_input();
                if typing && event.state == ElementState::Pressed {
                    Ok(())
                } else {
                    s.key(&event, now)
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                s.mouse_button(state, button, response.consumed, now)
            }
            WindowEvent::CursorMoved { position, .. } => {
                s.cursor_moved([position.x, position.y]);
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } => {
                if !s.egui_ctx.is_pointer_over_egui() {
                    let steps = match delta {
                        MouseScrollDelta::LineDelta(_, y) => y as f64,
                        MouseScrollDelta::PixelDelta(p) => p.y / PIXELS_PER_STEP,
                    };
                    let size = s.view.size();
                    s.view.nav.zoom_at(steps, s.cursor, [size.0, size.1]);
                    s.window.request_redraw();
                }
                Ok(())
            }
            WindowEvent::RedrawRequested => s.redraw(now, automation.as_ref(), event_loop),
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let automated = self.config.automation.is_some();
        let Some(s) = self.state.as_mut() else {
            return;
        };
        if automated || s.ui.continuous || s.view.needs_frame() {
            s.window.request_redraw();
            event_loop.set_control_flow(ControlFlow::Poll);
        } else {
            // Nothing changes until the next event: sleep, and do not count the gap as a frame.
            s.view.stats.idle();
            s.last_frame = None;
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}

impl Running {
    fn size(&self) -> [u32; 2] {
        let (w, h) = self.view.size();
        [w, h]
    }

    fn act(&mut self, action: Action, now: f64) -> Result<(), ViewerError> {
        perform(action, &mut self.view, &mut self.ui, now)?;
        self.window.request_redraw();
        Ok(())
    }

    fn key(&mut self, event: &KeyEvent, now: f64) -> Result<(), ViewerError> {
        let down = event.state == ElementState::Pressed;
        if let PhysicalKey::Code(code) = event.physical_key {
            let movement = match code {
                KeyCode::KeyW | KeyCode::ArrowUp => Some(MoveKey::Forward),
                KeyCode::KeyS | KeyCode::ArrowDown => Some(MoveKey::Back),
                KeyCode::KeyA | KeyCode::ArrowLeft => Some(MoveKey::Left),
                KeyCode::KeyD | KeyCode::ArrowRight => Some(MoveKey::Right),
                KeyCode::KeyQ => Some(MoveKey::Down),
                KeyCode::KeyE => Some(MoveKey::Up),
                _ => None,
            };
            if let Some(m) = movement {
                self.view.nav.set_key(m, down);
                self.window.request_redraw();
                return Ok(());
            }
        }
        if !down || event.repeat {
            return Ok(());
        }
        let by_code = match event.physical_key {
            PhysicalKey::Code(KeyCode::F1) => Some(Action::ToggleHelp),
            PhysicalKey::Code(KeyCode::KeyF) => Some(Action::Fit),
            PhysicalKey::Code(KeyCode::KeyM) => Some(Action::ToggleMeasure),
            PhysicalKey::Code(KeyCode::KeyP) => Some(Action::Screenshot),
            PhysicalKey::Code(KeyCode::KeyB) => Some(Action::AddBookmark),
            PhysicalKey::Code(KeyCode::KeyR) => Some(Action::ToggleRecording),
            PhysicalKey::Code(KeyCode::KeyH) => Some(Action::ToggleUi),
            PhysicalKey::Code(KeyCode::KeyV) => Some(Action::ToggleMode),
            _ => None,
        };
        let action = by_code.or_else(|| match &event.logical_key {
            Key::Named(NamedKey::Escape) => {
                self.ui.tool = Tool::Navigate;
                Some(Action::ClearMeasure)
            }
            Key::Character(c) => match c.as_str() {
                "?" => Some(Action::ToggleHelp),
                "+" | "=" => Some(Action::Faster),
                "-" => Some(Action::Slower),
                d => d
                    .parse::<usize>()
                    .ok()
                    .filter(|n| (1..=9).contains(n))
                    .map(|n| Action::GoBookmark(n - 1)),
            },
            _ => None,
        });
        match action {
            Some(a) => self.act(a, now),
            None => Ok(()),
        }
    }

    fn mouse_button(
        &mut self,
        state: ElementState,
        button: MouseButton,
        consumed: bool,
        now: f64,
    ) -> Result<(), ViewerError> {
        match state {
            ElementState::Pressed => {
                if consumed || self.egui_ctx.is_pointer_over_egui() || self.press.is_some() {
                    return Ok(());
                }
                let drag = match button {
                    MouseButton::Left if !self.shift => Drag::Rotate,
                    MouseButton::Left | MouseButton::Right | MouseButton::Middle => Drag::Pan,
                    _ => return Ok(()),
                };
                self.press = Some(Press {
                    drag,
                    button,
                    from: self.cursor,
                    moved: false,
                });
                Ok(())
            }
            ElementState::Released => {
                let Some(press) = self.press.take_if(|p| p.button == button) else {
                    return Ok(());
                };
                if press.moved || button != MouseButton::Left {
                    return Ok(());
                }
                self.click(now)
            }
        }
    }

    /// A left click that did not drag: measure, or (the second of two) focus.
    fn click(&mut self, now: f64) -> Result<(), ViewerError> {
        let pixel = [
            self.cursor[0].max(0.0) as u32,
            self.cursor[1].max(0.0) as u32,
        ];
        let double = self.last_click.is_some_and(|(t, at)| {
            now - t < DOUBLE_CLICK_S
                && (at[0] - self.cursor[0]).hypot(at[1] - self.cursor[1]) < CLICK_SLOP
        });
        self.last_click = if double {
            None
        } else {
            Some((now, self.cursor))
        };
        if self.ui.tool == Tool::Measure {
            match self.view.pick(pixel)? {
                Some(p) => self.view.measure.add(p),
                None => self.ui.say("no point under the cursor", now),
            }
        } else if double {
            match self.view.pick(pixel)? {
                Some(p) => self.view.nav.focus(p),
                None => self.ui.say("no point under the cursor", now),
            }
        }
        self.window.request_redraw();
        Ok(())
    }

    fn cursor_moved(&mut self, to: [f64; 2]) {
        let delta = [to[0] - self.cursor[0], to[1] - self.cursor[1]];
        self.cursor = to;
        let size = self.size();
        if let Some(p) = &mut self.press {
            if (to[0] - p.from[0]).hypot(to[1] - p.from[1]) >= CLICK_SLOP {
                p.moved = true;
            }
            if p.moved {
                self.view.nav.drag(p.drag, delta, size);
                self.window.request_redraw();
            }
        }
    }

    fn redraw(
        &mut self,
        now: f64,
        automation: Option<&Automation>,
        event_loop: &ActiveEventLoop,
    ) -> Result<(), ViewerError> {
        let ui_started = Instant::now();
        let input = self.egui.take_egui_input(&self.window);
        let view = &mut self.view;
        let ui = &mut self.ui;
        let mut actions = Vec::new();
        let mut output = self.egui_ctx.run_ui(input, |root| {
            actions = crate::ui::draw(root, view, ui, now);
        });
        self.egui
            .handle_platform_output(&self.window, std::mem::take(&mut output.platform_output));
        let repaint = output
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .is_some_and(|v| v.repaint_delay.is_zero());
        let mut textures = std::mem::take(&mut output.textures_delta);
        let primitives = self
            .egui_ctx
            .tessellate(std::mem::take(&mut output.shapes), output.pixels_per_point);
        let mut overlay = Overlay {
            primitives: &primitives,
            textures: &mut textures,
            pixels_per_point: output.pixels_per_point,
        };
        let ui_ms = ui_started.elapsed().as_secs_f64() * 1e3;
        let result = self.advance(actions, &mut overlay, now, ui_ms, automation, event_loop);
        // Handled by the presenter, or the viewer is ending on an error: egui wants them gone.
        textures.clear();
        result?;
        if repaint {
            self.window.request_redraw();
        }
        Ok(())
    }

    /// Performs the UI's actions, draws a frame if one is due and presents it under `overlay`.
    fn advance(
        &mut self,
        actions: Vec<Action>,
        overlay: &mut Overlay<'_>,
        now: f64,
        ui_ms: f64,
        automation: Option<&Automation>,
        event_loop: &ActiveEventLoop,
    ) -> Result<(), ViewerError> {
        for a in actions {
            self.act(a, now)?;
        }
        let dt = self.last_frame.map_or(0.0, |t| now - t);
        self.last_frame = Some(now);
        let drawing = Instant::now();
        let drew = automation.is_some() || self.ui.continuous || self.view.needs_frame();
        if drew {
            self.view.frame(now, dt)?;
            self.frames += 1;
        }
        let draw_ms = drawing.elapsed().as_secs_f64() * 1e3;
        let finishing = automation.filter(|a| {
            self.frames >= a.frames && (self.view.drawn.converged || self.timed_out(a, now))
        });
        let capture = finishing.is_some_and(|a| a.window_screenshot.is_some());
        let presenting = Instant::now();
        let shown =
            self.presenter
                .present(&self.view.ctx, self.view.target.output(), overlay, capture)?;
        if drew && self.view.drawn.points > 0 && self.first_points_s.is_none() {
            self.first_points_s = Some(self.begun.elapsed().as_secs_f64());
        }
        if drew {
            self.view.stats.cpu_times(crate::stats::CpuTimes {
                ui_ms,
                draw_ms,
                present_ms: presenting.elapsed().as_secs_f64() * 1e3,
            });
        }
        if let (Some(a), Presented::Shown(window_pixels)) = (finishing, shown) {
            self.finish(a, window_pixels)?;
            event_loop.exit();
        }
        Ok(())
    }

    /// Automation: whether a store has had its time to converge after the N frames.
    fn timed_out(&mut self, a: &Automation, now: f64) -> bool {
        let since = *self.frames_done_at.get_or_insert(now);
        now - since > a.converge_timeout_s
    }

    fn finish(
        &mut self,
        a: &Automation,
        window_pixels: Option<Vec<u8>>,
    ) -> Result<(), ViewerError> {
        if !self.view.drawn.converged {
            return Err(ViewerError::Load(format!(
                "the view did not converge within {} s after {} frames",
                a.converge_timeout_s, a.frames
            )));
        }
        let (w, h) = self.view.size();
        if let Some(path) = &a.screenshot {
            crate::png_out::write_png(path, w, h, &self.view.image()?)?;
        }
        if let (Some(path), Some(pixels)) = (&a.window_screenshot, window_pixels) {
            let (pw, ph) = self.presenter.size();
            crate::png_out::write_png(path, pw, ph, &pixels)?;
        }
        let first = self
            .first_points_s
            .map(|t| format!("; the first points were on screen {t:.3} s after starting"))
            .unwrap_or_default();
        let tiles = self
            .view
            .drawn
            .tiles
            .as_ref()
            .map(|r| format!(" of {} streamed tiles", r.drawn_tiles))
            .unwrap_or_default();
        eprintln!(
            "viewed {} frames of {} ({} points drawn{tiles}) with {} on {}{first}",
            self.frames,
            self.view.content.name(),
            self.view.drawn.points,
            self.view.settings.variant.name(),
            self.view.ctx.describe()
        );
        let stats = &self.view.stats;
        if let (Some(fps), Some(c)) = (stats.fps(), stats.cpu_mean()) {
            let gpu = stats
                .gpu
                .map(|g| {
                    format!(
                        "; GPU: LoD {:.2} ms, raster {:.2} ms, screen {:.2} ms",
                        g.lod_ms, g.raster_ms, g.screen_ms
                    )
                })
                .unwrap_or_default();
            eprintln!(
                "{fps:.1} FPS over the last {} frames; main thread per frame: overlay {:.2} ms, \
                 draw {:.2} ms, present {:.2} ms{gpu}",
                stats.frame_times().count(),
                c.ui_ms,
                c.draw_ms,
                c.present_ms
            );
        }
        Ok(())
    }
}
