//! The GPU buffer suballocator (WebGPU-engine paper §3.5): streamed content (3D Tiles' tiles)
//! comes and goes in pieces of a few hundred kilobytes, and a `create_buffer` for each costs a
//! trip through the backend. So buffers are made in pages of a fixed size, one pool per usage,
//! and an allocation is a range of a page: a first fit over pages that skips every page whose
//! largest free range is too small, the page's free ranges kept sorted by offset and joined
//! with their neighbours when a range comes back. A request larger than a page gets a page of
//! its own. The range bookkeeping (`Ranges`) is plain CPU code, tested without a GPU.

use crate::context::GpuContext;
use crate::GpuError;
use std::collections::HashMap;

/// Offsets are multiples of this (wgpu's storage binding offset alignment is at most 256).
pub const ALIGNMENT: u64 = 256;

/// The free ranges of one page, sorted by offset, never adjacent (joined when freed).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ranges {
    size: u64,
    /// (offset, length), sorted by offset.
    free: Vec<(u64, u64)>,
    largest: u64,
}

impl Ranges {
    /// A page of `size` bytes, all free.
    pub fn new(size: u64) -> Self {
        Self {
            size,
            free: vec![(0, size)],
            largest: size,
        }
    }

    /// The largest free range: a page whose largest range is too small is skipped whole.
    pub fn largest(&self) -> u64 {
        self.largest
    }

    /// Bytes free in all ranges.
    pub fn free_bytes(&self) -> u64 {
        self.free.iter().map(|(_, l)| l).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.free == [(0, self.size)]
    }

    /// Takes `len` bytes (a multiple of [`ALIGNMENT`]) from the first free range that holds
    /// them; its offset, or `None` when no range is large enough.
    pub fn take(&mut self, len: u64) -> Option<u64> {
        if len == 0 || len > self.largest {
            return None;
        }
        let k = self.free.iter().position(|(_, l)| *l >= len)?;
        let (offset, l) = self.free[k];
        if l == len {
            self.free.remove(k);
        } else {
            self.free[k] = (offset + len, l - len);
        }
        if l == self.largest {
            self.largest = self.free.iter().map(|(_, l)| *l).max().unwrap_or(0);
        }
        Some(offset)
    }

    /// Returns `offset..offset + len` (taken before), joining it with free neighbours.
    pub fn give(&mut self, offset: u64, len: u64) {
        let k = self.free.partition_point(|(o, _)| *o < offset);
        let (mut start, mut end) = (offset, offset + len);
        let joins_next = self.free.get(k).is_some_and(|(o, _)| *o == end);
        let joins_prev = k > 0 && {
            let (o, l) = self.free[k - 1];
            o + l == start
        };
        if joins_next {
            end += self.free[k].1;
            self.free.remove(k);
        }
        if joins_prev {
            start = self.free[k - 1].0;
            self.free[k - 1] = (start, end - start);
        } else {
            self.free.insert(k, (start, end - start));
        }
        self.largest = self.largest.max(end - start);
    }
}

/// A range of a page: where an allocation's bytes are.
#[derive(Clone, Debug)]
pub struct Allocation {
    usage: wgpu::BufferUsages,
    page: usize,
    pub offset: u64,
    /// Bytes asked for.
    pub size: u64,
    /// Bytes taken (rounded up to the alignment).
    taken: u64,
    buffer: wgpu::Buffer,
}

impl Allocation {
    /// The page buffer holding the allocation.
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Which page of its pool holds it (pages keep their index while they exist).
    pub fn page(&self) -> usize {
        self.page
    }

    /// The allocation's bytes as a binding.
    pub fn binding(&self) -> wgpu::BufferBinding<'_> {
        wgpu::BufferBinding {
            buffer: &self.buffer,
            offset: self.offset,
            size: wgpu::BufferSize::new(self.size),
        }
    }
}

struct Page {
    buffer: wgpu::Buffer,
    ranges: Ranges,
}

/// Pages of one usage.
#[derive(Default)]
struct Pool {
    pages: Vec<Option<Page>>,
}

/// Pools of pages, one per buffer usage.
pub struct Suballocator {
    page_size: u64,
    pools: HashMap<wgpu::BufferUsages, Pool>,
}

/// What the pools hold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SuballocatorStats {
    pub pages: usize,
    /// GPU bytes of all pages.
    pub reserved: u64,
    /// Bytes of them allocated.
    pub used: u64,
}

