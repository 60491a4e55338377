//! Attribute colouring: turns a point attribute into the RGBA8 word the rasterizers draw
//! (red in the low byte). The viewer switches between these; render/bench use one.

use crate::extra::{ExtraAttributes, ExtraValue};
use crate::{PointBatch, PointLayout};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ColorMode {
    Rgb,
    Intensity,
    Elevation,
    Classification,
    ReturnNumber,
    PointSourceId,
    GpsTime,
    ScanAngle,
    UserData,
    Nir,
    /// Attribute `i` of the data's extra bytes ([`crate::extra::ExtraAttributes`]).
    Extra(u8),
}

impl ColorMode {
    pub const ALL: [ColorMode; 10] = [
        ColorMode::Rgb,
        ColorMode::Intensity,
        ColorMode::Elevation,
        ColorMode::Classification,
        ColorMode::ReturnNumber,
        ColorMode::PointSourceId,
        ColorMode::GpsTime,
        ColorMode::ScanAngle,
        ColorMode::UserData,
        ColorMode::Nir,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ColorMode::Rgb => "rgb",
            ColorMode::Intensity => "intensity",
            ColorMode::Elevation => "elevation",
            ColorMode::Classification => "classification",
            ColorMode::ReturnNumber => "return-number",
            ColorMode::PointSourceId => "point-source-id",
            ColorMode::GpsTime => "gps-time",
            ColorMode::ScanAngle => "scan-angle",
            ColorMode::UserData => "user-data",
            ColorMode::Nir => "nir",
            ColorMode::Extra(_) => "extra",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }
}

impl ColorMode {
    /// Whether data of `layout` has what this mode colours by (every point has a position,
    /// intensity, returns, class, scan angle, user data and source id; RGB, GPS time and NIR
    /// only in some formats).
    pub fn available_in(self, layout: &PointLayout) -> bool {
        match self {
            ColorMode::Rgb => layout.rgb,
            ColorMode::GpsTime => layout.gps_time,
            ColorMode::Nir => layout.nir,
            ColorMode::Extra(_) => layout.extra_bytes > 0,
            _ => true,
        }
    }

    /// Whether the mode maps a scalar through a range and a ramp (rather than fixed colours).
    pub fn is_scalar(self) -> bool {
        matches!(
            self,
            ColorMode::Intensity
                | ColorMode::Elevation
                | ColorMode::GpsTime
                | ColorMode::ScanAngle
                | ColorMode::UserData
                | ColorMode::Nir
                | ColorMode::Extra(_)
        )
    }
}

/// The colouring chosen for data when none was asked for, and why (for a `note:` line).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DefaultColor {
    pub mode: ColorMode,
    pub reason: &'static str,
}

impl std::fmt::Display for DefaultColor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "colouring by {} ({}; --color picks another)",
            self.mode.name(),
            self.reason
        )
    }
}

/// Pointlets a store's default colouring looks at, spread over the store.
const DEFAULT_COLOR_SAMPLES: usize = 8;

/// The colouring that shows data of `layout` when none is asked for: its RGB when some point
/// of `sample` has a colour other than black, else its intensity when some point has one, else
/// elevation (which every point has). An all-zero RGB column would draw a black picture.
pub fn default_color(layout: &PointLayout, sample: &[&PointBatch]) -> DefaultColor {
    let any_rgb = sample.iter().any(|b| b.rgb.iter().any(|c| *c != [0; 3]));
    let any_intensity = sample.iter().any(|b| b.intensity.iter().any(|v| *v != 0));
    let (mode, reason) = match (layout.rgb, any_rgb, any_intensity) {
        (true, true, _) => (ColorMode::Rgb, "the data has RGB colours"),
        (false, _, true) => (ColorMode::Intensity, "the data has no RGB"),
        (true, false, true) => (ColorMode::Intensity, "its RGB is black everywhere"),
        (false, _, false) => (
            ColorMode::Elevation,
            "the data has no RGB and its intensity is zero everywhere",
        ),
        (true, false, false) => (
            ColorMode::Elevation,
            "its RGB is black and its intensity zero everywhere",
        ),
    };
    DefaultColor { mode, reason }
}

