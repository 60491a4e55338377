//! Which prefix of each pointlet's shuffled points sits in which GPU page slot, for the
//! browser: the LoD's requests become fetches of the missing pages, and pages of pointlets
//! nobody asks for any more make room when the pool is full. Only one fetch per pointlet is
//! in flight, so its window grows in order. Pure bookkeeping: no GPU, no network.

use crate::ranges::PointRange;

/// One pointlet's fetch: points `points` into `slots` (one per page, in page order).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Load {
    pub range: PointRange,
    pub slots: Vec<u32>,
}

/// What the GPU must be told after a plan: pointlets whose windows shrank.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Plan {
    pub loads: Vec<Load>,
    /// Pointlets whose resident prefix got shorter (evicted pages): republish their window.
    pub shrunk: Vec<usize>,
}

#[derive(Clone, Debug)]
pub struct Residency {
    page_size: u32,
    counts: Vec<u32>,
    /// Points resident: a prefix `0..resident[i]`.
    resident: Vec<u32>,
    /// Slots of the resident pages and of pages being fetched, in page order.
    slots: Vec<Vec<u32>>,
    /// End of the fetch in flight (0 when none).
    loading: Vec<u32>,
    /// Last feedback frame that requested points of the pointlet.
    wanted_at: Vec<u64>,
    free: Vec<u32>,
}

impl Residency {
    pub fn new(counts: Vec<u32>, slots: u32, page_size: u32) -> Self {
        let n = counts.len();
        Self {
            page_size: page_size.max(1),
            counts,
            resident: vec![0; n],
            slots: vec![Vec::new(); n],
            loading: vec![0; n],
            wanted_at: vec![0; n],
            free: (0..slots).rev().collect(),
        }
    }

    pub fn resident(&self, i: usize) -> u32 {
        self.resident.get(i).copied().unwrap_or(0)
    }

    /// Slots of pointlet `i`'s resident pages.
    pub fn resident_slots(&self, i: usize) -> &[u32] {
        let pages = self.resident(i).div_ceil(self.page_size) as usize;
        self.slots.get(i).map_or(&[], |s| &s[..pages.min(s.len())])
    }

    pub fn resident_points(&self) -> u64 {
        self.resident.iter().map(|r| *r as u64).sum()
    }

    pub fn in_flight(&self) -> usize {
        self.loading.iter().filter(|l| **l > 0).count()
    }

    /// True when every requested point is resident.
    pub fn satisfies(&self, requested: &[u32]) -> bool {
        requested
            .iter()
            .zip(&self.resident)
            .all(|(r, have)| *r <= *have)
    }

    /// Pages needed for `points` points.
    fn pages(&self, points: u32) -> usize {
        points.div_ceil(self.page_size) as usize
    }

    /// Frees pages of pointlets asked for least recently (not `keep`, nothing in flight)
    /// until `need` slots are free: whole windows of pointlets nobody requests first, then
    /// the tails beyond each request.
    fn make_room(&mut self, need: usize, requested: &[u32], keep: usize, plan: &mut Plan) {
        if self.free.len() >= need {
            return;
        }
        let mut order: Vec<usize> = (0..self.counts.len())
            .filter(|&i| i != keep && self.loading[i] == 0 && self.resident[i] > 0)
            .collect();
        order.sort_by_key(|&i| {
            (
                requested.get(i).copied().unwrap_or(0) > 0,
                self.wanted_at[i],
            )
        });
        for i in order {
            if self.free.len() >= need {
                break;
            }
            let want = requested.get(i).copied().unwrap_or(0);
            let keep_pages = self.pages(want.min(self.resident[i]));
            let short = need - self.free.len();
            let can = self.slots[i].len().saturating_sub(keep_pages).min(short);
            if can == 0 {
                continue;
            }
            let new_len = self.slots[i].len() - can;
            self.free.extend(self.slots[i].drain(new_len..));
            self.resident[i] = (new_len as u32 * self.page_size).min(self.resident[i]);
            plan.shrunk.push(i);
        }
    }

    /// Fetches for the feedback of frame `frame`: each pointlet requested beyond its window
    /// (rounded up to whole pages) and not fetching already, largest shortfall first, until
    /// `max_points` points or `max_loads` fetches are in flight.
    pub fn plan(
        &mut self,
        requested: &[u32],
        frame: u64,
        max_points: u64,
        max_loads: usize,
    ) -> Plan {
        let mut plan = Plan::default();
        let n = self.counts.len().min(requested.len());
        for (at, r) in self.wanted_at.iter_mut().zip(requested) {
            if *r > 0 {
                *at = frame;
            }
        }
        let ps = self.page_size;
        let mut todo: Vec<(usize, u32)> = (0..n)
            .filter(|&i| self.loading[i] == 0)
            .filter_map(|i| {
                let want = requested[i]
                    .div_ceil(ps)
                    .saturating_mul(ps)
                    .min(self.counts[i]);
                (want > self.resident[i]).then_some((i, want))
            })
            .collect();
        // Pointlets with nothing resident first (holes show most), then the largest shortfall.
        todo.sort_by_key(|&(i, want)| (self.resident[i] > 0, u32::MAX - (want - self.resident[i])));
        let mut points: u64 = (0..self.counts.len())
            .filter(|&i| self.loading[i] > 0)
            .map(|i| (self.loading[i] - self.resident[i]) as u64)
            .sum();
        let mut loads = self.in_flight();
        for (i, want) in todo {
            if loads >= max_loads || points >= max_points {
                break;
            }
            let have = self.resident[i];
            let need = self.pages(want) - self.slots[i].len();
            self.make_room(need, requested, i, &mut plan);
            let take = need.min(self.free.len());
            if take == 0 {
                continue;
            }
            let new_slots: Vec<u32> = (0..take).filter_map(|_| self.free.pop()).collect();
            self.slots[i].extend_from_slice(&new_slots);
            let end = (self.slots[i].len() as u32 * ps).min(want);
            self.loading[i] = end;
            points += (end - have) as u64;
            loads += 1;
            plan.loads.push(Load {
                range: PointRange {
                    pointlet: i,
                    points: have..end,
                },
                slots: new_slots,
            });
        }
        plan
    }

