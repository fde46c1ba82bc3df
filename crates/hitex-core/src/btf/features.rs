//! Appearance features of a BTF sample: the first principal components of
//! each texel's appearance over the (view, light) images, what index
//! synthesis ([`super::index`]), the MIP codebooks ([`super::mip`]) and the
//! local PCA ([`super::pca`]) compare; and the dense linear algebra behind
//! them (Gram matrices, subspace iteration, Jacobi).

use super::dataset::Btf;
use crate::{hash3, unit_interval};
use rayon::prelude::*;

/// Most principal components [`features`] computes (larger requests are clamped).
pub const MAX_FEATURE_DIMS: usize = 64;

/// Most (view, light) images [`features`] reads per texel.
pub const MAX_FEATURE_IMAGES: usize = 512;

/// Floats allowed in the PCA data matrix (texels × 3 × images); large samples read fewer images.
const FEATURE_BUDGET: usize = 1 << 24;

/// Subspace-iteration limits of the PCA.
const EIGEN_ITERS: usize = 60;
const EIGEN_OVERSAMPLE: usize = 4;

/// Per-texel feature vectors of a sample: `dims` floats per texel, texels
/// row-major (`values[(y * width + x) * dims + i]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// Floats per texel.
    pub dims: usize,
    /// `texels × dims` values.
    pub values: Vec<f32>,
}

impl Features {
    /// Number of texels described.
    pub fn texels(&self) -> usize {
        self.values.len().checked_div(self.dims).unwrap_or(0)
    }

    /// The vector of texel `t` (row-major index), empty when out of range.
    pub fn texel(&self, t: usize) -> &[f32] {
        let s = t.saturating_mul(self.dims);
        self.values.get(s..s.saturating_add(self.dims)).unwrap_or(&[])
    }

    /// Variance of each dimension over the texels.
    pub fn variances(&self) -> Vec<f32> {
        let n = self.texels();
        if n == 0 {
            return vec![0.0; self.dims];
        }
        (0..self.dims)
            .map(|i| {
                let col = || self.values.chunks_exact(self.dims).map(move |v| f64::from(v[i]));
                let mean = col().sum::<f64>() / n as f64;
                (col().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64) as f32
            })
            .collect()
    }
}

/// The (view, light) images [`features`] reads for a sample of `n` texels:
/// every image when they fit the budget, else a views × lights subgrid with
/// the lights staggered from view to view.
fn feature_images(btf: &Btf, n: usize) -> Vec<usize> {
    let dirs = btf.grid().directions().max(1);
    let total = btf.images();
    let budget = (FEATURE_BUDGET / (3 * n.max(1))).clamp(1, MAX_FEATURE_IMAGES);
    if total <= budget {
        return (0..total).collect();
    }
    let views = budget.isqrt().clamp(1, dirs);
    let lights = (budget / views).clamp(1, dirs);
    let mut out = Vec::with_capacity(views * lights);
    for i in 0..views {
        let view = i * dirs / views;
        for j in 0..lights {
            out.push(btf.image_index(view, (j * dirs / lights + i) % dirs));
        }
    }
    out
}

