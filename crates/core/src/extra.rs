//! LAS extra-bytes attributes: what the extra bytes after a point format's own fields hold,
//! from the extra-bytes record (LASF_Spec 4; LAS 1.4 R15 §2.5 and Table 24). Each 192-byte
//! descriptor names an attribute, its data type, and optionally its scale, offset and no-data
//! value; the attributes follow each other in descriptor order.

use crate::Vlr;

/// Bytes of one descriptor.
const DESCRIPTOR: usize = 192;

/// Numeric types an extra-bytes attribute can have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExtraType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl ExtraType {
    /// Types 1–10 of the specification.
    fn from_code(code: u8) -> Option<Self> {
        use ExtraType::*;
        Some(match code {
            1 => U8,
            2 => I8,
            3 => U16,
            4 => I16,
            5 => U32,
            6 => I32,
            7 => U64,
            8 => I64,
            9 => F32,
            10 => F64,
            _ => return None,
        })
    }

    pub fn bytes(self) -> usize {
        use ExtraType::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }

    pub fn name(self) -> &'static str {
        use ExtraType::*;
        match self {
            U8 => "u8",
            I8 => "i8",
            U16 => "u16",
            I16 => "i16",
            U32 => "u32",
            I32 => "i32",
            U64 => "u64",
            I64 => "i64",
            F32 => "f32",
            F64 => "f64",
        }
    }

    /// The raw value of `b` (exactly `bytes()` long) as f64; 64-bit integers may round.
    fn read(self, b: &[u8]) -> f64 {
        use ExtraType::*;
        let a = |n: usize| -> [u8; 8] {
            let mut out = [0u8; 8];
            out[..n].copy_from_slice(&b[..n]);
            out
        };
        match self {
            U8 => f64::from(b[0]),
            I8 => f64::from(b[0] as i8),
            U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            U64 => u64::from_le_bytes(a(8)) as f64,
            I64 => i64::from_le_bytes(a(8)) as f64,
            F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            F64 => f64::from_le_bytes(a(8)),
        }
    }
}

/// How to read one attribute's value out of a point's extra bytes (the part of an
/// [`ExtraAttribute`] a colour scale keeps).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExtraValue {
    /// Where the value starts inside a point's extra bytes.
    pub at: usize,
    pub kind: ExtraType,
    /// value = raw · scale + offset.
    pub scale: f64,
    pub offset: f64,
    /// A raw value meaning "no data".
    pub no_data: Option<f64>,
}

impl ExtraValue {
    /// The value in a point's extra bytes; `None` for the no-data value or bytes too short.
    pub fn read(&self, extra: &[u8]) -> Option<f64> {
        let raw = self
            .kind
            .read(extra.get(self.at..self.at + self.kind.bytes())?);
        if self.no_data == Some(raw) {
            return None;
        }
        Some(raw * self.scale + self.offset)
    }
}

/// One numeric attribute held in the extra bytes (an element of a legacy array type counts as
/// one attribute, named `name[i]`).
#[derive(Clone, Debug, PartialEq)]
pub struct ExtraAttribute {
    pub name: String,
    pub description: String,
    /// Where the value starts inside a point's extra bytes.
    pub at: usize,
    pub kind: ExtraType,
    /// value = raw · scale + offset (1 and 0 when the descriptor gives none).
    pub scale: f64,
    pub offset: f64,
    /// A raw value meaning "no data", when the descriptor gives one.
    pub no_data: Option<f64>,
}

impl ExtraAttribute {
    pub fn reader(&self) -> ExtraValue {
        ExtraValue {
            at: self.at,
            kind: self.kind,
            scale: self.scale,
            offset: self.offset,
            no_data: self.no_data,
        }
    }

    /// The attribute's value in a point's extra bytes; `None` for the no-data value or bytes
    /// too short to hold it.
    pub fn value(&self, extra: &[u8]) -> Option<f64> {
        self.reader().read(extra)
    }
}

