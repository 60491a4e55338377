//! Text point files (`.xyz`, `.txt`, `.csv`, `.pts`): one point per line.
//!
//! - Separators: whitespace, comma or semicolon (decided by the first significant line: a comma
//!   anywhere means comma-separated, else a semicolon means semicolon-separated).
//! - Blank lines and lines starting with `#` or `//` are skipped; a first line holding a single
//!   integer (the point count of `.pts` files) is skipped too.
//! - An optional header line names the columns: `x`, `y`, `z`, `r`/`red`, `g`/`green`,
//!   `b`/`blue`, `i`/`intensity` (case-insensitive); other columns are ignored.
//! - Without names the column count decides: 3 = x y z, 4 = x y z intensity, 6 = x y z r g b,
//!   7 = x y z intensity r g b; any other count of at least 3 reads x y z and ignores the rest.
//! - Colour: values within 0–255 are widened ×257 to LAS's 16 bits unless some value in the
//!   file exceeds 255 (then kept as they are); fractions within 0–1 are scaled ×65535.
//!   Intensity: see [`crate::ValueRange::intensity_scale`].
//! - NaN, infinity or an unparsable number is an error naming the line.
//!
//! Text has no header bounds, so [`open`] parses the whole file once for the exact point count
//! and bounds (and the colour/intensity ranges); reading parses it a second time, so the
//! total cost is two parses of the text.

use crate::{push_defaults, IoError, PointReader, Scale, ValueRange};
use pointlet_core::{Aabb, PointBatch, PointLayout, SourceMeta};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// Longest line accepted (bounds memory on a file without line breaks).
pub(crate) const MAX_LINE: usize = 1 << 20;

/// Reads lines of at most [`MAX_LINE`] bytes without the line break, counting them.
pub(crate) struct LineReader<R> {
    inner: R,
    pub line_no: u64,
}

impl<R: BufRead> LineReader<R> {
    pub fn new(inner: R) -> Self {
        LineReader { inner, line_no: 0 }
    }

    /// The next line into `buf`; `false` at the end of the input.
    pub fn next_line(&mut self, buf: &mut Vec<u8>) -> Result<bool, LineError> {
        buf.clear();
        let mut any = false;
        loop {
            let avail = self.inner.fill_buf().map_err(LineError::Io)?;
            if avail.is_empty() {
                break;
            }
            any = true;
            match avail.iter().position(|b| *b == b'\n') {
                Some(i) => {
                    buf.extend_from_slice(&avail[..i]);
                    self.inner.consume(i + 1);
                    break;
                }
                None => {
                    let n = avail.len();
                    buf.extend_from_slice(avail);
                    self.inner.consume(n);
                }
            }
            if buf.len() > MAX_LINE {
                return Err(LineError::TooLong(self.line_no + 1));
            }
        }
        if !any {
            return Ok(false);
        }
        if buf.len() > MAX_LINE {
            return Err(LineError::TooLong(self.line_no + 1));
        }
        if buf.last() == Some(&b'\r') {
            buf.pop();
        }
        self.line_no += 1;
        Ok(true)
    }

    pub fn inner_mut(&mut self) -> &mut R {
        &mut self.inner
    }
}

pub(crate) enum LineError {
    Io(std::io::Error),
    TooLong(u64),
}

impl LineError {
    pub fn into_io_error(self, path: &Path) -> IoError {
        match self {
            LineError::Io(e) => IoError::io(path, e),
            LineError::TooLong(n) => IoError::invalid(
                path,
                format!("line {n} is longer than {MAX_LINE} bytes: not a point text file"),
            ),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sep {
    Whitespace,
    Comma,
    Semicolon,
}

impl Sep {
    fn of(line: &str) -> Sep {
        if line.contains(',') {
            Sep::Comma
        } else if line.contains(';') {
            Sep::Semicolon
        } else {
            Sep::Whitespace
        }
    }

    /// The fields of `line`, without allocating (an empty CSV field stays, as an empty str).
    fn fields(self, line: &str) -> impl Iterator<Item = &str> {
        line.split(move |c: char| match self {
            Sep::Whitespace => c.is_whitespace(),
            Sep::Comma => c == ',',
            Sep::Semicolon => c == ';',
        })
        .map(str::trim)
        .filter(move |f| self != Sep::Whitespace || !f.is_empty())
    }
}

/// What a column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Field {
    X,
    Y,
    Z,
    Intensity,
    Red,
    Green,
    Blue,
}

impl Field {
    fn name(self) -> &'static str {
        match self {
            Field::X => "x",
            Field::Y => "y",
            Field::Z => "z",
            Field::Intensity => "intensity",
            Field::Red => "red",
            Field::Green => "green",
            Field::Blue => "blue",
        }
    }
}

/// What each column up to the last one used holds.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Columns {
    sep: Sep,
    slots: Vec<Option<Field>>,
}

