// Final compose (edl.wgsl before this): background for empty pixels and Eye-Dome Lighting on the
// rest, from a resolved (and maybe filtered) layer. A colour alpha below 1 holds the splat's
// side / 255 (resolve_common.wgsl), which sets EDL's tolerance for splat steps.

@group(0) @binding(1) var in_color: texture_2d<f32>;
@group(0) @binding(2) var in_depth: texture_2d<f32>;
@group(0) @binding(3) var out_color: texture_storage_2d<rgba8unorm, write>;

fn neighbour_depth(q: vec2<i32>) -> f32 {
    return textureLoad(in_depth, q, 0).r;
}

@compute @workgroup_size(8, 8)
fn compose(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(in_color);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let here = vec2<i32>(id.xy);
    let c = textureLoad(in_color, here, 0);
    if c.a == 0.0 {
        textureStore(out_color, here, params.background);
        return;
    }
    let side = select(0.0, round(c.a * 255.0), c.a < 0.5);
    let shade = edl_shade(here, vec2<i32>(size), textureLoad(in_depth, here, 0).r, side);
    textureStore(out_color, here, vec4<f32>(c.rgb * shade, 1.0));
}
