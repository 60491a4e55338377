//! What keys and buttons ask for, and doing it: one place, so a shortcut and its button
//! always do the same. Failures of user actions (a file that cannot be written) become status
//! messages; they never end the viewer.

use crate::navigation::NavMode;
use crate::view::View;
use crate::ViewerError;
use pointlet_core::color::ColorMode;
use std::path::PathBuf;
use std::sync::mpsc;

#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Fit,
    ToggleMode,
    ToggleHelp,
    ToggleUi,
    ToggleMeasure,
    ClearMeasure,
    Screenshot,
    AddBookmark,
    GoBookmark(usize),
    RemoveBookmark(usize),
    SaveBookmarks,
    LoadBookmarks,
    ToggleRecording,
    Faster,
    Slower,
    SelectColor(ColorMode),
    ResetColorScale,
    /// Shows (true) or hides input i of several.
    ShowInput(usize, bool),
}

/// Tool the primary click uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tool {
    Navigate,
    /// Clicks pick points for the distance measurement.
    Measure,
}

/// UI-side state the actions touch: panels, files named in the UI, status messages.
pub struct UiState {
    pub show_help: bool,
    pub show_ui: bool,
    pub tool: Tool,
    /// Screenshots are numbered: `{screenshot_stem}-NNN.png`.
    pub screenshot_stem: String,
    pub screenshots: u32,
    pub bookmarks_file: String,
    pub path_file: String,
    /// Redraw every frame even when nothing changed (for timing the renderer).
    pub continuous: bool,
    status: Option<(String, f64)>,
    /// Results of background writes (screenshots).
    done_tx: mpsc::Sender<String>,
    done_rx: mpsc::Receiver<String>,
}

/// Seconds a status message stays.
const STATUS_SECONDS: f64 = 6.0;
/// Speed steps of `+`/`-`.
const SPEED_STEP: f64 = 1.5;

impl Default for UiState {
    fn default() -> Self {
        let (done_tx, done_rx) = mpsc::channel();
        Self {
            show_help: false,
            show_ui: true,
            tool: Tool::Navigate,
            screenshot_stem: "pointlet".into(),
            screenshots: 0,
            bookmarks_file: "pointlet-bookmarks.json".into(),
            path_file: "pointlet-path.json".into(),
            continuous: false,
            status: None,
            done_tx,
            done_rx,
        }
    }
}

impl UiState {
    pub fn say(&mut self, message: impl Into<String>, now: f64) {
        self.status = Some((message.into(), now + STATUS_SECONDS));
    }

    /// The current status message, after collecting finished background work.
    pub fn status(&mut self, now: f64) -> Option<&str> {
        while let Ok(m) = self.done_rx.try_recv() {
            self.status = Some((m, now + STATUS_SECONDS));
        }
        match &self.status {
            Some((m, until)) if *until > now => Some(m.as_str()),
            _ => None,
        }
    }
}

/// Carries out `action`; `now` is the clock in seconds.
pub fn perform(
    action: Action,
    view: &mut View,
    ui: &mut UiState,
    now: f64,
) -> Result<(), ViewerError> {
    match action {
        Action::Fit => view.nav.fit(),
        Action::ToggleMode => {
            view.nav.mode = match view.nav.mode {
                NavMode::Orbit => NavMode::Fly,
                NavMode::Fly => NavMode::Orbit,
            };
        }
        Action::ToggleHelp => ui.show_help = !ui.show_help,
        Action::ToggleUi => ui.show_ui = !ui.show_ui,
        Action::ToggleMeasure => {
            ui.tool = match ui.tool {
                Tool::Navigate => Tool::Measure,
                Tool::Measure => Tool::Navigate,
            };
        }
        Action::ClearMeasure => view.measure.clear(),
        Action::Screenshot => {
            ui.screenshots += 1;
            let file = PathBuf::from(format!("{}-{:03}.png", ui.screenshot_stem, ui.screenshots));
            let (w, h) = view.size();
            let rgba = view.image()?;
            let tx = ui.done_tx.clone();
            // Encoding and writing happen off the frame loop: the UI does not wait for disk.
            std::thread::spawn(move || {
                let message = match crate::png_out::write_png(&file, w, h, &rgba) {
                    Ok(()) => format!("saved {}", file.display()),
                    Err(e) => format!("screenshot failed: {e}"),
                };
                let _ = tx.send(message);
            });
        }
        Action::AddBookmark => {
            let name = view.bookmarks.add(view.nav.camera);
            ui.say(format!("bookmarked {name}"), now);
        }
        Action::GoBookmark(i) => match view.bookmarks.get(i) {
            Some(cam) => {
                let cam = *cam;
                view.nav.set_camera(cam);
            }
            None => ui.say(format!("no bookmark {}", i + 1), now),
        },
        Action::RemoveBookmark(i) => view.bookmarks.remove(i),
        Action::SaveBookmarks => {
            let m = match view.bookmarks.save(ui.bookmarks_file.as_ref()) {
                Ok(()) => format!(
                    "saved {} bookmarks to {}",
                    view.bookmarks.list.len(),
                    ui.bookmarks_file
                ),
                Err(e) => e.to_string(),
            };
            ui.say(m, now);
        }
        Action::LoadBookmarks => {
            let m = match crate::tools::Bookmarks::load(ui.bookmarks_file.as_ref()) {
                Ok(b) => {
                    view.bookmarks = b;
                    format!("loaded {} bookmarks", view.bookmarks.list.len())
                }
                Err(e) => e.to_string(),
            };
            ui.say(m, now);
        }
        Action::ToggleRecording => {
            if view.recorder.recording() {
                let m = match view.recorder.save(ui.path_file.as_ref()) {
                    Ok(p) => format!(
                        "saved a {:.1} s path ({} keyframes) to {}",
                        p.duration(),
                        p.keyframes.len(),
                        ui.path_file
                    ),
                    Err(e) => e.to_string(),
                };
                ui.say(m, now);
            } else {
                view.recorder.start(now, &view.nav.camera);
                ui.say("recording the camera path (R stops)", now);
            }
        }
        Action::Faster => view.nav.speed = (view.nav.speed * SPEED_STEP).min(1e4),
        Action::Slower => view.nav.speed = (view.nav.speed / SPEED_STEP).max(1e-4),
        Action::SelectColor(mode) => {
            if mode != view.colors.mode() {
                let fitted = view.content.fitted(mode)?;
                view.colors.select(fitted);
            }
        }
        Action::ResetColorScale => {
            let fitted = view.content.fitted(view.colors.mode())?;
            view.colors.select(fitted);
        }
        Action::ShowInput(i, shown) => match view.set_visible(i, shown) {
            // Hiding the last input is refused in the status line, not as a failure.
            Err(ViewerError::Config(m)) => ui.say(m, now),
            other => other?,
        },
    }
    Ok(())
}
