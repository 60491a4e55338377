//! Colours of fetched points, computed as the native loaders compute them: the streams a
//! colouring reads, decoded into a batch's columns, through `core::color::point_colors`.

use pointlet_core::color::{point_colors, ColorMode, ColorScale};
use pointlet_core::PointBatch;
use pointlet_store::{decode_positions, StoreHeader, StreamKind};

/// The streams a fetch reads for `mode`: positions, the attribute's stream (if the store has
/// it) and the classes (hidden classes are decided on them, in the colour's alpha byte).
pub fn fetch_streams(header: &StoreHeader, mode: ColorMode) -> Vec<StreamKind> {
    let mut kinds = vec![StreamKind::Position];
    if let Some(kind) = StreamKind::for_color(mode).filter(|k| header.stream(*k).is_some()) {
        kinds.push(kind);
    }
    if header.stream(StreamKind::Classification).is_some() && mode != ColorMode::Classification {
        kinds.push(StreamKind::Classification);
    }
    kinds
}

fn u16s(raw: &[u8]) -> Vec<u16> {
    raw.chunks_exact(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect()
}

/// Decodes one stream's bytes into the matching column of `batch`.
fn fill_column(batch: &mut PointBatch, kind: StreamKind, raw: &[u8]) {
    match kind {
        StreamKind::Rgb => {
            batch.rgb = raw
                .chunks_exact(6)
                .map(|c| [0, 1, 2].map(|k| u16::from_le_bytes([c[2 * k], c[2 * k + 1]])))
                .collect()
        }
        StreamKind::Intensity => batch.intensity = u16s(raw),
        StreamKind::PointSourceId => batch.point_source_id = u16s(raw),
        StreamKind::Nir => batch.nir = u16s(raw),
        StreamKind::Classification => batch.classification = raw.to_vec(),
        StreamKind::UserData => batch.user_data = raw.to_vec(),
        StreamKind::ExtraBytes => batch.extra_bytes = raw.to_vec(),
        StreamKind::Returns => batch.returns = raw.to_vec(),
        StreamKind::ScanAngle => {
            batch.scan_angle = raw
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        }
        StreamKind::GpsTime => {
            batch.gps_time = raw
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
                .collect()
        }
        StreamKind::Position | StreamKind::Flags | StreamKind::Waveform => {}
    }
}

/// Quantized positions and packed colours of `n` points from the raw bytes of `kinds`
/// (as [`fetch_streams`] lists them).
pub fn decode(
    header: &StoreHeader,
    scale: &ColorScale,
    kinds: &[StreamKind],
    raws: &[Vec<u8>],
    n: usize,
) -> (Vec<[i32; 3]>, Vec<u32>) {
    let mut batch = PointBatch::default();
    let mut xyz = Vec::new();
    for (kind, raw) in kinds.iter().zip(raws) {
        if *kind == StreamKind::Position {
            xyz = decode_positions(raw);
        } else {
            fill_column(&mut batch, *kind, raw);
        }
    }
    if scale.mode == ColorMode::Elevation {
        let q = header.quantization;
        batch.xyz = xyz.iter().map(|p| q.dequantize(*p)).collect();
    }
    batch.layout.extra_bytes = header.layout.extra_bytes;
    let mut colors = vec![0; n];
    point_colors(&batch, scale, &mut colors);
    (xyz, colors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::color::Ramp;

    #[test]
    fn classification_colours_carry_the_class() {
        let scale = ColorScale {
            mode: ColorMode::Classification,
            range: [0.0, 1.0],
            gamma: 1.0,
            rgb_8bit: false,
            ramp: Ramp::Viridis,
            extra: None,
        };
        let header_kinds = [StreamKind::Position, StreamKind::Classification];
        let mut pos = Vec::new();
        for v in [1i32, 2, 3, 4, 5, 6] {
            pos.extend_from_slice(&v.to_le_bytes());
        }
        let raws = vec![pos, vec![2u8, 6]];
        let header = crate::ranges::tests_header();
        let (xyz, colors) = decode(&header, &scale, &header_kinds, &raws, 2);
        assert_eq!(xyz, vec![[1, 2, 3], [4, 5, 6]]);
        assert_eq!(colors[0] >> 24, 2);
        assert_eq!(colors[1] >> 24, 6);
        assert_ne!(colors[0] & 0xffffff, colors[1] & 0xffffff);
    }
}
