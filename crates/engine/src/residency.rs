//! CPU bookkeeping of the GPU page pool: which window of each pointlet's shuffled points lives
//! in which page slots, the free slots, and which pointlets changed since the last publish.

use std::collections::VecDeque;

/// The GPU-resident points of one pointlet: [lo, hi), page `lo / page_size + k` in `slots[k]`.
/// A prefix (lo = 0) while the camera moves; while it stays still, drawn pages may leave the
/// front.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Window {
    pub lo: u32,
    pub hi: u32,
    pub slots: VecDeque<u32>,
    /// Frame in which the pointlet was last requested (least-recently-used eviction).
    pub last_used: u64,
}

impl Window {
    pub fn points(&self) -> u32 {
        self.hi - self.lo
    }
}

pub struct ResidencySet {
    page_size: u32,
    free: Vec<u32>,
    /// Per slot: the pointlet whose page it holds (u32::MAX when free), for picking.
    owner: Vec<u32>,
    windows: Vec<Window>,
    dirty: Vec<u32>,
    is_dirty: Vec<bool>,
    /// Pages given a slot since the last take: (pointlet, page index, slot).
    new_pages: Vec<[u32; 3]>,
    /// Σ window points, kept up to date by every change.
    points: u64,
}

impl ResidencySet {
    pub fn new(pointlets: usize, slots: u32, page_size: u32) -> Self {
        Self {
            page_size,
            // Reversed so slots are handed out from 0 upwards (chunk 0 fills first).
            free: (0..slots).rev().collect(),
            owner: vec![u32::MAX; slots as usize],
            windows: vec![Window::default(); pointlets],
            dirty: Vec::new(),
            is_dirty: vec![false; pointlets],
            new_pages: Vec::new(),
            points: 0,
        }
    }

    /// Points held in GPU pages, all pointlets together.
    pub fn resident_points(&self) -> u64 {
        self.points
    }

    pub fn page_size(&self) -> u32 {
        self.page_size
    }

    pub fn window(&self, i: usize) -> &Window {
        &self.windows[i]
    }

    pub fn windows(&self) -> &[Window] {
        &self.windows
    }

    pub fn free_slots(&self) -> usize {
        self.free.len()
    }

    fn mark(&mut self, i: usize) {
        if !self.is_dirty[i] {
            self.is_dirty[i] = true;
            self.dirty.push(i as u32);
        }
    }

    /// The slot that will receive point `self.window(i).hi`: the partly filled last page, or a
    /// free slot appended to the window. `None` when no slot is free.
    pub fn slot_for_next(&mut self, i: usize) -> Option<u32> {
        let ps = self.page_size;
        let w = &self.windows[i];
        if !w.hi.is_multiple_of(ps) && w.hi > w.lo {
            return w.slots.back().copied();
        }
        let slot = self.free.pop()?;
        self.owner[slot as usize] = i as u32;
        let w = &mut self.windows[i];
        let page = w.lo / self.page_size + w.slots.len() as u32;
        w.slots.push_back(slot);
        self.new_pages.push([i as u32, page, slot]);
        self.mark(i);
        Some(slot)
    }

    /// Records that points up to `hi` were written (the caller filled the slots).
    pub fn extend(&mut self, i: usize, hi: u32) {
        if hi > self.windows[i].hi {
            self.points += (hi - self.windows[i].hi) as u64;
            self.windows[i].hi = hi;
            self.mark(i);
        }
    }

    /// Keeps only points below `keep_hi`: whole pages beyond it return to the free list.
    /// Returns the pages freed.
    pub fn trim_tail(&mut self, i: usize, keep_hi: u32) -> u32 {
        let ps = self.page_size;
        let w = &mut self.windows[i];
        if keep_hi >= w.hi {
            return 0;
        }
        let before = w.points();
        let hi = keep_hi.max(w.lo);
        let pages = (hi - w.lo).div_ceil(ps) as usize;
        let mut freed = 0;
        while w.slots.len() > pages {
            if let Some(s) = w.slots.pop_back() {
                self.free.push(s);
                self.owner[s as usize] = u32::MAX;
                freed += 1;
            }
        }
        w.hi = hi;
        if w.slots.is_empty() {
            w.lo = 0;
            w.hi = 0;
        }
        self.points -= (before - w.points()) as u64;
        self.mark(i);
        freed
    }

    /// Drops whole pages that lie below `keep_lo` (already drawn into a kept framebuffer).
    /// Returns the pages freed.
    pub fn trim_head(&mut self, i: usize, keep_lo: u32) -> u32 {
        let ps = self.page_size;
        let w = &mut self.windows[i];
        let before = w.points();
        let mut freed = 0;
        while w.lo + ps <= keep_lo.min(w.hi) {
            match w.slots.pop_front() {
                Some(s) => {
                    self.free.push(s);
                    self.owner[s as usize] = u32::MAX;
                    freed += 1;
                    w.lo += ps;
                }
                None => break,
            }
        }
        if w.slots.is_empty() {
            // An empty window restarts where the next point must go.
            let start = (keep_lo / ps) * ps;
            w.lo = start;
            w.hi = start;
        }
        self.points -= (before - w.points()) as u64;
        if freed > 0 {
            self.mark(i);
        }
        freed
    }

