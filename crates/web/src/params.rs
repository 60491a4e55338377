//! The page URL's view state: `?store=NAME&eye=x,y,z&target=x,y,z&fov=DEG&ui=off` and the
//! viewer's settings. Eye, target and fov mean what `pointlet render --eye --target --fov`
//! means: data coordinates, z up, vertical field of view in degrees.

use pointlet_core::color::ColorMode;

/// Point size: fixed pixels or adaptive (sized from the spacing the LoD drew).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SizeParam {
    Pixels(u32),
    Adaptive,
}

/// Everything a shared link restores.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewParams {
    /// The store's file name without `.pointlet`.
    pub store: Option<String>,
    pub eye: Option<[f64; 3]>,
    pub target: Option<[f64; 3]>,
    /// Vertical field of view in degrees.
    pub fov: f64,
    /// Overlays shown (`ui=off` hides all: embedding, screenshots).
    pub ui: bool,
    /// `None`: the store's default colouring (as `pointlet render` picks it).
    pub color: Option<ColorMode>,
    pub size: SizeParam,
    pub edl: bool,
    /// The LoD's point budget B while the camera moves.
    pub budget: u64,
}

/// Point budget of a moving camera: small enough for a software WebGPU adapter.
pub const DEFAULT_BUDGET: u64 = 2_000_000;
/// `pointlet render`'s default vertical field of view.
pub const DEFAULT_FOV: f64 = 60.0;

