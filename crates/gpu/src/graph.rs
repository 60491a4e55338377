//! The render graph (WebGPU-engine paper §3.4): a frame's passes are declared as nodes that
//! read and write resources, in the order they run. Compiling culls the passes whose outputs
//! nothing reads (walking back from the outputs the frame must produce), checks that every
//! transient is written before it is read, and gives each transient a slot for the span from its
//! first to its last use: a slot whose resource nothing reads any more takes the next transient
//! of the same description. A [`TransientPool`] holds the slots' GPU resources, sized to the
//! image, allocated before their first use and shared by every graph drawn into one target.
//! Graphs are compiled once per settings change, not per frame.

use std::collections::HashMap;

/// A resource of a graph: an index into its declarations.
pub(crate) type Res = usize;

/// What a resource is; transients of equal descriptions can share a slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum ResourceDesc {
    /// A storage buffer of so many bytes per pixel, zeroed before the pass that creates it.
    PixelBuffer { bytes_per_pixel: u32 },
    /// A colour image and its linear depth (target.rs `Layer`); every pass that creates one
    /// writes all of its pixels.
    Layer,
    /// The depth attachment of a render pipeline.
    DepthAttachment,
    /// Anything else a source owns and hands in (draw lists, the output image): imported only.
    Image,
}

#[derive(Clone, Debug)]
struct Declared {
    name: &'static str,
    desc: ResourceDesc,
    /// Owned outside the graph (kept between frames or read after them).
    imported: bool,
}

#[derive(Clone, Debug)]
struct Node<P> {
    pass: P,
    reads: Vec<Res>,
    writes: Vec<Res>,
}

/// Declares resources and passes.
#[derive(Clone, Debug)]
pub(crate) struct GraphBuilder<P> {
    resources: Vec<Declared>,
    nodes: Vec<Node<P>>,
}

/// A graph that cannot run: a bug in whoever declared it.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum GraphError {
    #[error("render graph: pass {pass} reads '{resource}' before any pass writes it")]
    ReadBeforeWrite {
        pass: String,
        resource: &'static str,
    },
    #[error("render graph: '{0}' is not declared")]
    Unknown(Res),
}

/// One pass that survived culling, with the transients it creates (cleared first when they are
/// pixel buffers).
#[derive(Clone, Debug)]
pub(crate) struct CompiledPass<P> {
    pub pass: P,
    pub creates: Vec<Res>,
}

/// Passes in order and where each transient lives.
#[derive(Clone, Debug)]
pub(crate) struct CompiledGraph<P> {
    pub passes: Vec<CompiledPass<P>>,
    /// The passes culled (their outputs were never read).
    pub culled: Vec<P>,
    resources: Vec<Declared>,
    /// Slot of each transient that a surviving pass uses.
    slot_of: Vec<Option<usize>>,
    /// Description of each slot.
    pub slots: Vec<ResourceDesc>,
}

impl<P> Default for GraphBuilder<P> {
    fn default() -> Self {
        Self {
            resources: Vec::new(),
            nodes: Vec::new(),
        }
    }
}

impl<P: Clone + std::fmt::Debug> GraphBuilder<P> {
    /// A resource owned outside the graph.
    pub fn import(&mut self, name: &'static str, desc: ResourceDesc) -> Res {
        self.declare(name, desc, true)
    }

    /// A resource that lives within one frame.
    pub fn transient(&mut self, name: &'static str, desc: ResourceDesc) -> Res {
        self.declare(name, desc, false)
    }

    fn declare(&mut self, name: &'static str, desc: ResourceDesc, imported: bool) -> Res {
        self.resources.push(Declared {
            name,
            desc,
            imported,
        });
        self.resources.len() - 1
    }

    /// A pass reading `reads` and writing `writes`, run after those declared before it.
    pub fn pass(&mut self, pass: P, reads: &[Res], writes: &[Res]) {
        self.nodes.push(Node {
            pass,
            reads: reads.to_vec(),
            writes: writes.to_vec(),
        });
    }

