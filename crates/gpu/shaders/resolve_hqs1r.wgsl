// Resolve of HQS1R (compute-shader paper §3.5.1): the 16-16-16-16 word plus the fallback words.

@group(1) @binding(0) var<storage, read> depth_buffer: array<u32>;
@group(1) @binding(1) var<storage, read> packed: array<u64>;
@group(1) @binding(2) var<storage, read> overflow: array<u64>;

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= screen.size.x || id.y >= screen.size.y {
        return;
    }
    let p = id.y * screen.size.x + id.x;
    let w = packed[p];
    let rg = overflow[p * 2u];
    let ba = overflow[p * 2u + 1u];
    let n = u32(w & 0xfffflu) + u32(ba & 0xfffffffflu);
    if n == 0u {
        write_empty(id.xy);
        return;
    }
    let r = (u32((w >> 48u) & 0xfffflu) + u32(rg >> 32u)) / n;
    let g = (u32((w >> 32u) & 0xfffflu) + u32(rg & 0xfffffffflu)) / n;
    let b = (u32((w >> 16u) & 0xfffflu) + u32(ba >> 32u)) / n;
    write_pixel(id.xy, r | (g << 8u) | (b << 16u), depth_bits_of(depth_buffer[p]));
}
