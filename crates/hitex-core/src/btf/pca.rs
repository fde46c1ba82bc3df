//! Local PCA compression of a BTF (after Müller, Meseth and Klein, 2003):
//! the sample texels are clustered, and each cluster keeps its mean
//! appearance and its first `k` principal components over every (view,
//! light) image; each texel keeps its cluster and `k` coefficients.
//!
//! A texel's appearance in image `i` is then
//! `μ_c[i] + Σ_j a_j · B_cj[i]`, linear in the basis images, so that a
//! renderer interpolates the basis images over the angles (the same
//! hexa-linear reads as the raw codebook's, through any layout) and blends
//! them with the coefficients afterwards.
//!
//! The basis is stored as a small signed half-float "BTF" of
//! `(k + 1) × clusters` texels: texel `(j, c)` holds cluster `c`'s mean
//! (`j = 0`) or its component `j` scaled by the largest magnitude of that
//! component's coefficients in the cluster; the coefficients are divided by
//! the same scale and lie in [−1, 1]. Coefficients and basis are half
//! floats, what both renderers read.
//!
//! The fit streams the images: the data matrix (texels × images × 3) is never
//! held. Clusters come from k-means on the texels' appearance features (those
//! of the index synthesis); each cluster's subspace from a randomised
//! subspace iteration (a few passes of `Xᵀ Y` and `X Z` over the images)
//! and a Rayleigh–Ritz step; the coefficients from a last projection pass.

use super::dataset::{Btf, half_value};
use super::grid::AngularGrid;
use crate::CoreError;
use crate::texture::image::{ColorSpace, decode_table, linear_to_srgb_u8};
use rayon::prelude::*;

/// Most principal components per cluster (the cluster id and up to 15
/// coefficients fill at most four RGBA texels per sample texel).
pub const MAX_PCA_COMPONENTS: usize = 15;

/// Most clusters.
pub const MAX_PCA_CLUSTERS: usize = 1024;

/// Power steps of the subspace iteration (two passes over the images each).
const POWER_STEPS: usize = 3;

/// Extra vectors the subspace iteration carries beyond the components kept.
const OVERSAMPLE: usize = 6;

/// Feature dimensions the clustering reads.
const CLUSTER_FEATURE_DIMS: usize = 16;

/// Runs of images summed apart (in parallel) and then in order, when a pass
/// accumulates over every image.
const SUM_RUNS: usize = 8;

/// What [`fit`] builds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PcaOptions {
    /// Clusters of sample texels (1 = one global basis).
    pub clusters: usize,
    /// Principal components per cluster (0 = the cluster means alone).
    pub components: usize,
}

/// A BTF compressed by local PCA (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct LocalPca {
    grid: AngularGrid,
    width: u32,
    height: u32,
    clusters: u32,
    components: u32,
    /// Each sample texel's cluster, row-major.
    cluster: Vec<u16>,
    /// Each sample texel's `components` coefficients as half floats.
    coefs: Vec<u16>,
    /// The basis BTF's signed halves: image-major like [`Btf::texels`],
    /// `(components + 1) × clusters` texels of three halves each.
    basis: Vec<u16>,
    /// The source's display scale (1 for an 8-bit BTF; see [`super::dataset::Hdr`]).
    ldr_scale: f32,
    hdr: bool,
}

/// The signed half float nearest to `v`, clamped to ±65504 (NaN to 0).
pub fn signed_half_bits(v: f32) -> u16 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(-65504.0, 65504.0) };
    half::f16::from_f32(v).to_bits()
}

/// The image's texels in linear light, three per texel.
fn decode_image(btf: &Btf, image: usize, out: &mut [f32]) {
    let n = btf.width() as usize * btf.height() as usize * 3;
    if let Some(h) = btf.hdr() {
        for (o, &v) in out.iter_mut().zip(&h.half[image * n..(image + 1) * n]) {
            *o = half_value(v);
        }
    } else {
        let lut = decode_table(ColorSpace::Srgb);
        for (o, &b) in out.iter_mut().zip(&btf.texels()[image * n..(image + 1) * n]) {
            *o = lut[b as usize];
        }
    }
}

