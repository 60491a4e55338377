//! Image comparison for the visual-quality experiments (virtualized paper §IV-C, Figs. 16–17):
//! PSNR over RGB and an error image of the per-pixel RGB distance.

use crate::ReportError;

/// Checks that `a` and `b` are RGBA8 images of the same size (same non-zero multiple of 4 bytes).
fn check_pair(a: &[u8], b: &[u8]) -> Result<(), ReportError> {
    if a.len() != b.len() {
        return Err(ReportError::ImageSizeMismatch {
            a: a.len(),
            b: b.len(),
        });
    }
    if a.is_empty() || !a.len().is_multiple_of(4) {
        return Err(ReportError::NotRgba(a.len()));
    }
    Ok(())
}

/// Peak signal-to-noise ratio in dB of RGBA8 image `b` against reference `a`, over the red,
/// green and blue channels (alpha ignored): 10 · log10(255² / MSE) with the MSE averaged over
/// 3 · pixels samples. Identical images give `f64::INFINITY`.
pub fn psnr(a: &[u8], b: &[u8]) -> Result<f64, ReportError> {
    check_pair(a, b)?;
    // Exact integer sum: at most 255² per sample, so u64 holds 2^40 pixels' worth.
    let squared: u64 = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .flat_map(|(p, q)| p[..3].iter().zip(&q[..3]))
        .map(|(&x, &y)| u64::from(x.abs_diff(y)).pow(2))
        .sum();
    if squared == 0 {
        return Ok(f64::INFINITY);
    }
    let samples = (a.len() / 4 * 3) as f64;
    let mse = squared as f64 / samples;
    Ok(10.0 * (255.0 * 255.0 / mse).log10())
}

/// The error image of the paper's Fig. 16: each pixel's distance |Δr| + |Δg| + |Δb| (alpha
/// ignored) divided by the largest distance in the image, drawn as an opaque RGBA8 heat ramp
/// from black (no error) through red and yellow to white (the largest error). Identical images
/// give an all-black image.
pub fn diff_image(a: &[u8], b: &[u8]) -> Result<Vec<u8>, ReportError> {
    check_pair(a, b)?;
    let distances: Vec<u16> = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .map(|(p, q)| (0..3).map(|c| u16::from(p[c].abs_diff(q[c]))).sum())
        .collect();
    let max = distances.iter().copied().max().unwrap_or(0);
    let mut out = Vec::with_capacity(a.len());
    for &d in &distances {
        let v = if max == 0 {
            0.0
        } else {
            f64::from(d) / f64::from(max)
        };
        out.extend_from_slice(&heat(v));
    }
    Ok(out)
}

/// Black → red → yellow → white over v in [0, 1], each channel ramping over one third.
fn heat(v: f64) -> [u8; 4] {
    let ramp = |start: f64| ((3.0 * v - start).clamp(0.0, 1.0) * 255.0).round() as u8;
    [ramp(0.0), ramp(1.0), ramp(2.0), 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(pixels: &[[u8; 4]]) -> Vec<u8> {
        pixels.concat()
    }

    #[test]
    fn psnr_of_known_images() {
        let a = image(&[[0, 0, 0, 255], [100, 100, 100, 255]]);
        assert_eq!(psnr(&a, &a).unwrap(), f64::INFINITY);
        // Alpha differences do not count.
        let a_alpha = image(&[[0, 0, 0, 0], [100, 100, 100, 7]]);
        assert_eq!(psnr(&a, &a_alpha).unwrap(), f64::INFINITY);
        // One sample of six off by 255: MSE = 255²/6, PSNR = 10·log10(6).
        let b = image(&[[255, 0, 0, 255], [100, 100, 100, 255]]);
        let expected = 10.0 * 6f64.log10();
        assert!((psnr(&a, &b).unwrap() - expected).abs() < 1e-12);
        // Every sample off by 1: MSE = 1, PSNR = 20·log10(255) ≈ 48.13 dB.
        let c = image(&[[1, 1, 1, 255], [101, 99, 101, 255]]);
        let expected = 20.0 * 255f64.log10();
        assert!((psnr(&a, &c).unwrap() - expected).abs() < 1e-12);
        assert!((expected - 48.1308).abs() < 1e-4);
        // Black against white: MSE = 255², PSNR = 0.
        let black = image(&[[0, 0, 0, 255]]);
        let white = image(&[[255, 255, 255, 255]]);
        assert_eq!(psnr(&black, &white).unwrap(), 0.0);
    }

    #[test]
    fn bad_image_sizes_are_errors() {
        let a = vec![0u8; 8];
        assert!(matches!(
            psnr(&a, &[0u8; 4]),
            Err(ReportError::ImageSizeMismatch { a: 8, b: 4 })
        ));
        assert!(matches!(psnr(&[], &[]), Err(ReportError::NotRgba(0))));
        assert!(matches!(
            diff_image(&[0u8; 6], &[0u8; 6]),
            Err(ReportError::NotRgba(6))
        ));
        assert_eq!(
            diff_image(&a, &[0u8; 12]).unwrap_err().to_string(),
            "cannot compare images of 8 and 12 bytes: sizes differ"
        );
    }

    #[test]
    fn diff_image_normalises_the_rgb_distance() {
        let a = image(&[
            [10, 10, 10, 255],
            [0, 0, 0, 255],
            [50, 50, 50, 0],
            [0, 0, 0, 255],
        ]);
        // Distances: 0 (alpha differs only), 30 (max), 10, 20.
        let b = image(&[
            [10, 10, 10, 0],
            [10, 10, 10, 255],
            [55, 45, 50, 0],
            [20, 0, 0, 255],
        ]);
        let d = diff_image(&a, &b).unwrap();
        assert_eq!(d.len(), a.len());
        let px: Vec<&[u8]> = d.chunks_exact(4).collect();
        assert_eq!(px[0], [0, 0, 0, 255]);
        assert_eq!(px[1], [255, 255, 255, 255], "largest error is white");
        assert_eq!(
            px[2],
            [255, 0, 0, 255],
            "a third of the largest is full red"
        );
        assert_eq!(px[3], [255, 255, 0, 255], "two thirds is yellow");
        assert!(diff_image(&a, &a)
            .unwrap()
            .chunks_exact(4)
            .all(|p| p == [0, 0, 0, 255]));
        assert_eq!(heat(0.5), [255, 128, 0, 255]);
    }
}
