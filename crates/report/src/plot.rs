//! Line and stacked-area plots without a plotting library: standalone SVG text, or PNG bytes
//! rasterised here (Bresenham lines, a built-in 3×5 bitmap font for titles, ticks and legend).
//!
//! Axes take "nice" ranges (steps of 1, 2 or 5 × 10ᵏ) that cover every finite point; points
//! with a non-finite coordinate break a series' line instead of distorting the axes.

use crate::stats::StageBreakdown;
use crate::ReportError;

/// Limits on `plot_png`'s size: below the minimum the margins leave no plot; the maximum
/// bounds the RGBA buffer (256 MiB).
pub const MIN_PLOT_SIDE: u32 = 160;
pub const MAX_PLOT_SIDE: u32 = 8192;

const SVG_WIDTH: f64 = 800.0;
const SVG_HEIGHT: f64 = 500.0;
/// Values beyond this are clamped when choosing axis ranges, so spans never overflow.
const VALUE_LIMIT: f64 = 1e300;
/// Mapped coordinates are clamped to this many pixels: far outside any image, still finite.
const PIXEL_LIMIT: f64 = 1e6;

/// One named line of a plot.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    /// sRGB colour of the line.
    pub color: [u8; 3],
    /// (x, y) in data units, drawn in the given order.
    pub points: Vec<(f64, f64)>,
}

const PALETTE: [[u8; 3]; 8] = [
    [52, 101, 164],
    [230, 124, 40],
    [78, 154, 6],
    [204, 0, 0],
    [117, 80, 123],
    [196, 160, 0],
    [6, 152, 154],
    [110, 110, 110],
];

/// A distinguishable colour for series `i` (cycles after eight).
pub fn palette(i: usize) -> [u8; 3] {
    PALETTE[i % PALETTE.len()]
}

/// A nice axis: range [lo, hi] in whole steps, with a tick at every step.
struct Scale {
    lo: f64,
    hi: f64,
    step: f64,
    ticks: Vec<f64>,
}

impl Scale {
    fn nice(min: f64, max: f64) -> Scale {
        let (mut lo, mut hi) = (min, max);
        if lo >= hi {
            let pad = if lo == 0.0 {
                1.0
            } else {
                (lo.abs() * 0.1).max(1e-300)
            };
            lo -= pad;
            hi += pad;
        }
        // About five intervals, rounded to 1, 2 or 5 times a power of ten.
        let raw = (hi - lo) / 5.0;
        let magnitude = 10f64.powf(raw.log10().floor());
        let norm = raw / magnitude;
        let step = magnitude
            * if norm < 1.5 {
                1.0
            } else if norm < 3.5 {
                2.0
            } else if norm < 7.5 {
                5.0
            } else {
                10.0
            };
        let first = (lo / step).floor();
        let last = (hi / step).ceil();
        let count = (last - first).clamp(1.0, 100.0) as usize;
        // Ticks as whole multiples of the step, so labels carry no accumulated rounding.
        let ticks = (0..=count).map(|i| (first + i as f64) * step).collect();
        Scale {
            lo: first * step,
            hi: (first + count as f64) * step,
            step,
            ticks,
        }
    }

    /// Where `v` lies on the axis, 0 at `lo` and 1 at `hi`.
    fn fraction(&self, v: f64) -> f64 {
        (v - self.lo) / (self.hi - self.lo)
    }

    fn label(&self, v: f64) -> String {
        let v = if v.abs() < self.step * 1e-6 { 0.0 } else { v };
        let step_exp = self.step.log10().floor();
        if self.step >= 1e6 || self.step < 1e-4 {
            let digits = (v.abs().log10().floor() - step_exp).clamp(0.0, 15.0) as usize;
            format!("{v:.digits$e}")
        } else {
            let decimals = (-step_exp).clamp(0.0, 15.0) as usize;
            format!("{v:.decimals$}")
        }
    }
}

/// Pixel rectangle of the plot area and the two axes.
struct Layout {
    left: f64,
    right: f64,
    top: f64,
    bottom: f64,
    x: Scale,
    y: Scale,
}

impl Layout {
    fn new(size: (f64, f64), margins: [f64; 4], x: Scale, y: Scale) -> Layout {
        let [left, right, top, bottom] = margins;
        Layout {
            left,
            right: size.0 - right,
            top,
            bottom: size.1 - bottom,
            x,
            y,
        }
    }

