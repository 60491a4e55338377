//! What the points are coloured by, as the UI edits it, and the classification legend.

use pointlet_core::color::{classification_color, classification_name, ColorMode, ColorScale};
use pointlet_core::PointLayout;

/// The colour modes a layout can show (RGB, GPS time and NIR only where the data has them).
pub fn available_modes(layout: &PointLayout) -> Vec<ColorMode> {
    ColorMode::ALL
        .into_iter()
        .filter(|m| m.available_in(layout))
        .collect()
}

/// The modes of [`available_modes`] and one per extra-bytes attribute named in `extras`.
pub fn available_with_extras(layout: &PointLayout, extras: &[String]) -> Vec<ColorMode> {
    let mut modes = available_modes(layout);
    modes.extend((0..extras.len().min(256)).map(|i| ColorMode::Extra(i as u8)));
    modes
}

/// Which parts of the scale mean something for a mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScaleKnobs {
    pub range: bool,
    pub gamma: bool,
    pub ramp: bool,
}

pub fn knobs(mode: ColorMode) -> ScaleKnobs {
    match mode {
        // Intensity is drawn in grey, whatever ramp is chosen.
        ColorMode::Intensity => ScaleKnobs {
            range: true,
            gamma: true,
            ramp: false,
        },
        m if m.is_scalar() => ScaleKnobs {
            range: true,
            gamma: true,
            ramp: true,
        },
        _ => ScaleKnobs {
            range: false,
            gamma: false,
            ramp: false,
        },
    }
}

/// The colouring the UI shows and edits, and the one the GPU holds: they differ until the
/// app re-uploads colours.
#[derive(Clone, Debug)]
pub struct ColorState {
    pub available: Vec<ColorMode>,
    /// Names of the extra-bytes attributes (`ColorMode::Extra(i)` is `extra_names[i]`).
    pub extra_names: Vec<String>,
    /// What the UI edits.
    pub scale: ColorScale,
    applied: Option<ColorScale>,
}

impl ColorState {
    /// Starts with `scale` already on the GPU.
    pub fn new(available: Vec<ColorMode>, scale: ColorScale) -> Self {
        Self {
            available,
            extra_names: Vec::new(),
            scale,
            applied: Some(scale),
        }
    }

    /// What the UI calls `mode` (an extra-bytes attribute by its name).
    pub fn label(&self, mode: ColorMode) -> String {
        match mode {
            ColorMode::Extra(i) => match self.extra_names.get(usize::from(i)) {
                Some(name) => format!("extra: {name}"),
                None => format!("extra bytes {i}"),
            },
            m => m.name().to_string(),
        }
    }

    pub fn mode(&self) -> ColorMode {
        self.scale.mode
    }

    /// Switches to `fitted` (the data-fitted scale of another mode), keeping the chosen ramp.
    pub fn select(&mut self, fitted: ColorScale) {
        let ramp = self.scale.ramp;
        self.scale = ColorScale { ramp, ..fitted };
    }

    /// Takes `scale` as what the GPU shows and the UI edits (a loading file's colouring,
    /// fitted by its load thread).
    pub fn adopt(&mut self, scale: ColorScale) {
        self.scale = scale;
        self.applied = Some(scale);
    }

    /// The scale the GPU shows, as last applied.
    pub fn applied(&self) -> Option<ColorScale> {
        self.applied
    }

    /// The scale to upload, if the GPU does not show it yet.
    pub fn pending(&self) -> Option<ColorScale> {
        let wanted = self.sanitized();
        (self.applied != Some(wanted)).then_some(wanted)
    }

    pub fn mark_applied(&mut self, scale: ColorScale) {
        self.applied = Some(scale);
    }

    /// The edited scale with a usable range (min < max) and gamma (> 0).
    fn sanitized(&self) -> ColorScale {
        let mut s = self.scale;
        if s.range[1].partial_cmp(&s.range[0]) != Some(std::cmp::Ordering::Greater) {
            s.range[1] = s.range[0] + 1.0;
        }
        if !s.gamma.is_finite() || s.gamma <= 0.0 {
            s.gamma = 1.0;
        }
        s
    }
}

/// One line of the classification legend.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendEntry {
    pub class: u8,
    pub name: &'static str,
    pub color: [u8; 3],
    /// Points of the class, where known (in-memory data).
    pub count: Option<u64>,
}

/// The legend: the classes present with their counts, or the standard ASPRS classes 0–18 when
/// counts are unknown (stores are not read whole).
pub fn legend(counts: Option<&[u64; 256]>) -> Vec<LegendEntry> {
    let entry = |class: u8, count| LegendEntry {
        class,
        name: classification_name(class),
        color: classification_color(class),
        count,
    };
    match counts {
        Some(c) => (0..=255u8)
            .filter(|k| c[*k as usize] > 0)
            .map(|k| entry(k, Some(c[k as usize])))
            .collect(),
        None => (0..=18u8).map(|k| entry(k, None)).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::color::Ramp;

    fn scale(mode: ColorMode) -> ColorScale {
        ColorScale {
            mode,
            range: [0.0, 10.0],
            gamma: 1.0,
            rgb_8bit: true,
            ramp: Ramp::Viridis,
            extra: None,
        }
    }

    #[test]
    fn modes_follow_the_layout() {
        let plain = available_modes(&PointLayout::default());
        assert!(!plain.contains(&ColorMode::Rgb) && !plain.contains(&ColorMode::GpsTime));
        assert!(!plain.contains(&ColorMode::Nir) && plain.contains(&ColorMode::ScanAngle));
        let full = available_modes(&PointLayout {
            rgb: true,
            gps_time: true,
            nir: true,
            ..Default::default()
        });
        assert_eq!(full.len(), ColorMode::ALL.len());
    }

    #[test]
    fn edits_are_pending_until_applied_and_sanitized() {
        let mut c = ColorState::new(vec![], scale(ColorMode::Elevation));
        assert_eq!(c.pending(), None);
        c.scale.ramp = Ramp::Turbo;
        c.select(scale(ColorMode::Intensity));
        assert_eq!(c.mode(), ColorMode::Intensity);
        assert_eq!(
            c.scale.ramp,
            Ramp::Turbo,
            "the ramp choice survives a mode switch"
        );
        c.scale.range = [5.0, 5.0];
        c.scale.gamma = -1.0;
        let p = c.pending().expect("changed");
        assert_eq!((p.range, p.gamma), ([5.0, 6.0], 1.0));
        c.mark_applied(p);
        assert_eq!(c.pending(), None);
    }

    #[test]
    fn legend_lists_present_classes_or_the_standard_ones() {
        let mut counts = [0u64; 256];
        counts[2] = 10;
        counts[6] = 3;
        let l = legend(Some(&counts));
        assert_eq!(l.len(), 2);
        assert_eq!((l[0].name, l[0].count), ("ground", Some(10)));
        assert_eq!(l[1].color, classification_color(6));
        assert_eq!(legend(None).len(), 19);
    }
}
