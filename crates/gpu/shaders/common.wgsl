// Shared by every point pass: page table, per-frame and per-dispatch parameters, projection.
// Points live in fixed-size pages; a page's points are stored relative to the page origin and the
// origin is re-expressed relative to the eye every frame on the CPU in f64 (camera-relative
// rendering, WebGPU paper §5), so clip = view_proj · (origin + local) never sees large numbers.

struct Page {
    // Page origin minus the eye, in f32 (subtracted in f64 on the CPU).
    origin: vec3<f32>,
    // Points stored in the page (≤ PAGE_SIZE).
    count: u32,
    // Compact layout: size of one quantization step per axis; unused by the 16-byte layout.
    step: vec3<f32>,
    // Bit 0: compact layout reads the fine position word too (coarse step too large on screen).
    flags: u32,
}

struct Frame {
    // Projection · rotation with the eye at the origin.
    view_proj: mat4x4<f32>,
    size: vec2<u32>,
    // HQS: points within this factor of the closest depth blend (the paper's 1 %).
    blend_factor: f32,
    _pad: u32,
}

// One dispatch covers the pages of one point-buffer chunk listed in page_list.
struct Dispatch {
    first_page: u32,
    list_offset: u32,
    page_count: u32,
    _pad: u32,
}

const NO_PIXEL: u32 = 0xffffffffu;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> pages: array<Page>;
@group(0) @binding(2) var<storage, read> page_list: array<u32>;
@group(0) @binding(3) var<uniform> dispatch: Dispatch;

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

// Index of the page this workgroup draws (2-D dispatch: 65 535 groups per dimension at most).
fn page_slot(wg: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wg.x + wg.y * nwg.x;
}
