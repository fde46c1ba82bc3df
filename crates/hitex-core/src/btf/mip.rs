//! MIP mapping of BTFs: a pyramid of index maps, each level with its own
//! codebook, so that a minified BTF surface shows the mean appearance of the
//! texels a pixel covers instead of aliasing.
//!
//! Level 0 is the index map and the sample as they are. Index-map level k
//! has max(1, ⌊W / 2ᵏ⌋) × max(1, ⌊H / 2ᵏ⌋) texels (a GPU texture's MIP
//! chain), up to the level where both are 1; texel (i, j) of a level of
//! w' × h' covers the level-0 texels [⌊iW/w'⌋, ⌊(i+1)W/w'⌋) ×
//! [⌊jH/h'⌋, ⌊(j+1)H/h'⌋) (2ᵏ × 2ᵏ when the sides are powers of two), and its
//! appearance is the **mean of their appearances over every (view, light)
//! pair**, in linear light. Those means are re-quantised into a codebook of
//! at most `w × ⌈h / 2ᵏ⌉` entries (the sample's width times half as many
//! rows per level, so all levels together at most double the codebook): by
//! k-means (k-means++ seeding, a fixed seed, Lloyd iterations) on the
//! appearance features index synthesis uses ([`super::features::features`]),
//! averaged over each footprint the same way; when a level has no more
//! distinct footprints than entries, every footprint keeps its exact mean.
//! A cluster's entry is the mean appearance of its members' footprints, so
//! every entry is a mean of measured appearances, never a feature's guess.
//!
//! The levels' entries are stacked below the sample into one taller sample
//! (`w × (h + rows₁ + rows₂ + …)`, level k's rows from [`BtfMip::row0`]):
//! one codebook, laid out by any of the paper's layouts, serves every
//! level, and a level's index map names entries by (column, row + row0).

use super::dataset::{Btf, half_bits, half_value};
use super::features::features;
use super::index::IndexMap;
use crate::CoreError;
use crate::texture::{linear_to_srgb_u8, srgb_to_linear};
use rayon::prelude::*;
use std::collections::HashMap;

/// Feature dimensions used for re-quantisation.
const MIP_FEATURE_DIMS: usize = 16;

/// Lloyd iterations of the k-means.
const KMEANS_ITERATIONS: usize = 12;

/// A BTF with its MIP pyramid.
#[derive(Debug, Clone)]
pub struct BtfMip {
    /// The stacked sample: the original rows, then each level's entries.
    pub btf: Btf,
    /// Index maps, level 0 first (level 0 is the input map).
    pub levels: Vec<IndexMap>,
    /// First row of each level's entries in the stacked sample (0 for level 0).
    pub row0: Vec<u32>,
    /// Entries used by each level (footprints of level 0: the sample's texels).
    pub entries: Vec<usize>,
    /// Distinct footprints per level before re-quantisation.
    pub footprints: Vec<usize>,
}

impl BtfMip {
    /// Number of levels, level 0 included.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }
}

/// The linear value of channel `c` of texel `t` (row-major in the sample) of
/// image `img`.
fn linear_of(btf: &Btf, lut: &[f32; 256], img: usize, t: usize, c: usize) -> f32 {
    let i = img * btf.image_bytes() + t * 3 + c;
    match btf.hdr() {
        Some(h) => half_value(h.half[i]),
        None => lut[btf.texels()[i] as usize],
    }
}

/// A deterministic generator (SplitMix64) for the k-means seeding.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        crate::splitmix64(self.0)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn dist2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// At most this many points per cluster train the k-means centres.
const KMEANS_TRAIN_PER_CLUSTER: usize = 8;

