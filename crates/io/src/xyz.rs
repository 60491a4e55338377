//! Text point files (`.xyz`, `.txt`, `.csv`, `.pts`): one point per line.
//!
//! - Separators: whitespace, comma or semicolon (decided by the first significant line: a comma
//!   anywhere means comma-separated, else a semicolon means semicolon-separated).
//! - Blank lines and lines starting with `#` or `//` are skipped; a first line holding a single
//!   integer (the point count of `.pts` files) is skipped too.
//! - Columns are named by `--columns` ([`ReadOptions::columns`]), else by a header line: the
//!   first significant line when it is not numbers, or a `//` line naming x, y and z (as
//!   CloudCompare writes `//X,Y,Z,Rf,Gf,Bf,Intensity`). Names are case-insensitive, a leading
//!   `scalar_` and the characters `_`, `-` and space are ignored: `x y z`, `intensity`/`i`,
//!   `red green blue`/`r g b`, `rf gf bf`, `nir`, `classification`/`class`, `return_number`,
//!   `number_of_returns`, `gps_time`/`time`, `point_source_id`/`source_id`, `user_data`,
//!   `scan_angle`. Other header names (normals `nx ny nz` among them) are skipped with a note;
//!   in `--columns` an unknown name is an error and `_` skips a column.
//! - Without names the column count decides: 3 = x y z, 4 = x y z intensity, 6 = x y z r g b,
//!   and for `.pts` 7 = x y z intensity r g b (the PTS layout). Any other count is ambiguous
//!   and an error that says how to name the columns.
//! - Colour: `rf gf bf` are fractions 0–1, scaled ×65535. Other colour columns are judged by
//!   their values: fractions within 0–1 are scaled ×65535, values within 0–255 are widened
//!   ×257 to LAS's 16 bits, larger ones are kept as they are. Intensity: see
//!   [`crate::ValueRange::intensity_scale`]; NIR is judged like colour.
//! - Classification, return number, number of returns, point source id and user data must be
//!   whole numbers within their LAS range; return counts missing from the file are 1.
//! - NaN, infinity or an unparsable number is an error naming the line.
//! - Positions are quantized at the decimals written (the most on each axis), coarsened by
//!   powers of ten only as far as the extent needs (see [`crate::scale`]).
//!
//! Text has no header bounds, so [`open`] parses the whole file once for the exact point count
//! and bounds (and the value ranges and decimals); reading parses it a second time, so the
//! total cost is two parses of the text.

use crate::scale::{fit_quantization, written_decimals};
use crate::{IoError, PointReader, ReadOptions, Scale, ValueRange};
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
    Nir,
    Classification,
    ReturnNumber,
    NumberOfReturns,
    GpsTime,
    PointSourceId,
    UserData,
    ScanAngle,
}

/// Values per [`Record`]: one per [`Field`].
const FIELDS: usize = Field::ScanAngle as usize + 1;

/// The names `--columns` accepts, for its error message.
const KNOWN_NAMES: &str = "x, y, z, intensity (i), red green blue (r g b), rf gf bf, nir, \
     classification (class), return_number, number_of_returns, gps_time (time), \
     point_source_id, user_data, scan_angle";

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
            Field::Nir => "nir",
            Field::Classification => "classification",
            Field::ReturnNumber => "return_number",
            Field::NumberOfReturns => "number_of_returns",
            Field::GpsTime => "gps_time",
            Field::PointSourceId => "point_source_id",
            Field::UserData => "user_data",
            Field::ScanAngle => "scan_angle",
        }
    }

    /// The largest value of a field that holds whole numbers (LAS's range for it).
    fn whole_max(self) -> Option<f64> {
        match self {
            Field::Classification | Field::UserData => Some(255.0),
            Field::ReturnNumber | Field::NumberOfReturns => Some(15.0),
            Field::PointSourceId => Some(65535.0),
            _ => None,
        }
    }

    /// The axis of a coordinate.
    fn axis(self) -> Option<usize> {
        match self {
            Field::X => Some(0),
            Field::Y => Some(1),
            Field::Z => Some(2),
            _ => None,
        }
    }

    /// The value a missing column gives.
    fn default_value(self) -> f64 {
        match self {
            Field::ReturnNumber | Field::NumberOfReturns => 1.0,
            _ => 0.0,
        }
    }
}

/// What a column name means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Named {
    Field(Field),
    /// `rf`, `gf`, `bf`: colour as fractions 0–1.
    UnitColour(Field),
    /// `_` (or an empty name): a column to skip.
    Skip,
    Unknown,
}

