//! Index maps grown from a small BTF sample by texture synthesis (seed 000,
//! refs [4, 5]).
//!
//! The paper stores a BTF as a *codebook* of small sample images and an
//! *index map* telling each texel of the (large) surface which sample texel
//! to read. A plain tiling `(x mod w, y mod h)` repeats visibly; an index map
//! grown by texture synthesis rearranges the sample into a non-repeating,
//! seamless texture of any size — and, since every neighbourhood wraps
//! around the map's edges, the map itself tiles without a seam.
//!
//! * [`features`](super::features): the first principal components of each
//!   sample texel's appearance over the (view, light) images — what synthesis
//!   compares (in their own module);
//! * [`synthesize_index`]: patch quilting on the torus, then k-coherence
//!   correction (Tong et al. 2002, with the candidate sets of Lefebvre &
//!   Hoppe 2005) on those features, with toroidal neighbourhoods in both the
//!   sample and the output;
//! * [`seam_quality`](super::seams::seam_quality) (in its own module): how
//!   coherent the map is across its wrap-around edges compared with its
//!   interior.

use super::dataset::{Btf, MAX_BTF_SIDE};
use super::features::{Features, MAX_FEATURE_DIMS, bounded_sqdist, features, sqdist};
use crate::CoreError;
use crate::{hash3, unit_interval};
use rayon::prelude::*;

/// Largest index-map side accepted by [`synthesize_index`].
pub const MAX_INDEX_SIDE: u32 = 8192;

/// Largest (odd) neighbourhood side accepted by [`synthesize_index`].
pub const MAX_NEIGHBOURHOOD: u32 = 15;

/// Largest number of feature dimensions accepted by [`synthesize_index`].
pub const MAX_SYNTH_DIMS: usize = 16;

/// Largest k-coherence set accepted by [`synthesize_index`].
pub const MAX_K: usize = 16;

/// Largest number of correction passes accepted by [`synthesize_index`].
pub const MAX_PASSES: u32 = 64;

/// Floats allowed for the precomputed sample neighbourhoods; above it they are gathered on the fly.
const NBHD_BUDGET: usize = 1 << 24;

/// Multiply-adds allowed for the exact k-coherence search (texels² × neighbourhood length).
const EXACT_KSET_BUDGET: u64 = 1 << 32;

/// Propagation rounds and random probes per round of the approximate k-coherence search.
const APPROX_ITERS: usize = 4;
const APPROX_RANDOM: usize = 16;

/// Initial patches are this fraction of the sample side apart.
const PATCH_FRACTION: f64 = 0.75;

/// Most source candidates tried for each initial patch.
const MAX_INIT_CANDIDATES: usize = 1024;

/// Seed of the (sample-only) approximate k-coherence search.
const KSET_SEED: u64 = 0x6b5f_636f_6865_7265;

// ---------------------------------------------------------------------------
// index map

/// An index map: for each output texel, the sample texel `[su, sv]` to read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IndexMap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major entries, `entries[y * width + x] = [su, sv]`.
    pub entries: Vec<[u16; 2]>,
}

impl IndexMap {
    /// Plain tiling of a `sample_w`×`sample_h` sample: entry (x, y) is
    /// `(x mod sample_w, y mod sample_h)` (sample sides below 1 count as 1).
    pub fn identity(sample_w: u32, sample_h: u32, width: u32, height: u32) -> IndexMap {
        let (sw, sh) = (sample_w.clamp(1, 1 << 16), sample_h.clamp(1, 1 << 16));
        let entries = (0..height).flat_map(|y| (0..width).map(move |x| [(x % sw) as u16, (y % sh) as u16])).collect();
        IndexMap { width, height, entries }
    }

    /// The entry at (x, y); coordinates wrap around (the map tiles), and a
    /// map without entries reads `[0, 0]`.
    pub fn get(&self, x: u32, y: u32) -> [u16; 2] {
        if self.width == 0 || self.height == 0 {
            return [0, 0];
        }
        let i = (y % self.height) as usize * self.width as usize + (x % self.width) as usize;
        self.entries.get(i).copied().unwrap_or([0, 0])
    }

    /// The paper's visualisation as RGBA8: u → red and v → green, each
    /// scaled from 0..=side−1 to 0..=255 (entries past the sample clamp to
    /// 255), blue 0, alpha 255.
    pub fn to_rgba(&self, sample_w: u32, sample_h: u32) -> Vec<u8> {
        let scale = |v: u16, side: u32| -> u8 {
            if side <= 1 {
                return 0;
            }
            let top = side as u64 - 1;
            ((u64::from(v).min(top) * 255 + top / 2) / top) as u8
        };
        self.entries.iter().flat_map(|&[u, v]| [scale(u, sample_w), scale(v, sample_h), 0, 255]).collect()
    }

    /// Lossless 16-bit RGBA encoding (e.g. for a 16-bit PNG): red = su,
    /// green = sv, blue 0, alpha 65535.
    pub fn to_rgba16(&self) -> Vec<u16> {
        self.entries.iter().flat_map(|&[u, v]| [u, v, 0, u16::MAX]).collect()
    }