/// [`default_color`] for data held in `pointlets` parts (a store), looking at a few parts
/// spread over it that `read` returns.
pub fn default_color_of_parts<E>(
    layout: &PointLayout,
    pointlets: usize,
    read: impl FnMut(usize) -> Result<PointBatch, E>,
) -> Result<DefaultColor, E> {
    let sample = sample_parts(pointlets, read)?;
    Ok(default_color(layout, &sample.iter().collect::<Vec<_>>()))
}

/// A few of `pointlets` parts spread over the data, which `read` returns: one pointlet alone is
/// one small region of the scene, not a sample of its values.
pub fn sample_parts<E>(
    pointlets: usize,
    read: impl FnMut(usize) -> Result<PointBatch, E>,
) -> Result<Vec<PointBatch>, E> {
    sample_indices(pointlets).into_iter().map(read).collect()
}

/// The parts [`sample_parts`] reads, for callers that read them in parallel.
pub fn sample_indices(pointlets: usize) -> Vec<usize> {
    let step = pointlets.div_ceil(DEFAULT_COLOR_SAMPLES).max(1);
    (0..pointlets).step_by(step).collect()
}

/// How values map to colours: the range (and gamma) of scalar attributes, and whether RGB is
/// stored as 8-bit values in LAS's 16-bit fields (common in the wild).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColorScale {
    pub mode: ColorMode,
    pub range: [f64; 2],
    pub gamma: f64,
    pub rgb_8bit: bool,
    pub ramp: Ramp,
    /// How to read the value of an [`ColorMode::Extra`] attribute (`None` draws it grey).
    pub extra: Option<ExtraValue>,
}

impl ColorScale {
    /// [`ColorScale::fit`] that can also fit an extra-bytes attribute of `extras`.
    pub fn fit_in(
        mode: ColorMode,
        sample: &[&PointBatch],
        z_range: [f64; 2],
        extras: &ExtraAttributes,
    ) -> Self {
        let mut scale = Self::fit(mode, sample, z_range);
        if let ColorMode::Extra(i) = mode {
            if let Some(a) = extras.attributes.get(usize::from(i)) {
                let x = a.reader();
                let values = sample
                    .iter()
                    .flat_map(|b| extra_values(b, x))
                    .collect::<Vec<f64>>();
                scale.range = percentile_range(values);
                scale.extra = Some(x);
            }
        }
        scale
    }

    /// A scale whose ranges come from a sample of the data (a file's first batch, a store's
    /// [`sample_parts`]), with 1 % / 99 % percentiles so outliers do not flatten the picture.
    pub fn fit(mode: ColorMode, sample: &[&PointBatch], z_range: [f64; 2]) -> Self {
        let pct = percentile_range;
        let range = match mode {
            ColorMode::Intensity => pct(sample
                .iter()
                .flat_map(|b| b.intensity.iter().map(|v| *v as f64))
                .collect()),
            ColorMode::Elevation => z_range,
            ColorMode::GpsTime => pct(sample.iter().flat_map(|b| b.gps_time.clone()).collect()),
            ColorMode::ScanAngle => pct(sample
                .iter()
                .flat_map(|b| b.scan_angle.iter().map(|v| f64::from(*v)))
                .collect()),
            ColorMode::UserData => pct(sample
                .iter()
                .flat_map(|b| b.user_data.iter().map(|v| f64::from(*v)))
                .collect()),
            ColorMode::Nir => pct(sample
                .iter()
                .flat_map(|b| b.nir.iter().map(|v| f64::from(*v)))
                .collect()),
            ColorMode::PointSourceId => [0.0, 1.0],
            _ => [0.0, 1.0],
        };
        let rgb_8bit = sample
            .iter()
            .all(|b| b.rgb.iter().all(|c| c.iter().all(|v| *v <= 255)));
        Self {
            mode,
            range,
            gamma: 1.0,
            rgb_8bit,
            ramp: Ramp::Viridis,
            extra: None,
        }
    }
}

/// The 1 % and 99 % percentiles of `v` (outliers do not flatten the picture); [0, 1] when
/// empty, one unit wide when flat.
fn percentile_range(mut v: Vec<f64>) -> [f64; 2] {
    if v.is_empty() {
        return [0.0, 1.0];
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q) as usize];
    let (lo, hi) = (at(0.01), at(0.99));
    if hi > lo {
        [lo, hi]
    } else {
        [lo, lo + 1.0]
    }
}

