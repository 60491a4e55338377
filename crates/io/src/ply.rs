//! PLY point files: `ascii`, `binary_little_endian` and `binary_big_endian`.
//!
//! Points are the `vertex` element: `x`, `y`, `z` of any numeric type (required), colour
//! `red`/`green`/`blue` (also `r`/`g`/`b`, `diffuse_red`/…), intensity (`intensity` or
//! `scalar_intensity`). Every other property, list properties included, and every other
//! element, before or after the vertices, is skipped. ASCII files hold one element per line.
//!
//! - Colour: 8-bit types are widened ×257 to LAS's 16 bits; 16- and 32-bit integers are kept
//!   (clamped to 65535); floats follow [`crate::ValueRange::colour_scale`].
//! - Intensity: [`crate::ValueRange::intensity_scale`] (integers up to 65535 are kept as is).
//! - NaN or infinite coordinates are an error naming the vertex.
//! - Positions are quantized at the finest power-of-ten step their precision calls for (ascii:
//!   the decimals written; floats: the spacing of the type at the largest magnitude; integers:
//!   1), coarsened only as far as the extent needs (see [`crate::scale`]).
//!
//! PLY has no bounds, so [`open`] reads the vertices once for the exact bounds (and value
//! ranges); reading then decodes them a second time.

use crate::scale::{f32_ulp, f64_ulp, fit_quantization, float_decimals, written_decimals};
use crate::xyz::LineReader;
use crate::{push_defaults, IoError, PointReader, Scale, ValueRange};
use pointlet_core::{Aabb, PointBatch, PointLayout, SourceMeta};
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Header lines accepted at most (a PLY header is a few dozen lines).
const MAX_HEADER_LINES: u64 = 10_000;
/// Entries a list property may hold per element (faces have a handful).
const MAX_LIST: u64 = 1 << 20;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Ty::F32 | Ty::F64)
    }

    /// The value of `b` (exactly `size()` bytes).
    fn decode(self, b: &[u8], enc: Encoding) -> f64 {
        let mut a = [0u8; 8];
        let n = self.size().min(b.len());
        a[..n].copy_from_slice(&b[..n]);
        if enc == Encoding::BigEndian {
            a[..n].reverse();
        }
        let [a0, a1, a2, a3, ..] = a;
        match self {
            Ty::I8 => f64::from(a0 as i8),
            Ty::U8 => f64::from(a0),
            Ty::I16 => f64::from(i16::from_le_bytes([a0, a1])),
            Ty::U16 => f64::from(u16::from_le_bytes([a0, a1])),
            Ty::I32 => f64::from(i32::from_le_bytes([a0, a1, a2, a3])),
            Ty::U32 => f64::from(u32::from_le_bytes([a0, a1, a2, a3])),
            Ty::F32 => f64::from(f32::from_le_bytes([a0, a1, a2, a3])),
            Ty::F64 => f64::from_le_bytes(a),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Prop {
    Scalar(Ty),
    List { count: Ty, item: Ty },
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<(String, Prop)>,
}

/// What each vertex property feeds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Coord(usize),
    Colour(usize),
    Intensity,
    Ignored,
}

#[derive(Clone, Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    vertex: usize,
    roles: Vec<Role>,
    colour_ty: Option<Ty>,
}

impl Header {
    fn vertex(&self) -> Option<&Element> {
        self.elements.get(self.vertex)
    }

    fn vertex_count(&self) -> u64 {
        self.vertex().map_or(0, |e| e.count)
    }
}

fn role(name: &str) -> Role {
    match name {
        "x" => Role::Coord(0),
        "y" => Role::Coord(1),
        "z" => Role::Coord(2),
        "red" | "r" | "diffuse_red" => Role::Colour(0),
        "green" | "g" | "diffuse_green" => Role::Colour(1),
        "blue" | "b" | "diffuse_blue" => Role::Colour(2),
        "intensity" | "scalar_intensity" => Role::Intensity,
        _ => Role::Ignored,
    }
}

