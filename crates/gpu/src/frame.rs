//! A frame's passes as a render graph (graph.rs): which passes a frame of a given shape runs,
//! what each reads and writes, and the executor that records the compiled graph. Screen passes
//! are recorded here; the passes that draw points belong to the renderer of their source (a
//! static cloud, the virtualized page pool, a progressive shuffled buffer) and are recorded
//! through a callback. With blending (HQS, HQS1R) and no filter between, the resolve is culled:
//! the normalisation is merged into the EDL pass (WebGPU-engine paper §6.2).

use crate::graph::{CompiledGraph, GraphBuilder, GraphError, Physical, Res, ResourceDesc};
use crate::raster::PixelKind;
use crate::screen::{Filter, ScreenPasses};
use crate::splat::SplatShape;
use crate::target::{Layer, RenderTarget};
use crate::GpuError;

/// Every pass a frame can have.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum FramePass {
    /// Virtualized rendering: the LoD and the frame's draw list.
    Lod,
    /// Stage k of the rasterizer (depth, then colour or accumulation for two-stage variants).
    Raster(u8),
    /// The hardware point-list baseline, straight into the raster layer.
    HwPoints,
    /// Splats as billboard quads, straight into the raster layer.
    Quads,
    /// Temporal reuse: the last frame's pixels into this frame's keys, then keeping this frame.
    ReuseReproject,
    ReuseKeep,
    /// Progressive rendering (progressive.rs): last frame's points, the next S slots, index
    /// keys to colour keys, and the list for the next frame.
    Reproject,
    Fill,
    Lookup,
    Prepare,
    /// Pixel buffers → the raster layer (colour and linear depth).
    Resolve,
    /// Closest-point splats: empty pixels take the closest splat within its reach.
    SplatGaps,
    Occlusion,
    HoleFill,
    /// Background and EDL into the output image.
    Compose,
    /// Blending's normalisation, background and EDL in one pass, from the pixel buffers.
    ComposeBlended,
}

impl FramePass {
    /// First of the two timestamp queries of the stage the pass belongs to (target.rs).
    fn stamps(self) -> Option<u32> {
        match self {
            FramePass::Raster(_) | FramePass::HwPoints | FramePass::Quads | FramePass::Fill => {
                Some(2)
            }
            FramePass::Reproject => Some(0),
            FramePass::Resolve
            | FramePass::SplatGaps
            | FramePass::Occlusion
            | FramePass::HoleFill
            | FramePass::Compose
            | FramePass::ComposeBlended => Some(4),
            _ => None,
        }
    }
}

/// Where a frame's points come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Source {
    Static,
    Paged,
    Progressive,
}

/// Everything that decides a frame's graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct FrameShape {
    pub source: Source,
    /// `Hardware` for hw-points and billboard quads, which write the raster layer directly.
    pub kind: PixelKind,
    /// Splats as billboard quads rather than hw-points (with `Hardware` pixels).
    pub quads: bool,
    pub reuse: bool,
    /// Closest-point splats of this shape fill their gaps on the screen.
    pub gaps: Option<SplatShape>,
    pub occlusion: bool,
    pub fill: bool,
}

/// A frame's resources by role.
#[derive(Clone, Copy, Debug, Default)]
struct Roles {
    keys: Option<Res>,
    depth32: Option<Res>,
    color32: Option<Res>,
    sums: Option<Res>,
    packed: Option<Res>,
    overflow: Option<Res>,
    hw_depth: Option<Res>,
    tiles: Option<Res>,
    raster_layer: Option<Res>,
    output: Option<Res>,
}

/// A compiled frame graph and the roles of its resources.
pub(crate) struct FrameGraph {
    pub shape: FrameShape,
    pub graph: CompiledGraph<FramePass>,
    roles: Roles,
    /// Per pass: the layers it reads and writes (filters and compose).
    layers: Vec<(Option<Res>, Option<Res>)>,
}

/// The per-pixel buffers a pass of points draws into, resolved for one frame.
pub(crate) struct PixelResources<'a> {
    pub keys: &'a wgpu::Buffer,
    pub depth32: Option<&'a wgpu::Buffer>,
    pub color32: Option<&'a wgpu::Buffer>,
    pub sums: Option<&'a wgpu::Buffer>,
    pub packed: Option<&'a wgpu::Buffer>,
    pub overflow: Option<&'a wgpu::Buffer>,
    pub hw_depth: Option<&'a wgpu::Texture>,
    pub raster_layer: &'a Layer,
}

