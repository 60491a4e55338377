//! BYTE version 2: the extra bytes after the standard fields, each coded as its difference
//! (mod 256) from the same byte of the last point, with one model per byte position.

use super::arith::{Arith, ByteModel};

pub(super) struct Bytes {
    last: Box<[u8]>,
    models: Box<[ByteModel]>,
}

impl Bytes {
    pub fn new(count: usize) -> Self {
        Bytes {
            last: vec![0; count].into_boxed_slice(),
            models: vec![ByteModel::INIT; count].into_boxed_slice(),
        }
    }

    /// Starts a chunk whose first bytes (kept raw) are `first`.
    pub fn reset(&mut self, first: &[u8]) {
        for (l, f) in self.last.iter_mut().zip(first) {
            *l = *f;
        }
        self.models.fill(ByteModel::INIT);
    }

    #[inline(always)]
    pub fn decode(&mut self, ac: &mut Arith, out: &mut [u8]) {
        for ((l, m), o) in self.last.iter_mut().zip(self.models.iter_mut()).zip(out) {
            *l = l.wrapping_add(ac.symbol(m) as u8);
            *o = *l;
        }
    }
}