    /// Decodes [`IndexMap::to_rgba16`]: `data` holds `width`×`height` RGBA16
    /// pixels whose red and green must address a `sample_w`×`sample_h` sample.
    pub fn from_rgba16(
        width: u32,
        height: u32,
        data: &[u16],
        sample_w: u32,
        sample_h: u32,
    ) -> Result<IndexMap, CoreError> {
        let bad = |key: &str, message: String| CoreError::OutOfRange { key: key.into(), message };
        if width == 0 || height == 0 || width > MAX_INDEX_SIDE || height > MAX_INDEX_SIDE {
            return Err(bad(
                "index map",
                format!("{width}x{height} texels; each side must be in 1..={MAX_INDEX_SIDE}"),
            ));
        }
        let want = width as usize * height as usize * 4;
        if data.len() != want {
            return Err(bad("index map", format!("{} values; {width}x{height} RGBA pixels need {want}", data.len())));
        }
        let mut entries = Vec::with_capacity(want / 4);
        for (i, px) in data.chunks_exact(4).enumerate() {
            let (u, v) = (px[0], px[1]);
            if u32::from(u) >= sample_w || u32::from(v) >= sample_h {
                return Err(bad(
                    "index map",
                    format!(
                        "texel ({}, {}) reads ({u}, {v}), outside the {sample_w}x{sample_h} sample",
                        i % width as usize,
                        i / width as usize
                    ),
                ));
            }
            entries.push([u, v]);
        }
        Ok(IndexMap { width, height, entries })
    }
}

// ---------------------------------------------------------------------------
// synthesis

/// Options of [`synthesize_index`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SynthesisOptions {
    /// Index-map width in texels, 1..=[`MAX_INDEX_SIDE`].
    pub width: u32,
    /// Index-map height in texels, 1..=[`MAX_INDEX_SIDE`].
    pub height: u32,
    /// Side of the square neighbourhood compared, odd, 1..=[`MAX_NEIGHBOURHOOD`]
    /// (1 compares nothing: the initial patches are kept).
    pub neighbourhood: u32,
    /// Size of each sample texel's k-coherence set, 1..=[`MAX_K`] (at most
    /// the number of other sample texels is used).
    pub k: usize,
    /// Correction passes, 0..=[`MAX_PASSES`].
    pub passes: u32,
    /// Seed of the initial patches.
    pub seed: u64,
    /// Principal components per texel compared, 1..=[`MAX_SYNTH_DIMS`].
    pub dims: usize,
}

impl Default for SynthesisOptions {
    fn default() -> Self {
        Self { width: 256, height: 256, neighbourhood: 5, k: 4, passes: 3, seed: 1, dims: 8 }
    }
}

fn out_of_range(key: &str, message: String) -> CoreError {
    CoreError::OutOfRange { key: key.into(), message }
}

fn validate(o: &SynthesisOptions) -> Result<(), CoreError> {
    for (key, v) in [("width", o.width), ("height", o.height)] {
        if !(1..=MAX_INDEX_SIDE).contains(&v) {
            return Err(out_of_range(key, format!("{v} texels; 1..={MAX_INDEX_SIDE} are allowed")));
        }
    }
    if o.neighbourhood.is_multiple_of(2) || !(1..=MAX_NEIGHBOURHOOD).contains(&o.neighbourhood) {
        return Err(out_of_range(
            "neighbourhood",
            format!("{}; an odd side in 1..={MAX_NEIGHBOURHOOD} is required", o.neighbourhood),
        ));
    }
    if !(1..=MAX_K).contains(&o.k) {
        return Err(out_of_range("k", format!("{}; 1..={MAX_K} is allowed", o.k)));
    }
    if !(1..=MAX_SYNTH_DIMS).contains(&o.dims) {
        return Err(out_of_range("dims", format!("{}; 1..={MAX_SYNTH_DIMS} are allowed", o.dims)));
    }
    if o.passes > MAX_PASSES {
        return Err(out_of_range("passes", format!("{}; 0..={MAX_PASSES} are allowed", o.passes)));
    }
    Ok(())
}

/// The sample seen as a torus of feature vectors, with its neighbourhood vectors.
struct Sample<'a> {
    w: usize,
    h: usize,
    n: usize,
    d: usize,
    /// Neighbourhood side.
    side: usize,
    /// Neighbourhood offsets (dx, dy), row-major, centre included.
    offsets: Vec<(i64, i64)>,
    /// Index of the (0, 0) offset.
    centre: usize,
    feats: &'a [f32],
    /// Precomputed neighbourhood vectors, `n × offsets.len() × d`, when they fit.
    nbhd: Option<Vec<f32>>,
}

