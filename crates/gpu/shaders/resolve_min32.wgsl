// Resolve of the 32-bit fallback rasterizer: ~depth and ~rgba in two buffers; 0 means no point.

@group(1) @binding(0) var<storage, read> depth_buffer: array<u32>;
@group(1) @binding(1) var<storage, read> color_buffer: array<u32>;

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= screen.size.x || id.y >= screen.size.y {
        return;
    }
    let p = id.y * screen.size.x + id.x;
    let inv_depth = depth_buffer[p];
    if inv_depth == 0u {
        write_empty(id.xy);
        return;
    }
    write_pixel(id.xy, ~color_buffer[p], depth_bits_of(inv_depth));
}
