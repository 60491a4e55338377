//! Tilesets written by independent producers (py3dtiles 12.1.1 and 3d-tiles-tools 0.5.4, see
//! testdata/README.md) decode to the points of their source LAS/LAZ file.
//!
//! What is checked, for each tileset:
//! - REPLACE (the producers' own trees): the leaves' points together are the source (same
//!   count; each point within 1 mm of a grid position of the source's 0.01 m quantization; the
//!   same multiset of grid positions; the colours at each position equal, exactly for pnts and
//!   within one linear 8-bit step for GLB, whose COLOR_0 the producer stored as linear unorm8).
//!   Each interior content point (the producers' coarser previews) lies within its tile's
//!   geometric error of a source point. Every point lies inside its tile's world bounding
//!   volume (within 1 mm for leaves, within the geometric error for the others).
//! - ADD (hand-edited tree over the same contents): all tiles' points together are the source.
//! - Nested transforms with a rotation undone one level down, and an external tileset one
//!   folder down: the leaves are the source.

mod common;
use common::*;
use pointlet_tiles::{Refine, Tileset};

struct Case {
    tileset: &'static str,
    source: &'static str,
    colours: ColourCheck,
    intensity: bool,
}

fn check_replace(case: &Case) {
    let (tileset, source) = Tileset::open(&testdata(case.tileset)).unwrap();
    assert_eq!(tileset.root().refine, Refine::Replace);
    let (src, scale, offset) = read_las(&testdata(case.source));
    let leaves = read_tiles(&tileset, &source, tileset.leaves());
    let worst = assert_same_points(
        &decoded_points(&leaves),
        &src,
        scale,
        offset,
        1e-3,
        case.colours,
        case.intensity,
    );
    assert!(worst < 1e-3);
    // Interior contents approximate the source: each point within the tile's geometric error
    // of a source point (py3dtiles' previews hold a subset at coarser precision).
    let interior: Vec<usize> = (0..tileset.tiles.len())
        .filter(|t| !tileset.tiles[*t].children.is_empty())
        .collect();
    assert!(!interior.is_empty());
    for t in interior {
        let tile = &tileset.tiles[t];
        for p in decoded_points(&read_tiles(&tileset, &source, std::iter::once(t))) {
            let nearest = src
                .iter()
                .map(|s| {
                    (0..3)
                        .map(|i| (s.xyz[i] - p.xyz[i]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                nearest <= tile.geometric_error,
                "interior point {:?} of tile {} is {nearest} m from the source",
                p.xyz,
                tile.path
            );
        }
    }
    assert_points_in_volumes(&tileset, &source);
}

const SIMPLE_PNTS: Case = Case {
    tileset: "tiles/simple_pnts/tileset.json",
    source: "simple.las",
    colours: ColourCheck::Exact,
    intensity: false,
};
const SIMPLE_GLB: Case = Case {
    tileset: "tiles/simple_glb/tileset.json",
    source: "simple.las",
    colours: ColourCheck::LinearStep,
    intensity: false,
};
const AUTZEN_PNTS: Case = Case {
    tileset: "tiles/autzen_pnts/tileset.json",
    source: "tiles/autzen_crop.laz",
    colours: ColourCheck::Exact,
    intensity: true,
};
const AUTZEN_GLB: Case = Case {
    tileset: "tiles/autzen_glb/tileset.json",
    source: "tiles/autzen_crop.laz",
    colours: ColourCheck::LinearStep,
    intensity: true,
};

#[test]
fn py3dtiles_pnts_replace_leaves_are_the_source() {
    check_replace(&SIMPLE_PNTS);
}

#[test]
fn py3dtiles_pnts_with_batch_table_intensity_are_the_source() {
    check_replace(&AUTZEN_PNTS);
}

#[test]
fn upgraded_glb_replace_leaves_are_the_source() {
    check_replace(&SIMPLE_GLB);
}

#[test]
fn upgraded_glb_with_structural_metadata_intensity_are_the_source() {
    check_replace(&AUTZEN_GLB);
}

fn check_variant(folder: &str, file: &str, colours: ColourCheck) -> Tileset {
    let (tileset, source) = Tileset::open(&testdata(&format!("tiles/{folder}/{file}"))).unwrap();
    let (src, scale, offset) = read_las(&testdata("simple.las"));
    let tiles: Vec<usize> = if tileset.root().refine == Refine::Add {
        (0..tileset.tiles.len()).collect()
    } else {
        tileset.leaves().collect()
    };
    let parts = read_tiles(&tileset, &source, tiles.into_iter());
    assert_same_points(
        &decoded_points(&parts),
        &src,
        scale,
        offset,
        1e-3,
        colours,
        false,
    );
    assert_points_in_volumes(&tileset, &source);
    tileset
}

#[test]
fn add_refinement_all_tiles_together_are_the_source() {
    for (folder, colours) in [
        ("simple_pnts", ColourCheck::Exact),
        ("simple_glb", ColourCheck::LinearStep),
    ] {
        let tileset = check_variant(folder, "tileset_add.json", colours);
        assert!(tileset.tiles.iter().all(|t| t.refine == Refine::Add));
        // Content on three levels: refinement ADD really adds.
        let levels: std::collections::BTreeSet<usize> = tileset
            .tiles
            .iter()
            .filter(|t| !t.contents.is_empty())
            .map(|t| t.depth)
            .collect();
        assert_eq!(levels.len(), 3, "{levels:?}");
    }
}

#[test]
fn nested_transforms_with_a_rotation_give_the_source() {
    for (folder, colours) in [
        ("simple_pnts", ColourCheck::Exact),
        ("simple_glb", ColourCheck::LinearStep),
    ] {
        let tileset = check_variant(folder, "tileset_rotated.json", colours);
        // Three transforms on the way down: root (translation × rotation), middle (inverse
        // rotation), child (scale 100 and translation); the leaves inherit REPLACE/ADD as written.
        let leaf = &tileset.tiles[tileset.leaves().next().unwrap()];
        assert_eq!(leaf.depth, 3);
        assert!(
            (leaf.transform.0[0] - 100.0).abs() < 1e-9,
            "{:?}",
            leaf.transform
        );
    }
}

#[test]
fn external_tileset_one_folder_down_gives_the_source() {
    for (folder, colours) in [
        ("simple_pnts", ColourCheck::Exact),
        ("simple_glb", ColourCheck::LinearStep),
    ] {
        let tileset = check_variant(folder, "tileset_external.json", colours);
        assert_eq!(tileset.files.len(), 2);
        assert_eq!(tileset.files[1].uri, "external/subtree.json");
        let grafted = &tileset.tiles[tileset.files[1].root];
        assert_eq!(grafted.parent, tileset.files[1].referenced_by);
        // The subtree's content URIs (../points/...) resolve next to the root file.
        assert!(
            grafted.contents[0].uri.starts_with("points/"),
            "{}",
            grafted.contents[0].uri
        );
    }
}