    /// Frees every page of pointlet `i`; the window restarts at `start` (a page boundary).
    pub fn clear(&mut self, i: usize, start: u32) -> u32 {
        let w = &mut self.windows[i];
        self.points -= w.points() as u64;
        let freed = w.slots.len() as u32;
        for s in w.slots.drain(..) {
            self.owner[s as usize] = u32::MAX;
            self.free.push(s);
        }
        let start = (start / self.page_size) * self.page_size;
        if freed > 0 || w.lo != start {
            w.lo = start;
            w.hi = start;
            self.mark(i);
        }
        freed
    }

    /// The pointlet and point index that a point id of the GPU (slot · page size + index in the
    /// page) names, if that slot holds a page now.
    pub fn point_of(&self, id: u32) -> Option<(usize, u32)> {
        let (slot, local) = (id / self.page_size, id % self.page_size);
        let i = *self.owner.get(slot as usize)?;
        let w = self.windows.get(i as usize)?;
        let k = w.slots.iter().position(|s| *s == slot)? as u32;
        let index = w.lo + k * self.page_size + local;
        (index < w.hi).then_some((i as usize, index))
    }

    /// Pages given a slot since the last call, to publish: (pointlet, page index, slot).
    pub fn take_new_pages(&mut self) -> Vec<[u32; 3]> {
        std::mem::take(&mut self.new_pages)
    }

    /// Marks every requested pointlet as used in `frame` and returns the pointlets whose window
    /// no longer starts at 0 (one parallel pass over all of them).
    pub fn touch_requested(&mut self, requested: &[u32], frame: u64) -> Vec<u32> {
        use rayon::prelude::*;
        self.windows
            .par_iter_mut()
            .zip(requested.par_iter())
            .enumerate()
            .with_min_len(1024)
            .filter_map(|(i, (w, r))| {
                if *r > 0 {
                    w.last_used = frame;
                }
                (w.lo > 0).then_some(i as u32)
            })
            .collect()
    }

    /// Pointlets changed since the last call, to publish to the GPU.
    pub fn take_dirty(&mut self) -> Vec<u32> {
        for i in &self.dirty {
            self.is_dirty[*i as usize] = false;
        }
        std::mem::take(&mut self.dirty)
    }

    pub fn resident_pages(&self, total_slots: u32) -> u32 {
        total_slots - self.free.len() as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_follow_the_window() {
        let mut r = ResidencySet::new(3, 4, 256);
        let s0 = r.slot_for_next(0).unwrap();
        r.extend(0, 100);
        // The partly filled page takes the next points.
        assert_eq!(r.slot_for_next(0), Some(s0));
        r.extend(0, 256);
        let s1 = r.slot_for_next(0).unwrap();
        assert_ne!(s0, s1);
        r.extend(0, 300);
        assert_eq!(r.window(0).slots, [s0, s1]);
        assert_eq!(r.resident_points(), 300);
        assert_eq!(r.free_slots(), 2);
        assert_eq!(r.take_dirty(), vec![0]);
        assert!(r.take_dirty().is_empty());
        // Tail: keep 200 points → one page.
        assert_eq!(r.trim_tail(0, 200), 1);
        assert_eq!((r.window(0).lo, r.window(0).hi), (0, 200));
        assert_eq!(r.resident_points(), 200);
        // Head: drawn up to 256 drops page 0 only once it is wholly below.
        r.extend(0, 256);
        let s2 = r.slot_for_next(0).unwrap();
        r.extend(0, 400);
        assert_eq!(r.trim_head(0, 255), 0);
        assert_eq!(r.trim_head(0, 260), 1);
        assert_eq!(r.window(0).lo, 256);
        assert_eq!(r.window(0).slots, [s2]);
        assert_eq!(r.resident_points(), 144);
        assert_eq!(r.clear(0, 0), 1);
        assert_eq!(r.resident_points(), 0);
        assert_eq!(r.free_slots(), 4);
        assert_eq!(
            r.window(0),
            &Window {
                last_used: 0,
                ..Default::default()
            }
        );
    }

    #[test]
    fn no_slot_when_the_pool_is_full() {
        let mut r = ResidencySet::new(2, 1, 256);
        assert!(r.slot_for_next(0).is_some());
        r.extend(0, 256);
        assert!(r.slot_for_next(1).is_none());
        assert_eq!(r.window(1).slots.len(), 0);
    }
}
