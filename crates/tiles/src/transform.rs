//! Affine transforms as 4×4 f64 matrices stored column-major, as 3D Tiles writes `transform`
//! (3D Tiles 1.1 §"Transforms": a tile's transform maps its coordinates to its parent's; the
//! world transform of a tile is the product down the tree, root first). glTF node matrices
//! use the same layout (glTF 2.0 §3.5.3). Everything is f64: ECEF coordinates need it.

/// A column-major 4×4 matrix: element (row r, column c) is `m[c * 4 + r]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform(pub [f64; 16]);

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    pub const IDENTITY: Transform = Transform([
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);

    /// glTF's y-up frame to the z-up frame of 3D Tiles: a rotation of +90° about x,
    /// (x, y, z) → (x, −z, y) (3D Tiles 1.1 §"glTF transforms").
    pub const Y_UP_TO_Z_UP: Transform = Transform([
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);

    /// An x-up frame to z-up (`asset.gltfUpAxis: "X"`): a rotation of −90° about y,
    /// (x, y, z) → (−z, y, x).
    pub const X_UP_TO_Z_UP: Transform = Transform([
        0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ]);

    pub fn from_translation(t: [f64; 3]) -> Transform {
        let mut m = Transform::IDENTITY;
        m.0[12] = t[0];
        m.0[13] = t[1];
        m.0[14] = t[2];
        m
    }

    /// Translation × rotation (unit quaternion x, y, z, w) × scale, as a glTF node's TRS.
    pub fn from_trs(t: [f64; 3], q: [f64; 4], s: [f64; 3]) -> Transform {
        let [x, y, z, w] = q;
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y + z * w),
                2.0 * (x * z - y * w),
            ],
            [
                2.0 * (x * y - z * w),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z + x * w),
            ],
            [
                2.0 * (x * z + y * w),
                2.0 * (y * z - x * w),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        let mut m = [0.0; 16];
        for c in 0..3 {
            for r_ in 0..3 {
                m[c * 4 + r_] = r[c][r_] * s[c];
            }
        }
        m[12] = t[0];
        m[13] = t[1];
        m[14] = t[2];
        m[15] = 1.0;
        Transform(m)
    }

    /// `self × other`: `other` applies first.
    pub fn mul(&self, other: &Transform) -> Transform {
        let (a, b) = (&self.0, &other.0);
        let mut m = [0.0; 16];
        for c in 0..4 {
            for r in 0..4 {
                m[c * 4 + r] = (0..4).map(|k| a[k * 4 + r] * b[c * 4 + k]).sum();
            }
        }
        Transform(m)
    }

    pub fn apply_point(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.0;
        [
            m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
            m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
            m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14],
        ]
    }

    /// The linear part applied to a direction (no translation).
    pub fn apply_vector(&self, v: [f64; 3]) -> [f64; 3] {
        let m = &self.0;
        [
            m[0] * v[0] + m[4] * v[1] + m[8] * v[2],
            m[1] * v[0] + m[5] * v[1] + m[9] * v[2],
            m[2] * v[0] + m[6] * v[1] + m[10] * v[2],
        ]
    }

    /// Column `c` (0..3) of the linear part.
    pub fn column(&self, c: usize) -> [f64; 3] {
        [self.0[c * 4], self.0[c * 4 + 1], self.0[c * 4 + 2]]
    }

    /// Determinant of the linear (upper-left 3×3) part.
    pub fn determinant3(&self) -> f64 {
        let [a, b, c] = [self.column(0), self.column(1), self.column(2)];
        dot(a, cross(b, c))
    }

    /// The largest length of the linear part's columns: how much a sphere's radius grows.
    pub fn max_scale(&self) -> f64 {
        (0..3).map(|c| length(self.column(c))).fold(0.0, f64::max)
    }

    /// The matrix that maps normals: the inverse transpose of the linear part, up to a
    /// positive factor (the cofactor matrix times the determinant's sign), so singular
    /// transforms need no division. Returned as three columns.
    pub fn normal_matrix(&self) -> [[f64; 3]; 3] {
        let [a, b, c] = [self.column(0), self.column(1), self.column(2)];
        let sign = if self.determinant3() < 0.0 { -1.0 } else { 1.0 };
        // The cofactor matrix of M = [a b c] has columns b×c, c×a, a×b: (cof M) x = (b×c) x0 + ...
        let scale = |v: [f64; 3]| [v[0] * sign, v[1] * sign, v[2] * sign];
        [scale(cross(b, c)), scale(cross(c, a)), scale(cross(a, b))]
    }

    /// Why this transform cannot place content, or `None` when it can: every element finite,
    /// the last row (0, 0, 0, 1), the linear part invertible and not nearly flat.
    pub fn defect(&self) -> Option<String> {
        if let Some(i) = self.0.iter().position(|v| !v.is_finite()) {
            return Some(format!(
                "has a non-finite element {} at index {i}",
                self.0[i]
            ));
        }
        let last_row = [self.0[3], self.0[7], self.0[11], self.0[15]];
        if last_row != [0.0, 0.0, 0.0, 1.0] {
            return Some(format!(
                "is not affine: last row {last_row:?} instead of [0, 0, 0, 1]"
            ));
        }
        let lengths = [0, 1, 2].map(|c| length(self.column(c)));
        if lengths.iter().any(|l| *l == 0.0 || !l.is_finite()) {
            return Some(format!(
                "is degenerate: an axis has zero length (column lengths {lengths:?})"
            ));
        }
        // The determinant of the unit axes: 1 for orthogonal axes, 0 for flat ones (computed
        // on unit vectors so that huge or tiny scales do not overflow).
        let unit = [0, 1, 2].map(|c| self.column(c).map(|v| v / lengths[c]));
        let flatness = dot(unit[0], cross(unit[1], unit[2])).abs();
        if flatness.is_nan() || flatness <= 1e-12 {
            return Some(format!(
                "is degenerate: its axes are (nearly) coplanar (determinant of the unit axes {flatness:e})"
            ));
        }
        None
    }
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Euclidean length, without overflow for components near the f64 limits.
pub(crate) fn length(v: [f64; 3]) -> f64 {
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return largest;
    }
    let u = v.map(|x| x / largest);
    largest * dot(u, u).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn y_up_to_z_up_sends_gltf_up_to_tiles_up() {
        assert_eq!(
            Transform::Y_UP_TO_Z_UP.apply_point([0.0, 1.0, 0.0]),
            [0.0, 0.0, 1.0]
        );
        // glTF's +z (towards the viewer) becomes −y.
        assert_eq!(
            Transform::Y_UP_TO_Z_UP.apply_point([0.0, 0.0, 1.0]),
            [0.0, -1.0, 0.0]
        );
        assert_eq!(
            Transform::X_UP_TO_Z_UP.apply_point([1.0, 0.0, 0.0]),
            [0.0, 0.0, 1.0]
        );
        assert!(Transform::Y_UP_TO_Z_UP.defect().is_none());
    }

    #[test]
    fn trs_matches_a_quarter_turn() {
        // −90° about x (what 3d-tiles-tools writes on its nodes) undoes y-up → z-up.
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let node = Transform::from_trs([0.0; 3], [-h, 0.0, 0.0, h], [1.0; 3]);
        let both = Transform::Y_UP_TO_Z_UP.mul(&node);
        for (a, b) in both.0.iter().zip(Transform::IDENTITY.0) {
            assert!((a - b).abs() < 1e-15);
        }
    }

    #[test]
    fn defects_name_the_problem() {
        let mut zero = Transform::IDENTITY;
        zero.0[5] = 0.0;
        assert!(zero.defect().unwrap().contains("zero length"));
        let mut nan = Transform::IDENTITY;
        nan.0[12] = f64::NAN;
        assert!(nan.defect().unwrap().contains("non-finite"));
        let mut projective = Transform::IDENTITY;
        projective.0[3] = 1.0;
        assert!(projective.defect().unwrap().contains("affine"));
        let mut flat = Transform::IDENTITY;
        flat.0[8] = 1.0;
        flat.0[10] = 1e-14;
        assert!(flat.defect().unwrap().contains("coplanar"));
    }

    #[test]
    fn normal_matrix_is_the_inverse_transpose_up_to_scale() {
        let m = Transform([
            2.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 5.0, 0.0, 0.0, 1.0,
        ]);
        let n = m.normal_matrix();
        // Inverse transpose of diag(2,1,1) is diag(0.5,1,1) ∝ diag(1,2,2).
        assert_eq!(n, [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]);
    }
}
