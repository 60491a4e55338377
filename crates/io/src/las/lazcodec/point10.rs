//! POINT10 version 2: the 20 bytes every format 0–5 record begins with.
//!
//! A point starts with a 6-bit mask of which non-coordinate fields changed since the last one
//! (return/flag byte, intensity, classification, scan angle, user data, point source id).
//! Changed bytes are decoded with a model chosen by their previous value; the scan angle as a
//! difference; intensity and point source id through the integer corrector. Return number
//! `r` and return count `n` pick the contexts: `m` (a table of the (n, r) pairs) selects the
//! intensity kept for that kind of return and the running medians of the x and y steps, from
//! which dx and dy are predicted; `|n - r|` selects the last z of that return level. The
//! contexts of dy and z also depend on the magnitudes of the differences decoded just before.
//!
//! The models of the byte fields are indexed by the previous byte (256 each) and created
//! lazily in each chunk, as most are never used.

use super::arith::{table_len, Arith, ByteModel, Model};
use super::integer::{Int16, Int32};

/// The context `m` of each (return count, return number) pair, as LASzip defines it.
const RETURN_MAP: [[u8; 8]; 8] = [
    [15, 14, 13, 12, 11, 10, 9, 8],
    [14, 0, 1, 3, 6, 10, 10, 9],
    [13, 1, 2, 4, 7, 11, 11, 10],
    [12, 3, 4, 5, 8, 12, 12, 11],
    [11, 6, 7, 8, 9, 13, 13, 12],
    [10, 10, 11, 12, 13, 14, 14, 13],
    [9, 10, 11, 12, 13, 14, 15, 14],
    [8, 9, 10, 11, 12, 13, 14, 15],
];

/// The median of the last five values, kept sorted and updated in place.
#[derive(Clone, Copy, Default)]
struct Median5 {
    v: [i32; 5],
    /// The next value replaces from the top (after a low insert) or from the bottom.
    low_next: bool,
}

impl Median5 {
    #[inline(always)]
    fn get(&self) -> i32 {
        self.v[2]
    }

    /// Puts `x` in, dropping the largest value or the smallest by turns: the largest until a
    /// value lands at or above the median, then the smallest until one lands at or below it.
    /// Selects, not branches: where `x` lands is as random as the data.
    #[inline(always)]
    fn add(&mut self, x: i32) {
        let v = self.v;
        // The four that stay, in order; `x` goes in among them.
        let o = usize::from(self.low_next);
        let keep = [v[o], v[1 + o], v[2 + o], v[3 + o]];
        self.v = [
            keep[0].min(x),
            keep[0].max(keep[1].min(x)),
            keep[1].max(keep[2].min(x)),
            keep[2].max(keep[3].min(x)),
            keep[3].max(x),
        ];
        self.low_next = (x > v[2]) | ((x == v[2]) & !self.low_next);
    }
}

/// 256 models indexed by a previous byte, each made fresh on its first use in a chunk. Only
/// the contexts a chunk uses take memory (files use a few), kept from chunk to chunk.
struct ByteContexts {
    /// Where each context's model is in `models`; [`NO_MODEL`] before its first use.
    slot: [u16; 256],
    models: Vec<ByteModel>,
}

const NO_MODEL: u16 = u16::MAX;

impl ByteContexts {
    fn new() -> Self {
        ByteContexts {
            slot: [NO_MODEL; 256],
            models: Vec::new(),
        }
    }

    /// Forgets every context's model (the memory stays for the next chunk).
    fn reset(&mut self) {
        self.slot = [NO_MODEL; 256];
        self.models.clear();
    }

    #[inline(always)]
    fn decode(&mut self, ac: &mut Arith, ctx: u8) -> u8 {
        let ctx = usize::from(ctx);
        if self.slot[ctx] == NO_MODEL {
            self.slot[ctx] = self.models.len() as u16;
            self.models.push(ByteModel::INIT);
        }
        match self.models.get_mut(usize::from(self.slot[ctx])) {
            Some(m) => ac.symbol(m) as u8,
            None => 0,
        }
    }
}

pub(super) struct Point10 {
    x: i32,
    y: i32,
    z: i32,
    intensity: u16,
    /// Return number, return count, scan direction and edge flags.
    returns: u8,
    classification: u8,
    scan_angle: u8,
    user_data: u8,
    source_id: u16,
    last_intensity: [u16; 16],
    x_median: [Median5; 16],
    y_median: [Median5; 16],
    last_z: [i32; 8],
    changed: Model<64, { table_len(64) }>,
    scan_angle_step: [ByteModel; 2],
    returns_byte: ByteContexts,
    classification_byte: ByteContexts,
    user_byte: ByteContexts,
    ic_intensity: Int16,
    ic_source_id: Int16,
    ic_dx: Int32,
    ic_dy: Int32,
    ic_z: Int32,
}

impl Point10 {
    pub const LEN: usize = 20;

