//! Vertex orders of the compute-shader paper (§4): the order points sit in GPU memory changes
//! how atomics contend and how well caches serve the framebuffer.

use crate::partition::{order as curve_order, Partitioner};
use crate::shuffle::{permutation, shuffle};
use crate::Aabb;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum VertexOrder {
    /// As the input delivered them (scan order for LiDAR).
    Original,
    Morton,
    /// Uniformly random.
    Shuffled,
    /// Morton order cut into batches of 128 points, the batches shuffled (the paper's proposal).
    ShuffledMorton,
    Hilbert,
}

/// Points per batch of the shuffled Morton order (the paper's choice).
pub const SHUFFLED_MORTON_BATCH: usize = 128;

impl VertexOrder {
    pub const ALL: [VertexOrder; 5] = [
        VertexOrder::Original,
        VertexOrder::Morton,
        VertexOrder::Shuffled,
        VertexOrder::ShuffledMorton,
        VertexOrder::Hilbert,
    ];

    pub fn name(self) -> &'static str {
        match self {
            VertexOrder::Original => "original",
            VertexOrder::Morton => "morton",
            VertexOrder::Shuffled => "shuffled",
            VertexOrder::ShuffledMorton => "shuffled-morton",
            VertexOrder::Hilbert => "hilbert",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.name() == s)
    }

    /// The permutation that puts `points` in this order (`out[k]` = index of the k-th point).
    pub fn permutation(self, points: &[[f64; 3]], bounds: &Aabb, seed: u64) -> Vec<u32> {
        match self {
            VertexOrder::Original => (0..points.len() as u32).collect(),
            VertexOrder::Morton => curve_order(points, bounds, 1, Partitioner::Morton),
            VertexOrder::Hilbert => curve_order(points, bounds, 1, Partitioner::Hilbert),
            VertexOrder::Shuffled => permutation(points.len(), seed),
            VertexOrder::ShuffledMorton => {
                let morton = curve_order(points, bounds, 1, Partitioner::Morton);
                let mut batches: Vec<&[u32]> = morton.chunks(SHUFFLED_MORTON_BATCH).collect();
                shuffle(&mut batches, seed);
                batches.concat()
            }
        }
    }
}

/// Applies a permutation to a column.
pub fn apply<T: Copy + Send + Sync>(column: &[T], perm: &[u32]) -> Vec<T> {
    perm.iter().map(|i| column[*i as usize]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codes::KeyGrid;

    #[test]
    fn every_order_is_a_permutation_and_shuffled_morton_keeps_batches() {
        let mut rng = crate::shuffle::SplitMix64::new(3);
        let pts: Vec<[f64; 3]> = (0..5120)
            .map(|_| [rng.unit_f64(), rng.unit_f64(), rng.unit_f64()])
            .collect();
        let mut b = Aabb::EMPTY;
        pts.iter().for_each(|p| b.grow(*p));
        for o in VertexOrder::ALL {
            let mut p = o.permutation(&pts, &b, 1);
            p.sort_unstable();
            assert_eq!(p, (0..5120).collect::<Vec<u32>>(), "{o:?}");
        }
        let grid = KeyGrid::new(&b);
        // 5120 = 40 full batches, so chunks of the result are exactly the batches.
        let sm = VertexOrder::ShuffledMorton.permutation(&pts, &b, 1);
        for batch in sm.chunks(SHUFFLED_MORTON_BATCH) {
            let keys: Vec<u64> = batch
                .iter()
                .map(|i| grid.morton(pts[*i as usize]))
                .collect();
            assert!(
                keys.windows(2).all(|w| w[0] <= w[1]),
                "sorted inside a batch"
            );
        }
        let first: Vec<u64> = sm[..SHUFFLED_MORTON_BATCH * 4]
            .chunks(SHUFFLED_MORTON_BATCH)
            .map(|c| grid.morton(pts[c[0] as usize]))
            .collect();
        assert!(
            first.windows(2).any(|w| w[0] > w[1]),
            "batches are shuffled"
        );
    }
}
