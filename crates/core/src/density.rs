//! The spacing of a point cloud's surfaces, for splats sized to the data: LiDAR and
//! photogrammetry sample 2-D surfaces, so a cloud's density is points per square metre of
//! surface, and its spacing is 1/√density. Surface area is measured by occupancy: the number of
//! voxels of side h that hold points, times h². That is only right when the occupied voxels are
//! well filled, so occupancy is kept at several voxel sizes and the finest size whose occupied
//! voxels hold enough points on average is used. Points may be fed as a sample (a stride of
//! each batch); the spacing is then that of all the points the sample stands for.

use crate::Aabb;
use std::collections::HashSet;
use std::hash::{BuildHasherDefault, Hasher};

/// Voxel sizes kept, each twice the previous.
const LEVELS: usize = 11;
/// The finest voxel: this fraction of the largest extent.
const FINEST: f64 = 1.0 / 4096.0;
/// Mean sample points per occupied voxel for a level to count as filled.
const FILLED: f64 = 6.0;
/// Voxels counted per level at most (bounds memory on huge, sparse clouds).
const MAX_VOXELS: usize = 1 << 21;

/// Occupancy of a cloud's voxels at several sizes, fed with (a sample of) its points.
#[derive(Clone, Debug)]
pub struct SurfaceDensity {
    origin: [f64; 3],
    /// 1 / the finest voxel size.
    inv_finest: f64,
    finest: f64,
    levels: Vec<HashSet<u64, VoxelHash>>,
    /// Sample points fed.
    sampled: u64,
}

impl SurfaceDensity {
    /// An empty count over `bounds` (the cloud's, or its header's).
    pub fn new(bounds: &Aabb) -> Self {
        let e = bounds.extent();
        let largest = e[0].max(e[1]).max(e[2]);
        let finest = if largest.is_finite() && largest > 0.0 {
            largest * FINEST
        } else {
            1.0
        };
        Self {
            origin: if bounds.is_empty() {
                [0.0; 3]
            } else {
                bounds.min
            },
            inv_finest: 1.0 / finest,
            finest,
            levels: vec![HashSet::default(); LEVELS],
            sampled: 0,
        }
    }

    /// Counts `points` (a sample: any subset spread like the cloud).
    pub fn add(&mut self, points: impl IntoIterator<Item = [f64; 3]>) {
        for p in points {
            let c = [0, 1, 2].map(|a| ((p[a] - self.origin[a]) * self.inv_finest).max(0.0));
            if !c.iter().all(|v| v.is_finite()) {
                continue;
            }
            // 21 bits per axis at the finest level covers 4096 cells with room for points
            // outside lying bounds.
            let cell = c.map(|v| (v as u64).min((1 << 21) - 1));
            self.sampled += 1;
            for (l, set) in self.levels.iter_mut().enumerate() {
                if set.len() >= MAX_VOXELS {
                    continue;
                }
                let k = cell.map(|v| v >> l);
                set.insert(k[0] | k[1] << 21 | k[2] << 42);
            }
        }
    }

    /// Adds another count over the same bounds.
    pub fn merge(&mut self, other: &SurfaceDensity) {
        for (mine, theirs) in self.levels.iter_mut().zip(&other.levels) {
            if mine.len() < MAX_VOXELS {
                mine.extend(theirs.iter().copied());
            }
        }
        self.sampled += other.sampled;
    }

    /// Sample points counted so far.
    pub fn sampled(&self) -> u64 {
        self.sampled
    }

    /// Surface area (square units) the points cover, if any level is filled enough to tell.
    pub fn area(&self) -> Option<f64> {
        let n = self.sampled as f64;
        if self.sampled == 0 {
            return None;
        }
        let filled = self.levels.iter().enumerate().find(|(_, set)| {
            !set.is_empty() && set.len() < MAX_VOXELS && n / set.len() as f64 >= FILLED
        });
        // Too few points to fill even the coarsest voxels: the coarsest still bounds the area.
        let (l, set) = filled.or_else(|| self.levels.iter().enumerate().next_back())?;
        let h = self.finest * (1u64 << l) as f64;
        Some(set.len() as f64 * h * h)
    }

    /// The spacing (1/√density) of `total` points on the surface the sample covers.
    pub fn spacing(&self, total: u64) -> Option<f64> {
        let area = self.area()?;
        (total > 0 && area > 0.0).then(|| (area / total as f64).sqrt())
    }
}

