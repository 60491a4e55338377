//! Points for in-core rendering: from a store, any point file, or the built-in demo scene,
//! coloured by one attribute.

use anyhow::{bail, Context, Result};
use pointlet_core::color::{point_color, ColorMode, ColorScale};
use pointlet_core::{Aabb, PointBatch};
use pointlet_gpu::PointSet;
use std::path::Path;

/// Points of the built-in demo scene when no input is given.
pub const DEMO_POINTS: u64 = 2_000_000;
pub const DEMO_SEED: u64 = 1;

pub struct Scene {
    pub name: String,
    pub set: PointSet,
    pub bounds: Aabb,
}

/// Reads every point of `input` (or the demo scene of `demo_points`) coloured by `mode`.
pub fn load(
    input: Option<&Path>,
    read: &crate::load::ReadArgs,
    mode: ColorMode,
    demo_points: u64,
) -> Result<Scene> {
    match input {
        Some(p) if crate::load::is_store_path(p) => {
            let store = pointlet_store::Store::open(p)
                .with_context(|| format!("opening store {}", p.display()))?;
            let bounds = store.header().bounds;
            let mut acc = Accumulator::new(mode, bounds, store.header().points);
            for i in 0..store.pointlets().len() {
                let batch = store
                    .read_pointlet(i)
                    .with_context(|| format!("reading pointlet {i} of {}", p.display()))?;
                acc.push(&batch);
            }
            acc.finish(p.display().to_string())
        }
        Some(p) => {
            let reader = crate::load::open_point_file(p, read)?;
            read_all(reader, mode, p.display().to_string())
        }
        None => {
            let generator =
                pointlet_io::generate::SceneGenerator::new(pointlet_io::generate::SceneConfig {
                    points: demo_points,
                    seed: DEMO_SEED,
                });
            read_all(
                Box::new(generator.reader()),
                mode,
                format!("demo scene ({demo_points} points)"),
            )
        }
    }
}

fn read_all(
    mut reader: Box<dyn pointlet_io::PointReader>,
    mode: ColorMode,
    name: String,
) -> Result<Scene> {
    let meta = reader.meta().clone();
    let mut acc = Accumulator::new(mode, meta.bounds, meta.point_count);
    while let Some(batch) = reader
        .read_batch(1 << 20)
        .with_context(|| format!("reading {name}"))?
    {
        acc.push(&batch);
    }
    acc.finish(name)
}

struct Accumulator {
    mode: ColorMode,
    scale: Option<ColorScale>,
    bounds: Aabb,
    set: PointSet,
}

impl Accumulator {
    fn new(mode: ColorMode, bounds: Aabb, expected: u64) -> Self {
        // Reserve what the header claims, capped: a lying header must not allocate terabytes.
        let cap = expected.min(1 << 28) as usize;
        Self {
            mode,
            scale: None,
            bounds,
            set: PointSet {
                positions: Vec::with_capacity(cap),
                colors: Vec::with_capacity(cap),
            },
        }
    }

    fn push(&mut self, batch: &PointBatch) {
        let z = if self.bounds.is_empty() {
            [0.0, 1.0]
        } else {
            [self.bounds.min[2], self.bounds.max[2]]
        };
        let mode = self.mode;
        let scale = *self
            .scale
            .get_or_insert_with(|| ColorScale::fit(mode, batch, z));
        self.set.positions.extend_from_slice(&batch.xyz);
        self.set
            .colors
            .extend((0..batch.len()).map(|i| point_color(batch, i, &scale)));
    }

    fn finish(self, name: String) -> Result<Scene> {
        if self.set.is_empty() {
            bail!("{name} holds no points");
        }
        // Header bounds may be stale or absent: the camera is fitted to the real points.
        let bounds = self.set.bounds();
        Ok(Scene {
            name,
            set: self.set,
            bounds,
        })
    }
}