    /// Data → pixel coordinates (y grows downwards), clamped to stay finite.
    fn px(&self, x: f64, y: f64) -> (f64, f64) {
        let px = self.left + self.x.fraction(x) * (self.right - self.left);
        let py = self.bottom - self.y.fraction(y) * (self.bottom - self.top);
        (
            px.clamp(-PIXEL_LIMIT, PIXEL_LIMIT),
            py.clamp(-PIXEL_LIMIT, PIXEL_LIMIT),
        )
    }
}

/// Nice scales covering every finite point (0..1 when there is none).
fn scales(points: impl Iterator<Item = (f64, f64)>) -> (Scale, Scale) {
    let mut range = [[f64::INFINITY, f64::NEG_INFINITY]; 2];
    for (x, y) in points.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        for (r, v) in range.iter_mut().zip([x, y]) {
            let v = v.clamp(-VALUE_LIMIT, VALUE_LIMIT);
            r[0] = r[0].min(v);
            r[1] = r[1].max(v);
        }
    }
    let [x, y] = range.map(|[lo, hi]| {
        if lo <= hi {
            Scale::nice(lo, hi)
        } else {
            Scale::nice(0.0, 1.0)
        }
    });
    (x, y)
}

/// The runs of consecutive finite points, in pixels.
fn finite_runs<'a>(
    layout: &'a Layout,
    points: &'a [(f64, f64)],
) -> impl Iterator<Item = Vec<(f64, f64)>> + 'a {
    points
        .split(|(x, y)| !(x.is_finite() && y.is_finite()))
        .filter(|run| !run.is_empty())
        .map(|run| run.iter().map(|&(x, y)| layout.px(x, y)).collect())
}

fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// Text safe inside XML content and attribute values: markup characters escaped, characters
/// that XML 1.0 forbids dropped.
fn xml_text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' | '\n' | '\r' => out.push(' '),
            c if c < ' ' || c == '\u{fffe}' || c == '\u{ffff}' => {}
            c => out.push(c),
        }
    }
    out
}

fn svg_points(run: &[(f64, f64)]) -> String {
    run.iter()
        .map(|(x, y)| format!("{x:.2},{y:.2}"))
        .collect::<Vec<_>>()
        .join(" ")
}

const SVG_MARGINS: [f64; 4] = [72.0, 16.0, 36.0, 48.0];

/// Opens the document and draws background, title, grid, ticks, axes and axis labels; the
/// caller adds its marks inside the plot clip, then the legend and `</svg>`.
fn svg_frame(layout: &Layout, title: &str, x_label: &str, y_label: &str) -> String {
    let (w, h) = (SVG_WIDTH, SVG_HEIGHT);
    let (l, r, t, b) = (layout.left, layout.right, layout.top, layout.bottom);
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" \
         viewBox=\"0 0 {w} {h}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n\
         <text x=\"{:.1}\" y=\"22\" text-anchor=\"middle\" font-size=\"16\">{}</text>\n\
         <defs><clipPath id=\"plot-area\"><rect x=\"{l}\" y=\"{t}\" width=\"{:.2}\" \
         height=\"{:.2}\"/></clipPath></defs>\n",
        w / 2.0,
        xml_text(title),
        r - l,
        b - t
    );
    s.push_str("<g stroke=\"#dddddd\" stroke-width=\"1\">\n");
    for &v in &layout.x.ticks {
        let (x, _) = layout.px(v, 0.0);
        s.push_str(&format!(
            "<line x1=\"{x:.2}\" y1=\"{t}\" x2=\"{x:.2}\" y2=\"{b}\"/>\n"
        ));
    }
    for &v in &layout.y.ticks {
        let (_, y) = layout.px(0.0, v);
        s.push_str(&format!(
            "<line x1=\"{l}\" y1=\"{y:.2}\" x2=\"{r}\" y2=\"{y:.2}\"/>\n"
        ));
    }
    s.push_str("</g>\n<g fill=\"#333333\">\n");
    for &v in &layout.x.ticks {
        let (x, _) = layout.px(v, 0.0);
        s.push_str(&format!(
            "<text x=\"{x:.2}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n",
            b + 16.0,
            xml_text(&layout.x.label(v))
        ));
    }
    for &v in &layout.y.ticks {
        let (_, y) = layout.px(0.0, v);
        s.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{:.2}\" text-anchor=\"end\">{}</text>\n",
            l - 6.0,
            y + 4.0,
            xml_text(&layout.y.label(v))
        ));
    }
    s.push_str(&format!(
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n\
         <text transform=\"translate(16 {:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>\n\
         </g>\n",
        0.5 * (l + r),
        h - 8.0,
        xml_text(x_label),
        0.5 * (t + b),
        xml_text(y_label)
    ));
    s.push_str(&format!(
        "<path d=\"M{l} {t}V{b}H{r}\" fill=\"none\" stroke=\"black\" stroke-width=\"1\"/>\n"
    ));
    s
}