/// The values of an extra-bytes attribute in `batch` (no-data left out).
fn extra_values(batch: &PointBatch, x: ExtraValue) -> impl Iterator<Item = f64> + '_ {
    let w = usize::from(batch.layout.extra_bytes).max(1);
    batch
        .extra_bytes
        .chunks_exact(w)
        .filter_map(move |e| x.read(e))
}

/// Colour ramps for scalar attributes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Ramp {
    Viridis,
    Turbo,
    Grey,
}

impl Ramp {
    pub const ALL: [Ramp; 3] = [Ramp::Viridis, Ramp::Turbo, Ramp::Grey];

    pub fn name(self) -> &'static str {
        match self {
            Ramp::Viridis => "viridis",
            Ramp::Turbo => "turbo",
            Ramp::Grey => "grey",
        }
    }

    /// Colour at `t` in [0, 1], interpolated between control points of the ramp.
    pub fn at(self, t: f64) -> [u8; 3] {
        const VIRIDIS: [[f64; 3]; 5] = [
            [68.0, 1.0, 84.0],
            [59.0, 82.0, 139.0],
            [33.0, 145.0, 140.0],
            [94.0, 201.0, 98.0],
            [253.0, 231.0, 37.0],
        ];
        const TURBO: [[f64; 3]; 6] = [
            [48.0, 18.0, 59.0],
            [40.0, 151.0, 247.0],
            [40.0, 237.0, 145.0],
            [217.0, 230.0, 48.0],
            [251.0, 128.0, 34.0],
            [122.0, 4.0, 3.0],
        ];
        let t = if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let stops: &[[f64; 3]] = match self {
            Ramp::Viridis => &VIRIDIS,
            Ramp::Turbo => &TURBO,
            Ramp::Grey => &[[0.0; 3], [255.0; 3]],
        };
        let x = t * (stops.len() - 1) as f64;
        let i = (x as usize).min(stops.len() - 2);
        let f = x - i as f64;
        [0, 1, 2].map(|k| (stops[i][k] * (1.0 - f) + stops[i + 1][k] * f).round() as u8)
    }
}

/// The word the GPU draws: red, green, blue, and the ASPRS class in the alpha byte (the
/// renderer hides classes by it; the image itself is opaque).
pub fn pack_rgba(c: [u8; 3], class: u8) -> u32 {
    u32::from_le_bytes([c[0], c[1], c[2], class])
}

/// The standard ASPRS LAS classification colours (as the common viewers draw them).
pub fn classification_color(class: u8) -> [u8; 3] {
    match class {
        0 | 1 => [170, 170, 170],
        2 => [166, 110, 56],
        3 => [140, 200, 90],
        4 => [60, 160, 60],
        5 => [20, 110, 30],
        6 => [220, 60, 50],
        7 => [255, 0, 255],
        8 => [255, 200, 0],
        9 => [40, 110, 230],
        10 => [120, 70, 40],
        11 => [90, 90, 90],
        12 => [255, 255, 160],
        13..=16 => [250, 150, 30],
        17 => [190, 190, 230],
        18 => [255, 80, 160],
        _ => [
            (class.wrapping_mul(67)) | 64,
            (class.wrapping_mul(151)) | 64,
            (class.wrapping_mul(199)) | 64,
        ],
    }
}

/// Human names of the ASPRS classes 0–18 (LAS 1.4 R15).
pub fn classification_name(class: u8) -> &'static str {
    match class {
        0 => "created, never classified",
        1 => "unclassified",
        2 => "ground",
        3 => "low vegetation",
        4 => "medium vegetation",
        5 => "high vegetation",
        6 => "building",
        7 => "low point (noise)",
        8 => "model key-point",
        9 => "water",
        10 => "rail",
        11 => "road surface",
        12 => "overlap",
        13 => "wire guard",
        14 => "wire conductor",
        15 => "transmission tower",
        16 => "wire connector",
        17 => "bridge deck",
        18 => "high noise",
        _ => "user defined",
    }
}

const RETURN_COLORS: [[u8; 3]; 5] = [
    [230, 60, 60],
    [240, 200, 40],
    [60, 200, 90],
    [50, 130, 240],
    [170, 80, 220],
];

/// Where the intensity ramp starts on the grey ramp (0 = black).
const INTENSITY_FLOOR: f64 = 0.15;