/// PCA features of every sample texel.
///
/// A texel's appearance vector is its RGB (sRGB bytes / 255) in each of the
/// (view, light) images — all of them, or an evenly spread deterministic
/// subset of at most [`MAX_FEATURE_IMAGES`] (fewer for samples so large that
/// texels × 3 × images would pass 16 Mi floats). The vectors are mean-centred
/// and projected on the first `dims` principal components (clamped to
/// 1..=[`MAX_FEATURE_DIMS`]), found by subspace iteration with a final
/// Rayleigh–Ritz step on the Gram matrix of the texel vectors (or on their
/// covariance, whichever is smaller). Dimension 0 has the largest variance
/// and variances never increase with the dimension; dimensions past the
/// rank of the data are zero. Each component's sign makes its largest-magnitude
/// value positive. Deterministic.
pub fn features(btf: &Btf, dims: usize) -> Features {
    let dims = dims.clamp(1, MAX_FEATURE_DIMS);
    let n = btf.width() as usize * btf.height() as usize;
    let images = feature_images(btf, n);
    let l = images.len() * 3;
    let mut values = vec![0f32; n * dims];
    if n == 0 || l == 0 {
        return Features { dims, values };
    }
    let ib = btf.image_bytes();
    let texels = btf.texels();
    let mut x = vec![0f32; n * l];
    x.par_chunks_mut(l).enumerate().for_each(|(t, row)| {
        for (dst, &img) in row.chunks_exact_mut(3).zip(&images) {
            let o = img * ib + t * 3;
            if let Some(src) = texels.get(o..o + 3) {
                for (d, &b) in dst.iter_mut().zip(src) {
                    *d = f32::from(b) / 255.0;
                }
            }
        }
    });
    let mut mean = vec![0f64; l];
    for row in x.chunks_exact(l) {
        for (m, &v) in mean.iter_mut().zip(row) {
            *m += f64::from(v);
        }
    }
    let mean: Vec<f32> = mean.iter().map(|m| (m / n as f64) as f32).collect();
    x.par_chunks_mut(l).for_each(|row| {
        for (v, m) in row.iter_mut().zip(&mean) {
            *v -= m;
        }
    });

    let want = dims.min(n).min(l);
    if n <= l {
        // Gram matrix X Xᵀ: its eigenvectors u_i give the projections σ_i u_i
        let g = gram(&x, n, l);
        let (lambda, vecs) = top_eigen(&g, n, want);
        for (i, (lam, u)) in lambda.iter().zip(&vecs).enumerate() {
            let s = lam.max(0.0).sqrt();
            for (dst, &ut) in values.chunks_exact_mut(dims).zip(u) {
                dst[i] = (s * ut) as f32;
            }
        }
    } else {
        // covariance Xᵀ X: its eigenvectors v_i give the projections X v_i
        let mut xt = vec![0f32; l * n];
        for (t, row) in x.chunks_exact(l).enumerate() {
            for (j, &v) in row.iter().enumerate() {
                xt[j * n + t] = v;
            }
        }
        let c = gram(&xt, l, n);
        let (_, vecs) = top_eigen(&c, l, want);
        let vf: Vec<Vec<f32>> = vecs.iter().map(|v| v.iter().map(|&a| a as f32).collect()).collect();
        values.par_chunks_mut(dims).zip(x.par_chunks(l)).for_each(|(dst, row)| {
            for (d, v) in dst.iter_mut().zip(&vf) {
                *d = dot(row, v);
            }
        });
    }
    // deterministic signs: the largest-magnitude value of each component is positive
    for i in 0..dims {
        let mut big = 0f32;
        for v in values.chunks_exact(dims) {
            if v[i].abs() > big.abs() {
                big = v[i];
            }
        }
        if big < 0.0 {
            for v in values.chunks_exact_mut(dims) {
                v[i] = -v[i];
            }
        }
    }
    Features { dims, values }
}

/// f32 dot product with eight accumulators (vectorises).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let (ca, ra) = a[..n].as_chunks::<8>();
    let (cb, rb) = b[..n].as_chunks::<8>();
    let mut acc = [0f32; 8];
    for (x, y) in ca.iter().zip(cb) {
        for ((s, p), q) in acc.iter_mut().zip(x).zip(y) {
            *s += p * q;
        }
    }
    acc.iter().sum::<f32>() + ra.iter().zip(rb).map(|(p, q)| p * q).sum::<f32>()
}

/// f64 dot product with four accumulators.
fn dot64(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (ca, ra) = a[..n].as_chunks::<4>();
    let (cb, rb) = b[..n].as_chunks::<4>();
    let mut acc = [0f64; 4];
    for (x, y) in ca.iter().zip(cb) {
        for ((s, p), q) in acc.iter_mut().zip(x).zip(y) {
            *s += p * q;
        }
    }
    acc.iter().sum::<f64>() + ra.iter().zip(rb).map(|(p, q)| p * q).sum::<f64>()
}

