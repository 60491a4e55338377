//! Readers and writers of point files, and the synthetic scene generator.
//!
//! Every reader streams: [`PointReader::read_batch`] hands out structure-of-arrays batches and
//! no reader holds a whole file in memory unless the format forces it. Coordinates stay f64.
//!
//! [`open`] picks the reader: LAS/LAZ/COPC by the `LASF` signature (whatever the extension),
//! otherwise by extension (`.ply`; `.xyz`, `.txt`, `.csv`, `.pts`). [`open_inputs`] opens the
//! files and folders of a merge, skipping what in a folder is not a point cloud.

pub mod generate;
pub mod las;
pub mod ply;
pub mod scale;
pub mod writer;
pub mod xyz;

use pointlet_core::{PointBatch, SourceMeta};
use std::io::Read;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// What can go wrong reading or writing a point file. Every variant names the file.
#[derive(Debug, Error)]
pub enum IoError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not what it claims to be, or lies about itself (bad header, truncated, ...).
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    /// A format or feature this build does not read or write.
    #[error("{}: {message}", path.display())]
    Unsupported { path: PathBuf, message: String },
    /// The file holds no points: empty, or (text) not a point file at all.
    #[error("{}: {message}", path.display())]
    NoPoints { path: PathBuf, message: String },
    /// An error of another layer that already names the file (a store read as a point file).
    #[error(transparent)]
    Named(Box<dyn std::error::Error + Send + Sync>),
}

impl IoError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        IoError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub fn unsupported(path: &Path, message: impl Into<String>) -> Self {
        IoError::Unsupported {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub fn no_points(path: &Path, message: impl Into<String>) -> Self {
        IoError::NoPoints {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

/// A streaming source of points.
pub trait PointReader: Send + Sync {
    /// The file being read (or a descriptive pseudo-path for generated data).
    fn path(&self) -> &Path;
    /// What the header says; available before the first batch.
    fn meta(&self) -> &SourceMeta;
    /// The next batch of at most `max` points; `None` once every point was read.
    /// A reader that finds fewer points than its header claims returns an error, not `None`.
    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError>;
    /// What the reader decided that the user should hear (columns skipped, ...), one line each.
    fn notes(&self) -> &[String] {
        &[]
    }
    /// The file as parts that threads decode at once (LAS, LAZ with a chunk table); `None`
    /// when it can only be read front to back. Reading parts does not move `read_batch`.
    fn parted(&self) -> Option<&dyn pointlet_core::PartedSource> {
        None
    }
}

/// What a file's content cannot say for itself.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Names of the columns of text files, in order (overriding a header line); see [`xyz`].
    pub columns: Option<Vec<String>>,
}

/// The kinds of point file [`open`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Las,
    Ply,
    Text,
}

/// The kind an extension names (case-insensitive); `.copc.laz` ends in `.laz`.
fn kind_of_extension(path: &Path) -> Option<Kind> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "las" | "laz" => Some(Kind::Las),
        "ply" => Some(Kind::Ply),
        "xyz" | "txt" | "csv" | "pts" => Some(Kind::Text),
        _ => None,
    }
}

/// Opens any supported point file. LAS/LAZ headers are validated here; PLY and text files get
/// one full pre-pass for their exact point count and bounds (they have no header bounds).
pub fn open(path: &Path) -> Result<Box<dyn PointReader>, IoError> {
    open_with(path, &ReadOptions::default())
}

/// [`open`] with options for what the file does not say.
pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Box<dyn PointReader>, IoError> {
    let meta = std::fs::metadata(path).map_err(|e| IoError::io(path, e))?;
    if meta.is_dir() {
        return Err(IoError::invalid(path, "is a folder, not a point file"));
    }
    if !meta.is_file() {
        // A FIFO or device would block or never end.
        return Err(IoError::invalid(path, "is not a regular file"));
    }
    let mut file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
    let mut magic = [0u8; 4];
    let mut got = 0;
    while got < magic.len() {
        match file.read(&mut magic[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(IoError::io(path, e)),
        }
    }
    drop(file);
    if &magic[..got] == b"LASF" {
        return las::open(path);
    }
    match kind_of_extension(path) {
        Some(Kind::Las) => Err(IoError::invalid(
            path,
            "not a LAS/LAZ file: it does not start with the \"LASF\" signature",
        )),
        Some(Kind::Ply) => ply::open(path),
        Some(Kind::Text) => xyz::open(path, options),
        None if magic.starts_with(b"ply") => ply::open(path),
        None => Err(IoError::unsupported(
            path,
            "unknown point file type: expected .las, .laz, .copc.laz, .ply, .xyz, .txt, .csv or .pts",
        )),
    }
}

/// An input file: named on its own, or found in a folder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputFile {
    pub path: PathBuf,
    pub in_folder: bool,
}

/// A file of a folder left out of a merge, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Skipped {
    pub path: PathBuf,
    pub reason: String,
}

