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
    // Surface spacing (1/√density, world units) of the points drawn from here this frame:
    // adaptive splats are sized from it (0: unknown, one-pixel splats).
    spacing: f32,
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
    _pad: u32,
    // One bit per ASPRS class (the colour's alpha byte): set = hidden.
    hidden_classes: array<vec4<u32>, 2>,
    // Splat size in pixels (SPLATS pipelines): `splat_fixed`, or with `splat_scale` > 0
    // clamp(splat_scale · spacing / view depth, 1, splat_max) (adaptive); `splat_ring` is the
    // ratio of the gap-filling ring's side to the splat's.
    splat_fixed: f32,
    splat_scale: f32,
    splat_max: f32,
    splat_ring: f32,
}

// One dispatch covers the entries of one point-buffer chunk; their number is read from
// entry_counts so the list can be built on the GPU and dispatched indirectly.
struct Dispatch {
    first_slot: u32,
    list_offset: u32,
    chunk: u32,
    // Page slots of this chunk.
    slots: u32,
}

// True when `slot` (global) lies in this dispatch's chunk.
fn in_chunk(slot: u32) -> bool {
    let first = dispatch.first_slot * PAGE_SIZE;
    return slot >= first && slot - first < dispatch.slots * PAGE_SIZE;
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
        return Work(false, 0u, DrawInfo(vec3<f32>(0.0), 0u, vec3<f32>(0.0), 0.0), 0u, 0u, 0u);
    }
    let e = entries[dispatch.list_offset + k];
    return Work(true, e.slot, infos[e.info], (e.slot - dispatch.first_slot) * PAGE_SIZE, e.first,
                e.first + e.count);
}

// Splats (splat.rs; WebGPU-engine paper §6.2 sizes billboards to the point spacing). A point
// covers a square or circle of pixels around its projection, all at its view depth. Around that
// footprint a larger gap-filling ring writes keys of a lower tier: the top bit of the inverted
// depth word, always set for a point's own footprint (positive depths have it clear), is cleared
// there, so a ring pixel never beats a footprint pixel and fills only what no footprint covers
// (random LoD subsets leave gaps that splats of the mean spacing cannot close). Footprints are
// computed in integer 1/256 pixels so the CPU reference (reference.rs) covers the same pixels.
override SPLATS: bool = false;
override CIRCLE: bool = false;

const TIER_BIT: u32 = 0x80000000u;

struct Splat {
    valid: bool,
    // Centre in 1/256 pixel.
    q: vec2<i32>,
    depth_bits: u32,
    // Sides in pixels of the footprint and of the ring around it.
    side: u32,
    ring: u32,
    // Top-left pixels of the footprint's and of the ring's square.
    corner: vec2<i32>,
    ring_corner: vec2<i32>,
}

// A splat's pixel: NO_PIXEL when outside the image or the shape; `ring` for gap-filling pixels.
struct SplatPixel {
    pixel: u32,
    ring: bool,
}

// Pixel squares of side s around a centre q (1/256 px) cover the s pixels whose centres lie
// in (q/256 - s/2, q/256 + s/2]; for s = 1, the pixel holding the point, as project() picks.
fn square_corner(q: vec2<i32>, side: u32) -> vec2<i32> {
    return ((q - vec2<i32>(128 * (i32(side) + 1))) >> vec2<u32>(8u)) + vec2<i32>(1);
}

fn splat_side(size: f32) -> u32 {
    return u32(clamp(round(size), 1.0, frame.splat_max));
}

// The splat of a camera-relative position drawn with surface `spacing`.
fn project_splat(p: vec3<f32>, spacing: f32) -> Splat {
    var s: Splat;
    s.valid = false;
    let c = frame.view_proj * vec4<f32>(p, 1.0);
    if !(c.w > 0.0 && c.z >= 0.0 && c.z <= c.w) {
        return s;
    }
    var size = frame.splat_fixed;
    if frame.splat_scale > 0.0 {
        size = frame.splat_scale * spacing / c.w;
    }
    s.side = splat_side(size);
    s.ring = max(splat_side(size * frame.splat_ring), s.side);
    let ndc = c.xy / c.w;
    let fx = (ndc.x * 0.5 + 0.5) * f32(frame.size.x);
    let fy = (0.5 - ndc.y * 0.5) * f32(frame.size.y);
    // Splats reaching into the image from beside it count; far beyond, no pixel can be hit.
    let margin = f32(s.ring);
    if !(fx >= -margin && fy >= -margin && fx <= f32(frame.size.x) + margin
         && fy <= f32(frame.size.y) + margin) {
        return s;
    }
    s.q = vec2<i32>(floor(vec2<f32>(fx, fy) * 256.0));
    s.depth_bits = bitcast<u32>(c.w);
    s.corner = square_corner(s.q, s.side);
    s.ring_corner = square_corner(s.q, s.ring);
    s.valid = true;
    return s;
}

// Whether pixel `xy` is in the splat's footprint (x) and in its ring (y).
fn splat_covers(s: Splat, xy: vec2<i32>) -> vec2<bool> {
    if CIRCLE {
        // Distances between pixel centres and the splat centre, in 1/256 px.
        let d = xy * 256 + vec2<i32>(128) - s.q;
        let d2 = d.x * d.x + d.y * d.y;
        let r = 128 * i32(s.side);
        let rr = 128 * i32(s.ring);
        // The pixel holding the centre always belongs to it: a circle narrower than a pixel
        // may cover no pixel centre at all.
        let inside = d2 <= r * r || all(xy == (s.q >> vec2<u32>(8u)));
        return vec2<bool>(inside, d2 <= rr * rr);
    }
    let o = xy - s.corner;
    let inside = o.x >= 0 && o.y >= 0 && o.x < i32(s.side) && o.y < i32(s.side);
    return vec2<bool>(inside, true);
}

// The pixel at offset `d` in the ring's square (loops walk d row by row: no division).
fn splat_pixel(s: Splat, d: vec2<u32>) -> SplatPixel {
    let xy = s.ring_corner + vec2<i32>(d);
    var out = SplatPixel(NO_PIXEL, false);
    if xy.x < 0 || xy.y < 0 || xy.x >= i32(frame.size.x) || xy.y >= i32(frame.size.y) {
        return out;
    }
    let covered = splat_covers(s, xy);
    if covered.x || covered.y {
        out.pixel = u32(xy.y) * frame.size.x + u32(xy.x);
        out.ring = !covered.x;
    }
    return out;
}

// The colour word a splat's pixels carry: RGB, and in the alpha byte (the class, no longer
// needed once drawn) the splat's side, so the screen passes know the splat sizes (EDL on splats).
fn splat_color_word(color: u32, s: Splat) -> u32 {
    return (color & 0x00ffffffu) | (s.side << 24u);
}

// The inverted depth word of a splat pixel: its tier bit cleared in the ring.
fn tier_depth(inv_depth: u32, ring: bool) -> u32 {
    return select(inv_depth, inv_depth & ~TIER_BIT, ring);
}

// The depth bits of an inverted depth word of either tier.
fn untier(inv_depth: u32) -> u32 {
    return ~(inv_depth | TIER_BIT);
}
