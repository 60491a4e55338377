//! Bounding volumes in world space (3D Tiles 1.1 §"Bounding volumes").
//!
//! A tile's `box` (center and three half-axis vectors, 12 numbers) and `sphere` (center and
//! radius, 4 numbers) are given in the tile's frame and mapped to world space by the tile's
//! world transform: a box's center and axes map exactly, a sphere's radius grows by the
//! transform's largest axis scale. A `region` (west, south, east, north in radians, minimum and
//! maximum height in metres above the WGS84 ellipsoid) is already in EPSG:4979 and is not
//! transformed; it becomes the ECEF axis-aligned box that holds it exactly: the extremes of each
//! ECEF coordinate over a region lie on its corners, on the equator or on the meridians that
//! are multiples of 90°, at the lowest or highest height, and all those candidates are
//! evaluated. Every volume is kept both as an oriented box and as a bounding sphere.

use crate::transform::{length, Transform};
use pointlet_core::Aabb;

/// A box: center and three half-axis vectors (any orientation; a face is at center ± axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrientedBox {
    pub center: [f64; 3],
    pub half_axes: [[f64; 3]; 3],
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: [f64; 3],
    pub radius: f64,
}

/// A tile's volume in world space, as a box and as a sphere that holds the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingVolume {
    pub oriented_box: OrientedBox,
    pub sphere: Sphere,
}

/// A volume as a tileset gives it, in the tile's own frame (regions in radians and metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VolumeSpec {
    Box(OrientedBox),
    Sphere(Sphere),
    Region {
        west: f64,
        south: f64,
        east: f64,
        north: f64,
        min_height: f64,
        max_height: f64,
    },
}

/// WGS84 semi-major axis (m) and flattening.
pub const WGS84_A: f64 = 6_378_137.0;
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// ECEF coordinates of a WGS84 longitude, latitude (radians) and height (m).
pub fn geodetic_to_ecef(lon: f64, lat: f64, height: f64) -> [f64; 3] {
    let e2 = WGS84_F * (2.0 - WGS84_F);
    let (sin_lat, cos_lat) = lat.sin_cos();
    let n = WGS84_A / (1.0 - e2 * sin_lat * sin_lat).sqrt();
    [
        (n + height) * cos_lat * lon.cos(),
        (n + height) * cos_lat * lon.sin(),
        (n * (1.0 - e2) + height) * sin_lat,
    ]
}

impl VolumeSpec {
    /// Parses the numbers of a `box`, `sphere` or `region`; the error says what is wrong.
    pub fn from_box(v: &[f64]) -> Result<VolumeSpec, String> {
        let v = exactly::<12>(v, "box")?;
        Ok(VolumeSpec::Box(OrientedBox {
            center: [v[0], v[1], v[2]],
            half_axes: [[v[3], v[4], v[5]], [v[6], v[7], v[8]], [v[9], v[10], v[11]]],
        }))
    }

    pub fn from_sphere(v: &[f64]) -> Result<VolumeSpec, String> {
        let v = exactly::<4>(v, "sphere")?;
        if v[3] < 0.0 {
            return Err(format!("sphere has a negative radius {}", v[3]));
        }
        Ok(VolumeSpec::Sphere(Sphere {
            center: [v[0], v[1], v[2]],
            radius: v[3],
        }))
    }

    pub fn from_region(v: &[f64]) -> Result<VolumeSpec, String> {
        let [west, south, east, north, min_height, max_height] = exactly::<6>(v, "region")?;
        let pi = std::f64::consts::PI;
        let eps = 1e-9;
        for (name, lon) in [("west", west), ("east", east)] {
            if lon.abs() > pi + eps {
                return Err(format!("region {name} {lon} is outside [-pi, pi] radians"));
            }
        }
        for (name, lat) in [("south", south), ("north", north)] {
            if lat.abs() > pi / 2.0 + eps {
                return Err(format!(
                    "region {name} {lat} is outside [-pi/2, pi/2] radians"
                ));
            }
        }
        if south > north {
            return Err(format!("region south {south} is north of north {north}"));
        }
        if min_height > max_height {
            return Err(format!(
                "region minimum height {min_height} is above its maximum {max_height}"
            ));
        }
        Ok(VolumeSpec::Region {
            west,
            south,
            east,
            north,
            min_height,
            max_height,
        })
    }