/// What the extra bytes of a file hold.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExtraAttributes {
    pub attributes: Vec<ExtraAttribute>,
    /// Bytes the descriptors leave undescribed (type 0 "undocumented" runs and any tail).
    pub undocumented: usize,
    /// Why descriptors were not used, if some were not (one line for a `note:`).
    pub problem: Option<String>,
}

impl ExtraAttributes {
    /// The attribute called `name` (exactly, or ignoring case when that is unambiguous).
    pub fn find(&self, name: &str) -> Option<usize> {
        let exact = self.attributes.iter().position(|a| a.name == name);
        exact.or_else(|| {
            let mut same = self
                .attributes
                .iter()
                .enumerate()
                .filter(|(_, a)| a.name.eq_ignore_ascii_case(name));
            match (same.next(), same.next()) {
                (Some((i, _)), None) => Some(i),
                _ => None,
            }
        })
    }

    /// The names, for messages.
    pub fn names(&self) -> String {
        let names: Vec<&str> = self.attributes.iter().map(|a| a.name.as_str()).collect();
        if names.is_empty() {
            "none".to_string()
        } else {
            names.join(", ")
        }
    }

    /// Reads the extra-bytes record among `vlrs` for points with `extra_len` extra bytes.
    /// A damaged or inconsistent record is not an error: the bytes stay undocumented and
    /// `problem` says why (the points themselves are still good).
    pub fn from_vlrs(vlrs: &[Vlr], extra_len: usize) -> Self {
        let Some(record) = vlrs.iter().find(|v| v.is_extra_bytes()) else {
            return ExtraAttributes {
                undocumented: extra_len,
                ..Default::default()
            };
        };
        match parse(&record.data, extra_len) {
            Ok(out) => out,
            Err(problem) => ExtraAttributes {
                attributes: Vec::new(),
                undocumented: extra_len,
                problem: Some(problem),
            },
        }
    }
}

