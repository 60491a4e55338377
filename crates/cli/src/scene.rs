//! Points for in-core rendering: from a store, any point file, or the built-in demo scene,
//! coloured by one attribute.

use crate::view_args::ColorArg;
use anyhow::{bail, Context, Result};
use pointlet_core::color::{
    default_color, default_color_of_parts, point_colors, ColorMode, ColorScale, DefaultColor,
};
use pointlet_core::extra::ExtraAttributes;
use pointlet_core::{Aabb, PointBatch, PointLayout};
use pointlet_gpu::PointSet;
use std::path::PathBuf;

/// Points of the built-in demo scene when no input is given.
pub const DEMO_POINTS: u64 = 2_000_000;
pub const DEMO_SEED: u64 = 1;

pub struct Scene {
    pub name: String,
    pub set: PointSet,
    pub bounds: Aabb,
}

/// The colouring `asked` for, which data of `layout` (with extra-bytes attributes `extras`)
/// must have, or without one the data's default (said on stderr).
pub fn choose_color(
    asked: Option<&ColorArg>,
    layout: &PointLayout,
    extras: &ExtraAttributes,
    name: &str,
    default: impl FnOnce() -> Result<DefaultColor>,
) -> Result<ColorMode> {
    match asked {
        Some(ColorArg::Mode(mode)) if mode.available_in(layout) => Ok(*mode),
        Some(ColorArg::Mode(mode)) => bail!("{name} has no {} attribute to colour by", mode.name()),
        Some(ColorArg::Extra(attr)) => match extras.find(attr).map(u8::try_from) {
            Some(Ok(i)) => Ok(ColorMode::Extra(i)),
            _ => bail!(
                "{name} has no extra-bytes attribute '{attr}' to colour by (its extra-bytes \
                 attributes: {})",
                extras.names()
            ),
        },
        None => {
            let d = default()?;
            eprintln!("note: {name}: {d}");
            Ok(d.mode)
        }
    }
}

/// The extra-bytes attributes of data with these records and this layout.
pub fn extras_of(vlrs: &[pointlet_core::Vlr], layout: &PointLayout) -> ExtraAttributes {
    ExtraAttributes::from_vlrs(vlrs, usize::from(layout.extra_bytes))
}

/// [`choose_color`] for a store, its default chosen on a few pointlets.
pub fn store_color(asked: Option<&ColorArg>, store: &pointlet_store::Store) -> Result<ColorMode> {
    let h = store.header();
    let layout = h.layout;
    let extras = extras_of(&h.vlrs, &layout);
    choose_color(
        asked,
        &layout,
        &extras,
        &store.path().display().to_string(),
        || {
            Ok(default_color_of_parts(
                &layout,
                store.pointlets().len(),
                |i| store.read_pointlet(i),
            )?)
        },
    )
}

/// Reads every point of `inputs` (several together; none: the demo scene of `demo_points`)
/// coloured by `asked`, or by the data's default colouring.
pub fn load(
    inputs: &[PathBuf],
    read: &crate::load::ReadArgs,
    asked: Option<&ColorArg>,
    demo_points: u64,
) -> Result<Scene> {
    match inputs {
        [p] if crate::load::is_store_path(p) => {
            let store = pointlet_store::Store::open(p)?;
            let mode = store_color(asked, &store)?;
            let h = store.header();
            let extras = extras_of(&h.vlrs, &h.layout);
            let name = p.display().to_string();
            let bounds = store.header().bounds;
            let asked = ColorArg::Mode(mode);
            let mut acc = Accumulator::new(Some(&asked), extras, bounds, h.points);
            for i in 0..store.pointlets().len() {
                let batch = store
                    .read_pointlet(i)
                    .with_context(|| format!("reading pointlet {i}"))?;
                acc.push(&batch, &name)?;
            }
            acc.finish(name)
        }
        [p] => read_all(
            crate::load::open_point_file(p, read)?,
            asked,
            p.display().to_string(),
        ),
        [_, _, ..] => {
            let reader = pointlet_engine::open_inputs(inputs, &read.options())?;
            // Several inputs' notes name their file.
            for n in reader.notes() {
                eprintln!("note: {n}");
            }
            let name = reader.path().display().to_string();
            read_all(reader, asked, name)
        }
        [] => {
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
    asked: Option<&ColorArg>,
    name: String,
) -> Result<Scene> {
    let meta = reader.meta().clone();
    let extras = extras_of(&meta.vlrs, &meta.layout);
    let mut acc = Accumulator::new(asked, extras, meta.bounds, meta.point_count);
    while let Some(batch) = reader.read_batch(1 << 20)? {
        acc.push(&batch, &name)?;
    }
    acc.finish(name)
}

struct Accumulator {
    /// What was asked for (`None`: the first batch chooses the default colouring).
    mode: Option<ColorArg>,
    extras: ExtraAttributes,
    scale: Option<ColorScale>,
    bounds: Aabb,
    set: PointSet,
}

impl Accumulator {
    fn new(mode: Option<&ColorArg>, extras: ExtraAttributes, bounds: Aabb, expected: u64) -> Self {
        // Reserve what the header claims, capped: a lying header must not allocate terabytes.
        let cap = expected.min(1 << 28) as usize;
        Self {
            mode: mode.cloned(),
            extras,
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
                let mode = choose_color(
                    self.mode.as_ref(),
                    &batch.layout,
                    &self.extras,
                    name,
                    || Ok(default_color(&batch.layout, &[batch])),
                )?;
                *self
                    .scale
                    .insert(ColorScale::fit_in(mode, &[batch], z, &self.extras))
            }
        };
        self.set.positions.extend_from_slice(&batch.xyz);
        let from = self.set.colors.len();
        self.set.colors.resize(from + batch.len(), 0);
        point_colors(batch, &scale, &mut self.set.colors[from..]);
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