/// A deterministic value in [−½, ½) from three integers.
fn noise(a: u64, b: u64, c: u64) -> f32 {
    let h = crate::splitmix64(crate::splitmix64(a ^ crate::splitmix64(b)) ^ c);
    ((h >> 40) as f32 / (1u64 << 24) as f32) - 0.5
}

/// Orthonormalises, within each cluster, the columns of the `n × m`
/// row-major `y` (rows of texels in their cluster).
fn orthonormalise_clusters(y: &mut [f32], m: usize, members: &[Vec<usize>]) {
    let done: Vec<(usize, Vec<Vec<f64>>)> = members
        .par_iter()
        .enumerate()
        .map(|(c, rows)| {
            let mut cols: Vec<Vec<f64>> =
                (0..m).map(|j| rows.iter().map(|&t| f64::from(y[t * m + j])).collect()).collect();
            super::features::orthonormalise(&mut cols);
            (c, cols)
        })
        .collect();
    for (c, cols) in done {
        for (r, &t) in members[c].iter().enumerate() {
            for (j, col) in cols.iter().enumerate() {
                y[t * m + j] = col[r] as f32;
            }
        }
    }
}

/// Fits a local PCA to `btf`. `progress(done, total)` is called per pass
/// over the images.
pub fn fit(btf: &Btf, opts: PcaOptions, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<LocalPca, CoreError> {
    let n = btf.width() as usize * btf.height() as usize;
    let bad = |m: String| Err(CoreError::OutOfRange { key: "PCA".into(), message: m });
    if opts.clusters == 0 || opts.clusters > MAX_PCA_CLUSTERS.min(n) {
        return bad(format!(
            "{} clusters; 1..={} are allowed for a sample of {n} texels",
            opts.clusters,
            MAX_PCA_CLUSTERS.min(n)
        ));
    }
    if opts.components > MAX_PCA_COMPONENTS {
        return bad(format!("{} components; at most {MAX_PCA_COMPONENTS} are allowed", opts.components));
    }
    let (nc, k) = (opts.clusters, opts.components);
    let images = btf.images();
    let total_passes = 4 + 2 * POWER_STEPS + 1;
    let mut pass = 0;
    let mut step = || {
        pass += 1;
        progress(pass, total_passes);
    };
    // clusters of texels by their appearance features
    let cluster: Vec<usize> = if nc == 1 {
        vec![0; n]
    } else {
        let f = super::features::features(btf, CLUSTER_FEATURE_DIMS);
        super::mip::kmeans(&f.values, &vec![1.0; n], f.dims, nc, 0x09ca_5eed)
    };
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); nc];
    for (t, &c) in cluster.iter().enumerate() {
        members[c].push(t);
    }
    let count: Vec<f32> = members.iter().map(|m| m.len().max(1) as f32).collect();
    // cluster means, [image·3 + channel][cluster]
    let mut mean = vec![0f32; images * 3 * nc];
    mean.par_chunks_mut(3 * nc).enumerate().for_each_init(
        || vec![0f32; n * 3],
        |x, (i, mu)| {
            decode_image(btf, i, x);
            let mut acc = vec![0f64; 3 * nc];
            for (t, &c) in cluster.iter().enumerate() {
                for ch in 0..3 {
                    acc[ch * nc + c] += f64::from(x[t * 3 + ch]);
                }
            }
            for ch in 0..3 {
                for c in 0..nc {
                    mu[ch * nc + c] = (acc[ch * nc + c] / f64::from(count[c])) as f32;
                }
            }
        },
    );
    step();
    // the centred image i into `x`
    let centred = |i: usize, x: &mut [f32]| {
        decode_image(btf, i, x);
        let mu = &mean[i * 3 * nc..(i + 1) * 3 * nc];
        for (t, &c) in cluster.iter().enumerate() {
            for ch in 0..3 {
                x[t * 3 + ch] -= mu[ch * nc + c];
            }
        }
    };
    // Z = Xᵀ Y per cluster: [image·3 + channel][cluster][m]
    let m = (k + OVERSAMPLE).min(n).max(1);
    let xt_y = |y: &[f32]| -> Vec<f32> {
        let mut z = vec![0f32; images * 3 * nc * m];
        z.par_chunks_mut(3 * nc * m).enumerate().for_each_init(
            || vec![0f32; n * 3],
            |x, (i, zi)| {
                centred(i, x);
                for (t, &c) in cluster.iter().enumerate() {
                    let yt = &y[t * m..(t + 1) * m];
                    for ch in 0..3 {
                        let v = x[t * 3 + ch];
                        let dst = &mut zi[(ch * nc + c) * m..(ch * nc + c + 1) * m];
                        for (d, &w) in dst.iter_mut().zip(yt) {
                            *d += v * w;
                        }
                    }
                }
            },
        );
        z
    };
    // Y = X Z per cluster: n × width, Z of `width` columns per (dimension, cluster).
    // The images are summed in a fixed number of runs, each in image order, and
    // the runs' sums are added in run order: the result does not depend on how
    // many threads there are or how the work was stolen.
    let x_z = |z: &[f32], width: usize| -> Vec<f32> {
        let run = images.div_ceil(SUM_RUNS).max(1);
        let partial: Vec<Vec<f32>> = (0..images.div_ceil(run))
            .into_par_iter()
            .map(|r| {
                let (mut x, mut y) = (vec![0f32; n * 3], vec![0f32; n * width]);
                for i in r * run..((r + 1) * run).min(images) {
                    centred(i, &mut x);
                    let zi = &z[i * 3 * nc * width..(i + 1) * 3 * nc * width];
                    for (t, &c) in cluster.iter().enumerate() {
                        let yt = &mut y[t * width..(t + 1) * width];
                        for ch in 0..3 {
                            let v = x[t * 3 + ch];
                            for (d, &w) in yt.iter_mut().zip(&zi[(ch * nc + c) * width..(ch * nc + c + 1) * width]) {
                                *d += v * w;
                            }
                        }
                    }
                }
                y
            })
            .collect();
        let mut runs = partial.into_iter();
        let mut y = runs.next().unwrap_or_else(|| vec![0f32; n * width]);
        for p in runs {
            y.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
        }
        y
    };
    // randomised subspace iteration from a random start in texel space
    let mut y: Vec<f32> = (0..n * m).map(|e| noise(0x5ca1_ab1e, (e / m) as u64, (e % m) as u64)).collect();
    orthonormalise_clusters(&mut y, m, &members);
    let mut z = xt_y(&y);
    step();
    for _ in 0..POWER_STEPS {
        y = x_z(&z, m);
        step();
        orthonormalise_clusters(&mut y, m, &members);
        z = xt_y(&y);
        step();
    }
    // Rayleigh–Ritz: Zᵀ Z = W Λ Wᵀ per cluster; directions Z w_j / √λ_j
    let dims = images * 3;
    let mut basis_dirs = vec![0f32; dims * nc * k.max(1)];
    for c in 0..nc {
        let mut g = vec![0f64; m * m];
        for d in 0..dims {
            let zr = &z[(d * nc + c) * m..(d * nc + c + 1) * m];
            for a in 0..m {
                for b in 0..=a {
                    g[a * m + b] += f64::from(zr[a]) * f64::from(zr[b]);
                }
            }
        }
        for a in 0..m {
            for b in 0..a {
                g[b * m + a] = g[a * m + b];
            }
        }
        let (ev, w) = super::features::jacobi(g, m);
        let mut order: Vec<usize> = (0..m).collect();
        order.sort_by(|&a, &b| ev[b].total_cmp(&ev[a]));
        for (j, &o) in order.iter().take(k).enumerate() {
            let lambda = ev[o];
            if lambda.is_nan() || lambda <= 1e-20 {
                continue;
            }
            let s = 1.0 / lambda.sqrt();
            for d in 0..dims {
                let zr = &z[(d * nc + c) * m..(d * nc + c + 1) * m];
                let v: f64 = (0..m).map(|a| f64::from(zr[a]) * w[a * m + o]).sum();
                basis_dirs[(d * nc + c) * k + j] = (v * s) as f32;
            }
        }
    }
    drop(z);
    // coefficients: the projection of every texel on its cluster's directions
    let a = if k > 0 { x_z(&basis_dirs, k) } else { Vec::new() };
    step();
    // scales: each (cluster, component)'s largest coefficient magnitude
    let mut scale = vec![0f32; nc * k];
    for (t, &c) in cluster.iter().enumerate() {
        for j in 0..k {
            scale[c * k + j] = scale[c * k + j].max(a[t * k + j].abs());
        }
    }
    scale.iter_mut().for_each(|s| *s = if *s > 0.0 && s.is_finite() { *s } else { 1.0 });
    let coefs: Vec<u16> =
        (0..n * k).map(|e| signed_half_bits(a[e] / scale[cluster[e / k.max(1)] * k + e % k.max(1)])).collect();
    // the basis BTF: (k + 1) × nc texels per image
    let bw = k + 1;
    let mut basis = vec![0u16; images * nc * bw * 3];
    basis.par_chunks_mut(nc * bw * 3).enumerate().for_each(|(i, img)| {
        for c in 0..nc {
            for j in 0..bw {
                for ch in 0..3 {
                    let d = i * 3 + ch;
                    let v = if j == 0 {
                        mean[d * nc + c]
                    } else {
                        basis_dirs[(d * nc + c) * k + j - 1] * scale[c * k + j - 1]
                    };
                    img[(c * bw + j) * 3 + ch] = signed_half_bits(v);
                }
            }
        }
    });
    step();
    Ok(LocalPca {
        grid: btf.grid().clone(),
        width: btf.width(),
        height: btf.height(),
        clusters: nc as u32,
        components: k as u32,
        cluster: cluster.iter().map(|&c| c as u16).collect(),
        coefs,
        basis,
        ldr_scale: btf.hdr().map_or(1.0, |h| h.ldr_scale),
        hdr: btf.is_hdr(),
    })
}

