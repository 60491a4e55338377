//! The incremental shuffle of the progressive-rendering paper (Schütz et al., "Progressive
//! Real-Time Rendering of One Billion Points Without Hierarchical Acceleration Structures",
//! §3.3, eq. 1–2): point i of a buffer of n slots goes to slot `target(i)`, computed from i
//! alone, so batches can be scattered in parallel as they arrive and any prefix of the buffer
//! is a spread-out subsample of the points.

use thiserror::Error;

/// Largest buffer the permutation accepts: indices stay below 2^32, so every slot index fits a
/// GPU `u32` and i² fits a `u64`.
pub const MAX_SLOTS: u64 = 1 << 32;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum ShuffleError {
    #[error("a shuffled buffer of {n} slots exceeds the limit of {MAX_SLOTS} (2^32) slots")]
    TooManySlots { n: u64 },
    #[error("groups of {group} points cannot be interleaved: the size must be a power of two")]
    GroupSize { group: u64 },
    #[error("{slots} slots cannot keep a point of each of {groups} groups")]
    TooFewSlots { slots: u64, groups: u64 },
    #[error("a chunk of {chunk_slots} slots cannot hold a group's {rows} points")]
    ChunkTooSmall { chunk_slots: u64, rows: u64 },
}

/// The permutation of a buffer of `n` slots: slots `0..P` are permuted by applying eq. 1
/// twice (eq. 2), slots `P..n` stay in place, where P is the largest prime ≡ 3 (mod 4) ≤ n.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShufflePermutation {
    n: u64,
    prime: u64,
}

impl ShufflePermutation {
    pub fn new(n: u64) -> Result<Self, ShuffleError> {
        if n > MAX_SLOTS {
            return Err(ShuffleError::TooManySlots { n });
        }
        Ok(Self {
            n,
            prime: prime_3_mod_4_at_most(n).unwrap_or(0),
        })
    }

    /// Slots of the buffer.
    pub fn len(&self) -> u64 {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// P: slots below it are shuffled; 0 when n < 3 (no such prime: the identity).
    pub fn prime(&self) -> u64 {
        self.prime
    }

    /// Eq. 1: quadratic residues for the lower half, their negatives (the non-residues, since
    /// −1 is a non-residue when P ≡ 3 mod 4) for the upper half; a bijection of `0..P`.
    pub fn permute(&self, i: u64) -> u64 {
        let p = self.prime;
        if i >= p {
            return i;
        }
        // i < P < 2^32, so i² < 2^64.
        let square = (i * i) % p;
        if i <= p / 2 {
            square
        } else {
            p - square
        }
    }

    /// Eq. 2: the slot point `i` goes to; one pass of eq. 1 leaves visible runs (paper Fig. 4).
    pub fn target(&self, i: u64) -> u64 {
        self.permute(self.permute(i))
    }
}

/// The slots of one chunk of groups whose points are each in random order already (a store's
/// pointlets, shuffled when the store was built), `rows` points kept of each: point j of every
/// group comes before point j + 1 of any (rows of one point per group), so every run of whole
/// rows holds the first points of every group loaded so far, a stratified uniform subsample.
/// Within a row, blocks of up to 64 neighbouring groups are permuted (eq. 1–2 over the blocks),
/// so that a prefix ending inside a row still spreads over the whole chunk, while a batch of
/// whole groups lands in runs of neighbouring slots (a block each) instead of all over the
/// buffer. The last group may keep fewer rows: rows past them skip it, so the slots are
/// exactly the points kept; columns past the last whole block of the shorter rows stay in
/// place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroupInterleave {
    /// Slots: the points kept.
    n: u64,
    rows: u64,
    groups: u64,
    /// Rows that include the last group: the rows it keeps.
    full_rows: u64,
    /// log2 of the groups in a block, and the permutation of the whole blocks of a row.
    block_shift: u32,
    blocks: ShufflePermutation,
}

/// Most groups in a block, and fewest blocks in a row the block size aims at.
const MAX_BLOCK: u64 = 64;
const MIN_BLOCKS: u64 = 1024;