fn parse(data: &[u8], extra_len: usize) -> Result<ExtraAttributes, String> {
    if !data.len().is_multiple_of(DESCRIPTOR) {
        return Err(format!(
            "the extra-bytes record is {} bytes, not a multiple of {DESCRIPTOR}",
            data.len()
        ));
    }
    let text = |b: &[u8]| {
        let end = b.iter().position(|c| *c == 0).unwrap_or(b.len());
        String::from_utf8_lossy(&b[..end]).trim().to_string()
    };
    let f64_at = |d: &[u8], at: usize| {
        let mut a = [0u8; 8];
        a.copy_from_slice(&d[at..at + 8]);
        f64::from_le_bytes(a)
    };
    let mut out = ExtraAttributes::default();
    let mut at = 0usize;
    for d in data.chunks_exact(DESCRIPTOR) {
        let (code, options) = (d[2], d[3]);
        let name = text(&d[4..36]);
        let description = text(&d[160..192]);
        if code == 0 {
            // Undocumented bytes: `options` holds their count.
            at += usize::from(options);
            out.undocumented += usize::from(options);
            continue;
        }
        // Types 11–30 are the deprecated arrays of 2 or 3 elements of types 1–10.
        let (kind, count) = match code {
            1..=10 => (ExtraType::from_code(code), 1),
            11..=30 => (
                ExtraType::from_code((code - 1) % 10 + 1),
                usize::from((code - 1) / 10) + 1,
            ),
            _ => (None, 0),
        };
        let Some(kind) = kind else {
            return Err(format!(
                "attribute '{name}' has the unknown data type {code}"
            ));
        };
        for k in 0..count {
            // Element k's no-data, scale and offset: the first element in place, later ones in
            // the (now deprecated) slots that follow it.
            let slot = |base: usize| base + 8 * k;
            let raw_no_data = kind.read(&d[slot(40)..slot(40) + kind.bytes()]);
            out.attributes.push(ExtraAttribute {
                name: if count == 1 {
                    name.clone()
                } else {
                    format!("{name}[{k}]")
                },
                description: description.clone(),
                at,
                kind,
                scale: if options & 8 != 0 {
                    f64_at(d, slot(112))
                } else {
                    1.0
                },
                offset: if options & 16 != 0 {
                    f64_at(d, slot(136))
                } else {
                    0.0
                },
                no_data: (options & 1 != 0).then_some(raw_no_data),
            });
            at += kind.bytes();
        }
    }
    if at > extra_len {
        return Err(format!(
            "the extra-bytes record describes {at} bytes but points have {extra_len}"
        ));
    }
    out.undocumented += extra_len - at;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn descriptor(code: u8, options: u8, name: &str, scale: f64, offset: f64) -> Vec<u8> {
        let mut d = vec![0u8; DESCRIPTOR];
        d[2] = code;
        d[3] = options;
        d[4..4 + name.len()].copy_from_slice(name.as_bytes());
        d[112..120].copy_from_slice(&scale.to_le_bytes());
        d[136..144].copy_from_slice(&offset.to_le_bytes());
        d
    }

    fn vlr(data: Vec<u8>) -> Vlr {
        Vlr {
            user_id: "LASF_Spec".into(),
            record_id: 4,
            description: String::new(),
            data,
            extended: false,
        }
    }

    #[test]
    fn scalars_arrays_and_undocumented_bytes_are_laid_out_in_order() {
        let mut data = descriptor(4, 8 | 16, "height", 0.01, 100.0); // i16, scaled
        data.extend(descriptor(0, 3, "", 0.0, 0.0)); // 3 undocumented bytes
        data.extend(descriptor(13, 0, "rgb", 0.0, 0.0)); // 2 × u16 (legacy array)
        let mut nd = descriptor(9, 1, "quality", 0.0, 0.0); // f32 with no-data −1
        nd[40..44].copy_from_slice(&(-1.0f32).to_le_bytes());
        data.extend(nd);
        let x = ExtraAttributes::from_vlrs(&[vlr(data)], 2 + 3 + 4 + 4 + 2);
        let names: Vec<&str> = x.attributes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["height", "rgb[0]", "rgb[1]", "quality"]);
        assert_eq!(
            x.attributes.iter().map(|a| a.at).collect::<Vec<_>>(),
            [0, 5, 7, 9]
        );
        assert_eq!(x.undocumented, 3 + 2);
        assert_eq!(x.problem, None);
        let mut point = vec![0u8; 15];
        point[0..2].copy_from_slice(&(-250i16).to_le_bytes());
        point[7..9].copy_from_slice(&513u16.to_le_bytes());
        point[9..13].copy_from_slice(&(-1.0f32).to_le_bytes());
        let height = x.attributes[0].value(&point).unwrap();
        assert!((height - 97.5).abs() < 1e-9, "{height}");
        assert_eq!(x.attributes[2].value(&point), Some(513.0));
        assert_eq!(x.attributes[3].value(&point), None, "the no-data value");
        assert_eq!(x.attributes[3].value(&point[..11]), None, "too short");
    }

    #[test]
    fn damaged_records_leave_the_bytes_undocumented_with_a_reason() {
        let short = ExtraAttributes::from_vlrs(&[vlr(vec![0; 100])], 4);
        assert!(short.problem.unwrap().contains("multiple of 192"));
        assert!(short.attributes.is_empty() && short.undocumented == 4);
        let too_long = ExtraAttributes::from_vlrs(&[vlr(descriptor(10, 0, "t", 0.0, 0.0))], 4);
        assert!(too_long.problem.unwrap().contains("describes 8 bytes"));
        let unknown = ExtraAttributes::from_vlrs(&[vlr(descriptor(31, 0, "u", 0.0, 0.0))], 4);
        assert!(unknown.problem.unwrap().contains("unknown data type 31"));
        let none = ExtraAttributes::from_vlrs(&[], 6);
        assert_eq!((none.attributes.len(), none.undocumented), (0, 6));
    }
}