impl Suballocator {
    /// Pools whose pages hold `page_size` bytes (rounded up to the alignment).
    pub fn new(page_size: u64) -> Self {
        Self {
            page_size: page_size.max(ALIGNMENT).div_ceil(ALIGNMENT) * ALIGNMENT,
            pools: HashMap::new(),
        }
    }

    pub fn page_size(&self) -> u64 {
        self.page_size
    }

    /// `size` bytes of a buffer of `usage` (COPY_DST is added: content is written into it).
    pub fn alloc(
        &mut self,
        ctx: &GpuContext,
        usage: wgpu::BufferUsages,
        size: u64,
    ) -> Result<Allocation, GpuError> {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let taken = size.max(1).div_ceil(ALIGNMENT) * ALIGNMENT;
        let pool = self.pools.entry(usage).or_default();
        for (k, slot) in pool.pages.iter_mut().enumerate() {
            let Some(page) = slot else {
                continue;
            };
            if page.ranges.largest() < taken {
                continue;
            }
            if let Some(offset) = page.ranges.take(taken) {
                return Ok(Allocation {
                    usage,
                    page: k,
                    offset,
                    size,
                    taken,
                    buffer: page.buffer.clone(),
                });
            }
        }
        // No page holds it: a new one (of its own size when larger than a page).
        let bytes = taken.max(self.page_size);
        if bytes > ctx.caps.max_buffer {
            return Err(GpuError::InvalidInput(format!(
                "an allocation of {size} bytes exceeds the largest buffer ({} bytes)",
                ctx.caps.max_buffer
            )));
        }
        let buffer = ctx.checked("allocating a suballocator page", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("suballocator page"),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        })?;
        let mut ranges = Ranges::new(bytes);
        let offset = ranges.take(taken).unwrap_or(0);
        let page = Page {
            buffer: buffer.clone(),
            ranges,
        };
        let k = match pool.pages.iter().position(Option::is_none) {
            Some(k) => {
                pool.pages[k] = Some(page);
                k
            }
            None => {
                pool.pages.push(Some(page));
                pool.pages.len() - 1
            }
        };
        Ok(Allocation {
            usage,
            page: k,
            offset,
            size,
            taken,
            buffer,
        })
    }

    /// GPU bytes a new page would add for `size` bytes of `usage` (0 when a page has room).
    pub fn growth_for(&self, usage: wgpu::BufferUsages, size: u64) -> u64 {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let taken = size.max(1).div_ceil(ALIGNMENT) * ALIGNMENT;
        let fits = self.pools.get(&usage).is_some_and(|pool| {
            pool.pages
                .iter()
                .flatten()
                .any(|p| p.ranges.largest() >= taken)
        });
        if fits {
            0
        } else {
            taken.max(self.page_size)
        }
    }

    /// Gives an allocation back. Pages stay allocated for later requests; see
    /// [`trim`](Self::trim).
    pub fn free(&mut self, a: Allocation) {
        let page = self
            .pools
            .get_mut(&a.usage)
            .and_then(|p| p.pages.get_mut(a.page))
            .and_then(Option::as_mut);
        if let Some(page) = page {
            page.ranges.give(a.offset, a.taken);
        }
    }

    /// Releases the pages nothing is allocated from.
    pub fn trim(&mut self) {
        for pool in self.pools.values_mut() {
            for slot in &mut pool.pages {
                if slot.as_ref().is_some_and(|p| p.ranges.is_empty()) {
                    *slot = None;
                }
            }
        }
    }

    pub fn stats(&self) -> SuballocatorStats {
        let mut s = SuballocatorStats::default();
        for page in self.pools.values().flat_map(|p| p.pages.iter().flatten()) {
            s.pages += 1;
            s.reserved += page.ranges.size;
            s.used += page.ranges.size - page.ranges.free_bytes();
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::shuffle::SplitMix64;

    #[test]
    fn ranges_are_taken_first_fit_and_joined_when_given_back() {
        let mut r = Ranges::new(4096);
        let a = r.take(1024);
        let b = r.take(1024);
        let c = r.take(1024);
        assert_eq!((a, b, c), (Some(0), Some(1024), Some(2048)));
        assert_eq!(r.largest(), 1024);
        r.give(1024, 1024);
        assert_eq!(r.largest(), 1024, "a hole between two taken ranges");
        assert_eq!(r.take(2048), None, "no range of 2048 bytes yet");
        r.give(0, 1024);
        assert_eq!(r.largest(), 2048, "joined with the hole after it");
        r.give(2048, 1024);
        assert!(r.is_empty(), "everything joined back: {r:?}");
        assert_eq!(r.largest(), 4096);
    }

    #[test]
    fn random_allocations_never_overlap_and_all_come_back() {
        let mut rng = SplitMix64::new(3);
        let size = 64 << 20;
        let mut r = Ranges::new(size);
        let mut taken: Vec<(u64, u64)> = Vec::new();
        for step in 0..20_000 {
            if rng.below(3) < 2 || taken.is_empty() {
                let len = (1 + rng.below(4096)) * ALIGNMENT;
                if let Some(o) = r.take(len) {
                    assert!(o + len <= size);
                    taken.push((o, len));
                }
            } else {
                let k = rng.below(taken.len() as u64) as usize;
                let (o, l) = taken.swap_remove(k);
                r.give(o, l);
            }
            if step % 997 == 0 {
                let mut all = taken.clone();
                all.extend(r.free.iter().copied());
                all.sort_unstable();
                // Taken and free ranges tile the page exactly.
                let mut end = 0;
                for (o, l) in all {
                    assert_eq!(o, end, "a gap or an overlap at {o}");
                    end = o + l;
                }
                assert_eq!(end, size);
                let largest = r.free.iter().map(|(_, l)| *l).max().unwrap_or(0);
                assert_eq!(r.largest(), largest);
                assert!(
                    r.free.windows(2).all(|w| w[0].0 + w[0].1 < w[1].0),
                    "unjoined"
                );
            }
        }
        for (o, l) in taken {
            r.give(o, l);
        }
        assert!(r.is_empty());
    }
}

/// Mean cost of allocating and freeing, per operation, for the paper's benchmark.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AllocTimes {
    pub alloc_us: f64,
    pub free_ns: f64,
    /// Pages the suballocator made (0 for direct buffers).
    pub pages: usize,
}

