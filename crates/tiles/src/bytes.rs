//! Little-endian typed values in byte buffers, with every range checked before it is read.
//!
//! The component types are those of 3D Tiles feature and batch tables (`BYTE` … `DOUBLE`,
//! 3D Tiles 1.0 §"Feature Table", §"Batch Table"), of glTF accessors (GL enums 5120–5126,
//! glTF 2.0 §3.6.2.2) and of 3D Metadata (`INT8` … `FLOAT64`). A [`Strided`] view is built only
//! when all its elements lie inside the buffer, so reading an element cannot go out of range.

/// A scalar type stored in a buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ComponentType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl ComponentType {
    pub fn size(self) -> usize {
        match self {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::I32 | ComponentType::U32 | ComponentType::F32 => 4,
            ComponentType::I64 | ComponentType::U64 | ComponentType::F64 => 8,
        }
    }

    pub fn is_float(self) -> bool {
        matches!(self, ComponentType::F32 | ComponentType::F64)
    }

    /// Batch table names (3D Tiles 1.0): `BYTE`, `UNSIGNED_BYTE`, …, `FLOAT`, `DOUBLE`.
    pub fn from_tiles_name(name: &str) -> Option<ComponentType> {
        Some(match name {
            "BYTE" => ComponentType::I8,
            "UNSIGNED_BYTE" => ComponentType::U8,
            "SHORT" => ComponentType::I16,
            "UNSIGNED_SHORT" => ComponentType::U16,
            "INT" => ComponentType::I32,
            "UNSIGNED_INT" => ComponentType::U32,
            "FLOAT" => ComponentType::F32,
            "DOUBLE" => ComponentType::F64,
            _ => return None,
        })
    }

    /// 3D Metadata names: `INT8` … `UINT64`, `FLOAT32`, `FLOAT64`.
    pub fn from_metadata_name(name: &str) -> Option<ComponentType> {
        Some(match name {
            "INT8" => ComponentType::I8,
            "UINT8" => ComponentType::U8,
            "INT16" => ComponentType::I16,
            "UINT16" => ComponentType::U16,
            "INT32" => ComponentType::I32,
            "UINT32" => ComponentType::U32,
            "INT64" => ComponentType::I64,
            "UINT64" => ComponentType::U64,
            "FLOAT32" => ComponentType::F32,
            "FLOAT64" => ComponentType::F64,
            _ => return None,
        })
    }

    /// glTF accessor component types (GL enums).
    pub fn from_gl(code: u32) -> Option<ComponentType> {
        Some(match code {
            5120 => ComponentType::I8,
            5121 => ComponentType::U8,
            5122 => ComponentType::I16,
            5123 => ComponentType::U16,
            5125 => ComponentType::U32,
            5126 => ComponentType::F32,
            _ => return None,
        })
    }

    /// The value at the start of `b` as f64 (`b` holds at least [`Self::size`] bytes).
    pub fn read_f64(self, b: &[u8]) -> f64 {
        match self {
            ComponentType::I8 => b[0] as i8 as f64,
            ComponentType::U8 => b[0] as f64,
            ComponentType::I16 => i16::from_le_bytes(array(b)) as f64,
            ComponentType::U16 => u16::from_le_bytes(array(b)) as f64,
            ComponentType::I32 => i32::from_le_bytes(array(b)) as f64,
            ComponentType::U32 => u32::from_le_bytes(array(b)) as f64,
            ComponentType::I64 => i64::from_le_bytes(array(b)) as f64,
            ComponentType::U64 => u64::from_le_bytes(array(b)) as f64,
            ComponentType::F32 => f32::from_le_bytes(array(b)) as f64,
            ComponentType::F64 => f64::from_le_bytes(array(b)),
        }
    }

    /// The integer at the start of `b`; `None` for floats and for u64 values beyond i64.
    pub fn read_i64(self, b: &[u8]) -> Option<i64> {
        Some(match self {
            ComponentType::I8 => b[0] as i8 as i64,
            ComponentType::U8 => b[0] as i64,
            ComponentType::I16 => i16::from_le_bytes(array(b)) as i64,
            ComponentType::U16 => u16::from_le_bytes(array(b)) as i64,
            ComponentType::I32 => i32::from_le_bytes(array(b)) as i64,
            ComponentType::U32 => u32::from_le_bytes(array(b)) as i64,
            ComponentType::I64 => i64::from_le_bytes(array(b)),
            ComponentType::U64 => i64::try_from(u64::from_le_bytes(array(b))).ok()?,
            ComponentType::F32 | ComponentType::F64 => return None,
        })
    }

    /// A normalized integer mapped to [0, 1] (unsigned) or [−1, 1] (signed, the most negative
    /// value clamped to −1), as glTF 2.0 §3.11 and 3D Metadata define it; floats unchanged.
    pub fn read_normalized(self, b: &[u8]) -> f64 {
        let v = self.read_f64(b);
        let max = match self {
            ComponentType::I8 => 127.0,
            ComponentType::U8 => 255.0,
            ComponentType::I16 => 32767.0,
            ComponentType::U16 => 65535.0,
            ComponentType::I32 => 2147483647.0,
            ComponentType::U32 => 4294967295.0,
            ComponentType::I64 => 9223372036854775807.0,
            ComponentType::U64 => 18446744073709551615.0,
            ComponentType::F32 | ComponentType::F64 => return v,
        };
        (v / max).max(-1.0)
    }
}