impl<'a> Sample<'a> {
    /// The sample, its neighbourhood vectors precomputed when `n × len`
    /// floats fit `budget`.
    fn new(w: usize, h: usize, feats: &'a Features, side: usize, budget: usize) -> Self {
        let r = (side / 2) as i64;
        let offsets: Vec<(i64, i64)> = (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (dx, dy))).collect();
        let centre = offsets.len() / 2;
        let mut s = Sample { w, h, n: w * h, d: feats.dims, side, offsets, centre, feats: &feats.values, nbhd: None };
        let len = s.len();
        if s.n.saturating_mul(len) <= budget {
            let mut v = vec![0f32; s.n * len];
            v.par_chunks_mut(len).enumerate().for_each(|(t, dst)| s.gather(t, dst));
            s.nbhd = Some(v);
        }
        s
    }

    /// Floats in a neighbourhood vector.
    fn len(&self) -> usize {
        self.offsets.len() * self.d
    }

    /// Floats in one neighbourhood row (the early-termination granule).
    fn chunk(&self) -> usize {
        self.side * self.d
    }

    /// Texel `t` moved by (dx, dy) on the torus.
    fn wrap(&self, t: usize, dx: i64, dy: i64) -> usize {
        let x = ((t % self.w) as i64 + dx).rem_euclid(self.w as i64) as usize;
        let y = ((t / self.w) as i64 + dy).rem_euclid(self.h as i64) as usize;
        y * self.w + x
    }

    fn feat(&self, t: usize) -> &[f32] {
        &self.feats[t * self.d..(t + 1) * self.d]
    }

    fn gather(&self, t: usize, dst: &mut [f32]) {
        for (block, &(dx, dy)) in dst.chunks_exact_mut(self.d).zip(&self.offsets) {
            block.copy_from_slice(self.feat(self.wrap(t, dx, dy)));
        }
    }

    /// The neighbourhood vector of texel `t` (precomputed, or gathered into `scratch`).
    fn nbhd<'s>(&'s self, t: usize, scratch: &'s mut [f32]) -> &'s [f32] {
        let len = self.len();
        match &self.nbhd {
            Some(v) => &v[t * len..(t + 1) * len],
            None => {
                self.gather(t, scratch);
                scratch
            }
        }
    }

    /// Neighbourhood distance without the centre texel, stopping at `bound`.
    fn dist_around(&self, a: &[f32], b: &[f32], bound: f32) -> f32 {
        let (c0, c1) = (self.centre * self.d, (self.centre + 1) * self.d);
        let first = bounded_sqdist(&a[..c0], &b[..c0], self.chunk(), bound);
        if first >= bound {
            return first;
        }
        first + bounded_sqdist(&a[c1..], &b[c1..], self.chunk(), bound - first)
    }
}

/// Scratch of a k-coherence search.
struct KScratch {
    a: Vec<f32>,
    b: Vec<f32>,
    best: Vec<(f32, u32)>,
}

/// Offers sample texel `c` to the k best neighbours of `t` (sorted, distinct, without `t`).
fn offer(s: &Sample, a: &[f32], scratch: &mut [f32], best: &mut Vec<(f32, u32)>, k: usize, t: usize, c: usize) {
    if c == t || best.iter().any(|e| e.1 as usize == c) {
        return;
    }
    let bound = if best.len() >= k { best[k - 1].0 } else { f32::INFINITY };
    let d = bounded_sqdist(a, s.nbhd(c, scratch), s.chunk(), bound);
    if d < bound {
        let pos = best.partition_point(|e| e.0 <= d);
        best.insert(pos, (d, c as u32));
        best.truncate(k);
    }
}

/// The k-coherence sets: for each sample texel the `k` other texels with the
/// most similar (toroidal, centre included) neighbourhoods, nearest first.
/// Exact by exhaustive search when texels² × neighbourhood fits the budget,
/// else approximate by random probes and coherent propagation (PatchMatch).
/// Returns the set size used (`k` capped at texels − 1) and the sets.
fn ksets(s: &Sample, k: usize, exact_budget: u64) -> (usize, Vec<u32>) {
    let k = k.min(s.n.saturating_sub(1));
    if k == 0 {
        return (0, Vec::new());
    }
    let len = s.len();
    let init = || KScratch { a: vec![0.0; len], b: vec![0.0; len], best: Vec::with_capacity(k + 1) };
    let mut out = vec![0u32; s.n * k];
    let exact = (s.n as u64).saturating_mul(s.n as u64).saturating_mul(len as u64) <= exact_budget;
    if exact {
        out.par_chunks_mut(k).enumerate().for_each_init(init, |scr, (t, dst)| {
            let KScratch { a, b, best } = scr;
            best.clear();
            let a = s.nbhd(t, a);
            for c in 0..s.n {
                offer(s, a, b, best, k, t, c);
            }
            for (d, e) in dst.iter_mut().zip(best.iter()) {
                *d = e.1;
            }
        });
        return (k, out);
    }
    // approximate: random start, then rounds of propagation from the four
    // neighbours' sets (shifted back) plus random probes
    let n = s.n as u64;
    let mut dist = vec![0f32; s.n * k];
    for round in 0..=APPROX_ITERS {
        let (prev, prev_dist) = (out.clone(), dist.clone());
        out.par_chunks_mut(k).zip(dist.par_chunks_mut(k)).enumerate().for_each_init(init, |scr, (t, (dst, dd))| {
            let KScratch { a, b, best } = scr;
            best.clear();
            let a = s.nbhd(t, a);
            if round > 0 {
                best.extend(
                    prev_dist[t * k..(t + 1) * k].iter().copied().zip(prev[t * k..(t + 1) * k].iter().copied()),
                );
                for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                    let nt = s.wrap(t, dx, dy);
                    for &c in &prev[nt * k..(nt + 1) * k] {
                        offer(s, a, b, best, k, t, s.wrap(c as usize, -dx, -dy));
                    }
                }
            }
            for j in 0..APPROX_RANDOM + k {
                let c = (hash3(KSET_SEED ^ round as u64, t as u64, j as u64) % n) as usize;
                offer(s, a, b, best, k, t, c);
            }
            // never short of k (tiny chance of repeated probes)
            let mut c = t;
            while best.len() < k {
                c = (c + 1) % s.n;
                offer(s, a, b, best, k, t, c);
            }
            for ((d, x), e) in dst.iter_mut().zip(dd.iter_mut()).zip(best.iter()) {
                *d = e.1;
                *x = e.0;
            }
        });
    }
    (k, out)
}

