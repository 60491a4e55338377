// Scatters the frame's uploaded point runs from one staging area into their page slots, one
// workgroup per run. The CPU packs every new page of a frame into three staging streams and
// a run table, so a frame costs a handful of buffer writes however many pages changed
// (thousands of small writes cost more in allocation than in bytes).

struct Run {
    // Point index in this chunk's buffers.
    dst: u32,
    // Point index in the staging streams.
    src: u32,
    count: u32,
    // Bit 0: colours only (recolouring).
    flags: u32,
}

struct ChunkRuns {
    offset: u32,
    count: u32,
    // Position words per point: 3 (full16) or 1 (compact8).
    words: u32,
    has_fine: u32,
}

@group(0) @binding(0) var<uniform> chunk: ChunkRuns;
@group(0) @binding(1) var<storage, read> runs: array<Run>;
@group(0) @binding(2) var<storage, read> src_positions: array<u32>;
@group(0) @binding(3) var<storage, read> src_fine: array<u32>;
@group(0) @binding(4) var<storage, read> src_colors: array<u32>;
@group(0) @binding(5) var<storage, read_write> dst_positions: array<u32>;
@group(0) @binding(6) var<storage, read_write> dst_fine: array<u32>;
@group(0) @binding(7) var<storage, read_write> dst_colors: array<u32>;

@compute @workgroup_size(256)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
    let k = wg.x + wg.y * nwg.x;
    if k >= chunk.count {
        return;
    }
    let r = runs[chunk.offset + k];
    for (var i = lid; i < r.count; i += 256u) {
        dst_colors[r.dst + i] = src_colors[r.src + i];
        if (r.flags & 1u) != 0u {
            continue;
        }
        for (var w = 0u; w < chunk.words; w++) {
            dst_positions[(r.dst + i) * chunk.words + w] = src_positions[(r.src + i) * chunk.words + w];
        }
        if chunk.has_fine != 0u {
            dst_fine[r.dst + i] = src_fine[r.src + i];
        }
    }
}