/// Squared Euclidean distance with eight accumulators.
pub(crate) fn sqdist(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let (ca, ra) = a[..n].as_chunks::<8>();
    let (cb, rb) = b[..n].as_chunks::<8>();
    let mut acc = [0f32; 8];
    for (x, y) in ca.iter().zip(cb) {
        for ((s, p), q) in acc.iter_mut().zip(x).zip(y) {
            let d = p - q;
            *s += d * d;
        }
    }
    acc.iter().sum::<f32>() + ra.iter().zip(rb).map(|(p, q)| (p - q) * (p - q)).sum::<f32>()
}

/// Squared distance summed `chunk` floats at a time, stopping once it reaches `bound`.
pub(crate) fn bounded_sqdist(a: &[f32], b: &[f32], chunk: usize, bound: f32) -> f32 {
    let mut s = 0.0;
    for (x, y) in a.chunks(chunk.max(1)).zip(b.chunks(chunk.max(1))) {
        s += sqdist(x, y);
        if s >= bound {
            break;
        }
    }
    s
}

/// The `count`×`count` matrix of dot products of `count` rows of `len` floats.
fn gram(rows: &[f32], count: usize, len: usize) -> Vec<f64> {
    let mut g = vec![0f64; count * count];
    if count == 0 || len == 0 {
        return g;
    }
    g.par_chunks_mut(count).enumerate().for_each(|(i, gi)| {
        let ri = &rows[i * len..(i + 1) * len];
        for (gij, rj) in gi.iter_mut().zip(rows.chunks_exact(len)).take(i + 1) {
            *gij = f64::from(dot(ri, rj));
        }
    });
    for i in 0..count {
        for j in 0..i {
            g[j * count + i] = g[i * count + j];
        }
    }
    g
}

/// A `m`×`m` (row-major) matrix times each column of `q`.
fn mul_cols(a: &[f64], m: usize, q: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let b = q.len();
    if b == 0 || m == 0 {
        return vec![Vec::new(); b];
    }
    let mut rows = vec![0f64; m * b];
    rows.par_chunks_mut(b).zip(a.par_chunks(m)).for_each(|(zi, ai)| {
        for (z, qc) in zi.iter_mut().zip(q) {
            *z = dot64(ai, qc);
        }
    });
    (0..b).map(|c| rows.iter().skip(c).step_by(b).copied().collect()).collect()
}

/// Modified Gram–Schmidt (twice) on the columns; degenerate columns become zero.
pub(crate) fn orthonormalise(q: &mut [Vec<f64>]) {
    for c in 0..q.len() {
        let (done, rest) = q.split_at_mut(c);
        let Some(v) = rest.first_mut() else { return };
        for _ in 0..2 {
            for p in done.iter() {
                let d = dot64(p, v);
                if d != 0.0 {
                    for (x, y) in v.iter_mut().zip(p) {
                        *x -= d * y;
                    }
                }
            }
        }
        let norm = dot64(v, v).sqrt();
        if norm > 1e-200 && norm.is_finite() {
            v.iter_mut().for_each(|x| *x /= norm);
        } else {
            v.fill(0.0);
        }
    }
}

/// Eigen-decomposition of a symmetric `n`×`n` matrix by cyclic Jacobi
/// rotations: eigenvalues and the eigenvector matrix (column k = vector k).
pub(crate) fn jacobi(mut a: Vec<f64>, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut v = vec![0f64; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    for _sweep in 0..64 {
        let mut off = 0.0;
        let mut diag = 0.0;
        for i in 0..n {
            for j in 0..n {
                let x = a[i * n + j] * a[i * n + j];
                if i == j {
                    diag += x;
                } else {
                    off += x;
                }
            }
        }
        if off <= 1e-28 * diag || off < 1e-300 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq.abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = if theta.is_finite() && theta.abs() < 1e150 {
                    theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
                } else {
                    0.5 / theta
                };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| a[i * n + i]).collect(), v)
}