    /// The volume in world space under the tile's world transform.
    pub fn to_world(&self, world: &Transform) -> BoundingVolume {
        match *self {
            VolumeSpec::Box(b) => BoundingVolume::from_box(OrientedBox {
                center: world.apply_point(b.center),
                half_axes: b.half_axes.map(|a| world.apply_vector(a)),
            }),
            VolumeSpec::Sphere(s) => BoundingVolume::from_sphere(Sphere {
                center: world.apply_point(s.center),
                radius: s.radius * world.max_scale(),
            }),
            VolumeSpec::Region {
                west,
                south,
                east,
                north,
                min_height,
                max_height,
            } => BoundingVolume::from_aabb(region_aabb(
                west, south, east, north, min_height, max_height,
            )),
        }
    }
}

fn exactly<const N: usize>(v: &[f64], what: &str) -> Result<[f64; N], String> {
    let array: [f64; N] = v
        .try_into()
        .map_err(|_| format!("{what} has {} numbers instead of {N}", v.len()))?;
    if let Some(bad) = array.iter().find(|x| !x.is_finite()) {
        return Err(format!("{what} has a non-finite number {bad}"));
    }
    Ok(array)
}

/// The ECEF axis-aligned box of a region (east < west: the region crosses the antimeridian).
fn region_aabb(
    west: f64,
    south: f64,
    east: f64,
    north: f64,
    min_height: f64,
    max_height: f64,
) -> Aabb {
    use std::f64::consts::{FRAC_PI_2, PI};
    let east = if east < west { east + 2.0 * PI } else { east };
    let mut lons = vec![west, east];
    // Multiples of 90° strictly inside (west, east).
    let mut k = (west / FRAC_PI_2).floor() + 1.0;
    while k * FRAC_PI_2 < east && lons.len() < 16 {
        lons.push(k * FRAC_PI_2);
        k += 1.0;
    }
    let mut lats = vec![south, north];
    if south < 0.0 && north > 0.0 {
        lats.push(0.0);
    }
    let mut aabb = Aabb::EMPTY;
    for &lon in &lons {
        for &lat in &lats {
            for h in [min_height, max_height] {
                aabb.grow(geodetic_to_ecef(lon, lat, h));
            }
        }
    }
    aabb
}