fn named(name: &str) -> Named {
    use Field::*;
    let lower = name.trim().to_ascii_lowercase();
    let bare = lower.strip_prefix("scalar_").unwrap_or(&lower);
    let key: String = bare
        .chars()
        .filter(|c| !matches!(c, '_' | '-' | ' '))
        .collect();
    Named::Field(match key.as_str() {
        "x" => X,
        "y" => Y,
        "z" => Z,
        "i" | "intensity" => Intensity,
        "r" | "red" => Red,
        "g" | "green" => Green,
        "b" | "blue" => Blue,
        "rf" => return Named::UnitColour(Red),
        "gf" => return Named::UnitColour(Green),
        "bf" => return Named::UnitColour(Blue),
        "nir" | "nearinfrared" => Nir,
        "classification" | "class" => Classification,
        "returnnumber" => ReturnNumber,
        "numberofreturns" => NumberOfReturns,
        "gpstime" | "time" => GpsTime,
        "pointsourceid" | "sourceid" => PointSourceId,
        "userdata" => UserData,
        "scanangle" | "scananglerank" => ScanAngle,
        "" => return Named::Skip,
        _ => return Named::Unknown,
    })
}

/// Whether `names` name x, y and z (what makes a line a header line).
fn names_xyz(names: &[&str]) -> bool {
    [Field::X, Field::Y, Field::Z]
        .iter()
        .all(|f| names.iter().any(|n| named(n) == Named::Field(*f)))
}

/// What each column up to the last one used holds.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Columns {
    sep: Sep,
    slots: Vec<Option<Field>>,
    /// The colour columns are fractions 0–1 (`rf gf bf`).
    unit_colour: bool,
    /// Lines must have exactly this many fields (the columns `--columns` names).
    exact: Option<usize>,
}

impl Columns {
    /// The layouts a column count alone makes clear; `.pts` files have their own 7.
    fn by_count(sep: Sep, n: usize, pts: bool) -> Option<Columns> {
        use Field::*;
        let fields: &[Field] = match n {
            3 => &[X, Y, Z],
            4 => &[X, Y, Z, Intensity],
            6 => &[X, Y, Z, Red, Green, Blue],
            7 if pts => &[X, Y, Z, Intensity, Red, Green, Blue],
            _ => return None,
        };
        Some(Columns {
            sep,
            slots: fields.iter().copied().map(Some).collect(),
            unit_colour: false,
            exact: None,
        })
    }

    /// Columns from names; `strict` (names the user typed): an unknown name is an error, not
    /// a note. Also returns the notes for the user.
    fn from_names(
        sep: Sep,
        names: &[&str],
        strict: bool,
    ) -> Result<(Columns, Vec<String>), String> {
        let mut slots: Vec<Option<Field>> = vec![None; names.len()];
        let mut notes = Vec::new();
        let mut unit_colour = false;
        for (i, name) in names.iter().enumerate() {
            let field = match named(name) {
                Named::Field(f) => f,
                Named::UnitColour(f) => {
                    unit_colour = true;
                    f
                }
                Named::Skip => continue,
                Named::Unknown if strict => {
                    return Err(format!(
                        "unknown column name '{name}' (known: {KNOWN_NAMES}; _ skips a column)"
                    ))
                }
                Named::Unknown => {
                    notes.push(format!("column '{name}' is not a point attribute: skipped"));
                    continue;
                }
            };
            if slots.contains(&Some(field)) {
                return Err(format!(
                    "column '{name}' names {} a second time",
                    field.name()
                ));
            }
            slots[i] = Some(field);
        }
        for f in [Field::X, Field::Y, Field::Z] {
            if !slots.contains(&Some(f)) {
                return Err(format!("the columns {names:?} name no {}", f.name()));
            }
        }
        let colour = [Field::Red, Field::Green, Field::Blue];
        let channels = colour.iter().filter(|f| slots.contains(&Some(**f))).count();
        if channels > 0 && channels < 3 {
            notes.push("colour needs red, green and blue columns: skipped".into());
            for s in slots.iter_mut() {
                if s.is_some_and(|f| colour.contains(&f)) {
                    *s = None;
                }
            }
        }
        // Columns after the last one used need not be present.
        while slots.last() == Some(&None) {
            slots.pop();
        }
        let columns = Columns {
            sep,
            slots,
            unit_colour,
            exact: None,
        };
        Ok((columns, notes))
    }

    fn has(&self, f: Field) -> bool {
        self.slots.contains(&Some(f))
    }