impl Columns {
    fn by_count(sep: Sep, n: usize) -> Columns {
        use Field::*;
        let fields: &[Field] = match n {
            4 => &[X, Y, Z, Intensity],
            6 => &[X, Y, Z, Red, Green, Blue],
            7 => &[X, Y, Z, Intensity, Red, Green, Blue],
            _ => &[X, Y, Z],
        };
        Columns {
            sep,
            slots: fields.iter().copied().map(Some).collect(),
        }
    }

    fn from_names<'a>(sep: Sep, names: impl Iterator<Item = &'a str>) -> Result<Columns, String> {
        let names: Vec<&str> = names.collect();
        let find = |want: &[&str]| {
            names
                .iter()
                .position(|n| want.iter().any(|w| n.eq_ignore_ascii_case(w)))
        };
        let mut slots = vec![None; names.len()];
        let (Some(x), Some(y), Some(z)) = (find(&["x"]), find(&["y"]), find(&["z"])) else {
            return Err(format!(
                "the header line names the columns {names:?} but not x, y and z"
            ));
        };
        for (at, f) in [(x, Field::X), (y, Field::Y), (z, Field::Z)] {
            slots[at] = Some(f);
        }
        if let Some(i) = find(&["i", "intensity"]) {
            slots[i] = Some(Field::Intensity);
        }
        if let (Some(r), Some(g), Some(b)) = (
            find(&["r", "red"]),
            find(&["g", "green"]),
            find(&["b", "blue"]),
        ) {
            for (at, f) in [(r, Field::Red), (g, Field::Green), (b, Field::Blue)] {
                slots[at] = Some(f);
            }
        }
        // Columns after the last one used need not be present.
        while slots.last() == Some(&None) {
            slots.pop();
        }
        Ok(Columns { sep, slots })
    }

    fn has(&self, f: Field) -> bool {
        self.slots.contains(&Some(f))
    }

    fn has_rgb(&self) -> bool {
        self.has(Field::Red)
    }

    fn parse(&self, line: &str, line_no: u64) -> Result<Record, String> {
        let mut r = Record::default();
        let mut seen = 0;
        for (text, slot) in self.sep.fields(line).zip(self.slots.iter()) {
            seen += 1;
            let Some(f) = slot else { continue };
            let v = number(text, f.name(), line_no)?;
            match f {
                Field::X => r.xyz[0] = v,
                Field::Y => r.xyz[1] = v,
                Field::Z => r.xyz[2] = v,
                Field::Intensity => r.intensity = v,
                Field::Red => r.rgb[0] = v,
                Field::Green => r.rgb[1] = v,
                Field::Blue => r.rgb[2] = v,
            }
        }
        if seen < self.slots.len() {
            return Err(format!(
                "line {line_no} has {seen} fields, {} are needed",
                self.slots.len()
            ));
        }
        Ok(r)
    }
}

/// One parsed data line.
#[derive(Default)]
struct Record {
    xyz: [f64; 3],
    intensity: f64,
    rgb: [f64; 3],
}

fn number(field: &str, what: &str, line: u64) -> Result<f64, String> {
    let v: f64 = field
        .parse()
        .map_err(|_| format!("line {line}: {what} '{field}' is not a number"))?;
    if !v.is_finite() {
        return Err(format!(
            "line {line}: {what} is {field}, not a finite number"
        ));
    }
    Ok(v)
}

/// What a line is, once the columns are known.
enum Line<'a> {
    Skip,
    Data(&'a str),
}

fn classify<'a>(line: &'a [u8], path: &Path, line_no: u64) -> Result<Line<'a>, IoError> {
    let s = std::str::from_utf8(line)
        .map_err(|_| IoError::invalid(path, format!("line {line_no} is not text (UTF-8)")))?;
    let t = s.trim();
    if t.is_empty() || t.starts_with('#') || t.starts_with("//") {
        Ok(Line::Skip)
    } else {
        Ok(Line::Data(t))
    }
}

/// Reads the leading lines up to the first data line: the columns, and how many lines precede it.
fn detect(path: &Path, lines: &mut LineReader<BufReader<File>>) -> Result<(Columns, u64), IoError> {
    let mut buf = Vec::new();
    let mut first = true;
    loop {
        if !lines
            .next_line(&mut buf)
            .map_err(|e| e.into_io_error(path))?
        {
            return Err(IoError::invalid(
                path,
                "no points: the file holds no data lines",
            ));
        }
        let n = lines.line_no;
        let Line::Data(t) = classify(&buf, path, n)? else {
            continue;
        };
        let sep = Sep::of(t);
        let count = sep.fields(t).count();
        if first && count == 1 && t.parse::<u64>().is_ok() {
            first = false;
            continue; // the point count line of a .pts file
        }
        let numeric = sep.fields(t).all(|f| f.parse::<f64>().is_ok());
        if numeric {
            if count < 3 {
                return Err(IoError::invalid(
                    path,
                    format!("line {n} has {count} fields; at least x, y and z are needed"),
                ));
            }
            return Ok((Columns::by_count(sep, count), n - 1));
        }
        let columns = Columns::from_names(sep, sep.fields(t))
            .map_err(|m| IoError::invalid(path, format!("line {n}: {m}")))?;
        return Ok((columns, n));
    }
}

