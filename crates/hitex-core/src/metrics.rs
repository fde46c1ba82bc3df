//! Image metrics, one implementation each: PSNR and SSIM of RGBA8 images,
//! and the comparison the parity tests and benches report (mean and p99 of
//! the channel differences, with a difference image).

/// Differences between two RGBA8 images of the same size, over RGB channels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageDiff {
    /// Mean absolute difference per channel, in 8-bit steps.
    pub mean_abs: f64,
    /// 99th percentile of the per-pixel maximum channel difference, in 8-bit steps.
    pub p99: u8,
    /// Largest channel difference.
    pub max: u8,
    /// Fraction of pixels whose maximum channel difference exceeds 8 steps.
    pub frac_over_8: f64,
    /// Peak signal-to-noise ratio in dB (∞ for identical images).
    pub psnr_db: f64,
}

impl std::fmt::Display for ImageDiff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mean |Δ| {:.3}, p99 {}, max {}, >8 steps {:.3}%, PSNR {:.1} dB",
            self.mean_abs,
            self.p99,
            self.max,
            100.0 * self.frac_over_8,
            self.psnr_db
        )
    }
}

/// Compares two RGBA8 buffers of equal length; returns the metrics and a diff
/// image (per-pixel max channel difference ×8, as grey; red where > 8 steps).
///
/// # Panics
/// When the buffers differ in length (a caller's error: both are frames of
/// one size).
pub fn compare_rgba(a: &[u8], b: &[u8]) -> (ImageDiff, Vec<u8>) {
    assert_eq!(a.len(), b.len(), "compare_rgba: buffers differ in size");
    let n = a.len() / 4;
    let mut hist = [0u64; 256];
    let mut sum = 0u64;
    let mut sq = 0u64;
    let mut diff = Vec::with_capacity(a.len());
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let mut m = 0u8;
        for c in 0..3 {
            let d = pa[c].abs_diff(pb[c]);
            sum += d as u64;
            sq += (d as u64) * (d as u64);
            m = m.max(d);
        }
        hist[m as usize] += 1;
        if m > 8 {
            diff.extend_from_slice(&[255, 0, 0, 255]);
        } else {
            let g = m.saturating_mul(8);
            diff.extend_from_slice(&[g, g, g, 255]);
        }
    }
    let target = (n as f64 * 0.99).ceil() as u64;
    let mut acc = 0;
    let mut p99 = 0u8;
    for (v, &h) in hist.iter().enumerate() {
        acc += h;
        if acc >= target {
            p99 = v as u8;
            break;
        }
    }
    let max = hist.iter().rposition(|&h| h > 0).unwrap_or(0) as u8;
    let over: u64 = hist[9..].iter().sum();
    let psnr_db = psnr_of(sq as f64, 3 * n as u64);
    (
        ImageDiff {
            mean_abs: sum as f64 / (3 * n.max(1)) as f64,
            p99,
            max,
            frac_over_8: over as f64 / n.max(1) as f64,
            psnr_db,
        },
        diff,
    )
}

/// 10·log10(255² / MSE) of a sum of squared 8-bit differences over `n`
/// values: ∞ when the sum is 0 (identical), NaN when there are no values.
fn psnr_of(squares: f64, n: u64) -> f64 {
    if n == 0 {
        f64::NAN
    } else if squares == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / (squares / n as f64)).log10()
    }
}

/// Peak signal-to-noise ratio of two RGBA8 buffers over their three colour
/// channels (alpha ignored), in dB: ∞ when identical, NaN when they differ
/// in length or are empty.
pub fn psnr_rgb(a: &[u8], b: &[u8]) -> f64 {
    if a.len() != b.len() {
        return f64::NAN;
    }
    let mut se = 0.0f64;
    for (p, q) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            se += d * d;
        }
    }
    psnr_of(se, (a.len() / 4 * 3) as u64)
}

fn luma(rgba: &[u8]) -> Vec<f64> {
    rgba.chunks_exact(4).map(|p| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64).collect()
}