/// The stored parts of a [`LocalPca`], as a file holds them
/// ([`LocalPca::from_parts`], [`LocalPca::to_parts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PcaParts {
    /// The angular grid.
    pub grid: AngularGrid,
    /// Sample width in texels.
    pub width: u32,
    /// Sample height in texels.
    pub height: u32,
    /// Clusters (1..=[`MAX_PCA_CLUSTERS`]).
    pub clusters: u32,
    /// Components per cluster (0..=[`MAX_PCA_COMPONENTS`]).
    pub components: u32,
    /// Each sample texel's cluster, row-major (`width × height`).
    pub cluster: Vec<u16>,
    /// Each sample texel's coefficients as half floats (`width × height × components`).
    pub coefs: Vec<u16>,
    /// The basis images as signed halves (see the module documentation):
    /// `images × clusters × (components + 1) × 3`.
    pub basis: Vec<u16>,
    /// The source's display scale (1 for an 8-bit BTF).
    pub ldr_scale: f32,
    /// Whether the source was HDR.
    pub hdr: bool,
}

impl PcaParts {
    /// The number of halves the basis holds for this shape, or None past
    /// 64 bits (shape and cluster limits not checked).
    pub fn basis_len(&self) -> Option<u64> {
        let d = self.grid.directions() as u64;
        (d * d).checked_mul(u64::from(self.clusters))?.checked_mul(u64::from(self.components) + 1)?.checked_mul(3)
    }
}