/// Legend box in the plot's top-right corner, one swatch and name per entry.
fn svg_legend<'a>(layout: &Layout, entries: impl Iterator<Item = (&'a str, [u8; 3])>) -> String {
    let entries: Vec<_> = entries.collect();
    if entries.is_empty() {
        return String::new();
    }
    // Sans-serif at 12 px averages under 7 px per character.
    let longest = entries
        .iter()
        .map(|(n, _)| n.chars().count())
        .max()
        .unwrap_or(0);
    let width = 34.0 + 7.0 * longest as f64;
    let height = 8.0 + 16.0 * entries.len() as f64;
    let (x, y) = (layout.right - width - 8.0, layout.top + 8.0);
    let mut s = format!(
        "<g>\n<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{width:.1}\" height=\"{height:.1}\" \
         fill=\"white\" fill-opacity=\"0.85\" stroke=\"#999999\"/>\n"
    );
    for (i, (name, color)) in entries.iter().enumerate() {
        let row = y + 12.0 + 16.0 * i as f64;
        s.push_str(&format!(
            "<line x1=\"{:.1}\" y1=\"{row:.1}\" x2=\"{:.1}\" y2=\"{row:.1}\" stroke=\"{}\" \
             stroke-width=\"3\"/>\n<text x=\"{:.1}\" y=\"{:.1}\">{}</text>\n",
            x + 6.0,
            x + 24.0,
            hex(*color),
            x + 30.0,
            row + 4.0,
            xml_text(name)
        ));
    }
    s.push_str("</g>\n");
    s
}

/// A multi-line plot as a standalone SVG document (800×500): title, axes with ticks and
/// labels, grid, one polyline per series (broken at non-finite points) and a legend.
pub fn plot_svg(title: &str, series: &[Series], x_label: &str, y_label: &str) -> String {
    let (x, y) = scales(series.iter().flat_map(|s| s.points.iter().copied()));
    let layout = Layout::new((SVG_WIDTH, SVG_HEIGHT), SVG_MARGINS, x, y);
    let mut s = svg_frame(&layout, title, x_label, y_label);
    s.push_str("<g clip-path=\"url(#plot-area)\" fill=\"none\" stroke-width=\"1.5\">\n");
    for line in series {
        for run in finite_runs(&layout, &line.points) {
            s.push_str(&format!(
                "<polyline stroke=\"{}\" points=\"{}\"/>\n",
                hex(line.color),
                svg_points(&run)
            ));
        }
    }
    s.push_str("</g>\n");
    s.push_str(&svg_legend(
        &layout,
        series.iter().map(|s| (s.name.as_str(), s.color)),
    ));
    s.push_str("</svg>\n");
    s
}

/// The stage breakdown as a stacked-area SVG (x: frame index, y: ms; stages stacked bottom to
/// top in breakdown order, coloured by `palette`), so the top edge is the frame's total time.
pub fn plot_stages_svg(title: &str, breakdown: &StageBreakdown) -> String {
    let frames = breakdown.frames();
    let totals = breakdown.frame_totals_ms();
    let extent = [(0.0, 0.0), (frames.saturating_sub(1) as f64, 0.0)];
    let (x, y) = scales(
        extent
            .into_iter()
            .chain(totals.iter().enumerate().map(|(i, &t)| (i as f64, t))),
    );
    let layout = Layout::new((SVG_WIDTH, SVG_HEIGHT), SVG_MARGINS, x, y);
    let mut s = svg_frame(&layout, title, "frame", "time (ms)");
    s.push_str("<g clip-path=\"url(#plot-area)\" stroke-width=\"0.5\">\n");
    let mut below = vec![0.0; frames];
    for (k, (_, ms)) in breakdown.series().enumerate() {
        let above: Vec<f64> = below.iter().zip(ms).map(|(b, m)| b + m).collect();
        let upper = above.iter().enumerate().map(|(i, &v)| (i as f64, v));
        let lower = below.iter().enumerate().rev().map(|(i, &v)| (i as f64, v));
        let outline: Vec<_> = upper.chain(lower).map(|(x, y)| layout.px(x, y)).collect();
        if !outline.is_empty() {
            let color = hex(palette(k));
            s.push_str(&format!(
                "<polygon fill=\"{color}\" fill-opacity=\"0.85\" stroke=\"{color}\" points=\"{}\"/>\n",
                svg_points(&outline)
            ));
        }
        below = above;
    }
    s.push_str("</g>\n");
    s.push_str(&svg_legend(
        &layout,
        breakdown.names().enumerate().map(|(k, n)| (n, palette(k))),
    ));
    s.push_str("</svg>\n");
    s
}

