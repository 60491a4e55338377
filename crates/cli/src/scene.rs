//! Points for in-core rendering: from a store, any point file, or the built-in demo scene,
//! coloured by one attribute.

use anyhow::{bail, Context, Result};
use pointlet_core::color::{
    default_color, default_color_of_parts, point_color, ColorMode, ColorScale, DefaultColor,
};
use pointlet_core::{Aabb, PointBatch, PointLayout};
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

/// The colouring `asked` for, which data of `layout` must have, or without one the data's
/// default (said on stderr).
pub fn choose_color(
    asked: Option<ColorMode>,
    layout: &PointLayout,
    name: &str,
    default: impl FnOnce() -> Result<DefaultColor>,
) -> Result<ColorMode> {
    match asked {
        Some(mode) if mode.available_in(layout) => Ok(mode),
        Some(mode) => bail!("{name} has no {} attribute to colour by", mode.name()),
        None => {
            let d = default()?;
            eprintln!("note: {name}: {d}");
            Ok(d.mode)
        }
    }
}

/// [`choose_color`] for a store, its default chosen on a few pointlets.
pub fn store_color(asked: Option<ColorMode>, store: &pointlet_store::Store) -> Result<ColorMode> {
    let layout = store.header().layout;
    choose_color(asked, &layout, &store.path().display().to_string(), || {
        Ok(default_color_of_parts(
            &layout,
            store.pointlets().len(),
            |i| store.read_pointlet(i),
        )?)
    })
}

/// Reads every point of `input` (or the demo scene of `demo_points`) coloured by `asked`, or
/// by the data's default colouring.
pub fn load(
    input: Option<&Path>,
    read: &crate::load::ReadArgs,
    asked: Option<ColorMode>,
    demo_points: u64,
) -> Result<Scene> {
    match input {
        Some(p) if crate::load::is_store_path(p) => {
            let store = pointlet_store::Store::open(p)?;
            let mode = store_color(asked, &store)?;
            let name = p.display().to_string();
            let bounds = store.header().bounds;
            let mut acc = Accumulator::new(Some(mode), bounds, store.header().points);
            for i in 0..store.pointlets().len() {
                let batch = store
                    .read_pointlet(i)
                    .with_context(|| format!("reading pointlet {i}"))?;
                acc.push(&batch, &name)?;
            }
            acc.finish(name)
        }
        Some(p) => read_all(
            crate::load::open_point_file(p, read)?,
            asked,
            p.display().to_string(),
        ),
        None => {
            let generator =
                pointlet_io::generate::SceneGenerator::new(pointlet_io::generate::SceneConfig {
                    points: demo_points,
                    seed: DEMO_SEED,
                });
            read_all(
                Box::new(generator.reader()),
                asked,
                "demo scene".to_string(),
            )
        }
    }
}

fn read_all(
    mut reader: Box<dyn pointlet_io::PointReader>,
    asked: Option<ColorMode>,
    name: String,
) -> Result<Scene> {
    let meta = reader.meta().clone();
    let mut acc = Accumulator::new(asked, meta.bounds, meta.point_count);
    while let Some(batch) = reader.read_batch(1 << 20)? {
        acc.push(&batch, &name)?;
    }
    acc.finish(name)
}

struct Accumulator {
    /// `None` until the first batch chooses the default colouring.
    mode: Option<ColorMode>,
    scale: Option<ColorScale>,
    bounds: Aabb,
    set: PointSet,
}

impl Accumulator {
    fn new(mode: Option<ColorMode>, bounds: Aabb, expected: u64) -> Self {
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

    /// Adds a batch of the data called `name`; the first one fits the colour scale (and
    /// chooses the colouring unless one was asked for, as the viewer does).
    fn push(&mut self, batch: &PointBatch, name: &str) -> Result<()> {
        let scale = match self.scale {
            Some(scale) => scale,
            None => {
                let z = if self.bounds.is_empty() {
                    [0.0, 1.0]
                } else {
                    [self.bounds.min[2], self.bounds.max[2]]
                };
                let mode = choose_color(self.mode, &batch.layout, name, || {
                    Ok(default_color(&batch.layout, &[batch]))
                })?;
                *self.scale.insert(ColorScale::fit(mode, &[batch], z))
            }
        };
        self.set.positions.extend_from_slice(&batch.xyz);
        self.set
            .colors
            .extend((0..batch.len()).map(|i| point_color(batch, i, &scale)));
        Ok(())
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