/// Initial map by patch quilting on the torus.
///
/// Sites on a jittered grid, [`PATCH_FRACTION`] of the sample side apart
/// (each row of cells shifted by a random phase),
/// cut the map into irregular cells (each texel belongs to the nearest of
/// the sites of its own and the eight surrounding grid cells, distances
/// wrapping around). Cells are filled one at a time, in raster order from a
/// random start cell — so the last, most constrained cells close up at a
/// random place, not on the map's wrap edges — each with a coherent copy of
/// the sample. The source texel put at the site is drawn at random among
/// the candidates whose coherent extension matches the already filled texels
/// within `band` of the cell (summed squared feature difference) within 10 %
/// of the best match. Candidates that would merely continue a neighbouring
/// cell (offset within an eighth of the sample of that cell's) are left out
/// when any other remains, or the map would grow into a plain tiling.
fn initial_patches(sample: &Sample, w: usize, h: usize, band: usize, seed: u64) -> Vec<u32> {
    let (sw, sh, n) = (sample.w, sample.h, sample.n);
    let p = (sw.min(sh) as f64 * PATCH_FRACTION).max(1.0);
    let cx = ((w as f64 / p).round() as usize).max(1);
    let cy = ((h as f64 / p).round() as usize).max(1);
    let (fx, fy) = (w as f64 / cx as f64, h as f64 / cy as f64);
    // a random phase per row of cells in x and one in y, so that the cell
    // boundaries (which gather near the grid lines) fall anywhere, not on
    // the map's wrap edges
    let phase_y = unit_interval(hash3(seed, 0, 8)) * fy;
    let phase_x: Vec<f64> = (0..cy).map(|j| unit_interval(hash3(seed, j as u64, 9)) * fx).collect();
    let sites: Vec<(i64, i64)> = (0..cx * cy)
        .map(|c| {
            let (i, j) = (c % cx, c / cx);
            let px = ((i as f64 + unit_interval(hash3(seed, c as u64, 1))) * fx + phase_x[j]) as usize % w;
            let py = ((j as f64 + unit_interval(hash3(seed, c as u64, 2))) * fy + phase_y) as usize % h;
            (px as i64, py as i64)
        })
        .collect();
    let torus = |d: i64, n: usize| {
        let n = n as i64;
        let d = d.rem_euclid(n);
        if d > n / 2 { d - n } else { d }
    };
    // the cell of every texel
    let mut owner = vec![0u32; w * h];
    owner.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let j0 = ((y as f64 + 0.5 - phase_y).rem_euclid(h as f64) / fy) as i64;
        for (x, dst) in row.iter_mut().enumerate() {
            let mut best = (i64::MAX, 0usize);
            for dj in -1..=1 {
                let j = (j0 + dj).rem_euclid(cy as i64) as usize;
                let i0 = ((x as f64 + 0.5 - phase_x[j]).rem_euclid(w as f64) / fx) as i64;
                for di in -1..=1 {
                    let c = j * cx + (i0 + di).rem_euclid(cx as i64) as usize;
                    let (px, py) = sites[c];
                    let (dx, dy) = (torus(x as i64 - px, w), torus(y as i64 - py, h));
                    if dx * dx + dy * dy < best.0 {
                        best = (dx * dx + dy * dy, c);
                    }
                }
            }
            *dst = best.1 as u32;
        }
    });
    // texels bucketed by cell
    let mut start = vec![0usize; cx * cy + 1];
    for &o in &owner {
        start[o as usize + 1] += 1;
    }
    for c in 0..cx * cy {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut members = vec![0u32; w * h];
    for (t, &o) in owner.iter().enumerate() {
        members[fill[o as usize]] = t as u32;
        fill[o as usize] += 1;
    }
    let candidates: Vec<usize> = if n <= MAX_INIT_CANDIDATES {
        (0..n).collect()
    } else {
        (0..MAX_INIT_CANDIDATES).map(|j| (hash3(seed, j as u64, 4) % n as u64) as usize).collect()
    };
    let mut cur = vec![0u32; w * h];
    let mut done = vec![false; cx * cy];
    let mut filled: Vec<usize> = Vec::new();
    let mut overlap: Vec<(i64, i64, usize)> = Vec::new();
    // each filled cell's offset (source − site, in the sample) and the
    // neighbouring filled cells of the cell being filled
    let mut offsets = vec![(0i64, 0i64); cx * cy];
    let mut near: Vec<usize> = Vec::new();
    let (rx, ry) = ((sw / 8).max(1) as i64, (sh / 8).max(1) as i64);
    let b = band as i64;
    let (i0, j0) = ((hash3(seed, 5, 5) % cx as u64) as usize, (hash3(seed, 6, 6) % cy as u64) as usize);
    for jj in 0..cy {
        for ii in 0..cx {
            let c = ((j0 + jj) % cy) * cx + (i0 + ii) % cx;
            let (px, py) = sites[c];
            let cell = &members[start[c]..start[c + 1]];
            // already filled texels near the cell, as offsets from its site
            filled.clear();
            for &t in cell {
                let (x, y) = ((t as usize % w) as i64, (t as usize / w) as i64);
                for oy in -b..=b {
                    for ox in -b..=b {
                        let q = (y + oy).rem_euclid(h as i64) as usize * w + (x + ox).rem_euclid(w as i64) as usize;
                        if done[owner[q] as usize] {
                            filled.push(q);
                        }
                    }
                }
            }
            filled.sort_unstable();
            filled.dedup();
            overlap.clear();
            near.clear();
            for &q in &filled {
                if !near.contains(&(owner[q] as usize)) {
                    near.push(owner[q] as usize);
                }
                let (qx, qy) = ((q % w) as i64, (q / w) as i64);
                overlap.push((torus(qx - px, w), torus(qy - py, h), cur[q] as usize));
            }
            // a candidate continuing a neighbour coherently (same offset, give
            // or take an eighth of the sample) would just extend the tiling
            let offset_of = |src: usize| {
                (((src % sw) as i64 - px).rem_euclid(sw as i64), ((src / sw) as i64 - py).rem_euclid(sh as i64))
            };
            let fresh = |src: usize| {
                let (ox, oy) = offset_of(src);
                near.iter().all(|&m| {
                    let (mx, my) = offsets[m];
                    torus(ox - mx, sw).abs() >= rx || torus(oy - my, sh).abs() >= ry
                })
            };
            let any_fresh = candidates.iter().any(|&src| fresh(src));
            // the overlap as sample offsets in 0..side (no division in the loop below)
            let shifted: Vec<(usize, usize, &[f32])> = overlap
                .iter()
                .map(|&(dx, dy, q)| {
                    (dx.rem_euclid(sw as i64) as usize, dy.rem_euclid(sh as i64) as usize, sample.feat(q))
                })
                .collect();
            let costs: Vec<f32> = candidates
                .par_iter()
                .with_min_len(32)
                .map(|&src| {
                    if any_fresh && !fresh(src) {
                        return f32::INFINITY;
                    }
                    let (sx, sy) = (src % sw, src / sw);
                    let mut sum = 0.0;
                    for &(dx, dy, target) in &shifted {
                        let (x, y) = (sx + dx, sy + dy);
                        let x = if x >= sw { x - sw } else { x };
                        let y = if y >= sh { y - sh } else { y };
                        sum += sqdist(sample.feat(y * sw + x), target);
                    }
                    sum
                })
                .collect();
            let best = costs.iter().copied().fold(f32::INFINITY, f32::min);
            let limit = best * 1.1 + 1e-12;
            let eligible = costs.iter().filter(|&&v| v <= limit).count().max(1);
            let mut pick = (hash3(seed, c as u64, 7) % eligible as u64) as usize;
            let mut src = candidates.first().copied().unwrap_or(0);
            for (&cand, &v) in candidates.iter().zip(&costs) {
                if v <= limit {
                    if pick == 0 {
                        src = cand;
                        break;
                    }
                    pick -= 1;
                }
            }
            for &t in cell {
                let (x, y) = ((t as usize % w) as i64, (t as usize / w) as i64);
                cur[t as usize] = sample.wrap(src, torus(x - px, w), torus(y - py, h)) as u32;
            }
            offsets[c] = offset_of(src);
            done[c] = true;
        }
    }
    cur
}