    /// Culls what `outputs` do not need, checks the order and places the transients.
    pub fn compile(self, outputs: &[Res]) -> Result<CompiledGraph<P>, GraphError> {
        let n = self.resources.len();
        for r in outputs.iter().chain(
            self.nodes
                .iter()
                .flat_map(|x| x.reads.iter().chain(&x.writes)),
        ) {
            if *r >= n {
                return Err(GraphError::Unknown(*r));
            }
        }
        // Backwards from the outputs: a pass lives when a later live pass or the frame reads
        // something it writes.
        let mut needed = vec![false; n];
        for r in outputs {
            needed[*r] = true;
        }
        let mut live = vec![false; self.nodes.len()];
        for (k, node) in self.nodes.iter().enumerate().rev() {
            if node.writes.iter().any(|w| needed[*w]) {
                live[k] = true;
                for r in &node.reads {
                    needed[*r] = true;
                }
            }
        }
        // Forwards: first and last use of each transient by live passes.
        let mut first = vec![usize::MAX; n];
        let mut last = vec![0usize; n];
        let mut written = vec![false; n];
        let kept: Vec<&Node<P>> = self
            .nodes
            .iter()
            .zip(&live)
            .filter(|(_, l)| **l)
            .map(|(x, _)| x)
            .collect();
        for (k, node) in kept.iter().enumerate() {
            for r in &node.reads {
                if !self.resources[*r].imported && !written[*r] {
                    return Err(GraphError::ReadBeforeWrite {
                        pass: format!("{:?}", node.pass),
                        resource: self.resources[*r].name,
                    });
                }
            }
            for r in node.reads.iter().chain(&node.writes) {
                first[*r] = first[*r].min(k);
                last[*r] = last[*r].max(k);
            }
            for w in &node.writes {
                written[*w] = true;
            }
        }
        // Transients that are outputs stay alive to the end.
        for r in outputs {
            last[*r] = kept.len();
        }
        // Slots in pass order: a slot is free once its resource's last use has passed.
        let mut slots: Vec<ResourceDesc> = Vec::new();
        let mut busy_until: Vec<usize> = Vec::new();
        let mut slot_of = vec![None; n];
        let mut passes = Vec::with_capacity(kept.len());
        for (k, node) in kept.iter().enumerate() {
            let mut creates = Vec::new();
            for r in node.reads.iter().chain(&node.writes) {
                let d = &self.resources[*r];
                if d.imported || slot_of[*r].is_some() || first[*r] != k {
                    continue;
                }
                let free = (0..slots.len()).find(|s| slots[*s] == d.desc && busy_until[*s] < k);
                let s = free.unwrap_or_else(|| {
                    slots.push(d.desc);
                    busy_until.push(0);
                    slots.len() - 1
                });
                busy_until[s] = last[*r];
                slot_of[*r] = Some(s);
                creates.push(*r);
            }
            passes.push(CompiledPass {
                pass: node.pass.clone(),
                creates,
            });
        }
        let culled = self
            .nodes
            .into_iter()
            .zip(live)
            .filter(|(_, l)| !*l)
            .map(|(x, _)| x.pass)
            .collect();
        Ok(CompiledGraph {
            passes,
            culled,
            resources: self.resources,
            slot_of,
            slots,
        })
    }
}

impl<P> CompiledGraph<P> {
    /// The slot a transient lives in (None: imported, or used by no surviving pass).
    pub fn slot(&self, r: Res) -> Option<usize> {
        self.slot_of.get(r).copied().flatten()
    }

    pub fn desc(&self, r: Res) -> Option<ResourceDesc> {
        self.resources.get(r).map(|d| d.desc)
    }

    /// Bytes per pixel of the graph's transients.
    pub fn transient_bytes_per_pixel(&self) -> u64 {
        self.slots.iter().map(|d| bytes_per_pixel(*d)).sum()
    }
}

