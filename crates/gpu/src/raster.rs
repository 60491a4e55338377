//! The rasterizer variants of the compute-shader paper (§3) and their pipelines.

use crate::context::Capabilities;
use crate::shaders;
use crate::splat::{self, SplatMode};
use crate::storage::{point_group_layout, PointEncoding, PointStorage};

/// Every way of drawing points, selectable by name (`--raster`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RasterVariant {
    /// The render pipeline's point-list primitive (the paper's GL_POINTS baseline).
    HwPoints,
    /// One 64-bit atomic per point (§3.1).
    AtomicMin,
    /// `AtomicMin` + early depth test (§3.2).
    EarlyZ,
    /// Subgroup reduction (§3.3).
    Reduce,
    ReduceEarlyZ,
    /// Subgroup deduplication (§3.4, emulated with WGSL subgroup operations).
    Dedup,
    /// Depth pass + blend of points within 1 % of the closest (§3.5).
    Hqs,
    /// Single 64-bit atomicAdd per point with overflow fallback (§3.5.1).
    Hqs1r,
    /// Two 32-bit passes (depth, then colour): for adapters without 64-bit atomics.
    AtomicMin32,
}

impl RasterVariant {
    pub const ALL: [RasterVariant; 9] = [
        RasterVariant::HwPoints,
        RasterVariant::AtomicMin,
        RasterVariant::EarlyZ,
        RasterVariant::Reduce,
        RasterVariant::ReduceEarlyZ,
        RasterVariant::Dedup,
        RasterVariant::Hqs,
        RasterVariant::Hqs1r,
        RasterVariant::AtomicMin32,
    ];

    pub fn name(self) -> &'static str {
        match self {
            RasterVariant::HwPoints => "hw-points",
            RasterVariant::AtomicMin => "atomic-min",
            RasterVariant::EarlyZ => "early-z",
            RasterVariant::Reduce => "reduce",
            RasterVariant::ReduceEarlyZ => "reduce-early-z",
            RasterVariant::Dedup => "dedup",
            RasterVariant::Hqs => "hqs",
            RasterVariant::Hqs1r => "hqs1r",
            RasterVariant::AtomicMin32 => "atomic-min-32",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == s)
    }

    /// Why this variant cannot run on an adapter with `caps`, if it cannot.
    pub fn unsupported_reason(self, caps: &Capabilities) -> Option<&'static str> {
        use RasterVariant::*;
        match self {
            AtomicMin | EarlyZ if !caps.int64_atomics => {
                Some("needs 64-bit atomicMin/Max (SHADER_INT64_ATOMIC_MIN_MAX)")
            }
            Reduce | ReduceEarlyZ | Dedup if !caps.int64_atomics => {
                Some("needs 64-bit atomicMin/Max (SHADER_INT64_ATOMIC_MIN_MAX)")
            }
            Reduce | ReduceEarlyZ | Dedup if !caps.subgroups => {
                Some("needs subgroup operations (SUBGROUP)")
            }
            Hqs1r if !caps.int64_atomic_add => {
                Some("needs 64-bit atomicAdd (SHADER_INT64_ATOMIC_ALL_OPS)")
            }
            _ => None,
        }
    }

    /// The variant to use instead when this one is unsupported: the closest-point variants fall
    /// back to the two-pass 32-bit path, HQS1R to HQS.
    pub fn fallback(self, caps: &Capabilities) -> RasterVariant {
        if self.unsupported_reason(caps).is_none() {
            return self;
        }
        match self {
            RasterVariant::Hqs1r => RasterVariant::Hqs,
            RasterVariant::Reduce | RasterVariant::ReduceEarlyZ | RasterVariant::Dedup
                if caps.int64_atomics =>
            {
                RasterVariant::EarlyZ
            }
            _ => RasterVariant::AtomicMin32,
        }
    }

    /// Which per-pixel buffers the variant writes and the resolve pass reads.
    pub(crate) fn buffers(self) -> PixelKind {
        match self {
            RasterVariant::HwPoints => PixelKind::Hardware,
            RasterVariant::AtomicMin
            | RasterVariant::EarlyZ
            | RasterVariant::Reduce
            | RasterVariant::ReduceEarlyZ
            | RasterVariant::Dedup => PixelKind::Key64,
            RasterVariant::AtomicMin32 => PixelKind::TwoPass32,
            RasterVariant::Hqs => PixelKind::Hqs,
            RasterVariant::Hqs1r => PixelKind::Hqs1r,
        }
    }

    /// True for the variants that keep the closest point per pixel (against blending).
    pub fn closest_point(self) -> bool {
        matches!(self.buffers(), PixelKind::Key64 | PixelKind::TwoPass32)
    }

    /// True for the single-atomic closest-point variants: one key per pixel that only grows,
    /// so more points can be drawn into a kept framebuffer later with the same result.
    pub fn accumulates(self) -> bool {
        self.buffers() == PixelKind::Key64
    }

    /// Geometry passes over all points (HQS and the 32-bit path read every point twice).
    pub fn geometry_passes(self) -> u32 {
        match self {
            RasterVariant::Hqs | RasterVariant::Hqs1r | RasterVariant::AtomicMin32 => 2,
            _ => 1,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum PixelKind {
    Hardware,
    Key64,
    TwoPass32,
    Hqs,
    Hqs1r,
}

impl PixelKind {
    /// Closest-point buffers keep a colour word per pixel, whose alpha byte holds the splat
    /// side when splats are drawn (blending sums colours and keeps none).
    pub fn carries_splat_sizes(self) -> bool {
        matches!(self, PixelKind::Key64 | PixelKind::TwoPass32)
    }
}

/// A layout of `n` storage buffers at bindings 0..n.
pub(crate) fn storage_layout(
    device: &wgpu::Device,
    n: usize,
    read_only: bool,
) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = (0..n as u32)
        .map(|binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("pixel buffers"),
        entries: &entries,
    })
}

