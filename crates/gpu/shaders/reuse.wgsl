// Temporal reuse for the virtualized path: a moving camera's frame starts from the surface the
// last frame showed. None of the papers combines the two: this follows the Reproject pass of
// the progressive-rendering paper (§3.4), but for points in a page pool that may be evicted
// between frames it reprojects the last frame's pixels (depth and colour) rather than its
// points. `reproject`: each kept pixel is unprojected with the last camera (its view depth is
// the key's depth) and drawn with the new one, into the frame's 64-bit keys and into `ghost`,
// which remembers what reprojection wrote, with the age of what it moved. `keep`: the frame's
// keys become the next frame's input; a pixel a reprojected key won ages by one, one a point
// won is new, and pixels older than MAX_AGE are dropped (each reprojection rounds a point to
// its pixel's centre: the age bounds how far that rounding can add up over a long move).

struct Reuse {
    // Clip position in the new view of (ndc.x · w, ndc.y · w, w, 1) in the last one.
    to_new: mat4x4<f32>,
    size: vec2<u32>,
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> reuse: Reuse;
@group(0) @binding(1) var<storage, read_write> previous: array<u64>;
@group(0) @binding(2) var<storage, read_write> keys: array<atomic<u64>>;
@group(0) @binding(3) var<storage, read_write> ghost: array<atomic<u64>>;
// Reprojections each kept pixel has been through, and the oldest that landed on each pixel.
@group(0) @binding(4) var<storage, read_write> ages: array<u32>;
@group(0) @binding(5) var<storage, read_write> ghost_ages: array<atomic<u32>>;

override MAX_AGE: u32 = 4u;

@compute @workgroup_size(8, 8)
fn reproject(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= reuse.size.x || id.y >= reuse.size.y {
        return;
    }
    let key = previous[id.y * reuse.size.x + id.x];
    if key == 0lu {
        return;
    }
    let w = bitcast<f32>(~(u32(key >> 32u) | 0x80000000u));
    let ndc = vec2<f32>((f32(id.x) + 0.5) / f32(reuse.size.x) * 2.0 - 1.0,
                        1.0 - (f32(id.y) + 0.5) / f32(reuse.size.y) * 2.0);
    let c = reuse.to_new * vec4<f32>(ndc * w, w, 1.0);
    if !(c.w > 0.0 && abs(c.x) <= c.w && abs(c.y) <= c.w && c.z >= 0.0 && c.z <= c.w) {
        return;
    }
    let at = c.xy / c.w;
    let x = min(u32(max((at.x * 0.5 + 0.5) * f32(reuse.size.x), 0.0)), reuse.size.x - 1u);
    let y = min(u32(max((0.5 - at.y * 0.5) * f32(reuse.size.y), 0.0)), reuse.size.y - 1u);
    // The same key layout as raster_min64.wgsl: ~depth << 32 | ~rgba.
    // A splat's gap-filling ring keeps its lower tier (common.wgsl): the tier bit is kept.
    let inv = ~bitcast<u32>(c.w) & (u32(key >> 32u) | 0x7fffffffu);
    let moved = (u64(inv) << 32u) | (key & 0xfffffffflu);
    let pixel = y * reuse.size.x + x;
    atomicMax(&keys[pixel], moved);
    atomicMax(&ghost[pixel], moved);
    atomicMax(&ghost_ages[pixel], ages[id.y * reuse.size.x + id.x] + 1u);
}

@compute @workgroup_size(8, 8)
fn keep(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= reuse.size.x || id.y >= reuse.size.y {
        return;
    }
    let pixel = id.y * reuse.size.x + id.x;
    let key = atomicLoad(&keys[pixel]);
    let moved = key != 0lu && key == atomicLoad(&ghost[pixel]);
    let age = select(0u, atomicLoad(&ghost_ages[pixel]), moved);
    previous[pixel] = select(key, 0lu, age > MAX_AGE);
    ages[pixel] = age;
}
