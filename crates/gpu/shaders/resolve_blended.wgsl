// Resolve of the blending rasterizers (HQS, HQS1R; blend_*.wgsl before this): the average colour
// and the closest depth, for the screen filters that need a layer.

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= screen.size.x || id.y >= screen.size.y {
        return;
    }
    let b = blended_pixel(id.y * screen.size.x + id.x);
    if !b.lit {
        write_empty(id.xy);
        return;
    }
    write_pixel(id.xy, b.rgb, depth_bits_of(b.inv_depth));
}