/// k-means of `points` (`n × dims`, weights `w`) into `k` clusters; returns
/// each point's cluster. k-means++ seeding from a fixed seed, then Lloyd
/// iterations; a cluster left empty takes the point farthest from its own.
/// Beyond 8 points per cluster (at least 4096) the centres are fitted on an
/// evenly strided subset and every point then joins its nearest centre.
pub(crate) fn kmeans(points: &[f32], weights: &[f32], dims: usize, k: usize, seed: u64) -> Vec<usize> {
    let n = weights.len();
    let train = (KMEANS_TRAIN_PER_CLUSTER * k).max(4096);
    if n <= train {
        return kmeans_fit(points, weights, dims, k, seed).0;
    }
    // many more footprints than clusters (a large index map): fit the centres
    // on an evenly strided subset, then give every footprint its nearest centre
    let step = n.div_ceil(train);
    let subset: Vec<usize> = (0..n).step_by(step).collect();
    let sub_points: Vec<f32> = subset.iter().flat_map(|&i| points[i * dims..(i + 1) * dims].iter().copied()).collect();
    let sub_weights: Vec<f32> = subset.iter().map(|&i| weights[i]).collect();
    let (_, centres) = kmeans_fit(&sub_points, &sub_weights, dims, k, seed);
    (0..n)
        .into_par_iter()
        .map(|i| {
            let p = &points[i * dims..(i + 1) * dims];
            let mut best = (0, f32::INFINITY);
            for (c, centre) in centres.chunks_exact(dims).enumerate() {
                let d = dist2(p, centre);
                if d < best.1 {
                    best = (c, d);
                }
            }
            best.0
        })
        .collect()
}

/// [`kmeans`] on every point: each point's cluster and the centres.
fn kmeans_fit(points: &[f32], weights: &[f32], dims: usize, k: usize, seed: u64) -> (Vec<usize>, Vec<f32>) {
    let n = weights.len();
    let pt = |i: usize| &points[i * dims..(i + 1) * dims];
    let mut rng = Rng(seed);
    let mut centres: Vec<f32> = Vec::with_capacity(k * dims);
    centres.extend_from_slice(pt((rng.next() % n as u64) as usize));
    let mut d2: Vec<f32> = (0..n).map(|i| dist2(pt(i), &centres[..dims])).collect();
    while centres.len() < k * dims {
        let total: f64 = d2.iter().zip(weights).map(|(&d, &w)| d as f64 * w as f64).sum();
        let pick = if total > 0.0 {
            let mut r = rng.unit() * total;
            let mut pick = n - 1;
            for (i, (&d, &w)) in d2.iter().zip(weights).enumerate() {
                r -= d as f64 * w as f64;
                if r <= 0.0 {
                    pick = i;
                    break;
                }
            }
            pick
        } else {
            (rng.next() % n as u64) as usize
        };
        let c = centres.len() / dims;
        centres.extend_from_slice(pt(pick));
        let new = &centres[c * dims..];
        d2.par_iter_mut().enumerate().for_each(|(i, d)| *d = d.min(dist2(pt(i), new)));
    }
    let mut assign = vec![0usize; n];
    for _ in 0..KMEANS_ITERATIONS {
        let nearest: Vec<(usize, f32)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let p = pt(i);
                let mut best = (0, f32::INFINITY);
                for (c, centre) in centres.chunks_exact(dims).enumerate() {
                    let d = dist2(p, centre);
                    if d < best.1 {
                        best = (c, d);
                    }
                }
                best
            })
            .collect();
        let changed = nearest.iter().zip(&assign).any(|(a, &b)| a.0 != b);
        assign.iter_mut().zip(&nearest).for_each(|(a, b)| *a = b.0);
        // new centres: weighted means; an empty cluster takes the worst-fitted point
        let mut sums = vec![0f64; k * dims];
        let mut mass = vec![0f64; k];
        for (i, &c) in assign.iter().enumerate() {
            mass[c] += weights[i] as f64;
            for (s, &v) in sums[c * dims..(c + 1) * dims].iter_mut().zip(pt(i)) {
                *s += v as f64 * weights[i] as f64;
            }
        }
        let mut worst: Vec<usize> = (0..n).collect();
        worst.sort_by(|&a, &b| nearest[b].1.total_cmp(&nearest[a].1).then(a.cmp(&b)));
        let mut next_worst = worst.into_iter();
        for c in 0..k {
            if mass[c] > 0.0 {
                for (dst, &s) in centres[c * dims..(c + 1) * dims].iter_mut().zip(&sums[c * dims..]) {
                    *dst = (s / mass[c]) as f32;
                }
            } else if let Some(i) = next_worst.next() {
                centres[c * dims..(c + 1) * dims].copy_from_slice(pt(i));
            }
        }
        if !changed {
            break;
        }
    }
    (assign, centres)
}