/// A bind group of whole buffers, buffer i at binding i.
pub(crate) fn storage_group(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<_> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// One compute pipeline that runs over every page, with the pixel buffers it writes.
pub(crate) struct PointStage {
    pub pipeline: wgpu::ComputePipeline,
    /// Indices into the variant's pixel buffers (group 1 is built from these).
    pub buffers: Vec<usize>,
    pub group1_layout: wgpu::BindGroupLayout,
}

/// The compute stages of one variant, in order.
pub(crate) struct RasterPipelines {
    pub stages: Vec<PointStage>,
}

pub(crate) const WORKGROUP: u32 = 256;

impl RasterPipelines {
    pub fn new(
        device: &wgpu::Device,
        variant: RasterVariant,
        encoding: PointEncoding,
        page_size: u32,
        splats: SplatMode,
    ) -> Self {
        Self::build(device, variant, encoding, page_size, false, splats)
    }

    /// A closest-point variant keyed by point id instead of colour (progressive rendering's
    /// Fill pass: its Prepare pass lists the winning points), which also keeps the colour key
    /// of each point in a second pixel buffer (color_keys_kept.wgsl).
    pub fn indexed(
        device: &wgpu::Device,
        variant: RasterVariant,
        encoding: PointEncoding,
        page_size: u32,
        splats: SplatMode,
    ) -> Self {
        Self::build(device, variant, encoding, page_size, true, splats)
    }

    fn build(
        device: &wgpu::Device,
        variant: RasterVariant,
        encoding: PointEncoding,
        page_size: u32,
        index_keys: bool,
        splats: SplatMode,
    ) -> Self {
        // The shuffled buffer of progressive rendering (always Full16) has empty slots.
        let skip_empty = index_keys && encoding == PointEncoding::Full16;
        // Closest-point stages: what they do with colour keys, and the pixel buffers they
        // write (the framebuffer, and for index keys the colour keys beside it).
        let (keys, keyed_buffers) = if index_keys {
            (shaders::COLOR_KEYS_KEPT, vec![0, 1])
        } else {
            (shaders::COLOR_KEYS_OFF, vec![0])
        };
        let keyed = |body: &str| format!("{keys}\n{body}");
        let index_keys = ("INDEX_KEYS", index_keys as u32 as f64);
        let group0 = point_group_layout(device, encoding);
        let stage =
            |label: &str, body: &str, entry: &str, consts: &[(&str, f64)], buffers: Vec<usize>| {
                let source = shaders::point_pass(encoding, body);
                let module = shaders::module(device, label, &source);
                let group1_layout = storage_layout(device, buffers.len(), false);
                let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(label),
                    bind_group_layouts: &[Some(&group0), Some(&group1_layout)],
                    immediate_size: 0,
                });
                let mut constants = vec![("WG", WORKGROUP as f64), ("PAGE_SIZE", page_size as f64)];
                constants.extend_from_slice(consts);
                constants.extend_from_slice(&splat::constants(splats));
                if skip_empty {
                    constants.push(("SKIP_EMPTY", 1.0));
                }
                let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        zero_initialize_workgroup_memory: false,
                    },
                    cache: None,
                });
                PointStage {
                    pipeline,
                    buffers,
                    group1_layout,
                }
            };
        let depth = || {
            stage(
                "depth pass",
                shaders::RASTER_DEPTH,
                "depth_pass",
                &[],
                vec![0],
            )
        };
        let stages = match variant {
            RasterVariant::HwPoints => vec![],
            RasterVariant::AtomicMin | RasterVariant::EarlyZ => vec![stage(
                variant.name(),
                &keyed(shaders::RASTER_MIN64),
                "raster",
                &[
                    ("EARLY_Z", (variant == RasterVariant::EarlyZ) as u32 as f64),
                    index_keys,
                ],
                keyed_buffers,
            )],
            RasterVariant::Reduce | RasterVariant::ReduceEarlyZ | RasterVariant::Dedup => {
                let early = variant != RasterVariant::Reduce;
                let mode = (variant == RasterVariant::Dedup) as u32;
                vec![stage(
                    variant.name(),
                    &keyed(shaders::RASTER_SUBGROUP),
                    "raster",
                    &[
                        ("EARLY_Z", early as u32 as f64),
                        ("MODE", mode as f64),
                        index_keys,
                    ],
                    keyed_buffers,
                )]
            }
            RasterVariant::AtomicMin32 => vec![
                depth(),
                stage(
                    "colour pass",
                    shaders::RASTER_MIN32,
                    "color_pass",
                    &[],
                    vec![0, 1],
                ),
            ],
            RasterVariant::Hqs => vec![
                depth(),
                stage(
                    "hqs",
                    &format!("{}\n{}", shaders::RASTER_HQS, shaders::BLEND_SPLATS),
                    "accumulate",
                    &[],
                    vec![0, 1],
                ),
            ],
            RasterVariant::Hqs1r => vec![
                depth(),
                stage(
                    "hqs1r",
                    &format!("{}\n{}", shaders::RASTER_HQS1R, shaders::BLEND_SPLATS),
                    "accumulate",
                    &[],
                    vec![0, 1, 2],
                ),
            ],
        };
        Self { stages }
    }

    /// Records stage `k` over every chunk of `storage` (its pixel buffers picked from the
    /// variant's `pixel_buffers`).
    pub fn record_stage(
        &self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        k: usize,
        storage: &PointStorage,
        dispatch: RasterDispatch<'_>,
        pixel_buffers: &[&wgpu::Buffer],
    ) {
        let Some(stage) = self.stages.get(k) else {
            return;
        };
        let mine: Vec<&wgpu::Buffer> = stage.buffers.iter().map(|i| pixel_buffers[*i]).collect();
        let group1 = storage_group(device, "pixel buffers", &stage.group1_layout, &mine);
        pass.set_pipeline(&stage.pipeline);
        pass.set_bind_group(1, &group1, &[]);
        for (c, chunk) in storage.chunks.iter().enumerate() {
            pass.set_bind_group(0, &chunk.bind_group, &[]);
            match dispatch {
                RasterDispatch::Direct => {
                    let [x, y] = grid(chunk.slots);
                    pass.dispatch_workgroups(x, y, 1);
                }
                RasterDispatch::Indirect(args) => {
                    pass.dispatch_workgroups_indirect(args, c as u64 * 12);
                }
            }
        }
    }

    /// Records every stage over every chunk of `storage` into one compute pass.
    pub fn record(
        &self,
        device: &wgpu::Device,
        pass: &mut wgpu::ComputePass<'_>,
        storage: &PointStorage,
        dispatch: RasterDispatch<'_>,
        pixel_buffers: &[&wgpu::Buffer],
    ) {
        for k in 0..self.stages.len() {
            self.record_stage(device, pass, k, storage, dispatch, pixel_buffers);
        }
    }
}