/// Scratch of one correction worker.
struct Scratch {
    target: Vec<f32>,
    srcs: Vec<usize>,
    cand: Vec<f32>,
    stamp: Vec<u32>,
    generation: u32,
}

/// The best sample texel for output texel (x, y) given the current map `prev`.
fn correct(
    s: &Sample,
    ks: (usize, &[u32]),
    prev: &[u32],
    (w, h): (usize, usize),
    (x, y): (usize, usize),
    scr: &mut Scratch,
) -> u32 {
    let Scratch { target, srcs, cand, stamp, generation } = scr;
    for (bi, &(dx, dy)) in s.offsets.iter().enumerate() {
        let ox = (x as i64 + dx).rem_euclid(w as i64) as usize;
        let oy = (y as i64 + dy).rem_euclid(h as i64) as usize;
        let src = prev[oy * w + ox] as usize;
        srcs[bi] = src;
        target[bi * s.d..(bi + 1) * s.d].copy_from_slice(s.feat(src));
    }
    if *generation == u32::MAX {
        stamp.fill(0);
        *generation = 0;
    }
    *generation += 1;
    let gen_now = *generation;
    let (k, sets) = ks;
    let mut best = (srcs[s.centre], f32::INFINITY);
    let mut eval = |c: usize, best: &mut (usize, f32)| {
        if stamp[c] == gen_now {
            return;
        }
        stamp[c] = gen_now;
        let d = s.dist_around(target, s.nbhd(c, cand), best.1);
        if d < best.1 {
            *best = (c, d);
        }
    };
    // the current value first, so that ties keep it
    let order = std::iter::once(s.centre).chain((0..s.offsets.len()).filter(|&b| b != s.centre));
    for bi in order {
        let (dx, dy) = s.offsets[bi];
        let c0 = s.wrap(srcs[bi], -dx, -dy);
        eval(c0, &mut best);
        for &c in &sets[c0 * k..(c0 + 1) * k] {
            eval(c as usize, &mut best);
        }
    }
    best.0 as u32
}

