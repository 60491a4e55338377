//! Which tiles a view needs, chosen as 3D Tiles clients choose them (the WebGPU-engine paper
//! §4, eq. 1): a tile's screen-space error is its geometric error seen at its distance,
//! `sse = geometricError · focal_px / distance` (focal_px = image height / (2 tan(fov / 2))),
//! tiles whose bounding sphere lies outside the view frustum are culled, and a tile whose error
//! exceeds the maximum is refined into its children. An `ADD` tile stays drawn under its
//! children; a `REPLACE` tile is drawn until all its visible children can be drawn instead, and
//! meanwhile those children are requested. The building block of streaming: what to draw now,
//! and what to fetch, most important first.

use crate::tileset::{Refine, Tileset};
use pointlet_core::camera::{dot, length, sub};
use pointlet_core::Camera;

/// The view tiles are chosen for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileView {
    pub camera: Camera,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
}

/// A tile the view wants, with its screen-space error (pixels) and distance from the eye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WantedTile {
    pub tile: usize,
    pub sse: f64,
    pub distance: f64,
}

/// What a view draws now and what it asks for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TilePlan {
    /// Tiles with content to draw, in traversal order (parents before children).
    pub draw: Vec<WantedTile>,
    /// Tiles with content the view needs and does not have, largest error first, then nearest.
    pub requests: Vec<WantedTile>,
}

/// The error of `geometric_error` seen at `distance` by a camera of `focal_px`.
pub fn screen_space_error(geometric_error: f64, distance: f64, focal_px: f64) -> f64 {
    geometric_error * focal_px / distance.max(1e-9)
}

/// Frustum test of spheres against a camera (planes through the eye, near and far).
struct Frustum {
    eye: [f64; 3],
    axes: [[f64; 3]; 3],
    /// Tangents of the half angles, horizontal and vertical.
    tan: [f64; 2],
    near: f64,
    far: f64,
}

impl Frustum {
    fn new(view: &TileView) -> Self {
        let c = &view.camera;
        let tan_y = (c.fov_y_deg.to_radians() / 2.0).tan();
        let aspect = f64::from(view.width.max(1)) / f64::from(view.height.max(1));
        Self {
            eye: c.eye,
            axes: c.basis(),
            tan: [tan_y * aspect, tan_y],
            near: c.near,
            far: c.far,
        }
    }

    /// False when the sphere lies wholly outside one plane.
    fn sees(&self, center: [f64; 3], radius: f64) -> bool {
        let v = sub(center, self.eye);
        let [right, up, back] = self.axes;
        // The camera looks down -back (a right-handed view basis).
        let (x, y, z) = (dot(v, right), dot(v, up), -dot(v, back));
        if z + radius < self.near || z - radius > self.far {
            return false;
        }
        let outside = |side: f64, tan: f64| (side - z * tan) / (1.0 + tan * tan).sqrt() > radius;
        !(outside(x, self.tan[0])
            || outside(-x, self.tan[0])
            || outside(y, self.tan[1])
            || outside(-y, self.tan[1]))
    }
}

