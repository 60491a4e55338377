//! RGB12 version 2: three 16-bit colour channels.
//!
//! A 7-bit symbol says which of the six bytes (low and high byte of red, green, blue) changed
//! since the last point, and whether the colour is grey (all channels equal). Red's changed
//! bytes are differences from the last red. Green is predicted as its last value moved by
//! red's change, blue by the mean of red's and green's changes (clamped to a byte); only
//! the corrections are coded, each byte position with its own model.

use super::arith::{table_len, Arith, ByteModel, Model};

pub(super) struct Rgb {
    last: [u16; 3],
    used: Model<128, { table_len(128) }>,
    /// Low and high byte models of red, green and blue: `[channel * 2 + high]`.
    bytes: [ByteModel; 6],
}

fn lo(v: u16) -> i32 {
    i32::from(v & 0xFF)
}

fn hi(v: u16) -> i32 {
    i32::from(v >> 8)
}

/// `prediction + correction` within a byte, the prediction clamped to 0–255 first.
#[inline(always)]
fn corrected(correction: u32, prediction: i32) -> u16 {
    u16::from((correction as u8).wrapping_add(prediction.clamp(0, 255) as u8))
}

impl Rgb {
    pub const LEN: usize = 6;

    pub fn new() -> Self {
        Rgb {
            last: [0; 3],
            used: Model::INIT,
            bytes: std::array::from_fn(|_| ByteModel::INIT),
        }
    }

    /// Starts a chunk whose first colour (kept raw) is `first`.
    pub fn reset(&mut self, first: &[u8; Self::LEN]) {
        self.last = [
            u16::from_le_bytes([first[0], first[1]]),
            u16::from_le_bytes([first[2], first[3]]),
            u16::from_le_bytes([first[4], first[5]]),
        ];
        self.used = Model::INIT;
        self.bytes.fill(ByteModel::INIT);
    }

    #[inline(always)]
    pub fn decode(&mut self, ac: &mut Arith, out: &mut [u8; Self::LEN]) {
        let used = ac.symbol(&mut self.used);
        let [lr, lg, lb] = self.last;
        let mut red = if used & 1 != 0 {
            corrected(ac.symbol(&mut self.bytes[0]), lo(lr))
        } else {
            lr & 0xFF
        };
        red |= if used & 2 != 0 {
            corrected(ac.symbol(&mut self.bytes[1]), hi(lr)) << 8
        } else {
            lr & 0xFF00
        };
        let (green, blue);
        if used & 64 != 0 {
            let d = lo(red) - lo(lr);
            let mut g = if used & 4 != 0 {
                corrected(ac.symbol(&mut self.bytes[2]), d + lo(lg))
            } else {
                lg & 0xFF
            };
            let mut b = if used & 16 != 0 {
                let d = (d + lo(g) - lo(lg)) / 2;
                corrected(ac.symbol(&mut self.bytes[4]), d + lo(lb))
            } else {
                lb & 0xFF
            };
            let d = hi(red) - hi(lr);
            g |= if used & 8 != 0 {
                corrected(ac.symbol(&mut self.bytes[3]), d + hi(lg)) << 8
            } else {
                lg & 0xFF00
            };
            b |= if used & 32 != 0 {
                let d = (d + hi(g) - hi(lg)) / 2;
                corrected(ac.symbol(&mut self.bytes[5]), d + hi(lb)) << 8
            } else {
                lb & 0xFF00
            };
            (green, blue) = (g, b);
        } else {
            (green, blue) = (red, red);
        }
        self.last = [red, green, blue];
        out[0..2].copy_from_slice(&red.to_le_bytes());
        out[2..4].copy_from_slice(&green.to_le_bytes());
        out[4..6].copy_from_slice(&blue.to_le_bytes());
    }
}