/// 3×5 glyphs, one bit per pixel, rows top to bottom, three bits per row (high bit left).
/// Letters are upper case; lower case is drawn with them; unknown characters are blank.
fn glyph(c: char) -> u16 {
    match c.to_ascii_uppercase() {
        '0' => 0b111_101_101_101_111,
        '1' => 0b010_110_010_010_111,
        '2' => 0b111_001_111_100_111,
        '3' => 0b111_001_111_001_111,
        '4' => 0b101_101_111_001_001,
        '5' => 0b111_100_111_001_111,
        '6' => 0b111_100_111_101_111,
        '7' => 0b111_001_001_001_001,
        '8' => 0b111_101_111_101_111,
        '9' => 0b111_101_111_001_111,
        '.' => 0b000_000_000_000_010,
        ',' => 0b000_000_000_010_100,
        '-' => 0b000_000_111_000_000,
        '+' => 0b000_010_111_010_000,
        '%' => 0b101_001_010_100_101,
        '(' => 0b010_100_100_100_010,
        ')' => 0b010_001_001_001_010,
        '/' => 0b001_001_010_100_100,
        ':' => 0b000_010_000_010_000,
        '_' => 0b000_000_000_000_111,
        '=' => 0b000_111_000_111_000,
        '<' => 0b001_010_100_010_001,
        '>' => 0b100_010_001_010_100,
        'A' => 0b010_101_111_101_101,
        'B' => 0b110_101_110_101_110,
        'C' => 0b011_100_100_100_011,
        'D' => 0b110_101_101_101_110,
        'E' => 0b111_100_110_100_111,
        'F' => 0b111_100_110_100_100,
        'G' => 0b011_100_101_101_011,
        'H' => 0b101_101_111_101_101,
        'I' => 0b111_010_010_010_111,
        'J' => 0b001_001_001_101_010,
        'K' => 0b101_101_110_101_101,
        'L' => 0b100_100_100_100_111,
        'M' => 0b101_111_111_101_101,
        'N' => 0b110_101_101_101_101,
        'O' => 0b010_101_101_101_010,
        'P' => 0b110_101_110_100_100,
        'Q' => 0b010_101_101_110_011,
        'R' => 0b110_101_110_101_101,
        'S' => 0b011_100_010_001_110,
        'T' => 0b111_010_010_010_010,
        'U' => 0b101_101_101_101_111,
        'V' => 0b101_101_101_101_010,
        'W' => 0b101_101_111_111_101,
        'X' => 0b101_101_010_101_101,
        'Y' => 0b101_101_010_010_010,
        'Z' => 0b111_001_010_100_111,
        _ => 0,
    }
}

/// An RGBA8 image being drawn; every write is bounds-checked, so marks may stray outside.
struct Canvas {
    width: i64,
    height: i64,
    rgba: Vec<u8>,
}

