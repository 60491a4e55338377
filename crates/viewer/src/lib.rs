//! `pointlet view`: an interactive window on winit + a wgpu surface with an egui overlay,
//! drawing through the same `Renderer` as `pointlet render` (stores through the virtualized
//! `VirtualScene`, a tileset streamed through `TilesetScene`, point files drawn while they load
//! or held in memory) and copying the image to the window.
//!
//! Modules, one job each: [`navigation`] (input → f64 camera), [`tools`] (measure, bookmarks,
//! path recording), [`colors`] (colouring state, legend), [`memory`] (in-memory points),
//! [`content`] (memory, store, loading file or tileset behind one interface), [`view`] (the
//! window-independent viewer state and frame), [`commands`] (actions of keys and buttons),
//! [`ui`] (the overlay), [`present`] (image + overlay onto the surface), `app` (the winit
//! event loop).

mod app;
pub mod colors;
pub mod commands;
pub mod content;
pub mod memory;
pub mod navigation;
pub mod png_out;
pub mod present;
pub mod stats;
pub mod tools;
pub mod ui;
pub mod view;

use pointlet_core::color::ColorMode;
use pointlet_core::order::VertexOrder;
use pointlet_core::{Aabb, Camera};
use pointlet_gpu::{PointEncoding, RenderSettings};
use std::path::PathBuf;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ViewerError {
    #[error("{0}")]
    Config(String),
    #[error("{0}")]
    Load(String),
    #[error("{0}")]
    Gpu(String),
    #[error("the window: {0}")]
    Window(String),
    #[error("writing {0}")]
    Write(String),
}

/// What to open.
#[derive(Clone, Debug, PartialEq)]
pub enum Input {
    /// A `.pointlet` store, drawn through the virtualized scene.
    Store(PathBuf),
    /// Point files (or stores or tilesets read as point files), several drawn together in one
    /// coordinate frame: drawn while they load by the closest-point rasterizers, read whole
    /// into memory for the others.
    Files {
        paths: Vec<PathBuf>,
        read: pointlet_io::ReadOptions,
    },
    /// A 3D Tiles tileset (`tileset.json`, local or a URL), streamed by screen-space error
    /// through `TilesetScene` within `config`'s budgets.
    Tileset {
        path: PathBuf,
        config: pointlet_engine::TilesetConfig,
    },
    /// The built-in synthetic scene.
    Demo { points: u64, seed: u64 },
}

/// Budgets and LoD of the virtualized scene (stores; `vram` also bounds a point file's
/// shuffled buffer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StoreBudgets {
    pub vram: u64,
    pub ram: u64,
    pub bucket: f64,
}

/// `--frames N --screenshot out.png`: draw N frames in the real window, save, exit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Automation {
    pub frames: u32,
    /// The rendered image (what `pointlet render` writes), once converged and after N frames.
    pub screenshot: Option<PathBuf>,
    /// The whole window, overlay included.
    pub window_screenshot: Option<PathBuf>,
    /// Longest wait for a store to converge after the N frames.
    pub converge_timeout_s: f64,
}

/// The first camera, from the data's bounds (the command line's `--view`/`--eye`/...).
pub type CameraChoice = Box<dyn Fn(&Aabb) -> Result<Camera, String>>;

pub struct ViewerConfig {
    pub input: Input,
    pub camera: CameraChoice,
    /// Window (and image) size in physical pixels.
    pub size: (u32, u32),
    /// Variant as requested (the viewer falls back where the adapter lacks it).
    pub settings: RenderSettings,
    /// What to colour by; `None`: the data's default (RGB, else intensity, else elevation).
    pub color: Option<ColorMode>,
    pub encoding: PointEncoding,
    /// Points per GPU page of in-memory clouds.
    pub page_size: u32,
    pub order: VertexOrder,
    pub adapter: Option<String>,
    pub store: StoreBudgets,
    pub automation: Option<Automation>,
    /// Wait for the display's refresh between frames.
    pub vsync: bool,
    /// Point files drawn while loading: the frame rate the adaptive fill budget aims at.
    pub target_fps: f64,
}

/// Opens the window and runs until it is closed (or the automation is done).
pub fn run(config: ViewerConfig) -> Result<(), ViewerError> {
    app::run(config)
}