fn read_header(path: &Path, lines: &mut LineReader<BufReader<File>>) -> Result<Header, IoError> {
    let bad = |m: String| IoError::invalid(path, m);
    let mut buf = Vec::new();
    let mut next = |lines: &mut LineReader<BufReader<File>>| -> Result<String, IoError> {
        if lines.line_no >= MAX_HEADER_LINES {
            return Err(IoError::invalid(
                path,
                format!("no end_header within {MAX_HEADER_LINES} lines"),
            ));
        }
        if !lines
            .next_line(&mut buf)
            .map_err(|e| e.into_io_error(path))?
        {
            return Err(IoError::invalid(
                path,
                "the PLY header has no end_header line",
            ));
        }
        Ok(String::from_utf8_lossy(&buf).trim().to_string())
    };
    if next(lines)? != "ply" {
        return Err(bad("not a PLY file: the first line is not 'ply'".into()));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let line = next(lines)?;
        let n = lines.line_no;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, _version] => {
                encoding = Some(match *kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::LittleEndian,
                    "binary_big_endian" => Encoding::BigEndian,
                    other => return Err(bad(format!("line {n}: unknown PLY format '{other}'"))),
                })
            }
            ["element", name, count] => {
                let count = count.parse::<u64>().map_err(|_| {
                    bad(format!("line {n}: element count '{count}' is not a number"))
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", "list", ct, it, name] => {
                let (Some(count), Some(item)) = (Ty::parse(ct), Ty::parse(it)) else {
                    return Err(bad(format!(
                        "line {n}: unknown list property types in '{line}'"
                    )));
                };
                if count.is_float() {
                    return Err(bad(format!("line {n}: a list count cannot be a {ct}")));
                }
                let el = elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("line {n}: property before any element")))?;
                el.props
                    .push((name.to_string(), Prop::List { count, item }));
            }
            ["property", ty, name] => {
                let ty = Ty::parse(ty)
                    .ok_or_else(|| bad(format!("line {n}: unknown property type '{ty}'")))?;
                let el = elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("line {n}: property before any element")))?;
                el.props.push((name.to_string(), Prop::Scalar(ty)));
            }
            _ => {
                return Err(bad(format!(
                    "line {n}: cannot read PLY header line '{line}'"
                )))
            }
        }
    }
    let encoding = encoding.ok_or_else(|| bad("the PLY header has no format line".into()))?;
    let vertex = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| bad("no points: the PLY file has no vertex element".into()))?;
    let mut roles = Vec::new();
    let mut have = [false; 3];
    let mut colour = [false; 3];
    let mut colour_ty = None;
    for (name, prop) in elements.get(vertex).map_or(&[][..], |e| &e.props[..]) {
        let r = role(name);
        match (r, prop) {
            (Role::Coord(a), Prop::Scalar(_)) => have[a] = true,
            (Role::Colour(c), Prop::Scalar(t)) => {
                colour[c] = true;
                colour_ty = Some(*t);
            }
            (Role::Ignored, _) | (Role::Intensity, Prop::Scalar(_)) => {}
            (_, Prop::List { .. }) => {
                return Err(bad(format!(
                    "vertex property '{name}' is a list, not a number"
                )))
            }
        }
        roles.push(r);
    }
    if have != [true; 3] {
        return Err(bad("the vertex element lacks x, y or z".into()));
    }
    if colour != [true; 3] {
        // Partial colour is not colour: ignore the channels present.
        for r in roles.iter_mut() {
            if matches!(r, Role::Colour(_)) {
                *r = Role::Ignored;
            }
        }
        colour_ty = None;
    }
    Ok(Header {
        encoding,
        elements,
        vertex,
        roles,
        colour_ty,
    })
}

