//! The quantization of inputs whose positions are not integers (PLY, text).
//!
//! Per axis the step is the power of ten the data's own precision calls for (the decimals a
//! text file writes; for binary floats, the spacing of the values at the largest magnitude),
//! coarsened by powers of ten only as far as the extent needs to fit the store's 32-bit
//! integers, and not beyond 0.01 (or the data's own step, when coarser). A finer step than the
//! data holds would keep nothing more.

use pointlet_core::{Aabb, Quantization};

/// The finest step chosen from the data: 10^-12 (a float's precision needs no finer one).
pub const MAX_DECIMALS: i32 = 12;
/// The coarsest step the extent may force on data written more finely: 0.01.
const COARSEST_DECIMALS: i32 = 2;

/// 10^-decimals, correctly rounded (3 gives exactly the literal 0.001).
pub fn decimal_step(decimals: i32) -> f64 {
    if decimals >= 0 {
        1.0 / 10f64.powi(decimals)
    } else {
        10f64.powi(-decimals)
    }
}

/// The decimals a number is written with: `1.250` → 3, `5e-4` → 4, `12` → 0 (at most
/// [`MAX_DECIMALS`]).
pub fn written_decimals(number: &str) -> i32 {
    let (mantissa, exponent) = match number.find(['e', 'E']) {
        Some(i) => (&number[..i], number[i + 1..].parse::<i32>().unwrap_or(0)),
        None => (number, 0),
    };
    let fraction = mantissa.find('.').map_or(0, |i| mantissa.len() - i - 1);
    let fraction = i32::try_from(fraction).unwrap_or(MAX_DECIMALS);
    fraction.saturating_sub(exponent).clamp(0, MAX_DECIMALS)
}

/// The decimals that keep apart neighbouring values of a float type near `magnitude`:
/// the largest power-of-ten step not above their spacing there (`ulp`).
pub fn float_decimals(magnitude: f64, ulp: impl Fn(f64) -> f64) -> i32 {
    let spacing = ulp(magnitude.abs());
    if !(spacing.is_finite() && spacing > 0.0) {
        return MAX_DECIMALS;
    }
    let d = -spacing.log10().floor();
    if d >= MAX_DECIMALS as f64 {
        MAX_DECIMALS
    } else {
        // Above ~1e300 the spacing is huge: the fit below coarsens further anyway.
        d.max(-300.0) as i32
    }
}

/// Spacing of f32 values at `m` (m ≥ 0).
pub fn f32_ulp(m: f64) -> f64 {
    let f = m as f32;
    f64::from(f32::from_bits(f.to_bits() + 1)) - f64::from(f)
}

/// Spacing of f64 values at `m` (m ≥ 0).
pub fn f64_ulp(m: f64) -> f64 {
    f64::from_bits(m.to_bits() + 1) - m
}

/// `scale` on every axis, with an offset on its grid near the middle of the bounds; `Err(axis)`
/// for the first axis whose extent does not fit 32-bit integers at that scale.
pub fn quantization_with_scale(bounds: &Aabb, scale: f64) -> Result<Quantization, usize> {
    let mut q = Quantization {
        scale: [scale; 3],
        offset: [0.0; 3],
    };
    for axis in 0..3 {
        q.offset[axis] = centred_offset(bounds, axis, scale);
        if !fits(bounds, axis, scale, q.offset[axis]) {
            return Err(axis);
        }
    }
    Ok(q)
}

/// Per axis the step of `decimals[axis]`, coarsened by powers of ten until the bounds fit;
/// `None` when an axis does not fit even at 0.01 (or the data's own step, when coarser): the
/// merge of inputs then says so.
pub fn fit_quantization(bounds: &Aabb, decimals: [i32; 3]) -> Option<Quantization> {
    let mut q = Quantization {
        scale: [1.0; 3],
        offset: [0.0; 3],
    };
    for (axis, finest) in decimals.into_iter().enumerate() {
        let coarsest = finest.min(COARSEST_DECIMALS);
        let (step, offset) = (coarsest..=finest).rev().find_map(|d| {
            let step = decimal_step(d);
            let offset = centred_offset(bounds, axis, step);
            fits(bounds, axis, step, offset).then_some((step, offset))
        })?;
        q.scale[axis] = step;
        q.offset[axis] = offset;
    }
    Some(q)
}

