// Final compose: background for empty pixels and Eye-Dome Lighting (Boucheny; WebGPU paper §6.3,
// eq. 10–12): r_i = max(0, log2 z_c − log2 z_i) over 8 neighbours at `radius` pixels, shade =
// exp(−mean(r) · 300 · strength). Strength 0 disables EDL. Empty neighbours contribute nothing.
// On splats (alpha < 1 holds the splat's side / 255, resolve_common.wgsl) a response counts only
// beyond the depth step two neighbouring splats of one surface show: splats are flat, so a
// tilted surface is a staircase of steps up to about side / focal · tan θ in relative depth,
// which would outline every splat; real edges step far more.

struct ComposeParams {
    background: vec4<f32>,
    strength: f32,
    radius: f32,
    // Pixels per unit of lateral size over depth.
    focal_px: f32,
    _pad: f32,
}

// Steps EDL ignores, in log2 depth per pixel of splat side: adaptive splats are 1.5 spacings
// wide, so neighbours on a surface tilted by θ differ by side / (1.5 · focal) · tan θ in depth;
// up to tan θ = 3 (72°), over ln 2.
const STEP_SLOPE: f32 = 2.9;

@group(0) @binding(0) var<uniform> params: ComposeParams;
@group(0) @binding(1) var in_color: texture_2d<f32>;
@group(0) @binding(2) var in_depth: texture_2d<f32>;
@group(0) @binding(3) var out_color: texture_storage_2d<rgba8unorm, write>;

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
    var shade = 1.0;
    if params.strength > 0.0 {
        let zc = log2(textureLoad(in_depth, here, 0).r);
        // Splat side in pixels from alpha (1 = not a splat: no tolerance).
        var tolerance = 0.0;
        if c.a < 0.5 {
            tolerance = STEP_SLOPE * round(c.a * 255.0) / params.focal_px;
        }
        var response = 0.0;
        for (var k = 0; k < 8; k++) {
            let angle = f32(k) * 0.785398163;
            let d = vec2<i32>(round(vec2<f32>(cos(angle), sin(angle)) * params.radius));
            let q = clamp(here + d, vec2<i32>(0), vec2<i32>(size) - vec2<i32>(1));
            let z = textureLoad(in_depth, q, 0).r;
            if z > 0.0 {
                response += max(0.0, zc - log2(z) - tolerance);
            }
        }
        shade = exp(-(response / 8.0) * 300.0 * params.strength);
    }
    textureStore(out_color, here, vec4<f32>(c.rgb * shade, 1.0));
}
