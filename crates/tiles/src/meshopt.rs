//! Buffer views compressed with EXT_meshopt_compression (glTF extension; the same layout as
//! KHR_meshopt_compression): the extension names a buffer range holding the compressed bytes,
//! the decoded element count and byte stride, a mode (`ATTRIBUTES`, `TRIANGLES`, `INDICES`)
//! and a filter (`NONE`, `OCTAHEDRAL`, `QUANTIZATION`, `EXPONENTIAL`). The bytes are decoded by
//! the meshoptimizer library through the `meshopt` crate, whose decoders are written to take
//! untrusted input. The decoded size is bounded before anything is allocated: the codecs
//! spend at least 2 bits of header on 16 output bytes, so the output is refused beyond 128
//! times the input (plus 64 KiB for the smallest buffers). The OCTAHEDRAL and EXPONENTIAL
//! filters are applied here; QUANTIZATION (quaternions, for rotations) is refused.

use serde_json::Value;
use std::borrow::Cow;

/// The decoded bytes of a compressed buffer view.
pub(crate) fn decode_view(ext: &Value, buffers: &[Option<Cow<[u8]>>]) -> Result<Vec<u8>, String> {
    let field = |name: &str| ext.get(name).and_then(Value::as_u64);
    let buffer_index = field("buffer").ok_or("EXT_meshopt_compression has no buffer")? as usize;
    let offset = field("byteOffset").unwrap_or(0);
    let length = field("byteLength").ok_or("EXT_meshopt_compression has no byteLength")?;
    let stride = field("byteStride").ok_or("EXT_meshopt_compression has no byteStride")? as usize;
    let count = field("count").ok_or("EXT_meshopt_compression has no count")? as usize;
    let mode = ext.get("mode").and_then(Value::as_str).unwrap_or("");
    let filter = ext.get("filter").and_then(Value::as_str).unwrap_or("NONE");
    let buffer = buffers
        .get(buffer_index)
        .ok_or_else(|| format!("compressed data in buffer {buffer_index}, which does not exist"))?
        .as_ref()
        .ok_or_else(|| format!("compressed data in buffer {buffer_index}, which has no data"))?;
    let end = offset.checked_add(length).filter(|e| *e <= buffer.len() as u64).ok_or_else(|| {
        format!(
            "compressed range of {length} bytes at {offset} reaches past buffer {buffer_index} of {} bytes",
            buffer.len()
        )
    })?;
    let encoded = &buffer[offset as usize..end as usize];
    let size = count
        .checked_mul(stride)
        .filter(|s| *s as u64 <= 128 * length + 65536)
        .ok_or_else(|| {
            format!("{count} elements of {stride} bytes cannot come from {length} compressed bytes")
        })?;
    // Backed by u32 words, aligned for the decoder's 4-byte writes.
    let mut words = vec![0u32; size.div_ceil(4)];
    let out = &mut bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..size];
    match mode {
        "ATTRIBUTES" => {
            if stride == 0 || !stride.is_multiple_of(4) || stride > 256 {
                return Err(format!(
                    "ATTRIBUTES stride {stride} is not a multiple of 4 up to 256"
                ));
            }
            decode_vertices(out, count, stride, encoded)?;
            match filter {
                "NONE" => {}
                "OCTAHEDRAL" if stride == 4 || stride == 8 => {
                    filter_in_place(out, count, stride, Filter::Octahedral)
                }
                "QUANTIZATION" => {
                    return Err("the QUANTIZATION (quaternion) filter is not supported".into())
                }
                "EXPONENTIAL" => filter_in_place(out, count, stride, Filter::Exponential),
                other => return Err(format!("filter {other} with stride {stride}")),
            }
        }
        "TRIANGLES" | "INDICES" => {
            if !(stride == 2 || stride == 4) {
                return Err(format!("{mode} stride {stride} is neither 2 nor 4"));
            }
            if mode == "TRIANGLES" && !count.is_multiple_of(3) {
                return Err(format!("TRIANGLES count {count} is not a multiple of 3"));
            }
            decode_indices(out, count, stride, encoded, mode == "TRIANGLES")?;
        }
        other => return Err(format!("unknown EXT_meshopt_compression mode '{other}'")),
    }
    let mut bytes = bytemuck::cast_slice::<u32, u8>(&words).to_vec();
    bytes.truncate(size);
    Ok(bytes)
}

enum Filter {
    Octahedral,
    Exponential,
}

fn decode_vertices(
    out: &mut [u8],
    count: usize,
    stride: usize,
    encoded: &[u8],
) -> Result<(), String> {
    debug_assert_eq!(out.len(), count * stride);
    // SAFETY: `out` holds exactly count × stride bytes, which is what the decoder writes; it
    // reads only `encoded.len()` bytes of `encoded` and validates them.
    let code = unsafe {
        meshopt::ffi::meshopt_decodeVertexBuffer(
            out.as_mut_ptr().cast(),
            count,
            stride,
            encoded.as_ptr(),
            encoded.len(),
        )
    };
    if code != 0 {
        return Err(format!("meshopt vertex data does not decode (code {code})"));
    }
    Ok(())
}