impl LocalPca {
    /// A compressed BTF from its stored parts, checked: the shape within
    /// the BTF limits, clusters and components within theirs, every array
    /// of the size the shape gives, every cluster id below the cluster
    /// count, every half float finite, the display scale in (0, 1].
    pub fn from_parts(p: PcaParts) -> Result<Self, CoreError> {
        let bad = |m: String| CoreError::InvalidImage(m);
        super::dataset::checked_size(&p.grid, p.width, p.height)?;
        if p.clusters == 0 || p.clusters as usize > MAX_PCA_CLUSTERS {
            return Err(bad(format!("{} clusters; 1..={MAX_PCA_CLUSTERS} are allowed", p.clusters)));
        }
        if p.components as usize > MAX_PCA_COMPONENTS {
            return Err(bad(format!("{} components; 0..={MAX_PCA_COMPONENTS} are allowed", p.components)));
        }
        let n = p.width as usize * p.height as usize;
        let k = p.components as usize;
        if p.cluster.len() != n {
            return Err(bad(format!("{} cluster ids for {}x{} texels", p.cluster.len(), p.width, p.height)));
        }
        if p.coefs.len() != n * k {
            return Err(bad(format!(
                "{} coefficients for {}x{} texels × {k} components",
                p.coefs.len(),
                p.width,
                p.height
            )));
        }
        if p.basis_len() != Some(p.basis.len() as u64) {
            return Err(bad(format!(
                "{} basis halves; {} images × {} clusters × {} basis images × RGB need {}",
                p.basis.len(),
                p.grid.directions() * p.grid.directions(),
                p.clusters,
                k + 1,
                p.basis_len().map_or("more than 2^64".into(), |b| b.to_string())
            )));
        }
        if let Some(t) = p.cluster.iter().position(|&c| u32::from(c) >= p.clusters) {
            return Err(bad(format!(
                "texel ({}, {}) is in cluster {} of {}",
                t % p.width as usize,
                t / p.width as usize,
                p.cluster[t],
                p.clusters
            )));
        }
        let finite = |h: &u16| h & 0x7c00 != 0x7c00;
        if let Some(i) = p.coefs.iter().position(|h| !finite(h)) {
            return Err(bad(format!("coefficient {i} is {:#06x}: infinite or NaN", p.coefs[i])));
        }
        if let Some(i) = p.basis.iter().position(|h| !finite(h)) {
            return Err(bad(format!("basis half {i} is {:#06x}: infinite or NaN", p.basis[i])));
        }
        if !(p.ldr_scale.is_finite() && p.ldr_scale > 0.0 && p.ldr_scale <= 1.0) || (!p.hdr && p.ldr_scale != 1.0) {
            return Err(bad(format!(
                "display scale {} is not {}",
                p.ldr_scale,
                if p.hdr { "in (0, 1]" } else { "1, as an 8-bit source's is" }
            )));
        }
        Ok(LocalPca {
            grid: p.grid,
            width: p.width,
            height: p.height,
            clusters: p.clusters,
            components: p.components,
            cluster: p.cluster,
            coefs: p.coefs,
            basis: p.basis,
            ldr_scale: p.ldr_scale,
            hdr: p.hdr,
        })
    }