impl PixelResources<'_> {
    /// The buffers of `kind`, in the order its passes bind them.
    pub fn buffers(&self, kind: PixelKind) -> Vec<&wgpu::Buffer> {
        let all = match kind {
            PixelKind::Hardware => vec![],
            PixelKind::Key64 => vec![Some(self.keys)],
            PixelKind::TwoPass32 => vec![self.depth32, self.color32],
            PixelKind::Hqs => vec![self.depth32, self.sums],
            PixelKind::Hqs1r => vec![self.depth32, self.packed, self.overflow],
        };
        all.into_iter().flatten().collect()
    }
}

/// Timestamp query indices of one pass: the beginning of its stage, the end, or both.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Stamps<'a> {
    pub queries: Option<&'a wgpu::QuerySet>,
    pub begin: Option<u32>,
    pub end: Option<u32>,
}

impl<'a> Stamps<'a> {
    pub fn compute(&self) -> Option<wgpu::ComputePassTimestampWrites<'a>> {
        let q = self.queries?;
        (self.begin.is_some() || self.end.is_some()).then_some(wgpu::ComputePassTimestampWrites {
            query_set: q,
            beginning_of_pass_write_index: self.begin,
            end_of_pass_write_index: self.end,
        })
    }

    pub fn render(&self) -> Option<wgpu::RenderPassTimestampWrites<'a>> {
        let q = self.queries?;
        (self.begin.is_some() || self.end.is_some()).then_some(wgpu::RenderPassTimestampWrites {
            query_set: q,
            beginning_of_pass_write_index: self.begin,
            end_of_pass_write_index: self.end,
        })
    }
}

const KEYS: ResourceDesc = ResourceDesc::PixelBuffer { bytes_per_pixel: 8 };
const WORD: ResourceDesc = ResourceDesc::PixelBuffer { bytes_per_pixel: 4 };

