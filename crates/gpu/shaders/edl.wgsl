// Eye-Dome Lighting (Boucheny; WebGPU-engine paper §6.3, eq. 10–12), shared by the compose
// passes: r_i = max(0, log2 z_c − log2 z_i) over 8 neighbours at `radius` pixels, shade =
// exp(−mean(r) · 300 · strength). Empty neighbours contribute nothing.
// On splats a response counts only beyond the depth step two neighbouring splats of one surface
// show: splats are flat, so a tilted surface is a staircase of steps up to about
// side / focal · tan θ in relative depth, which would outline every splat; real edges step far
// more. The including pass defines `neighbour_depth(q)` (linear depth, 0 = empty).
// EDL off is a pipeline of its own (EDL = false), not a test of the uniform strength: Mesa's
// lavapipe specialises a shader on uniform values that decide branches, again at every bind
// of its bind group, and keeps each copy until the device goes (~150 KB a frame).

struct ComposeParams {
    background: vec4<f32>,
    strength: f32,
    radius: f32,
    // Pixels per unit of lateral size over depth.
    focal_px: f32,
    _pad: f32,
}

// Steps EDL ignores, in log2 depth per pixel of splat side: adaptive splats are 1.25 spacings
// wide, so neighbours on a surface tilted by θ differ by side / (1.25 · focal) · tan θ in depth;
// up to tan θ = 3 (72°), over ln 2.
const STEP_SLOPE: f32 = 3.5;

@group(0) @binding(0) var<uniform> params: ComposeParams;

override EDL: bool = true;

// The shade of the pixel `here` (depth `depth`, splat side `side` in pixels, 0: not a splat).
fn edl_shade(here: vec2<i32>, size: vec2<i32>, depth: f32, side: f32) -> f32 {
    if !EDL {
        return 1.0;
    }
    let zc = log2(depth);
    let tolerance = STEP_SLOPE * side / params.focal_px;
    var response = 0.0;
    for (var k = 0; k < 8; k++) {
        let angle = f32(k) * 0.785398163;
        let d = vec2<i32>(round(vec2<f32>(cos(angle), sin(angle)) * params.radius));
        let q = clamp(here + d, vec2<i32>(0), size - vec2<i32>(1));
        let z = neighbour_depth(q);
        if z > 0.0 {
            response += max(0.0, zc - log2(z) - tolerance);
        }
    }
    return exp(-(response / 8.0) * 300.0 * params.strength);
}