/// The word drawn for point `i` of `batch` under `scale` (see [`pack_rgba`]). Attributes the
/// batch lacks draw grey.
pub fn point_color(batch: &PointBatch, i: usize, scale: &ColorScale) -> u32 {
    let exponent = 1.0 / scale.gamma.max(1e-3);
    let norm = |v: f64| {
        let t = ((v - scale.range[0]) / (scale.range[1] - scale.range[0])).clamp(0.0, 1.0);
        // powf(t, 1) is t exactly; skipping it keeps the common case cheap.
        if exponent == 1.0 {
            t
        } else {
            t.powf(exponent)
        }
    };
    let grey = [150, 150, 150];
    let c = match scale.mode {
        ColorMode::Rgb => match batch.rgb.get(i) {
            Some(c) if scale.rgb_8bit => c.map(|v| v as u8),
            Some(c) => c.map(|v| (v >> 8) as u8),
            None => grey,
        },
        ColorMode::Intensity => {
            let t = batch.intensity.get(i).map_or(0.0, |v| norm(*v as f64));
            // The darkest returns stay visible on the default black background.
            Ramp::Grey.at(INTENSITY_FLOOR + (1.0 - INTENSITY_FLOOR) * t)
        }
        ColorMode::Elevation => batch.xyz.get(i).map_or(grey, |p| scale.ramp.at(norm(p[2]))),
        ColorMode::Classification => batch
            .classification
            .get(i)
            .map_or(grey, |c| classification_color(*c)),
        ColorMode::ReturnNumber => batch.returns.get(i).map_or(grey, |r| {
            let n = (r & 0x0f).max(1) as usize;
            RETURN_COLORS[(n - 1).min(RETURN_COLORS.len() - 1)]
        }),
        ColorMode::PointSourceId => batch.point_source_id.get(i).map_or(grey, |id| {
            let h = crate::shuffle::mix_seed(*id as u64, 17);
            [h as u8 | 48, (h >> 8) as u8 | 48, (h >> 16) as u8 | 48]
        }),
        ColorMode::GpsTime => batch
            .gps_time
            .get(i)
            .map_or(grey, |t| scale.ramp.at(norm(*t))),
        ColorMode::ScanAngle => batch
            .scan_angle
            .get(i)
            .map_or(grey, |v| scale.ramp.at(norm(f64::from(*v)))),
        ColorMode::UserData => batch
            .user_data
            .get(i)
            .map_or(grey, |v| scale.ramp.at(norm(f64::from(*v)))),
        ColorMode::Nir => batch
            .nir
            .get(i)
            .map_or(grey, |v| scale.ramp.at(norm(f64::from(*v)))),
        ColorMode::Extra(_) => {
            let w = usize::from(batch.layout.extra_bytes);
            let value = scale
                .extra
                .and_then(|x| x.read(batch.extra_bytes.get(i * w..(i + 1) * w)?));
            value.map_or(grey, |v| scale.ramp.at(norm(v)))
        }
    };
    pack_rgba(c, batch.classification.get(i).copied().unwrap_or(0))
}

/// [`point_color`] of points `0..out.len()` of `batch`, into `out`: the colouring is chosen
/// once for the batch instead of once per point (loaders colour hundreds of millions).
pub fn point_colors(batch: &PointBatch, scale: &ColorScale, out: &mut [u32]) {
    let n = out.len();
    match (
        scale.mode,
        batch.rgb.get(..n),
        batch.classification.get(..n),
    ) {
        (ColorMode::Rgb, Some(rgb), Some(classes)) => {
            let shift = if scale.rgb_8bit { 0 } else { 8 };
            for ((o, c), class) in out.iter_mut().zip(rgb).zip(classes) {
                *o = pack_rgba(c.map(|v| (v >> shift) as u8), *class);
            }
        }
        (ColorMode::Classification, _, Some(classes)) => {
            for (o, c) in out.iter_mut().zip(classes) {
                *o = pack_rgba(classification_color(*c), *c);
            }
        }
        _ => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = point_color(batch, i, scale);
            }
        }
    }
}