/// Files named as inputs are kept as given (a missing one is an error); folders expand,
/// recursively, to their files with a supported extension, sorted so merges are deterministic;
/// their other files come back as skipped. Folders reached through symbolic links are not
/// entered (no cycles).
pub fn list_inputs(inputs: &[PathBuf]) -> Result<(Vec<InputFile>, Vec<Skipped>), IoError> {
    let mut files = Vec::new();
    let mut skipped = Vec::new();
    for input in inputs {
        let meta = std::fs::metadata(input).map_err(|e| IoError::io(input, e))?;
        if meta.is_dir() {
            let mut found = Vec::new();
            walk(input, &mut found, &mut skipped)?;
            found.sort();
            files.extend(found.into_iter().map(|path| InputFile {
                path,
                in_folder: true,
            }));
        } else {
            files.push(InputFile {
                path: input.clone(),
                in_folder: false,
            });
        }
    }
    skipped.sort_by(|a, b| a.path.cmp(&b.path));
    Ok((files, skipped))
}

/// The opened inputs of a merge.
pub struct Inputs {
    pub readers: Vec<Box<dyn PointReader>>,
    /// Files of folders left out, sorted by path.
    pub skipped: Vec<Skipped>,
}

/// The readers of every input, as [`list_inputs`] lists them. A file found in a folder that
/// holds no points (or, for text, is no point file at all) is skipped; the same file named on
/// its own is an error, as is any other error.
pub fn open_inputs(inputs: &[PathBuf], options: &ReadOptions) -> Result<Inputs, IoError> {
    let (files, mut skipped) = list_inputs(inputs)?;
    let mut readers = Vec::with_capacity(files.len());
    for f in files {
        match open_with(&f.path, options) {
            Ok(r) => readers.push(r),
            Err(IoError::NoPoints { path, message }) if f.in_folder => skipped.push(Skipped {
                path,
                reason: message,
            }),
            Err(e) => return Err(e),
        }
    }
    skipped.sort_by(|a, b| a.path.cmp(&b.path));
    Ok(Inputs { readers, skipped })
}

fn walk(dir: &Path, found: &mut Vec<PathBuf>, skipped: &mut Vec<Skipped>) -> Result<(), IoError> {
    for entry in std::fs::read_dir(dir).map_err(|e| IoError::io(dir, e))? {
        let entry = entry.map_err(|e| IoError::io(dir, e))?;
        let path = entry.path();
        let kind = entry.file_type().map_err(|e| IoError::io(&path, e))?;
        if kind.is_dir() {
            walk(&path, found, skipped)?;
        } else if kind_of_extension(&path).is_some() && path.is_file() {
            found.push(path);
        } else if !kind.is_symlink() || path.is_file() {
            skipped.push(Skipped {
                path,
                reason: "not a point file: expected .las, .laz, .copc.laz, .ply, .xyz, .txt, \
                         .csv or .pts"
                    .into(),
            });
        }
    }
    Ok(())
}

/// How a numeric text/PLY column becomes a 16-bit LAS-style value, decided from the pre-pass.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ValueRange {
    pub min: f64,
    pub max: f64,
    /// Some value has a fractional part.
    pub fractional: bool,
    pub seen: bool,
}

impl ValueRange {
    pub fn add(&mut self, v: f64) {
        if !self.seen {
            (self.min, self.max, self.seen) = (v, v, true);
        }
        self.min = self.min.min(v);
        self.max = self.max.max(v);
        self.fractional |= v.fract() != 0.0;
    }

    fn is_unit(&self) -> bool {
        self.fractional && self.min >= 0.0 && self.max <= 1.0
    }

    /// Intensity: fractions within 0–1 are scaled to 0–65535; a range with negative values
    /// (e.g. PTS's -2048..2047) is shifted to start at 0; then rounded and clamped to 0–65535.
    pub fn intensity_scale(&self) -> Scale {
        if self.is_unit() {
            Scale::mul(65535.0)
        } else if self.seen && self.min < 0.0 {
            Scale {
                add: -self.min,
                mul: 1.0,
            }
        } else {
            Scale::mul(1.0)
        }
    }

    /// Colour (all channels together): fractions within 0–1 are scaled to 0–65535, values
    /// within 0–255 by 257 (LAS keeps 16-bit colour), anything larger is kept as is.
    pub fn colour_scale(&self) -> Scale {
        if self.is_unit() {
            Scale::mul(65535.0)
        } else if self.max <= 255.0 {
            Scale::mul(257.0)
        } else {
            Scale::mul(1.0)
        }
    }
}

/// `(v + add) * mul`, rounded and clamped to u16.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Scale {
    pub add: f64,
    pub mul: f64,
}

impl Scale {
    pub fn mul(mul: f64) -> Scale {
        Scale { add: 0.0, mul }
    }

    #[inline]
    pub fn apply(&self, v: f64) -> u16 {
        ((v + self.add) * self.mul).round().clamp(0.0, 65535.0) as u16
    }
}

/// Columns PLY, text and tileset points lack: a single return, never classified, no flags.
pub fn push_defaults(b: &mut PointBatch) {
    b.returns.push(0x11);
    b.flags.push(0);
    b.classification.push(0);
    b.scan_angle.push(0.0);
    b.user_data.push(0);
    b.point_source_id.push(0);
}