/// Mean SSIM of the luma (Rec. 709 weights on the 8-bit codes) of two
/// `width`×`height` RGBA8 images over 8×8 windows at a stride of 4 (the whole
/// image if smaller), with the usual constants `(0.01·255)²`, `(0.03·255)²`:
/// 1 for identical images, NaN when a buffer is not `width`×`height` or the
/// image is empty.
pub fn ssim_luma(a: &[u8], b: &[u8], width: u32, height: u32) -> f64 {
    let want = width as usize * height as usize * 4;
    if a.len() != want || b.len() != want || want == 0 {
        return f64::NAN;
    }
    let (w, h) = (width as usize, height as usize);
    let (la, lb) = (luma(a), luma(b));
    let (ww, wh) = (w.min(8), h.min(8));
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let (mut sum, mut n) = (0.0f64, 0usize);
    let starts = |len: usize, win: usize| {
        let mut v: Vec<usize> = (0..=len - win).step_by(4).collect();
        if v.last() != Some(&(len - win)) {
            v.push(len - win);
        }
        v
    };
    for y0 in starts(h, wh) {
        for x0 in starts(w, ww) {
            let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for y in y0..y0 + wh {
                for x in x0..x0 + ww {
                    let (p, q) = (la[y * w + x], lb[y * w + x]);
                    sa += p;
                    sb += q;
                    saa += p * p;
                    sbb += q * q;
                    sab += p * q;
                }
            }
            let m = (ww * wh) as f64;
            let (ma, mb) = (sa / m, sb / m);
            let (va, vb, cov) = (saa / m - ma * ma, sbb / m - mb * mb, sab / m - ma * mb);
            sum += ((2.0 * ma * mb + c1) * (2.0 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            n += 1;
        }
    }
    sum / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_by_hand() {
        let a = vec![10, 10, 10, 255, 0, 0, 0, 255];
        let b = vec![10, 10, 10, 255, 0, 0, 30, 255];
        let (d, img) = compare_rgba(&a, &b);
        assert_eq!(d.max, 30);
        assert!((d.mean_abs - 5.0).abs() < 1e-12);
        assert_eq!(d.frac_over_8, 0.5);
        assert_eq!(&img[4..8], &[255, 0, 0, 255]);
        let (same, _) = compare_rgba(&a, &a);
        assert_eq!(same.psnr_db, f64::INFINITY);
        assert_eq!(same.p99, 0);
    }

    #[test]
    fn psnr_by_hand() {
        // one channel off by 5 in 3 values: MSE 25 / 3
        let (a, b) = ([0u8, 0, 0, 255], [5u8, 0, 0, 0]);
        let want = 10.0 * (255.0f64 * 255.0 * 3.0 / 25.0).log10();
        assert!((psnr_rgb(&a, &b) - want).abs() < 1e-12);
        assert_eq!(compare_rgba(&a, &b).0.psnr_db, psnr_rgb(&a, &b));
        // alpha is ignored; identical colours are infinitely close
        assert_eq!(psnr_rgb(&[1, 2, 3, 4], &[1, 2, 3, 9]), f64::INFINITY);
        assert!(psnr_rgb(&[], &[]).is_nan() && psnr_rgb(&[0; 4], &[0; 8]).is_nan());
    }

    #[test]
    fn ssim_of_equal_and_different_images() {
        let img: Vec<u8> = (0..16 * 12).flat_map(|i| [(i * 7 % 256) as u8, (i * 3 % 256) as u8, 40, 255]).collect();
        assert!((ssim_luma(&img, &img, 16, 12) - 1.0).abs() < 1e-12);
        let flat = vec![128u8; img.len()];
        assert!(ssim_luma(&img, &flat, 16, 12) < 0.5);
        assert!(ssim_luma(&img, &img, 16, 11).is_nan() && ssim_luma(&[], &[], 0, 0).is_nan());
    }
}
