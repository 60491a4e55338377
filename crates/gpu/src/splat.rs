//! Point size: splats. A point covers a square or a circle of pixels around its projection, all
//! at its view depth, the same way in every rasterizer (the footprint is in `common.wgsl`, the
//! CPU reference in `reference.rs`). Sizes are fixed in pixels or adaptive: the surface spacing
//! of what is drawn (a pointlet's extent over the points of it drawn this frame, or a point
//! file's density) seen at the point's depth, times a scale — the WebGPU-engine paper (§6.1–6.2)
//! sizes its billboards to the target spacing the same way. Adaptive splats also write a larger
//! ring of a lower tier that only fills pixels no splat covers, because a random subset of a
//! surface leaves gaps that splats of the mean spacing cannot close.

/// Largest splat side in pixels.
pub const MAX_SPLAT: u32 = 32;

/// How large points are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PointSize {
    /// A square or circle of this many pixels across (1–32); 1 is the one-pixel point.
    Fixed(u32),
    /// The spacing of the drawn points at the point's depth, times `scale`.
    Adaptive { scale: f32 },
}

impl PointSize {
    /// The adaptive default: a splat as wide as the spacing times this.
    pub const ADAPTIVE_SCALE: f32 = 1.25;

    pub fn adaptive() -> Self {
        PointSize::Adaptive {
            scale: Self::ADAPTIVE_SCALE,
        }
    }

    /// `adaptive`, `adaptive:SCALE` (splats SCALE spacings wide, 0.5–4) or a number of pixels
    /// (1–32).
    pub fn parse(s: &str) -> Result<Self, String> {
        let bad = || {
            format!(
                "'{s}' is not a point size: give pixels (1–{MAX_SPLAT}), 'adaptive' or 'adaptive:SCALE' (0.5–4)"
            )
        };
        if s == "adaptive" {
            return Ok(Self::adaptive());
        }
        if let Some(scale) = s.strip_prefix("adaptive:") {
            return match scale.parse::<f32>() {
                Ok(scale) if (0.5..=4.0).contains(&scale) => Ok(PointSize::Adaptive { scale }),
                _ => Err(bad()),
            };
        }
        match s.parse::<u32>() {
            Ok(px) if (1..=MAX_SPLAT).contains(&px) => Ok(PointSize::Fixed(px)),
            _ => Err(bad()),
        }
    }

    pub fn name(self) -> String {
        match self {
            PointSize::Fixed(px) => px.to_string(),
            PointSize::Adaptive { scale } if scale == Self::ADAPTIVE_SCALE => "adaptive".into(),
            PointSize::Adaptive { scale } => format!("adaptive:{scale}"),
        }
    }
}

/// The footprint's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SplatShape {
    Square,
    Circle,
}

impl SplatShape {
    pub const ALL: [SplatShape; 2] = [SplatShape::Square, SplatShape::Circle];

    pub fn name(self) -> &'static str {
        match self {
            SplatShape::Square => "square",
            SplatShape::Circle => "circle",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == s)
    }
}

/// How splats reach the pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SplatRaster {
    /// Each compute rasterizer loops over the footprint with its own atomics.
    Compute,
    /// Billboard quads through the render pipeline and the hardware depth test (closest-point
    /// rasterizers only; on equal depth the first drawn wins).
    Quads,
}

impl SplatRaster {
    pub const ALL: [SplatRaster; 2] = [SplatRaster::Compute, SplatRaster::Quads];

    pub fn name(self) -> &'static str {
        match self {
            SplatRaster::Compute => "compute",
            SplatRaster::Quads => "quads",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == s)
    }
}

/// Point size and shape of a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplatSettings {
    pub size: PointSize,
    pub shape: SplatShape,
    pub raster: SplatRaster,
}

impl Default for SplatSettings {
    fn default() -> Self {
        Self {
            size: PointSize::Fixed(1),
            shape: SplatShape::Square,
            raster: SplatRaster::Compute,
        }
    }
}

/// Which pipelines draw a frame's points: one-pixel points need no footprint loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum SplatMode {
    Pixel,
    Splats(SplatShape),
}

impl SplatSettings {
    pub fn adaptive() -> Self {
        Self {
            size: PointSize::adaptive(),
            ..Default::default()
        }
    }

    /// True when every point is one pixel (the rasterizers' fastest path).
    pub fn is_pixel(&self) -> bool {
        self.size == PointSize::Fixed(1)
    }

    pub fn is_adaptive(&self) -> bool {
        matches!(self.size, PointSize::Adaptive { .. })
    }

    /// How many pixels beyond its point a splat (or its ring) can reach: its largest half side
    /// and the pixel holding the point; 0 for one-pixel points.
    pub fn reach_px(&self) -> f32 {
        match self.size {
            PointSize::Fixed(px) if px <= 1 => 0.0,
            PointSize::Fixed(px) => (px.min(MAX_SPLAT) / 2 + 1) as f32,
            PointSize::Adaptive { .. } => (MAX_SPLAT / 2 + 1) as f32,
        }
    }

