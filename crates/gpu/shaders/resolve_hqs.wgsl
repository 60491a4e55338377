// Resolve of HQS (compute-shader paper §3.5, Listing 8): average colour = sums / count.

@group(1) @binding(0) var<storage, read> depth_buffer: array<u32>;
@group(1) @binding(1) var<storage, read> sums: array<u32>;

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= screen.size.x || id.y >= screen.size.y {
        return;
    }
    let p = id.y * screen.size.x + id.x;
    let n = sums[p * 4u + 3u];
    if n == 0u {
        write_empty(id.xy);
        return;
    }
    let r = sums[p * 4u] / n;
    let g = sums[p * 4u + 1u] / n;
    let b = sums[p * 4u + 2u] / n;
    write_pixel(id.xy, r | (g << 8u) | (b << 16u), depth_bits_of(depth_buffer[p]));
}
