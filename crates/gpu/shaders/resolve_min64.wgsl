// Resolve of the 64-bit closest-point framebuffer (compute-shader paper §3.1, Listing 2):
// unpack ~depth << 32 | ~rgba keys; 0 means no point.

@group(1) @binding(0) var<storage, read> framebuffer: array<u64>;

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= screen.size.x || id.y >= screen.size.y {
        return;
    }
    let key = framebuffer[id.y * screen.size.x + id.x];
    if key == 0lu {
        write_empty(id.xy);
        return;
    }
    write_pixel(id.xy, ~u32(key & 0xfffffffflu), depth_bits_of(u32(key >> 32u)));
}
