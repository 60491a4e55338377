//! The CRS a LAS file's records name: GeoTIFF keys (LASF_Projection 34735, with the ASCII
//! parameters of 34737) or OGC WKT (LASF_Projection 2112).
//!
//! GeoTIFF keys give the projected CRS (ProjectedCSTypeGeoKey 3072) in preference to the
//! geographic one it is built on (GeographicTypeGeoKey 2048); 32767 means user-defined (named by
//! its citation); a vertical CRS (VerticalCSTypeGeoKey 4096) is added. WKT gives its top-level
//! AUTHORITY/ID, else its name, and the vertical part of a compound CRS. When both encodings are
//! present, the one that names an authority code wins, GeoTIFF first.

use crate::Vlr;
use std::fmt;

const GEOTIFF_KEYS: u16 = 34735;
const GEOTIFF_ASCII: u16 = 34737;
const WKT: u16 = 2112;
const USER_DEFINED: u16 = 32767;
/// WKT nesting deeper than this is not a CRS anyone wrote; refusing it bounds the recursion.
const MAX_WKT_DEPTH: usize = 32;

/// One CRS, as its records identify it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CrsId {
    Epsg(u32),
    /// Another authority's code, e.g. `ESRI:102100`.
    Authority(String, String),
    /// Defined by parameters (GeoTIFF code 32767), with its citation when it has one.
    UserDefined(Option<String>),
    /// A WKT CRS without an authority code, by its name.
    Named(String),
}

impl CrsId {
    fn has_code(&self) -> bool {
        matches!(self, CrsId::Epsg(_) | CrsId::Authority(..))
    }
}

impl fmt::Display for CrsId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CrsId::Epsg(code) => write!(f, "EPSG:{code}"),
            CrsId::Authority(a, code) => write!(f, "{a}:{code}"),
            CrsId::UserDefined(None) => write!(f, "user-defined"),
            CrsId::UserDefined(Some(c)) => write!(f, "user-defined ({c})"),
            CrsId::Named(n) => write!(f, "\"{n}\""),
        }
    }
}

/// What the CRS records of a file or store say.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Crs {
    /// The projected or geographic CRS; `None` when the records name only a vertical one.
    pub horizontal: Option<CrsId>,
    pub vertical: Option<CrsId>,
    /// `"GeoTIFF keys"` or `"WKT"`: the records the identification came from.
    pub encoding: &'static str,
    /// The WKT text, when there is a WKT record.
    pub wkt: Option<String>,
}

impl fmt::Display for Crs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.horizontal, &self.vertical) {
            (Some(h), Some(v)) => write!(f, "{h} + {v} vertical"),
            (Some(h), None) => write!(f, "{h}"),
            (None, Some(v)) => write!(f, "{v} vertical"),
            (None, None) => write!(f, "unidentified"),
        }
    }
}

impl Crs {
    /// The CRS of `vlrs`, `None` when they hold no CRS record.
    pub fn from_vlrs(vlrs: &[Vlr]) -> Option<Crs> {
        let wkt = vlrs
            .iter()
            .find(|v| v.is_crs() && v.record_id == WKT)
            .map(|v| {
                String::from_utf8_lossy(&v.data)
                    .trim_end_matches('\0')
                    .trim()
                    .to_string()
            });
        let from_keys = vlrs
            .iter()
            .find(|v| v.is_crs() && v.record_id == GEOTIFF_KEYS)
            .and_then(|keys| {
                let ascii = vlrs
                    .iter()
                    .find(|v| v.is_crs() && v.record_id == GEOTIFF_ASCII)
                    .map_or(&[][..], |v| &v.data[..]);
                geotiff(&keys.data, ascii)
            });
        let from_wkt = wkt.as_deref().and_then(wkt_ids);
        let coded = |ids: &Option<(Option<CrsId>, Option<CrsId>)>| {
            ids.as_ref()
                .is_some_and(|(h, _)| h.as_ref().is_some_and(CrsId::has_code))
        };
        let (ids, encoding) = if coded(&from_keys) || (from_keys.is_some() && !coded(&from_wkt)) {
            (from_keys, "GeoTIFF keys")
        } else {
            (from_wkt, "WKT")
        };
        if ids.is_none() && wkt.is_none() {
            return None;
        }
        let (horizontal, vertical) = ids.unwrap_or_default();
        Some(Crs {
            horizontal,
            vertical,
            encoding,
            wkt,
        })
    }
}