    /// The stored parts (copies), for a writer.
    pub fn to_parts(&self) -> PcaParts {
        PcaParts {
            grid: self.grid.clone(),
            width: self.width,
            height: self.height,
            clusters: self.clusters,
            components: self.components,
            cluster: self.cluster.clone(),
            coefs: self.coefs.clone(),
            basis: self.basis.clone(),
            ldr_scale: self.ldr_scale,
            hdr: self.hdr,
        }
    }

    /// Each sample texel's cluster, row-major.
    pub fn cluster_ids(&self) -> &[u16] {
        &self.cluster
    }

    /// Every sample texel's coefficient halves, row-major, `components` each.
    pub fn coef_halves(&self) -> &[u16] {
        &self.coefs
    }

    /// The source's display scale (1 for an 8-bit BTF).
    pub fn ldr_scale(&self) -> f32 {
        self.ldr_scale
    }

    /// The angular grid.
    pub fn grid(&self) -> &AngularGrid {
        &self.grid
    }

    /// Sample width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Sample height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Clusters.
    pub fn clusters(&self) -> u32 {
        self.clusters
    }

    /// Principal components per cluster.
    pub fn components(&self) -> u32 {
        self.components
    }

    /// Whether the source BTF was HDR.
    pub fn is_hdr(&self) -> bool {
        self.hdr
    }

    /// The cluster of sample texel (x, y).
    pub fn cluster_of(&self, x: u32, y: u32) -> u32 {
        u32::from(self.cluster[(y * self.width + x) as usize])
    }

    /// The coefficient halves of sample texel (x, y) (`components` of them).
    pub fn coefs_of(&self, x: u32, y: u32) -> &[u16] {
        let k = self.components as usize;
        let t = (y * self.width + x) as usize;
        &self.coefs[t * k..(t + 1) * k]
    }

    /// The basis as signed halves, three per texel, image-major, each image
    /// `(components + 1) × clusters` texels (see the module documentation).
    pub fn basis_halves(&self) -> &[u16] {
        &self.basis
    }