    /// The values of one data line; `decimals` (when given) grows to the decimals written in
    /// each coordinate.
    fn parse(
        &self,
        line: &str,
        line_no: u64,
        mut decimals: Option<&mut [i32; 3]>,
    ) -> Result<Record, String> {
        let mut r = Record::default();
        let mut seen = 0;
        for (i, text) in self.sep.fields(line).enumerate() {
            seen += 1;
            let Some(Some(f)) = self.slots.get(i) else {
                if self.exact.is_none() && i >= self.slots.len() {
                    break;
                }
                continue;
            };
            let v = number(text, f.name(), line_no)?;
            if let Some(max) = f.whole_max() {
                if v.fract() != 0.0 || !(0.0..=max).contains(&v) {
                    return Err(format!(
                        "line {line_no}: {} {text} is not a whole number within 0–{max}",
                        f.name()
                    ));
                }
            }
            if let (Some(d), Some(axis)) = (decimals.as_deref_mut(), f.axis()) {
                d[axis] = d[axis].max(written_decimals(text));
            }
            r.values[*f as usize] = v;
        }
        match self.exact {
            Some(n) if seen != n => Err(format!(
                "line {line_no} has {seen} fields but --columns names {n}"
            )),
            _ if seen < self.slots.len() => Err(format!(
                "line {line_no} has {seen} fields, {} are needed",
                self.slots.len()
            )),
            _ => Ok(r),
        }
    }
}

/// One parsed data line: a value per [`Field`], defaults where the file has no column.
struct Record {
    values: [f64; FIELDS],
}

impl Default for Record {
    fn default() -> Self {
        let mut values = [0.0; FIELDS];
        values[Field::ReturnNumber as usize] = Field::ReturnNumber.default_value();
        values[Field::NumberOfReturns as usize] = Field::NumberOfReturns.default_value();
        Record { values }
    }
}

impl Record {
    fn get(&self, f: Field) -> f64 {
        self.values[f as usize]
    }

    fn xyz(&self) -> [f64; 3] {
        [self.get(Field::X), self.get(Field::Y), self.get(Field::Z)]
    }

