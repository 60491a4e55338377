//! 63-bit 3-D Morton and Hilbert keys (21 bits per axis).
//!
//! As in the virtualized paper (§III-A), the Hilbert index is derived from the Morton code:
//! the Morton code is walked three bits (one octant) at a time through a state table that maps
//! each octant to its Hilbert digit and to the orientation of the child cube. We walk three
//! levels per step with a 512-entry table per state. The table is built once from the curve's
//! base pattern (the 8-cell Gray-code order) and the orientation of each of its children.

use std::sync::OnceLock;

/// Bits per axis of the keys.
pub const KEY_BITS: u32 = 21;
/// Cells per axis.
pub const KEY_CELLS: u64 = 1 << KEY_BITS;

/// Bits 0..8 of an index spread to bits 0, 3, .., 21: three loads spread 21 bits, a third
/// faster than shifting and masking them into place (measured on the key pass).
const SPREAD_BYTE: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut i = 0;
    while i < 256 {
        let mut b = 0;
        while b < 8 {
            t[i] |= ((i as u64 >> b) & 1) << (3 * b);
            b += 1;
        }
        i += 1;
    }
    t
};

/// Spreads the low 21 bits of `v` so that bit i lands at bit 3i.
#[inline]
pub fn spread3(v: u32) -> u64 {
    let spread = |bits: u32| SPREAD_BYTE[bits as usize];
    spread(v & 0xFF) | spread((v >> 8) & 0xFF) << 24 | spread((v >> 16) & 0x1F) << 48
}

/// Inverse of [`spread3`].
#[inline]
pub fn compact3(v: u64) -> u32 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x ^ (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x ^ (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x ^ (x >> 8)) & 0x001f_0000_ff00_00ff;
    x = (x ^ (x >> 16)) & 0x001f_0000_0000_ffff;
    x = (x ^ (x >> 32)) & 0x1f_ffff;
    x as u32
}

/// Morton code: per level, the octant digit is `x << 2 | y << 1 | z`.
#[inline]
pub fn morton3(x: u32, y: u32, z: u32) -> u64 {
    spread3(x) << 2 | spread3(y) << 1 | spread3(z)
}

/// Inverse of [`morton3`].
#[inline]
pub fn morton3_decode(m: u64) -> [u32; 3] {
    [compact3(m >> 2), compact3(m >> 1), compact3(m)]
}

/// An element of the cube's symmetry group: output bit i = input bit `perm[i]` xor `flip` bit i.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Transform {
    perm: [u8; 3],
    flip: u8,
}

impl Transform {
    const IDENTITY: Transform = Transform {
        perm: [0, 1, 2],
        flip: 0,
    };

    /// Octants are `x << 2 | y << 1 | z`; axis 0 is x (bit 2).
    fn apply(self, octant: u8) -> u8 {
        let bit = |o: u8, axis: u8| (o >> (2 - axis)) & 1;
        let mut out = 0;
        for i in 0..3u8 {
            let b = bit(octant, self.perm[i as usize]) ^ ((self.flip >> (2 - i)) & 1);
            out |= b << (2 - i);
        }
        out
    }

    /// `self` after `first`.
    fn after(self, first: Transform) -> Transform {
        // Found by evaluation: the group is small and this keeps the algebra obviously right.
        all_transforms()
            .into_iter()
            .find(|t| (0..8).all(|o| t.apply(o) == self.apply(first.apply(o))))
            .unwrap_or(Transform::IDENTITY)
    }
}

fn all_transforms() -> Vec<Transform> {
    const PERMS: [[u8; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(48);
    for perm in PERMS {
        for flip in 0..8 {
            out.push(Transform { perm, flip });
        }
    }
    out
}

/// Reference Hilbert index (Skilling's transpose method), used to derive the base pattern
/// and child orientations and in tests. `bits` levels, cells `0..2^bits`.
pub fn hilbert3_reference(p: [u32; 3], bits: u32) -> u64 {
    let mut x = p;
    let m = 1u32 << (bits - 1);
    // Undo excess work: walk the levels from the top, inverting or exchanging low bits.
    let mut q = m;
    while q > 1 {
        let low = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= low;
            } else {
                let t = (x[0] ^ x[i]) & low;
                x[0] ^= t;
                x[i] ^= t;
            }
        }
        q >>= 1;
    }
    // Gray encode.
    x[1] ^= x[0];
    x[2] ^= x[1];
    let mut t = 0;
    q = m;
    while q > 1 {
        if x[2] & q != 0 {
            t ^= q - 1;
        }
        q >>= 1;
    }
    for v in &mut x {
        *v ^= t;
    }
    let mut h = 0u64;
    for b in (0..bits).rev() {
        for v in &x {
            h = h << 1 | ((v >> b) & 1) as u64;
        }
    }
    h
}

