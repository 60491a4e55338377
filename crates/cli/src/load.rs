//! Reading any input (store or point file) into memory for the commands that need it whole.

use anyhow::{bail, Context, Result};
use pointlet_core::Aabb;
use pointlet_io::{PointReader, ReadOptions};
use std::path::{Path, PathBuf};

/// How to read point files, for what their content does not say.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ReadArgs {
    /// Names of the columns of text point files, in order, overriding a header line
    /// (e.g. x,y,z,r,g,b,intensity; `_` skips a column).
    #[arg(long, value_delimiter = ',')]
    pub columns: Option<Vec<String>>,
}

impl ReadArgs {
    pub fn options(&self) -> ReadOptions {
        ReadOptions {
            columns: self.columns.clone(),
        }
    }
}

/// Opens one point file and prints the reader's notes.
pub fn open_point_file(path: &Path, read: &ReadArgs) -> Result<Box<dyn PointReader>> {
    let reader = pointlet_engine::open_points(path, &read.options())?;
    print_notes(reader.as_ref());
    Ok(reader)
}

/// The reader's notes, one `note:` line each.
pub fn print_notes(reader: &dyn PointReader) {
    for n in reader.notes() {
        eprintln!("note: {}: {n}", reader.path().display());
    }
}

/// What the flag checks and the point-size default see when `render` or `view` is given
/// several inputs: they are drawn together as one point file (stores among them included).
pub const SEVERAL_INPUTS: &str = "several inputs";

/// The one input drawn, [`SEVERAL_INPUTS`] for several, `None` for the demo scene.
pub fn drawn_input(inputs: &[PathBuf]) -> Option<&Path> {
    match inputs {
        [] => None,
        [one] => Some(one),
        _ => Some(Path::new(SEVERAL_INPUTS)),
    }
}

/// True for what [`drawn_input`] gives for several inputs.
pub fn is_several(input: &Path) -> bool {
    input == Path::new(SEVERAL_INPUTS)
}

/// Stores are recognised by their extension; anything else goes to the point-file readers.
pub fn is_store_path(path: &Path) -> bool {
    pointlet_engine::is_store(path)
}

/// Opens the store that `command` reads: a point file is told to be converted, not called damaged.
pub fn open_store(path: &Path, command: &str) -> Result<pointlet_store::Store> {
    match pointlet_store::Store::open(path) {
        Err(_) if !is_store_path(path) && path.is_file() => bail!(
            "{}: {command} reads a pointlet store, not a point file (`pointlet convert` makes one)",
            path.display()
        ),
        opened => Ok(opened?),
    }
}

/// All positions of a store or point file, with their bounds.
pub fn load_positions(path: &Path, read: &ReadArgs) -> Result<(Vec<[f64; 3]>, Aabb)> {
    let mut pts = Vec::new();
    let mut bounds = Aabb::EMPTY;
    if is_store_path(path) {
        let store = pointlet_store::Store::open(path)?;
        let q = store.header().quantization;
        pts.reserve(store.header().points as usize);
        for (i, p) in store.pointlets().iter().enumerate() {
            for raw in store
                .read_positions(i, 0..p.count)
                .with_context(|| format!("reading pointlet {i}"))?
            {
                let v = q.dequantize(raw);
                bounds.grow(v);
                pts.push(v);
            }
        }
    } else {
        let mut r = open_point_file(path, read)?;
        while let Some(b) = r.read_batch(1 << 20)? {
            for p in &b.xyz {
                bounds.grow(*p);
            }
            pts.extend_from_slice(&b.xyz);
        }
    }
    Ok((pts, bounds))
}