impl FrameGraph {
    /// The graph of a frame of `shape`.
    pub fn build(shape: FrameShape) -> Result<Self, GraphError> {
        let mut g = GraphBuilder::default();
        let mut r = Roles {
            output: Some(g.import("output image", ResourceDesc::Image)),
            raster_layer: Some(g.import("raster layer", ResourceDesc::Layer)),
            keys: Some(g.import("keys", KEYS)),
            ..Default::default()
        };
        let (Some(output), Some(raster_layer), Some(keys)) = (r.output, r.raster_layer, r.keys)
        else {
            unreachable!("declared above")
        };
        // What the source keeps between frames or hands out after them.
        let mut outputs = vec![output];
        let draw_list = g.import("draw list", ResourceDesc::Image);
        match shape.source {
            Source::Paged => g.pass(FramePass::Lod, &[], &[draw_list]),
            Source::Static => {}
            Source::Progressive => {
                let list = g.import("reproject list", ResourceDesc::Image);
                let indexed = g.import("index keys", KEYS);
                g.pass(FramePass::Reproject, &[list], &[indexed]);
                g.pass(FramePass::Fill, &[], &[indexed]);
                g.pass(FramePass::Lookup, &[indexed], &[keys]);
                g.pass(FramePass::Prepare, &[indexed], &[list]);
                outputs.push(list);
            }
        }
        let pixel_buffers: Vec<Res> = match (shape.source, shape.kind) {
            (Source::Progressive, _) => vec![keys],
            (_, PixelKind::Hardware) => {
                let hw = g.transient("hw depth", ResourceDesc::DepthAttachment);
                r.hw_depth = Some(hw);
                let pass = if shape.quads {
                    FramePass::Quads
                } else {
                    FramePass::HwPoints
                };
                g.pass(pass, &[draw_list], &[raster_layer, hw]);
                vec![]
            }
            (_, PixelKind::Key64) => {
                g.pass(FramePass::Raster(0), &[draw_list], &[keys]);
                if shape.reuse {
                    let kept = g.import("kept frame", KEYS);
                    g.pass(FramePass::ReuseReproject, &[kept], &[keys]);
                    g.pass(FramePass::ReuseKeep, &[keys], &[kept]);
                    outputs.push(kept);
                }
                vec![keys]
            }
            (_, kind) => {
                let depth = g.transient("depth", WORD);
                r.depth32 = Some(depth);
                g.pass(FramePass::Raster(0), &[draw_list], &[depth]);
                let second: Vec<Res> = match kind {
                    PixelKind::TwoPass32 => vec![g.transient("colour", WORD)],
                    PixelKind::Hqs => vec![g.transient(
                        "hqs sums",
                        ResourceDesc::PixelBuffer {
                            bytes_per_pixel: 16,
                        },
                    )],
                    _ => vec![
                        g.transient("hqs1r words", KEYS),
                        g.transient(
                            "hqs1r overflow",
                            ResourceDesc::PixelBuffer {
                                bytes_per_pixel: 16,
                            },
                        ),
                    ],
                };
                match kind {
                    PixelKind::TwoPass32 => r.color32 = second.first().copied(),
                    PixelKind::Hqs => r.sums = second.first().copied(),
                    _ => {
                        r.packed = second.first().copied();
                        r.overflow = second.get(1).copied();
                    }
                }
                g.pass(FramePass::Raster(1), &[draw_list, depth], &second);
                [vec![depth], second].concat()
            }
        };
        let mut layers = Vec::new();
        let mut declare = |g: &mut GraphBuilder<FramePass>,
                           pass: FramePass,
                           reads: &[Res],
                           writes: &[Res],
                           layer: (Option<Res>, Option<Res>)| {
            g.pass(pass, reads, writes);
            layers.push((pass, layer));
        };
        if shape.kind != PixelKind::Hardware || shape.source == Source::Progressive {
            declare(
                &mut g,
                FramePass::Resolve,
                &pixel_buffers,
                &[raster_layer],
                (None, Some(raster_layer)),
            );
        }
        let blended = matches!(shape.kind, PixelKind::Hqs | PixelKind::Hqs1r)
            && shape.source != Source::Progressive;
        if blended && !shape.occlusion && !shape.fill {
            declare(
                &mut g,
                FramePass::ComposeBlended,
                &pixel_buffers,
                &[output],
                (None, None),
            );
        } else {
            let mut current = raster_layer;
            if shape.gaps.is_some() {
                let tiles = g.transient(
                    "splat tiles",
                    ResourceDesc::PixelBuffer { bytes_per_pixel: 1 },
                );
                r.tiles = Some(tiles);
                let next = g.transient("gaps filled", ResourceDesc::Layer);
                declare(
                    &mut g,
                    FramePass::SplatGaps,
                    &[current],
                    &[next, tiles],
                    (Some(current), Some(next)),
                );
                current = next;
            }
            for (on, pass, name) in [
                (shape.occlusion, FramePass::Occlusion, "occlusion-filtered"),
                (shape.fill, FramePass::HoleFill, "hole-filled"),
            ] {
                if on {
                    let next = g.transient(name, ResourceDesc::Layer);
                    declare(
                        &mut g,
                        pass,
                        &[current],
                        &[next],
                        (Some(current), Some(next)),
                    );
                    current = next;
                }
            }
            declare(
                &mut g,
                FramePass::Compose,
                &[current],
                &[output],
                (Some(current), None),
            );
        }
        let graph = g.compile(&outputs)?;
        // Layers of the passes that survived, in order (screen passes are never culled twice).
        let layers = graph
            .passes
            .iter()
            .map(|p| {
                layers
                    .iter()
                    .find(|(pass, _)| *pass == p.pass)
                    .map(|(_, l)| *l)
                    .unwrap_or((None, None))
            })
            .collect();
        Ok(Self {
            shape,
            graph,
            roles: r,
            layers,
        })
    }

