//! Several inputs drawn as one scene: their points, in world coordinates, read one input after
//! the other, each batch widened to the union of the inputs' attributes (what an input lacks
//! reads as zero). Headers merge as `convert` merges them: inputs in different CRSs are refused.

use crate::open_points;
use pointlet_core::color::ColorMode;
use pointlet_core::parts::{PartError, PartedSource};
use pointlet_core::{PointBatch, PointLayout, SourceMeta};
use pointlet_io::{IoError, PointReader, ReadOptions};
use std::path::{Path, PathBuf};

/// Opens one input as [`open_points`] does, or several as one [`Datasets`] reader.
pub fn open_inputs(
    inputs: &[PathBuf],
    read: &ReadOptions,
) -> Result<Box<dyn PointReader>, IoError> {
    match inputs {
        [] => Err(IoError::invalid(Path::new(""), "no input to open")),
        [one] => open_points(one, read),
        several => Ok(Box::new(Datasets::open(several, read)?)),
    }
}

/// The name several inputs go by in messages: their paths joined by " + ".
pub fn inputs_name(inputs: &[PathBuf]) -> PathBuf {
    let names: Vec<String> = inputs.iter().map(|p| p.display().to_string()).collect();
    PathBuf::from(names.join(" + "))
}

pub struct Datasets {
    name: PathBuf,
    readers: Vec<Box<dyn PointReader>>,
    meta: SourceMeta,
    notes: Vec<String>,
    /// The reader `read_batch` takes points from.
    current: usize,
    /// Every input's parts in input order, when every input has parts.
    part_sizes: Option<Vec<u64>>,
    /// Index of each input's first part among all parts.
    first_part: Vec<usize>,
}

impl Datasets {
    pub fn open(inputs: &[PathBuf], read: &ReadOptions) -> Result<Self, IoError> {
        let name = inputs_name(inputs);
        let readers = inputs
            .iter()
            .map(|p| open_points(p, read))
            .collect::<Result<Vec<_>, _>>()?;
        let metas: Vec<SourceMeta> = readers.iter().map(|r| r.meta().clone()).collect();
        let names: Vec<String> = inputs.iter().map(|p| p.display().to_string()).collect();
        let meta = pointlet_store::merge_meta(&metas, &names)
            .map_err(|e| IoError::invalid(&name, format!("drawing these inputs together: {e}")))?;
        let notes = readers
            .iter()
            .flat_map(|r| {
                let path = r.path().display().to_string();
                r.notes().iter().map(move |n| format!("{path}: {n}"))
            })
            .collect();
        let mut first_part = Vec::with_capacity(readers.len());
        let part_sizes = readers
            .iter()
            .map(|r| r.parted().map(|p| p.part_sizes().to_vec()))
            .collect::<Option<Vec<_>>>()
            .map(|all| {
                let mut sizes = Vec::new();
                for s in all {
                    first_part.push(sizes.len());
                    sizes.extend(s);
                }
                sizes
            });
        Ok(Self {
            name,
            readers,
            meta,
            notes,
            current: 0,
            part_sizes,
            first_part,
        })
    }

    /// The input holding part `i` and the part's index within it.
    fn locate(&self, i: usize) -> Option<(&dyn PartedSource, usize)> {
        let k = self.first_part.partition_point(|first| *first <= i);
        let k = k.checked_sub(1)?;
        let parts = self.readers.get(k)?.parted()?;
        let local = i - self.first_part[k];
        (local < parts.part_sizes().len()).then_some((parts, local))
    }

    fn no_part(&self, i: usize) -> PartError {
        Box::new(IoError::invalid(
            &self.name,
            format!("there is no part {i}"),
        ))
    }
}

/// Widens `batch` to `layout`; columns a partial decode left empty stay consistent.
fn conform(batch: &mut PointBatch, layout: PointLayout) {
    let n = batch.len();
    let old = usize::from(batch.layout.extra_bytes);
    if batch.extra_bytes.len() != n * old {
        batch.extra_bytes = vec![0; n * old];
    }
    batch.widen(layout);
}

impl PointReader for Datasets {
    fn path(&self) -> &Path {
        &self.name
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
        while let Some(reader) = self.readers.get_mut(self.current) {
            if let Some(mut batch) = reader.read_batch(max)? {
                conform(&mut batch, self.meta.layout);
                return Ok(Some(batch));
            }
            self.current += 1;
        }
        Ok(None)
    }

    fn notes(&self) -> &[String] {
        &self.notes
    }

    fn parted(&self) -> Option<&dyn PartedSource> {
        self.part_sizes.as_ref().map(|_| self as &dyn PartedSource)
    }
}

impl PartedSource for Datasets {
    fn part_sizes(&self) -> &[u64] {
        self.part_sizes.as_deref().unwrap_or(&[])
    }

    fn decode_part(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
    ) -> Result<(), PartError> {
        let (parts, local) = self.locate(i).ok_or_else(|| self.no_part(i))?;
        parts.decode_part(local, out, scratch)?;
        conform(out, self.meta.layout);
        Ok(())
    }

    fn decode_part_for(
        &self,
        i: usize,
        out: &mut PointBatch,
        scratch: &mut Vec<u8>,
        mode: ColorMode,
    ) -> Result<(), PartError> {
        let (parts, local) = self.locate(i).ok_or_else(|| self.no_part(i))?;
        parts.decode_part_for(local, out, scratch, mode)?;
        conform(out, self.meta.layout);
        Ok(())
    }
}
