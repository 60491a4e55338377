//! Merging the headers of several inputs into the one header a store is built with.

use crate::StoreError;
use pointlet_core::crs::{same_crs, Crs};
use pointlet_core::{Aabb, LasFields, PointLayout, Quantization, SourceMeta, Vlr};

/// Scale given to inputs whose positions are not integers (PLY, XYZ): millimetres.
const FLOAT_INPUT_SCALE: f64 = 0.001;
/// The coarsest scale chosen for float inputs when millimetres cannot span the extent.
const COARSEST_SCALE: f64 = 0.01;
/// Decimal scales tried, finest first, when the preferred scale cannot span the extent.
const DECIMAL_SCALES: [f64; 10] = [1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0];
const AXES: [char; 3] = ['x', 'y', 'z'];

/// One header for all inputs:
/// - quantization: kept exactly when every input has the same one; otherwise per axis the finest
///   input scale (millimetres for float inputs), coarsened by powers of ten (up to 0.01 or the
///   coarsest input scale) only when the merged extent does not fit 32-bit integers;
/// - layout: the union; LAS point format: the inputs' when all agree, else the smallest 1.4
///   format holding the layout; bounds: the union; point count: the sum;
/// - CRS: inputs in different CRSs are refused; inputs without one take the others';
/// - records: the CRS records and the extra-bytes description of the first input that has
///   them, and every other record that all LAS inputs carry, byte for byte (so waveform data
///   survives only when every LAS input points into the same packets);
/// - LAS header fields: see [`merge_las_fields`].
///
/// `names` name the inputs in messages. Inputs that claim no points do not vote on
/// quantization or bounds.
pub fn merge_meta(metas: &[SourceMeta], names: &[String]) -> Result<SourceMeta, StoreError> {
    let name = |i: usize| {
        names
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("input {}", i + 1))
    };
    let mut total = 0u64;
    for m in metas {
        total = total
            .checked_add(m.point_count)
            .ok_or_else(|| StoreError::meta("the inputs claim more than 2^64 points"))?;
    }
    if total == 0 {
        return Err(StoreError::meta("no points: the inputs claim no points"));
    }
    let voters: Vec<&SourceMeta> = metas.iter().filter(|m| m.point_count > 0).collect();
    let mut bounds = Aabb::EMPTY;
    for (i, m) in voters.iter().enumerate() {
        if m.bounds.is_empty() {
            continue;
        }
        let finite = m
            .bounds
            .min
            .iter()
            .chain(m.bounds.max.iter())
            .all(|v| v.is_finite());
        if !finite {
            return Err(StoreError::meta(format!(
                "input {} ({}) has bounds that are not finite: {:?} to {:?}",
                i + 1,
                m.format,
                m.bounds.min,
                m.bounds.max
            )));
        }
        bounds = bounds.union(&m.bounds);
    }
    if bounds.is_empty() {
        return Err(StoreError::meta(
            "the inputs give no bounds, so positions cannot be quantized",
        ));
    }
    let quantization = choose_quantization(&voters, &bounds)?;
    let layout = metas
        .iter()
        .fold(PointLayout::default(), |l, m| l.union(m.layout));
    let first_format = metas.first().and_then(|m| m.las_point_format);
    let las_point_format = if metas.iter().all(|m| m.las_point_format == first_format) {
        first_format.unwrap_or_else(|| layout.las_point_format())
    } else {
        layout.las_point_format()
    };
    check_crs(metas, &name)?;
    let las = merge_las_fields(metas, &name)?;
    let format = match metas {
        [one] => one.format.clone(),
        _ => format!("merge of {} inputs", metas.len()),
    };
    Ok(SourceMeta {
        format,
        point_count: total,
        bounds,
        quantization: Some(quantization),
        layout,
        las_point_format: Some(las_point_format),
        vlrs: merge_vlrs(metas),
        las,
    })
}