/// Per state, a table for three levels: index = 9 Morton bits, value = 9 Hilbert bits << 5 |
/// next state (the curve has 24 states, so 5 bits hold one; the tests against the reference
/// would fail otherwise). 1 KiB per state: all of them stay in the L1 cache.
struct HilbertTables {
    /// Rows past the curve's states stay zero: indexing by `state & 31` needs no bounds check.
    three_level: Box<[[u16; 512]; STATE_ROWS]>,
}

/// Rows of the state table: the curve's 24 states, rounded up to a power of two.
const STATE_ROWS: usize = 32;

fn tables() -> &'static HilbertTables {
    static TABLES: OnceLock<HilbertTables> = OnceLock::new();
    TABLES.get_or_init(build_tables)
}

fn build_tables() -> HilbertTables {
    let split = |o: u8| [((o >> 2) & 1) as u32, ((o >> 1) & 1) as u32, (o & 1) as u32];
    // Base pattern: the digit of each octant on a 2-level curve (top level only).
    let mut base = [0u8; 8];
    for o in 0..8u8 {
        let c = split(o);
        base[o as usize] = (hilbert3_reference([c[0] << 1, c[1] << 1, c[2] << 1], 2) >> 3) as u8;
    }
    // Child orientation C_o: the 8 cells inside octant o are visited in the order base(C_o(q)).
    let transforms = all_transforms();
    let mut child = [Transform::IDENTITY; 8];
    for o in 0..8u8 {
        let c = split(o);
        let order: Vec<u8> = (0..8u8)
            .map(|q| {
                let l = split(q);
                let p = [c[0] << 1 | l[0], c[1] << 1 | l[1], c[2] << 1 | l[2]];
                (hilbert3_reference(p, 2) & 7) as u8
            })
            .collect();
        if let Some(t) = transforms
            .iter()
            .find(|t| (0..8u8).all(|q| base[t.apply(q) as usize] == order[q as usize]))
        {
            child[o as usize] = *t;
        }
    }
    // States are orientations reachable from the root: digit = base(S(q)), next = C_{S(q)} ∘ S.
    let mut states = vec![Transform::IDENTITY];
    let mut one_level: Vec<[(u8, u8); 8]> = Vec::new();
    let mut i = 0;
    while i < states.len() {
        let s = states[i];
        let mut row = [(0u8, 0u8); 8];
        for q in 0..8u8 {
            let sq = s.apply(q);
            let next = child[sq as usize].after(s);
            let idx = match states.iter().position(|t| *t == next) {
                Some(k) => k,
                None => {
                    states.push(next);
                    states.len() - 1
                }
            };
            row[q as usize] = (base[sq as usize], idx as u8);
        }
        one_level.push(row);
        i += 1;
    }
    let mut three_level = Box::new([[0u16; 512]; STATE_ROWS]);
    for (row, t) in one_level.iter().zip(three_level.iter_mut()) {
        for (m, out) in t.iter_mut().enumerate() {
            let (d1, s1) = row[m >> 6];
            let (d2, s2) = one_level[s1 as usize][(m >> 3) & 7];
            let (d3, s3) = one_level[s2 as usize][m & 7];
            let digits = u16::from(d1) << 6 | u16::from(d2) << 3 | u16::from(d3);
            *out = digits << 5 | u16::from(s3);
        }
    }
    HilbertTables { three_level }
}

/// Hilbert index of a 63-bit Morton code (21 levels), three levels per table lookup.
#[inline]
pub fn hilbert_from_morton(morton: u64) -> u64 {
    let t = tables();
    let mut state = 0usize;
    let mut h = 0u64;
    let mut shift = 63;
    while shift > 0 {
        shift -= 9;
        let e = t.three_level[state & (STATE_ROWS - 1)][((morton >> shift) & 511) as usize];
        h = h << 9 | u64::from(e >> 5);
        state = usize::from(e & 31);
    }
    h
}