/// The spacing of `positions` (all of a cloud's points, or a spread sample standing for
/// `total`), from a sample of at most `max_sample` of them taken at an even stride.
pub fn cloud_spacing(positions: &[[f64; 3]], total: u64, max_sample: usize) -> Option<f64> {
    let mut bounds = Aabb::EMPTY;
    for p in positions {
        bounds.grow(*p);
    }
    let mut density = SurfaceDensity::new(&bounds);
    let stride = positions.len().div_ceil(max_sample.max(1)).max(1);
    density.add(positions.iter().step_by(stride).copied());
    // The sample stands for `total` points: scale by what it covers.
    density.spacing(total)
}

/// A multiply-xor hash of voxel keys (std's SipHash is several times slower here).
#[derive(Default, Clone, Copy)]
struct VoxelHasher(u64);

impl Hasher for VoxelHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 = (self.0 ^ *b as u64).wrapping_mul(0x100_0000_01b3);
        }
    }

    fn write_u64(&mut self, v: u64) {
        let x = (v ^ (v >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        self.0 = x ^ (x >> 32);
    }
}

type VoxelHash = BuildHasherDefault<VoxelHasher>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shuffle::SplitMix64;

    fn plane(n: usize, side: f64, tilt: f64, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|_| {
                let (u, v) = (rng.unit_f64() * side, rng.unit_f64() * side);
                [u, v * tilt.cos(), v * tilt.sin() + 100.0]
            })
            .collect()
    }

    #[test]
    fn a_flat_plane_has_the_spacing_of_its_density() {
        // 200 000 points on 100 m × 100 m: density 20 /m², spacing 0.2236 m.
        let pts = plane(200_000, 100.0, 0.0, 1);
        let s = cloud_spacing(&pts, pts.len() as u64, usize::MAX).unwrap_or(0.0);
        let want = (100.0f64 * 100.0 / 200_000.0).sqrt();
        assert!((s / want - 1.0).abs() < 0.1, "spacing {s}, want {want}");
    }

    #[test]
    fn a_sample_stands_for_all_the_points() {
        let pts = plane(400_000, 50.0, 0.3, 2);
        let all = cloud_spacing(&pts, pts.len() as u64, usize::MAX).unwrap_or(0.0);
        let sampled = cloud_spacing(&pts, pts.len() as u64, 20_000).unwrap_or(0.0);
        assert!(
            (sampled / all - 1.0).abs() < 0.15,
            "sampled {sampled} vs all {all}"
        );
    }

    #[test]
    fn two_planes_have_twice_the_area_of_one() {
        let mut pts = plane(100_000, 40.0, 0.0, 3);
        let area_one = {
            let mut d = SurfaceDensity::new(&bounds_of(&pts));
            d.add(pts.iter().copied());
            d.area().unwrap_or(0.0)
        };
        let wall: Vec<[f64; 3]> = plane(100_000, 40.0, std::f64::consts::FRAC_PI_2, 4);
        pts.extend(wall);
        let mut d = SurfaceDensity::new(&bounds_of(&pts));
        let (a, b) = pts.split_at(pts.len() / 2);
        let mut other = SurfaceDensity::new(&bounds_of(&pts));
        d.add(a.iter().copied());
        other.add(b.iter().copied());
        d.merge(&other);
        let area_two = d.area().unwrap_or(0.0);
        assert!(
            (area_two / area_one - 2.0).abs() < 0.3,
            "{area_two} vs {area_one}"
        );
        assert!((area_one / 1600.0 - 1.0).abs() < 0.15, "{area_one}");
    }

    #[test]
    fn degenerate_input_gives_no_spacing_or_a_finite_one() {
        assert_eq!(cloud_spacing(&[], 0, 10), None);
        let one = cloud_spacing(&[[1.0, 2.0, 3.0]], 1, 10);
        assert!(one.is_none_or(|s| s.is_finite()));
        let same = vec![[5.0, 5.0, 5.0]; 1000];
        assert!(cloud_spacing(&same, 1000, 100).is_none_or(|s| s.is_finite()));
        let nan = vec![[f64::NAN, 0.0, 0.0]; 10];
        assert!(cloud_spacing(&nan, 10, 10).is_none_or(|s| s.is_finite()));
    }

    fn bounds_of(pts: &[[f64; 3]]) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in pts {
            b.grow(*p);
        }
        b
    }
}