impl GroupInterleave {
    /// `groups` groups of `rows` points kept, the last one `last_rows` (at most `rows`).
    pub fn new(groups: u64, rows: u64, last_rows: u64) -> Result<Self, ShuffleError> {
        let n = groups.saturating_sub(1) * rows + last_rows.min(rows);
        if n > MAX_SLOTS {
            return Err(ShuffleError::TooManySlots { n });
        }
        // Blocks as large as keep a thousand of them in a row: small chunks permute groups.
        let block = (groups / MIN_BLOCKS).clamp(1, MAX_BLOCK);
        let block_shift = block.ilog2();
        let short_row = groups.saturating_sub(1);
        Ok(Self {
            n,
            rows,
            groups,
            full_rows: last_rows.min(rows),
            block_shift,
            blocks: ShufflePermutation::new(short_row >> block_shift)?,
        })
    }

    /// Slots: the points kept.
    pub fn len(&self) -> u64 {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Points kept of each group (the last one: [`full_rows`](Self::full_rows)).
    pub fn rows(&self) -> u64 {
        self.rows
    }

    pub fn groups(&self) -> u64 {
        self.groups
    }

    /// Rows with a point of every group, the last one included (the rows it keeps).
    pub fn full_rows(&self) -> u64 {
        self.full_rows
    }

    /// log2 of the groups in a block.
    pub fn block_shift(&self) -> u32 {
        self.block_shift
    }

    /// The permutation of the whole blocks of a row.
    pub fn blocks(&self) -> ShufflePermutation {
        self.blocks
    }

    /// The slot of point `row` of group `group`, `None` when that point is not kept.
    pub fn slot(&self, row: u64, group: u64) -> Option<u64> {
        let last = group + 1 == self.groups;
        if group >= self.groups || row >= self.rows || (last && row >= self.full_rows) {
            return None;
        }
        let block = group >> self.block_shift;
        let column = if block < self.blocks.len() {
            let within = group & ((1 << self.block_shift) - 1);
            self.blocks.target(block) << self.block_shift | within
        } else {
            group
        };
        Some(if row < self.full_rows {
            row * self.groups + column
        } else {
            self.full_rows * self.groups + (row - self.full_rows) * (self.groups - 1) + column
        })
    }
}

/// The slots of a file whose points come in groups of `2^shift`, each in random order already
/// (a store's pointlets): the first `rows` points of every group are kept (all of them unless
/// the buffer holds fewer slots than the file has points), and the groups are cut into chunks
/// of consecutive groups, one GPU buffer of `chunk_slots` slots each, interleaved inside
/// ([`GroupInterleave`]). A chunk fills as its groups load (file order), so it can be drawn
/// as soon as its buffer exists and loading need not wait for the rest of the GPU memory; a
/// fill taking the same share of every chunk's slots is a uniform subsample of everything
/// loaded. Chunk c starts at slot c × `chunk_slots`; the slots a chunk does not fill are never
/// written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroupRows {
    n: u64,
    shift: u32,
    groups: u64,
    rows: u64,
    /// Groups per chunk (the last chunk may hold fewer).
    per_chunk: u64,
    chunk_slots: u64,
}

impl GroupRows {
    /// `n` points in groups of `group` (a power of two) points in a buffer of at most
    /// `max_slots` slots (at least one a group), in one chunk.
    pub fn new(n: u64, group: u64, max_slots: u64) -> Result<Self, ShuffleError> {
        if !group.is_power_of_two() {
            return Err(ShuffleError::GroupSize { group });
        }
        let groups = n.div_ceil(group);
        let last_size = n - groups.saturating_sub(1) * group;
        let placed = |rows: u64| groups.saturating_sub(1) * rows + last_size.min(rows);
        // The most rows within the slots (a short last group leaves room for more).
        let mut rows = if max_slots >= n {
            group
        } else {
            group.min(max_slots / groups.max(1))
        };
        while rows < group && placed(rows + 1) <= max_slots {
            rows += 1;
        }
        if groups > 0 && rows == 0 {
            return Err(ShuffleError::TooFewSlots {
                slots: max_slots,
                groups,
            });
        }
        let order = Self {
            n,
            shift: group.trailing_zeros(),
            groups,
            rows,
            per_chunk: groups.max(1),
            chunk_slots: MAX_SLOTS,
        };
        if order.placed() > MAX_SLOTS {
            return Err(ShuffleError::TooManySlots { n: order.placed() });
        }
        Ok(order)
    }