/// Values of one vertex.
#[derive(Clone, Copy, Debug, Default)]
struct Vertex {
    xyz: [f64; 3],
    rgb: [f64; 3],
    intensity: f64,
}

/// Reads elements from the data section.
struct Body {
    path: PathBuf,
    header: Header,
    layout: Arc<VertexLayout>,
    lines: LineReader<BufReader<File>>,
    buf: Vec<u8>,
    /// Ascii only: the most decimals written in each coordinate so far.
    decimals: [i32; 3],
}

/// The vertex properties with their roles; binary offsets when no property is a list.
struct VertexLayout {
    props: Vec<(String, Prop, Role)>,
    stride: Option<usize>,
    offsets: Vec<usize>,
}

impl VertexLayout {
    fn new(h: &Header) -> VertexLayout {
        let props: Vec<(String, Prop, Role)> = h
            .vertex()
            .map(|e| &e.props[..])
            .unwrap_or_default()
            .iter()
            .zip(h.roles.iter())
            .map(|((n, p), r)| (n.clone(), p.clone(), *r))
            .collect();
        let mut offsets = Vec::with_capacity(props.len());
        let mut stride = Some(0usize);
        for (_, p, _) in &props {
            offsets.push(stride.unwrap_or(0));
            stride = match p {
                Prop::Scalar(t) => stride.map(|s| s + t.size()),
                Prop::List { .. } => None,
            };
        }
        VertexLayout {
            props,
            stride,
            offsets,
        }
    }
}

impl Body {
    fn open(path: &Path) -> Result<Body, IoError> {
        let file = File::open(path).map_err(|e| IoError::io(path, e))?;
        let mut lines = LineReader::new(BufReader::with_capacity(1 << 20, file));
        let header = read_header(path, &mut lines)?;
        let mut body = Body {
            path: path.to_path_buf(),
            layout: Arc::new(VertexLayout::new(&header)),
            header,
            lines,
            buf: Vec::new(),
            decimals: [0; 3],
        };
        for e in 0..body.header.vertex {
            body.skip_element(e)?;
        }
        Ok(body)
    }

    fn ends_early(&self, what: &str, index: u64, of: u64) -> IoError {
        IoError::invalid(
            &self.path,
            format!("the file ends early: {what} {index} of the {of} the header claims is missing"),
        )
    }

    fn read_exact(&mut self, n: usize) -> Result<bool, IoError> {
        self.buf.resize(n, 0);
        match self.lines.inner_mut().read_exact(&mut self.buf) {
            Ok(()) => Ok(true),
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Ok(false),
            Err(e) => Err(IoError::io(&self.path, e)),
        }
    }

    fn skip_element(&mut self, index: usize) -> Result<(), IoError> {
        let Some(el) = self.header.elements.get(index).cloned() else {
            return Ok(());
        };
        let enc = self.header.encoding;
        if enc == Encoding::Ascii {
            for i in 0..el.count {
                if !self
                    .lines
                    .next_line(&mut self.buf)
                    .map_err(|e| e.into_io_error(&self.path))?
                {
                    return Err(self.ends_early(&el.name, i, el.count));
                }
            }
            return Ok(());
        }
        let fixed: Option<usize> = el
            .props
            .iter()
            .map(|(_, p)| match p {
                Prop::Scalar(t) => Some(t.size()),
                Prop::List { .. } => None,
            })
            .sum();
        if let Some(size) = fixed {
            let bytes = el.count.saturating_mul(size as u64);
            let skipped = std::io::copy(
                &mut self.lines.inner_mut().by_ref().take(bytes),
                &mut std::io::sink(),
            )
            .map_err(|e| IoError::io(&self.path, e))?;
            if skipped < bytes {
                return Err(self.ends_early(&el.name, skipped / size.max(1) as u64, el.count));
            }
            return Ok(());
        }
        for i in 0..el.count {
            for (_, p) in &el.props {
                let ok = match p {
                    Prop::Scalar(t) => self.read_exact(t.size())?,
                    Prop::List { count, item } => self.skip_list(*count, *item, &el.name, i)?,
                };
                if !ok {
                    return Err(self.ends_early(&el.name, i, el.count));
                }
            }
        }
        Ok(())
    }