fn open_lines(path: &Path) -> Result<LineReader<BufReader<File>>, IoError> {
    let file = File::open(path).map_err(|e| IoError::io(path, e))?;
    Ok(LineReader::new(BufReader::with_capacity(1 << 20, file)))
}

/// Opens a text point file: one full pass for the point count, bounds and value ranges.
pub fn open(path: &Path) -> Result<Box<dyn PointReader>, IoError> {
    let mut lines = open_lines(path)?;
    let (columns, skip) = detect(path, &mut lines)?;
    // Restart so the first data line is parsed with the others.
    let mut lines = open_lines(path)?;
    let mut buf = Vec::new();
    for _ in 0..skip {
        lines
            .next_line(&mut buf)
            .map_err(|e| e.into_io_error(path))?;
    }
    let mut bounds = Aabb::EMPTY;
    let (mut count, mut intensity, mut colour) =
        (0u64, ValueRange::default(), ValueRange::default());
    while lines
        .next_line(&mut buf)
        .map_err(|e| e.into_io_error(path))?
    {
        let n = lines.line_no;
        let Line::Data(t) = classify(&buf, path, n)? else {
            continue;
        };
        let r = columns.parse(t, n).map_err(|m| IoError::invalid(path, m))?;
        bounds.grow(r.xyz);
        count += 1;
        if columns.has(Field::Intensity) {
            intensity.add(r.intensity);
        }
        if columns.has_rgb() {
            r.rgb.iter().for_each(|c| colour.add(*c));
        }
    }
    if count == 0 {
        return Err(IoError::invalid(
            path,
            "no points: the file holds no data lines",
        ));
    }
    let layout = PointLayout {
        rgb: columns.has_rgb(),
        ..Default::default()
    };
    let sep = match columns.sep {
        Sep::Whitespace => "whitespace",
        Sep::Comma => "comma",
        Sep::Semicolon => "semicolon",
    };
    let meta = SourceMeta {
        format: format!("text ({sep}-separated)"),
        point_count: count,
        bounds,
        quantization: None,
        layout,
        las_point_format: None,
        vlrs: Vec::new(),
        las: None,
    };
    Ok(Box::new(TextReader {
        path: path.to_path_buf(),
        meta,
        lines: open_lines(path)?,
        skip,
        columns,
        intensity: intensity.intensity_scale(),
        colour: colour.colour_scale(),
        buf: Vec::new(),
        read: 0,
    }))
}

struct TextReader {
    path: PathBuf,
    meta: SourceMeta,
    lines: LineReader<BufReader<File>>,
    /// Lines before the first data line not yet skipped.
    skip: u64,
    columns: Columns,
    intensity: Scale,
    colour: Scale,
    buf: Vec<u8>,
    read: u64,
}

impl PointReader for TextReader {
    fn path(&self) -> &Path {
        &self.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
        let path = &self.path;
        while self.skip > 0 {
            self.lines
                .next_line(&mut self.buf)
                .map_err(|e| e.into_io_error(path))?;
            self.skip -= 1;
        }
        let left = self.meta.point_count - self.read;
        let n = max
            .min(1 << 20)
            .min(usize::try_from(left).unwrap_or(usize::MAX));
        if left == 0 {
            return Ok(None);
        }
        if n == 0 {
            return Ok(Some(PointBatch::new(self.meta.layout)));
        }
        let mut b = PointBatch::with_capacity(self.meta.layout, n);
        while b.len() < n {
            if !self
                .lines
                .next_line(&mut self.buf)
                .map_err(|e| e.into_io_error(path))?
            {
                return Err(IoError::invalid(
                    path,
                    format!(
                        "the file changed while being read: it ends after {} of {} points",
                        self.read + b.len() as u64,
                        self.meta.point_count
                    ),
                ));
            }
            let line_no = self.lines.line_no;
            let Line::Data(t) = classify(&self.buf, path, line_no)? else {
                continue;
            };
            let r = self
                .columns
                .parse(t, line_no)
                .map_err(|m| IoError::invalid(path, m))?;
            b.xyz.push(r.xyz);
            b.intensity.push(self.intensity.apply(r.intensity));
            if self.meta.layout.rgb {
                b.rgb.push(r.rgb.map(|c| self.colour.apply(c)));
            }
            push_defaults(&mut b);
        }
        self.read += n as u64;
        Ok(Some(b))
    }
}
