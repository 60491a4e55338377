//! GPSTIME11 version 2: the 8-byte GPS time (a double, handled as its 64-bit pattern).
//!
//! Four time sequences are tracked at once (interleaved flight lines or scanners), each with
//! its last time and last 32-bit step. While a sequence has no step yet, a point says whether
//! its time is unchanged, one 32-bit step away (which becomes the sequence's step), a new
//! sequence (upper half through the integer corrector, lower half raw), or a switch to one of
//! the other three sequences. Once it has a step, the point's time is predicted as a multiple
//! of it (-10 to 500 times, the multiple itself a symbol), with the rest through the integer
//! corrector in a context for the kind of multiple; repeated extreme multiples replace the
//! step. A switch re-decodes the same point in the other sequence; valid data switches at
//! most once per point, so more than [`MAX_SWITCHES`] marks the chunk damaged.

use super::arith::{table_len, Arith, Model};
use super::integer::Int32;

/// Multiples of the step that have their own symbol: 1 to `MULTI`, -1 to `MULTI_MINUS`.
const MULTI: i32 = 500;
const MULTI_MINUS: i32 = -10;
/// Symbols after the multiples: the time is unchanged; a new sequence; switches (3).
const MULTI_UNCHANGED: u32 = (MULTI - MULTI_MINUS + 1) as u32;
const MULTI_NEW: u32 = MULTI_UNCHANGED + 1;
const MULTI_SYMBOLS: usize = (MULTI - MULTI_MINUS + 6) as usize;
/// Sequence switches one point may make before the chunk counts as damaged.
const MAX_SWITCHES: u32 = 3;

pub(super) struct Gps {
    multi: Model<MULTI_SYMBOLS, { table_len(MULTI_SYMBOLS) }>,
    no_step: Model<6, 0>,
    ic: Int32,
    last: usize,
    next: usize,
    times: [i64; 4],
    steps: [i32; 4],
    extremes: [i32; 4],
}

impl Gps {
    pub const LEN: usize = 8;

    pub fn new() -> Self {
        Gps {
            multi: Model::INIT,
            no_step: Model::INIT,
            ic: Int32::new(9),
            last: 0,
            next: 0,
            times: [0; 4],
            steps: [0; 4],
            extremes: [0; 4],
        }
    }

    /// Starts a chunk whose first time (kept raw) is `first`.
    pub fn reset(&mut self, first: &[u8; Self::LEN]) {
        self.multi = Model::INIT;
        self.no_step = Model::INIT;
        self.ic.reset();
        self.last = 0;
        self.next = 0;
        self.times = [i64::from_le_bytes(*first), 0, 0, 0];
        self.steps = [0; 4];
        self.extremes = [0; 4];
    }

    /// Decodes the next time into `out`; false when the data switched sequences too often.
    #[inline(never)]
    pub fn decode(&mut self, ac: &mut Arith, out: &mut [u8; Self::LEN]) -> bool {
        let mut switches = 0;
        while let Some(to) = self.step(ac) {
            switches += 1;
            if switches > MAX_SWITCHES {
                return false;
            }
            self.last = (self.last + to) & 3;
        }
        *out = self.times[self.last & 3].to_le_bytes();
        true
    }

    /// Decodes one time in the current sequence, or returns the switch to another one.
    fn step(&mut self, ac: &mut Arith) -> Option<usize> {
        let last = self.last & 3;
        if self.steps[last] == 0 {
            match ac.symbol(&mut self.no_step) {
                0 => {}
                1 => {
                    let d = self.ic.decode(ac, 0, 0);
                    self.steps[last] = d;
                    self.times[last] = self.times[last].wrapping_add(i64::from(d));
                    self.extremes[last] = 0;
                }
                2 => self.new_sequence(ac),
                s => return Some(s as usize - 2),
            }
            return None;
        }
        let multi = ac.symbol(&mut self.multi);
        let step = self.steps[last];
        if multi == 1 {
            let d = self.ic.decode(ac, step, 1);
            self.times[last] = self.times[last].wrapping_add(i64::from(d));
            self.extremes[last] = 0;
        } else if multi < MULTI_UNCHANGED {
            let multi = multi as i32;
            let (d, extreme) = if multi == 0 {
                (self.ic.decode(ac, 0, 7), true)
            } else if multi < MULTI {
                let ctx = if multi < 10 { 2 } else { 3 };
                (self.ic.decode(ac, multi.wrapping_mul(step), ctx), false)
            } else if multi == MULTI {
                (self.ic.decode(ac, multi.wrapping_mul(step), 4), true)
            } else {
                let multi = MULTI - multi;
                if multi > MULTI_MINUS {
                    (self.ic.decode(ac, multi.wrapping_mul(step), 5), false)
                } else {
                    let pred = MULTI_MINUS.wrapping_mul(step);
                    (self.ic.decode(ac, pred, 6), true)
                }
            };
            if extreme {
                self.extremes[last] += 1;
                if self.extremes[last] > 3 {
                    self.steps[last] = d;
                    self.extremes[last] = 0;
                }
            }
            self.times[last] = self.times[last].wrapping_add(i64::from(d));
        } else if multi == MULTI_NEW {
            self.new_sequence(ac);
        } else if multi > MULTI_NEW {
            return Some((multi - MULTI_NEW) as usize);
        }
        None
    }

    /// A time far from the current one starts the next of the four sequences.
    fn new_sequence(&mut self, ac: &mut Arith) {
        let last = self.last & 3;
        let next = (self.next + 1) & 3;
        let high = self.ic.decode(ac, (self.times[last] >> 32) as i32, 8);
        let low = ac.int();
        self.times[next] = (i64::from(high) << 32) | i64::from(low);
        self.next = next;
        self.last = next;
        self.steps[next] = 0;
        self.extremes[next] = 0;
    }
}
