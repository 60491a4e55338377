//! The GPU stage: a headless wgpu context, point data in GPU pages, the compute rasterizers of
//! the compute-shader paper and the hardware point baseline, and the screen passes (resolve,
//! hole filling, Eye-Dome Lighting). WGSL lives in `shaders/`, one file per pass.

mod bandwidth;
mod cloud;
mod context;
#[cfg_attr(
    any(target_arch = "wasm32", target_vendor = "apple"),
    path = "device_memory_none.rs"
)]
mod device_memory;
mod frame;
mod graph;
mod hw_points;
mod paged;
mod pick;
pub mod progressive;
mod quads;
mod raster;
pub mod reference;
mod renderer;
mod reuse;
mod screen;
mod shaders;
pub mod shuffle;
mod splat;
mod storage;
pub mod suballoc;
mod target;
pub mod tile_pool;
mod upload;

pub use bandwidth::{copy_bandwidth, upload_bandwidth, UploadBandwidth};
pub use cloud::{GpuCloud, PageMeta, PointSet};
pub use context::{describe, AdapterRequest, Capabilities, GpuContext};
pub use frame::FrameGraphSummary;
pub use paged::{gammas, LodFeedback, PagedCloud, PagedView, PointletDesc};
pub use pick::PickHit;
pub use raster::RasterVariant;
pub use renderer::{FrameTiming, RenderSettings, Renderer};
pub use reuse::{reprojection, TemporalReuse};
pub use screen::{EdlSettings, OcclusionSettings, ScreenSettings};
pub use splat::{box_spacing, PointSize, SplatRaster, SplatSettings, SplatShape, MAX_SPLAT};
pub use storage::{
    compact_step, decode_compact, encode_point, encode_positions, needs_fine, quantize_compact,
    PointEncoding, COMPACT_STEPS,
};
pub use target::RenderTarget;
pub use tile_pool::{TileContent, TileDraw, TileFrame, TilePool, CONTENT_PAGE_BYTES};
pub use upload::{PageBatch, PageJob, PageSink, PageWrite};

use thiserror::Error;

#[derive(Debug, Error)]
pub enum GpuError {
    #[error("no GPU adapter{}: found [{}]{}", wanted.as_ref().map(|w| format!(" matching '{w}'")).unwrap_or_default(), found.join("; "), if found.is_empty() { " — install a Vulkan driver (on Debian without a GPU: apt-get install mesa-vulkan-drivers)" } else { "" })]
    NoAdapter {
        wanted: Option<String>,
        found: Vec<String>,
    },
    #[error("the GPU device failed: {0}")]
    Device(String),
    #[error("out of GPU memory while {0}")]
    OutOfMemory(String),
    #[error("GPU validation error while {0}")]
    Validation(String),
    #[error("'{what}' is not available on {adapter}: {why}")]
    Unsupported {
        what: String,
        why: String,
        adapter: String,
    },
    #[error("{0}")]
    InvalidInput(String),
}
