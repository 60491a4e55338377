// Shared by every point pass: draw entries, per-frame and per-dispatch parameters, projection.
// Points live in fixed-size pages of PAGE_SIZE points; a draw entry names a page and a range of
// its points plus a DrawInfo whose origin was made relative to the eye in f64 (camera-relative
// rendering, WebGPU paper §5), so clip = view_proj · (origin + local) never sees large numbers.
// Every module that includes this declares `override PAGE_SIZE: u32`.

// Where a drawn range of points comes from: an origin (minus the eye, in f32) and, for the
// compact encoding, one quantization step per axis. One per page (static clouds) or per
// pointlet (virtualized rendering).
struct DrawInfo {
    origin: vec3<f32>,
    // Bit 0: compact encoding reads the fine position word too (coarse step too large on screen).
    flags: u32,
    step: vec3<f32>,
    _pad: u32,
}

// One unit of raster work, one workgroup: points first..first+count of the page in `slot`.
struct DrawEntry {
    slot: u32,
    info: u32,
    first: u32,
    count: u32,
}

struct Frame {
    // Projection · rotation with the eye at the origin.
    view_proj: mat4x4<f32>,
    size: vec2<u32>,
    // HQS: points within this factor of the closest depth blend (the paper's 1 %).
    blend_factor: f32,
    // Non-zero when some class is hidden (else no colour needs loading to decide visibility).
    any_hidden: u32,
    // One bit per ASPRS class (the colour's alpha byte): set = hidden.
    hidden_classes: array<vec4<u32>, 2>,
}

// One dispatch covers the entries of one point-buffer chunk; their number is read from
// entry_counts so the list can be built on the GPU and dispatched indirectly.
struct Dispatch {
    first_slot: u32,
    list_offset: u32,
    chunk: u32,
    _pad: u32,
}

const NO_PIXEL: u32 = 0xffffffffu;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> infos: array<DrawInfo>;
@group(0) @binding(2) var<storage, read> entries: array<DrawEntry>;
@group(0) @binding(3) var<uniform> dispatch: Dispatch;
@group(0) @binding(6) var<storage, read> entry_counts: array<u32>;

struct Hit {
    pixel: u32,
    // bit pattern of the positive view depth (clip w): orders like the float itself
    depth_bits: u32,
}

// Pixel and depth of a camera-relative position; NO_PIXEL outside the frustum.
fn project(p: vec3<f32>) -> Hit {
    let c = frame.view_proj * vec4<f32>(p, 1.0);
    if !(c.w > 0.0 && abs(c.x) <= c.w && abs(c.y) <= c.w && c.z >= 0.0 && c.z <= c.w) {
        return Hit(NO_PIXEL, 0u);
    }
    let ndc = c.xy / c.w;
    let fx = (ndc.x * 0.5 + 0.5) * f32(frame.size.x);
    let fy = (0.5 - ndc.y * 0.5) * f32(frame.size.y);
    let x = min(u32(max(fx, 0.0)), frame.size.x - 1u);
    let y = min(u32(max(fy, 0.0)), frame.size.y - 1u);
    return Hit(y * frame.size.x + x, bitcast<u32>(c.w));
}

// True when the class in the colour's alpha byte is switched off.
fn class_hidden(color: u32) -> bool {
    let c = color >> 24u;
    let word = frame.hidden_classes[c >> 7u][(c >> 5u) & 3u];
    return (word & (1u << (c & 31u))) != 0u;
}

struct Work {
    valid: bool,
    // The page slot drawn (global: point ids are slot * PAGE_SIZE + index in the page).
    slot: u32,
    info: DrawInfo,
    // Index of the page's first point in this dispatch's point buffer.
    base: u32,
    first: u32,
    end: u32,
}

// The entry this workgroup draws (2-D dispatch: 65 535 groups per dimension at most).
fn work_for(wg: vec3<u32>, nwg: vec3<u32>) -> Work {
    let k = wg.x + wg.y * nwg.x;
    if k >= entry_counts[dispatch.chunk] {
        return Work(false, 0u, DrawInfo(vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0u), 0u, 0u, 0u);
    }
    let e = entries[dispatch.list_offset + k];
    return Work(true, e.slot, infos[e.info], (e.slot - dispatch.first_slot) * PAGE_SIZE, e.first,
                e.first + e.count);
}