    /// The same order in chunks of at most `chunk_slots` slots (whole groups).
    pub fn chunked(self, chunk_slots: u64) -> Result<Self, ShuffleError> {
        let per_chunk = chunk_slots / self.rows.max(1);
        if per_chunk == 0 {
            return Err(ShuffleError::ChunkTooSmall {
                chunk_slots,
                rows: self.rows,
            });
        }
        let chunked = Self {
            per_chunk: per_chunk.min(self.groups.max(1)),
            chunk_slots,
            ..self
        };
        if chunked.physical_slots() > MAX_SLOTS {
            return Err(ShuffleError::TooManySlots {
                n: chunked.physical_slots(),
            });
        }
        Ok(chunked)
    }

    /// Points of the file.
    pub fn len(&self) -> u64 {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// log2 of the group size.
    pub fn shift(&self) -> u32 {
        self.shift
    }

    pub fn groups(&self) -> u64 {
        self.groups
    }

    /// Points kept of every group (the last one may have fewer).
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Points of the last group.
    fn last_size(&self) -> u64 {
        self.n - self.groups.saturating_sub(1) * (1 << self.shift)
    }

    /// Points the buffer holds.
    pub fn placed(&self) -> u64 {
        self.groups.saturating_sub(1) * self.rows + self.last_size().min(self.rows)
    }

    pub fn chunk_slots(&self) -> u64 {
        self.chunk_slots
    }

    /// Chunks (at least one).
    pub fn chunks(&self) -> u64 {
        self.groups.div_ceil(self.per_chunk).max(1)
    }

    /// The chunk group `group` lies in.
    pub fn chunk_of(&self, group: u64) -> u64 {
        group / self.per_chunk
    }

    /// Chunk `c`'s groups and the rows its last group keeps.
    fn chunk_groups(&self, c: u64) -> (std::ops::Range<u64>, u64) {
        let first = (c * self.per_chunk).min(self.groups);
        let end = (first + self.per_chunk).min(self.groups);
        let last_rows = if end == self.groups {
            self.last_size().min(self.rows)
        } else {
            self.rows
        };
        (first..end, last_rows)
    }

    /// Chunk `c`: its first group and its slots.
    pub fn chunk(&self, c: u64) -> Result<(u64, GroupInterleave), ShuffleError> {
        let (groups, last_rows) = self.chunk_groups(c);
        let slots = GroupInterleave::new(groups.end - groups.start, self.rows, last_rows)?;
        Ok((groups.start, slots))
    }

    /// The slots chunk `c` fills: from its start, one a point it keeps (without making its
    /// permutation).
    pub fn chunk_span(&self, c: u64) -> std::ops::Range<u64> {
        let (groups, last_rows) = self.chunk_groups(c);
        let start = c * self.chunk_slots;
        let kept = (groups.end - groups.start).saturating_sub(1) * self.rows;
        start..start + kept + if groups.is_empty() { 0 } else { last_rows }
    }

    /// Slots from the first chunk's start to the last one's end.
    pub fn physical_slots(&self) -> u64 {
        self.chunk_span(self.chunks() - 1).end
    }

    /// The slot of point `i`, `None` when it is not kept.
    pub fn target(&self, i: u64) -> Option<u64> {
        if i >= self.n {
            return None;
        }
        let (row, group) = (i & ((1 << self.shift) - 1), i >> self.shift);
        let c = self.chunk_of(group);
        let (first, chunk) = self.chunk(c).ok()?;
        let local = chunk.slot(row, group - first)?;
        Some(c * self.chunk_slots + local)
    }
}

/// Where the points of a file go in its shuffled buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotOrder {
    /// Any file: the paper's prime-number permutation (eq. 1–2).
    Permuted(ShufflePermutation),
    /// Files of groups each in random order already (stores): the groups interleaved, chunk
    /// by chunk.
    Interleaved(GroupRows),
}