fn decode_indices(
    out: &mut [u8],
    count: usize,
    stride: usize,
    encoded: &[u8],
    triangles: bool,
) -> Result<(), String> {
    debug_assert_eq!(out.len(), count * stride);
    // SAFETY: `out` holds exactly count × stride bytes (stride is 2 or 4, the index size the
    // decoder writes); the decoder reads only `encoded.len()` bytes and validates them.
    let code = unsafe {
        if triangles {
            meshopt::ffi::meshopt_decodeIndexBuffer(
                out.as_mut_ptr().cast(),
                count,
                stride,
                encoded.as_ptr(),
                encoded.len(),
            )
        } else {
            meshopt::ffi::meshopt_decodeIndexSequence(
                out.as_mut_ptr().cast(),
                count,
                stride,
                encoded.as_ptr(),
                encoded.len(),
            )
        }
    };
    if code != 0 {
        return Err(format!("meshopt index data does not decode (code {code})"));
    }
    Ok(())
}

/// The filters, applied in place to decoded attribute data (the `meshopt` crate does not
/// build meshoptimizer's filter code, so they are written here from the extension's
/// definitions).
fn filter_in_place(out: &mut [u8], count: usize, stride: usize, filter: Filter) {
    debug_assert_eq!(out.len(), count * stride);
    match filter {
        Filter::Octahedral => {
            for element in out.chunks_exact_mut(stride) {
                octahedral(element, stride / 4);
            }
        }
        Filter::Exponential => {
            for word in out.chunks_exact_mut(4) {
                let v = i32::from_le_bytes([word[0], word[1], word[2], word[3]]);
                let exponent = v >> 24;
                let mantissa = (v << 8) >> 8;
                let value = mantissa as f32 * (exponent as f32).exp2();
                word.copy_from_slice(&value.to_le_bytes());
            }
        }
    }
}

/// One octahedral-filtered element of four signed components of `width` bytes (1 or 2): x and
/// y are the octahedral coordinates, z holds the encoding of 1.0, w is kept. The result is the
/// unit vector as normalized signed integers of the same width.
fn octahedral(element: &mut [u8], width: usize) {
    let read = |i: usize| -> f32 {
        if width == 1 {
            element[i] as i8 as f32
        } else {
            i16::from_le_bytes([element[2 * i], element[2 * i + 1]]) as f32
        }
    };
    let (mut x, mut y, one) = (read(0), read(1), read(2));
    let z = one - x.abs() - y.abs();
    let fold = z.min(0.0);
    x += if x >= 0.0 { fold } else { -fold };
    y += if y >= 0.0 { fold } else { -fold };
    let length = (x * x + y * y + z * z).sqrt();
    let max = if width == 1 { 127.0 } else { 32767.0 };
    let scale = if length > 0.0 { max / length } else { 0.0 };
    for (i, v) in [x, y, z].into_iter().enumerate() {
        let q = (v * scale).round() as i32;
        if width == 1 {
            element[i] = q.clamp(-127, 127) as i8 as u8;
        } else {
            element[2 * i..2 * i + 2]
                .copy_from_slice(&(q.clamp(-32767, 32767) as i16).to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn vertex_data_round_trips_and_lies_are_refused() {
        let vertices: Vec<[u16; 4]> = (0..100u16).map(|i| [i, i * 2, 7, 0]).collect();
        let encoded = meshopt::encode_vertex_buffer(&vertices).unwrap();
        let buffers = vec![Some(Cow::Owned(encoded.clone()))];
        let ext = json!({"buffer": 0, "byteLength": encoded.len(), "byteStride": 8, "count": 100, "mode": "ATTRIBUTES"});
        let decoded = decode_view(&ext, &buffers).unwrap();
        assert_eq!(u16::from_le_bytes([decoded[8], decoded[9]]), 1);
        assert_eq!(
            u16::from_le_bytes([decoded[8 * 99 + 2], decoded[8 * 99 + 3]]),
            198
        );
        let huge = json!({"buffer": 0, "byteLength": encoded.len(), "byteStride": 8, "count": 1u64 << 40, "mode": "ATTRIBUTES"});
        assert!(decode_view(&huge, &buffers).is_err());
        let past = json!({"buffer": 0, "byteOffset": 1, "byteLength": encoded.len(), "byteStride": 8, "count": 100, "mode": "ATTRIBUTES"});
        assert!(decode_view(&past, &buffers).unwrap_err().contains("past"));
        let garbage = vec![Some(Cow::Owned(vec![0xA0u8; 64]))];
        let ext = json!({"buffer": 0, "byteLength": 64, "byteStride": 8, "count": 100, "mode": "ATTRIBUTES"});
        assert!(decode_view(&ext, &garbage).is_err());
    }
}
