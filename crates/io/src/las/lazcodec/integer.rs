//! LASzip's integer corrector: a value is sent as its difference `c` from a prediction.
//!
//! First comes `k`, the number of significant bits of `c` (a symbol of a model chosen by the
//! caller's context), then `c` itself within the 2^(k-1) values of that magnitude: for k = 0
//! one adaptive bit (c is 0 or 1), for k up to 8 one symbol of the model for that k, above that
//! the top 8 bits as a symbol and the rest as raw bits. For 16-bit fields the sum wraps around
//! 2^16; for 32-bit fields k = 32 stands for the most negative difference. `K` is the number
//! of k symbols (bits + 1) and `KT` its model's table size; `k` of the last value is kept,
//! since the point decoder derives later contexts from it.

use super::arith::{table_len, Arith, BitModel, ByteModel, Model};

/// Bits of `c` above which the lowest bits are sent raw.
const HIGH_BITS: u32 = 8;

pub(super) struct IntDecoder<const K: usize, const KT: usize> {
    /// The k model of each context.
    magnitude: Box<[Model<K, KT>]>,
    zero: BitModel,
    c1: Model<2, 0>,
    c2: Model<4, 0>,
    c3: Model<8, 0>,
    c4: Model<16, 0>,
    c5: Model<32, { table_len(32) }>,
    c6: Model<64, { table_len(64) }>,
    c7: Model<128, { table_len(128) }>,
    /// k = 8, 9, ... bits - 1 (k = 32 needs no model).
    high: Box<[ByteModel]>,
    k: u32,
}

/// Differences of 16-bit fields (intensity, point source id).
pub(super) type Int16 = IntDecoder<17, { table_len(17) }>;
/// Differences of 32-bit fields (coordinates, GPS time).
pub(super) type Int32 = IntDecoder<33, { table_len(33) }>;

impl<const K: usize, const KT: usize> IntDecoder<K, KT> {
    const BITS: u32 = K as u32 - 1;
    /// Values wrap around this (0: they do not wrap).
    const RANGE: i32 = if K == 33 { 0 } else { 1 << (K - 1) };

    pub fn new(contexts: usize) -> Self {
        const { assert!(K == 17 || K == 33) };
        let high = (Self::BITS.min(31) - HIGH_BITS + 1) as usize;
        IntDecoder {
            magnitude: vec![Model::INIT; contexts].into_boxed_slice(),
            zero: BitModel::INIT,
            c1: Model::INIT,
            c2: Model::INIT,
            c3: Model::INIT,
            c4: Model::INIT,
            c5: Model::INIT,
            c6: Model::INIT,
            c7: Model::INIT,
            high: vec![ByteModel::INIT; high].into_boxed_slice(),
            k: 0,
        }
    }

    /// Back to the state of a fresh decoder.
    pub fn reset(&mut self) {
        self.magnitude.fill(Model::INIT);
        self.zero = BitModel::INIT;
        self.c1 = Model::INIT;
        self.c2 = Model::INIT;
        self.c3 = Model::INIT;
        self.c4 = Model::INIT;
        self.c5 = Model::INIT;
        self.c6 = Model::INIT;
        self.c7 = Model::INIT;
        self.high.fill(ByteModel::INIT);
        self.k = 0;
    }

    /// The magnitude `k` of the last value decoded.
    #[inline(always)]
    pub fn k(&self) -> u32 {
        self.k
    }

    /// The value predicted as `pred`, in context `ctx` (below the context count given to
    /// [`Self::new`]). Not inlined: one copy per field width keeps the point loop small
    /// enough for the instruction cache.
    #[inline(never)]
    pub fn decode(&mut self, ac: &mut Arith, pred: i32, ctx: usize) -> i32 {
        let k = match self.magnitude.get_mut(ctx) {
            Some(m) => ac.symbol(m),
            None => 0,
        };
        self.k = k;
        let corr = if k == 0 {
            ac.bit(&mut self.zero) as i32
        } else if k < 32 {
            let c = match k {
                1 => ac.symbol(&mut self.c1),
                2 => ac.symbol(&mut self.c2),
                3 => ac.symbol(&mut self.c3),
                4 => ac.symbol(&mut self.c4),
                5 => ac.symbol(&mut self.c5),
                6 => ac.symbol(&mut self.c6),
                7 => ac.symbol(&mut self.c7),
                _ => {
                    let top = match self.high.get_mut((k - HIGH_BITS) as usize) {
                        Some(m) => ac.symbol(m),
                        None => 0,
                    };
                    if k > HIGH_BITS {
                        let low = k - HIGH_BITS;
                        (top << low) | ac.bits(low)
                    } else {
                        top
                    }
                }
            } as i32;
            // c counts the values of magnitude k: the upper half are positive (from
            // 2^(k-1) + 1), the lower half negative (from -(2^k - 1)). The sign is as random
            // as the data, so it is arithmetic rather than a branch.
            let negative = (c as u32) < 1u32 << (k - 1);
            (c as u32)
                .wrapping_add(1)
                .wrapping_sub(u32::from(negative) << k) as i32
        } else {
            i32::MIN
        };
        let real = pred.wrapping_add(corr);
        if Self::RANGE == 0 {
            real
        } else if real < 0 {
            real.wrapping_add(Self::RANGE)
        } else if real >= Self::RANGE {
            real.wrapping_sub(Self::RANGE)
        } else {
            real
        }
    }
}
