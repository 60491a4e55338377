// Draw entries of the continuous-LoD filter's output (clod.wgsl; WebGPU-engine paper §6.1):
// once the survivors of each drawn tile are counted, entry k draws page
// `entry_pages[k]` of its tile's region (entries[k].info is the drawn tile), so it holds the
// survivors of that page's span of the region, from none to a whole page.
struct Finalize {
    entries: u32,
    page_size: u32,
    _pad0: u32,
    _pad1: u32,
}

struct DrawEntry {
    slot: u32,
    info: u32,
    first: u32,
    count: u32,
}

@group(0) @binding(0) var<uniform> fin: Finalize;
@group(0) @binding(1) var<storage, read> entry_pages: array<u32>;
@group(0) @binding(2) var<storage, read> counted: array<u32>;
@group(0) @binding(3) var<storage, read_write> entries: array<DrawEntry>;

@compute @workgroup_size(64)
fn finalize_entries(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= fin.entries {
        return;
    }
    let start = entry_pages[k] * fin.page_size;
    let n = counted[entries[k].info];
    entries[k].count = select(0u, min(n - start, fin.page_size), n > start);
}
