// Gap filling of closest-point splats (splat.rs): an empty pixel takes the closest of the splat
// pixels whose reach covers it — 0.9 of the splat's side beyond that pixel (round(0.9 · side),
// 1 to GAP_REACH_MAX pixels; a square window, or a disc for circles), so a surface a random LoD
// subset leaves open closes, while silhouettes grow by that reach at most. Blending draws the
// same reach as rings of its splats instead; here it costs a screen pass rather than ring
// pixels for every point. A splat pixel's side is its colour alpha · 255 (resolve_common.wgsl).
// `tiles` keeps the largest side of every 16 × 16 tile, so `fill` searches only as far as the
// splats around can reach: not at all far from every splat.

override CIRCLE: bool = false;

const TILE: u32 = 16u;
const GAP_REACH_MAX: i32 = 16;

@group(0) @binding(0) var in_color: texture_2d<f32>;
@group(0) @binding(1) var in_depth: texture_2d<f32>;
@group(0) @binding(2) var out_color: texture_storage_2d<rgba8unorm, write>;
@group(0) @binding(3) var out_depth: texture_storage_2d<r32float, write>;
// Largest splat side per tile, row by row.
@group(0) @binding(4) var<storage, read_write> tiles: array<atomic<u32>>;

var<workgroup> tile_max: atomic<u32>;

// The splat side of a pixel's colour (0: empty or not a splat).
fn side_of(c: vec4<f32>) -> u32 {
    return select(0u, u32(round(c.a * 255.0)), c.a > 0.0 && c.a < 0.5);
}

// splat.rs gap_reach: round(0.9 · side) in integers, 1 to GAP_REACH_MAX.
fn reach(side: u32) -> i32 {
    return clamp(i32((side * 9u + 5u) / 10u), 1, GAP_REACH_MAX);
}

fn tiles_x() -> u32 {
    return (textureDimensions(in_color).x + TILE - 1u) / TILE;
}

@compute @workgroup_size(16, 16)
fn tiles_pass(@builtin(global_invocation_id) id: vec3<u32>,
              @builtin(workgroup_id) wg: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
    let size = textureDimensions(in_color);
    if lid == 0u {
        atomicStore(&tile_max, 0u);
    }
    workgroupBarrier();
    if id.x < size.x && id.y < size.y {
        atomicMax(&tile_max, side_of(textureLoad(in_color, vec2<i32>(id.xy), 0)));
    }
    workgroupBarrier();
    if lid == 0u {
        atomicStore(&tiles[wg.y * tiles_x() + wg.x], atomicLoad(&tile_max));
    }
}

@compute @workgroup_size(8, 8)
fn fill(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = vec2<i32>(textureDimensions(in_color));
    let p = vec2<i32>(id.xy);
    if p.x >= size.x || p.y >= size.y {
        return;
    }
    let here = textureLoad(in_color, p, 0);
    if here.a > 0.0 {
        textureStore(out_color, p, here);
        textureStore(out_depth, p, textureLoad(in_depth, p, 0));
        return;
    }
    // Every splat pixel within GAP_REACH_MAX lies in the 3 × 3 tiles around.
    let t = p / i32(TILE);
    let nt = vec2<i32>(i32(tiles_x()), (size.y + i32(TILE) - 1) / i32(TILE));
    var largest = 0u;
    for (var ty = max(t.y - 1, 0); ty <= min(t.y + 1, nt.y - 1); ty++) {
        for (var tx = max(t.x - 1, 0); tx <= min(t.x + 1, nt.x - 1); tx++) {
            largest = max(largest, atomicLoad(&tiles[u32(ty * nt.x + tx)]));
        }
    }
    var found = false;
    var best_depth = 0.0;
    var best_word = 0u;
    var best = vec4<f32>(0.0);
    if largest > 0u {
        let r = reach(largest);
        for (var qy = max(p.y - r, 0); qy <= min(p.y + r, size.y - 1); qy++) {
            for (var qx = max(p.x - r, 0); qx <= min(p.x + r, size.x - 1); qx++) {
                let q = vec2<i32>(qx, qy);
                let c = textureLoad(in_color, q, 0);
                let side = side_of(c);
                if side == 0u {
                    continue;
                }
                let rq = reach(side);
                let d = q - p;
                var inside = abs(d.x) <= rq && abs(d.y) <= rq;
                if CIRCLE {
                    inside = d.x * d.x + d.y * d.y <= rq * rq;
                }
                if !inside {
                    continue;
                }
                let depth = textureLoad(in_depth, q, 0).r;
                let word = pack4x8unorm(c);
                if !found || depth < best_depth || (depth == best_depth && word < best_word) {
                    found = true;
                    best_depth = depth;
                    best_word = word;
                    best = c;
                }
            }
        }
    }
    textureStore(out_color, p, best);
    textureStore(out_depth, p, vec4<f32>(best_depth, 0.0, 0.0, 0.0));
}
