// Bandwidth probe: a plain vec4 copy, the practical memory-bandwidth ceiling on this GPU that
// rasterizer throughput is compared against (DESIGN.md: "GB/s vs a copy kernel").

struct CopyParams {
    count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: CopyParams;
@group(0) @binding(1) var<storage, read> src: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<u32>>;

const PER_THREAD: u32 = 4u;

@compute @workgroup_size(256)
fn copy(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
    let base = (wg.x + wg.y * nwg.x) * 256u * PER_THREAD + lid;
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = base + k * 256u;
        if i < params.count {
            dst[i] = src[i];
        }
    }
}