impl SlotOrder {
    /// Points the order takes (past a permutation's slots, none).
    pub fn len(&self) -> u64 {
        match self {
            Self::Permuted(p) => p.len(),
            Self::Interleaved(g) => g.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Points the buffer holds.
    pub fn placed(&self) -> u64 {
        match self {
            Self::Permuted(p) => p.len(),
            Self::Interleaved(g) => g.placed(),
        }
    }

    /// Slots of the buffer (an interleave's chunks may leave slots unused at their ends).
    pub fn physical_slots(&self) -> u64 {
        match self {
            Self::Permuted(p) => p.len(),
            Self::Interleaved(g) => g.physical_slots(),
        }
    }

    /// The slot of point `i`, `None` when it is left out.
    pub fn target(&self, i: u64) -> Option<u64> {
        match self {
            Self::Permuted(p) => (i < p.len()).then(|| p.target(i)),
            Self::Interleaved(g) => g.target(i),
        }
    }
}

/// Where point `i` of a file goes in a shuffled buffer that holds fewer slots than the file
/// has points. The first `capacity` points fill it through the permutation; each later point i
/// takes slot j for a j uniform in `0..=i` when j < capacity, else is left out (reservoir
/// sampling, Vitter's Algorithm R). At any time the buffer holds a uniform random subset of the
/// points read so far, and since its slots are exchangeable, so does every prefix of it. j is a
/// hash of (seed, i), so points can be placed in parallel; of two points that pick the same
/// slot, the later one must win.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reservoir {
    permutation: ShufflePermutation,
    seed: u64,
}

impl Reservoir {
    pub fn new(capacity: u64, seed: u64) -> Result<Self, ShuffleError> {
        Ok(Self {
            permutation: ShufflePermutation::new(capacity)?,
            seed,
        })
    }

    pub fn capacity(&self) -> u64 {
        self.permutation.len()
    }

    /// The slot of point `i`, or `None` when it is left out.
    pub fn slot(&self, i: u64) -> Option<u64> {
        let capacity = self.permutation.len();
        if i < capacity {
            return Some(self.permutation.target(i));
        }
        let h = crate::shuffle::mix_seed(self.seed, i);
        // Uniform in 0..=i by a multiply-shift (bias below 2^-32 for i < 2^32).
        let j = ((u128::from(h) * (u128::from(i) + 1)) >> 64) as u64;
        (j < capacity).then_some(j)
    }
}

/// The largest prime P ≡ 3 (mod 4) with P ≤ n, searching downward; `None` below 3.
pub fn prime_3_mod_4_at_most(n: u64) -> Option<u64> {
    if n < 3 {
        return None;
    }
    // The largest candidate ≡ 3 (mod 4) not above n; candidates then step by 4.
    let mut c = n - (n % 4 + 1) % 4;
    loop {
        if is_prime(c) {
            return Some(c);
        }
        // 3 is prime, so the loop stops before c could drop below it.
        c -= 4;
    }
}

/// Deterministic for every u64: Miller–Rabin with the first twelve primes as bases is exact
/// below 3.3·10^24.
pub fn is_prime(n: u64) -> bool {
    const BASES: [u64; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];
    if n < 2 {
        return false;
    }
    for p in BASES {
        if n.is_multiple_of(p) {
            return n == p;
        }
    }
    let (mut d, mut s) = (n - 1, 0);
    while d.is_multiple_of(2) {
        d /= 2;
        s += 1;
    }
    'bases: for a in BASES {
        let mut x = pow_mod(a, d, n);
        if x == 1 || x == n - 1 {
            continue;
        }
        for _ in 1..s {
            x = mul_mod(x, x, n);
            if x == n - 1 {
                continue 'bases;
            }
        }
        return false;
    }
    true
}

fn mul_mod(a: u64, b: u64, m: u64) -> u64 {
    ((a as u128 * b as u128) % m as u128) as u64
}

