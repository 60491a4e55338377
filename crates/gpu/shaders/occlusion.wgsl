// Occlusion filter (virtualized paper §III-D2, eq. 4): removes points seen through gaps of a
// nearer surface, using only depths. For a pixel at depth d1 and a neighbour k pixels away at
// d2 < d1: β = atan(k · w(d1) / (d1 − d2)), with w(d) = d · pixel_angle the width of a pixel at
// depth d. β < threshold (the paper's 0.1) means the neighbour towers over the pixel. The
// paper gives β but not how neighbours combine; we look along 8 directions up to `radius` and
// drop the pixel when at least 6 are blocked — a point seen through a hole is surrounded by the
// nearer surface, while the background just beside a silhouette is blocked on one side only.
// Dropped pixels become empty, for hole filling to cover.

struct OcclusionParams {
    radius: u32,
    threshold: f32,
    // tan of the horizontal pixel angle: width of a pixel at depth d is d · pixel_angle.
    pixel_angle: f32,
    min_blocked: u32,
}

@group(0) @binding(0) var<uniform> params: OcclusionParams;
@group(0) @binding(1) var in_color: texture_2d<f32>;
@group(0) @binding(2) var in_depth: texture_2d<f32>;
@group(0) @binding(3) var out_color: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(4) var out_depth: texture_storage_2d<r32float, write>;

const DIRS = array<vec2<i32>, 8>(
    vec2<i32>(1, 0), vec2<i32>(1, 1), vec2<i32>(0, 1), vec2<i32>(-1, 1),
    vec2<i32>(-1, 0), vec2<i32>(-1, -1), vec2<i32>(0, -1), vec2<i32>(1, -1),
);

@compute @workgroup_size(8, 8)
fn occlusion(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(in_color);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let here = vec2<i32>(id.xy);
    let c = textureLoad(in_color, here, 0);
    let d1 = textureLoad(in_depth, here, 0).r;
    var blocked = 0u;
    if c.a > 0.0 {
        let w = d1 * params.pixel_angle;
        for (var k = 0u; k < 8u; k++) {
            for (var s = 1u; s <= params.radius; s++) {
                let q = here + DIRS[k] * i32(s);
                if q.x < 0 || q.y < 0 || q.x >= i32(size.x) || q.y >= i32(size.y) {
                    break;
                }
                let d2 = textureLoad(in_depth, q, 0).r;
                let lateral = f32(s) * length(vec2<f32>(DIRS[k])) * w;
                if d2 > 0.0 && d2 < d1 && atan(lateral / (d1 - d2)) < params.threshold {
                    blocked += 1u;
                    break;
                }
            }
        }
    }
    if blocked >= params.min_blocked {
        textureStore(out_color, here, vec4<f32>(0.0));
        textureStore(out_depth, here, vec4<f32>(0.0));
    } else {
        textureStore(out_color, here, c);
        textureStore(out_depth, here, vec4<f32>(d1, 0.0, 0.0, 0.0));
    }
}