/// The `want` largest eigenpairs of a symmetric positive semi-definite
/// `m`×`m` matrix, eigenvalues descending, vectors of unit length (or zero
/// past the rank): subspace iteration on `want + 4` vectors, then Rayleigh–Ritz.
fn top_eigen(a: &[f64], m: usize, want: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
    let want = want.min(m);
    let b = (want + EIGEN_OVERSAMPLE).min(m);
    if b == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut q: Vec<Vec<f64>> =
        (0..b).map(|c| (0..m).map(|i| unit_interval(hash3(0x5ca1_ab1e, c as u64, i as u64)) - 0.5).collect()).collect();
    orthonormalise(&mut q);
    let mut prev = vec![f64::NAN; b];
    for _ in 0..EIGEN_ITERS {
        let z = mul_cols(a, m, &q);
        let ritz: Vec<f64> = q.iter().zip(&z).map(|(qc, zc)| dot64(qc, zc)).collect();
        q = z;
        orthonormalise(&mut q);
        let scale = ritz.first().map_or(0.0, |r| r.abs()).max(1e-300);
        let settled = ritz.iter().zip(&prev).take(want).all(|(r, p)| (r - p).abs() <= 1e-7 * scale);
        prev = ritz;
        if settled {
            break;
        }
    }
    // Rayleigh–Ritz on the final subspace
    let z = mul_cols(a, m, &q);
    let mut t = vec![0f64; b * b];
    for i in 0..b {
        for j in 0..b {
            t[i * b + j] = 0.5 * (dot64(&q[i], &z[j]) + dot64(&q[j], &z[i]));
        }
    }
    let (ev, w) = jacobi(t, b);
    let mut order: Vec<usize> = (0..b).collect();
    order.sort_by(|&i, &j| ev[j].total_cmp(&ev[i]));
    let mut lambda = Vec::with_capacity(want);
    let mut vecs = Vec::with_capacity(want);
    for &k in order.iter().take(want) {
        let mut v = vec![0f64; m];
        for (i, qi) in q.iter().enumerate() {
            let c = w[i * b + k];
            for (x, y) in v.iter_mut().zip(qi) {
                *x += c * y;
            }
        }
        lambda.push(ev[k].max(0.0));
        vecs.push(v);
    }
    (lambda, vecs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::synth::tiny_corduroy as corduroy;

    #[test]
    fn pca_variances_decrease() {
        let btf = corduroy();
        let f = features(&btf, 8);
        assert_eq!((f.dims, f.texels()), (8, 64));
        let var = f.variances();
        assert!(var[0] > 1e-4, "{var:?}");
        for i in 1..var.len() {
            assert!(var[i] <= var[i - 1] * (1.0 + 1e-4) + 1e-9, "{var:?}");
        }
        // the components are centred and uncorrelated
        for i in 0..8 {
            let mean = f.values.chunks_exact(8).map(|v| v[i] as f64).sum::<f64>() / 64.0;
            assert!(mean.abs() < 1e-4, "mean {i} = {mean}");
            for j in 0..i {
                let cov = f.values.chunks_exact(8).map(|v| v[i] as f64 * v[j] as f64).sum::<f64>() / 64.0;
                assert!(cov.abs() < 1e-3 * (var[0] as f64), "cov {i},{j} = {cov}");
            }
        }
        // the first component carries more than an equal share of the variance
        let total: f32 = var.iter().sum();
        assert!(var[0] > total / 8.0 * 1.5, "{var:?}");
        assert_eq!(f, features(&btf, 8), "deterministic");
    }

    #[test]
    fn pca_matches_both_paths_and_a_known_spectrum() {
        // Jacobi recovers a known diagonal-in-disguise matrix
        let (ev, _) = jacobi(vec![2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0], 3);
        let mut ev = ev;
        ev.sort_by(f64::total_cmp);
        for (a, b) in ev.iter().zip([1.0, 3.0, 5.0]) {
            assert!((a - b).abs() < 1e-12, "{ev:?}");
        }
        let (lam, vecs) = top_eigen(&[2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 5.0], 3, 2);
        assert!((lam[0] - 5.0).abs() < 1e-9 && (lam[1] - 3.0).abs() < 1e-9, "{lam:?}");
        assert!((vecs[0][2].abs() - 1.0).abs() < 1e-6, "{vecs:?}");
    }
}