/// Whether the CRS records of `a` and `b` describe the same CRS: the same records, or the same
/// authority codes (e.g. GeoTIFF keys and WKT naming the same EPSG code). Records without a CRS
/// match only records without a CRS.
pub fn same_crs(a: &[Vlr], b: &[Vlr]) -> bool {
    let records = |v: &[Vlr]| -> Vec<(u16, Vec<u8>)> {
        let mut r: Vec<_> = v
            .iter()
            .filter(|v| v.is_crs())
            .map(|v| (v.record_id, v.data.clone()))
            .collect();
        r.sort();
        r
    };
    if records(a) == records(b) {
        return true;
    }
    match (Crs::from_vlrs(a), Crs::from_vlrs(b)) {
        (Some(x), Some(y)) => {
            x.horizontal.as_ref().is_some_and(CrsId::has_code)
                && x.horizontal == y.horizontal
                && x.vertical == y.vertical
        }
        _ => false,
    }
}

/// (horizontal, vertical) from a GeoKeyDirectory: a header of 4 u16 (the last is the number of
/// keys), then keys of 4 u16 (id, location, count, value or offset).
fn geotiff(data: &[u8], ascii: &[u8]) -> Option<(Option<CrsId>, Option<CrsId>)> {
    let words: Vec<u16> = data
        .chunks_exact(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    let count = usize::from(*words.get(3)?);
    let keys: Vec<&[u16]> = words.get(4..)?.chunks_exact(4).take(count).collect();
    let short = |id: u16| keys.iter().find(|k| k[0] == id && k[1] == 0).map(|k| k[3]);
    let citation = |ids: &[u16]| {
        ids.iter().find_map(|id| {
            let k = keys.iter().find(|k| k[0] == *id && k[1] == GEOTIFF_ASCII)?;
            let (at, len) = (usize::from(k[3]), usize::from(k[2]));
            let text = ascii.get(at..at.checked_add(len)?)?;
            let text = String::from_utf8_lossy(text);
            let text = text.trim_end_matches(['|', '\0']).trim();
            let named = !text.is_empty() && !text.eq_ignore_ascii_case("unnamed");
            named.then(|| text.to_string())
        })
    };
    let code = |v: u16, citations: &[u16]| match v {
        0 => None,
        USER_DEFINED => Some(CrsId::UserDefined(citation(citations))),
        c => Some(CrsId::Epsg(u32::from(c))),
    };
    // GTModelTypeGeoKey 1: projected, even when no projected CRS code is given.
    let projected_model = short(1024) == Some(1);
    let horizontal = match (short(3072), short(2048)) {
        (Some(p), _) if p != 0 => code(p, &[3073, 1026]),
        (_, Some(g)) if g != 0 && !projected_model => code(g, &[2049, 1026]),
        _ if projected_model => Some(CrsId::UserDefined(citation(&[3073, 1026]))),
        (_, Some(g)) => code(g, &[2049, 1026]),
        _ => None,
    };
    let vertical = short(4096).and_then(|v| code(v, &[4097]));
    (horizontal.is_some() || vertical.is_some()).then_some((horizontal, vertical))
}

/// A WKT element: `KEYWORD[arg, ...]`; arguments are quoted text, bare values or elements.
#[derive(Debug)]
enum Wkt {
    Node(String, Vec<Wkt>),
    Text(String),
    Bare(String),
}

fn wkt_ids(text: &str) -> Option<(Option<CrsId>, Option<CrsId>)> {
    let mut chars = text.chars().peekable();
    let Wkt::Node(keyword, args) = parse_wkt(&mut chars, 0)? else {
        return None;
    };
    let compound = matches!(keyword.as_str(), "COMPD_CS" | "COMPOUNDCRS");
    if let Some(id) = authority(&args) {
        return Some((Some(id), vertical_child(&args)));
    }
    if compound {
        let horizontal = args.iter().find_map(|a| match a {
            Wkt::Node(k, sub) if !is_vertical(k) => Some(identify(sub)),
            _ => None,
        });
        return Some((horizontal, vertical_child(&args)));
    }
    Some((Some(identify(&args)), vertical_child(&args)))
}

fn is_vertical(keyword: &str) -> bool {
    matches!(keyword, "VERT_CS" | "VERTCS" | "VERTCRS" | "VERTICALCRS")
}

fn vertical_child(args: &[Wkt]) -> Option<CrsId> {
    args.iter().find_map(|a| match a {
        Wkt::Node(k, sub) if is_vertical(k) => Some(identify(sub)),
        _ => None,
    })
}

/// The element's authority code, else its name.
fn identify(args: &[Wkt]) -> CrsId {
    authority(args).unwrap_or_else(|| {
        let name = args.iter().find_map(|a| match a {
            Wkt::Text(t) => Some(t.clone()),
            _ => None,
        });
        name.map_or(CrsId::UserDefined(None), CrsId::Named)
    })
}

/// `AUTHORITY["EPSG","2994"]` (WKT 1) or `ID["EPSG",2994]` (WKT 2) among the arguments.
fn authority(args: &[Wkt]) -> Option<CrsId> {
    args.iter().find_map(|a| match a {
        Wkt::Node(k, sub) if k == "AUTHORITY" || k == "ID" => {
            let value = |w: &Wkt| match w {
                Wkt::Text(t) | Wkt::Bare(t) => Some(t.trim().to_string()),
                Wkt::Node(..) => None,
            };
            let name = value(sub.first()?)?;
            let code = value(sub.get(1)?)?;
            Some(match code.parse::<u32>() {
                Ok(c) if name.eq_ignore_ascii_case("EPSG") => CrsId::Epsg(c),
                _ => CrsId::Authority(name, code),
            })
        }
        _ => None,
    })
}

fn parse_wkt(chars: &mut std::iter::Peekable<std::str::Chars<'_>>, depth: usize) -> Option<Wkt> {
    if depth > MAX_WKT_DEPTH {
        return None;
    }
    while chars.next_if(|c| c.is_whitespace()).is_some() {}
    if chars.next_if_eq(&'"').is_some() {
        let mut t = String::new();
        loop {
            match chars.next()? {
                // A doubled quote is a quote inside the text.
                '"' if chars.next_if_eq(&'"').is_some() => t.push('"'),
                '"' => return Some(Wkt::Text(t)),
                c => t.push(c),
            }
        }
    }
    let mut word = String::new();
    while let Some(c) = chars.next_if(|c| !matches!(c, '[' | '(' | ']' | ')' | ',')) {
        word.push(c);
    }
    let word = word.trim().to_string();
    if chars.next_if(|c| matches!(c, '[' | '(')).is_none() {
        return Some(Wkt::Bare(word));
    }
    let mut args = Vec::new();
    loop {
        args.push(parse_wkt(chars, depth + 1)?);
        while chars.next_if(|c| c.is_whitespace()).is_some() {}
        match chars.next()? {
            ',' => continue,
            ']' | ')' => return Some(Wkt::Node(word.to_ascii_uppercase(), args)),
            _ => return None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vlr(record_id: u16, data: Vec<u8>) -> Vlr {
        Vlr {
            user_id: "LASF_Projection".into(),
            record_id,
            description: String::new(),
            data,
            extended: false,
        }
    }

    fn keys(entries: &[[u16; 4]]) -> Vlr {
        let mut words = vec![1, 1, 0, entries.len() as u16];
        words.extend(entries.iter().flatten());
        vlr(
            GEOTIFF_KEYS,
            words.iter().flat_map(|w| w.to_le_bytes()).collect(),
        )
    }

    #[test]
    fn geotiff_prefers_the_projected_code_and_adds_the_vertical() {
        let k = keys(&[[1024, 0, 1, 1], [2048, 0, 1, 4152], [3072, 0, 1, 2994]]);
        let c = Crs::from_vlrs(&[k]).unwrap();
        assert_eq!(c.to_string(), "EPSG:2994");
        let k = keys(&[[2048, 0, 1, 4152], [3072, 0, 1, 2994], [4096, 0, 1, 5703]]);
        let c = Crs::from_vlrs(&[k]).unwrap();
        assert_eq!(c.to_string(), "EPSG:2994 + EPSG:5703 vertical");
        let k = keys(&[[1024, 0, 1, 2], [2048, 0, 1, 4326]]);
        assert_eq!(Crs::from_vlrs(&[k]).unwrap().to_string(), "EPSG:4326");
    }

    #[test]
    fn geotiff_user_defined_is_named_by_its_citation() {
        let k = keys(&[
            [2048, 0, 1, 32767],
            [3072, 0, 1, 32767],
            [3073, 34737, 4, 0],
        ]);
        let ascii = vlr(GEOTIFF_ASCII, b"LCC1|x|\0".to_vec());
        let c = Crs::from_vlrs(&[k.clone(), ascii]).unwrap();
        assert_eq!(c.horizontal, Some(CrsId::UserDefined(Some("LCC1".into()))));
        assert_eq!(c.to_string(), "user-defined (LCC1)");
        assert_eq!(Crs::from_vlrs(&[k]).unwrap().to_string(), "user-defined");
    }

    #[test]
    fn wkt_top_level_authority_else_name_and_compound_parts() {
        let w = |s: &str| vlr(WKT, s.as_bytes().to_vec());
        let projcs = r#"PROJCS["a",GEOGCS["g",AUTHORITY["EPSG","4152"]],AUTHORITY["EPSG","2994"]]"#;
        assert_eq!(
            Crs::from_vlrs(&[w(projcs)]).unwrap().to_string(),
            "EPSG:2994"
        );
        let named = r#"PROJCS["Lambert, ""x""",GEOGCS["g",AUTHORITY["EPSG","4152"]]]"#;
        assert_eq!(
            Crs::from_vlrs(&[w(named)]).unwrap().horizontal,
            Some(CrsId::Named("Lambert, \"x\"".into()))
        );
        let compound = r#"COMPD_CS["c",PROJCS["p",AUTHORITY["EPSG","2991"]],VERT_CS["v",AUTHORITY["EPSG","6360"]]]"#;
        assert_eq!(
            Crs::from_vlrs(&[w(compound)]).unwrap().to_string(),
            "EPSG:2991 + EPSG:6360 vertical"
        );
        let wkt2 = r#"PROJCRS["p", BASEGEOGCRS["g"], ID["EPSG", 32633]]"#;
        assert_eq!(
            Crs::from_vlrs(&[w(wkt2)]).unwrap().to_string(),
            "EPSG:32633"
        );
        for bad in ["", "PROJCS[", "PROJCS[\"a\"", &"A[".repeat(100)] {
            let c = Crs::from_vlrs(&[w(bad)]).unwrap();
            assert_eq!(c.horizontal, None, "{bad}");
        }
    }

    #[test]
    fn same_crs_by_records_or_by_code() {
        let k = keys(&[[3072, 0, 1, 2994]]);
        let w = vlr(WKT, br#"PROJCS["x",AUTHORITY["EPSG","2994"]]"#.to_vec());
        let other = keys(&[[3072, 0, 1, 2992]]);
        let k = std::slice::from_ref(&k);
        assert!(same_crs(k, k));
        assert!(same_crs(k, &[w]));
        assert!(!same_crs(k, &[other]));
        assert!(!same_crs(k, &[]));
        assert!(same_crs(&[], &[]));
        let user = keys(&[[3072, 0, 1, 32767]]);
        let user2 = keys(&[[3072, 0, 1, 32767], [3076, 0, 1, 9002]]);
        assert!(
            !same_crs(&[user], &[user2]),
            "user-defined: records must match"
        );
    }
}