    /// Bytes the compressed form holds: the basis and the coefficients as
    /// half floats, the clusters as 16-bit ids (when more than one).
    pub fn bytes(&self) -> u64 {
        let n = u64::from(self.width) * u64::from(self.height);
        let ids = if self.clusters > 1 { 2 * n } else { 0 };
        2 * self.basis.len() as u64 + 2 * self.coefs.len() as u64 + ids
    }

    /// Bytes of the raw codebook it replaces: RGB8 per texel, or RGB half
    /// floats for an HDR BTF.
    pub fn raw_bytes(&self) -> u64 {
        let d = self.grid.directions() as u64;
        let texels = d * d * u64::from(self.width) * u64::from(self.height);
        texels * if self.hdr { 6 } else { 3 }
    }

    /// The compression ratio (raw bytes over compressed bytes).
    pub fn ratio(&self) -> f64 {
        self.raw_bytes() as f64 / self.bytes().max(1) as f64
    }

    /// Linear RGB of sample texel (x, y) in image `image` as the renderers
    /// reconstruct it from the stored halves.
    pub fn texel_linear(&self, image: usize, x: u32, y: u32) -> [f32; 3] {
        let bw = self.components as usize + 1;
        let nc = self.clusters as usize;
        let c = self.cluster_of(x, y) as usize;
        let img = &self.basis[image * nc * bw * 3..(image + 1) * nc * bw * 3];
        let b = |j: usize, ch: usize| half_value(img[(c * bw + j) * 3 + ch]);
        let a = self.coefs_of(x, y);
        std::array::from_fn(|ch| {
            let mut v = b(0, ch);
            for (j, &h) in a.iter().enumerate() {
                v += half_value(h) * b(j + 1, ch);
            }
            v
        })
    }

    /// The BTF the compressed form stands for: every texel reconstructed
    /// (negative values clamped to 0), as an HDR BTF, or as 8-bit sRGB when
    /// the source was.
    pub fn decompress(&self) -> Result<Btf, CoreError> {
        let (w, h) = (self.width, self.height);
        let images = self.grid.directions() * self.grid.directions();
        let per = w as usize * h as usize * 3;
        let mut linear = vec![0f32; images * per];
        linear.par_chunks_mut(per).enumerate().for_each(|(i, img)| {
            for y in 0..h {
                for x in 0..w {
                    let v = self.texel_linear(i, x, y);
                    let o = ((y * w + x) * 3) as usize;
                    img[o..o + 3].copy_from_slice(&v);
                }
            }
        });
        if self.hdr {
            Btf::from_linear(self.grid.clone(), w, h, &linear)
        } else {
            let texels = linear.par_iter().map(|&v| linear_to_srgb_u8(v)).collect();
            Btf::new(self.grid.clone(), w, h, texels)
        }
    }