pub(crate) fn bytes_per_pixel(desc: ResourceDesc) -> u64 {
    match desc {
        ResourceDesc::PixelBuffer { bytes_per_pixel } => bytes_per_pixel as u64,
        ResourceDesc::Layer => 8,
        ResourceDesc::DepthAttachment | ResourceDesc::Image => 4,
    }
}

/// A slot's GPU resource.
pub(crate) enum Physical {
    Buffer(wgpu::Buffer),
    Layer(crate::target::Layer),
    DepthAttachment(wgpu::Texture),
}

/// The GPU resources of graph slots, for one image size: slot k of a description is the k-th
/// resource of that description here, so graphs drawn into the same target share them (graphs
/// run one after the other and transients carry nothing from one to the next).
pub(crate) struct TransientPool {
    width: u32,
    height: u32,
    by_desc: HashMap<ResourceDesc, Vec<Physical>>,
}

impl TransientPool {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            by_desc: HashMap::new(),
        }
    }

    /// GPU bytes held.
    pub fn bytes(&self) -> u64 {
        let px = self.width as u64 * self.height as u64;
        self.by_desc
            .iter()
            .map(|(d, v)| bytes_per_pixel(*d) * px * v.len() as u64)
            .sum()
    }

    /// Allocates what `graph` needs and is not here yet.
    pub fn ensure<P>(
        &mut self,
        ctx: &crate::GpuContext,
        graph: &CompiledGraph<P>,
    ) -> Result<(), crate::GpuError> {
        let mut wanted: HashMap<ResourceDesc, usize> = HashMap::new();
        for d in &graph.slots {
            *wanted.entry(*d).or_default() += 1;
        }
        for (desc, count) in wanted {
            let have = self.by_desc.get(&desc).map_or(0, Vec::len);
            for _ in have..count {
                let made = ctx.checked("allocating a frame's transient resources", || {
                    allocate(&ctx.device, desc, self.width, self.height)
                })?;
                self.by_desc.entry(desc).or_default().push(made);
            }
        }
        Ok(())
    }

    /// The resource of transient `r` of `graph` (after [`ensure`](Self::ensure)).
    pub fn get<P>(&self, graph: &CompiledGraph<P>, r: Res) -> Option<&Physical> {
        let desc = graph.desc(r)?;
        let slot = graph.slot(r)?;
        // The k-th slot of this description in the graph.
        let ordinal = graph.slots[..slot].iter().filter(|d| **d == desc).count();
        self.by_desc.get(&desc)?.get(ordinal)
    }
}

