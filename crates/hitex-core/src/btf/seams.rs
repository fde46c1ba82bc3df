//! How seamlessly an index map tiles: the coherence of its wrap-around
//! edges against its interior, in the sample's feature space.

use super::dataset::Btf;
use super::features::{Features, sqdist};
use super::index::IndexMap;
use rayon::prelude::*;

/// Coherence of an index map at its wrap-around edges versus its interior
/// (see [`seam_quality`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeamReport {
    /// Mean neighbour error over the pairs that straddle the map's wrap
    /// edges (x = width−1 → 0 and y = height−1 → 0).
    pub seam_error: f32,
    /// Mean neighbour error over all other adjacent pairs (0 when there are none).
    pub interior_error: f32,
    /// `seam_error / interior_error`: about 1 when the wrap edges are no
    /// worse than the interior (the map tiles seamlessly); 1 when both are
    /// 0, infinite when only the interior is 0.
    pub ratio: f32,
}

/// Neighbour errors of `map` over the BTF's sample with features `feats`.
///
/// For each pair of horizontally (vertically) adjacent output texels, with
/// the map wrapping around, the *neighbour error* is the Euclidean feature
/// distance between the sample texel that would continue the first texel's
/// source coherently — s(left) + (1, 0), resp. s(top) + (0, 1), wrapped in
/// the sample — and the source actually chosen for the second texel; it is
/// 0 wherever the two are coherent (or merely look the same). Entries
/// outside the sample wrap into it; texels missing from `feats` count as
/// zero distance.
pub fn seam_quality(btf: &Btf, map: &IndexMap, feats: &Features) -> SeamReport {
    let (sw, sh) = (btf.width().max(1), btf.height().max(1));
    let (w, h) = (map.width, map.height);
    let feat =
        |[u, v]: [u16; 2]| feats.texel((u32::from(v) % sh) as usize * sw as usize + (u32::from(u) % sw) as usize);
    let dist = |a: &[f32], b: &[f32]| sqdist(a, b).sqrt();
    // per row: (seam sum, seam count, interior sum, interior count), summed in order
    let rows: Vec<[f64; 4]> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut acc = [0f64; 4];
            for x in 0..w {
                let [u, v] = map.get(x, y);
                let (u, v) = (u32::from(u) % sw, u32::from(v) % sh);
                let right = dist(feat([((u + 1) % sw) as u16, v as u16]), feat(map.get(x + 1, y)));
                let down = dist(feat([u as u16, ((v + 1) % sh) as u16]), feat(map.get(x, y + 1)));
                for (e, seam) in [(right, x + 1 == w), (down, y + 1 == h)] {
                    let i = if seam { 0 } else { 2 };
                    acc[i] += f64::from(e);
                    acc[i + 1] += 1.0;
                }
            }
            acc
        })
        .collect();
    let mut t = [0f64; 4];
    for r in &rows {
        for (a, b) in t.iter_mut().zip(r) {
            *a += b;
        }
    }
    let seam = if t[1] > 0.0 { (t[0] / t[1]) as f32 } else { 0.0 };
    let interior = if t[3] > 0.0 { (t[2] / t[3]) as f32 } else { 0.0 };
    let ratio = if interior > 0.0 {
        seam / interior
    } else if seam == 0.0 {
        1.0
    } else {
        f32::INFINITY
    };
    SeamReport { seam_error: seam, interior_error: interior, ratio }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::synth::tiny_corduroy as corduroy;

    #[test]
    fn seam_quality_tolerates_foreign_input() {
        let btf = corduroy();
        let short = Features { dims: 3, values: vec![1.0; 10] };
        let map = IndexMap { width: 3, height: 2, entries: vec![[40, 9]; 6] };
        let q = seam_quality(&btf, &map, &short);
        assert!(q.seam_error.is_finite() && q.interior_error.is_finite());
        let empty = IndexMap { width: 0, height: 0, entries: Vec::new() };
        assert_eq!(seam_quality(&btf, &empty, &short).ratio, 1.0);
    }
}
