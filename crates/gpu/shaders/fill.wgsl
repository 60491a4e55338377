// Hole filling (virtualized paper §III-D1): an empty pixel takes the mean colour and mean depth
// of the non-empty pixels in its (2r+1)×(2r+1) neighbourhood; with none, it stays empty.
// Deliberately simple: no boundary detection, so silhouettes grow by r pixels.
// The radius is a pipeline constant, not a uniform: lavapipe recompiles a loop bounded by a
// uniform at every bind and keeps each copy.

override RADIUS: u32 = 1u;

@group(0) @binding(1) var in_color: texture_2d<f32>;
@group(0) @binding(2) var in_depth: texture_2d<f32>;
@group(0) @binding(3) var out_color: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(4) var out_depth: texture_storage_2d<r32float, write>;

@compute @workgroup_size(8, 8)
fn fill(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(in_color);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let here = vec2<i32>(id.xy);
    let c = textureLoad(in_color, here, 0);
    if c.a > 0.0 {
        textureStore(out_color, here, c);
        textureStore(out_depth, here, textureLoad(in_depth, here, 0));
        return;
    }
    let r = i32(RADIUS);
    var sum = vec3<f32>(0.0);
    var depth = 0.0;
    var n = 0.0;
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let q = here + vec2<i32>(dx, dy);
            if q.x < 0 || q.y < 0 || q.x >= i32(size.x) || q.y >= i32(size.y) {
                continue;
            }
            let s = textureLoad(in_color, q, 0);
            if s.a > 0.0 {
                sum += s.rgb;
                depth += textureLoad(in_depth, q, 0).r;
                n += 1.0;
            }
        }
    }
    if n > 0.0 {
        textureStore(out_color, here, vec4<f32>(sum / n, 1.0));
        textureStore(out_depth, here, vec4<f32>(depth / n, 0.0, 0.0, 0.0));
    } else {
        textureStore(out_color, here, vec4<f32>(0.0));
        textureStore(out_depth, here, vec4<f32>(0.0));
    }
}