/// Sizes of the paper's benchmark: `count` vertex buffers of 128 KB to 1 MB, uniformly
/// distributed (seeded).
pub fn benchmark_sizes(count: usize, seed: u64) -> Vec<u64> {
    let mut rng = pointlet_core::shuffle::SplitMix64::new(seed);
    (0..count)
        .map(|_| (128 << 10) + rng.below((1 << 20) - (128 << 10) + 1))
        .collect()
}

/// `sizes` allocated one `create_buffer` each, then all dropped; what each took on the CPU.
pub fn time_direct(ctx: &GpuContext, sizes: &[u64]) -> Result<AllocTimes, GpuError> {
    let usage = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
    let started = web_time::Instant::now();
    let buffers = ctx.checked("allocating buffers", || {
        sizes
            .iter()
            .map(|s| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: None,
                    size: *s,
                    usage,
                    mapped_at_creation: false,
                })
            })
            .collect::<Vec<_>>()
    })?;
    let allocated = started.elapsed();
    let started = web_time::Instant::now();
    for b in buffers {
        b.destroy();
        drop(b);
    }
    let freed = started.elapsed();
    ctx.wait()?;
    Ok(per_operation(allocated, freed, sizes.len(), 0))
}

/// `sizes` allocated from a suballocator of `page_size` pages, then all freed.
pub fn time_suballocator(
    ctx: &GpuContext,
    sizes: &[u64],
    page_size: u64,
) -> Result<AllocTimes, GpuError> {
    let mut sub = Suballocator::new(page_size);
    let started = web_time::Instant::now();
    let mut allocations = Vec::with_capacity(sizes.len());
    for s in sizes {
        allocations.push(sub.alloc(ctx, wgpu::BufferUsages::VERTEX, *s)?);
    }
    let allocated = started.elapsed();
    let pages = sub.stats().pages;
    let started = web_time::Instant::now();
    for a in allocations {
        sub.free(a);
    }
    let freed = started.elapsed();
    sub.trim();
    ctx.wait()?;
    Ok(per_operation(allocated, freed, sizes.len(), pages))
}

fn per_operation(
    allocated: std::time::Duration,
    freed: std::time::Duration,
    n: usize,
    pages: usize,
) -> AllocTimes {
    let n = n.max(1) as f64;
    AllocTimes {
        alloc_us: allocated.as_secs_f64() * 1e6 / n,
        free_ns: freed.as_secs_f64() * 1e9 / n,
        pages,
    }
}