/// Builds the MIP pyramid of `btf` read through `map` (see the module
/// documentation). `progress(done, total)` is called per level and per
/// image of the stacked codebook.
pub fn build_mip(btf: &Btf, map: &IndexMap, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<BtfMip, CoreError> {
    let (sw, sh) = (btf.width() as usize, btf.height() as usize);
    if map.width == 0 || map.height == 0 || map.entries.len() != map.width as usize * map.height as usize {
        return Err(CoreError::InvalidImage("the index map is empty or inconsistent".into()));
    }
    if map.entries.iter().any(|e| e[0] as usize >= sw || e[1] as usize >= sh) {
        return Err(CoreError::InvalidImage("the index map names texels outside the BTF sample".into()));
    }
    let (mw, mh) = (map.width as usize, map.height as usize);
    let top = (usize::BITS - 1 - mw.max(mh).leading_zeros()) as usize;
    // the stacked codebook's size is known before any clustering: refuse early
    let stacked = sh + (1..=top).map(|k| sh.div_ceil(1 << k).max(1)).sum::<usize>();
    let stacked_rows = u32::try_from(stacked).ok().filter(|&r| r <= super::dataset::MAX_BTF_SIDE).ok_or_else(|| {
        CoreError::InvalidImage(format!(
            "the MIP codebook of {sw}x{stacked} texels exceeds the sample side limit of {}",
            super::dataset::MAX_BTF_SIDE
        ))
    })?;
    super::dataset::checked_size(btf.grid(), sw as u32, stacked_rows)
        .map_err(|e| CoreError::InvalidImage(format!("the MIP codebook is too large: {e}")))?;
    let feats = features(btf, MIP_FEATURE_DIMS);
    let dims = feats.dims;
    let mut levels = vec![map.clone()];
    let mut row0 = vec![0u32];
    let mut entries_used = vec![sw * sh];
    let mut footprints = vec![sw * sh];
    // per level ≥ 1: each entry's weights over the sample texels
    let mut recipes: Vec<Vec<(u32, f32)>> = Vec::new();
    let mut rows_total = sh;
    for k in 1..=top {
        progress(k, top + 1);
        let s = 1usize << k;
        let (lw, lh) = ((mw >> k).max(1), (mh >> k).max(1));
        // each coarse texel's histogram over sample texels
        let hists: Vec<Vec<(u32, u32)>> = (0..lw * lh)
            .into_par_iter()
            .map(|c| {
                let (i, j) = (c % lw, c / lw);
                let mut h: HashMap<u32, u32> = HashMap::new();
                for y in j * mh / lh..(j + 1) * mh / lh {
                    for x in i * mw / lw..(i + 1) * mw / lw {
                        let e = map.entries[y * mw + x];
                        *h.entry(e[1] as u32 * sw as u32 + e[0] as u32).or_insert(0) += 1;
                    }
                }
                let mut v: Vec<(u32, u32)> = h.into_iter().collect();
                v.sort_unstable();
                v
            })
            .collect();
        // distinct footprints
        let mut distinct: HashMap<&[(u32, u32)], usize> = HashMap::new();
        let mut of_texel = Vec::with_capacity(hists.len());
        let mut uniq: Vec<&[(u32, u32)]> = Vec::new();
        for h in &hists {
            let next = uniq.len();
            let id = *distinct.entry(h.as_slice()).or_insert(next);
            if id == next {
                uniq.push(h.as_slice());
            }
            of_texel.push(id);
        }
        let rows = sh.div_ceil(s).max(1);
        let cap = sw * rows;
        footprints.push(uniq.len());
        // each distinct footprint's cluster
        let cluster: Vec<usize> = if uniq.len() <= cap {
            (0..uniq.len()).collect()
        } else {
            let mut pts = vec![0f32; uniq.len() * dims];
            let mut wts = vec![0f32; uniq.len()];
            for (u, h) in uniq.iter().enumerate() {
                let total: u32 = h.iter().map(|p| p.1).sum();
                for &(t, n) in h.iter() {
                    for (d, &f) in pts[u * dims..(u + 1) * dims].iter_mut().zip(feats.texel(t as usize)) {
                        *d += f * n as f32 / total as f32;
                    }
                }
            }
            for &u in &of_texel {
                wts[u] += 1.0;
            }
            kmeans(&pts, &wts, dims, cap, 0x5eed ^ k as u64)
        };
        let used = cluster.iter().copied().max().map_or(0, |m| m + 1);
        // a cluster's recipe: the mean of its members' footprints, each weighted by its texel count
        let mut acc: Vec<HashMap<u32, f64>> = vec![HashMap::new(); used];
        let mut members = vec![0f64; used];
        for &u in &of_texel {
            let c = cluster[u];
            let h = uniq[u];
            let total: u32 = h.iter().map(|p| p.1).sum();
            members[c] += 1.0;
            for &(t, n) in h {
                *acc[c].entry(t).or_insert(0.0) += n as f64 / total as f64;
            }
        }
        for (c, a) in acc.into_iter().enumerate() {
            let mut r: Vec<(u32, f32)> = a.into_iter().map(|(t, w)| (t, (w / members[c]) as f32)).collect();
            r.sort_unstable_by_key(|p| p.0);
            recipes.push(r);
        }
        // the level's index map: (column, row0 + row) of its texel's cluster
        let r0 = rows_total;
        let entries = of_texel
            .iter()
            .map(|&u| {
                let c = cluster[u];
                [(c % sw) as u16, (r0 + c / sw) as u16]
            })
            .collect();
        levels.push(IndexMap { width: lw as u32, height: lh as u32, entries });
        row0.push(r0 as u32);
        entries_used.push(used);
        rows_total += rows;
    }
    // the stacked sample: per image, the original rows, then every level's entries
    let grid = btf.grid().clone();
    let total_rows = u32::try_from(rows_total)
        .ok()
        .filter(|&r| r as usize <= super::dataset::MAX_BTF_SIDE as usize)
        .ok_or_else(|| {
            CoreError::InvalidImage(format!(
                "the MIP codebook of {sw}x{rows_total} texels exceeds the sample side limit of {}",
                super::dataset::MAX_BTF_SIDE
            ))
        })?;
    super::dataset::checked_size(&grid, sw as u32, total_rows)
        .map_err(|e| CoreError::InvalidImage(format!("the MIP codebook is too large: {e}")))?;
    let lut: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0));
    let images = btf.images();
    let per_image = sw * rows_total * 3;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let make = |img: usize, out: &mut [f32]| {
        // level 0: the sample itself
        for t in 0..sw * sh {
            for c in 0..3 {
                out[t * 3 + c] = linear_of(btf, &lut, img, t, c);
            }
        }
        // padding entries (past a level's last cluster) stay black and are never named
        let mut at = sw * sh;
        let mut r = 0;
        for k in 1..levels.len() {
            let rows = (row0.get(k + 1).map_or(rows_total, |&x| x as usize)) - row0[k] as usize;
            for e in 0..sw * rows {
                if e < entries_used[k] {
                    let recipe = &recipes[r + e];
                    for c in 0..3 {
                        out[(at + e) * 3 + c] =
                            recipe.iter().map(|&(t, w)| w * linear_of(btf, &lut, img, t as usize, c)).sum();
                    }
                }
            }
            r += entries_used[k];
            at += sw * rows;
        }
        let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        if n.is_multiple_of(64) || n == images {
            progress(top + 1 + n, top + 1 + images);
        }
    };
    let stacked = if btf.is_hdr() {
        let mut half = vec![0u16; images * per_image];
        half.par_chunks_mut(per_image).enumerate().for_each_init(
            || vec![0f32; per_image],
            |buf, (img, out)| {
                make(img, buf);
                out.iter_mut().zip(buf.iter()).for_each(|(o, &v)| *o = half_bits(v));
            },
        );
        Btf::from_half(grid, sw as u32, total_rows, half)?
    } else {
        let mut texels = vec![0u8; images * per_image];
        texels.par_chunks_mut(per_image).enumerate().for_each_init(
            || vec![0f32; per_image],
            |buf, (img, out)| {
                make(img, buf);
                // level 0 keeps its bytes exactly
                let n0 = sw * sh * 3;
                let src = &btf.texels()[img * btf.image_bytes()..][..n0];
                out[..n0].copy_from_slice(src);
                out[n0..].iter_mut().zip(&buf[n0..]).for_each(|(o, &v)| *o = linear_to_srgb_u8(v));
            },
        );
        Btf::new(grid, sw as u32, total_rows, texels)?
    };
    Ok(BtfMip { btf: stacked, levels, row0, entries: entries_used, footprints })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::AngularGrid;

    fn noise_btf() -> Btf {
        let grid = AngularGrid::new(vec![0.0, 40.0], 3).unwrap();
        let n = super::super::dataset::checked_size(&grid, 8, 8).unwrap();
        let mut s = 12345u32;
        let texels = (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                (s >> 24) as u8
            })
            .collect();
        Btf::new(grid, 8, 8, texels).unwrap()
    }

    #[test]
    fn levels_halve_and_level_0_is_unchanged() {
        let btf = noise_btf();
        let map = IndexMap::identity(8, 8, 32, 32);
        let mip = build_mip(&btf, &map, &|_, _| {}).unwrap();
        assert_eq!(mip.level_count(), 6);
        let sides: Vec<(u32, u32)> = mip.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sides, vec![(32, 32), (16, 16), (8, 8), (4, 4), (2, 2), (1, 1)]);
        // rows 8 + 4 + 2 + 1 + 1 + 1
        assert_eq!(mip.row0, vec![0, 8, 12, 14, 15, 16]);
        assert_eq!(mip.btf.height(), 17);
        assert_eq!(mip.levels[0], map);
        // the sample's own rows are untouched, byte for byte
        for img in 0..btf.images() {
            let (v, l) = (img / btf.grid().directions(), img % btf.grid().directions());
            assert_eq!(&mip.btf.image(v, l)[..8 * 8 * 3], btf.image(v, l));
        }
        // a plain tiling of an 8×8 sample: level 3 (8×8 footprints) sees the whole sample everywhere
        assert_eq!(mip.footprints[3], 1);
        assert_eq!(mip.entries[3], 1);
    }

    #[test]
    fn coarse_entries_are_footprint_means_in_linear_light() {
        let btf = noise_btf();
        let map = IndexMap::identity(8, 8, 16, 16);
        let mip = build_mip(&btf, &map, &|_, _| {}).unwrap();
        let lin = |b: u8| srgb_to_linear(b as f32 / 255.0);
        // level 1: each 2×2 footprint of the plain tiling is its own entry (16 distinct ≤ 32 entries)
        assert_eq!(mip.footprints[1], 16);
        for (ci, e) in mip.levels[1].entries.iter().enumerate() {
            let (i, j) = (ci % 8, ci / 8);
            for img in [0usize, 7, 20] {
                let (v, l) = (img / 6, img % 6);
                for c in 0..3 {
                    let mut want = 0.0;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let t = btf.texel(v, l, ((2 * i + dx) % 8) as u32, ((2 * j + dy) % 8) as u32);
                        want += lin(t[c]) / 4.0;
                    }
                    let got = lin(mip.btf.texel(v, l, e[0] as u32, e[1] as u32)[c]);
                    // one 8-bit step of sRGB
                    assert!((got - want).abs() <= 0.5 / 255.0 + want * 0.02, "{ci} {img} {c}: {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn too_many_footprints_are_clustered_within_the_bound() {
        let btf = noise_btf();
        // a scrambled map: level-1 footprints are almost all distinct
        let mut s = 7u64;
        let entries = (0..64 * 64)
            .map(|_| {
                s = crate::splitmix64(s);
                [(s % 8) as u16, ((s >> 8) % 8) as u16]
            })
            .collect();
        let map = IndexMap { width: 64, height: 64, entries };
        let mip = build_mip(&btf, &map, &|_, _| {}).unwrap();
        assert!(mip.footprints[1] > 32 * 32 / 2, "{:?}", mip.footprints);
        for k in 1..mip.level_count() {
            let cap = 8 * (8usize >> k).max(1);
            assert!(mip.entries[k] <= cap, "level {k}: {} entries > {cap}", mip.entries[k]);
            let rows = mip.row0.get(k + 1).map_or(mip.btf.height(), |&r| r) - mip.row0[k];
            for e in &mip.levels[k].entries {
                assert!(e[1] as u32 >= mip.row0[k] && (e[1] as u32) < mip.row0[k] + rows);
            }
        }
        // deterministic
        let again = build_mip(&btf, &map, &|_, _| {}).unwrap();
        assert_eq!(again.btf, mip.btf);
    }

    #[test]
    fn many_footprints_are_clustered_from_a_subset_almost_as_well() {
        // 16 blobs in 4-D, 20,000 points: beyond 8 per cluster and 4096, so
        // the centres are fitted on a strided subset
        let (n, dims, k) = (20_000usize, 4usize, 16usize);
        let mut s = 99u64;
        let mut unit = || {
            s = crate::splitmix64(s);
            (s >> 11) as f32 / (1u64 << 53) as f32
        };
        let points: Vec<f32> = (0..n)
            .flat_map(|i| {
                let blob = i % k;
                (0..dims).map(move |d| ((blob >> d) & 1) as f32 * 4.0 + (blob % 3) as f32).collect::<Vec<_>>()
            })
            .zip(std::iter::repeat_with(&mut unit))
            .map(|(c, r)| c + (r - 0.5) * 0.5)
            .collect();
        let weights = vec![1.0f32; n];
        let sse = |assign: &[usize]| {
            let mut sums = vec![0f64; k * dims];
            let mut mass = vec![0f64; k];
            for (i, &c) in assign.iter().enumerate() {
                mass[c] += 1.0;
                for d in 0..dims {
                    sums[c * dims + d] += points[i * dims + d] as f64;
                }
            }
            let mut e = 0.0;
            for (i, &c) in assign.iter().enumerate() {
                for d in 0..dims {
                    let m = sums[c * dims + d] / mass[c];
                    e += (points[i * dims + d] as f64 - m).powi(2);
                }
            }
            e
        };
        let subset = kmeans(&points, &weights, dims, k, 1);
        let (full, _) = kmeans_fit(&points, &weights, dims, k, 1);
        assert!(subset.iter().all(|&c| c < k));
        let (a, b) = (sse(&subset), sse(&full));
        assert!(a <= b * 1.1 + 1e-9, "subset fit SSE {a} vs full fit {b}");
    }

    #[test]
    fn an_oversized_pyramid_is_refused_before_any_clustering() {
        let grid = AngularGrid::new(vec![0.0], 1).unwrap();
        let btf = Btf::new(grid, 4, 600, vec![128; 4 * 600 * 3]).unwrap();
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let e = build_mip(&btf, &IndexMap::identity(4, 600, 4, 600), &|_, _| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        })
        .unwrap_err();
        assert!(e.to_string().contains("exceeds the sample side limit"), "{e}");
        assert_eq!(calls.load(std::sync::atomic::Ordering::Relaxed), 0, "work began before the refusal");
    }

    #[test]
    fn hdr_btfs_keep_half_floats_in_every_level() {
        let b = noise_btf();
        let linear: Vec<f32> = b.texels().iter().map(|&c| 4.0 * srgb_to_linear(c as f32 / 255.0)).collect();
        let hdr = Btf::from_linear(b.grid().clone(), 8, 8, &linear).unwrap();
        let mip = build_mip(&hdr, &IndexMap::identity(8, 8, 16, 16), &|_, _| {}).unwrap();
        assert!(mip.btf.is_hdr());
        // the whole-sample mean at the top: about 4 × the mean linear value
        let top = mip.levels.last().unwrap().entries[0];
        let v = mip.btf.texel_linear(0, 0, top[0] as u32, top[1] as u32)[0];
        let want: f32 = (0..64).map(|t| hdr.texel_linear(0, 0, t % 8, t / 8)[0]).sum::<f32>() / 64.0;
        assert!((v - want).abs() < want * 2e-3, "{v} vs {want}");
    }
}
