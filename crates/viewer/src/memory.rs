//! Raw point files and the demo scene, held whole in RAM (a later issue streams them): the
//! attribute columns stay on the CPU so that switching the colouring recomputes colours here
//! and uploads only the colour stream, and picks map back to the exact file coordinates.
//!
//! Loading mirrors `pointlet render` exactly (batches of 2^20 points, colour ranges fitted on
//! the first batch with the header's z range, camera fitted to the real points, the same vertex
//! order permutation), so the viewer's image of a camera equals the headless render's.

use crate::ViewerError;
use pointlet_core::color::{default_color, point_color, ColorMode, ColorScale, DefaultColor};
use pointlet_core::order::{apply, VertexOrder};
use pointlet_core::{Aabb, PointBatch, PointLayout};
use pointlet_gpu::PointSet;
use pointlet_io::PointReader;
use rayon::prelude::*;
use std::path::PathBuf;

/// Points read per batch (and the size of the sample that colour ranges are fitted on).
const BATCH: usize = 1 << 20;
/// Seed of the shuffled vertex orders: the one `pointlet render` uses, so images match.
pub const ORDER_SEED: u64 = 0x5eed;
/// Points reserved up front at most, whatever a header claims.
const MAX_RESERVE: u64 = 1 << 28;

/// Where in-memory points come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Source<'a> {
    Files {
        paths: &'a [PathBuf],
        read: &'a pointlet_io::ReadOptions,
    },
    /// The built-in synthetic scene.
    Demo { points: u64, seed: u64 },
}

pub struct MemoryData {
    pub name: String,
    pub layout: PointLayout,
    /// Attribute columns in file order (only those colours read: xyz, intensity, returns,
    /// classification, point source id, GPS time, RGB).
    batch: PointBatch,
    /// Upload order: GPU point k is file point `perm[k]`.
    perm: Vec<u32>,
    pub bounds: Aabb,
    /// Data-fitted scale of every colour mode, in `ColorMode::ALL` order.
    fitted: Vec<ColorScale>,
    /// The colouring when none is asked for, chosen on the same sample as the scales.
    pub default_color: DefaultColor,
    pub class_counts: [u64; 256],
}

impl MemoryData {
    pub fn load(source: Source<'_>, order: VertexOrder) -> Result<Self, ViewerError> {
        let (reader, name): (Box<dyn PointReader>, String) = match source {
            Source::Files { paths, read } => (
                pointlet_engine::open_inputs(paths, read)
                    .map_err(|e| ViewerError::Load(e.to_string()))?,
                pointlet_engine::inputs_name(paths).display().to_string(),
            ),
            Source::Demo { points, seed } => {
                let generator = pointlet_io::generate::SceneGenerator::new(
                    pointlet_io::generate::SceneConfig { points, seed },
                );
                (
                    Box::new(generator.reader()),
                    format!("demo scene ({points} points)"),
                )
            }
        };
        Self::read(reader, name, order)
    }

    fn read(
        mut reader: Box<dyn PointReader>,
        name: String,
        order: VertexOrder,
    ) -> Result<Self, ViewerError> {
        let meta = reader.meta().clone();
        let z = if meta.bounds.is_empty() {
            [0.0, 1.0]
        } else {
            [meta.bounds.min[2], meta.bounds.max[2]]
        };
        let layout = meta.layout;
        let mut batch =
            PointBatch::with_capacity(layout, meta.point_count.min(MAX_RESERVE) as usize);
        let mut fitted = None;
        while let Some(b) = reader
            .read_batch(BATCH)
            .map_err(|e| ViewerError::Load(format!("reading {name}: {e}")))?
        {
            if fitted.is_none() {
                fitted = Some(fit_all(&b, z));
            }
            append(&mut batch, &b);
        }
        Self::build(name, batch, fitted, order)
    }

    /// Points already in memory (tests, tools), colour ranges fitted on all of them.
    pub fn from_batch(
        name: String,
        batch: &PointBatch,
        order: VertexOrder,
    ) -> Result<Self, ViewerError> {
        let mut bounds = Aabb::EMPTY;
        for p in &batch.xyz {
            bounds.grow(*p);
        }
        let fitted = fit_all(batch, [bounds.min[2], bounds.max[2]]);
        let mut own = PointBatch::new(batch.layout);
        append(&mut own, batch);
        Self::build(name, own, Some(fitted), order)
    }

    fn build(
        name: String,
        batch: PointBatch,
        fitted: Option<(Vec<ColorScale>, DefaultColor)>,
        order: VertexOrder,
    ) -> Result<Self, ViewerError> {
        let layout = batch.layout;
        let Some((fitted, default_color)) = fitted.filter(|_| !batch.xyz.is_empty()) else {
            return Err(ViewerError::Load(format!("{name} holds no points")));
        };
        if batch.xyz.len() as u64 >= u32::MAX as u64 {
            return Err(ViewerError::Load(format!(
                "{name}: {} points are too many to hold in memory (convert it to a store)",
                batch.xyz.len()
            )));
        }
        // Header bounds may be stale or absent: the camera is fitted to the real points.
        let mut bounds = Aabb::EMPTY;
        for p in &batch.xyz {
            bounds.grow(*p);
        }
        let perm = order.permutation(&batch.xyz, &bounds, ORDER_SEED);
        let mut class_counts = [0u64; 256];
        for c in &batch.classification {
            class_counts[*c as usize] += 1;
        }
        Ok(Self {
            name,
            layout,
            batch,
            perm,
            bounds,
            fitted,
            default_color,
            class_counts,
        })
    }