/// [`point_colors`] in RGB mode from the stored bytes: `rgb` holds three little-endian u16 a
/// point, `classes` one byte a point (the alpha). A byte of each u16 is the 8-bit value: the
/// high one, or the low one for `rgb_8bit` data.
pub fn rgb_colors_from_bytes(rgb: &[u8], classes: &[u8], rgb_8bit: bool, out: &mut [u32]) {
    let n = out.len().min(rgb.len() / 6).min(classes.len());
    let (rgb, classes, out) = (&rgb[..n * 6], &classes[..n], &mut out[..n]);
    #[cfg(target_arch = "x86_64")]
    let done = match std::arch::is_x86_feature_detected!("ssse3") {
        // SAFETY: the CPU has SSSE3; the three slices hold n points each.
        true if rgb_8bit => unsafe { rgb_colors_ssse3::<0>(rgb, classes, out) },
        true => unsafe { rgb_colors_ssse3::<1>(rgb, classes, out) },
        false => 0,
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    let (rgb, classes, out) = (&rgb[done * 6..], &classes[done..], &mut out[done..]);
    if rgb_8bit {
        rgb_colors_at::<0>(rgb, classes, out);
    } else {
        rgb_colors_at::<1>(rgb, classes, out);
    }
}

/// [`rgb_colors_at`] four points at a time by byte shuffles: 0.15 ns a point against 0.7 for
/// that loop and 1.2 for a loop with the byte's place a variable (dev machine; the latter had
/// a fifth of the CPU samples of a store's progressive load: docs/BENCHMARKS.md, issue 11,
/// session 50). Returns the points done (a multiple of four; the rest is the caller's).
///
/// # Safety
/// The CPU must have SSSE3, `rgb` must hold `6 * out.len()` bytes and `classes` `out.len()`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "ssse3")]
unsafe fn rgb_colors_ssse3<const AT: usize>(rgb: &[u8], classes: &[u8], out: &mut [u32]) -> usize {
    use std::arch::x86_64::*;
    let fours = out.len() / 4;
    let a = AT as i8;
    // Points 0 and 1 of four from the first 16 bytes, points 2 and 3 from bytes 8..24; the
    // classes into the fourth byte of each colour; x (-1) gives a zero byte.
    let x = -1;
    #[rustfmt::skip]
    let masks = [
        [a, a + 2, a + 4, x, a + 6, a + 8, a + 10, x, x, x, x, x, x, x, x, x],
        [x, x, x, x, x, x, x, x, a + 4, a + 6, a + 8, x, a + 10, a + 12, a + 14, x],
        [x, x, x, 0, x, x, x, 1, x, x, x, 2, x, x, x, 3],
    ];
    // SAFETY: each array holds the 16 bytes loaded.
    let [first, second, alpha] =
        masks.map(|m: [i8; 16]| unsafe { _mm_loadu_si128(m.as_ptr().cast()) });
    for q in 0..fours {
        // SAFETY: bytes 24q..24q + 24 of `rgb`, 4q..4q + 4 of `classes` and colours 4q..4q + 4
        // of `out` lie inside them (q < out.len() / 4, the caller's lengths).
        unsafe {
            let p = rgb.as_ptr().add(24 * q);
            let lo = _mm_loadu_si128(p.cast());
            let hi = _mm_loadu_si128(p.add(8).cast());
            let k = _mm_cvtsi32_si128(classes.as_ptr().add(4 * q).cast::<i32>().read_unaligned());
            let c = _mm_or_si128(
                _mm_or_si128(_mm_shuffle_epi8(lo, first), _mm_shuffle_epi8(hi, second)),
                _mm_shuffle_epi8(k, alpha),
            );
            _mm_storeu_si128(out.as_mut_ptr().add(4 * q).cast(), c);
        }
    }
    fours * 4
}

/// [`rgb_colors_from_bytes`] taking byte `AT` of each u16, eight points at a time: for CPUs
/// without byte shuffles and the last points.
fn rgb_colors_at<const AT: usize>(rgb: &[u8], classes: &[u8], out: &mut [u32]) {
    let n = out.len().min(rgb.len() / 6).min(classes.len());
    let (rgb, classes, out) = (&rgb[..n * 6], &classes[..n], &mut out[..n]);
    let whole = n / 8 * 8;
    for ((o, c), k) in out[..whole]
        .chunks_exact_mut(8)
        .zip(rgb.chunks_exact(48))
        .zip(classes.chunks_exact(8))
    {
        for j in 0..8 {
            o[j] = u32::from_le_bytes([c[6 * j + AT], c[6 * j + 2 + AT], c[6 * j + 4 + AT], k[j]]);
        }
    }
    for ((o, c), &k) in out[whole..]
        .iter_mut()
        .zip(rgb[whole * 6..].chunks_exact(6))
        .zip(&classes[whole..])
    {
        *o = u32::from_le_bytes([c[AT], c[2 + AT], c[4 + AT], k]);
    }
}

/// [`point_colors`] in classification mode from the classes alone.
pub fn class_colors(classes: &[u8], out: &mut [u32]) {
    let table: [u32; 256] =
        std::array::from_fn(|c| pack_rgba(classification_color(c as u8), c as u8));
    for (o, &c) in out.iter_mut().zip(classes) {
        *o = table[usize::from(c)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_from_stored_bytes_equal_point_colors() {
        let mut rng = crate::shuffle::SplitMix64::new(3);
        let mut b = PointBatch::new(PointLayout {
            rgb: true,
            ..PointLayout::default()
        });
        // Not a multiple of eight: the last points go one at a time.
        for _ in 0..5_003 {
            let r = rng.next_u64();
            b.xyz.push([0.0; 3]);
            // Some 8-bit values stored in 16 bits, some full 16-bit ones.
            let v = |s: u32| {
                if r & 1 == 0 {
                    (r >> s) as u16 & 0xff
                } else {
                    (r >> s) as u16
                }
            };
            b.rgb.push([v(8), v(24), v(40)]);
            b.classification.push((r >> 56) as u8);
        }
        let rgb: Vec<u8> = b
            .rgb
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let n = b.len();
        for rgb_8bit in [false, true] {
            let scale = ColorScale {
                mode: ColorMode::Rgb,
                range: [0.0, 1.0],
                gamma: 1.0,
                rgb_8bit,
                ramp: Ramp::Grey,
                extra: None,
            };
            let (mut want, mut got) = (vec![0; n], vec![0; n]);
            point_colors(&b, &scale, &mut want);
            rgb_colors_from_bytes(&rgb, &b.classification, rgb_8bit, &mut got);
            assert_eq!(got, want, "rgb_8bit {rgb_8bit}");
            // The loop without byte shuffles (other CPUs, and the last points here).
            got.fill(0);
            match rgb_8bit {
                true => rgb_colors_at::<0>(&rgb, &b.classification, &mut got),
                false => rgb_colors_at::<1>(&rgb, &b.classification, &mut got),
            }
            assert_eq!(got, want, "rgb_8bit {rgb_8bit}, eight at a time");
            let classes = ColorScale {
                mode: ColorMode::Classification,
                ..scale
            };
            point_colors(&b, &classes, &mut want);
            class_colors(&b.classification, &mut got);
            assert_eq!(got, want);
        }
    }

    #[test]
    fn ramps_hit_their_end_points() {
        assert_eq!(Ramp::Grey.at(0.0), [0, 0, 0]);
        assert_eq!(Ramp::Grey.at(1.0), [255, 255, 255]);
        assert_eq!(Ramp::Viridis.at(0.0), [68, 1, 84]);
        assert_eq!(Ramp::Viridis.at(2.0), [253, 231, 37]);
        assert_eq!(Ramp::Turbo.at(f64::NAN), [48, 18, 59]);
    }

    #[test]
    fn the_weakest_intensity_is_not_drawn_black() {
        let mut b = PointBatch::new(PointLayout::default());
        b.xyz.extend([[0.0; 3]; 3]);
        b.intensity.extend([0, 500, 1000]);
        let scale = ColorScale {
            mode: ColorMode::Intensity,
            range: [0.0, 1000.0],
            gamma: 1.0,
            rgb_8bit: false,
            ramp: Ramp::Grey,
            extra: None,
        };
        let rgb = |i| point_color(&b, i, &scale).to_le_bytes();
        let (low, high) = (rgb(0), rgb(2));
        assert!(
            low[0] >= 30,
            "intensity 0 draws {low:?}, invisible on black"
        );
        assert_eq!(&high[..3], &[255, 255, 255]);
        assert!(rgb(1)[0] > low[0] && rgb(1)[0] < high[0]);
    }

    #[test]
    fn the_default_colouring_skips_missing_and_black_columns() {
        let layout = |rgb| PointLayout {
            rgb,
            ..Default::default()
        };
        let mut b = PointBatch::new(layout(true));
        b.xyz.push([0.0; 3]);
        b.rgb.push([0; 3]);
        b.intensity.push(0);
        assert_eq!(
            default_color(&layout(true), &[&b]).mode,
            ColorMode::Elevation
        );
        b.intensity[0] = 7;
        assert_eq!(
            default_color(&layout(true), &[&b]).mode,
            ColorMode::Intensity
        );
        b.rgb[0] = [0, 0, 1];
        assert_eq!(default_color(&layout(true), &[&b]).mode, ColorMode::Rgb);
        assert_eq!(
            default_color(&layout(false), &[&b]).mode,
            ColorMode::Intensity,
            "a layout without RGB is never coloured by it"
        );
        let read = |i: usize| -> Result<PointBatch, ()> {
            let mut p = PointBatch::new(layout(true));
            p.rgb.push(if i == 40 { [9; 3] } else { [0; 3] });
            Ok(p)
        };
        assert_eq!(
            default_color_of_parts(&layout(true), 64, read),
            Ok(default_color(&layout(true), &[&b])),
            "a colour in a later part counts"
        );
    }

    #[test]
    fn rgb_depth_is_detected_and_classes_have_colours() {
        let mut b = PointBatch::new(crate::PointLayout {
            rgb: true,
            ..Default::default()
        });
        b.xyz.push([0.0; 3]);
        b.rgb.push([200, 100, 50]);
        b.classification.push(6);
        let s = ColorScale::fit(ColorMode::Rgb, &[&b], [0.0, 1.0]);
        assert!(s.rgb_8bit);
        assert_eq!(point_color(&b, 0, &s), pack_rgba([200, 100, 50], 6));
        b.rgb[0] = [51200, 25600, 12800];
        let s = ColorScale::fit(ColorMode::Rgb, &[&b], [0.0, 1.0]);
        assert!(!s.rgb_8bit);
        assert_eq!(point_color(&b, 0, &s), pack_rgba([200, 100, 50], 6));
        let s = ColorScale::fit(ColorMode::Classification, &[&b], [0.0, 1.0]);
        assert_eq!(
            point_color(&b, 0, &s),
            pack_rgba(classification_color(6), 6)
        );
        assert_eq!(
            point_color(&b, 0, &s) >> 24,
            6,
            "the class rides in the alpha byte"
        );
        assert_eq!(classification_name(2), "ground");
    }

    #[test]
    fn batch_colours_equal_point_colours_in_every_mode() {
        let layout = crate::PointLayout {
            rgb: true,
            gps_time: true,
            ..Default::default()
        };
        let mut b = PointBatch::new(layout);
        for i in 0..300u32 {
            let v = i.wrapping_mul(2_654_435_761);
            b.xyz
                .push([f64::from(i), 0.5 * f64::from(i), f64::from(v % 97)]);
            b.intensity.push(v as u16);
            b.returns.push((v >> 8) as u8);
            b.flags.push(0);
            b.classification.push((v >> 16) as u8 % 20);
            b.scan_angle.push(f64::from(v % 60) as f32 - 30.0);
            b.user_data.push((v >> 3) as u8);
            b.point_source_id.push((v >> 5) as u16);
            b.gps_time.push(f64::from(v) * 1e-3);
            b.rgb.push([v as u16, (v >> 4) as u16, (v >> 12) as u16]);
        }
        for mode in ColorMode::ALL {
            for gamma in [1.0, 2.2] {
                let mut s = ColorScale::fit(mode, &[&b], [0.0, 97.0]);
                s.gamma = gamma;
                let mut out = vec![0; 250];
                point_colors(&b, &s, &mut out);
                let each: Vec<u32> = (0..250).map(|i| point_color(&b, i, &s)).collect();
                assert_eq!(out, each, "{mode:?}, gamma {gamma}");
            }
        }
        // Without classes the alpha is 0, as point by point.
        b.classification.clear();
        let s = ColorScale::fit(ColorMode::Rgb, &[&b], [0.0, 1.0]);
        let mut out = vec![0; 10];
        point_colors(&b, &s, &mut out);
        assert_eq!(
            out,
            (0..10).map(|i| point_color(&b, i, &s)).collect::<Vec<_>>()
        );
    }
}