    fn rgb(&self) -> [f64; 3] {
        [
            self.get(Field::Red),
            self.get(Field::Green),
            self.get(Field::Blue),
        ]
    }
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

/// The columns of a file, how many lines precede its first data line, and notes for the user.
struct Detected {
    columns: Columns,
    skip: u64,
    notes: Vec<String>,
}

/// Reads the leading lines up to the first data line and decides the columns. A file that is
/// no point file at all (binary, or words that name no x, y and z) is [`IoError::NoPoints`].
fn detect(
    path: &Path,
    lines: &mut LineReader<BufReader<File>>,
    options: &ReadOptions,
    pts: bool,
) -> Result<Detected, IoError> {
    let not_points = |m: String| IoError::no_points(path, format!("not a point file: {m}"));
    let mut buf = Vec::new();
    let mut first = true;
    // A `//` comment naming x, y and z (CloudCompare's header): its text and line.
    let mut comment_header: Option<(String, u64)> = None;
    loop {
        let more = lines.next_line(&mut buf).map_err(|e| match e {
            LineError::TooLong(n) => {
                not_points(format!("line {n} is longer than {MAX_LINE} bytes"))
            }
            e => e.into_io_error(path),
        })?;
        if !more {
            return Err(IoError::no_points(
                path,
                "no points: the file holds no data lines",
            ));
        }
        let n = lines.line_no;
        let s = std::str::from_utf8(&buf)
            .map_err(|_| not_points(format!("line {n} is not text (UTF-8)")))?;
        let t = s.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        if let Some(rest) = t.strip_prefix("//") {
            let rest = rest.trim();
            let names: Vec<&str> = Sep::of(rest).fields(rest).collect();
            if comment_header.is_none() && names_xyz(&names) {
                comment_header = Some((rest.to_string(), n));
            }
            continue;
        }
        let sep = Sep::of(t);
        let count = sep.fields(t).count();
        if first && count == 1 && t.parse::<u64>().is_ok() {
            first = false;
            continue; // the point count line of a .pts file
        }
        let numeric = sep.fields(t).all(|f| f.parse::<f64>().is_ok());
        // A header line is skipped: --columns overrides it.
        let skip = if numeric { n - 1 } else { n };
        if let Some(names) = &options.columns {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let (mut columns, notes) = Columns::from_names(sep, &names, true)
                .map_err(|m| IoError::invalid(path, format!("--columns: {m}")))?;
            columns.exact = Some(names.len());
            return Ok(Detected {
                columns,
                skip,
                notes,
            });
        }
        let (header, at) = match (&comment_header, numeric) {
            (_, false) => (t, n),
            (Some((h, at)), true) => (h.as_str(), *at),
            (None, true) => {
                let columns = Columns::by_count(sep, count, pts)
                    .ok_or_else(|| IoError::invalid(path, ambiguous(n, count)))?;
                return Ok(Detected {
                    columns,
                    skip,
                    notes: Vec::new(),
                });
            }
        };
        let names: Vec<&str> = Sep::of(header).fields(header).collect();
        if !names_xyz(&names) {
            return Err(not_points(format!(
                "line {at} is neither numbers nor column names that include x, y and z"
            )));
        }
        let (columns, notes) = Columns::from_names(sep, &names, false)
            .map_err(|m| IoError::invalid(path, format!("line {at}: {m}")))?;
        return Ok(Detected {
            columns,
            skip,
            notes,
        });
    }
}

/// The message for unnamed columns whose count does not say what they are.
fn ambiguous(line: u64, count: usize) -> String {
    let at_least = if count < 3 {
        "; at least x, y and z are needed"
    } else {
        ""
    };
    format!(
        "line {line} has {count} unnamed columns{at_least}; without names only 3 (x y z), \
         4 (x y z intensity) and 6 (x y z r g b) columns are read: name them in a first line \
         such as 'x y z r g b intensity', or with --columns x,y,z,r,g,b,intensity"
    )
}

fn open_lines(path: &Path) -> Result<LineReader<BufReader<File>>, IoError> {
    let file = File::open(path).map_err(|e| IoError::io(path, e))?;
    Ok(LineReader::new(BufReader::with_capacity(1 << 20, file)))
}

/// Opens a text point file: one full pass for the point count, bounds, value ranges and the
/// decimals of the positions.
pub fn open(path: &Path, options: &ReadOptions) -> Result<Box<dyn PointReader>, IoError> {
    let pts = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pts"));
    let mut lines = open_lines(path)?;
    let Detected {
        columns,
        skip,
        notes,
    } = detect(path, &mut lines, options, pts)?;
    // Restart so the first data line is parsed with the others.
    let mut lines = open_lines(path)?;
    let mut buf = Vec::new();
    for _ in 0..skip {
        lines
            .next_line(&mut buf)
            .map_err(|e| e.into_io_error(path))?;
    }
    let mut bounds = Aabb::EMPTY;
    let mut decimals = [0i32; 3];
    let mut count = 0u64;
    let (mut intensity, mut colour, mut nir) = (
        ValueRange::default(),
        ValueRange::default(),
        ValueRange::default(),
    );
    while lines
        .next_line(&mut buf)
        .map_err(|e| e.into_io_error(path))?
    {
        let n = lines.line_no;
        let Line::Data(t) = classify(&buf, path, n)? else {
            continue;
        };
        let r = columns
            .parse(t, n, Some(&mut decimals))
            .map_err(|m| IoError::invalid(path, m))?;
        bounds.grow(r.xyz());
        count += 1;
        intensity.add(r.get(Field::Intensity));
        r.rgb().iter().for_each(|c| colour.add(*c));
        nir.add(r.get(Field::Nir));
    }
    if count == 0 {
        return Err(IoError::no_points(
            path,
            "no points: the file holds no data lines",
        ));
    }
    // None when 32-bit integers cannot span the extent even at 0.01: the merge says so.
    let quantization = fit_quantization(&bounds, decimals);
    let layout = PointLayout {
        rgb: columns.has(Field::Red),
        gps_time: columns.has(Field::GpsTime),
        nir: columns.has(Field::Nir),
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
        quantization,
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
        intensity: if columns.has(Field::Intensity) {
            intensity.intensity_scale()
        } else {
            Scale::mul(1.0)
        },
        colour: if columns.unit_colour {
            Scale::mul(65535.0)
        } else {
            colour.colour_scale()
        },
        nir: nir.colour_scale(),
        columns,
        notes,
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
    nir: Scale,
    notes: Vec<String>,
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

    fn notes(&self) -> &[String] {
        &self.notes
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
        let layout = self.meta.layout;
        let mut b = PointBatch::with_capacity(layout, n);
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
                .parse(t, line_no, None)
                .map_err(|m| IoError::invalid(path, m))?;
            // Whole-number fields were checked to be within their range while parsing.
            b.xyz.push(r.xyz());
            b.intensity
                .push(self.intensity.apply(r.get(Field::Intensity)));
            let (rn, nr) = (
                r.get(Field::ReturnNumber) as u8,
                r.get(Field::NumberOfReturns) as u8,
            );
            b.returns.push(rn | (nr << 4));
            b.flags.push(0);
            b.classification.push(r.get(Field::Classification) as u8);
            b.scan_angle.push(r.get(Field::ScanAngle) as f32);
            b.user_data.push(r.get(Field::UserData) as u8);
            b.point_source_id.push(r.get(Field::PointSourceId) as u16);
            if layout.gps_time {
                b.gps_time.push(r.get(Field::GpsTime));
            }
            if layout.rgb {
                b.rgb.push(r.rgb().map(|c| self.colour.apply(c)));
            }
            if layout.nir {
                b.nir.push(self.nir.apply(r.get(Field::Nir)));
            }
        }
        self.read += n as u64;
        Ok(Some(b))
    }
}
