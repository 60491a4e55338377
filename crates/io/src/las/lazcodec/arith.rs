//! The adaptive range decoder of LASzip, reading straight from a chunk's bytes.
//!
//! The decoder keeps a 32-bit `value` (where the code lies) and `length` (how wide the current
//! interval is); each decision narrows the interval and, once it is shorter than 2^24, shifts
//! in the 1–3 bytes that make it long enough again (at once, without a branch). Symbols come
//! from adaptive frequency models: [`BitModel`] for binary decisions, [`Model`] for alphabets
//! of `N` symbols, whose cumulative distribution (scaled to 2^15) is recomputed after a
//! growing number of decoded symbols (the update cycle), exactly as LASzip does. The decoded
//! symbol is the last whose cumulative count is at most `value / (length >> 15)`. Models of
//! more than 16 symbols find it through our own table (`T` entries, finer than LASzip's),
//! which gives the symbol at the start of the quotient's cell together with its interval: the
//! quotient lies in that symbol or, past a boundary inside the cell, nearly always in the next,
//! which is chosen without a branch, so that the usual decode is one division, two loads and
//! two multiplications; only beyond the next symbol does it step on through the distribution.
//! Smaller models search by bisection with multiplications only.
//! Any search for that symbol gives the one LASzip's encoder wrote.
//!
//! Reading past the end of the bytes yields zeros and moves the position on regardless, so
//! [`Arith::overrun`] tells the caller, once per point, that the chunk was too short. Every
//! operation uses wrapping arithmetic and clamped table indices, so damaged bytes decode to
//! garbage but can never panic, divide by zero or loop forever.

/// Bits of the interval length dropped before multiplying with a symbol model's distribution.
const SYMBOL_SHIFT: u32 = 15;
/// A symbol model's counts are halved once they sum to more than this.
const SYMBOL_MAX_TOTAL: u32 = 1 << SYMBOL_SHIFT;
/// Bits of the interval length dropped before multiplying with a bit model's probability.
const BIT_SHIFT: u32 = 13;
/// A bit model's counts are halved once they exceed this.
const BIT_MAX_TOTAL: u32 = 1 << BIT_SHIFT;

/// The range decoder over one chunk's compressed bytes.
pub(super) struct Arith<'a> {
    data: &'a [u8],
    /// Next byte to read; beyond `data.len()` once the decoder ran past the end.
    pos: usize,
    value: u32,
    length: u32,
}

impl<'a> Arith<'a> {
    /// Starts decoding at the first byte of `data`: the first four bytes seed the value.
    pub fn new(data: &'a [u8]) -> Self {
        let mut a = Arith {
            data,
            pos: 0,
            value: 0,
            length: u32::MAX,
        };
        a.value = a.peek4();
        a.pos = 4;
        a
    }

    /// The decoder needed bytes beyond the end of the chunk.
    #[inline(always)]
    pub fn overrun(&self) -> bool {
        self.pos > self.data.len()
    }

    /// Shifts in as many bytes (0–3) as bring the length back to at least 2^24, without a
    /// branch: whether a decision needs more bytes is as random as the data.
    #[inline(always)]
    fn renorm(&mut self) {
        // A length of zero cannot arise (every decision leaves at least one unit); were it to,
        // the 64-bit shifts stay in range and the divisions check for zero.
        let shift = self.length.leading_zeros() & !7;
        // Value and next bytes joined before the shift amount is known: one shift after it.
        let window = (u64::from(self.value) << 32) | u64::from(self.peek4());
        self.value = ((window << shift) >> 32) as u32;
        self.length = (u64::from(self.length) << shift) as u32;
        self.pos += (shift / 8) as usize;
    }

    /// The next four bytes, big-endian, zeros past the end.
    #[inline(always)]
    fn peek4(&self) -> u32 {
        match self.data.get(self.pos..self.pos + 4) {
            Some(&[a, b, c, d]) => u32::from_be_bytes([a, b, c, d]),
            _ => self.peek4_at_end(),
        }
    }

    #[cold]
    #[inline(never)]
    fn peek4_at_end(&self) -> u32 {
        let mut v = 0;
        for k in 0..4 {
            v = (v << 8) | u32::from(self.data.get(self.pos + k).copied().unwrap_or(0));
        }
        v
    }

    /// One binary decision with an adaptive bit model.
    #[inline(always)]
    pub fn bit(&mut self, m: &mut BitModel) -> u32 {
        let x = m.prob.wrapping_mul(self.length >> BIT_SHIFT);
        // Selects, not a branch: the bit is as random as the data.
        let bit = self.value >= x;
        self.value = self.value.wrapping_sub(if bit { x } else { 0 });
        self.length = if bit { self.length.wrapping_sub(x) } else { x };
        m.zeros += u32::from(!bit);
        self.renorm();
        m.until -= 1;
        if m.until == 0 {
            m.update();
        }
        u32::from(bit)
    }