    /// Skips one binary list property; `false` at the end of the file.
    fn skip_list(&mut self, count: Ty, item: Ty, el: &str, i: u64) -> Result<bool, IoError> {
        if !self.read_exact(count.size())? {
            return Ok(false);
        }
        let n = count.decode(&self.buf, self.header.encoding);
        if !(0.0..=MAX_LIST as f64).contains(&n) {
            return Err(IoError::invalid(
                &self.path,
                format!("{el} {i}: a list of {n} entries"),
            ));
        }
        self.read_exact(n as usize * item.size())
    }

    /// The next vertex (`index` counts from 0, for messages).
    fn vertex(&mut self, index: u64) -> Result<Vertex, IoError> {
        let total = self.header.vertex_count();
        let enc = self.header.encoding;
        let layout = Arc::clone(&self.layout);
        let mut v = Vertex::default();
        let mut set = |role: Role, value: f64| match role {
            Role::Coord(a) => v.xyz[a] = value,
            Role::Colour(c) => v.rgb[c] = value,
            Role::Intensity => v.intensity = value,
            Role::Ignored => {}
        };
        if enc == Encoding::Ascii {
            if !self
                .lines
                .next_line(&mut self.buf)
                .map_err(|e| e.into_io_error(&self.path))?
            {
                return Err(self.ends_early("vertex", index, total));
            }
            let line = self.lines.line_no;
            let path = &self.path;
            let at =
                |m: String| IoError::invalid(path, format!("vertex {index} (line {line}): {m}"));
            let text = std::str::from_utf8(&self.buf).map_err(|_| at("not text".into()))?;
            let mut words = text.split_whitespace();
            for (name, p, role) in layout.props.iter() {
                let mut word = || {
                    words
                        .next()
                        .ok_or_else(|| at(format!("no value for '{name}'")))
                };
                let num = |w: &str| {
                    w.parse::<f64>()
                        .map_err(|_| at(format!("'{w}' is not a number")))
                };
                match p {
                    Prop::Scalar(_) => {
                        let w = word()?;
                        if let Role::Coord(a) = role {
                            self.decimals[*a] = self.decimals[*a].max(written_decimals(w));
                        }
                        set(*role, num(w)?)
                    }
                    Prop::List { .. } => {
                        let n = num(word()?)?;
                        if !(0.0..=MAX_LIST as f64).contains(&n) {
                            return Err(at(format!("a list of {n} entries")));
                        }
                        for _ in 0..n as u64 {
                            word()?;
                        }
                    }
                }
            }
        } else if let Some(stride) = layout.stride {
            if !self.read_exact(stride)? {
                return Err(self.ends_early("vertex", index, total));
            }
            for (offset, (_, p, role)) in layout.offsets.iter().zip(layout.props.iter()) {
                if let (Prop::Scalar(t), Some(b)) = (p, self.buf.get(*offset..)) {
                    set(*role, t.decode(b, enc));
                }
            }
        } else {
            for (_, p, role) in layout.props.iter() {
                let ok = match p {
                    Prop::Scalar(t) => {
                        let ok = self.read_exact(t.size())?;
                        set(*role, t.decode(&self.buf, enc));
                        ok
                    }
                    Prop::List { count, item } => self.skip_list(*count, *item, "vertex", index)?,
                };
                if !ok {
                    return Err(self.ends_early("vertex", index, total));
                }
            }
        }
        if let Some(a) = v.xyz.iter().position(|c| !c.is_finite()) {
            return Err(IoError::invalid(
                &self.path,
                format!(
                    "vertex {index}: coordinate {} is {}, not a finite number",
                    ["x", "y", "z"][a],
                    v.xyz[a]
                ),
            ));
        }
        Ok(v)
    }
}

