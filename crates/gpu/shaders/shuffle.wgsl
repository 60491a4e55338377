// Scatters a batch of points from the staging ("Distribute") buffer to their shuffled slots,
// one thread per point: element j, the point of global index first + j, goes to slot
// target(first + j) of the bound destination chunk, if that slot lies in it (one dispatch per
// chunk: a buffer larger than the binding limit is split like the point storage).
// Follows the progressive-rendering paper (Schütz et al.), §3.1 (Distribute buffer into the
// shuffled vertex buffer) and §3.3, eq. 1 (permute) and eq. 2 (target = permute ∘ permute),
// with P the largest prime ≡ 3 (mod 4) not above the buffer's size (0: identity).
// A store's points are in pointlets shuffled when it was built: `interleaved` cuts the
// pointlets into chunks of whole pointlets (one destination buffer each, so a chunk can be
// drawn as soon as it is made and loaded) and inside a chunk puts point j of every pointlet
// before point j + 1 of any, keeping the first `rows` of each, blocks of neighbouring
// pointlets permuted within a row by eq. 1–2 over the blocks (core::progressive::GroupRows)
// instead; threads walk a batch row by row, so that neighbouring threads write neighbouring
// slots (the permutation's writes to random slots of a multi-GB buffer cost ~1 ns a point).
// WGSL has only 32-bit integers, so i² mod P is a Montgomery product (REDC with R = 2^32) of
// 16-bit partial products: straight-line code, no loop over the bits.
// Two variations: `given_slots` takes each point's slot from src_slots instead (points past the
// capacity of a buffer that keeps a uniform subset, core::progressive::Reservoir), and
// `colors_only` rewrites only the colours (attribute switching, paper §3.5). With `quantized`
// the staged positions are a store's as stored (x, y, z as i32 of its quantization) and become
// Full16 words here, (q - base) · step + shift relative to the buffer's origin: the file's
// bytes go to the GPU as they are (paper §5: loading is bound by reading and uploading).

struct Shuffle {
    // Slots of the whole shuffled buffer: points whose target lies past them are left out.
    n: u32,
    prime: u32,
    // Global index of staging element 0, and the batch's size.
    first: u32,
    count: u32,
    // Slots first_slot..first_slot + slots live in the bound destination buffers.
    first_slot: u32,
    slots: u32,
    // Position words per point: 3 (full16) or 1 (compact8).
    words: u32,
    has_fine: u32,
    given_slots: u32,
    colors_only: u32,
    quantized: u32,
    // Montgomery constants of prime (R = 2^32): -prime⁻¹ mod R and R² mod prime.
    neg_inv: u32,
    r2: u32,
    // Interleaved groups of 2^group_shift points, for one chunk: its groups, the rows that
    // include its (possibly short) last group, and the groups of the batch in it. `prime` and
    // its constants then permute the whole blocks (of 2^block_shift groups) of a row.
    interleaved: u32,
    group_shift: u32,
    groups: u32,
    full_rows: u32,
    window: u32,
    // Points the order places (n or more: those past the slots are left out).
    points: u32,
    block_shift: u32,
    blocks: u32,
    // Points kept of every group; the chunk's first group and first slot; the window's first
    // group.
    rows: u32,
    first_group: u32,
    chunk_base: u32,
    window_first: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // Dequantization (quantized only): the grid point nearest the origin, the step split in
    // a high and a low f32 (their sum is the f64 step to 48 bits), the origin's distance from
    // base.
    base: vec4<i32>,
    step_hi: vec4<f32>,
    step_lo: vec4<f32>,
    shift: vec4<f32>,
}

@group(0) @binding(0) var<uniform> shuffle: Shuffle;
@group(0) @binding(1) var<storage, read> src_positions: array<u32>;
@group(0) @binding(2) var<storage, read> src_fine: array<u32>;
@group(0) @binding(3) var<storage, read> src_colors: array<u32>;
@group(0) @binding(4) var<storage, read_write> dst_positions: array<u32>;
@group(0) @binding(5) var<storage, read_write> dst_fine: array<u32>;
@group(0) @binding(6) var<storage, read_write> dst_colors: array<u32>;
@group(0) @binding(7) var<storage, read> src_slots: array<u32>;

// An odd modulus p < 2^32 with its Montgomery constants (R = 2^32), computed on the CPU.
struct Modulus {
    p: u32,
    // -p⁻¹ mod R.
    neg_inv: u32,
    // R² mod p.
    r2: u32,
}

// The high 32 bits of a · b, from 16-bit halves.
fn mul_hi(a: u32, b: u32) -> u32 {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let cross0 = a0 * b1;
    let cross1 = a1 * b0;
    let mid = ((a0 * b0) >> 16u) + (cross0 & 0xffffu) + (cross1 & 0xffffu);
    return a1 * b1 + (cross0 >> 16u) + (cross1 >> 16u) + (mid >> 16u);
}