/// Refuses inputs whose CRS records name different CRSs (reprojection is not done here).
fn check_crs(metas: &[SourceMeta], name: &dyn Fn(usize) -> String) -> Result<(), StoreError> {
    let has_crs = |m: &SourceMeta| m.vlrs.iter().any(Vlr::is_crs);
    let Some(first) = metas.iter().position(has_crs) else {
        return Ok(());
    };
    for (i, m) in metas.iter().enumerate().skip(first + 1) {
        if has_crs(m) && !same_crs(&metas[first].vlrs, &m.vlrs) {
            let describe = |m: &SourceMeta| {
                Crs::from_vlrs(&m.vlrs).map_or("?".into(), |c| format!("{c} ({})", c.encoding))
            };
            return Err(StoreError::meta(format!(
                "{} is in CRS {} but {} is in CRS {}: inputs in different CRSs cannot be \
                 merged (reproject them to one CRS first)",
                name(first),
                describe(&metas[first]),
                name(i),
                describe(m)
            )));
        }
    }
    Ok(())
}

/// The records of the merged store, in the order the inputs give them.
fn merge_vlrs(metas: &[SourceMeta]) -> Vec<Vlr> {
    let first_with = |f: fn(&Vlr) -> bool| metas.iter().position(|m| m.vlrs.iter().any(f));
    let crs_from = first_with(Vlr::is_crs);
    let extra_bytes_from = first_with(Vlr::is_extra_bytes);
    let las: Vec<&SourceMeta> = metas.iter().filter(|m| m.las.is_some()).collect();
    let mut out: Vec<Vlr> = Vec::new();
    for (i, m) in metas.iter().enumerate() {
        for v in &m.vlrs {
            let keep = if v.is_crs() {
                crs_from == Some(i)
            } else if v.is_extra_bytes() {
                extra_bytes_from == Some(i)
            } else {
                !las.is_empty() && las.iter().all(|l| l.vlrs.contains(v))
            };
            if keep && !out.contains(v) {
                out.push(v.clone());
            }
        }
    }
    out
}

/// The LAS header fields of a merge: each field the LAS inputs agree on; where they differ,
/// zero (the system identifier becomes "MERGE", as the LAS specification suggests); the
/// synthetic-return-numbers bit when any input sets it. Inputs with GPS times that disagree on
/// the GPS time type are refused: their timestamps count from different origins.
pub(crate) fn merge_las_fields(
    metas: &[SourceMeta],
    name: &dyn Fn(usize) -> String,
) -> Result<Option<LasFields>, StoreError> {
    let las: Vec<(usize, &LasFields)> = metas
        .iter()
        .enumerate()
        .filter_map(|(i, m)| m.las.as_ref().map(|l| (i, l)))
        .collect();
    let Some((_, first)) = las.first() else {
        return Ok(None);
    };
    let adjusted = |l: &LasFields| l.global_encoding & LasFields::ADJUSTED_STANDARD_GPS_TIME;
    let timed: Vec<(usize, &LasFields)> = las
        .iter()
        .copied()
        .filter(|(i, _)| metas[*i].layout.gps_time)
        .collect();
    if let Some((a, la)) = timed.first() {
        if let Some((b, lb)) = timed.iter().find(|(_, l)| adjusted(l) != adjusted(la)) {
            let kind = |l: &LasFields| {
                if adjusted(l) != 0 {
                    "adjusted standard GPS time"
                } else {
                    "GPS week time"
                }
            };
            return Err(StoreError::meta(format!(
                "{} has {} but {} has {}: their GPS times cannot be merged",
                name(*a),
                kind(la),
                name(*b),
                kind(lb)
            )));
        }
    }
    let agreed = |f: &dyn Fn(&LasFields) -> bool| las.iter().all(|(_, l)| f(l));
    let mut out = LasFields::default();
    if let Some((_, l)) = timed.first() {
        out.global_encoding |= adjusted(l);
    }
    let synthetic = LasFields::SYNTHETIC_RETURN_NUMBERS;
    if las.iter().any(|(_, l)| l.global_encoding & synthetic != 0) {
        out.global_encoding |= synthetic;
    }
    if agreed(&|l| l.file_source_id == first.file_source_id) {
        out.file_source_id = first.file_source_id;
    }
    if agreed(&|l| l.project_id == first.project_id) {
        out.project_id = first.project_id;
    }
    out.system_identifier = if agreed(&|l| l.system_identifier == first.system_identifier) {
        first.system_identifier.clone()
    } else {
        "MERGE".into()
    };
    Ok(Some(out))
}