impl RasterPipelines {
    /// The pick passes: closest depth, then the id of the closest point per pixel (32-bit
    /// atomics only, so picking works on every adapter).
    pub fn pick(
        device: &wgpu::Device,
        encoding: PointEncoding,
        page_size: u32,
        splats: SplatMode,
    ) -> Self {
        let mut p = Self::new(
            device,
            RasterVariant::AtomicMin32,
            encoding,
            page_size,
            splats,
        );
        let group0 = point_group_layout(device, encoding);
        let source = shaders::point_pass(encoding, shaders::RASTER_MIN32);
        let module = shaders::module(device, "pick", &source);
        let group1_layout = storage_layout(device, 2, false);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("pick"),
            bind_group_layouts: &[Some(&group0), Some(&group1_layout)],
            immediate_size: 0,
        });
        let [splats, circle] = splat::constants(splats);
        let constants = [
            ("WG", WORKGROUP as f64),
            ("PAGE_SIZE", page_size as f64),
            ("PICK", 1.0),
            splats,
            circle,
        ];
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("pick"),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("color_pass"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        p.stages.truncate(1);
        p.stages.push(PointStage {
            pipeline,
            buffers: vec![0, 1],
            group1_layout,
        });
        p
    }
}

/// How many workgroups each chunk's dispatch gets: one per slot (static clouds list every
/// page), or the counts the LoD pass wrote (three u32 per chunk).
#[derive(Clone, Copy)]
pub(crate) enum RasterDispatch<'a> {
    Direct,
    Indirect(&'a wgpu::Buffer),
}

/// A 2-D workgroup grid with at least `groups` groups (65 535 per dimension at most).
pub(crate) fn grid(groups: u32) -> [u32; 2] {
    let x = groups.clamp(1, 65_535);
    [x, groups.div_ceil(x).max(1)]
}
