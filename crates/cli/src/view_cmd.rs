//! `pointlet view`: the interactive viewer (crates/viewer), with the camera and drawing
//! arguments of `render` so that both show the same image of the same view.

use crate::view_args::ColorArg;
use crate::view_args::{CameraArgs, DrawArgs, TileArgs, VirtualArgs};
use anyhow::Result;
use pointlet_viewer::{Automation, Input, StoreBudgets, ViewerConfig};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// A store (streamed within the budgets), a tileset (`tileset.json` or its URL: streamed
    /// by screen-space error within the budgets) or any point file (drawn while it loads);
    /// several are drawn together in one coordinate frame, each with a visibility toggle (as
    /// one point file: stores and tilesets among them are read whole); without one, the
    /// built-in demo scene.
    pub inputs: Vec<PathBuf>,
    /// Window width in pixels.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Window height in pixels.
    #[arg(long, default_value_t = 800)]
    pub height: u32,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub draw: DrawArgs,
    /// Points of the demo scene (without INPUT).
    #[arg(long, default_value_t = crate::scene::DEMO_POINTS, value_parser = crate::parse_count_arg)]
    pub demo_points: u64,
    /// GPU memory for a store's points, tables and frame, a tileset's tiles and their output,
    /// or a point file's shuffled buffer (a larger file shows a uniform subset).
    #[arg(long, default_value = "2GiB", value_parser = crate::parse_bytes_arg)]
    pub vram_budget: u64,
    /// RAM for a store's cached points or a tileset's decoded tiles.
    #[arg(long, default_value = "4GiB", value_parser = crate::parse_bytes_arg)]
    pub ram_budget: u64,
    /// The LoD's point bucket B for stores (points drawn per moving frame).
    #[arg(long, default_value = "25M", value_parser = crate::parse_bucket_arg)]
    pub bucket: u64,
    /// Automation: draw this many frames in the window, then exit.
    #[arg(long)]
    pub frames: Option<u32>,
    /// With --frames: save the rendered image (as `render` writes it) once the view has
    /// converged and the frames are drawn.
    #[arg(long, requires = "frames")]
    pub screenshot: Option<PathBuf>,
    /// With --frames: save the whole window, overlay included.
    #[arg(long, requires = "frames")]
    pub window_screenshot: Option<PathBuf>,
    /// With --frames: seconds a store may take to converge after the frames before failing.
    #[arg(long, default_value_t = 120.0, requires = "frames")]
    pub converge_timeout: f64,
    /// Draw as fast as possible instead of at the display's refresh rate.
    #[arg(long)]
    pub no_vsync: bool,
    /// Point files: the frame rate the adaptive fill budget aims at (default 60).
    #[arg(long, value_parser = crate::parse_fps_arg)]
    pub target_fps: Option<f64>,
    #[command(flatten)]
    pub read: crate::load::ReadArgs,
    #[command(flatten)]
    pub tiles: TileArgs,
}

impl Args {
    /// The input as the flag checks see it ([`crate::load::drawn_input`]).
    pub fn input(&self) -> Option<&Path> {
        crate::load::drawn_input(&self.inputs)
    }

    /// View's `--vram-budget` and `--ram-budget` as the budgets a tileset's configuration
    /// reads ([`TileArgs::config`]); the store-only fields keep their defaults.
    fn tile_budgets(&self) -> Result<VirtualArgs> {
        use clap::{Args as _, FromArgMatches as _};
        let defaults =
            VirtualArgs::augment_args(clap::Command::new("view")).try_get_matches_from(["view"])?;
        let mut budgets = VirtualArgs::from_arg_matches(&defaults)?;
        budgets.vram_budget = Some(self.vram_budget);
        budgets.ram_budget = Some(self.ram_budget);
        Ok(budgets)
    }
}

pub fn run(args: Args) -> Result<()> {
    let progressive = crate::progressive_cmd::is_progressive(args.input(), &args.draw);
    let mut input = match &args.inputs[..] {
        [p] if crate::tiles_cmd::is_streamed(&args.inputs) => Input::Tileset {
            path: p.clone(),
            config: args.tiles.config(&args.tile_budgets()?, None),
        },
        [p] if crate::load::is_store_path(p) && !progressive => Input::Store(p.clone()),
        [] => Input::Demo {
            points: args.demo_points,
            seed: crate::scene::DEMO_SEED,
        },
        paths => Input::Files {
            paths: paths.to_vec(),
            read: args.read.options(),
        },
    };
    // An extra-bytes attribute is found by name in the input's description of its records.
    let color = match (&args.draw.color, &input) {
        (None, _) => None,
        (Some(ColorArg::Mode(m)), _) => Some(*m),
        (Some(ColorArg::Extra(name)), Input::Tileset { .. }) => {
            anyhow::bail!("a tileset has no LAS extra-bytes attribute '{name}' to colour by")
        }
        (Some(asked), Input::Store(path)) => {
            let store = crate::load::open_store(path, "view")?;
            Some(crate::scene::store_color(Some(asked), &store)?)
        }
        (Some(asked), Input::Files { paths, .. }) if !progressive => {
            crate::progressive_cmd::resolve_color(paths, &args.read, Some(asked))?;
            anyhow::bail!(
                "{}: a file read whole ({}) cannot be coloured by extra-bytes attributes; \
                 a closest-point --raster draws it while it loads and can",
                pointlet_engine::inputs_name(paths).display(),
                args.draw.raster.name()
            )
        }
        (Some(asked), Input::Files { paths, .. }) => {
            crate::progressive_cmd::resolve_color(paths, &args.read, Some(asked))?
        }
        (Some(_), Input::Demo { .. }) => {
            anyhow::bail!("the demo scene has no extra-bytes attributes to colour by")
        }
    };
    // The tileset scene encodes its tiles' colours itself: the colouring goes with its config.
    if let Input::Tileset { config, .. } = &mut input {
        config.color = color;
    }
    let camera_args = args.camera.clone();
    let config = ViewerConfig {
        input,
        camera: Box::new(move |bounds| camera_args.camera(bounds).map_err(|e| format!("{e:#}"))),
        size: (args.width, args.height),
        settings: args.draw.settings_for(args.draw.raster, args.input()),
        color,
        encoding: args.draw.encoding,
        page_size: args.draw.page_size,
        order: args.draw.order,
        adapter: args.draw.adapter.clone(),
        store: StoreBudgets {
            vram: args.vram_budget,
            ram: args.ram_budget,
            bucket: args.bucket as f64,
        },
        automation: args.frames.map(|frames| Automation {
            frames,
            screenshot: args.screenshot,
            window_screenshot: args.window_screenshot,
            converge_timeout_s: args.converge_timeout,
        }),
        vsync: !args.no_vsync,
        target_fps: args.target_fps.unwrap_or(60.0),
    };
    pointlet_viewer::run(config)?;
    Ok(())
}
