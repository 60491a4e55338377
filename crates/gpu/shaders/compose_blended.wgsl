// Blending's normalisation merged with the final compose (WebGPU-engine paper §6.2: "the
// normalization step is merged with the Eye-Dome Lighting pass"; edl.wgsl and blend_*.wgsl before
// this): straight from HQS's or HQS1R's pixel buffers to the output image, with no resolved layer
// in between, when no screen filter needs one.

@group(0) @binding(1) var out_color: texture_storage_2d<rgba8unorm, write>;

fn neighbour_depth(q: vec2<i32>) -> f32 {
    let size = textureDimensions(out_color);
    let b = blended_pixel(u32(q.y) * size.x + u32(q.x));
    return select(0.0, bitcast<f32>(~(b.inv_depth | 0x80000000u)), b.lit);
}

@compute @workgroup_size(8, 8)
fn compose(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(out_color);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let here = vec2<i32>(id.xy);
    let b = blended_pixel(id.y * size.x + id.x);
    if !b.lit {
        textureStore(out_color, here, params.background);
        return;
    }
    let depth = bitcast<f32>(~(b.inv_depth | 0x80000000u));
    let shade = edl_shade(here, vec2<i32>(size), depth, 0.0);
    textureStore(out_color, here, vec4<f32>(unpack4x8unorm(b.rgb).rgb * shade, 1.0));
}