    /// PSNR (dB) of the reconstruction against `btf`'s 8-bit texels (the
    /// display copy of an HDR BTF), every image, RGB.
    pub fn psnr(&self, btf: &Btf) -> Result<f64, CoreError> {
        if btf.width() != self.width || btf.height() != self.height || btf.grid() != &self.grid {
            return Err(CoreError::InvalidImage("the PSNR needs the BTF the PCA was fitted to".into()));
        }
        let (w, h) = (self.width, self.height);
        let per = w as usize * h as usize * 3;
        let scale = self.ldr_scale;
        let sse: f64 = btf
            .texels()
            .par_chunks(per)
            .enumerate()
            .map(|(i, src)| {
                let mut s = 0f64;
                for y in 0..h {
                    for x in 0..w {
                        let v = self.texel_linear(i, x, y);
                        let o = ((y * w + x) * 3) as usize;
                        for ch in 0..3 {
                            let d = f64::from(linear_to_srgb_u8(v[ch] * scale)) - f64::from(src[o + ch]);
                            s += d * d;
                        }
                    }
                }
                s
            })
            .sum();
        let mse = sse / btf.texels().len().max(1) as f64;
        Ok(if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / mse).log10() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A BTF whose linear texels are exactly `rank` patterns mixed per texel
    /// (plus a mean), within the 8-bit rounding.
    fn low_rank(rank: usize, side: u32) -> Btf {
        let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
        let d = grid.directions();
        let n = (side * side) as usize;
        let mut lin = vec![0f32; d * d * n * 3];
        for i in 0..d * d {
            for t in 0..n {
                for ch in 0..3 {
                    let mut v = 0.4 + 0.1 * noise(1, i as u64, ch as u64);
                    for r in 0..rank {
                        v += 0.15 * noise(2, (i * 3 + ch) as u64, r as u64) * noise(3, t as u64, r as u64);
                    }
                    lin[(i * n + t) * 3 + ch] = v;
                }
            }
        }
        let texels = lin.iter().map(|&v| linear_to_srgb_u8(v)).collect();
        Btf::new(grid, side, side, texels).unwrap()
    }

    #[test]
    fn a_low_rank_btf_is_recovered_within_its_rounding() {
        let btf = low_rank(3, 8);
        let full = fit(&btf, PcaOptions { clusters: 1, components: 3 }, &|_, _| {}).unwrap();
        let short = fit(&btf, PcaOptions { clusters: 1, components: 1 }, &|_, _| {}).unwrap();
        let (pf, ps) = (full.psnr(&btf).unwrap(), short.psnr(&btf).unwrap());
        // the 8-bit rounding of the source bounds the error (±½ step: 51 dB and above)
        assert!(pf > 48.0, "3 components of a rank-3 BTF: {pf} dB");
        assert!(ps < pf - 6.0, "1 component of a rank-3 BTF: {ps} dB against {pf}");
    }

    #[test]
    fn the_fit_is_the_same_bits_on_any_number_of_threads() {
        // 12 × 12 images: many more than the runs the passes sum apart
        let btf = low_rank(4, 8);
        let opts = PcaOptions { clusters: 3, components: 4 };
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let p = pool.install(|| fit(&btf, opts, &|_, _| {}).unwrap());
            let mut all: Vec<u16> = Vec::new();
            for y in 0..8 {
                for x in 0..8 {
                    all.push(p.cluster_of(x, y) as u16);
                    all.extend_from_slice(p.coefs_of(x, y));
                }
            }
            all.extend_from_slice(p.basis_halves());
            all
        };
        let one = on(1);
        for threads in [2, 3] {
            let other = on(threads);
            assert_eq!(one.len(), other.len());
            let differ = one.iter().zip(&other).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{differ} of {} halves differ between 1 and {threads} threads", one.len());
        }
    }

    #[test]
    fn coefficients_lie_in_the_unit_interval_and_sizes_add_up() {
        let btf = low_rank(4, 8);
        let p = fit(&btf, PcaOptions { clusters: 3, components: 2 }, &|_, _| {}).unwrap();
        for y in 0..8 {
            for x in 0..8 {
                assert!(p.cluster_of(x, y) < 3);
                for &h in p.coefs_of(x, y) {
                    let v = half_value(h);
                    assert!((-1.0..=1.0).contains(&v), "coefficient {v}");
                }
            }
        }
        let images = 12 * 12;
        assert_eq!(p.basis_halves().len(), images * 3 * 3 * 3);
        assert_eq!(p.bytes(), 2 * (images * 27) as u64 + 2 * 64 * 2 + 2 * 64);
        assert_eq!(p.raw_bytes(), (images * 64 * 3) as u64);
        // the decompressed BTF is the reconstruction, encoded
        let back = p.decompress().unwrap();
        let v = p.texel_linear(5, 3, 4);
        let o = (5 * 64 + 4 * 8 + 3) * 3;
        for (ch, &vc) in v.iter().enumerate() {
            assert_eq!(back.texels()[o + ch], linear_to_srgb_u8(vc));
        }
    }

    #[test]
    fn more_components_and_clusters_never_fit_worse() {
        let btf = low_rank(6, 8);
        let mut last = 0.0;
        for k in [0, 2, 4, 6] {
            let p = fit(&btf, PcaOptions { clusters: 1, components: k }, &|_, _| {}).unwrap().psnr(&btf).unwrap();
            assert!(p >= last - 0.05, "{k} components: {p} dB after {last}");
            last = p;
        }
        let one = fit(&btf, PcaOptions { clusters: 1, components: 0 }, &|_, _| {}).unwrap().psnr(&btf).unwrap();
        let many = fit(&btf, PcaOptions { clusters: 8, components: 0 }, &|_, _| {}).unwrap().psnr(&btf).unwrap();
        assert!(many > one, "8 cluster means {many} dB against one mean {one} dB");
    }