/// The plan of `view` at `max_sse` pixels, `loaded(tile)` telling which tiles' content is at
/// hand. With every tile loaded, `draw` is what a client shows once streaming has settled.
pub fn plan(
    tileset: &Tileset,
    view: &TileView,
    max_sse: f64,
    loaded: &dyn Fn(usize) -> bool,
) -> TilePlan {
    let frustum = Frustum::new(view);
    let focal = view.camera.focal_px(view.height);
    let judge = |t: usize| -> Option<WantedTile> {
        let tile = tileset.tiles.get(t)?;
        let s = tile.volume.sphere;
        if !frustum.sees(s.center, s.radius) {
            return None;
        }
        let distance = (length(sub(s.center, view.camera.eye)) - s.radius).max(view.camera.near);
        Some(WantedTile {
            tile: t,
            sse: screen_space_error(tile.geometric_error, distance, focal),
            distance,
        })
    };
    let has_content = |t: usize| tileset.tiles.get(t).is_some_and(|x| !x.contents.is_empty());
    let mut out = TilePlan::default();
    let want = |w: WantedTile, out: &mut TilePlan| {
        if !has_content(w.tile) {
            return;
        }
        if loaded(w.tile) {
            out.draw.push(w);
        } else {
            out.requests.push(w);
        }
    };
    let mut stack: Vec<WantedTile> = judge(0).into_iter().collect();
    while let Some(w) = stack.pop() {
        let tile = &tileset.tiles[w.tile];
        // A maximum of 0 refines every tile, whatever its error: full detail.
        if (w.sse <= max_sse && max_sse > 0.0) || tile.children.is_empty() {
            want(w, &mut out);
            continue;
        }
        let children: Vec<WantedTile> = tile.children.iter().filter_map(|c| judge(*c)).collect();
        let ready = children
            .iter()
            .all(|c| !has_content(c.tile) || loaded(c.tile));
        if tile.refine == Refine::Add || ready {
            if tile.refine == Refine::Add {
                want(w, &mut out);
            }
            // Reversed so that children pop in their order.
            stack.extend(children.into_iter().rev());
        } else {
            // REPLACE before its children are in: the parent stays, the children come.
            want(w, &mut out);
            for c in children {
                if has_content(c.tile) && !loaded(c.tile) {
                    out.requests.push(c);
                }
            }
        }
    }
    out.requests.sort_by(|a, b| {
        b.sse
            .total_cmp(&a.sse)
            .then(a.distance.total_cmp(&b.distance))
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tileset::{ContentRef, Tile};
    use crate::volume::{BoundingVolume, Sphere};
    use crate::Transform;

    /// A root over [0, 64]² with four REPLACE children (quadrants), each with four ADD children.
    fn quadtree() -> Tileset {
        let mut tiles = Vec::new();
        let mut push =
            |parent: Option<usize>, center: [f64; 2], half: f64, depth, refine, error: f64| {
                let i = tiles.len();
                tiles.push(Tile {
                    parent,
                    children: Vec::new(),
                    depth,
                    path: format!("t{i}"),
                    file: 0,
                    volume: BoundingVolume::from_sphere(Sphere {
                        center: [center[0], center[1], 0.0],
                        radius: half * std::f64::consts::SQRT_2,
                    }),
                    geometric_error: error,
                    refine,
                    transform: Transform::IDENTITY,
                    contents: vec![ContentRef {
                        uri: format!("{i}.pnts"),
                        volume: None,
                    }],
                });
                if let Some(p) = parent {
                    tiles[p].children.push(i);
                }
                i
            };
        let root = push(None, [32.0, 32.0], 32.0, 0, Refine::Replace, 8.0);
        for q in 0..4 {
            let c = [16.0 + 32.0 * (q % 2) as f64, 16.0 + 32.0 * (q / 2) as f64];
            let child = push(Some(root), c, 16.0, 1, Refine::Add, 4.0);
            for k in 0..4 {
                let g = [
                    c[0] - 8.0 + 16.0 * (k % 2) as f64,
                    c[1] - 8.0 + 16.0 * (k / 2) as f64,
                ];
                push(Some(child), g, 8.0, 2, Refine::Add, 0.0);
            }
        }
        Tileset {
            tiles,
            files: Vec::new(),
        }
    }

    fn view(eye: [f64; 3], target: [f64; 3]) -> TileView {
        TileView {
            camera: Camera {
                eye,
                target,
                up: [0.0, 0.0, 1.0],
                fov_y_deg: 60.0,
                near: 0.1,
                far: 10_000.0,
            },
            width: 800,
            height: 600,
        }
    }

    fn tiles(w: &[WantedTile]) -> Vec<usize> {
        w.iter().map(|w| w.tile).collect()
    }

    #[test]
    fn error_shrinks_with_distance_and_grows_with_resolution() {
        let far = screen_space_error(2.0, 200.0, 500.0);
        assert_eq!(far, 5.0);
        assert_eq!(screen_space_error(2.0, 100.0, 500.0), 2.0 * far);
        assert_eq!(screen_space_error(2.0, 200.0, 1000.0), 2.0 * far);
    }

    #[test]
    fn a_distant_view_draws_the_root_and_a_close_one_refines() {
        let set = quadtree();
        let all = |_: usize| true;
        let far = plan(
            &set,
            &view([32.0, -5000.0, 3000.0], [32.0, 32.0, 0.0]),
            16.0,
            &all,
        );
        assert_eq!(tiles(&far.draw), vec![0]);
        assert!(far.requests.is_empty());
        // Close over the first quadrant: the root gives way (REPLACE) to the visible
        // quadrants, which stay drawn under their leaves (ADD).
        let near = plan(
            &set,
            &view([10.0, 10.0, 12.0], [16.0, 16.0, 0.0]),
            16.0,
            &all,
        );
        let drawn = tiles(&near.draw);
        assert!(!drawn.contains(&0), "{drawn:?}");
        let depth = |t: &usize| set.tiles[*t].depth;
        assert!(drawn.contains(&set.tiles[0].children[0]), "{drawn:?}");
        assert!(drawn.iter().any(|t| depth(t) == 2), "{drawn:?}");
        // A parent is listed before its children.
        let at = |t: usize| drawn.iter().position(|d| *d == t);
        for t in drawn.iter().filter(|t| depth(t) == 2) {
            let parent = set.tiles[*t].parent.and_then(at);
            assert!(parent.is_some_and(|p| Some(p) < at(*t)), "{drawn:?}");
        }
    }

    #[test]
    fn tiles_outside_the_frustum_are_culled() {
        let set = quadtree();
        // Looking away from the data.
        let away = plan(
            &set,
            &view([32.0, -100.0, 5.0], [32.0, -200.0, 5.0]),
            16.0,
            &|_| true,
        );
        assert!(away.draw.is_empty() && away.requests.is_empty());
        // Close over quadrant 1 (x < 32, y < 32) looking straight down: quadrant 4 is out.
        let q = plan(
            &set,
            &view([16.0, 16.0, 6.0], [16.001, 16.0, 0.0]),
            1.0,
            &|_| true,
        );
        let drawn = tiles(&q.draw);
        assert!(drawn.contains(&1), "{drawn:?}");
        let last_quadrant = set.tiles[0].children[3];
        assert!(!drawn.contains(&last_quadrant), "{drawn:?}");
    }

    #[test]
    fn a_replace_parent_stays_until_its_children_arrive() {
        let set = quadtree();
        let v = view([10.0, 10.0, 12.0], [16.0, 16.0, 0.0]);
        let only_root = |t: usize| t == 0;
        let p = plan(&set, &v, 16.0, &only_root);
        assert_eq!(tiles(&p.draw), vec![0]);
        let requested = tiles(&p.requests);
        assert!(!requested.is_empty() && requested.iter().all(|t| set.tiles[*t].depth == 1));
        // Largest error first, then nearest.
        for pair in p.requests.windows(2) {
            assert!(
                pair[0].sse > pair[1].sse
                    || (pair[0].sse == pair[1].sse && pair[0].distance <= pair[1].distance)
            );
        }
        // Nothing loaded: the root is requested first of all.
        let nothing = plan(&set, &v, 16.0, &|_| false);
        assert_eq!(tiles(&nothing.requests)[0], 0);
        assert!(nothing.draw.is_empty());
    }
}