/// Grows a seamless, tileable index map of `opts.width`×`opts.height` from
/// the BTF's sample (see [`synthesize_from_features`]), on the first
/// `opts.dims` principal components of [`features`]. `progress(pass, passes)`
/// is called after each correction pass.
pub fn synthesize_index(
    btf: &Btf,
    opts: &SynthesisOptions,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<IndexMap, CoreError> {
    validate(opts)?;
    let feats = features(btf, opts.dims);
    synthesize_from_features(btf.width(), btf.height(), &feats, opts, progress)
}

/// Grows an index map from per-texel features of a `sample_w`×`sample_h`
/// sample (`opts.dims` is not used: all of `feats`' dimensions are compared).
///
/// k-coherence synthesis with every neighbourhood toroidal, in the sample
/// (whose tiles are seamless) and in the output (so the map tiles):
///
/// 1. for every sample texel, its k-coherence set: the `k` other sample
///    texels whose neighbourhoods are closest in summed squared feature
///    distance;
/// 2. the map starts as irregular patches about 3/4 of the sample across,
///    each a coherent copy of the sample, quilted on the torus: each patch's
///    source is drawn (seeded) among those that best continue the patches
///    already placed around it, excluding the plain continuation of a
///    neighbour (which would regrow the tiling);
/// 3. each correction pass visits the map in about (r + 1)² interleaved
///    classes of texels at least r + 1 apart, wrap-around included (r the
///    neighbourhood radius), so that no texel of a class sees another one of
///    it; a class is corrected in parallel (deterministic). A texel p's candidates are, for each neighbour at
///    offset o (centre included), the coherent source s(p + o) − o and its
///    k-coherence set; it takes the candidate whose sample neighbourhood best
///    matches the features of p's current neighbours (centre excluded),
///    keeping its current source on ties.
///
/// Sample neighbourhoods are precomputed when they fit 16 Mi floats, and
/// the k-coherence search is exhaustive when texels² × neighbourhood floats
/// stay under 2³² (e.g. any sample up to 64×64 with 5×5 neighbourhoods of 8
/// dimensions); above that it is approximate (random probes and coherent
/// propagation, as PatchMatch).
pub fn synthesize_from_features(
    sample_w: u32,
    sample_h: u32,
    feats: &Features,
    opts: &SynthesisOptions,
    progress: &(dyn Fn(u32, u32) + Sync),
) -> Result<IndexMap, CoreError> {
    validate(opts)?;
    if !(1..=MAX_BTF_SIDE).contains(&sample_w) || !(1..=MAX_BTF_SIDE).contains(&sample_h) {
        return Err(out_of_range(
            "sample",
            format!("{sample_w}x{sample_h} texels; each side must be in 1..={MAX_BTF_SIDE}"),
        ));
    }
    let (sw, sh) = (sample_w as usize, sample_h as usize);
    if !(1..=MAX_FEATURE_DIMS).contains(&feats.dims) || feats.values.len() != sw * sh * feats.dims {
        return Err(out_of_range(
            "features",
            format!(
                "{} values of {} dimensions; a {sample_w}x{sample_h} sample needs {} texels × 1..={MAX_FEATURE_DIMS} dimensions",
                feats.values.len(),
                feats.dims,
                sw * sh
            ),
        ));
    }
    let (w, h) = (opts.width as usize, opts.height as usize);
    let sample = Sample::new(sw, sh, feats, opts.neighbourhood as usize, NBHD_BUDGET);
    let (k, sets) = ksets(&sample, opts.k, EXACT_KSET_BUDGET);
    let mut cur = initial_patches(&sample, w, h, (opts.neighbourhood as usize / 2).max(1), opts.seed);
    let len = sample.len();
    let blocks = sample.offsets.len();
    let n = sample.n;
    let init = || Scratch {
        target: vec![0.0; len],
        srcs: vec![0; blocks],
        cand: vec![0.0; len],
        stamp: vec![0; n],
        generation: 0,
    };
    // texels of one class are at least r + 1 apart, across the wrap too: none
    // reads another's value while it is being replaced (Gauss–Seidel without
    // an order). Per axis: the residues mod r + 1 of the first multiple of
    // r + 1 texels, then each remaining texel line alone.
    let q = opts.neighbourhood as usize / 2 + 1;
    let groups = |n: usize| -> Vec<Vec<usize>> {
        let whole = n - n % q;
        let mut g: Vec<Vec<usize>> = (0..q).map(|c| (c..whole).step_by(q).collect()).collect();
        g.extend((whole..n).map(|x| vec![x]));
        g.retain(|v| !v.is_empty());
        g
    };
    let (gx, gy) = (groups(w), groups(h));
    for pass in 0..opts.passes {
        for ys in &gy {
            for xs in &gx {
                let rows: Vec<Vec<u32>> = ys
                    .par_iter()
                    .map_init(init, |scr, &y| {
                        xs.iter().map(|&x| correct(&sample, (k, &sets), &cur, (w, h), (x, y), scr)).collect()
                    })
                    .collect();
                for (&y, vals) in ys.iter().zip(rows) {
                    for (&x, v) in xs.iter().zip(vals) {
                        cur[y * w + x] = v;
                    }
                }
            }
        }
        progress(pass + 1, opts.passes);
    }
    let entries = cur.iter().map(|&t| [(t as usize % sw) as u16, (t as usize / sw) as u16]).collect();
    Ok(IndexMap { width: opts.width, height: opts.height, entries })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::AngularGrid;
    use crate::btf::seams::seam_quality;
    use crate::btf::synth::{Material, SynthOptions, synthesize, tiny_corduroy as corduroy};

    fn opts(width: u32, height: u32, seed: u64) -> SynthesisOptions {
        SynthesisOptions { width, height, seed, ..SynthesisOptions::default() }
    }

    fn random_map(sw: u32, sh: u32, width: u32, height: u32, seed: u64) -> IndexMap {
        let entries = (0..width as u64 * height as u64)
            .map(|i| {
                let r = hash3(seed, i, 0);
                [(r % sw as u64) as u16, ((r >> 32) % sh as u64) as u16]
            })
            .collect();
        IndexMap { width, height, entries }
    }

    #[test]
    fn entries_stay_inside_the_sample() {
        let btf = corduroy();
        let calls = std::sync::atomic::AtomicU32::new(0);
        let map = synthesize_index(&btf, &opts(37, 22, 7), &|pass, passes| {
            assert_eq!(passes, 3);
            assert!(pass >= 1 && pass <= passes);
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        })
        .unwrap();
        assert_eq!(calls.into_inner(), 3);
        assert_eq!((map.width, map.height, map.entries.len()), (37, 22, 37 * 22));
        assert!(map.entries.iter().all(|&[u, v]| u < 8 && v < 8), "{:?}", map.entries);
        // every pass count and neighbourhood works, including the degenerate ones
        for (nb, passes) in [(1, 2), (3, 0), (15, 1)] {
            let o = SynthesisOptions { neighbourhood: nb, passes, ..opts(9, 5, 3) };
            let m = synthesize_index(&btf, &o, &|_, _| {}).unwrap();
            assert!(m.entries.len() == 45 && m.entries.iter().all(|&[u, v]| u < 8 && v < 8));
        }
    }

    #[test]
    fn synthesis_is_deterministic_per_seed() {
        let btf = corduroy();
        let a = synthesize_index(&btf, &opts(24, 24, 11), &|_, _| {}).unwrap();
        let b = synthesize_index(&btf, &opts(24, 24, 11), &|_, _| {}).unwrap();
        let c = synthesize_index(&btf, &opts(24, 24, 12), &|_, _| {}).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn synthesized_maps_are_coherent_and_tile() {
        let btf = corduroy();
        let f = features(&btf, 8);
        // pooled over seeds: one defect line next to the wrap edge swings a single map's ratio
        let (mut seam, mut interior) = (0.0, 0.0);
        for seed in 0..6 {
            let map = synthesize_index(&btf, &opts(48, 40, seed), &|_, _| {}).unwrap();
            let rnd = random_map(8, 8, 48, 40, seed);
            let q = seam_quality(&btf, &map, &f);
            let r = seam_quality(&btf, &rnd, &f);
            assert!(q.interior_error < 0.2 * r.interior_error, "seed {seed}: {q:?} vs random {r:?}");
            assert!(q.seam_error < 0.2 * r.seam_error, "seed {seed}: {q:?} vs random {r:?}");
            assert!(q.ratio < 4.0, "seed {seed}: {q:?}");
            // a random map has no preferred edge
            assert!((0.7..1.4).contains(&r.ratio), "random {r:?}");
            seam += q.seam_error;
            interior += q.interior_error;
        }
        assert!(seam < 1.5 * interior, "pooled seam error {seam} vs interior {interior}");
    }

    /// The share of a map's texels that continue one plain tiling of the
    /// `sw`×`sh` sample: the most common offset (source − position, modulo
    /// the sample) over all texels. 1 for a plain tiling; low when the map
    /// is made of many differently placed patches.
    fn tiling_share(map: &IndexMap, sw: u32, sh: u32) -> f32 {
        let mut counts = std::collections::HashMap::new();
        for y in 0..map.height {
            for x in 0..map.width {
                let [u, v] = map.get(x, y);
                let o = ((u as i64 - x as i64).rem_euclid(sw as i64), (v as i64 - y as i64).rem_euclid(sh as i64));
                *counts.entry(o).or_insert(0u32) += 1;
            }
        }
        counts.values().copied().max().unwrap_or(0) as f32 / (map.width * map.height) as f32
    }

    #[test]
    fn synthesized_maps_are_not_a_plain_tiling() {
        // a plain tiling is perfectly coherent and seamless, so the seam
        // measures above cannot tell it from synthesis: measure repetition
        assert_eq!(tiling_share(&IndexMap::identity(8, 8, 48, 40), 8, 8), 1.0);
        let btf = corduroy();
        for seed in 0..6 {
            let map = synthesize_index(&btf, &opts(48, 40, seed), &|_, _| {}).unwrap();
            let share = tiling_share(&map, 8, 8);
            assert!(share < 0.25, "seed {seed}: {:.0} % of the map continues one tiling", share * 100.0);
        }
    }

    #[test]
    fn identity_of_a_tileable_sample_is_coherent() {
        let btf = corduroy();
        let f = features(&btf, 4);
        let q = seam_quality(&btf, &IndexMap::identity(8, 8, 16, 24), &f);
        assert_eq!((q.seam_error, q.interior_error, q.ratio), (0.0, 0.0, 1.0));
        // cut off mid-sample, the plain tiling no longer wraps seamlessly
        let q = seam_quality(&btf, &IndexMap::identity(8, 8, 12, 16), &f);
        assert_eq!(q.interior_error, 0.0);
        assert!(q.seam_error > 0.0 && q.ratio == f32::INFINITY, "{q:?}");
        // a map whose texels do not continue each other is not coherent
        let q = seam_quality(&btf, &random_map(8, 8, 16, 16, 5), &f);
        assert!(q.interior_error > 0.0 && q.seam_error > 0.0, "{q:?}");
    }

    #[test]
    fn bad_options_are_refused() {
        let btf = corduroy();
        let base = opts(16, 16, 1);
        let cases = [
            ("width", SynthesisOptions { width: 0, ..base.clone() }),
            ("width", SynthesisOptions { width: 8193, ..base.clone() }),
            ("height", SynthesisOptions { height: 0, ..base.clone() }),
            ("height", SynthesisOptions { height: 9000, ..base.clone() }),
            ("neighbourhood", SynthesisOptions { neighbourhood: 4, ..base.clone() }),
            ("neighbourhood", SynthesisOptions { neighbourhood: 0, ..base.clone() }),
            ("neighbourhood", SynthesisOptions { neighbourhood: 17, ..base.clone() }),
            ("dims", SynthesisOptions { dims: 0, ..base.clone() }),
            ("dims", SynthesisOptions { dims: 17, ..base.clone() }),
            ("k", SynthesisOptions { k: 0, ..base.clone() }),
            ("k", SynthesisOptions { k: 17, ..base.clone() }),
            ("passes", SynthesisOptions { passes: 65, ..base.clone() }),
        ];
        for (key, o) in cases {
            match synthesize_index(&btf, &o, &|_, _| {}) {
                Err(CoreError::OutOfRange { key: k, .. }) => assert_eq!(k, key, "{o:?}"),
                other => panic!("{o:?} gave {other:?}"),
            }
        }
        assert!(synthesize_index(&btf, &base, &|_, _| {}).is_ok());
        // features that do not match the sample
        let f = Features { dims: 2, values: vec![0.0; 10] };
        assert!(synthesize_from_features(8, 8, &f, &base, &|_, _| {}).is_err());
        assert!(synthesize_from_features(0, 8, &f, &base, &|_, _| {}).is_err());
    }

    #[test]
    fn index_map_encodings() {
        let m = IndexMap::identity(8, 4, 10, 6);
        assert_eq!(m.get(9, 5), [1, 1]);
        assert_eq!(m.get(10, 6), m.get(0, 0), "get wraps");
        let rgba = m.to_rgba(8, 4);
        assert_eq!(rgba.len(), 240);
        assert_eq!(&rgba[7 * 4..8 * 4], &[255, 0, 0, 255]);
        assert_eq!(&rgba[(3 * 10 + 1) * 4..(3 * 10 + 2) * 4], &[36, 255, 0, 255]);
        let back = IndexMap::from_rgba16(10, 6, &m.to_rgba16(), 8, 4).unwrap();
        assert_eq!(back, m);
        assert!(IndexMap::from_rgba16(10, 6, &m.to_rgba16(), 8, 3).is_err());
        assert!(IndexMap::from_rgba16(10, 5, &m.to_rgba16(), 8, 4).is_err());
        let empty = IndexMap { width: 0, height: 0, entries: Vec::new() };
        assert_eq!(empty.get(3, 3), [0, 0]);
    }

    /// Timing on the paper's 32×32 sample and 8×16 grid: run with
    /// `cargo test --release -p hitex-core --lib btf::index -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn timing_512() {
        for mat in [Material::Corduroy, Material::Knit, Material::Leather] {
            let t = std::time::Instant::now();
            let o = SynthOptions { grid: AngularGrid::paper(), size: 32, supersample: 1, exposure: 0.85 };
            let btf = synthesize(mat, &o, &|_| {}).unwrap();
            println!("{}: BTF {} images of 32x32 rendered in {:.2?}", mat.name(), btf.images(), t.elapsed());
            let t = std::time::Instant::now();
            let f = features(&btf, 8);
            println!("  features: {:.2?}, variances {:.4?}", t.elapsed(), f.variances());
            let (mut seam, mut interior) = (0.0, 0.0);
            for seed in 0..3 {
                let t = std::time::Instant::now();
                let map = synthesize_index(&btf, &opts(512, 512, seed), &|_, _| {}).unwrap();
                let dt = t.elapsed();
                let q = seam_quality(&btf, &map, &f);
                let r = seam_quality(&btf, &random_map(32, 32, 512, 512, seed), &f);
                println!("  seed {seed}: synthesize_index 512x512 in {dt:.2?}: {q:?}; random map {r:?}");
                seam += q.seam_error;
                interior += q.interior_error;
            }
            println!("  pooled seam/interior ratio {:.3}", seam / interior);
        }
    }

    #[test]
    fn sample_paths_agree() {
        let btf = corduroy();
        let f = features(&btf, 6);
        let pre = Sample::new(8, 8, &f, 5, NBHD_BUDGET);
        let gathered = Sample::new(8, 8, &f, 5, 0);
        assert!(pre.nbhd.is_some() && gathered.nbhd.is_none());
        let (k, exact) = ksets(&pre, 4, EXACT_KSET_BUDGET);
        assert_eq!(k, 4);
        assert_eq!(ksets(&gathered, 4, EXACT_KSET_BUDGET), (k, exact.clone()));
        // the approximate search returns k distinct other texels, nearly as close
        let (ka, approx) = ksets(&gathered, 4, 0);
        assert_eq!(ka, 4);
        let (mut a, mut b) = (vec![0.0; pre.len()], vec![0.0; pre.len()]);
        let mut total = [0f64; 2];
        for t in 0..64 {
            for (which, sets) in [&exact, &approx].into_iter().enumerate() {
                let set = &sets[t * 4..t * 4 + 4];
                for (i, &c) in set.iter().enumerate() {
                    assert!(c as usize != t && !set[..i].contains(&c), "texel {t}: {set:?}");
                    let an = pre.nbhd(t, &mut a).to_vec();
                    total[which] += sqdist(&an, pre.nbhd(c as usize, &mut b)) as f64;
                }
            }
        }
        assert!(total[1] <= total[0] * 1.25 + 1e-9, "exact {} approximate {}", total[0], total[1]);
        // a one-texel sample has no k-coherence set and still synthesizes
        let one = Features { dims: 1, values: vec![0.5] };
        let m = synthesize_from_features(1, 1, &one, &opts(5, 3, 1), &|_, _| {}).unwrap();
        assert!(m.entries.iter().all(|&e| e == [0, 0]));
    }
}