/// [`hilbert_from_morton`] of `N` codes at once: the table walk is a chain of dependent loads,
/// and independent chains keep the core busy while each waits on its loads (eight: 2.4 against
/// 5.7 ns a key with four, dev machine). Walking the steps that neighbouring codes share only
/// once was no faster (dev, scanlines).
#[inline(always)]
pub fn hilbert_from_morton_n<const N: usize>(morton: [u64; N]) -> [u64; N] {
    let t = tables();
    let mut state = [0usize; N];
    let mut h = [0u64; N];
    let mut shift = 63;
    while shift > 0 {
        shift -= 9;
        for i in 0..N {
            let e =
                t.three_level[state[i] & (STATE_ROWS - 1)][((morton[i] >> shift) & 511) as usize];
            h[i] = h[i] << 9 | u64::from(e >> 5);
            state[i] = usize::from(e & 31);
        }
    }
    h
}

/// Bits of an axis in a Morton code, for the bit deposit.
#[cfg(target_arch = "x86_64")]
const MORTON_AXIS: u64 = 0x1249_2492_4924_9249;

/// Hilbert index of integer cell coordinates (each < 2^21).
#[inline]
pub fn hilbert3(x: u32, y: u32, z: u32) -> u64 {
    hilbert_from_morton(morton3(x, y, z))
}

/// Maps f64 positions inside a cube to integer cells for keys.
#[derive(Clone, Copy, Debug)]
pub struct KeyGrid {
    min: [f64; 3],
    inv_cell: f64,
}

impl KeyGrid {
    /// Grid over the bounding cube of `bounds`.
    pub fn new(bounds: &crate::Aabb) -> Self {
        let cube = bounds.bounding_cube();
        let side = cube.extent()[0];
        let inv_cell = if side > 0.0 && side.is_finite() {
            KEY_CELLS as f64 / side
        } else {
            0.0
        };
        Self {
            min: cube.min,
            inv_cell,
        }
    }

    /// Cell of a point; points outside the cube are clamped (keys stay valid, locality degrades).
    #[inline]
    pub fn cell(&self, p: [f64; 3]) -> [u32; 3] {
        let max = (KEY_CELLS - 1) as f64;
        let f = |i: usize| {
            // `max` first: it takes NaN to 0, as the saturating `as` would.
            let c = ((p[i] - self.min[i]) * self.inv_cell).max(0.0).min(max);
            // SAFETY: c is a finite value in 0..=max, which u32 holds.
            unsafe { c.to_int_unchecked::<u32>() }
        };
        [f(0), f(1), f(2)]
    }

    #[inline]
    pub fn morton(&self, p: [f64; 3]) -> u64 {
        let c = self.cell(p);
        morton3(c[0], c[1], c[2])
    }

    #[inline]
    pub fn hilbert(&self, p: [f64; 3]) -> u64 {
        hilbert_from_morton(self.morton(p))
    }

    /// [`hilbert`](Self::hilbert) of the stored positions `raw` (quantized by `q`) into `keys`
    /// (as long): eight at a time, with Morton codes by the CPU's bit deposit where it has one
    /// (BMI2: 4.3 against 9.0 ns a key in all, dev machine). The same keys either way.
    pub fn hilbert_raw(&self, q: &crate::Quantization, raw: &[[i32; 3]], keys: &mut [u64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("bmi2") {
            // SAFETY: the CPU has BMI2.
            return unsafe { self.hilbert_raw_bmi2(q, raw, keys) };
        }
        self.hilbert_raw_with::<false>(q, raw, keys);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "bmi2")]
    unsafe fn hilbert_raw_bmi2(&self, q: &crate::Quantization, raw: &[[i32; 3]], keys: &mut [u64]) {
        self.hilbert_raw_with::<true>(q, raw, keys);
    }