    pub fn new() -> Self {
        Point10 {
            x: 0,
            y: 0,
            z: 0,
            intensity: 0,
            returns: 0,
            classification: 0,
            scan_angle: 0,
            user_data: 0,
            source_id: 0,
            last_intensity: [0; 16],
            x_median: [Median5::default(); 16],
            y_median: [Median5::default(); 16],
            last_z: [0; 8],
            changed: Model::INIT,
            scan_angle_step: [ByteModel::INIT, ByteModel::INIT],
            returns_byte: ByteContexts::new(),
            classification_byte: ByteContexts::new(),
            user_byte: ByteContexts::new(),
            ic_intensity: Int16::new(4),
            ic_source_id: Int16::new(1),
            ic_dx: Int32::new(2),
            ic_dy: Int32::new(22),
            ic_z: Int32::new(20),
        }
    }

    /// Starts a chunk whose first record (kept raw) is `first`.
    pub fn reset(&mut self, first: &[u8; Self::LEN]) {
        let i32_at =
            |a: usize| i32::from_le_bytes([first[a], first[a + 1], first[a + 2], first[a + 3]]);
        self.x = i32_at(0);
        self.y = i32_at(4);
        self.z = i32_at(8);
        // LASzip does not carry the first intensity over: the next point's is predicted from 0.
        self.intensity = 0;
        self.returns = first[14];
        self.classification = first[15];
        self.scan_angle = first[16];
        self.user_data = first[17];
        self.source_id = u16::from_le_bytes([first[18], first[19]]);
        self.last_intensity = [0; 16];
        self.x_median = [Median5::default(); 16];
        self.y_median = [Median5::default(); 16];
        self.last_z = [0; 8];
        self.changed = Model::INIT;
        self.scan_angle_step = [ByteModel::INIT, ByteModel::INIT];
        self.returns_byte.reset();
        self.classification_byte.reset();
        self.user_byte.reset();
        self.ic_intensity.reset();
        self.ic_source_id.reset();
        self.ic_dx.reset();
        self.ic_dy.reset();
        self.ic_z.reset();
    }

    #[inline(always)]
    pub fn decode(&mut self, ac: &mut Arith, out: &mut [u8; Self::LEN]) {
        let changed = ac.symbol(&mut self.changed);
        if changed != 0 {
            if changed & 32 != 0 {
                self.returns = self.returns_byte.decode(ac, self.returns);
            }
            let (r, n) = (self.returns & 7, (self.returns >> 3) & 7);
            let m = usize::from(RETURN_MAP[usize::from(n)][usize::from(r)]);
            if changed & 16 != 0 {
                let pred = i32::from(self.last_intensity[m]);
                self.intensity = self.ic_intensity.decode(ac, pred, m.min(3)) as u16;
                self.last_intensity[m] = self.intensity;
            } else {
                self.intensity = self.last_intensity[m];
            }
            if changed & 8 != 0 {
                self.classification = self.classification_byte.decode(ac, self.classification);
            }
            if changed & 4 != 0 {
                let dir = usize::from((self.returns >> 6) & 1);
                let step = ac.symbol(&mut self.scan_angle_step[dir]) as u8;
                self.scan_angle = self.scan_angle.wrapping_add(step);
            }
            if changed & 2 != 0 {
                self.user_data = self.user_byte.decode(ac, self.user_data);
            }
            if changed & 1 != 0 {
                self.source_id = self.ic_source_id.decode(ac, i32::from(self.source_id), 0) as u16;
            }
        }
        let (r, n) = (self.returns & 7, (self.returns >> 3) & 7);
        let m = usize::from(RETURN_MAP[usize::from(n)][usize::from(r)]);
        let level = usize::from(n.abs_diff(r));
        let single = usize::from(n == 1);

        let dx = self.ic_dx.decode(ac, self.x_median[m].get(), single);
        self.x = self.x.wrapping_add(dx);
        self.x_median[m].add(dx);

        let kx = self.ic_dx.k();
        let ctx = single + if kx < 20 { (kx & !1) as usize } else { 20 };
        let dy = self.ic_dy.decode(ac, self.y_median[m].get(), ctx);
        self.y = self.y.wrapping_add(dy);
        self.y_median[m].add(dy);

        let kxy = (kx + self.ic_dy.k()) / 2;
        let ctx = single + if kxy < 18 { (kxy & !1) as usize } else { 18 };
        self.z = self.ic_z.decode(ac, self.last_z[level], ctx);
        self.last_z[level] = self.z;

        out[0..4].copy_from_slice(&self.x.to_le_bytes());
        out[4..8].copy_from_slice(&self.y.to_le_bytes());
        out[8..12].copy_from_slice(&self.z.to_le_bytes());
        out[12..14].copy_from_slice(&self.intensity.to_le_bytes());
        out[14] = self.returns;
        out[15] = self.classification;
        out[16] = self.scan_angle;
        out[17] = self.user_data;
        out[18..20].copy_from_slice(&self.source_id.to_le_bytes());
    }
}
