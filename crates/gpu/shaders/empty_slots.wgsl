// Marks slots of a progressive cloud's position stream empty before any point is loaded: the x
// word of each Full16 slot gets EMPTY_SLOT (fetch_full16.wgsl), which the Fill pass skips.
// The progressive-rendering paper (§3.1) fills its vertex buffer before drawing it; we draw
// while it fills, so slots not yet written must not show as points at the origin.

struct Marks {
    // Slots in the bound buffer, and position words per slot.
    slots: u32,
    words: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> marks: Marks;
@group(0) @binding(1) var<storage, read_write> positions: array<u32>;

@compute @workgroup_size(256)
fn mark(@builtin(global_invocation_id) gid: vec3<u32>,
        @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = gid.x + gid.y * nwg.x * 256u;
    if i < marks.slots {
        positions[i * marks.words] = 0xffffffffu;
    }
}
