// The hardware baseline (`hw-points`): the render pipeline's point-list primitive, one pixel per
// point, depth test in hardware (compute-shader paper §5: the GL_POINTS baseline). Points come in
// through vertex buffers; the page origin (camera-relative) is looked up per vertex. Draws
// static clouds only (one entry per page, in slot order).

override PAGE_SIZE: u32 = 4096u;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
    @location(1) depth: f32,
}

// Static clouds list their pages in slot order, one entry per page, so the vertex's page is
// entry vi / PAGE_SIZE of this chunk.
fn entry_of(vi: u32) -> DrawEntry {
    return entries[dispatch.list_offset + vi / PAGE_SIZE];
}

fn emit(e: DrawEntry, local: u32, p: vec3<f32>, color: u32) -> VertexOut {
    var out: VertexOut;
    if local < e.first || local >= e.first + e.count || class_hidden(color) {
        // Unused slot of a partly filled page: outside the clip volume.
        out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        return out;
    }
    out.clip = frame.view_proj * vec4<f32>(p, 1.0);
    out.color = vec4<f32>(unpack4x8unorm(color).rgb, 1.0);
    out.depth = out.clip.w;
    return out;
}

@vertex
fn vs_full16(@builtin(vertex_index) vi: u32, @location(0) local_pos: vec3<f32>,
             @location(1) color: u32) -> VertexOut {
    let e = entry_of(vi);
    return emit(e, vi % PAGE_SIZE, infos[e.info].origin + local_pos, color);
}

@vertex
fn vs_compact8(@builtin(vertex_index) vi: u32, @location(0) coarse_word: u32,
               @location(1) color: u32, @location(2) fine_word: u32) -> VertexOut {
    let e = entry_of(vi);
    let info = infos[e.info];
    let coarse = vec3<u32>(coarse_word & 0x3ffu, (coarse_word >> 10u) & 0x3ffu, (coarse_word >> 20u) & 0x3ffu);
    let fine = vec3<u32>(fine_word & 0x3ffu, (fine_word >> 10u) & 0x3ffu, (fine_word >> 20u) & 0x3ffu);
    var q = vec3<f32>(coarse * 1024u) + vec3<f32>(512.0);
    if (info.flags & 1u) != 0u {
        q = vec3<f32>(coarse * 1024u + fine) + vec3<f32>(0.5);
    }
    return emit(e, vi % PAGE_SIZE, info.origin + q * info.step, color);
}

struct FragmentOut {
    @location(0) color: vec4<f32>,
    @location(1) depth: vec4<f32>,
}

@fragment
fn fs_main(v: VertexOut) -> FragmentOut {
    return FragmentOut(v.color, vec4<f32>(v.depth, 0.0, 0.0, 0.0));
}
