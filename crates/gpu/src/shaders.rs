//! WGSL sources, included at build time. WGSL has no `#include`, so a module is assembled from
//! the shared header (common.wgsl), the point fetch of the encoding, and the pass body.

use crate::storage::PointEncoding;

pub const COMMON: &str = include_str!("../shaders/common.wgsl");
pub const FETCH_FULL16: &str = include_str!("../shaders/fetch_full16.wgsl");
pub const FETCH_COMPACT8: &str = include_str!("../shaders/fetch_compact8.wgsl");
pub const RASTER_MIN64: &str = include_str!("../shaders/raster_min64.wgsl");
pub const RASTER_SUBGROUP: &str = include_str!("../shaders/raster_subgroup.wgsl");
pub const COLOR_KEYS_OFF: &str = include_str!("../shaders/color_keys_off.wgsl");
pub const COLOR_KEYS_KEPT: &str = include_str!("../shaders/color_keys_kept.wgsl");
pub const RASTER_DEPTH: &str = include_str!("../shaders/raster_depth.wgsl");
pub const RASTER_MIN32: &str = include_str!("../shaders/raster_min32.wgsl");
pub const RASTER_HQS: &str = include_str!("../shaders/raster_hqs.wgsl");
pub const RASTER_HQS1R: &str = include_str!("../shaders/raster_hqs1r.wgsl");
pub const HW_POINTS: &str = include_str!("../shaders/hw_points.wgsl");
pub const RESOLVE_COMMON: &str = include_str!("../shaders/resolve_common.wgsl");
pub const RESOLVE_MIN64: &str = include_str!("../shaders/resolve_min64.wgsl");
pub const RESOLVE_MIN32: &str = include_str!("../shaders/resolve_min32.wgsl");
pub const BLEND_HQS: &str = include_str!("../shaders/blend_hqs.wgsl");
pub const BLEND_HQS1R: &str = include_str!("../shaders/blend_hqs1r.wgsl");
pub const RESOLVE_BLENDED: &str = include_str!("../shaders/resolve_blended.wgsl");
pub const EDL: &str = include_str!("../shaders/edl.wgsl");
pub const COMPOSE_BLENDED: &str = include_str!("../shaders/compose_blended.wgsl");
pub const FILL: &str = include_str!("../shaders/fill.wgsl");
pub const OCCLUSION: &str = include_str!("../shaders/occlusion.wgsl");
pub const COMPOSE: &str = include_str!("../shaders/compose.wgsl");
pub const COPY: &str = include_str!("../shaders/copy.wgsl");
pub const LOD: &str = include_str!("../shaders/lod.wgsl");
pub const UPLOAD: &str = include_str!("../shaders/upload.wgsl");
pub const TABLES: &str = include_str!("../shaders/tables.wgsl");
pub const SHUFFLE: &str = include_str!("../shaders/shuffle.wgsl");
pub const PROGRESSIVE_REPROJECT: &str = include_str!("../shaders/progressive_reproject.wgsl");
pub const PROGRESSIVE_PREPARE: &str = include_str!("../shaders/progressive_prepare.wgsl");
pub const PROGRESSIVE_LOOKUP: &str = include_str!("../shaders/progressive_lookup.wgsl");
pub const EMPTY_SLOTS: &str = include_str!("../shaders/empty_slots.wgsl");
pub const REUSE: &str = include_str!("../shaders/reuse.wgsl");
pub const SPLAT_QUADS: &str = include_str!("../shaders/splat_quads.wgsl");
pub const GAPS: &str = include_str!("../shaders/gaps.wgsl");
pub const CLOD: &str = include_str!("../shaders/clod.wgsl");
pub const CLOD_ENTRIES: &str = include_str!("../shaders/clod_entries.wgsl");
pub const BLEND_SPLATS: &str = include_str!("../shaders/blend_splats.wgsl");

/// A point pass: header + fetch for `encoding` + body.
pub fn point_pass(encoding: PointEncoding, body: &str) -> String {
    let fetch = match encoding {
        PointEncoding::Full16 => FETCH_FULL16,
        PointEncoding::Compact8 => FETCH_COMPACT8,
    };
    format!("{COMMON}\n{fetch}\n{body}")
}

pub fn resolve_pass(body: &str) -> String {
    format!("{RESOLVE_COMMON}\n{body}")
}

pub fn module(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}