/// The quantization for `voters` (inputs that have points) spanning `bounds`.
pub(crate) fn choose_quantization(
    voters: &[&SourceMeta],
    bounds: &Aabb,
) -> Result<Quantization, StoreError> {
    let quantized: Vec<Quantization> = voters.iter().filter_map(|m| m.quantization).collect();
    for q in &quantized {
        q.validate()
            .map_err(|e| StoreError::meta(format!("an input has a bad quantization: {e}")))?;
    }
    if let Some(first) = quantized.first() {
        if quantized.len() == voters.len() && quantized.iter().all(|q| q == first) {
            return Ok(*first);
        }
    }
    let has_float_input = quantized.len() < voters.len();
    let mut out = Quantization {
        scale: [0.0; 3],
        offset: [0.0; 3],
    };
    for (axis, axis_name) in AXES.iter().enumerate() {
        let input_scales = quantized.iter().map(|q| q.scale[axis]);
        let float_scale = has_float_input.then_some(FLOAT_INPUT_SCALE);
        let all = input_scales.clone().chain(float_scale);
        let finest = all.clone().fold(f64::INFINITY, f64::min);
        let limit = all.fold(COARSEST_SCALE, f64::max);
        let mut candidates = vec![finest];
        candidates.extend(
            DECIMAL_SCALES
                .iter()
                .filter(|s| **s > finest && **s <= limit),
        );
        // An input's own offset keeps its grid (and any grid offset from it by whole steps).
        let preferred_offset = quantized.first().map(|q| q.offset[axis]);
        let found = candidates.iter().find_map(|s| {
            let centred = centred_offset(bounds, axis, *s);
            preferred_offset
                .into_iter()
                .chain(std::iter::once(centred))
                .find(|o| fits(bounds, axis, *s, *o))
                .map(|o| (*s, o))
        });
        let Some((scale, offset)) = found else {
            // LAS bounds are only what the headers claim, and headers can be wrong.
            let claim = if quantized.is_empty() {
                ""
            } else {
                " (by the bounds their headers claim)"
            };
            return Err(StoreError::meta(format!(
                "the inputs span {:e} to {:e} on {}{claim}: too far apart for 32-bit integer \
                 coordinates even at a scale of {limit}",
                bounds.min[axis], bounds.max[axis], axis_name
            )));
        };
        out.scale[axis] = scale;
        out.offset[axis] = offset;
    }
    Ok(out)
}

/// An offset on the grid of `scale` near the middle of the bounds (largest room either side).
fn centred_offset(bounds: &Aabb, axis: usize, scale: f64) -> f64 {
    let centre = 0.5 * bounds.min[axis] + 0.5 * bounds.max[axis];
    (centre / scale).round() * scale
}

/// Whether both ends of the bounds quantize into `i32` on `axis`.
fn fits(bounds: &Aabb, axis: usize, scale: f64, offset: f64) -> bool {
    let inside = |v: f64| {
        let r = ((v - offset) / scale).round();
        r.is_finite() && r >= i32::MIN as f64 && r <= i32::MAX as f64
    };
    offset.is_finite() && inside(bounds.min[axis]) && inside(bounds.max[axis])
}

#[cfg(test)]
mod tests {
    use super::*;
    use pointlet_core::Vlr;

    fn meta(points: u64, min: [f64; 3], max: [f64; 3], q: Option<Quantization>) -> SourceMeta {
        SourceMeta {
            format: "test".into(),
            point_count: points,
            bounds: Aabb { min, max },
            quantization: q,
            layout: PointLayout::default(),
            las_point_format: q.map(|_| 1),
            vlrs: Vec::new(),
            las: None,
        }
    }

    fn q(scale: f64, offset: f64) -> Quantization {
        Quantization {
            scale: [scale; 3],
            offset: [offset; 3],
        }
    }

    #[test]
    fn shared_quantization_is_kept_exactly() {
        let a = meta(10, [0.0; 3], [10.0; 3], Some(q(0.01, 5.0)));
        let b = meta(20, [100.0; 3], [200.0; 3], Some(q(0.01, 5.0)));
        let m = merge_meta(&[a, b], &[]).unwrap();
        assert_eq!(m.quantization, Some(q(0.01, 5.0)));
        assert_eq!(m.point_count, 30);
        assert_eq!(m.bounds.max, [200.0; 3]);
        assert_eq!(m.las_point_format, Some(1));
    }