    /// True when splats are drawn as billboard quads (points larger than a pixel only).
    pub fn quads(&self) -> bool {
        self.raster == SplatRaster::Quads && !self.is_pixel()
    }

    pub(crate) fn mode(&self) -> SplatMode {
        if self.is_pixel() {
            SplatMode::Pixel
        } else {
            SplatMode::Splats(self.shape)
        }
    }

    /// The frame uniform's splat words: fixed side, adaptive scale (pixels per spacing / depth,
    /// 0 when fixed), largest side, and the gap-filling ring's side over the splat's: blending
    /// (`rings`) draws rings with its splats, the closest-point path fills gaps on the screen
    /// instead (gaps.wgsl).
    pub(crate) fn uniform(&self, focal_px: f64, rings: bool) -> [f32; 4] {
        let ring = if rings && self.is_adaptive() {
            RING
        } else {
            1.0
        };
        match self.size {
            PointSize::Fixed(px) => [px.clamp(1, MAX_SPLAT) as f32, 0.0, MAX_SPLAT as f32, 1.0],
            PointSize::Adaptive { scale } => [
                1.0,
                (scale as f64 * focal_px) as f32,
                MAX_SPLAT as f32,
                ring,
            ],
        }
    }
}

/// Side of the gap-filling ring of adaptive splats over the splat's. With splats of side
/// 1.25 × spacing, a random subset leaves a pixel uncovered by every splat with probability
/// about e^(−1.25²) ≈ 21 %, and by every ring with e^(−(1.25 · 2.8)²) ≈ 5·10⁻⁶. Blending draws
/// the rings with its splats; the closest-point path reaches as far on the screen (gaps.wgsl):
/// (2.8 − 1) / 2 = 0.9 of a splat's side beyond it.
pub const RING: f32 = 2.8;

/// How far beyond a splat of side `side` the screen's gap filling reaches, in pixels:
/// round(0.9 · side) in integers (as gaps.wgsl computes it), 1 to [`GAP_REACH_MAX`].
pub fn gap_reach(side: u32) -> u32 {
    ((side * 9 + 5) / 10).clamp(1, GAP_REACH_MAX)
}

/// The farthest the gap filling reaches (its search window is 2 · 16 + 1 pixels across).
pub const GAP_REACH_MAX: u32 = 16;

/// The pipeline override constants of a splat mode.
pub(crate) fn constants(mode: SplatMode) -> [(&'static str, f64); 2] {
    match mode {
        SplatMode::Pixel => [("SPLATS", 0.0), ("CIRCLE", 0.0)],
        SplatMode::Splats(shape) => [
            ("SPLATS", 1.0),
            ("CIRCLE", (shape == SplatShape::Circle) as u32 as f64),
        ],
    }
}

/// Surface spacing of `count` points spread over a box of `extent`: the box's two largest
/// sides span the surface (LiDAR samples surfaces); a box flat in two axes spreads them on a
/// line. The LoD pass computes the same per pointlet on the GPU (lod.wgsl).
pub fn box_spacing(extent: [f64; 3], count: u64) -> f64 {
    let mut e = extent.map(|v| v.max(0.0));
    e.sort_by(|a, b| b.total_cmp(a));
    let n = count.max(1) as f64;
    let area = e[0] * e[1];
    if area > 0.0 {
        (area / n).sqrt()
    } else {
        e[0] / n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_sizes_parse_and_refuse_what_is_out_of_range() {
        assert_eq!(PointSize::parse("1"), Ok(PointSize::Fixed(1)));
        assert_eq!(PointSize::parse("32"), Ok(PointSize::Fixed(32)));
        assert_eq!(PointSize::parse("adaptive"), Ok(PointSize::adaptive()));
        assert_eq!(
            PointSize::parse("adaptive:1.1"),
            Ok(PointSize::Adaptive { scale: 1.1 })
        );
        assert_eq!(
            PointSize::parse("adaptive:1.1").map(PointSize::name),
            Ok("adaptive:1.1".into())
        );
        for bad in [
            "0",
            "33",
            "-1",
            "1.5",
            "big",
            "",
            "adaptive:0",
            "adaptive:9",
            "adaptive:x",
        ] {
            assert!(PointSize::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(SplatShape::parse("circle"), Some(SplatShape::Circle));
        assert_eq!(SplatShape::parse("disc"), None);
    }

    #[test]
    fn box_spacing_spreads_points_over_the_two_largest_sides() {
        assert!((box_spacing([10.0, 10.0, 0.5], 100) - 1.0).abs() < 1e-12);
        assert!((box_spacing([0.5, 10.0, 10.0], 400) - 0.5).abs() < 1e-12);
        assert!((box_spacing([10.0, 0.0, 0.0], 10) - 1.0).abs() < 1e-12);
        assert_eq!(box_spacing([0.0; 3], 0), 0.0);
    }
}
