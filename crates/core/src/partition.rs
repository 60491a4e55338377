//! Pointlet quality (virtualized paper, Table I): cut the same points into pointlets of k points
//! by Morton order, Hilbert order and a k-d tree with median splits, and measure the AABBs.
//!
//! Definitions (the paper gives names, not formulas; ours are documented in docs/FORMAT.md):
//! extent = the AABB's diagonal; squareness = |dx − dy| of the AABB, the deviation of its plan
//! view from a square (airborne data is 2.5-D, so z is left out).

use crate::codes::KeyGrid;
use crate::Aabb;
use rayon::prelude::*;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Partitioner {
    Morton,
    Hilbert,
    KdTree,
}

impl Partitioner {
    pub const ALL: [Partitioner; 3] = [
        Partitioner::Morton,
        Partitioner::Hilbert,
        Partitioner::KdTree,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Partitioner::Morton => "Morton",
            Partitioner::Hilbert => "Hilbert",
            Partitioner::KdTree => "k-d tree",
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PartitionStats {
    pub partitioner: Partitioner,
    pub pointlets: usize,
    pub pointlet_size: usize,
    pub max_extent: f64,
    pub mean_extent: f64,
    pub std_extent: f64,
    pub mean_squareness: f64,
    /// Seconds to organise the points into pointlets (keys + sort, or tree build).
    pub seconds: f64,
}

/// Orders `points` for the partitioner; pointlets are then consecutive runs of `k` points.
pub fn order(points: &[[f64; 3]], bounds: &Aabb, k: usize, how: Partitioner) -> Vec<u32> {
    match how {
        Partitioner::Morton | Partitioner::Hilbert => {
            let grid = KeyGrid::new(bounds);
            let mut keyed: Vec<(u64, u32)> = points
                .par_iter()
                .enumerate()
                .map(|(i, p)| {
                    let key = if how == Partitioner::Morton {
                        grid.morton(*p)
                    } else {
                        grid.hilbert(*p)
                    };
                    (key, i as u32)
                })
                .collect();
            keyed.par_sort_unstable();
            keyed.into_iter().map(|(_, i)| i).collect()
        }
        Partitioner::KdTree => {
            let mut idx: Vec<u32> = (0..points.len() as u32).collect();
            kd_split(points, &mut idx, k.max(1));
            idx
        }
    }
}

/// Median split along the longest axis, the split index rounded to a multiple of `k` so every
/// leaf but the last holds exactly `k` points, like the curve-based pointlets.
fn kd_split(points: &[[f64; 3]], idx: &mut [u32], k: usize) {
    if idx.len() <= k {
        return;
    }
    let mut b = Aabb::EMPTY;
    for &i in idx.iter() {
        b.grow(points[i as usize]);
    }
    let e = b.extent();
    let axis = if e[0] >= e[1] && e[0] >= e[2] {
        0
    } else if e[1] >= e[2] {
        1
    } else {
        2
    };
    let leaves = idx.len().div_ceil(k);
    let mid = (leaves / 2).max(1) * k;
    idx.select_nth_unstable_by(mid, |a, c| {
        points[*a as usize][axis].total_cmp(&points[*c as usize][axis])
    });
    let (left, right) = idx.split_at_mut(mid);
    if left.len() + right.len() > 1 << 16 {
        rayon::join(|| kd_split(points, left, k), || kd_split(points, right, k));
    } else {
        kd_split(points, left, k);
        kd_split(points, right, k);
    }
}

/// AABB of each run of `k` consecutive points of `order`.
pub fn pointlet_boxes(points: &[[f64; 3]], order: &[u32], k: usize) -> Vec<Aabb> {
    order
        .par_chunks(k.max(1))
        .map(|chunk| {
            let mut b = Aabb::EMPTY;
            for &i in chunk {
                b.grow(points[i as usize]);
            }
            b
        })
        .collect()
}

/// Table I's statistics of a set of pointlet boxes.
pub fn box_stats(boxes: &[Aabb]) -> (f64, f64, f64, f64) {
    if boxes.is_empty() {
        return (0.0, 0.0, 0.0, 0.0);
    }
    let n = boxes.len() as f64;
    let extents: Vec<f64> = boxes.iter().map(|b| b.diagonal()).collect();
    let max = extents.iter().cloned().fold(0.0, f64::max);
    let mean = extents.iter().sum::<f64>() / n;
    let var = extents.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / n;
    let square = boxes
        .iter()
        .map(|b| {
            let e = b.extent();
            (e[0] - e[1]).abs()
        })
        .sum::<f64>()
        / n;
    (max, mean, var.sqrt(), square)
}

/// Runs one partitioner and measures it.
pub fn measure(points: &[[f64; 3]], bounds: &Aabb, k: usize, how: Partitioner) -> PartitionStats {
    let t = Instant::now();
    let ord = order(points, bounds, k, how);
    let seconds = t.elapsed().as_secs_f64();
    let boxes = pointlet_boxes(points, &ord, k);
    let (max_extent, mean_extent, std_extent, mean_squareness) = box_stats(&boxes);
    PartitionStats {
        partitioner: how,
        pointlets: boxes.len(),
        pointlet_size: k,
        max_extent,
        mean_extent,
        std_extent,
        mean_squareness,
        seconds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shuffle::SplitMix64;

    fn cloud(n: usize) -> (Vec<[f64; 3]>, Aabb) {
        let mut rng = SplitMix64::new(9);
        let mut b = Aabb::EMPTY;
        let pts: Vec<[f64; 3]> = (0..n)
            .map(|_| {
                let x = rng.unit_f64() * 100.0;
                let y = rng.unit_f64() * 60.0;
                let p = [x, y, (x * 0.1).sin() * 3.0 + rng.unit_f64() * 0.1];
                b.grow(p);
                p
            })
            .collect();
        (pts, b)
    }

    #[test]
    fn every_partitioner_is_a_permutation_with_full_pointlets() {
        let (pts, b) = cloud(10_000);
        for how in Partitioner::ALL {
            let ord = order(&pts, &b, 256, how);
            let mut s = ord.clone();
            s.sort_unstable();
            assert_eq!(s, (0..10_000).collect::<Vec<u32>>(), "{how:?}");
            let boxes = pointlet_boxes(&pts, &ord, 256);
            assert_eq!(boxes.len(), 10_000usize.div_ceil(256));
        }
    }

    #[test]
    fn hilbert_is_tighter_than_morton_and_kd_is_tightest_on_mean_extent() {
        let (pts, b) = cloud(200_000);
        let m = measure(&pts, &b, 512, Partitioner::Morton);
        let h = measure(&pts, &b, 512, Partitioner::Hilbert);
        let k = measure(&pts, &b, 512, Partitioner::KdTree);
        assert!(h.mean_extent < m.mean_extent, "{h:?} vs {m:?}");
        assert!(h.std_extent < m.std_extent, "{h:?} vs {m:?}");
        assert!(k.mean_extent < m.mean_extent, "{k:?} vs {m:?}");
    }

    #[test]
    fn stats_of_known_boxes() {
        let boxes = [
            Aabb {
                min: [0.0; 3],
                max: [3.0, 4.0, 0.0],
            },
            Aabb {
                min: [0.0; 3],
                max: [6.0, 8.0, 0.0],
            },
        ];
        let (max, mean, std, sq) = box_stats(&boxes);
        assert_eq!((max, mean, std, sq), (10.0, 7.5, 2.5, 1.5));
    }
}
