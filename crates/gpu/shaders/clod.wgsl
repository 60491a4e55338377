// Continuous-LoD filter of streamed 3D Tiles content (WebGPU-engine paper §6.1, eq. 6–9; after
// Schütz et al. 2019): every point of every drawn tile is tested, and a survivor is appended,
// camera-relative, to its tile's region of the frame's output points, which the rasterizers
// then draw like any page of points. A point survives when r(p) < s_native / s_target with
// s_target = d · k (eq. 8–9), written here as r(p) · d < s_native / k (`clod`, per tile): the
// acceptance follows each point's own distance, so density changes smoothly across tile
// boundaries. r(p) is an integer hash of the point's tile-local position bits instead of the
// paper's fract(cos(x + y + z) · c) (eq. 6): the same value on every GPU, and uniform.
// One dispatch per suballocator page: the page's bytes hold each tile's f32 xyz (relative to the
// tile's origin) followed by its RGBA8 colours. Survivors are counted per workgroup and claimed
// with one atomic per round, so the order inside a tile varies, which closest-point rasterizers
// do not see.

struct Range {
    first_block: u32,
    count: u32,
    _pad0: u32,
    _pad1: u32,
}

struct Tile {
    // The tile's origin minus the eye (f64 on the CPU, then f32: camera-relative rendering, §5).
    rel_origin: vec3<f32>,
    count: u32,
    // Word offsets of the positions and colours in the page.
    position_word: u32,
    color_word: u32,
    // First output point of the tile's region (as many points as the tile has).
    out_first: u32,
    // s_native / k in metres; keep_all: every point survives (CLOD off).
    keep_all: u32,
    clod: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

override BLOCK: u32 = 4096u;
const WG: u32 = 256u;

@group(0) @binding(0) var<uniform> range: Range;
@group(0) @binding(1) var<storage, read> content: array<u32>;
@group(0) @binding(2) var<storage, read> tiles: array<Tile>;
// (drawn tile, first point) of each block of BLOCK points.
@group(0) @binding(3) var<storage, read> blocks: array<vec2<u32>>;
@group(0) @binding(4) var<storage, read_write> out_positions: array<f32>;
@group(0) @binding(5) var<storage, read_write> out_colors: array<u32>;
@group(0) @binding(6) var<storage, read_write> survivors: array<atomic<u32>>;

var<workgroup> round_count: atomic<u32>;
var<workgroup> round_base: u32;

// A 32-bit mix (lowbias32-style) of the three coordinate bit patterns.
fn hash3(a: u32, b: u32, c: u32) -> u32 {
    var h = a * 0x9e3779b1u ^ (b * 0x85ebca77u) ^ (c * 0xc2b2ae3du);
    h ^= h >> 16u;
    h *= 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    h ^= h >> 16u;
    return h;
}

@compute @workgroup_size(256)
fn filter_points(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
    let k = wg.x + wg.y * nwg.x;
    if k >= range.count {
        return;
    }
    let block = blocks[range.first_block + k];
    let t = tiles[block.x];
    for (var round = 0u; round < BLOCK / WG; round++) {
        let i = block.y + round * WG + lid;
        var keep = false;
        var rel = vec3<f32>(0.0);
        if i < t.count {
            let w = t.position_word + 3u * i;
            let a = content[w];
            let b = content[w + 1u];
            let c = content[w + 2u];
            rel = t.rel_origin + vec3<f32>(bitcast<f32>(a), bitcast<f32>(b), bitcast<f32>(c));
            let r = f32(hash3(a, b, c) >> 8u) * (1.0 / 16777216.0);
            keep = t.keep_all != 0u || r * length(rel) < t.clod;
        }
        var local = 0u;
        if keep {
            local = atomicAdd(&round_count, 1u);
        }
        workgroupBarrier();
        if lid == 0u {
            let n = atomicLoad(&round_count);
            round_base = atomicAdd(&survivors[block.x], n);
            atomicStore(&round_count, 0u);
        }
        workgroupBarrier();
        if keep {
            let o = t.out_first + round_base + local;
            out_positions[3u * o] = rel.x;
            out_positions[3u * o + 1u] = rel.y;
            out_positions[3u * o + 2u] = rel.z;
            out_colors[o] = content[t.color_word + i];
        }
    }
}

