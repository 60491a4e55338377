//! Reporting for `pointlet bench` (virtualized paper §IV-B/C): frame-time statistics as in
//! Table II, per-stage time breakdowns as in Fig. 15, line and stacked-area plots written as SVG
//! or PNG without a plotting library, and image comparison (PSNR, error images) as in
//! Figs. 16–17.

pub mod image;
pub mod plot;
pub mod stats;

pub use image::{diff_image, psnr};
pub use plot::{palette, plot_png, plot_stages_svg, plot_svg, Series};
pub use stats::{FrameStats, StageBreakdown, StageSummary};

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("frame {index}: frame time {ms} ms is not a finite number > 0")]
    BadFrameTime { index: usize, ms: f64 },
    #[error("a stage breakdown needs at least one stage")]
    NoStages,
    #[error("stage {0:?} is named twice in the stage breakdown")]
    DuplicateStage(String),
    #[error("frame {frame}: got {got} stage times for the {expected} stages of the breakdown")]
    StageCount {
        frame: usize,
        expected: usize,
        got: usize,
    },
    #[error("frame {frame}, stage {stage:?}: time {ms} ms is not a finite number ≥ 0")]
    BadStageTime {
        frame: usize,
        stage: String,
        ms: f64,
    },
    #[error("cannot compare images of {a} and {b} bytes: sizes differ")]
    ImageSizeMismatch { a: usize, b: usize },
    #[error("an image of {0} bytes is not RGBA8 (a non-zero multiple of 4 bytes)")]
    NotRgba(usize),
    #[error(
        "plot size {width}×{height} is outside {}..={} pixels per side",
        plot::MIN_PLOT_SIDE,
        plot::MAX_PLOT_SIDE
    )]
    PlotSize { width: u32, height: u32 },
    #[error("encoding the plot as PNG: {0}")]
    Png(#[from] png::EncodingError),
}