fn allocate(device: &wgpu::Device, desc: ResourceDesc, width: u32, height: u32) -> Physical {
    let texture = |label: &str, format, usage| {
        crate::target::image(device, label, (width, height), format, usage)
    };
    let layer_usage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING;
    match desc {
        ResourceDesc::PixelBuffer { bytes_per_pixel } => {
            Physical::Buffer(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("transient pixel buffer"),
                size: (width as u64 * height as u64 * bytes_per_pixel as u64).max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }))
        }
        ResourceDesc::Layer => Physical::Layer(crate::target::Layer {
            color: texture("transient colour", crate::target::COLOR_FORMAT, layer_usage),
            depth: texture("transient depth", crate::target::DEPTH_FORMAT, layer_usage),
        }),
        ResourceDesc::DepthAttachment | ResourceDesc::Image => Physical::DepthAttachment(texture(
            "transient depth attachment",
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BUF: ResourceDesc = ResourceDesc::PixelBuffer { bytes_per_pixel: 4 };
    const IMG: ResourceDesc = ResourceDesc::Layer;

    #[test]
    fn passes_whose_outputs_nothing_reads_are_culled() {
        let mut g = GraphBuilder::default();
        let depth = g.transient("depth", BUF);
        let sums = g.transient("sums", BUF);
        let layer = g.transient("layer", IMG);
        let out = g.import("output", IMG);
        g.pass("depth pass", &[], &[depth]);
        g.pass("accumulate", &[depth], &[sums]);
        g.pass("resolve", &[depth, sums], &[layer]);
        g.pass("normalise + EDL", &[depth, sums], &[out]);
        let c = g.compile(&[out]).unwrap_or_else(|e| panic!("{e}"));
        let names: Vec<&str> = c.passes.iter().map(|p| p.pass).collect();
        assert_eq!(names, ["depth pass", "accumulate", "normalise + EDL"]);
        assert_eq!(c.culled, ["resolve"]);
        assert_eq!(
            c.slot(layer),
            None,
            "a culled pass's output is never allocated"
        );
        assert_eq!(c.slots.len(), 2);
    }

    #[test]
    fn dead_transients_give_their_slot_to_later_ones() {
        // resolve → occlusion → fill → a third filter → compose: the ping-pong of two images
        // emerges from lifetimes alone.
        let mut g = GraphBuilder::default();
        let a = g.transient("resolved", IMG);
        let b = g.transient("occluded", IMG);
        let c = g.transient("filled", IMG);
        let d = g.transient("smoothed", IMG);
        let out = g.import("output", IMG);
        g.pass("resolve", &[], &[a]);
        g.pass("occlusion", &[a], &[b]);
        g.pass("fill", &[b], &[c]);
        g.pass("smooth", &[c], &[d]);
        g.pass("compose", &[d], &[out]);
        let compiled = g.compile(&[out]).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(compiled.slots.len(), 2, "two images suffice");
        assert_eq!(compiled.slot(a), compiled.slot(c));
        assert_eq!(compiled.slot(b), compiled.slot(d));
        assert_ne!(compiled.slot(a), compiled.slot(b));
        assert_eq!(compiled.passes[0].creates, [a]);
        assert_eq!(compiled.passes[2].creates, [c]);
    }

    #[test]
    fn slots_are_shared_only_by_equal_descriptions() {
        let mut g = GraphBuilder::default();
        let a = g.transient("a", BUF);
        let b = g.transient("b", ResourceDesc::PixelBuffer { bytes_per_pixel: 8 });
        let out = g.import("output", IMG);
        g.pass("one", &[], &[a]);
        g.pass("two", &[a], &[]);
        g.pass("three", &[], &[b]);
        g.pass("four", &[a, b], &[out]);
        let c = g.compile(&[out]).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            c.culled,
            ["two"],
            "a pass that writes nothing read is culled"
        );
        assert_ne!(c.slot(a), c.slot(b));
        assert_eq!(c.transient_bytes_per_pixel(), 12);
    }

    #[test]
    fn reading_a_transient_nothing_wrote_is_an_error() {
        let mut g = GraphBuilder::default();
        let a = g.transient("keys", BUF);
        let out = g.import("output", IMG);
        g.pass("compose", &[a], &[out]);
        assert_eq!(
            g.compile(&[out]).err(),
            Some(GraphError::ReadBeforeWrite {
                pass: "\"compose\"".into(),
                resource: "keys"
            })
        );
        let mut g: GraphBuilder<&str> = GraphBuilder::default();
        g.pass("x", &[7], &[]);
        assert_eq!(g.compile(&[]).err(), Some(GraphError::Unknown(7)));
    }

    #[test]
    fn transient_outputs_live_to_the_end() {
        let mut g = GraphBuilder::default();
        let depth = g.transient("pick depth", BUF);
        let ids = g.transient("pick ids", BUF);
        let later = g.transient("later", BUF);
        g.pass("depth", &[], &[depth]);
        g.pass("ids", &[depth], &[ids]);
        g.pass("other", &[], &[later]);
        g.pass("reads other", &[later], &[ids]);
        let c = g.compile(&[depth, ids]).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(c.slots.len(), 3, "outputs are not reused");
    }
}
