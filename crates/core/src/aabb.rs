//! Axis-aligned bounding boxes in f64 (data coordinates stay f64 until quantized).

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box: growing it by any point yields that point's box.
    pub const EMPTY: Aabb = Aabb {
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
    };

    pub fn is_empty(&self) -> bool {
        (0..3).any(|i| self.min[i] > self.max[i])
    }

    pub fn grow(&mut self, p: [f64; 3]) {
        for (i, v) in p.iter().enumerate() {
            self.min[i] = self.min[i].min(*v);
            self.max[i] = self.max[i].max(*v);
        }
    }

    pub fn union(&self, other: &Aabb) -> Aabb {
        let mut out = *self;
        for i in 0..3 {
            out.min[i] = out.min[i].min(other.min[i]);
            out.max[i] = out.max[i].max(other.max[i]);
        }
        out
    }

    pub fn extent(&self) -> [f64; 3] {
        if self.is_empty() {
            return [0.0; 3];
        }
        [
            self.max[0] - self.min[0],
            self.max[1] - self.min[1],
            self.max[2] - self.min[2],
        ]
    }

    pub fn center(&self) -> [f64; 3] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }

    /// Length of the box diagonal.
    pub fn diagonal(&self) -> f64 {
        let e = self.extent();
        (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
    }

    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] && p[i] <= self.max[i])
    }

    /// Intersection with another box (may be empty).
    pub fn intersects(&self, other: &Aabb) -> bool {
        (0..3).all(|i| self.min[i] <= other.max[i] && other.min[i] <= self.max[i])
    }

    /// The smallest cube with the same minimum corner that holds this box
    /// (space-filling-curve keys are defined over a cube).
    pub fn bounding_cube(&self) -> Aabb {
        let e = self.extent();
        let side = e[0].max(e[1]).max(e[2]);
        Aabb {
            min: self.min,
            max: [self.min[0] + side, self.min[1] + side, self.min[2] + side],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grow_union_cube() {
        let mut a = Aabb::EMPTY;
        assert!(a.is_empty());
        a.grow([1.0, 2.0, 3.0]);
        a.grow([4.0, 0.0, 3.5]);
        assert_eq!(a.min, [1.0, 0.0, 3.0]);
        assert_eq!(a.max, [4.0, 2.0, 3.5]);
        let c = a.bounding_cube();
        assert_eq!(c.extent(), [3.0, 3.0, 3.0]);
        let b = Aabb {
            min: [10.0; 3],
            max: [11.0; 3],
        };
        assert!(!a.intersects(&b));
        assert_eq!(a.union(&b).max, [11.0, 11.0, 11.0]);
    }
}