    /// Allocates the transients in `target`'s pool, then records every pass: screen passes
    /// here, point passes through `points` (given the frame's pixel resources and the pass's
    /// timestamps). Returns the CPU time the graph itself took, besides recording its passes.
    pub fn record(
        &self,
        ctx: &crate::GpuContext,
        enc: &mut wgpu::CommandEncoder,
        target: &mut RenderTarget,
        screen: &mut ScreenPasses,
        splat_sizes: bool,
        mut points: impl FnMut(
            FramePass,
            &mut wgpu::CommandEncoder,
            &PixelResources<'_>,
            Stamps<'_>,
        ) -> Result<(), GpuError>,
    ) -> Result<std::time::Duration, GpuError> {
        let started = web_time::Instant::now();
        let mut in_passes = std::time::Duration::ZERO;
        let kind = self.shape.kind;
        target.pool.ensure(ctx, &self.graph)?;
        let target = &*target;
        let pool = &target.pool;
        let buffer = |r: Option<Res>| match r.and_then(|r| pool.get(&self.graph, r)) {
            Some(Physical::Buffer(b)) => Some(b),
            _ => None,
        };
        let layer = |r: Option<Res>| -> Option<&Layer> {
            match r {
                Some(r) if Some(r) == self.roles.raster_layer => Some(&target.raster_layer),
                Some(r) => match pool.get(&self.graph, r) {
                    Some(Physical::Layer(l)) => Some(l),
                    _ => None,
                },
                None => None,
            }
        };
        let px = PixelResources {
            keys: &target.keys,
            depth32: buffer(self.roles.depth32),
            color32: buffer(self.roles.color32),
            sums: buffer(self.roles.sums),
            packed: buffer(self.roles.packed),
            overflow: buffer(self.roles.overflow),
            hw_depth: match self.roles.hw_depth.and_then(|r| pool.get(&self.graph, r)) {
                Some(Physical::DepthAttachment(t)) => Some(t),
                _ => None,
            },
            raster_layer: &target.raster_layer,
        };
        let queries = target.timer.as_ref().map(|t| &t.queries);
        let passes = &self.graph.passes;
        for (k, p) in passes.iter().enumerate() {
            for r in &p.creates {
                if let Some(Physical::Buffer(b)) = pool.get(&self.graph, *r) {
                    enc.clear_buffer(b, 0, None);
                }
            }
            // A stage's first pass starts its timestamp, its last ends it.
            let base = p.pass.stamps();
            let first = k == 0 || passes[k - 1].pass.stamps() != base;
            let last = k + 1 == passes.len() || passes[k + 1].pass.stamps() != base;
            let stamps = Stamps {
                queries,
                begin: base.filter(|_| first),
                end: base.filter(|_| last).map(|b| b + 1),
            };
            let (src, dst) = self.layers.get(k).copied().unwrap_or((None, None));
            let pass_started = web_time::Instant::now();
            match p.pass {
                FramePass::Resolve => {
                    let mut pass = begin(enc, "resolve", &stamps);
                    screen.resolve(
                        &ctx.device,
                        &mut pass,
                        target,
                        kind,
                        splat_sizes,
                        &px.buffers(kind),
                    );
                }
                FramePass::Occlusion | FramePass::HoleFill => {
                    let (Some(src), Some(dst)) = (layer(src), layer(dst)) else {
                        return Err(GpuError::Device(format!(
                            "render graph: no layers for {:?}",
                            p.pass
                        )));
                    };
                    let filter = if p.pass == FramePass::Occlusion {
                        Filter::Occlusion
                    } else {
                        Filter::HoleFill
                    };
                    let mut pass = begin(enc, "screen filter", &stamps);
                    screen.filter(&ctx.device, &mut pass, target, filter, src, dst);
                }
                FramePass::SplatGaps => {
                    let (Some(src), Some(dst), Some(tiles), Some(shape)) = (
                        layer(src),
                        layer(dst),
                        buffer(self.roles.tiles),
                        self.shape.gaps,
                    ) else {
                        return Err(GpuError::Device("render graph: splat gaps unbound".into()));
                    };
                    let mut pass = begin(enc, "splat gaps", &stamps);
                    screen.gaps(&ctx.device, &mut pass, target, shape, src, dst, tiles);
                }
                FramePass::Compose => {
                    let Some(src) = layer(src) else {
                        return Err(GpuError::Device(
                            "render graph: compose has no layer".into(),
                        ));
                    };
                    let mut pass = begin(enc, "compose", &stamps);
                    screen.compose(&ctx.device, &mut pass, target, src);
                }
                FramePass::ComposeBlended => {
                    let mut pass = begin(enc, "normalise and compose", &stamps);
                    screen.compose_blended(&ctx.device, &mut pass, target, kind, &px.buffers(kind));
                }
                other => points(other, enc, &px, stamps)?,
            }
            in_passes += pass_started.elapsed();
        }
        // The graph's own work: allocation checks, clears, resolving resources, timestamps.
        Ok(started.elapsed().saturating_sub(in_passes))
    }
}