    #[inline(always)]
    fn hilbert_raw_with<const BMI2: bool>(
        &self,
        q: &crate::Quantization,
        raw: &[[i32; 3]],
        keys: &mut [u64],
    ) {
        let morton = |r: [i32; 3]| {
            let p = q.dequantize(r);
            #[cfg(target_arch = "x86_64")]
            if BMI2 {
                use std::arch::x86_64::_pdep_u64;
                let c = self.cell(p);
                // SAFETY: only reached from `hilbert_raw_bmi2`, on a CPU with BMI2.
                return unsafe {
                    _pdep_u64(u64::from(c[0]), MORTON_AXIS << 2)
                        | _pdep_u64(u64::from(c[1]), MORTON_AXIS << 1)
                        | _pdep_u64(u64::from(c[2]), MORTON_AXIS)
                };
            }
            self.morton(p)
        };
        let mut eights = raw.chunks_exact(8);
        let mut outs = keys.chunks_exact_mut(8);
        for (r, k) in eights.by_ref().zip(outs.by_ref()) {
            let m = [
                morton(r[0]),
                morton(r[1]),
                morton(r[2]),
                morton(r[3]),
                morton(r[4]),
                morton(r[5]),
                morton(r[6]),
                morton(r[7]),
            ];
            k.copy_from_slice(&hilbert_from_morton_n(m));
        }
        for (r, k) in eights.remainder().iter().zip(outs.into_remainder()) {
            *k = hilbert_from_morton(morton(*r));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shuffle::SplitMix64;

    /// [`spread3`] by shifting and masking: what the table replaced.
    fn spread3_by_shifts(v: u32) -> u64 {
        let mut x = u64::from(v) & 0x1f_ffff;
        x = (x | x << 32) & 0x001f_0000_0000_ffff;
        x = (x | x << 16) & 0x001f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    }

    #[test]
    fn spread3_moves_bit_i_to_bit_3i_and_drops_the_rest() {
        let bitwise =
            |v: u32| (0..KEY_BITS).fold(0u64, |m, i| m | u64::from(v >> i & 1) << (3 * i));
        let mut rng = SplitMix64::new(3);
        for v in (0..32)
            .map(|i| 1u32 << i)
            .chain((0..10_000).map(|_| rng.next_u64() as u32))
        {
            assert_eq!(spread3(v), bitwise(v), "{v:#x}");
            assert_eq!(spread3_by_shifts(v), bitwise(v), "{v:#x}");
        }
    }

    /// Nanoseconds per point of Morton codes by table and by shifts, and of Hilbert keys from
    /// them: `cargo test --release -p pointlet-core --lib key_time -- --ignored --nocapture`.
    #[test]
    #[ignore = "a timing, not a check"]
    fn key_time_of_random_cells() {
        let mut rng = SplitMix64::new(4);
        let cells: Vec<[u32; 3]> = (0..1 << 22)
            .map(|_| [0, 1, 2].map(|_| rng.below(KEY_CELLS) as u32))
            .collect();
        let mut keys = vec![0u64; cells.len()];
        let per_point =
            |t: std::time::Instant| t.elapsed().as_secs_f64() * 1e9 / cells.len() as f64;
        for round in 1..=3 {
            let t = std::time::Instant::now();
            for (k, c) in keys.iter_mut().zip(&cells) {
                *k = spread3_by_shifts(c[0]) << 2
                    | spread3_by_shifts(c[1]) << 1
                    | spread3_by_shifts(c[2]);
            }
            let shifts = per_point(t);
            let by_shifts = std::hint::black_box(keys.clone());
            let t = std::time::Instant::now();
            for (k, c) in keys.iter_mut().zip(&cells) {
                *k = morton3(c[0], c[1], c[2]);
            }
            let table = per_point(t);
            assert_eq!(keys, by_shifts);
            let t = std::time::Instant::now();
            for k in keys.chunks_exact_mut(8) {
                let h = hilbert_from_morton_n([k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7]]);
                k.copy_from_slice(&h);
            }
            let hilbert = per_point(t);
            std::hint::black_box(&keys);
            // The whole key of stored positions, one by one and eight at a time.
            let q = crate::Quantization {
                scale: [0.001; 3],
                offset: [0.0; 3],
            };
            let grid = KeyGrid::new(&crate::Aabb {
                min: [0.0; 3],
                max: [2000.0, 2000.0, 2000.0],
            });
            let mut raw: Vec<[i32; 3]> = cells.iter().map(|c| c.map(|v| v as i32 / 2)).collect();
            let t = std::time::Instant::now();
            for (k, r) in keys.iter_mut().zip(&raw) {
                *k = grid.hilbert(q.dequantize(*r));
            }
            let single = per_point(t);
            let one_by_one = std::hint::black_box(keys.clone());
            let t = std::time::Instant::now();
            grid.hilbert_raw(&q, &raw, &mut keys);
            let eights = per_point(t);
            assert_eq!(keys, one_by_one);
            // Scanlines: each point 0.1–0.6 m past the last, in rows 1 m apart.
            for (i, r) in raw.iter_mut().enumerate() {
                let (row, along) = (i / 4096, i % 4096);
                *r = [
                    along as i32 * 350,
                    row as i32 * 1000,
                    2000 + (i % 13) as i32 * 10,
                ];
            }
            let t = std::time::Instant::now();
            grid.hilbert_raw(&q, &raw, &mut keys);
            let scanlines = per_point(t);
            println!(
                "round {round}: Morton by shifts {shifts:.2} ns, by table {table:.2} ns; \
                 Hilbert from Morton, eight at a time {hilbert:.2} ns; keys of stored \
                 positions one by one {single:.2} ns, eight at a time {eights:.2} ns, of \
                 scanlines {scanlines:.2} ns"
            );
        }
    }

    #[test]
    fn keys_of_stored_positions_are_those_of_single_points() {
        let mut rng = SplitMix64::new(9);
        let q = crate::Quantization {
            scale: [0.01, 0.01, 0.001],
            offset: [1000.0, -50.0, 3.0],
        };
        let grid = KeyGrid::new(&crate::Aabb {
            min: [900.0, -80.0, 0.0],
            max: [1900.0, 400.0, 90.0],
        });
        // Inside the grid, outside it (clamped) and at the extremes; a length that leaves a
        // remainder after the eights.
        let mut raw: Vec<[i32; 3]> = (0..1003)
            .map(|_| [0, 1, 2].map(|_| rng.below(1 << 22) as i32 - (1 << 20)))
            .collect();
        raw.extend([[i32::MIN; 3], [i32::MAX; 3], [0; 3]]);
        // Points as a scanner writes them: each a little beyond the last, so that groups of
        // eight share the top of their keys, some all but the last bits, some all of them.
        let mut at = [50_000, 20_000, 4_000];
        for i in 0..4000 {
            at[0] += (i % 7) * 30;
            at[1] += (i % 3) - 1;
            raw.push(at);
            if i % 100 == 0 {
                raw.extend([at; 9]);
            }
        }
        let want: Vec<u64> = raw.iter().map(|r| grid.hilbert(q.dequantize(*r))).collect();
        let mut keys = vec![0; raw.len()];
        grid.hilbert_raw(&q, &raw, &mut keys);
        assert_eq!(keys, want);
        keys.fill(0);
        grid.hilbert_raw_with::<false>(&q, &raw, &mut keys);
        assert_eq!(keys, want);
    }

    #[test]
    fn morton_round_trip() {
        let mut rng = SplitMix64::new(1);
        for _ in 0..10_000 {
            let p = [
                rng.below(KEY_CELLS) as u32,
                rng.below(KEY_CELLS) as u32,
                rng.below(KEY_CELLS) as u32,
            ];
            assert_eq!(morton3_decode(morton3(p[0], p[1], p[2])), p);
        }
        assert_eq!(morton3(1, 0, 0), 4);
        assert_eq!(morton3(0, 0, 1), 1);
    }

    #[test]
    fn table_matches_reference_at_full_depth() {
        let mut rng = SplitMix64::new(2);
        for _ in 0..20_000 {
            let p = [
                rng.below(KEY_CELLS) as u32,
                rng.below(KEY_CELLS) as u32,
                rng.below(KEY_CELLS) as u32,
            ];
            assert_eq!(
                hilbert3(p[0], p[1], p[2]),
                hilbert3_reference(p, 21),
                "{p:?}"
            );
        }
    }

    #[test]
    fn curve_is_continuous_and_bijective() {
        // Cells of a 2^4 corner of the grid at full depth: consecutive Hilbert indices within
        // the smallest sub-cubes must be face neighbours.
        let n = 16u32;
        let mut cells: Vec<(u64, [u32; 3])> = Vec::new();
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    cells.push((hilbert3(x, y, z), [x, y, z]));
                }
            }
        }
        cells.sort_unstable();
        // The corner 16^3 cube is one sub-cube of the curve: its indices are contiguous.
        for w in cells.windows(2) {
            assert_eq!(w[1].0, w[0].0 + 1, "indices of a sub-cube are contiguous");
            let d: u32 = (0..3).map(|i| w[0].1[i].abs_diff(w[1].1[i])).sum();
            assert_eq!(d, 1, "{:?} -> {:?}", w[0], w[1]);
        }
    }
}