fn pow_mod(mut base: u64, mut exp: u64, m: u64) -> u64 {
    let mut result = 1;
    base %= m;
    while exp > 0 {
        if exp & 1 == 1 {
            result = mul_mod(result, base, m);
        }
        base = mul_mod(base, base, m);
        exp >>= 1;
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Slot → point of a buffer filled by `order` (`u32::MAX`: a slot no point fills),
    /// checking along the way that no slot is hit twice or lies outside the buffer and that
    /// the order places as many points as it says.
    fn filled(order: SlotOrder) -> Vec<u32> {
        let n = order.len() as usize;
        let mut slots = vec![u32::MAX; order.physical_slots() as usize];
        let mut placed = 0;
        for i in 0..n {
            let Some(t) = order.target(i as u64) else {
                continue;
            };
            assert!(
                t < slots.len() as u64,
                "{order:?}: point {i} goes to slot {t}"
            );
            assert_eq!(slots[t as usize], u32::MAX, "{order:?}: slot {t} hit twice");
            slots[t as usize] = i as u32;
            placed += 1;
        }
        assert_eq!(placed, order.placed(), "{order:?}");
        slots
    }

    fn placement(perm: &ShufflePermutation) -> Vec<u32> {
        filled(SlotOrder::Permuted(*perm))
    }

    fn interleaved(order: &GroupRows) -> Vec<u32> {
        filled(SlotOrder::Interleaved(*order))
    }

    /// All points of `n` in groups of `group`, in one chunk.
    fn whole(n: u64, group: u64) -> GroupRows {
        GroupRows::new(n, group, u64::MAX).unwrap()
    }

    #[test]
    fn every_buffer_up_to_20000_slots_is_a_bijection() {
        for n in 0..=20_000u64 {
            placement(&ShufflePermutation::new(n).unwrap());
        }
    }

    #[test]
    fn large_buffers_are_bijections() {
        for n in [1_000_007, 1 << 24, 3_000_000] {
            let perm = ShufflePermutation::new(n).unwrap();
            placement(&perm);
        }
    }

    #[test]
    fn the_prime_is_the_largest_3_mod_4_not_above_n() {
        const LIMIT: usize = 100_000;
        let mut composite = vec![false; LIMIT + 1];
        let mut best = None;
        for k in 2..=LIMIT {
            if !composite[k] {
                for m in (k * k..=LIMIT).step_by(k) {
                    composite[m] = true;
                }
                if k % 4 == 3 {
                    best = Some(k as u64);
                }
            }
            assert_eq!(prime_3_mod_4_at_most(k as u64), best, "n {k}");
            assert_eq!(is_prime(k as u64), !composite[k], "{k}");
        }
        assert_eq!(prime_3_mod_4_at_most(0), None);
        assert_eq!(prime_3_mod_4_at_most(1), None);
        assert_eq!(
            prime_3_mod_4_at_most(u64::MAX),
            Some(18_446_744_073_709_551_427)
        );
    }

    #[test]
    fn the_prime_near_the_limit_is_found_and_checked() {
        let perm = ShufflePermutation::new(MAX_SLOTS).unwrap();
        let p = perm.prime();
        assert!(p < MAX_SLOTS && p % 4 == 3 && is_prime(p));
        // 2^32 − 5 is the largest prime below 2^32 and is ≡ 3 (mod 4).
        assert_eq!(p, (1 << 32) - 5);
        assert!(((p + 1)..=MAX_SLOTS).all(|c| !is_prime(c) || c % 4 != 3));
        // The squares near the top of the range must not overflow.
        assert_eq!(perm.permute(p - 1), p - 1);
        assert_eq!(
            ShufflePermutation::new(MAX_SLOTS + 1),
            Err(ShuffleError::TooManySlots { n: MAX_SLOTS + 1 })
        );
        // Known primes, and a strong pseudoprime to bases 2, 3, 5 and 7 (151·751·28351).
        assert!(is_prime(4_294_967_291) && is_prime(2_147_483_647));
        assert!(!is_prime(3_215_031_751));
        assert!(!is_prime(4_294_967_297));
    }

    #[test]
    fn the_first_slots_are_the_identity_below_three() {
        for n in 0..3 {
            let perm = ShufflePermutation::new(n).unwrap();
            assert_eq!(perm.prime(), 0);
            assert!((0..n).all(|i| perm.target(i) == i));
        }
    }

    /// Chi-square statistic of a 16×16 histogram of the grid points in `slots` against uniform.
    fn chi_square(slots: &[u32], side: u32) -> f64 {
        let mut cells = [0u32; 256];
        let cell = side / 16;
        for &i in slots {
            let (x, y) = (i % side, i / side);
            cells[((y / cell) * 16 + x / cell) as usize] += 1;
        }
        let expected = slots.len() as f64 / 256.0;
        cells
            .iter()
            .map(|&c| (c as f64 - expected).powi(2) / expected)
            .sum()
    }

    /// Critical value of chi-square with 255 degrees of freedom (16 × 16 cells − 1) at
    /// significance 0.001: the 0.999 quantile, 330.52, found by bisection on the regularized
    /// incomplete gamma function P(255/2, x/2); Wilson–Hilferty's approximation
    /// k·(1 − 2/(9k) + z·√(2/(9k)))³ with z = 3.0902 agrees (330.55).
    const CHI2_255_AT_0_001: f64 = 330.52;

    /// Slot → point after streaming points `0..n` through `r`, later points winning.
    fn reservoir_fill(r: &Reservoir, n: u64) -> Vec<u32> {
        let mut slots = vec![u32::MAX; r.capacity() as usize];
        for i in 0..n {
            if let Some(s) = r.slot(i) {
                assert!(s < r.capacity(), "point {i} goes to slot {s}");
                slots[s as usize] = i as u32;
            }
        }
        slots
    }

    #[test]
    fn a_reservoir_keeps_a_uniform_subset_of_everything_read() {
        // Chi-square with 9 degrees of freedom at significance 0.001: 27.877 (tables).
        const CHI2_9_AT_0_001: f64 = 27.877;
        let capacity = 20_000u64;
        for (seed, n) in [(1u64, 200_000u64), (2, 1_000_000), (3, 20_001)] {
            let r = Reservoir::new(capacity, seed).unwrap();
            let slots = reservoir_fill(&r, n);
            assert!(slots.iter().all(|&p| p != u32::MAX), "a slot stayed empty");
            // Each tenth of the input order should hold a tenth of the kept points.
            let mut deciles = [0u32; 10];
            for &p in &slots {
                deciles[(p as u64 * 10 / n) as usize] += 1;
            }
            let expected = capacity as f64 / 10.0;
            let chi: f64 = deciles
                .iter()
                .map(|&c| (c as f64 - expected).powi(2) / expected)
                .sum();
            assert!(
                chi < CHI2_9_AT_0_001,
                "seed {seed}, n {n}: χ² = {chi}, {deciles:?}"
            );
        }
        // Within capacity it is the plain permutation, and it is deterministic.
        let r = Reservoir::new(capacity, 9).unwrap();
        let perm = ShufflePermutation::new(capacity).unwrap();
        assert!((0..capacity).all(|i| r.slot(i) == Some(perm.target(i))));
        assert_eq!(reservoir_fill(&r, 100_000), reservoir_fill(&r, 100_000));
    }

    #[test]
    fn prefixes_of_a_reservoir_over_a_sorted_grid_are_uniform() {
        // The grid (row by row) is four times the buffer: the buffer keeps a quarter of it.
        let side = 1024u32;
        let n = (side * side) as u64;
        let r = Reservoir::new(n / 4, 5).unwrap();
        let slots = reservoir_fill(&r, n);
        for percent in [5, 25, 100] {
            let k = slots.len() * percent / 100;
            let chi = chi_square(&slots[..k], side);
            assert!(chi < CHI2_255_AT_0_001, "{percent} % prefix: χ² = {chi}");
        }
    }

    #[test]
    fn prefixes_of_a_shuffled_sorted_grid_are_uniform() {
        // A 1024 × 1024 grid scanned row by row: spatially sorted like a tiled scan.
        let side = 1024u32;
        let n = (side * side) as u64;
        let shuffled = placement(&ShufflePermutation::new(n).unwrap());
        let sorted: Vec<u32> = (0..n as u32).collect();
        for percent in [1, 5, 25] {
            let k = (n * percent / 100) as usize;
            let chi = chi_square(&shuffled[..k], side);
            assert!(chi < CHI2_255_AT_0_001, "{percent} % prefix: χ² = {chi}");
            let control = chi_square(&sorted[..k], side);
            assert!(
                control > CHI2_255_AT_0_001,
                "unshuffled {percent} % prefix: χ² = {control}"
            );
        }
    }

    #[test]
    fn interleaved_groups_are_bijections_for_every_size() {
        for group in [1u64, 2, 8, 64] {
            for n in 0..=3_000u64 {
                interleaved(&whole(n, group));
            }
        }
        for (n, group) in [(1_000_003u64, 4096u64), (1 << 22, 1024), (65_537, 65_536)] {
            interleaved(&whole(n, group));
        }
        assert_eq!(
            GroupRows::new(100, 48, 100),
            Err(ShuffleError::GroupSize { group: 48 })
        );
        assert_eq!(
            GroupRows::new(MAX_SLOTS + 1, 1024, u64::MAX),
            Err(ShuffleError::TooManySlots { n: MAX_SLOTS + 1 })
        );
        assert_eq!(
            GroupRows::new(1000, 64, 15),
            Err(ShuffleError::TooFewSlots {
                slots: 15,
                groups: 16
            })
        );
        assert_eq!(
            whole(1000, 64).chunked(63),
            Err(ShuffleError::ChunkTooSmall {
                chunk_slots: 63,
                rows: 64
            })
        );
    }

    #[test]
    fn chunks_keep_the_first_rows_of_whole_groups_and_place_each_once() {
        for (n, group, max_slots, chunk_slots) in [
            (3_000u64, 64u64, u64::MAX, 1_000u64),
            (3_000, 64, 1_000, 200),
            (3_001, 64, 2_000, 64),
            (65_536 * 3 + 5, 4096, u64::MAX, 70_000),
            (100_000, 256, 30_000, 5_000),
        ] {
            let order = GroupRows::new(n, group, max_slots).unwrap();
            let rows = order.rows();
            assert!(order.placed() <= max_slots.min(n));
            let chunked = order.chunked(chunk_slots).unwrap();
            assert_eq!(chunked.placed(), order.placed());
            let slots = interleaved(&chunked);
            // Kept: the first rows of every group, nothing else.
            for i in 0..n {
                let kept = chunked.target(i).is_some();
                assert_eq!(kept, i % group < rows, "n {n}: point {i}");
            }
            // Chunk c holds whole groups, from slot c × chunk_slots, filled without a gap.
            for c in 0..chunked.chunks() {
                let (first, chunk) = chunked.chunk(c).unwrap();
                let at = (c * chunk_slots) as usize;
                assert_eq!(chunked.chunk_span(c), at as u64..at as u64 + chunk.len());
                let filled = &slots[at..at + chunk.len() as usize];
                assert!(filled.iter().all(|&i| {
                    let g = i as u64 / group;
                    i != u32::MAX && (first..first + chunk.groups()).contains(&g)
                }));
                let end = (at + chunk_slots as usize).min(slots.len());
                assert!(slots[at + chunk.len() as usize..end]
                    .iter()
                    .all(|&i| i == u32::MAX));
            }
        }
    }

    #[test]
    fn whole_blocks_of_groups_land_in_one_run_per_row() {
        // 8 192 groups of 64 points, the last one short: blocks of 8 groups, 1 023 of them
        // permuted in each row (the shorter rows have 8 191 columns).
        let order = whole(64 * 8191 + 17, 64);
        let (_, chunk) = order.chunk(0).unwrap();
        assert_eq!((chunk.groups(), chunk.full_rows()), (8192, 17));
        assert_eq!((chunk.block_shift(), chunk.blocks().len()), (3, 1023));
        let target = |i| order.target(i).unwrap();
        let mut starts = Vec::new();
        for row in 0..64u64 {
            // Groups 40..48 are block 5: one run of 8 slots wherever the block went.
            let slots: Vec<u64> = (40..48).map(|g| target(g * 64 + row)).collect();
            let start = slots[0];
            assert_eq!(slots, (start..start + 8).collect::<Vec<_>>(), "row {row}");
            starts.push(start - target(row));
        }
        // The block moved, to the same column in every row.
        assert!(starts.iter().all(|&s| s == starts[0] && s != 40));
        // Small files permute single groups.
        assert_eq!(whole(64 * 40, 64).chunk(0).unwrap().1.block_shift(), 0);
    }

    /// A `side` × `side` grid scanned row by row, cut into groups of `group` points, each
    /// group shuffled as a store shuffles its pointlets (seeds from `seed`): the points in
    /// file order, and the slot → point index of their interleave.
    fn shuffled_groups_of_a_grid(side: u32, group: usize, seed: u64) -> (Vec<u32>, Vec<u32>) {
        let n = (side * side) as u64;
        let mut points: Vec<u32> = (0..n as u32).collect();
        for (k, g) in points.chunks_mut(group).enumerate() {
            crate::shuffle::shuffle(g, k as u64 ^ seed);
        }
        let slots = interleaved(&whole(n, group as u64));
        (points, slots)
    }

    #[test]
    fn prefixes_of_interleaved_shuffled_groups_of_a_sorted_grid_are_uniform() {
        // Groups of 4096 points: four grid rows each.
        let side = 1024u32;
        let n = (side * side) as u64;
        let (points, slots) = shuffled_groups_of_a_grid(side, 4096, 0);
        let buffer: Vec<u32> = slots.iter().map(|&i| points[i as usize]).collect();
        for percent in [1, 5, 25] {
            let k = (n * percent / 100) as usize;
            let chi = chi_square(&buffer[..k], side);
            assert!(chi < CHI2_255_AT_0_001, "{percent} % prefix: χ² = {chi}");
        }
        // Without the shuffle inside groups, prefixes hold the groups' first grid rows only.
        let control = chi_square(&slots[..(n / 100) as usize], side);
        assert!(control > CHI2_255_AT_0_001, "control: χ² = {control}");
    }

    #[test]
    fn the_same_share_of_every_chunk_is_uniform_where_a_prefix_is_not() {
        // 256 groups of 4096 points (four grid rows each) in four chunks of 64 groups: a chunk
        // is a quarter of the grid, top to bottom.
        let side = 1024u32;
        let group = 4096usize;
        let n = (side * side) as u64;
        let mut points: Vec<u32> = (0..n as u32).collect();
        for (k, g) in points.chunks_mut(group).enumerate() {
            crate::shuffle::shuffle(g, k as u64);
        }
        let order = whole(n, group as u64).chunked(64 * 4096).unwrap();
        assert_eq!(order.chunks(), 4);
        let slots = interleaved(&order);
        let buffer: Vec<u32> = slots.iter().map(|&i| points[i as usize]).collect();
        let chunk = 64 * group;
        for percent in [1, 5, 25] {
            let k = chunk * percent / 100;
            let shares: Vec<u32> = (0..4)
                .flat_map(|c| buffer[c * chunk..c * chunk + k].iter().copied())
                .collect();
            let chi = chi_square(&shares, side);
            assert!(
                chi < CHI2_255_AT_0_001,
                "{percent} % of each chunk: χ² = {chi}"
            );
            let prefix = chi_square(&buffer[..4 * k], side);
            assert!(
                prefix > CHI2_255_AT_0_001,
                "{percent} % prefix of the buffer: χ² = {prefix}"
            );
        }
    }

    #[test]
    fn prefixes_ending_inside_a_row_spread_over_the_whole_file() {
        // Groups of 64 points, 16 to a grid row: 16 384 groups in blocks of 16 (one grid
        // row each), 1 023 blocks permuted in a row. Half a row of slots and a prefix of
        // 1.5 rows must be uniform, which a row of groups in file order is not.
        let side = 1024u32;
        let n = (side * side) as u64;
        let group = 64usize;
        let order = whole(n, group as u64).chunk(0).unwrap().1;
        assert_eq!(order.block_shift(), 4);
        let (points, slots) = shuffled_groups_of_a_grid(side, group, 0x5eed);
        let buffer: Vec<u32> = slots.iter().map(|&i| points[i as usize]).collect();
        let row = order.groups() as usize;
        for k in [row / 2, row + row / 2] {
            let chi = chi_square(&buffer[..k], side);
            assert!(chi < CHI2_255_AT_0_001, "prefix of {k} slots: χ² = {chi}");
        }
        // Groups in file order within a row: the first half row covers the top half only.
        let unpermuted: Vec<u32> = (0..row / 2).map(|g| points[g * group]).collect();
        let control = chi_square(&unpermuted, side);
        assert!(control > CHI2_255_AT_0_001, "control: χ² = {control}");
    }
}