fn begin<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    stamps: &Stamps<'_>,
) -> wgpu::ComputePass<'e> {
    enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: stamps.compute(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(source: Source, kind: PixelKind, occlusion: bool, fill: bool) -> FrameShape {
        FrameShape {
            source,
            kind,
            quads: false,
            reuse: false,
            gaps: None,
            occlusion,
            fill,
        }
    }

    fn passes(s: FrameShape) -> Vec<FramePass> {
        let g = FrameGraph::build(s).unwrap_or_else(|e| panic!("{e}"));
        g.graph.passes.iter().map(|p| p.pass).collect()
    }

    #[test]
    fn blending_without_filters_merges_its_normalisation_into_edl() {
        use FramePass::*;
        let s = shape(Source::Paged, PixelKind::Hqs, false, false);
        assert_eq!(passes(s), [Lod, Raster(0), Raster(1), ComposeBlended]);
        let g = FrameGraph::build(s).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(g.graph.culled, [Resolve], "the resolve is culled");
        // With a filter the resolved layer is needed again.
        let s = shape(Source::Paged, PixelKind::Hqs1r, false, true);
        assert_eq!(
            passes(s),
            [Lod, Raster(0), Raster(1), Resolve, HoleFill, Compose]
        );
    }

    #[test]
    fn closest_point_frames_allocate_only_what_they_use() {
        use FramePass::*;
        let s = shape(Source::Static, PixelKind::Key64, false, false);
        assert_eq!(passes(s), [Raster(0), Resolve, Compose]);
        let g = FrameGraph::build(s).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            g.graph.transient_bytes_per_pixel(),
            0,
            "keys and layer are the target's"
        );
        let both = FrameGraph::build(shape(Source::Static, PixelKind::Key64, true, true))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            both.graph.transient_bytes_per_pixel(),
            16,
            "two filtered layers"
        );
        let hqs1r = FrameGraph::build(shape(Source::Static, PixelKind::Hqs1r, false, false))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(hqs1r.graph.transient_bytes_per_pixel(), 28);
    }

    #[test]
    fn progressive_and_hardware_frames() {
        use FramePass::*;
        assert_eq!(
            passes(shape(Source::Progressive, PixelKind::Key64, true, false)),
            [Reproject, Fill, Lookup, Prepare, Resolve, Occlusion, Compose]
        );
        assert_eq!(
            passes(shape(Source::Static, PixelKind::Hardware, false, false)),
            [HwPoints, Compose]
        );
        let mut gaps = shape(Source::Static, PixelKind::Key64, false, true);
        gaps.gaps = Some(SplatShape::Circle);
        assert_eq!(
            passes(gaps),
            [Raster(0), Resolve, SplatGaps, HoleFill, Compose]
        );
        let mut quads = shape(Source::Paged, PixelKind::Hardware, false, true);
        quads.quads = true;
        assert_eq!(passes(quads), [Lod, Quads, HoleFill, Compose]);
        let mut reuse = shape(Source::Paged, PixelKind::Key64, false, false);
        reuse.reuse = true;
        assert_eq!(
            passes(reuse),
            [Lod, Raster(0), ReuseReproject, ReuseKeep, Resolve, Compose]
        );
    }
}

/// What a compiled frame graph runs, for reports (`bench`).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameGraphSummary {
    /// The passes in order.
    pub passes: Vec<String>,
    /// The passes culled because nothing read their outputs.
    pub culled: Vec<String>,
    /// GPU bytes per pixel of the graph's transients.
    pub transient_bytes_per_pixel: u64,
}

impl FrameGraph {
    pub fn summary(&self) -> FrameGraphSummary {
        let name = |p: &FramePass| format!("{p:?}");
        FrameGraphSummary {
            passes: self.graph.passes.iter().map(|p| name(&p.pass)).collect(),
            culled: self.graph.culled.iter().map(name).collect(),
            transient_bytes_per_pixel: self.graph.transient_bytes_per_pixel(),
        }
    }
}