/// The first N bytes of `b` as an array (callers hand slices of at least N bytes).
fn array<const N: usize>(b: &[u8]) -> [u8; N] {
    let mut out = [0u8; N];
    out.copy_from_slice(&b[..N]);
    out
}

/// `count` elements of `element_size` bytes, the first at `offset`, `stride` bytes apart, all
/// inside `data`.
#[derive(Clone, Copy, Debug)]
pub struct Strided<'a> {
    data: &'a [u8],
    offset: usize,
    stride: usize,
    count: usize,
    element_size: usize,
}

impl<'a> Strided<'a> {
    /// The view, or a message saying how far past the buffer it would reach.
    pub fn new(
        data: &'a [u8],
        offset: usize,
        stride: usize,
        count: usize,
        element_size: usize,
    ) -> Result<Strided<'a>, String> {
        let end = if count == 0 {
            Some(offset)
        } else {
            (count - 1)
                .checked_mul(stride)
                .and_then(|v| v.checked_add(offset))
                .and_then(|v| v.checked_add(element_size))
        };
        match end {
            Some(end) if end <= data.len() => Ok(Strided {
                data,
                offset,
                stride,
                count,
                element_size,
            }),
            Some(end) => Err(format!(
                "{count} elements of {element_size} bytes at offset {offset} (stride {stride}) \
                 need {end} bytes, the buffer has {}",
                data.len()
            )),
            None => Err(format!(
                "{count} elements of {element_size} bytes at offset {offset} (stride {stride}) \
                 overflow the address space"
            )),
        }
    }

    pub fn len(&self) -> usize {
        self.count
    }

    /// Element `i` (< len).
    pub fn element(&self, i: usize) -> &'a [u8] {
        let start = self.offset + i * self.stride;
        &self.data[start..start + self.element_size]
    }
}

/// Reads `components` values of type `ty` from each element of `view` as f64 (normalized
/// integers mapped to [0, 1] / [−1, 1] when `normalized`).
pub fn read_f64s(
    view: &Strided,
    ty: ComponentType,
    components: usize,
    normalized: bool,
) -> Vec<f64> {
    let size = ty.size();
    let mut out = Vec::with_capacity(view.len() * components);
    for i in 0..view.len() {
        let e = view.element(i);
        for c in 0..components {
            let b = &e[c * size..];
            out.push(if normalized {
                ty.read_normalized(b)
            } else {
                ty.read_f64(b)
            });
        }
    }
    out
}

/// Reads `components` integers of type `ty` from each element; `None` when a value does not
/// fit i64 (or the type is a float).
pub fn read_i64s(view: &Strided, ty: ComponentType, components: usize) -> Option<Vec<i64>> {
    let size = ty.size();
    let mut out = Vec::with_capacity(view.len() * components);
    for i in 0..view.len() {
        let e = view.element(i);
        for c in 0..components {
            out.push(ty.read_i64(&e[c * size..])?);
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_refuse_ranges_past_the_buffer() {
        let data = [0u8; 16];
        assert!(Strided::new(&data, 0, 4, 4, 4).is_ok());
        assert!(Strided::new(&data, 1, 4, 4, 4).is_err());
        assert!(Strided::new(&data, 0, usize::MAX, 3, 4).is_err());
        assert!(Strided::new(&data, 99, 4, 0, 4).is_err());
    }

    #[test]
    fn normalized_integers() {
        assert_eq!(ComponentType::I8.read_normalized(&[0x80]), -1.0);
        assert_eq!(ComponentType::U8.read_normalized(&[255]), 1.0);
        assert_eq!(
            ComponentType::I16.read_normalized(&32767i16.to_le_bytes()),
            1.0
        );
        assert_eq!(ComponentType::U64.read_i64(&u64::MAX.to_le_bytes()), None);
    }
}
