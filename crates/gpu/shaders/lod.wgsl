// Level of detail over pointlets and the frame's draw list (virtualized paper §III-B, eq. 2–3).
// `importance`: one thread per pointlet: frustum-cull the AABB (the side planes moved out as far as
// splats reach, so splats of points beside the view still cover the border), project its centre and
// max corner, l_i = γ_i · ‖(v/2)(p_center − p_max)‖ (γ precomputed on the CPU), workgroup partial
// sums of l. `total`: Σl. `build`: requested_i = min(count_i, max(1, round(l_i / Σl · B))) for
// visible pointlets (a prefix of the pointlet's shuffled points), the pointlet's camera-relative
// origin from double-single (hi + lo f32) coordinates, the spacing of the points it draws (for
// adaptive splats, bounded by its neighbours'), and one draw entry per resident page of the range
// to draw — the whole resident prefix up to the request, or when accumulating (camera still) only
// the points not drawn yet.
// Entries go to the list of the chunk holding the page; `finalize` turns the counts into indirect
// dispatch sizes and the draw arguments of billboard quads. Replaces the paper's per-frame buffer
// compaction: only pages change, and drawing reads them where they are.

struct Pointlet {
    origin_hi: vec3<f32>,
    count: u32,
    origin_lo: vec3<f32>,
    gamma: f32,
    extent: vec3<f32>,
    // At most 1: keeps a pointlet's splats near its neighbours' size (paged.rs spacing_factors).
    spacing_factor: f32,
}

struct LodParams {
    view_proj: mat4x4<f32>,
    eye_hi: vec3<f32>,
    pointlet_count: u32,
    eye_lo: vec3<f32>,
    bucket: f32,
    viewport: vec2<f32>,
    focal_px: f32,
    compact: u32,
    accumulate: u32,
    page_size: u32,
    max_pages: u32,
    chunk_slots: u32,
    chunk_count: u32,
    partial_count: u32,
    // Splats reach this many pixels beyond their point: boxes that close outside the view
    // still draw (0 for one-pixel points).
    cull_margin_px: f32,
    _pad: u32,
}

struct DrawInfo {
    origin: vec3<f32>,
    flags: u32,
    step: vec3<f32>,
    spacing: f32,
}

struct DrawEntry {
    slot: u32,
    info: u32,
    first: u32,
    count: u32,
}

// Per pointlet: resident points [x, y) on the GPU (CPU-written), points drawn into the kept
// framebuffer z (GPU-written), w unused.
@group(0) @binding(0) var<uniform> params: LodParams;
@group(0) @binding(1) var<storage, read> pointlets: array<Pointlet>;
// importance[0..n), then one partial sum per workgroup, then Σl.
@group(0) @binding(2) var<storage, read_write> importance: array<f32>;
// Read back by the CPU: requested points [0, n), then points drawn into the framebuffer [n, 2n).
@group(0) @binding(3) var<storage, read_write> feedback: array<u32>;
@group(0) @binding(4) var<storage, read_write> infos: array<DrawInfo>;
@group(0) @binding(5) var<storage, read_write> state: array<vec4<u32>>;
@group(0) @binding(6) var<storage, read> page_table: array<u32>;
@group(0) @binding(7) var<storage, read_write> entries: array<DrawEntry>;

@group(1) @binding(0) var<storage, read_write> entry_counts: array<atomic<u32>>;
@group(1) @binding(1) var<storage, read_write> indirect: array<u32>;
// Billboard quads (splat_quads.wgsl): 4 vertices, PAGE_SIZE instances an entry.
@group(1) @binding(2) var<storage, read_write> draw_args: array<u32>;

var<workgroup> sums: array<f32, 256>;

fn relative_origin(p: Pointlet) -> vec3<f32> {
    return (p.origin_hi - params.eye_hi) + (p.origin_lo - params.eye_lo);
}

fn outside(c: array<vec4<f32>, 8>) -> bool {
    // The side planes moved out by the splat margin (NDC spans the viewport in 2 units).
    let m = vec2<f32>(1.0) + 2.0 * params.cull_margin_px / params.viewport;
    var out = array<u32, 6>(0u, 0u, 0u, 0u, 0u, 0u);
    for (var k = 0u; k < 8u; k++) {
        let v = c[k];
        out[0] += u32(v.x < -m.x * v.w);
        out[1] += u32(v.x > m.x * v.w);
        out[2] += u32(v.y < -m.y * v.w);
        out[3] += u32(v.y > m.y * v.w);
        out[4] += u32(v.z < 0.0);
        out[5] += u32(v.z > v.w);
    }
    for (var f = 0u; f < 6u; f++) {
        if out[f] == 8u {
            return true;
        }
    }
    return false;
}

