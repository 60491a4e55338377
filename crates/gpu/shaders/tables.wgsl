// Applies the frame's residency changes to the GPU tables the LoD pass reads: page-table
// entries (index, slot) and per-pointlet resident ranges (pointlet, lo, hi), uploaded as two
// lists instead of one small buffer write each.

struct Counts {
    pages: u32,
    states: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> counts: Counts;
@group(0) @binding(1) var<storage, read> page_updates: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read> state_updates: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> page_table: array<u32>;
@group(0) @binding(4) var<storage, read_write> state: array<vec4<u32>>;

@compute @workgroup_size(256)
fn apply(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = gid.x + gid.y * nwg.x * 256u;
    if i < counts.pages {
        let u = page_updates[i];
        page_table[u.x] = u.y;
    }
    // Updates of one pointlet are listed in order; the last one wins because each pointlet
    // appears once per frame (the CPU keeps only its final range).
    if i < counts.states {
        let s = state_updates[i];
        state[s.x].x = s.y;
        state[s.x].y = s.z;
    }
}