impl Canvas {
    fn new(width: u32, height: u32) -> Canvas {
        Canvas {
            width: i64::from(width),
            height: i64::from(height),
            rgba: vec![255; width as usize * height as usize * 4],
        }
    }

    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if (0..self.width).contains(&x) && (0..self.height).contains(&y) {
            let i = ((y * self.width + x) * 4) as usize;
            self.rgba[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Fills [x0, x1) × [y0, y1), clipped to the canvas.
    fn fill(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3]) {
        for y in y0.max(0)..y1.min(self.height) {
            for x in x0.max(0)..x1.min(self.width) {
                self.put(x, y, c);
            }
        }
    }

    /// A line clipped to `clip` ([x0, y0, x1, y1] in pixels), two pixels thick when `bold`.
    fn line(&mut self, a: (f64, f64), b: (f64, f64), clip: [f64; 4], c: [u8; 3], bold: bool) {
        let Some((a, b)) = clip_segment(a, b, clip) else {
            return;
        };
        // Both ends now lie inside the canvas, so the walk takes at most width + height steps.
        let (mut x, mut y) = (a.0.round() as i64, a.1.round() as i64);
        let (x1, y1) = (b.0.round() as i64, b.1.round() as i64);
        let (dx, dy) = ((x1 - x).abs(), -(y1 - y).abs());
        let (sx, sy) = ((x1 - x).signum(), (y1 - y).signum());
        let mut err = dx + dy;
        loop {
            self.put(x, y, c);
            if bold {
                self.put(x + 1, y, c);
                self.put(x, y + 1, c);
            }
            if x == x1 && y == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// Text with its top-left corner at (x, y), each font pixel `scale` pixels wide.
    fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            let bits = glyph(ch);
            let gx = x + i as i64 * 4 * scale;
            for row in 0..5 {
                for col in 0..3 {
                    if bits >> (14 - (row * 3 + col)) & 1 == 1 {
                        let (px, py) = (gx + col * scale, y + row * scale);
                        self.fill(px, py, px + scale, py + scale, c);
                    }
                }
            }
        }
    }
}

fn text_width(s: &str, scale: i64) -> i64 {
    (s.chars().count() as i64 * 4 - 1).max(0) * scale
}

/// Liang–Barsky: the part of segment a→b inside the rectangle, if any.
fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    [x0, y0, x1, y1]: [f64; 4],
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

const INK: [u8; 3] = [0, 0, 0];
const GRID: [u8; 3] = [221, 221, 221];
const FRAME_GREY: [u8; 3] = [153, 153, 153];

/// The same plot as `plot_svg`, rasterised to a `width`×`height` RGBA PNG. Text uses the
/// built-in 3×5 font (doubled when both sides are at least 300 pixels); the y-axis label sits above the axis.
pub fn plot_png(
    title: &str,
    series: &[Series],
    x_label: &str,
    y_label: &str,
    width: u32,
    height: u32,
) -> Result<Vec<u8>, ReportError> {
    let side = MIN_PLOT_SIDE..=MAX_PLOT_SIDE;
    if !side.contains(&width) || !side.contains(&height) {
        return Err(ReportError::PlotSize { width, height });
    }
    let scale: i64 = if width.min(height) >= 300 { 2 } else { 1 };
    let line_h = 5 * scale;
    let (x, y) = scales(series.iter().flat_map(|s| s.points.iter().copied()));
    // Left: room for 10-character tick labels; top: title and y label rows.
    let margins = [
        (44 * scale + 10) as f64,
        12.0,
        (2 * line_h + 18) as f64,
        (2 * line_h + 20) as f64,
    ];
    let layout = Layout::new((f64::from(width), f64::from(height)), margins, x, y);
    let mut canvas = Canvas::new(width, height);
    let (l, r, t, b) = (
        layout.left.round() as i64,
        layout.right.round() as i64,
        layout.top.round() as i64,
        layout.bottom.round() as i64,
    );

    for &v in &layout.x.ticks {
        let px = layout.px(v, 0.0).0.round() as i64;
        canvas.fill(px, t, px + 1, b, GRID);
        canvas.fill(px, b, px + 1, b + 4, INK);
        let label = layout.x.label(v);
        canvas.text(
            px - text_width(&label, scale) / 2,
            b + 7,
            &label,
            scale,
            INK,
        );
    }
    for &v in &layout.y.ticks {
        let py = layout.px(0.0, v).1.round() as i64;
        canvas.fill(l, py, r, py + 1, GRID);
        canvas.fill(l - 4, py, l, py + 1, INK);
        let label = layout.y.label(v);
        let w = text_width(&label, scale);
        canvas.text(l - 7 - w, py - line_h / 2, &label, scale, INK);
    }
    canvas.fill(l, t, l + 1, b + 1, INK);
    canvas.fill(l, b, r + 1, b + 1, INK);

    let clip = [layout.left, layout.top, layout.right, layout.bottom];
    for line in series {
        for run in finite_runs(&layout, &line.points) {
            match run.as_slice() {
                [single] => canvas.line(*single, *single, clip, line.color, true),
                pairs => {
                    for w in pairs.windows(2) {
                        canvas.line(w[0], w[1], clip, line.color, true);
                    }
                }
            }
        }
    }

    let w = i64::from(width);
    canvas.text((w - text_width(title, scale)) / 2, 6, title, scale, INK);
    canvas.text(l - 7 * scale, 12 + line_h, y_label, scale, INK);
    let x_label_left = (l + r - text_width(x_label, scale)) / 2;
    canvas.text(x_label_left, b + 13 + line_h, x_label, scale, INK);

    if !series.is_empty() {
        let longest = series
            .iter()
            .map(|s| text_width(&s.name, scale))
            .max()
            .unwrap_or(0);
        let row = line_h + 4 * scale;
        let (box_w, box_h) = (longest + 14 * scale, row * series.len() as i64 + 2 * scale);
        let (x0, y0) = (r - box_w - 6, t + 6);
        canvas.fill(x0, y0, x0 + box_w, y0 + box_h, [255, 255, 255]);
        canvas.fill(x0, y0, x0 + box_w, y0 + 1, FRAME_GREY);
        canvas.fill(x0, y0 + box_h - 1, x0 + box_w, y0 + box_h, FRAME_GREY);
        canvas.fill(x0, y0, x0 + 1, y0 + box_h, FRAME_GREY);
        canvas.fill(x0 + box_w - 1, y0, x0 + box_w, y0 + box_h, FRAME_GREY);
        for (i, s) in series.iter().enumerate() {
            let ry = y0 + 3 * scale + i as i64 * row;
            let swatch_y = ry + line_h / 2;
            canvas.fill(
                x0 + 3 * scale,
                swatch_y - scale,
                x0 + 9 * scale,
                swatch_y + scale,
                s.color,
            );
            canvas.text(x0 + 11 * scale, ry, &s.name, scale, INK);
        }
    }

    let mut out = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&canvas.rgba)?;
        writer.finish()?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every '&' starts one of XML's predefined entities or a character reference.
    fn assert_entities(text: &str) {
        for (i, _) in text.match_indices('&') {
            let rest = &text[i + 1..];
            let ok = ["amp;", "lt;", "gt;", "quot;", "apos;"]
                .iter()
                .any(|e| rest.starts_with(e))
                || (rest.starts_with('#')
                    && rest[1..].find(';').is_some_and(|end| {
                        end > 0 && rest[1..1 + end].chars().all(|c| c.is_ascii_digit())
                    }));
            assert!(ok, "bare '&' in {text:?}");
        }
    }