    /// One symbol of an adaptive model.
    #[inline(always)]
    pub fn symbol<const N: usize, const T: usize>(&mut self, m: &mut Model<N, T>) -> u32 {
        let full = self.length;
        let unit = self.length >> SYMBOL_SHIFT;
        // The symbol, where its interval starts and how long it is.
        let (sym, x, len);
        if T > 0 {
            // The symbol is the last whose cumulative count is at most `dv`: the table gives
            // the symbol at the start of dv's cell with its interval. A boundary inside the
            // cell lies at or below dv as often as not when symbols are about as likely as
            // each other (noisy intensities and colours), so the next symbol is chosen without
            // a branch, which mispredicted on a fifth of all table decodes.
            let dv = self.value.checked_div(unit).unwrap_or(0);
            let cell = (dv >> Model::<N, T>::SHIFT) as usize;
            // A branch, not a clamp: only damaged data goes beyond the table.
            let entry = match m.table.get(cell) {
                Some(&e) => e,
                None => m.top_entry(),
            };
            let (first, start, end) = unpack(entry);
            let after = m.end(first + 1);
            if dv < after {
                let in_first = dv < end;
                sym = if in_first { first } else { first + 1 };
                let (lo, hi) = if in_first { (start, end) } else { (end, after) };
                x = lo.wrapping_mul(unit);
                // The last symbol also takes the rest of the length that `unit` rounds off.
                len = if sym + 1 < N {
                    hi.wrapping_mul(unit)
                } else {
                    full
                }
                .wrapping_sub(x);
            } else {
                let mut s = first + 2;
                let mut next = m.end(s);
                while next <= dv {
                    s += 1;
                    next = m.end(s);
                }
                x = u32::from(m.dist[s]).wrapping_mul(unit);
                len = if s + 1 < N {
                    next.wrapping_mul(unit)
                } else {
                    full
                }
                .wrapping_sub(x);
                sym = s;
            }
        } else {
            let (mut s, mut n, mut lo, mut hi) = (0usize, N, 0u32, full);
            let mut k = N >> 1;
            loop {
                let z = unit.wrapping_mul(u32::from(m.dist[k]));
                if z > self.value {
                    n = k;
                    hi = z;
                } else {
                    s = k;
                    lo = z;
                }
                k = (s + n) >> 1;
                if k == s {
                    break;
                }
            }
            (sym, x, len) = (s, lo, hi.wrapping_sub(lo));
        }
        self.value = self.value.wrapping_sub(x);
        self.length = len;
        self.renorm();
        m.count[sym] += 1;
        m.until -= 1;
        if m.until == 0 {
            m.update();
        }
        sym as u32
    }

    /// `bits` (1–32) raw bits, low bits first for more than 19.
    #[inline(always)]
    pub fn bits(&mut self, bits: u32) -> u32 {
        if bits > 19 {
            let low = self.raw(16);
            let high = self.raw(bits - 16);
            (high << 16) | low
        } else {
            self.raw(bits)
        }
    }

    /// Up to 19 raw bits in one step.
    #[inline(always)]
    fn raw(&mut self, bits: u32) -> u32 {
        self.length >>= bits;
        let sym = self.value.checked_div(self.length).unwrap_or(0);
        self.value = self.value.wrapping_sub(self.length.wrapping_mul(sym));
        self.renorm();
        sym
    }

    /// A raw 32-bit integer: low half first.
    pub fn int(&mut self) -> u32 {
        let low = self.raw(16);
        let high = self.raw(16);
        (high << 16) | low
    }
}

/// An adaptive model of a binary decision.
#[derive(Clone, Copy, Debug)]
pub(super) struct BitModel {
    zeros: u32,
    total: u32,
    /// Probability of a zero, scaled to 2^13.
    prob: u32,
    until: u32,
    cycle: u32,
}

impl BitModel {
    pub const INIT: BitModel = BitModel {
        zeros: 1,
        total: 2,
        prob: 1 << (BIT_SHIFT - 1),
        until: 4,
        cycle: 4,
    };

    #[inline(never)]
    fn update(&mut self) {
        self.total += self.cycle;
        if self.total > BIT_MAX_TOTAL {
            self.total = (self.total + 1) >> 1;
            self.zeros = (self.zeros + 1) >> 1;
            if self.zeros == self.total {
                self.total += 1;
            }
        }
        let scale = 0x8000_0000u32 / self.total;
        self.prob = (self.zeros * scale) >> (31 - BIT_SHIFT);
        self.cycle = ((5 * self.cycle) >> 2).min(64);
        self.until = self.cycle;
    }
}