impl Default for ViewParams {
    fn default() -> Self {
        Self {
            store: None,
            eye: None,
            target: None,
            fov: DEFAULT_FOV,
            ui: true,
            color: None,
            size: SizeParam::Pixels(1),
            edl: false,
            budget: DEFAULT_BUDGET,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParamError {
    #[error("URL parameter {name}={value}: {why}")]
    Bad {
        name: String,
        value: String,
        why: &'static str,
    },
    #[error("URL parameters eye and target go together")]
    EyeWithoutTarget,
}

fn bad(name: &str, value: &str, why: &'static str) -> ParamError {
    ParamError::Bad {
        name: name.into(),
        value: value.into(),
        why,
    }
}

fn vec3(name: &str, value: &str) -> Result<[f64; 3], ParamError> {
    let v: Vec<f64> = value
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad(name, value, "expected three numbers x,y,z"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(bad(name, value, "expected three finite numbers x,y,z")),
    }
}

/// Percent-decoding of a query component (`+` is a space).
pub fn decode_component(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match b[i] {
            b'+' => out.push(b' '),
            b'%' if i + 2 < b.len() => match (hex(b[i + 1]), hex(b[i + 2])) {
                (Some(h), Some(l)) => {
                    out.push((h * 16 + l) as u8);
                    i += 2;
                }
                _ => out.push(b'%'),
            },
            c => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Percent-encoding of everything but unreserved characters and the commas of vectors.
pub fn encode_component(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.bytes() {
        if c.is_ascii_alphanumeric() || b"-_.~,".contains(&c) {
            out.push(c as char);
        } else {
            out.push_str(&format!("%{c:02X}"));
        }
    }
    out
}

/// Shortest decimal that reads back as the same f64 (links stay exact and short).
fn num(v: f64) -> String {
    format!("{v}")
}

impl ViewParams {
    /// Parses a query string (with or without the leading `?`); unknown names are ignored so
    /// links from newer viewers still open.
    pub fn parse(query: &str) -> Result<Self, ParamError> {
        let mut p = Self::default();
        let query = query.strip_prefix('?').unwrap_or(query);
        for pair in query.split('&').filter(|s| !s.is_empty()) {
            let (name, raw) = pair.split_once('=').unwrap_or((pair, ""));
            let value = decode_component(raw);
            let v = value.as_str();
            match name {
                "store" if !v.is_empty() => p.store = Some(value.clone()),
                "eye" => p.eye = Some(vec3(name, v)?),
                "target" => p.target = Some(vec3(name, v)?),
                "fov" => {
                    p.fov = v
                        .parse::<f64>()
                        .ok()
                        .filter(|f| *f > 0.0 && *f < 180.0)
                        .ok_or_else(|| bad(name, v, "expected degrees in (0, 180)"))?
                }
                "ui" => p.ui = !matches!(v, "off" | "0" | "false"),
                "color" => {
                    p.color =
                        Some(ColorMode::parse(v).ok_or_else(|| bad(name, v, "unknown colouring"))?)
                }
                "size" => {
                    p.size = match v {
                        "adaptive" => SizeParam::Adaptive,
                        _ => SizeParam::Pixels(
                            v.parse::<u32>()
                                .ok()
                                .filter(|s| (1..=32).contains(s))
                                .ok_or_else(|| bad(name, v, "expected 1–32 or adaptive"))?,
                        ),
                    }
                }
                "edl" => p.edl = matches!(v, "on" | "1" | "true"),
                "budget" => {
                    p.budget = v
                        .parse::<u64>()
                        .ok()
                        .filter(|b| *b >= 1000)
                        .ok_or_else(|| bad(name, v, "expected at least 1000 points"))?
                }
                _ => {}
            }
        }
        if p.eye.is_some() != p.target.is_some() {
            return Err(ParamError::EyeWithoutTarget);
        }
        Ok(p)
    }

    /// The query string (with `?`) that [`parse`](Self::parse) reads back as `self`; settings
    /// at their defaults are left out.
    pub fn to_query(&self) -> String {
        let d = Self::default();
        let mut parts = Vec::new();
        if let Some(s) = &self.store {
            parts.push(format!("store={}", encode_component(s)));
        }
        if let (Some(e), Some(t)) = (self.eye, self.target) {
            parts.push(format!("eye={},{},{}", num(e[0]), num(e[1]), num(e[2])));
            parts.push(format!("target={},{},{}", num(t[0]), num(t[1]), num(t[2])));
        }
        if self.fov != d.fov {
            parts.push(format!("fov={}", num(self.fov)));
        }
        if let Some(c) = self.color {
            parts.push(format!("color={}", c.name()));
        }
        if self.size != d.size {
            parts.push(match self.size {
                SizeParam::Adaptive => "size=adaptive".to_string(),
                SizeParam::Pixels(n) => format!("size={n}"),
            });
        }
        if self.edl {
            parts.push("edl=on".into());
        }
        if self.budget != d.budget {
            parts.push(format!("budget={}", self.budget));
        }
        if !self.ui {
            parts.push("ui=off".into());
        }
        if parts.is_empty() {
            return String::new();
        }
        format!("?{}", parts.join("&"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_render_flags_meaning() {
        let p = ViewParams::parse("?store=city&eye=1,2.5,-3&target=0,0,0&fov=45&ui=off").unwrap();
        assert_eq!(p.store.as_deref(), Some("city"));
        assert_eq!(p.eye, Some([1.0, 2.5, -3.0]));
        assert_eq!(p.target, Some([0.0, 0.0, 0.0]));
        assert_eq!(p.fov, 45.0);
        assert!(!p.ui);
        assert_eq!(p.size, SizeParam::Pixels(1));
    }

    #[test]
    fn round_trips_through_the_query() {
        let p = ViewParams {
            store: Some("my city".into()),
            eye: Some([0.1 + 0.2, 1e7, -5.0]),
            target: Some([1.0, 2.0, 3.0]),
            fov: 30.5,
            ui: false,
            color: Some(ColorMode::Classification),
            size: SizeParam::Adaptive,
            edl: true,
            budget: 5_000_000,
        };
        let q = p.to_query();
        assert!(q.contains("store=my%20city"));
        assert_eq!(ViewParams::parse(&q).unwrap(), p);
        assert_eq!(ViewParams::default().to_query(), "");
    }

    #[test]
    fn refuses_bad_values() {
        assert!(ViewParams::parse("eye=1,2&target=0,0,0").is_err());
        assert!(ViewParams::parse("eye=1,2,nan&target=0,0,0").is_err());
        assert_eq!(
            ViewParams::parse("eye=1,2,3"),
            Err(ParamError::EyeWithoutTarget)
        );
        assert!(ViewParams::parse("fov=0").is_err());
        assert!(ViewParams::parse("fov=180").is_err());
        assert!(ViewParams::parse("size=0").is_err());
        assert!(ViewParams::parse("color=purple").is_err());
        // Unknown names and empty pairs are ignored.
        assert!(ViewParams::parse("?&zoom=3&").is_ok());
    }

    #[test]
    fn decodes_percent_escapes() {
        assert_eq!(decode_component("a%20b+c%2Cd"), "a b c,d");
        assert_eq!(decode_component("100%"), "100%");
        assert_eq!(decode_component("%zz"), "%zz");
    }
}