    /// The fetch of pointlet `i` arrived: its window now ends where the fetch ended.
    pub fn arrived(&mut self, i: usize) {
        if let Some(end) = self.loading.get_mut(i) {
            if *end > 0 {
                self.resident[i] = *end;
                *end = 0;
            }
        }
    }

    /// The fetch of pointlet `i` failed: its reserved pages go back to the pool.
    pub fn failed(&mut self, i: usize) {
        if let Some(end) = self.loading.get_mut(i) {
            *end = 0;
            let keep = self.resident[i].div_ceil(self.page_size) as usize;
            let extra: Vec<u32> = self.slots[i].drain(keep..).collect();
            self.free.extend(extra);
        }
    }

    /// Forgets every window and fetch (recolouring refetches all; the caller ignores fetches
    /// of the old colouring when they arrive); returns the pointlets that had pages.
    pub fn clear(&mut self) -> Vec<usize> {
        let mut cleared = Vec::new();
        for i in 0..self.counts.len() {
            if !self.slots[i].is_empty() {
                self.free.append(&mut self.slots[i]);
                cleared.push(i);
            }
            self.resident[i] = 0;
            self.loading[i] = 0;
        }
        cleared
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fetches_whole_pages_of_what_is_requested() {
        let mut r = Residency::new(vec![1000, 1000, 300], 100, 256);
        let p = r.plan(&[10, 0, 300], 1, u64::MAX, 8);
        assert_eq!(p.loads.len(), 2);
        let l0 = p.loads.iter().find(|l| l.range.pointlet == 0).unwrap();
        assert_eq!(l0.range.points, 0..256);
        assert_eq!(l0.slots.len(), 1);
        let l2 = p.loads.iter().find(|l| l.range.pointlet == 2).unwrap();
        assert_eq!(l2.range.points, 0..300);
        assert_eq!(l2.slots.len(), 2);
        // Nothing more while those are in flight.
        assert!(r.plan(&[600, 0, 300], 2, u64::MAX, 8).loads.is_empty());
        r.arrived(0);
        r.arrived(2);
        assert_eq!(r.resident(0), 256);
        assert!(r.satisfies(&[10, 0, 300]));
        let p = r.plan(&[600, 0, 300], 3, u64::MAX, 8);
        assert_eq!(p.loads[0].range.points, 256..768);
        assert_eq!(p.loads[0].slots.len(), 2);
        r.arrived(0);
        assert_eq!(r.resident_slots(0).len(), 3);
        assert_eq!(r.resident_points(), 768 + 300);
    }

    #[test]
    fn a_full_pool_evicts_what_nobody_requests() {
        let mut r = Residency::new(vec![512, 512, 512], 4, 256);
        r.plan(&[512, 512, 0], 1, u64::MAX, 8);
        r.arrived(0);
        r.arrived(1);
        // Pointlet 1 is no longer wanted: its pages go to pointlet 2.
        let p = r.plan(&[512, 0, 512], 2, u64::MAX, 8);
        assert_eq!(p.shrunk, vec![1]);
        assert_eq!(r.resident(1), 0);
        assert_eq!(p.loads[0].range.points, 0..512);
        r.arrived(2);
        assert!(r.satisfies(&[512, 0, 512]));
    }

    #[test]
    fn limits_and_failures() {
        let mut r = Residency::new(vec![256; 10], 10, 256);
        let p = r.plan(&[256; 10], 1, u64::MAX, 3);
        assert_eq!(p.loads.len(), 3);
        assert_eq!(r.in_flight(), 3);
        let first = p.loads[0].range.pointlet;
        r.failed(first);
        assert_eq!(r.in_flight(), 2);
        let p = r.plan(&[256; 10], 2, 256, 8);
        // The point limit counts what is in flight already.
        assert!(p.loads.is_empty());
        let cleared = r.clear();
        assert_eq!(cleared.len(), 2);
        assert_eq!(r.resident_points(), 0);
        assert_eq!(r.in_flight(), 0);
        assert_eq!(r.plan(&[256; 10], 3, u64::MAX, 10).loads.len(), 10);
    }
}
