//! Image comparison with named metrics.

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
    let mse = sq as f64 / (3 * n.max(1)) as f64;
    let psnr_db = if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / mse).log10() };
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
}