    #[test]
    fn mixed_quantizations_take_the_finest_scale_and_a_first_input_offset() {
        let a = meta(10, [0.0; 3], [10.0; 3], Some(q(0.01, 5.0)));
        let b = meta(20, [0.0; 3], [10.0; 3], Some(q(0.001, 0.0)));
        let m = merge_meta(&[a, b], &[]).unwrap();
        assert_eq!(m.quantization, Some(q(0.001, 5.0)));
    }

    #[test]
    fn float_inputs_get_millimetres_then_centimetres_then_an_error() {
        let small = meta(2, [0.0; 3], [1000.0; 3], None);
        assert_eq!(
            merge_meta(&[small], &[])
                .unwrap()
                .quantization
                .unwrap()
                .scale,
            [0.001; 3]
        );
        // 10 000 km does not fit at 1 mm (4 295 km) but does at 1 cm.
        let wide = meta(2, [0.0; 3], [1e7, 1.0, 1.0], None);
        let qw = merge_meta(&[wide], &[]).unwrap().quantization.unwrap();
        assert_eq!(qw.scale, [0.01, 0.001, 0.001]);
        assert!(qw.quantize([0.0, 0.0, 0.0]).is_ok() && qw.quantize([1e7, 1.0, 1.0]).is_ok());
        let huge = meta(2, [0.0; 3], [1e300, 0.0, 0.0], None);
        let e = merge_meta(&[huge], &[]).unwrap_err().to_string();
        assert!(e.contains("on x") && e.contains("32-bit"), "{e}");
        // A float input with a finer LAS input: the finer scale wins.
        let las = meta(2, [0.0; 3], [1.0; 3], Some(q(0.0001, 0.0)));
        let ply = meta(2, [0.0; 3], [1.0; 3], None);
        let m = merge_meta(&[las, ply], &[]).unwrap();
        assert_eq!(m.quantization.unwrap().scale, [0.0001; 3]);
        assert_eq!(
            m.las_point_format,
            Some(6),
            "formats disagree: a 1.4 format"
        );
    }

    #[test]
    fn bad_inputs_are_refused() {
        let e = merge_meta(&[meta(0, [0.0; 3], [1.0; 3], None)], &[]).unwrap_err();
        assert!(e.to_string().contains("no points"));
        assert!(merge_meta(&[], &[])
            .unwrap_err()
            .to_string()
            .contains("no points"));
        let nan = meta(1, [0.0; 3], [f64::NAN, 1.0, 1.0], None);
        assert!(merge_meta(&[nan], &[])
            .unwrap_err()
            .to_string()
            .contains("not finite"));
        let inf = meta(1, [f64::NEG_INFINITY, 0.0, 0.0], [1.0; 3], None);
        assert!(merge_meta(&[inf], &[]).is_err());
        let nob = meta(1, [f64::INFINITY; 3], [f64::NEG_INFINITY; 3], None);
        assert!(merge_meta(&[nob], &[])
            .unwrap_err()
            .to_string()
            .contains("no bounds"));
        let bad_scale = meta(1, [0.0; 3], [1.0; 3], Some(q(0.0, 0.0)));
        let other = meta(1, [0.0; 3], [1.0; 3], None);
        assert!(merge_meta(&[bad_scale, other], &[]).is_err());
    }

    #[test]
    fn layout_format_and_vlrs() {
        let crs = Vlr {
            user_id: "LASF_Projection".into(),
            record_id: 2112,
            description: "wkt".into(),
            data: b"GEOGCS".to_vec(),
            extended: false,
        };
        let other = Vlr {
            user_id: "Someone".into(),
            record_id: 1,
            description: String::new(),
            data: vec![1],
            extended: false,
        };
        let mut a = meta(1, [0.0; 3], [1.0; 3], Some(q(0.01, 0.0)));
        a.layout.gps_time = true;
        a.las_point_format = Some(1);
        a.vlrs = vec![other.clone()];
        let mut b = a.clone();
        b.layout.rgb = true;
        b.layout.extra_bytes = 4;
        b.las_point_format = Some(3);
        b.vlrs = vec![other, crs.clone()];
        let mut c = b.clone();
        c.vlrs = vec![Vlr {
            description: "second".into(),
            ..crs.clone()
        }];
        let m = merge_meta(&[a.clone(), b.clone(), c], &[]).unwrap();
        assert!(m.layout.gps_time && m.layout.rgb && m.layout.extra_bytes == 4);
        assert_eq!(m.las_point_format, Some(7));
        assert_eq!(m.vlrs, vec![crs]);
        let same = merge_meta(&[b.clone(), b], &[]).unwrap();
        assert_eq!(same.las_point_format, Some(3));
        // A zero-point input does not vote on quantization.
        let empty = meta(0, [0.0; 3], [0.0; 3], Some(q(0.5, 0.0)));
        let m = merge_meta(&[a.clone(), empty], &[]).unwrap();
        assert_eq!(m.quantization, a.quantization);
    }