    /// Minimal well-formedness check: one root element, balanced and properly nested tags,
    /// quoted unique attributes, no bare '<' or '&' in text or values, no forbidden characters.
    fn assert_well_formed(xml: &str) {
        assert!(
            !xml.chars()
                .any(|c| c < ' ' && !matches!(c, '\t' | '\n' | '\r')),
            "control character"
        );
        let mut rest = xml;
        if let Some(r) = rest.strip_prefix("<?xml") {
            let end = r.find("?>").expect("unterminated prolog");
            rest = &r[end + 2..];
        }
        let mut stack: Vec<&str> = Vec::new();
        let mut roots = 0;
        while let Some(open) = rest.find('<') {
            let text = &rest[..open];
            assert_entities(text);
            if stack.is_empty() {
                assert!(text.trim().is_empty(), "text outside the root: {text:?}");
            }
            let after = &rest[open + 1..];
            let mut in_quotes = false;
            let close = after
                .char_indices()
                .find(|&(_, c)| {
                    if c == '"' {
                        in_quotes = !in_quotes;
                    }
                    c == '>' && !in_quotes
                })
                .map(|(i, _)| i)
                .expect("unterminated tag");
            let tag = &after[..close];
            rest = &after[close + 1..];
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(stack.pop(), Some(name.trim()), "mismatched </{name}>");
                continue;
            }
            let self_closing = tag.ends_with('/');
            let body = tag.trim_end_matches('/');
            let name_end = body.find(char::is_whitespace).unwrap_or(body.len());
            let name = &body[..name_end];
            assert!(
                !name.is_empty()
                    && name
                        .chars()
                        .all(|c| c.is_alphanumeric() || c == '-' || c == ':'),
                "bad tag name {name:?}"
            );
            let mut attrs = body[name_end..].trim_start();
            let mut seen = Vec::new();
            while !attrs.is_empty() {
                let eq = attrs.find('=').expect("attribute without value");
                let attr = &attrs[..eq];
                assert!(
                    !attr.is_empty() && !attr.contains(char::is_whitespace),
                    "{attr:?}"
                );
                assert!(!seen.contains(&attr), "duplicate attribute {attr}");
                seen.push(attr);
                let value_and_rest = attrs[eq + 1..]
                    .strip_prefix('"')
                    .expect("unquoted attribute value");
                let end = value_and_rest.find('"').expect("unterminated value");
                let value = &value_and_rest[..end];
                assert!(!value.contains('<'), "'<' in attribute value");
                assert_entities(value);
                attrs = value_and_rest[end + 1..].trim_start();
            }
            if stack.is_empty() {
                roots += 1;
            }
            if !self_closing {
                stack.push(name);
            }
        }
        assert!(rest.trim().is_empty(), "trailing text {rest:?}");
        assert!(stack.is_empty(), "unclosed {stack:?}");
        assert_eq!(roots, 1);
    }

    #[test]
    fn the_checker_rejects_broken_xml() {
        for bad in [
            "<svg><g></svg>",
            "<svg a=1/>",
            "<svg>a & b</svg>",
            "<svg/><svg/>",
            "<svg a=\"1\" a=\"2\"/>",
            "<svg><g></g>",
        ] {
            assert!(
                std::panic::catch_unwind(|| assert_well_formed(bad)).is_err(),
                "accepted {bad}"
            );
        }
        assert_well_formed("<?xml version=\"1.0\"?>\n<svg a=\"&amp;\"><g/>x &lt; y</svg>\n");
    }

    fn ramp() -> Vec<Series> {
        vec![
            Series {
                name: "avg <fps> & more".into(),
                color: [200, 0, 0],
                points: vec![(0.0, 0.0), (10.0, 100.0)],
            },
            Series {
                name: "flat".into(),
                color: [0, 0, 200],
                points: vec![(0.0, 50.0), (5.0, 50.0), (10.0, 50.0)],
            },
        ]
    }

    #[test]
    fn nice_scales() {
        let s = Scale::nice(0.0, 10.0);
        assert_eq!((s.lo, s.hi, s.step), (0.0, 10.0, 2.0));
        assert_eq!(s.ticks, vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let s = Scale::nice(3.0, 97.0);
        assert_eq!((s.lo, s.hi, s.step), (0.0, 100.0, 20.0));
        let s = Scale::nice(5.0, 5.0);
        assert_eq!(s.ticks.len(), 7);
        assert_eq!(
            s.ticks.iter().map(|&v| s.label(v)).collect::<Vec<_>>(),
            ["4.4", "4.6", "4.8", "5.0", "5.2", "5.4", "5.6"]
        );
        let s = Scale::nice(-3e6, 9e6);
        assert_eq!(s.step, 2e6);
        assert_eq!(s.label(-2e6), "-2e6");
        let s = Scale::nice(0.0, 0.0003);
        assert_eq!(s.step, 5e-5);
        assert_eq!(s.label(5e-5), "5e-5");
        assert_eq!(s.label(1e-4), "1.0e-4");
        assert_eq!(s.label(1.5e-4), "1.5e-4");
        assert_eq!(Scale::nice(-0.25, 0.25).label(-1e-18), "0.0");
    }

    #[test]
    fn svg_is_well_formed_and_maps_points_to_the_plot_corners() {
        let svg = plot_svg(
            "FPS\u{1} over <time>",
            &ramp(),
            "time (s)",
            "FPS & \"frames\"",
        );
        assert_well_formed(&svg);
        // x 0..10 and y 0..100 are already nice: the ramp runs corner to corner of the plot
        // area (left 72, right 800 − 16, top 36, bottom 500 − 48).
        assert!(
            svg.contains("points=\"72.00,452.00 784.00,36.00\""),
            "{svg}"
        );
        assert!(svg.contains("points=\"72.00,244.00 428.00,244.00 784.00,244.00\""));
        assert!(svg.contains("stroke=\"#c80000\"") && svg.contains("stroke=\"#0000c8\""));
        assert!(svg.contains("avg &lt;fps&gt; &amp; more"));
        assert!(
            svg.contains(">FPS over &lt;time&gt;</text>"),
            "control character dropped"
        );
        for label in ["0", "20", "100", "10"] {
            assert!(svg.contains(&format!(">{label}</text>")), "tick {label}");
        }
    }

    #[test]
    fn non_finite_points_break_lines_and_do_not_move_the_axes() {
        let s = Series {
            name: "gaps".into(),
            color: [0, 0, 0],
            points: vec![
                (0.0, 0.0),
                (1.0, f64::NAN),
                (2.0, 2.0),
                (4.0, 4.0),
                (f64::INFINITY, 9.0),
            ],
        };
        let svg = plot_svg("t", &[s], "x", "y");
        assert_well_formed(&svg);
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert!(svg.contains("points=\"72.00,452.00\""));
        assert!(
            svg.contains("points=\"428.00,244.00 784.00,36.00\""),
            "{svg}"
        );
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        let empty = plot_svg("nothing", &[], "", "");
        assert_well_formed(&empty);
        assert!(!empty.contains("<polyline"));
    }

    #[test]
    fn stacked_stages_top_out_at_the_frame_total() {
        let mut b = StageBreakdown::new(["lod", "raster", "resolve"]).unwrap();
        for i in 0..11 {
            let f = f64::from(i);
            b.push_frame(&[1.0, 2.0 + f, 0.5 * f]).unwrap();
        }
        let svg = plot_stages_svg("stages", &b);
        assert_well_formed(&svg);
        assert_eq!(svg.matches("<polygon").count(), 3);
        // Totals run 3 → 18 ms: y axis 0..20, x 0..10. The last polygon starts at the top of
        // frame 0 (3 ms) and its first upper point is the total.
        let last = svg.rsplit("<polygon").next().unwrap();
        let y3 = 452.0 - 3.0 / 20.0 * 416.0;
        assert!(last.contains(&format!("points=\"72.00,{y3:.2} ")), "{last}");
        for name in ["lod", "raster", "resolve"] {
            assert!(svg.contains(&format!(">{name}</text>")));
        }
        let empty = StageBreakdown::new(["lod"]).unwrap();
        assert_well_formed(&plot_stages_svg("none", &empty));
    }

    fn decode(bytes: &[u8]) -> (png::OutputInfo, Vec<u8>) {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        (info, buf)
    }

    #[test]
    fn png_decodes_at_the_requested_size_with_lines_inside_the_plot() {
        let bytes = plot_png("Frame rate", &ramp(), "time (s)", "fps", 640, 360).unwrap();
        let (info, rgba) = decode(&bytes);
        assert_eq!((info.width, info.height), (640, 360));
        assert_eq!(info.color_type, png::ColorType::Rgba);
        let pixel = |x: usize, y: usize| &rgba[(y * 640 + x) * 4..(y * 640 + x) * 4 + 3];
        // Margins at scale 2: left 98, right 12, top 38, bottom 40.
        let (l, r, t, b) = (98usize, 628usize, 38usize, 320usize);
        let mut red_columns = vec![false; 640];
        for y in 0..360 {
            for (x, red) in red_columns.iter_mut().enumerate() {
                if pixel(x, y) == [200, 0, 0] {
                    let in_plot = (l..=r + 1).contains(&x) && (t..=b + 1).contains(&y);
                    let in_legend = x > 400 && y < 80;
                    assert!(in_plot || in_legend, "red at {x},{y}");
                    *red = true;
                }
            }
        }
        // The diagonal is unbroken, except where the flat line (drawn later) crosses it at
        // x = 5 (pixel 363) and where the legend (down to y = 84, reached at x ≈ 545) hides its top-right end.
        let gaps: Vec<usize> = (l..=540).filter(|&x| !red_columns[x]).collect();
        assert!(gaps.iter().all(|x| x.abs_diff(363) <= 3), "{gaps:?}");
        // The flat line at y = 50 is the middle row of the plot.
        let mid = (t + b) / 2;
        assert_eq!(pixel(200, mid), [0, 0, 200]);
        assert_eq!(pixel(l, 200), [0, 0, 0], "y axis");
        assert_eq!(pixel(300, b), [0, 0, 0], "x axis");
        assert_eq!(pixel(5, 300), [255, 255, 255], "background");
        // Title text is drawn centred in the top margin.
        assert!((0..20).any(|y| (250..390).any(|x| pixel(x, y) == [0, 0, 0])));
    }

    #[test]
    fn png_size_limits_and_extreme_values() {
        for (w, h) in [(0, 100), (100, 200), (200, 9000)] {
            assert!(matches!(
                plot_png("t", &[], "x", "y", w, h),
                Err(ReportError::PlotSize { .. })
            ));
        }
        let wild = Series {
            name: "wild".into(),
            color: [1, 2, 3],
            points: vec![
                (0.0, 1e308),
                (1.0, -1e308),
                (f64::MAX, 0.0),
                (2.0, f64::MIN_POSITIVE),
            ],
        };
        let (info, _) =
            decode(&plot_png("t", std::slice::from_ref(&wild), "x", "y", 160, 160).unwrap());
        assert_eq!((info.width, info.height), (160, 160));
        assert_well_formed(&plot_svg("t", &[wild], "x", "y"));
    }

    #[test]
    fn font_glyphs_and_clipping() {
        let mut c = Canvas::new(16, 8);
        c.text(0, 0, "0", 1, [0, 0, 0]);
        let ink = |c: &Canvas, x: usize, y: usize| c.rgba[(y * 16 + x) * 4] == 0;
        let rows: Vec<String> = (0..5)
            .map(|y| {
                (0..3)
                    .map(|x| if ink(&c, x, y) { '#' } else { '.' })
                    .collect()
            })
            .collect();
        assert_eq!(rows, ["###", "#.#", "#.#", "#.#", "###"]);
        assert_eq!(glyph('a'), glyph('A'));
        assert_eq!(glyph('€'), 0);
        // Marks off the canvas are dropped, not wrapped or panicking.
        c.text(-100, -100, "888", 3, [0, 0, 0]);
        c.line(
            (-50.0, 3.0),
            (500.0, 3.0),
            [0.0, 0.0, 15.0, 7.0],
            [9, 9, 9],
            true,
        );
        assert!((0..16).all(|x| c.rgba[(3 * 16 + x) * 4] == 9 || x < 3 && ink(&c, x, 3)));
        assert_eq!(
            clip_segment((20.0, 20.0), (30.0, 30.0), [0.0, 0.0, 15.0, 7.0]),
            None
        );
    }
}
