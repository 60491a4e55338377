//! The virtualized renderer (virtualized paper §III-C): a store on disk, the RAM cache of
//! pointlet windows fed by loader threads, and the GPU page pool, wired so that every frame the
//! GPU LoD's requests flow back to a residency thread, which moves what arrived into free pages
//! and hands the uploads to the render thread, and the GPU draws what is resident. Only changes
//! cost work; the render thread waits neither for the disk nor for the residency step.

mod datasets;
pub mod progressive;
mod progressive_scene;
mod remote_tiles;
mod residency;
mod scene;
mod source;
mod step;
mod store_points;
mod tileset_scene;

pub use datasets::{inputs_name, open_inputs, Datasets};
pub use progressive_scene::{
    FillBudget, OpenTimes, ProgressiveConfig, ProgressiveReport, ProgressiveScene, SLOT_BYTES,
};
pub use residency::{ResidencySet, Window};
pub use scene::{
    target_bytes, FrameReport, PickedPoint, SceneConfig, StepReport, VirtualScene, RESIDENCY_PARTS,
};
pub use source::{fit_scale, StoreSource};
pub use store_points::{is_store, open_points, StorePoints};
pub use tileset_scene::{TilesetConfig, TilesetFrameReport, TilesetScene};

use thiserror::Error;

#[derive(Debug, Error)]
pub enum EngineError {
    #[error(transparent)]
    Store(#[from] pointlet_store::StoreError),
    #[error(transparent)]
    Gpu(#[from] pointlet_gpu::GpuError),
    #[error(transparent)]
    Tiles(#[from] pointlet_tiles::TilesError),
    #[error("{0}")]
    Config(String),
    #[error("reading points: {0}")]
    Read(String),
}