/// The type of x, y and z (the header has checked that each is a scalar).
fn coordinate_types(h: &Header) -> [Ty; 3] {
    let mut types = [Ty::F64; 3];
    for ((_, p), r) in h
        .vertex()
        .map_or(&[][..], |e| &e.props[..])
        .iter()
        .zip(&h.roles)
    {
        if let (Role::Coord(a), Prop::Scalar(t)) = (r, p) {
            types[*a] = *t;
        }
    }
    types
}

/// Opens a PLY file: one pass over the vertices for the exact bounds and value ranges.
pub fn open(path: &Path) -> Result<Box<dyn PointReader>, IoError> {
    let mut body = Body::open(path)?;
    let count = body.header.vertex_count();
    if count == 0 {
        return Err(IoError::no_points(
            path,
            "no points: the vertex element is empty",
        ));
    }
    let has_intensity = body.header.roles.contains(&Role::Intensity);
    let colour_ty = body.header.colour_ty;
    let mut bounds = Aabb::EMPTY;
    let mut magnitude = [0f64; 3];
    let (mut intensity, mut colour) = (ValueRange::default(), ValueRange::default());
    for i in 0..count {
        let v = body.vertex(i)?;
        bounds.grow(v.xyz);
        for (m, c) in magnitude.iter_mut().zip(v.xyz) {
            *m = m.max(c.abs());
        }
        intensity.add(v.intensity);
        v.rgb.iter().for_each(|c| colour.add(*c));
    }
    let decimals = match body.header.encoding {
        Encoding::Ascii => body.decimals,
        _ => {
            let types = coordinate_types(&body.header);
            std::array::from_fn(|a| match types[a] {
                Ty::F32 => float_decimals(magnitude[a], f32_ulp),
                Ty::F64 => float_decimals(magnitude[a], f64_ulp),
                _ => 0,
            })
        }
    };
    // None when 32-bit integers cannot span the extent even at 0.01: the merge says so.
    let quantization = fit_quantization(&bounds, decimals);
    let colour_scale = match colour_ty {
        Some(Ty::U8 | Ty::I8) => Scale::mul(257.0),
        Some(t) if t.is_float() => colour.colour_scale(),
        _ => Scale::mul(1.0),
    };
    let encoding = match body.header.encoding {
        Encoding::Ascii => "ascii",
        Encoding::LittleEndian => "binary little endian",
        Encoding::BigEndian => "binary big endian",
    };
    let meta = SourceMeta {
        format: format!("PLY ({encoding})"),
        point_count: count,
        bounds,
        quantization,
        layout: PointLayout {
            rgb: colour_ty.is_some(),
            ..Default::default()
        },
        las_point_format: None,
        vlrs: Vec::new(),
        las: None,
    };
    Ok(Box::new(PlyReader {
        body: Body::open(path)?,
        meta,
        intensity: if has_intensity {
            intensity.intensity_scale()
        } else {
            Scale::mul(1.0)
        },
        colour: colour_scale,
        read: 0,
    }))
}

struct PlyReader {
    body: Body,
    meta: SourceMeta,
    intensity: Scale,
    colour: Scale,
    read: u64,
}

impl PointReader for PlyReader {
    fn path(&self) -> &Path {
        &self.body.path
    }

    fn meta(&self) -> &SourceMeta {
        &self.meta
    }

    fn read_batch(&mut self, max: usize) -> Result<Option<PointBatch>, IoError> {
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
        for _ in 0..n {
            let v = self.body.vertex(self.read)?;
            self.read += 1;
            b.xyz.push(v.xyz);
            b.intensity.push(self.intensity.apply(v.intensity));
            if self.meta.layout.rgb {
                b.rgb.push(v.rgb.map(|c| self.colour.apply(c)));
            }
            push_defaults(&mut b);
        }
        Ok(Some(b))
    }
}