@compute @workgroup_size(256)
fn importance_pass(@builtin(global_invocation_id) gid: vec3<u32>,
                   @builtin(local_invocation_index) lid: u32,
                   @builtin(workgroup_id) wg: vec3<u32>) {
    let i = gid.x;
    var l = 0.0;
    if i < params.pointlet_count {
        let p = pointlets[i];
        let o = relative_origin(p);
        var corners: array<vec4<f32>, 8>;
        for (var k = 0u; k < 8u; k++) {
            let f = vec3<f32>(f32(k & 1u), f32((k >> 1u) & 1u), f32((k >> 2u) & 1u));
            corners[k] = params.view_proj * vec4<f32>(o + f * p.extent, 1.0);
        }
        if !outside(corners) && p.count > 0u {
            let c = params.view_proj * vec4<f32>(o + 0.5 * p.extent, 1.0);
            let m = corners[7];
            var size = length(params.viewport);
            // A box reaching behind the eye fills the view.
            if c.w > 1e-9 && m.w > 1e-9 {
                size = length(0.5 * params.viewport * (c.xy / c.w - m.xy / m.w));
            }
            // At least a pixel: a pointlet whose box collapsed to a point still gets points.
            l = p.gamma * max(size, 1.0);
        }
        importance[i] = l;
    }
    sums[lid] = l;
    workgroupBarrier();
    for (var s = 128u; s > 0u; s >>= 1u) {
        if lid < s {
            sums[lid] += sums[lid + s];
        }
        workgroupBarrier();
    }
    if lid == 0u {
        importance[params.pointlet_count + wg.x] = sums[0];
    }
}

@compute @workgroup_size(256)
fn total_pass(@builtin(local_invocation_index) lid: u32) {
    var s = 0.0;
    for (var k = lid; k < params.partial_count; k += 256u) {
        s += importance[params.pointlet_count + k];
    }
    sums[lid] = s;
    workgroupBarrier();
    for (var h = 128u; h > 0u; h >>= 1u) {
        if lid < h {
            sums[lid] += sums[lid + h];
        }
        workgroupBarrier();
    }
    if lid == 0u {
        importance[params.pointlet_count + params.partial_count] = sums[0];
    }
}

// Surface spacing of `n` points spread over a box: its two largest sides span the surface
// (splat.rs box_spacing, the CPU side of the same rule).
fn box_spacing(extent: vec3<f32>, n: u32) -> f32 {
    let e = max(extent, vec3<f32>(0.0));
    let lo = min(e.x, min(e.y, e.z));
    let hi = max(e.x, max(e.y, e.z));
    let mid = e.x + e.y + e.z - lo - hi;
    let count = f32(max(n, 1u));
    if hi * mid > 0.0 {
        return sqrt(hi * mid / count);
    }
    return hi / count;
}

@compute @workgroup_size(256)
fn build_pass(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.pointlet_count {
        return;
    }
    let p = pointlets[i];
    let total = importance[params.pointlet_count + params.partial_count];
    var req = 0u;
    if total > 0.0 && importance[i] > 0.0 {
        // A point at least: a bucket too small to share out still shows every visible pointlet.
        req = min(p.count, max(1u, u32(round(importance[i] / total * params.bucket))));
    }
    feedback[i] = req;

    let o = relative_origin(p);
    let step = max(p.extent, vec3<f32>(1e-9)) / 1048576.0;
    // Compact encoding: read the fine word when a coarse cell spans over half a pixel.
    let nearest = max(max(o, -(o + p.extent)), vec3<f32>(0.0));
    let cell = max(step.x, max(step.y, step.z)) * 1024.0;
    let fine = params.compact != 0u && cell * params.focal_px > 0.5 * length(nearest);

    let st = state[i];
    var start = st.x;
    if params.accumulate != 0u {
        start = max(start, st.z);
    }
    let end = min(req, st.y);
    // Adaptive splats: the spacing of the points drawn this frame over the pointlet's box.
    let spacing = box_spacing(p.extent, max(end, st.x) - st.x) * p.spacing_factor;
    infos[i] = DrawInfo(o, u32(fine), step, spacing);
    var drawn = end;
    if params.accumulate != 0u {
        drawn = max(st.z, end);
    }
    state[i].z = drawn;
    feedback[params.pointlet_count + i] = drawn;
    if end <= start {
        return;
    }
    let ps = params.page_size;
    for (var j = start / ps; j * ps < end; j++) {
        let slot = page_table[i * params.max_pages + j];
        let lo = max(start, j * ps);
        let hi = min(end, (j + 1u) * ps);
        let chunk = slot / params.chunk_slots;
        let k = atomicAdd(&entry_counts[chunk], 1u);
        entries[chunk * params.chunk_slots + k] = DrawEntry(slot, i, lo - j * ps, hi - lo);
    }
}

@compute @workgroup_size(64)
fn finalize_pass(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if c >= params.chunk_count {
        return;
    }
    let n = atomicLoad(&entry_counts[c]);
    let x = clamp(n, 1u, 65535u);
    indirect[c * 3u] = select(0u, x, n > 0u);
    indirect[c * 3u + 1u] = (n + x - 1u) / x;
    indirect[c * 3u + 2u] = 1u;
    draw_args[c * 4u] = 4u;
    draw_args[c * 4u + 1u] = n * params.page_size;
    draw_args[c * 4u + 2u] = 0u;
    draw_args[c * 4u + 3u] = 0u;
}