impl BoundingVolume {
    /// A box and the smallest sphere around the box's center that holds it.
    pub fn from_box(b: OrientedBox) -> BoundingVolume {
        let [x, y, z] = b.half_axes;
        let mut radius: f64 = 0.0;
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    let corner = [0, 1, 2].map(|i| sx * x[i] + sy * y[i] + sz * z[i]);
                    radius = radius.max(length(corner));
                }
            }
        }
        BoundingVolume {
            oriented_box: b,
            sphere: Sphere {
                center: b.center,
                radius,
            },
        }
    }

    /// A sphere and the axis-aligned cube around it.
    pub fn from_sphere(s: Sphere) -> BoundingVolume {
        let r = s.radius;
        BoundingVolume {
            oriented_box: OrientedBox {
                center: s.center,
                half_axes: [[r, 0.0, 0.0], [0.0, r, 0.0], [0.0, 0.0, r]],
            },
            sphere: s,
        }
    }

    pub fn from_aabb(a: Aabb) -> BoundingVolume {
        let e = a.extent();
        BoundingVolume::from_box(OrientedBox {
            center: a.center(),
            half_axes: [
                [e[0] / 2.0, 0.0, 0.0],
                [0.0, e[1] / 2.0, 0.0],
                [0.0, 0.0, e[2] / 2.0],
            ],
        })
    }

    /// The axis-aligned box that holds the oriented box.
    pub fn aabb(&self) -> Aabb {
        let b = &self.oriented_box;
        let mut min = b.center;
        let mut max = b.center;
        for i in 0..3 {
            let reach: f64 = b.half_axes.iter().map(|a| a[i].abs()).sum();
            min[i] -= reach;
            max[i] += reach;
        }
        Aabb { min, max }
    }

    /// True when `p` lies in the box (with a relative tolerance for rounding).
    pub fn contains(&self, p: [f64; 3], tolerance: f64) -> bool {
        let b = &self.oriented_box;
        let d = [0, 1, 2].map(|i| p[i] - b.center[i]);
        // Solve d = A t for t (A's columns are the half axes) by Cramer's rule.
        let a = Transform([
            b.half_axes[0][0],
            b.half_axes[0][1],
            b.half_axes[0][2],
            0.0,
            b.half_axes[1][0],
            b.half_axes[1][1],
            b.half_axes[1][2],
            0.0,
            b.half_axes[2][0],
            b.half_axes[2][1],
            b.half_axes[2][2],
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
        ]);
        let det = a.determinant3();
        if det.abs() < 1e-300 {
            // A flat box (a single point or a plane): fall back to its axis-aligned box.
            let aabb = self.aabb();
            return (0..3)
                .all(|i| p[i] >= aabb.min[i] - tolerance && p[i] <= aabb.max[i] + tolerance);
        }
        // t = A⁻¹ d: the rows of A⁻¹ are the normal matrix's columns over |det|.
        let n = a.normal_matrix();
        (0..3).all(|k| {
            let t = crate::transform::dot(n[k], d) / det.abs();
            let axis_len = length(b.half_axes[k]).max(1e-300);
            t.abs() <= 1.0 + tolerance / axis_len
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn region_box_holds_its_corners_and_the_equator_bulge() {
        use std::f64::consts::PI;
        // A region straddling the equator and the meridian 90°E.
        let spec = VolumeSpec::from_region(&[1.5, -0.1, 1.7, 0.1, 0.0, 100.0]).unwrap();
        let aabb = spec.to_world(&Transform::IDENTITY).aabb();
        let top = geodetic_to_ecef(PI / 2.0, 0.0, 100.0);
        assert!((aabb.max[1] - top[1]).abs() < 1e-6, "{aabb:?} {top:?}");
        for lon in [1.5, 1.6, 1.7] {
            for lat in [-0.1, 0.0, 0.1] {
                for h in [0.0, 50.0, 100.0] {
                    let p = geodetic_to_ecef(lon, lat, h);
                    assert!(
                        (0..3).all(|i| p[i] >= aabb.min[i] - 1e-6 && p[i] <= aabb.max[i] + 1e-6)
                    );
                }
            }
        }
    }

    #[test]
    fn region_across_the_antimeridian_goes_the_short_way() {
        let spec = VolumeSpec::from_region(&[3.0, 0.0, -3.0, 0.1, 0.0, 0.0]).unwrap();
        let aabb = spec.to_world(&Transform::IDENTITY).aabb();
        // Longitude 180° (x = −a) is inside, longitude 0 (x = +a) is not.
        assert!(aabb.min[0] < -6.3e6 && aabb.max[0] < 0.0);
    }

    #[test]
    fn volumes_follow_the_transform() {
        let spec =
            VolumeSpec::from_box(&[1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0])
                .unwrap();
        let t = Transform([
            2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 10.0, 0.0, 0.0, 1.0,
        ]);
        let v = spec.to_world(&t);
        assert_eq!(v.oriented_box.center, [12.0, 0.0, 0.0]);
        assert_eq!(v.oriented_box.half_axes[2], [0.0, 0.0, 6.0]);
        assert!((v.sphere.radius - (4.0f64 + 16.0 + 36.0).sqrt()).abs() < 1e-12);
        assert!(v.contains([13.9, 3.9, -5.9], 0.0));
        assert!(!v.contains([14.1, 0.0, 0.0], 0.0));
        let s = VolumeSpec::from_sphere(&[0.0, 0.0, 0.0, 1.0])
            .unwrap()
            .to_world(&t);
        assert_eq!(s.sphere.radius, 2.0);
        assert!(VolumeSpec::from_box(&[0.0; 11]).is_err());
        assert!(VolumeSpec::from_sphere(&[0.0, 0.0, 0.0, -1.0]).is_err());
        assert!(VolumeSpec::from_region(&[0.0, 1.0, 0.1, 0.5, 0.0, 1.0]).is_err());
    }
}
