//! Picking: which point is under a pixel. The scene is drawn once more with point ids in place
//! of colours (32-bit passes, every adapter), and the pixels around the cursor are read back:
//! the answer is a point, not a pixel colour, so measurements use real coordinates.

use crate::cloud::GpuCloud;
use crate::context::GpuContext;
use crate::graph::{CompiledGraph, GraphBuilder, Physical, Res, ResourceDesc};
use crate::paged::{PagedCloud, PagedView};
use crate::raster::{RasterDispatch, RasterPipelines, RasterVariant};
use crate::renderer::{RenderSettings, Renderer};
use crate::splat::SplatMode;
use crate::storage::{PointEncoding, PointStorage};
use crate::target::{map_read, RenderTarget};
use crate::GpuError;
use pointlet_core::Camera;
use std::collections::hash_map::Entry;

/// The point found: its id (static clouds: the index in upload order; paged clouds: page slot
/// × page size + index in the page), its view depth and the pixel it covers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PickHit {
    pub id: u32,
    pub depth: f32,
    pub pixel: [u32; 2],
}

impl Renderer {
    /// The point of a static cloud nearest to `pixel` on screen within `radius` pixels (the
    /// closer one on a tie), drawn as `settings` hides classes.
    #[allow(clippy::too_many_arguments)]
    pub fn pick(
        &mut self,
        ctx: &GpuContext,
        cloud: &mut GpuCloud,
        camera: &Camera,
        settings: &RenderSettings,
        target: &mut RenderTarget,
        pixel: [u32; 2],
        radius: u32,
    ) -> Result<Option<PickHit>, GpuError> {
        Self::check(ctx, RasterVariant::AtomicMin32, &settings.splats, camera)?;
        cloud.prepare(ctx, camera, (target.width, target.height), settings);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        self.record_pick(
            ctx,
            &mut enc,
            (cloud.encoding, cloud.page_size, settings.splats.mode()),
            &cloud.storage,
            RasterDispatch::Direct,
            target,
        )?;
        ctx.checked("picking", || ctx.queue.submit([enc.finish()]))?;
        read_pick(ctx, target, self.pick_buffers(target)?, pixel, radius)
    }

    /// Like [`pick`](Self::pick) for a paged cloud: the LoD picks the points (as a moving
    /// frame with `view.bucket`) and ids name page slots.
    #[allow(clippy::too_many_arguments)]
    pub fn pick_paged(
        &mut self,
        ctx: &GpuContext,
        paged: &mut PagedCloud,
        camera: &Camera,
        settings: &RenderSettings,
        view: &PagedView,
        target: &mut RenderTarget,
        pixel: [u32; 2],
        radius: u32,
    ) -> Result<Option<PickHit>, GpuError> {
        Self::check(ctx, RasterVariant::AtomicMin32, &settings.splats, camera)?;
        let view = PagedView {
            accumulate: false,
            ..*view
        };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        paged.record_lod(
            ctx,
            &mut enc,
            camera,
            (target.width, target.height),
            &view,
            settings,
            None,
        )?;
        let key = (paged.encoding, paged.page_size, settings.splats.mode());
        self.record_pick(
            ctx,
            &mut enc,
            key,
            &paged.storage,
            RasterDispatch::Indirect(&paged.indirect),
            target,
        )?;
        ctx.checked("picking", || ctx.queue.submit([enc.finish()]))?;
        paged.after_submit();
        read_pick(ctx, target, self.pick_buffers(target)?, pixel, radius)
    }

    fn pick_buffers<'t>(
        &self,
        target: &'t RenderTarget,
    ) -> Result<[&'t wgpu::Buffer; 2], GpuError> {
        match &self.pick_graph {
            Some(g) => g.buffers(target),
            None => Err(GpuError::Device("no pick was drawn".into())),
        }
    }

    /// Draws the pick passes into the pick graph's two buffers (closest depth, then point ids),
    /// which stay in the target's pool for [`read_pick`].
    fn record_pick(
        &mut self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        key: (PointEncoding, u32, SplatMode),
        storage: &PointStorage,
        dispatch: RasterDispatch<'_>,
        target: &mut RenderTarget,
    ) -> Result<(), GpuError> {
        if let Entry::Vacant(slot) = self.pick.entry(key) {
            slot.insert(ctx.checked("building the pick passes", || {
                RasterPipelines::pick(&ctx.device, key.0, key.1, key.2)
            })?);
        }
        let Some(pipes) = self.pick.get(&key) else {
            return Ok(());
        };
        if self.pick_graph.is_none() {
            self.pick_graph = Some(PickGraph::new()?);
        }
        let Some(graph) = &self.pick_graph else {
            return Ok(());
        };
        target.pool.ensure(ctx, &graph.graph)?;
        let [depth, ids] = graph.buffers(target)?;
        for b in [depth, ids] {
            enc.clear_buffer(b, 0, None);
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("pick"),
            timestamp_writes: None,
        });
        pipes.record(&ctx.device, &mut pass, storage, dispatch, &[depth, ids]);
        Ok(())
    }
}