    #[test]
    fn stored_parts_rebuild_the_same_pca_and_bad_parts_are_refused() {
        let btf = low_rank(4, 8);
        let p = fit(&btf, PcaOptions { clusters: 3, components: 2 }, &|_, _| {}).unwrap();
        assert_eq!(LocalPca::from_parts(p.to_parts()).unwrap(), p);
        let refused = |f: &dyn Fn(&mut PcaParts), want: &str| {
            let mut parts = p.to_parts();
            f(&mut parts);
            let e = LocalPca::from_parts(parts).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        };
        refused(&|q| q.clusters = 0, "0 clusters");
        refused(&|q| q.clusters = MAX_PCA_CLUSTERS as u32 + 1, "clusters; 1..=1024");
        refused(&|q| q.components = 16, "16 components");
        refused(&|q| q.cluster.pop().map_or((), drop), "cluster ids for 8x8 texels");
        refused(&|q| q.coefs.push(0), "coefficients for 8x8 texels × 2 components");
        refused(&|q| q.basis.truncate(9), "basis halves");
        // a different component count with the same arrays: the sizes no longer agree
        refused(&|q| q.components = 1, "coefficients");
        refused(&|q| q.cluster[9] = 3, "texel (1, 1) is in cluster 3 of 3");
        refused(&|q| q.coefs[5] = 0x7c00, "coefficient 5 is 0x7c00");
        refused(&|q| q.basis[2] = 0xfe00, "basis half 2 is 0xfe00");
        refused(&|q| q.ldr_scale = 0.0, "display scale 0");
        refused(&|q| q.ldr_scale = 0.5, "as an 8-bit source's is");
        refused(&|q| q.width = 0, "8 texels");
    }

    #[test]
    fn bad_options_are_refused_by_name() {
        let btf = low_rank(1, 4);
        let e = fit(&btf, PcaOptions { clusters: 0, components: 2 }, &|_, _| {}).unwrap_err().to_string();
        assert!(e.contains("0 clusters"), "{e}");
        let e = fit(&btf, PcaOptions { clusters: 17, components: 2 }, &|_, _| {}).unwrap_err().to_string();
        assert!(e.contains("17 clusters"), "{e}");
        let e = fit(&btf, PcaOptions { clusters: 1, components: 16 }, &|_, _| {}).unwrap_err().to_string();
        assert!(e.contains("16 components"), "{e}");
    }

    #[test]
    fn the_basis_codebook_holds_the_signed_halves_in_every_layout() {
        use crate::btf::layout::{Codebook, Layout};
        let btf = low_rank(3, 4);
        let p = fit(&btf, PcaOptions { clusters: 2, components: 3 }, &|_, _| {}).unwrap();
        assert!(p.basis_halves().iter().any(|&h| h & 0x8000 != 0), "a centred basis has negative values");
        for layout in Layout::ALL {
            let cb = Codebook::build_signed(p.grid(), 4, 2, p.basis_halves(), layout).unwrap();
            let g = p.grid().clone();
            // a pixel exactly on grid angles reads one texel per combination: the stored half
            let lerp = |i: usize, n: usize| crate::btf::AxisLerp { i0: i, i1: (i + 1) % n, t: 0.0, coord: i as f32 };
            let l = crate::btf::AngleLerps {
                tc: lerp(1, g.theta_count()),
                pc: lerp(2, g.phi_count()),
                tl: lerp(2, g.theta_count()),
                pl: lerp(3, g.phi_count()),
            };
            let image = g.direction(1, 2) * g.directions() + g.direction(2, 3);
            for (j, c) in [(0u32, 0u32), (1, 0), (3, 1), (2, 1)] {
                let got = cb.corner(j, c, &l, &mut ());
                let o = image * 4 * 2 * 3 + ((c * 4 + j) * 3) as usize;
                for ch in 0..3 {
                    let want = half_value(p.basis_halves()[o + ch]);
                    assert!(
                        (got[ch] - want).abs() <= 1e-6 * want.abs().max(1.0),
                        "{layout:?} ({j}, {c}): {got} vs {want}"
                    );
                }
            }
        }
    }
}