/// Bits of the decoding table of a model of `n` symbols: fine enough that a cell rarely holds
/// the boundary between two likely symbols (models of 16 or fewer have none).
const fn table_bits(n: usize) -> u32 {
    if n <= 64 {
        6
    } else if n <= 256 {
        8
    } else {
        9
    }
}

/// Entries of the decoding table of a model of `n` symbols: one per cell and one for the
/// values at and beyond the top of the distribution.
pub(super) const fn table_len(n: usize) -> usize {
    if n <= 16 {
        0
    } else {
        (1 << table_bits(n)) + 1
    }
}

/// An adaptive model of `N` symbols with a decoding table of `T` entries (`table_len(N)`).
#[derive(Clone, Debug)]
pub(super) struct Model<const N: usize, const T: usize> {
    /// Cumulative distribution, scaled to 2^15.
    dist: [u16; N],
    /// Symbol counts: at most 2^15 plus one update cycle, as the counts are halved when
    /// their sum passes 2^15.
    count: [u16; N],
    /// The symbol at the start of each cell of 2^15 >> table_bits(N) distribution values,
    /// with its interval: see [`pack`].
    table: [u64; T],
    total: u32,
    cycle: u32,
    until: u32,
}

impl<const N: usize, const T: usize> Model<N, T> {
    const SHIFT: u32 = SYMBOL_SHIFT - table_bits(N);

    /// A fresh model: every symbol equally likely.
    pub const INIT: Self = Self::fresh();

    const fn fresh() -> Self {
        assert!(N >= 2 && N <= 2048 && T == table_len(N));
        let mut m = Model {
            dist: [0; N],
            count: [1; N],
            table: [0; T],
            total: 0,
            cycle: N as u32,
            until: 0,
        };
        m.update();
        m.cycle = (N as u32 + 6) >> 1;
        m.until = m.cycle;
        m
    }

    /// Where the interval of symbol `s` ends: the next one's start, beyond every quotient for
    /// the last.
    #[inline(always)]
    fn end(&self, s: usize) -> u32 {
        match self.dist.get(s + 1) {
            Some(&d) => u32::from(d),
            None => u32::MAX,
        }
    }

    /// The table entry of the quotients beyond the table, which only damaged data gives.
    #[cold]
    #[inline(never)]
    fn top_entry(&self) -> u64 {
        self.table.last().copied().unwrap_or(0)
    }

    #[inline(never)]
    const fn update(&mut self) {
        self.total += self.cycle;
        if self.total > SYMBOL_MAX_TOTAL {
            self.total = 0;
            let mut k = 0;
            while k < N {
                self.count[k] = self.count[k].div_ceil(2);
                self.total += self.count[k] as u32;
                k += 1;
            }
        }
        let scale = 0x8000_0000u32 / self.total;
        let (mut sum, mut k) = (0u32, 0usize);
        while k < N {
            self.dist[k] = ((scale * sum) >> (31 - SYMBOL_SHIFT)) as u16;
            sum += self.count[k] as u32;
            k += 1;
        }
        if T > 0 {
            // Cell c holds the last symbol whose distribution starts at or before c << SHIFT:
            // each symbol marks the cell it starts in (a later one overwrites an earlier), and
            // a running maximum over the cells fills the rest, without a branch on the data.
            let mut cell = 0;
            while cell < T {
                self.table[cell] = 0;
                cell += 1;
            }
            let mut k = 1;
            while k < N {
                let first = (self.dist[k] as usize + (1 << Self::SHIFT) - 1) >> Self::SHIFT;
                self.table[first] = k as u64;
                k += 1;
            }
            let (mut cell, mut sym) = (0, 0);
            while cell < T {
                let marked = self.table[cell] as usize;
                sym = if marked > sym { marked } else { sym };
                let end = if sym + 1 < N {
                    self.dist[sym + 1] as u32
                } else {
                    u32::MAX
                };
                self.table[cell] = pack(sym, self.dist[sym], end);
                cell += 1;
            }
        }
        let most = (N as u32 + 6) << 3;
        self.cycle = (5 * self.cycle) >> 2;
        if self.cycle > most {
            self.cycle = most;
        }
        self.until = self.cycle;
    }
}

/// A table entry: where a symbol's interval ends (low 32 bits, beyond every quotient for the
/// last symbol), where it starts (next 16) and the symbol (top 16): one load gives all a
/// decode needs.
const fn pack(sym: usize, start: u16, end: u32) -> u64 {
    end as u64 | (start as u64) << 32 | (sym as u64) << 48
}

/// The symbol, start and end of a table entry.
#[inline(always)]
fn unpack(entry: u64) -> (usize, u32, u32) {
    (
        (entry >> 48) as usize,
        ((entry >> 32) & 0xFFFF) as u32,
        entry as u32,
    )
}

/// The models of 256 symbols that most contexts use.
pub(super) type ByteModel = Model<256, { table_len(256) }>;