/// The pick passes' graph: the closest depth, then the point ids, both kept for reading back.
pub(crate) struct PickGraph {
    graph: CompiledGraph<&'static str>,
    depth: Res,
    ids: Res,
}

impl PickGraph {
    pub fn new() -> Result<Self, GpuError> {
        let mut g = GraphBuilder::default();
        let word = ResourceDesc::PixelBuffer { bytes_per_pixel: 4 };
        let depth = g.transient("pick depth", word);
        let ids = g.transient("pick ids", word);
        g.pass("pick depth pass", &[], &[depth]);
        g.pass("pick id pass", &[depth], &[ids]);
        let graph = g
            .compile(&[depth, ids])
            .map_err(|e| GpuError::Device(e.to_string()))?;
        Ok(Self { graph, depth, ids })
    }

    /// The depth and id buffers in `target`'s pool.
    fn buffers<'t>(&self, target: &'t RenderTarget) -> Result<[&'t wgpu::Buffer; 2], GpuError> {
        let get = |r| match target.pool.get(&self.graph, r) {
            Some(Physical::Buffer(b)) => Ok(b),
            _ => Err(GpuError::Device(
                "the pick buffers are not allocated".into(),
            )),
        };
        Ok([get(self.depth)?, get(self.ids)?])
    }
}

/// The depth bits of an inverted depth word of either splat tier (common.wgsl: a gap-filling
/// ring clears the top bit, which positive depths never set).
pub(crate) fn untier(inv_depth: u32) -> u32 {
    !(inv_depth | 0x8000_0000)
}

/// Reads the rows around `pixel` and picks the nearest covered pixel within `radius`.
fn read_pick(
    ctx: &GpuContext,
    target: &RenderTarget,
    [depth_buffer, id_buffer]: [&wgpu::Buffer; 2],
    pixel: [u32; 2],
    radius: u32,
) -> Result<Option<PickHit>, GpuError> {
    let (w, h) = (target.width, target.height);
    let Some(rows) = rows_around(pixel, radius, w, h) else {
        return Ok(None);
    };
    let (y0, y1) = (*rows.start(), *rows.end());
    let offset = y0 as u64 * w as u64 * 4;
    let size = (y1 - y0 + 1) as u64 * w as u64 * 4;
    let readback = |label| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (depth_rb, id_rb) = (readback("pick depth"), readback("pick ids"));
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(depth_buffer, offset, &depth_rb, 0, size);
    enc.copy_buffer_to_buffer(id_buffer, offset, &id_rb, 0, size);
    ctx.checked("reading the pick", || ctx.queue.submit([enc.finish()]))?;
    let depth: Vec<u32> = bytemuck::pod_collect_to_vec(&map_read(ctx, &depth_rb)?);
    let ids: Vec<u32> = bytemuck::pod_collect_to_vec(&map_read(ctx, &id_rb)?);
    let hit_at = |k: usize| match (depth.get(k), ids.get(k)) {
        (Some(d), Some(id)) if *d != 0 => Some((!*id, f32::from_bits(untier(*d)))),
        _ => None,
    };
    Ok(nearest_in_rows(w, pixel, radius, y0..=y1, hit_at))
}

/// The rows within `radius` of `pixel` in an image `height` pixels high; `None` when the
/// pixel lies outside a `width` × `height` image.
pub(crate) fn rows_around(
    pixel: [u32; 2],
    radius: u32,
    width: u32,
    height: u32,
) -> Option<std::ops::RangeInclusive<u32>> {
    if pixel[0] >= width || pixel[1] >= height {
        return None;
    }
    Some(pixel[1].saturating_sub(radius)..=(pixel[1] + radius).min(height - 1))
}

/// The covered pixel of `rows` (read back whole, `width` wide) nearest to `pixel` within
/// `radius`, the closer in depth on equal distance. `hit_at(k)` gives the id and depth at
/// index k of the rows read, `None` for an empty pixel.
pub(crate) fn nearest_in_rows(
    width: u32,
    pixel: [u32; 2],
    radius: u32,
    rows: std::ops::RangeInclusive<u32>,
    hit_at: impl Fn(usize) -> Option<(u32, f32)>,
) -> Option<PickHit> {
    let y0 = *rows.start();
    let mut best: Option<(u64, PickHit)> = None;
    for y in rows {
        for x in pixel[0].saturating_sub(radius)..=(pixel[0] + radius).min(width - 1) {
            let dist = (x.abs_diff(pixel[0]) as u64).pow(2) + (y.abs_diff(pixel[1]) as u64).pow(2);
            if dist > (radius as u64).pow(2) {
                continue;
            }
            let Some((id, depth)) = hit_at(((y - y0) * width + x) as usize) else {
                continue;
            };
            if best
                .as_ref()
                .is_none_or(|(bd, b)| (dist, depth) < (*bd, b.depth))
            {
                best = Some((
                    dist,
                    PickHit {
                        id,
                        depth,
                        pixel: [x, y],
                    },
                ));
            }
        }
    }
    best.map(|(_, h)| h)
}