fn centred_offset(bounds: &Aabb, axis: usize, scale: f64) -> f64 {
    let centre = 0.5 * bounds.min[axis] + 0.5 * bounds.max[axis];
    let steps = (centre / scale).round();
    // n / 10^d, not n × 10^-d: 0.0001 is inexact, and 1025 × 0.0001 is 0.10250000000000001.
    let per_unit = (1.0 / scale).round();
    if scale < 1.0 && (per_unit * scale - 1.0).abs() < 1e-12 {
        steps / per_unit
    } else {
        steps * scale
    }
}

/// Whether both ends of the bounds quantize into `i32` on `axis`.
fn fits(bounds: &Aabb, axis: usize, scale: f64, offset: f64) -> bool {
    let inside = |v: f64| {
        let r = ((v - offset) / scale).round();
        r.is_finite() && r >= f64::from(i32::MIN) && r <= f64::from(i32::MAX)
    };
    scale > 0.0 && offset.is_finite() && inside(bounds.min[axis]) && inside(bounds.max[axis])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimals_written() {
        assert_eq!(written_decimals("1.250"), 3);
        assert_eq!(written_decimals("-12"), 0);
        assert_eq!(written_decimals("5e-4"), 4);
        assert_eq!(written_decimals("1.5E2"), 0);
        assert_eq!(written_decimals("0.1234567890123456789"), MAX_DECIMALS);
        assert_eq!(decimal_step(3), 0.001);
        assert_eq!(decimal_step(-2), 100.0);
    }

    #[test]
    fn offsets_are_the_decimal_they_print_as() {
        let b = Aabb {
            min: [0.1, -0.2, 0.3],
            max: [0.105, -0.195, 0.305],
        };
        let q = quantization_with_scale(&b, 0.0001).unwrap();
        assert_eq!(format!("{:?}", q.offset), "[0.1025, -0.1975, 0.3025]");
        let q = fit_quantization(&b, [4; 3]).unwrap();
        assert_eq!(format!("{:?}", q.offset), "[0.1025, -0.1975, 0.3025]");
    }

    #[test]
    fn float_spacing_sets_the_step() {
        // f32 near 0.005: spacing 4.7e-10, so 1e-10 keeps every value apart.
        assert_eq!(float_decimals(0.005, f32_ulp), 10);
        // f32 near 600 000 (UTM): spacing 0.0625.
        assert_eq!(float_decimals(600_000.0, f32_ulp), 2);
        assert_eq!(float_decimals(0.005, f64_ulp), MAX_DECIMALS);
    }

    #[test]
    fn the_extent_coarsens_the_step_only_as_needed() {
        let b = Aabb {
            min: [0.0, 1000.0, -1.0],
            max: [0.005, 1100.0, 1.0],
        };
        let q = fit_quantization(&b, [12, 12, 3]).unwrap();
        assert_eq!(q.scale, [1e-11, 1e-7, 0.001]);
        for axis in 0..3 {
            assert!(fits(&b, axis, q.scale[axis], q.offset[axis]));
            assert!(!fits(&b, axis, q.scale[axis] / 10.0, q.offset[axis]) || axis == 2);
        }
        assert_eq!(quantization_with_scale(&b, 1e-9), Err(1));
        let huge = Aabb {
            min: [0.0; 3],
            max: [1e300, 1.0, 1.0],
        };
        assert_eq!(fit_quantization(&huge, [12; 3]), None, "not beyond 0.01");
        let km = Aabb {
            min: [0.0; 3],
            max: [1e7, 1.0, 1.0],
        };
        assert_eq!(fit_quantization(&km, [6; 3]).unwrap().scale[0], 0.01);
        assert_eq!(quantization_with_scale(&b, 1e-6).unwrap().scale, [1e-6; 3]);
    }
}
