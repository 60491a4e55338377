// Splats as billboard quads through the render pipeline (the WebGPU-engine paper's way, §6.2:
// "each point is rasterized as a view-aligned billboard quad"), the alternative to the compute
// rasterizers' footprint loops (`--splat-raster quads`). One instance per point slot of the
// frame's draw entries (PAGE_SIZE instances an entry; unused ones collapse), the vertex pulls its
// point from the storage buffers and spans the pixel square of the splat's ring exactly (corners
// on pixel edges, from the same 1/256-pixel centre as common.wgsl), and the fragment keeps the
// footprint's pixels (splat_covers). The hardware depth test keeps the closest: the fragment
// depth puts the footprint in [0, ½) and the gap-filling ring in [½, 1), so a ring pixel never
// beats a footprint pixel. On equal depth the first drawn wins (the compute path: the smaller
// colour). Output as the resolve writes it: colour (alpha = side / 255) and linear depth.

override PAGE_SIZE: u32 = 4096u;

struct QuadOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) color: u32,
    @location(1) @interpolate(flat) q: vec2<i32>,
    @location(2) @interpolate(flat) corner: vec2<i32>,
    // side, ring
    @location(3) @interpolate(flat) sides: vec2<u32>,
    // Linear view depth and the depth-buffer value of the footprint (0..½).
    @location(4) @interpolate(flat) depth: vec2<f32>,
}

fn collapsed() -> QuadOut {
    var out: QuadOut;
    out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
    return out;
}

@vertex
fn vs(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> QuadOut {
    let k = ii / PAGE_SIZE;
    let local = ii % PAGE_SIZE;
    if k >= entry_counts[dispatch.chunk] {
        return collapsed();
    }
    let e = entries[dispatch.list_offset + k];
    if local < e.first || local >= e.first + e.count {
        return collapsed();
    }
    let index = (e.slot - dispatch.first_slot) * PAGE_SIZE + local;
    let info = infos[e.info];
    let color = load_color(index);
    if class_hidden(color) {
        return collapsed();
    }
    let s = project_splat(load_position(info, index), info.spacing);
    if !s.valid {
        return collapsed();
    }
    let c = frame.view_proj * vec4<f32>(load_position(info, index), 1.0);
    // Corners of the ring's pixel square, on pixel edges.
    let corner = vec2<f32>(s.ring_corner) + vec2<f32>(f32(vi & 1u), f32(vi >> 1u)) * f32(s.ring);
    let ndc = vec2<f32>(corner.x / f32(frame.size.x) * 2.0 - 1.0,
                        1.0 - corner.y / f32(frame.size.y) * 2.0);
    var out: QuadOut;
    // The same depth over the quad: the papers' splats are flat, at the point's depth.
    out.clip = vec4<f32>(ndc * c.w, c.z, c.w);
    out.color = splat_color_word(color, s);
    out.q = s.q;
    out.corner = s.corner;
    out.sides = vec2<u32>(s.side, s.ring);
    out.depth = vec2<f32>(c.w, 0.5 * clamp(c.z / c.w, 0.0, 1.0));
    return out;
}

struct QuadPixel {
    @location(0) color: vec4<f32>,
    @location(1) depth: vec4<f32>,
    @builtin(frag_depth) z: f32,
}

@fragment
fn fs(v: QuadOut) -> QuadPixel {
    var s: Splat;
    s.q = v.q;
    s.corner = v.corner;
    s.side = v.sides.x;
    s.ring = v.sides.y;
    let covered = splat_covers(s, vec2<i32>(floor(v.clip.xy)));
    if !covered.x && !covered.y {
        discard;
    }
    var out: QuadPixel;
    let c = unpack4x8unorm(v.color);
    out.color = vec4<f32>(c.rgb, c.a);
    out.depth = vec4<f32>(v.depth.x, 0.0, 0.0, 0.0);
    out.z = v.depth.y + select(0.0, 0.5, !covered.x);
    return out;
}
