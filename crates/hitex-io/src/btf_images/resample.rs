//! Images fitted to one size and measured directions brought onto the
//! target grid: the grid inferred or matched, nearest measured directions
//! and their weights.

use super::*;

/// sRGB code → linear light.
pub(super) fn linear_lut() -> [f32; 256] {
    let mut t = [0.0; 256];
    for (i, v) in t.iter_mut().enumerate() {
        *v = srgb_to_linear(i as f32 / 255.0);
    }
    t
}

/// Output weights of an area (box) filter from `src` samples to `dst`.
pub(super) fn area_weights(src: usize, dst: usize) -> Vec<Vec<(usize, f32)>> {
    let scale = src as f64 / dst as f64;
    (0..dst)
        .map(|o| {
            let (a, b) = (o as f64 * scale, (o + 1) as f64 * scale);
            let mut ws = Vec::new();
            let mut i = a.floor() as usize;
            while (i as f64) < b && i < src {
                let (lo, hi) = (a.max(i as f64), b.min((i + 1) as f64));
                if hi > lo {
                    ws.push((i, ((hi - lo) / scale) as f32));
                }
                i += 1;
            }
            ws
        })
        .collect()
}

/// Centre-crops an RGB image to a square and box-filters it to
/// `size`×`size` in linear light (unchanged when already that size):
/// `lin` decodes a stored value to linear light, `enc` encodes it back.
pub(super) fn fit<T: Copy + Default>(
    rgb: Vec<T>,
    w: u32,
    h: u32,
    size: Option<u32>,
    lin: impl Fn(T) -> f32,
    enc: impl Fn(f32) -> T,
) -> Vec<T> {
    let Some(s) = size else { return rgb };
    let (w, h, s) = (w as usize, h as usize, s as usize);
    let c = w.min(h);
    let (x0, y0) = ((w - c) / 2, (h - c) / 2);
    let crop: Vec<T> = if c == w && c == h {
        rgb
    } else {
        (0..c).flat_map(|y| rgb[((y0 + y) * w + x0) * 3..((y0 + y) * w + x0 + c) * 3].iter().copied()).collect()
    };
    if c == s {
        return crop;
    }
    let wts = area_weights(c, s);
    // rows first: c rows × s columns
    let mut tmp = vec![0f32; c * s * 3];
    for y in 0..c {
        for (ox, ws) in wts.iter().enumerate() {
            for &(x, wt) in ws {
                for ch in 0..3 {
                    tmp[(y * s + ox) * 3 + ch] += wt * lin(crop[(y * c + x) * 3 + ch]);
                }
            }
        }
    }
    let mut out = vec![T::default(); s * s * 3];
    for (oy, ws) in wts.iter().enumerate() {
        for ox in 0..s {
            for ch in 0..3 {
                let v: f32 = ws.iter().map(|&(y, wt)| wt * tmp[(y * s + ox) * 3 + ch]).sum();
                out[(oy * s + ox) * 3 + ch] = enc(v);
            }
        }
    }
    out
}

/// Distinct directions in (θ, φ) order and the index of each key.
pub(super) fn distinct(dirs: impl Iterator<Item = Dir>) -> (Vec<Dir>, HashMap<Key, usize>) {
    let map: BTreeMap<Key, Dir> = dirs.map(|d| (d.key(), d)).collect();
    let list: Vec<Dir> = map.values().copied().collect();
    let index = map.keys().enumerate().map(|(i, &k)| (k, i)).collect();
    (list, index)
}

/// The grid of a set's own θ rings with the largest azimuth count found.
pub(super) fn infer_grid(views: &[Dir], lights: &[Dir]) -> Option<AngularGrid> {
    let mut rings: BTreeMap<i32, (f32, BTreeSet<i32>)> = BTreeMap::new();
    for d in views.iter().chain(lights) {
        let (tk, pk) = d.key();
        rings.entry(tk).or_insert((d.theta, BTreeSet::new())).1.insert(pk);
    }
    let n = rings.values().map(|r| r.1.len()).max()?;
    AngularGrid::new(rings.values().map(|r| r.0).collect(), n).ok()
}

/// For each grid direction, the measured direction naming it (within half a
/// degree), or `None` when some grid direction has none.
pub(super) fn match_grid(grid: &AngularGrid, dirs: &[Dir]) -> Option<Vec<usize>> {
    let mut out = Vec::with_capacity(grid.directions());
    for &t in grid.theta_deg() {
        for j in 0..grid.phi_count() {
            let p = grid.phi_deg(j);
            let err = |d: &Dir| (d.theta - t).abs() + circular_diff(d.phi, p);
            let best = dirs
                .iter()
                .enumerate()
                .filter(|(_, d)| (d.theta - t).abs() <= MATCH_TOL_DEG && circular_diff(d.phi, p) <= MATCH_TOL_DEG)
                .min_by(|a, b| err(a.1).total_cmp(&err(b.1)))?;
            out.push(best.0);
        }
    }
    Some(out)
}

pub(super) fn describe_grid(g: &AngularGrid) -> String {
    let th: Vec<String> = g.theta_deg().iter().map(|t| format!("{t}")).collect();
    format!("θ = [{}]° × {} azimuths", th.join(", "), g.phi_count())
}

/// The `k` nearest measured directions to `target` with weights ∝ 1/d²
/// (summing to 1), or the one measured direction at the target.
pub(super) fn neighbours(target: [f64; 3], measured: &[[f64; 3]]) -> Vec<(usize, f32)> {
    let mut d: Vec<(f64, usize)> = measured.iter().enumerate().map(|(i, &v)| (angle(target, v), i)).collect();
    d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    match d.first() {
        None => Vec::new(),
        Some(&(d0, i0)) if d0 < EXACT_RAD => vec![(i0, 1.0)],
        Some(_) => {
            d.truncate(NEIGHBOURS);
            let w: Vec<f64> = d.iter().map(|&(x, _)| 1.0 / (x * x)).collect();
            let sum: f64 = w.iter().sum();
            d.iter().zip(w).map(|(&(_, i), w)| (i, (w / sum) as f32)).collect()
        }
    }
}

/// The measured target: a grid direction clamped to the outermost measured
/// ring at its azimuth, as a unit vector.
pub(super) fn lookup(grid: &AngularGrid, dir: usize, theta_max: f32) -> [f64; 3] {
    let (ti, pj) = (dir / grid.phi_count(), dir % grid.phi_count());
    unit(grid.theta_deg()[ti].min(theta_max) as f64, grid.phi_deg(pj) as f64)
}