    fn geokeys(code: u16) -> Vlr {
        let words = [1u16, 1, 0, 1, 3072, 0, 1, code];
        Vlr {
            user_id: "LASF_Projection".into(),
            record_id: 34735,
            description: String::new(),
            data: words.iter().flat_map(|w| w.to_le_bytes()).collect(),
            extended: false,
        }
    }

    #[test]
    fn different_crss_are_refused_naming_both_inputs() {
        let mut a = meta(1, [0.0; 3], [1.0; 3], Some(q(0.01, 0.0)));
        a.vlrs = vec![geokeys(2994)];
        let mut b = a.clone();
        b.vlrs = vec![geokeys(2992)];
        let names = ["a.las".to_string(), "b.las".to_string()];
        let e = merge_meta(&[a.clone(), b], &names).unwrap_err().to_string();
        for want in ["a.las", "b.las", "EPSG:2994", "EPSG:2992"] {
            assert!(e.contains(want), "{e}");
        }
        // The same EPSG code as WKT is the same CRS; no CRS takes the others'.
        let mut wkt = a.clone();
        wkt.vlrs = vec![Vlr {
            record_id: 2112,
            data: br#"PROJCS["x",AUTHORITY["EPSG","2994"]]"#.to_vec(),
            ..geokeys(0)
        }];
        let none = meta(1, [0.0; 3], [1.0; 3], Some(q(0.01, 0.0)));
        let m = merge_meta(&[none, a.clone(), wkt], &names).unwrap();
        assert_eq!(m.vlrs, a.vlrs);
    }

    #[test]
    fn records_and_header_fields_kept_are_those_the_las_inputs_share() {
        let rec = |id: u16, byte: u8| Vlr {
            user_id: "Vendor".into(),
            record_id: id,
            description: String::new(),
            data: vec![byte],
            extended: id > 100,
        };
        let fields = LasFields {
            global_encoding: LasFields::ADJUSTED_STANDARD_GPS_TIME,
            file_source_id: 7,
            project_id: [3; 16],
            system_identifier: "scanner".into(),
        };
        let mut a = meta(1, [0.0; 3], [1.0; 3], Some(q(0.01, 0.0)));
        a.layout.gps_time = true;
        a.las = Some(fields.clone());
        a.vlrs = vec![rec(1, 1), rec(2, 2), rec(200, 3)];
        let one = merge_meta(std::slice::from_ref(&a), &[]).unwrap();
        assert_eq!(
            (one.vlrs.clone(), one.las.clone()),
            (a.vlrs.clone(), a.las.clone())
        );
        let mut b = a.clone();
        b.vlrs = vec![rec(200, 3), rec(2, 9)];
        b.las = Some(LasFields {
            file_source_id: 8,
            global_encoding: fields.global_encoding | LasFields::SYNTHETIC_RETURN_NUMBERS,
            system_identifier: "other".into(),
            ..fields.clone()
        });
        let ply = meta(1, [0.0; 3], [1.0; 3], None);
        let m = merge_meta(&[a.clone(), b.clone(), ply], &[]).unwrap();
        assert_eq!(m.vlrs, vec![rec(200, 3)]);
        let l = m.las.unwrap();
        assert_eq!(l.global_encoding, 0b1001);
        assert_eq!((l.file_source_id, l.project_id), (0, [3; 16]));
        assert_eq!(l.system_identifier, "MERGE");
        // GPS week time and adjusted standard time do not mix.
        b.las.as_mut().unwrap().global_encoding = 0;
        let e = merge_meta(&[a, b], &[]).unwrap_err().to_string();
        assert!(
            e.contains("GPS week time") && e.contains("adjusted standard"),
            "{e}"
        );
    }
}