    pub fn len(&self) -> usize {
        self.perm.len()
    }

    pub fn is_empty(&self) -> bool {
        self.perm.is_empty()
    }

    /// RAM held by the attribute columns and the upload order.
    pub fn ram_bytes(&self) -> u64 {
        let b = &self.batch;
        let bytes = b.xyz.len() * 24
            + b.intensity.len() * 2
            + b.returns.len()
            + b.classification.len()
            + b.point_source_id.len() * 2
            + b.gps_time.len() * 8
            + b.rgb.len() * 6
            + self.perm.len() * 4;
        bytes as u64
    }

    /// The data-fitted scale of `mode` (what `pointlet render --color` draws with).
    pub fn fitted(&self, mode: ColorMode) -> ColorScale {
        let k = ColorMode::ALL.iter().position(|m| *m == mode).unwrap_or(0);
        self.fitted[k]
    }

    /// Colours of every point in upload order.
    pub fn colors(&self, scale: &ColorScale) -> Vec<u32> {
        self.perm
            .par_iter()
            .map(|i| point_color(&self.batch, *i as usize, scale))
            .collect()
    }

    /// Positions and colours in upload order, for `GpuCloud::upload`.
    pub fn point_set(&self, scale: &ColorScale) -> PointSet {
        PointSet {
            positions: apply(&self.batch.xyz, &self.perm),
            colors: self.colors(scale),
        }
    }

    /// Exact coordinates of GPU point `id` (a pick's id), as read from the file.
    pub fn position(&self, id: u32) -> Option<[f64; 3]> {
        let i = *self.perm.get(id as usize)?;
        self.batch.xyz.get(i as usize).copied()
    }
}

/// The scale of every mode and the default colouring, fitted on `sample`.
fn fit_all(sample: &PointBatch, z: [f64; 2]) -> (Vec<ColorScale>, DefaultColor) {
    let scales = ColorMode::ALL
        .map(|m| ColorScale::fit(m, &[sample], z))
        .to_vec();
    (scales, default_color(&sample.layout, &[sample]))
}

/// Appends the columns colouring reads (others are not kept).
fn append(to: &mut PointBatch, from: &PointBatch) {
    to.xyz.extend_from_slice(&from.xyz);
    to.intensity.extend_from_slice(&from.intensity);
    to.returns.extend_from_slice(&from.returns);
    to.classification.extend_from_slice(&from.classification);
    to.point_source_id.extend_from_slice(&from.point_source_id);
    to.gps_time.extend_from_slice(&from.gps_time);
    to.rgb.extend_from_slice(&from.rgb);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_scene_loads_in_order_and_maps_ids_back() {
        let d = MemoryData::load(
            Source::Demo {
                points: 5000,
                seed: 3,
            },
            VertexOrder::Shuffled,
        )
        .expect("demo");
        assert_eq!(d.len(), 5000);
        let set = d.point_set(&d.fitted(ColorMode::Classification));
        for k in [0u32, 17, 4999] {
            assert_eq!(d.position(k), Some(set.positions[k as usize]));
        }
        assert_eq!(d.position(5000), None);
        assert_eq!(d.class_counts.iter().sum::<u64>(), 5000);
        // Class ids ride in the alpha byte of every colour.
        let classes: u64 = set.colors.iter().map(|c| (c >> 24) as u64).sum();
        let expected: u64 = (0..256).map(|k| k as u64 * d.class_counts[k]).sum();
        assert_eq!(classes, expected);
    }

    #[test]
    fn the_default_colouring_is_chosen_on_the_data() {
        let testdata = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata");
        for (file, mode) in [
            ("simple.las", ColorMode::Rgb),
            ("test1_4.las", ColorMode::Intensity), // no RGB
            ("plane.laz", ColorMode::Intensity),   // RGB all zero
        ] {
            let path = testdata.join(file);
            let source = Source::Files {
                paths: std::slice::from_ref(&path),
                read: &Default::default(),
            };
            let d = MemoryData::load(source, VertexOrder::Original).expect("test data");
            assert_eq!(d.default_color.mode, mode, "{file}");
        }
    }

    #[test]
    fn missing_file_is_an_error_naming_it() {
        let err = MemoryData::load(
            Source::Files {
                paths: &[PathBuf::from("/nonexistent/x.laz")],
                read: &Default::default(),
            },
            VertexOrder::Original,
        )
        .err()
        .expect("error");
        assert!(err.to_string().contains("/nonexistent/x.laz"), "{err}");
    }
}