// a · b · R⁻¹ mod p for a, b < p (REDC): adding m · p, m = lo · (-p⁻¹), clears the low word
// of the product, which leaves a carry exactly when that word is not 0. The sum is below 2p,
// which may pass 2^32 when p > 2^31: a wrapped sum is reduced too.
fn mont_mul(a: u32, b: u32, m: Modulus) -> u32 {
    let lo = a * b;
    let hi = mul_hi(a, b);
    let s = hi + mul_hi(lo * m.neg_inv, m.p);
    let t = s + select(0u, 1u, lo != 0u);
    if s < hi || t < s || t >= m.p {
        return t - m.p;
    }
    return t;
}

// (a · b) mod p for a, b < p: (a·b·R⁻¹) · R² · R⁻¹.
fn mul_mod(a: u32, b: u32, m: Modulus) -> u32 {
    return mont_mul(mont_mul(a, b, m), m.r2, m);
}

// Eq. 1: squares for the lower half, their negatives for the upper half; i ≥ p stays.
fn permute(i: u32, m: Modulus) -> u32 {
    if i >= m.p {
        return i;
    }
    let square = mul_mod(i, i, m);
    if i <= m.p / 2u {
        return square;
    }
    return m.p - square;
}

// Axis a of a stored position relative to the origin, within about an ulp of the f64 result.
// q - base may need 33 bits: each is split into its high and low 16 bits, whose differences
// are exact. Within 2^24 steps of the origin (every survey at mm steps) the difference is
// exact in f32 and only its product and one sum round; farther, the halves are scaled apart.
fn dequantize(q: i32, a: u32) -> f32 {
    let b = shuffle.base[a];
    let dh = (q >> 16u) - (b >> 16u);
    let dl = (q & 0xffff) - (b & 0xffff);
    let hs = shuffle.step_hi[a];
    let ls = shuffle.step_lo[a];
    if abs(dh) < 255 {
        let d = f32(dh * 65536 + dl);
        return d * hs + (d * ls + shuffle.shift[a]);
    }
    let hi = f32(dh) * 65536.0;
    let lo = f32(dl);
    return hi * hs + (hi * ls + (lo * hs + (lo * ls + shuffle.shift[a])));
}

// Eq. 2: one pass of eq. 1 leaves visible runs (paper Fig. 4), two do not.
fn shuffle_target(i: u32, m: Modulus) -> u32 {
    return permute(permute(i, m), m);
}

// The chunk's slot of point `row` of its group `group` under the interleave: its block moved
// by eq. 2 over the row's whole blocks.
fn interleaved_slot(row: u32, group: u32) -> u32 {
    let block = group >> shuffle.block_shift;
    var column = group;
    if block < shuffle.blocks {
        let m = Modulus(shuffle.prime, shuffle.neg_inv, shuffle.r2);
        let within = group & ((1u << shuffle.block_shift) - 1u);
        column = (shuffle_target(block, m) << shuffle.block_shift) | within;
    }
    if row < shuffle.full_rows {
        return row * shuffle.groups + column;
    }
    let full = shuffle.full_rows * shuffle.groups;
    return full + (row - shuffle.full_rows) * (shuffle.groups - 1u) + column;
}

@compute @workgroup_size(256)
fn scatter(@builtin(global_invocation_id) gid: vec3<u32>,
           @builtin(num_workgroups) nwg: vec3<u32>) {
    var j = gid.x + gid.y * nwg.x * 256u;
    var t: u32;
    if shuffle.interleaved != 0u {
        // Thread k takes row k / window of the batch's groups in the chunk, group k mod window.
        if j >= shuffle.window * shuffle.rows {
            return;
        }
        let row = j / shuffle.window;
        let group = shuffle.window_first + j % shuffle.window;
        let i = (group << shuffle.group_shift) + row;
        // The last group's missing rows lie past the points.
        if i < shuffle.first || i - shuffle.first >= shuffle.count || i >= shuffle.points {
            return;
        }
        j = i - shuffle.first;
        t = shuffle.chunk_base + interleaved_slot(row, group - shuffle.first_group);
    } else if j >= shuffle.count {
        return;
    } else if shuffle.given_slots != 0u {
        t = src_slots[j];
    } else {
        if shuffle.first + j >= shuffle.points {
            return;
        }
        t = shuffle_target(shuffle.first + j, Modulus(shuffle.prime, shuffle.neg_inv, shuffle.r2));
    }
    if t >= shuffle.n || t < shuffle.first_slot || t - shuffle.first_slot >= shuffle.slots {
        return;
    }
    let d = t - shuffle.first_slot;
    dst_colors[d] = src_colors[j];
    if shuffle.colors_only != 0u {
        return;
    }
    if shuffle.quantized != 0u {
        for (var a = 0u; a < 3u; a++) {
            let q = bitcast<i32>(src_positions[j * 3u + a]);
            dst_positions[d * 3u + a] = bitcast<u32>(dequantize(q, a));
        }
    } else {
        for (var w = 0u; w < shuffle.words; w++) {
            dst_positions[d * shuffle.words + w] = src_positions[j * shuffle.words + w];
        }
    }
    if shuffle.has_fine != 0u {
        dst_fine[d] = src_fine[j];
    }
}
