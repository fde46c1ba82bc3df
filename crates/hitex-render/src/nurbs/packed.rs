//! The paper's textures as flat arrays: knots, control points, trims,
//! edges, deviation grids and face colours.

use super::*;

/// The paper's textures, as flat arrays (row-major, one row per patch).
#[derive(Debug, Clone, PartialEq)]
pub struct PackedNurbs {
    /// Texels per knot row.
    pub knot_width: u32,
    /// u knots: texel 0 = knot count, then the knots.
    pub knots_u: Vec<f32>,
    /// v knots, same form.
    pub knots_v: Vec<f32>,
    /// Texels per control-point row.
    pub cp_width: u32,
    /// Texel 0 = (p, q, nu, nv); then homogeneous `(wx, wy, wz, w)`, index `1 + j·nu + i`.
    pub control: Vec<[f32; 4]>,
    /// Number of patches (rows).
    pub patches: u32,
    /// Texels per trim row.
    pub trim_width: u32,
    /// Trimming edges in parameter space: texel 0 = (edge count, r, g, b)
    /// with the patch's albedo in linear RGB (r < 0: the default), then
    /// `(u0, v0, u1, v1)` per edge of every loop (even–odd rule).
    pub trims: Vec<[f32; 4]>,
    /// Each patch's albedo (linear RGB) where the model gives one.
    pub colors: Vec<Option<[f32; 3]>>,
    /// Texels per edge row.
    pub edges_width: u32,
    /// Edges drawn over the display mode, one row per patch: texel 0 =
    /// (segment count, 0, 0, 0), then per segment its ends in the patch's
    /// parameters `(u0, v0, u1, v1)` and its colour `(r, g, b, 0)` (output
    /// encoded, 0–1). Set by [`PackedNurbs::set_edges`].
    pub edges: Vec<[f32; 4]>,
    /// Texels per deviation row.
    pub deviation_width: u32,
    /// The patches whose trimming loops held more than [`MAX_TRIM_EDGES`]
    /// edges, simplified to fit by [`PackedNurbs::set_trims`].
    pub trims_simplified: Vec<TrimSimplified>,
    /// Signed deviation from a reference, one row per patch: texel 0 = the
    /// grid's side G (0: none), then G×G values over the patch's parameter
    /// domain, v outer (`1 + j·G + i`), [`hitex_core::nurbs::deviation::NO_DATA`]
    /// where the reference has nothing near.
    pub deviation: Vec<f32>,
}

/// A polyline in a patch's parameters and the colour it is drawn in
/// (output-encoded RGB bytes).
pub type EdgeRun = (Vec<[f64; 2]>, [u8; 3]);

/// Most edge segments drawn on one patch (2 texels each in a row of 8,192).
pub const MAX_EDGE_SEGMENTS: usize = 4095;

/// Largest side of a patch's deviation grid (G² + 1 texels fit a row of
/// 8,192, the smallest texture width adapters guarantee).
pub const MAX_DEVIATION_GRID: usize = 90;

/// Trimming loops of one patch (closed polylines in its parameter space).
pub type TrimLoops = Vec<Vec<[f64; 2]>>;

/// Most trimming edges per patch (the width of the trim texture).
pub const MAX_TRIM_EDGES: usize = 8191;

/// A patch whose trimming loops were simplified to fit [`MAX_TRIM_EDGES`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrimSimplified {
    /// The patch.
    pub patch: usize,
    /// Edges its loops had.
    pub edges: usize,
    /// Edges kept.
    pub kept: usize,
    /// The largest distance between a loop as kept and as given, as a
    /// fraction of the side of the loops' box in parameter space (u and v
    /// each scaled by their own side).
    pub tolerance: f64,
}

/// `l` simplified (Douglas–Peucker): the points farther than `eps` from
/// the chord of the points kept around them are kept, first and last
/// always; distances with u and v divided by `scale`.
fn simplify(l: &[[f64; 2]], scale: [f64; 2], eps: f64) -> Vec<[f64; 2]> {
    if l.len() < 3 {
        return l.to_vec();
    }
    let p = |i: usize| [l[i][0] / scale[0], l[i][1] / scale[1]];
    let mut keep = vec![false; l.len()];
    keep[0] = true;
    keep[l.len() - 1] = true;
    let mut stack = vec![(0usize, l.len() - 1)];
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (pa, pb) = (p(a), p(b));
        let d = [pb[0] - pa[0], pb[1] - pa[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let (mut far, mut at) = (-1.0f64, a + 1);
        for i in a + 1..b {
            let q = p(i);
            let w = [q[0] - pa[0], q[1] - pa[1]];
            // distance to the segment (to `a` where the chord has no length)
            let t = if len2 > 0.0 { ((w[0] * d[0] + w[1] * d[1]) / len2).clamp(0.0, 1.0) } else { 0.0 };
            let e = [w[0] - t * d[0], w[1] - t * d[1]];
            let dist = (e[0] * e[0] + e[1] * e[1]).sqrt();
            // NaN (a point that is not finite) is kept
            if dist > far || dist.is_nan() {
                (far, at) = (dist, i);
            }
        }
        if far > eps || far.is_nan() {
            keep[at] = true;
            stack.push((a, at));
            stack.push((at, b));
        }
    }
    l.iter().zip(keep).filter_map(|(q, k)| k.then_some(*q)).collect()
}

impl PackedNurbs {
    /// Packs surfaces row by row.
    pub fn new(surfaces: &[NurbsSurface]) -> Self {
        let knot_width = surfaces.iter().map(|s| s.knots_u.len().max(s.knots_v.len()) + 1).max().unwrap_or(1) as u32;
        let cp_width = surfaces.iter().map(|s| s.points.len() + 1).max().unwrap_or(1) as u32;
        let rows = surfaces.len();
        let mut knots_u = vec![0.0f32; knot_width as usize * rows];
        let mut knots_v = vec![0.0f32; knot_width as usize * rows];
        let mut control = vec![[0.0f32; 4]; cp_width as usize * rows];
        for (k, s) in surfaces.iter().enumerate() {
            let ku = &mut knots_u[k * knot_width as usize..];
            ku[0] = s.knots_u.len() as f32;
            for (i, x) in s.knots_u.iter().enumerate() {
                ku[1 + i] = *x as f32;
            }
            let kv = &mut knots_v[k * knot_width as usize..];
            kv[0] = s.knots_v.len() as f32;
            for (i, x) in s.knots_v.iter().enumerate() {
                kv[1 + i] = *x as f32;
            }
            let c = &mut control[k * cp_width as usize..];
            c[0] = [s.degree_u as f32, s.degree_v as f32, s.count_u as f32, s.count_v as f32];
            for (i, p) in s.homogeneous().iter().enumerate() {
                c[1 + i] = p.map(|x| x as f32);
            }
        }
        Self {
            knot_width,
            knots_u,
            knots_v,
            cp_width,
            control,
            patches: rows as u32,
            trim_width: 1,
            trims: vec![[0.0, -1.0, -1.0, -1.0]; rows.max(1)],
            colors: vec![None; rows],
            trims_simplified: Vec::new(),
            deviation_width: 1,
            deviation: vec![0.0; rows.max(1)],
            edges_width: 1,
            edges: vec![[0.0; 4]; rows.max(1)],
        }
    }

    /// Packs polylines to draw over the display mode: for each patch, runs
    /// of parameter points with one colour (output-encoded RGB bytes).
    /// Consecutive points more than half the patch's domain apart (a run
    /// across a periodic seam) are not joined; a patch's segments beyond
    /// [`MAX_EDGE_SEGMENTS`] are thinned evenly.
    pub fn set_edges(&mut self, runs: &[Vec<EdgeRun>]) {
        let rows = self.patches as usize;
        let segments: Vec<Vec<([f32; 4], [f32; 4])>> = (0..rows)
            .map(|k| {
                let (u0, u1, v0, v1) = self.domain(k);
                let (hu, hv) = (0.5 * (u1 - u0).abs(), 0.5 * (v1 - v0).abs());
                let mut out = Vec::new();
                for (pts, rgb) in runs.get(k).map(Vec::as_slice).unwrap_or(&[]) {
                    let c = [rgb[0] as f32 / 255.0, rgb[1] as f32 / 255.0, rgb[2] as f32 / 255.0, 0.0];
                    for w in pts.windows(2) {
                        let (a, b) = (w[0].map(|x| x as f32), w[1].map(|x| x as f32));
                        if (a[0] - b[0]).abs() <= hu && (a[1] - b[1]).abs() <= hv {
                            out.push(([a[0], a[1], b[0], b[1]], c));
                        }
                    }
                    // a run of one point: a dot
                    if pts.len() == 1 {
                        let a = pts[0].map(|x| x as f32);
                        out.push(([a[0], a[1], a[0], a[1]], c));
                    }
                }
                let step = out.len().div_ceil(MAX_EDGE_SEGMENTS).max(1);
                out.into_iter().step_by(step).collect()
            })
            .collect();
        let width = segments.iter().map(|s| 2 * s.len() + 1).max().unwrap_or(1);
        let mut t = vec![[0.0f32; 4]; width * rows.max(1)];
        for (k, segs) in segments.iter().enumerate() {
            t[k * width] = [segs.len() as f32, 0.0, 0.0, 0.0];
            for (i, (e, c)) in segs.iter().enumerate() {
                t[k * width + 1 + 2 * i] = *e;
                t[k * width + 2 + 2 * i] = *c;
            }
        }
        self.edges_width = width as u32;
        self.edges = t;
    }

    /// Patch `k`'s parameter domain `(u0, u1, v0, v1)` from the packed knots.
    fn domain(&self, k: usize) -> (f32, f32, f32, f32) {
        let (kw, cw) = (self.knot_width as usize, self.cp_width as usize);
        let head = self.control[k * cw];
        let (p, q, nu, nv) = (head[0] as usize, head[1] as usize, head[2] as usize, head[3] as usize);
        let ku = |i: usize| self.knots_u.get(k * kw + 1 + i).copied().unwrap_or(0.0);
        let kv = |i: usize| self.knots_v.get(k * kw + 1 + i).copied().unwrap_or(0.0);
        (ku(p), ku(nu), kv(q), kv(nv))
    }

    /// Packs a deviation grid of side `grid` per patch (`values[k]`: G×G
    /// values over patch k's domain, v outer; a patch without values, or
    /// with fewer, gets none). `grid` is at least 2 and G² + 1 at most the
    /// texture width limit [`MAX_DEVIATION_GRID`]² + 1.
    pub fn set_deviation(&mut self, grid: usize, values: &[Vec<f32>]) {
        let g = grid.clamp(2, MAX_DEVIATION_GRID);
        let width = g * g + 1;
        let rows = self.patches as usize;
        let mut t = vec![0.0f32; width * rows.max(1)];
        for (k, v) in values.iter().enumerate().take(rows) {
            if v.len() == g * g {
                t[k * width] = g as f32;
                t[k * width + 1..(k + 1) * width].copy_from_slice(v);
            }
        }
        self.deviation_width = width as u32;
        self.deviation = t;
    }

    /// Gives patches their albedo (linear RGB; `None`: the default grey),
    /// used by the shaded mode.
    pub fn set_colors(&mut self, colors: &[Option<[f32; 3]>]) {
        self.colors = (0..self.patches as usize).map(|k| colors.get(k).copied().flatten()).collect();
        self.write_colors();
    }

    fn write_colors(&mut self) {
        let w = self.trim_width as usize;
        for (k, c) in self.colors.iter().enumerate() {
            if let Some(t) = self.trims.get_mut(k * w) {
                let [r, g, b] = c.unwrap_or([-1.0; 3]);
                *t = [t[0], r, g, b];
            }
        }
    }

    /// Packs trimming loops, one row per patch (patches beyond `trims` are
    /// untrimmed). A patch whose loops have more than [`MAX_TRIM_EDGES`]
    /// edges in total has them simplified to fit (Douglas–Peucker, the
    /// least tolerance found by doubling from a millionth of the loops'
    /// box: the points that shape the loop are kept, runs of nearly
    /// collinear ones dropped), and is listed in
    /// [`PackedNurbs::trims_simplified`]; were the loops more than the
    /// texture holds even as bare corners, the rest are thinned evenly.
    pub fn set_trims(&mut self, trims: &[TrimLoops]) {
        let rows = self.patches as usize;
        let mut simplified = Vec::new();
        let edges: Vec<Vec<[f32; 4]>> = (0..rows)
            .map(|k| {
                let given = trims.get(k).map(Vec::as_slice).unwrap_or(&[]);
                let count = |ls: &[Vec<[f64; 2]>]| ls.iter().map(|l| l.len().saturating_sub(1)).sum::<usize>();
                let total = count(given);
                let mut fitted: Vec<Vec<[f64; 2]>>;
                let loops = if total > MAX_TRIM_EDGES {
                    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
                    for q in given.iter().flatten().filter(|q| q[0].is_finite() && q[1].is_finite()) {
                        for a in 0..2 {
                            lo[a] = lo[a].min(q[a]);
                            hi[a] = hi[a].max(q[a]);
                        }
                    }
                    let side = |a: usize| if hi[a] > lo[a] { hi[a] - lo[a] } else { 1.0 };
                    let scale = [side(0), side(1)];
                    let mut eps = 1e-6;
                    loop {
                        fitted = given.iter().map(|l| simplify(l, scale, eps)).collect();
                        if count(&fitted) <= MAX_TRIM_EDGES || eps > 1.0 {
                            break;
                        }
                        eps *= 2.0;
                    }
                    simplified.push(TrimSimplified {
                        patch: k,
                        edges: total,
                        kept: count(&fitted).min(MAX_TRIM_EDGES),
                        tolerance: eps,
                    });
                    &fitted[..]
                } else {
                    given
                };
                let total = count(loops);
                let step = total.div_ceil(MAX_TRIM_EDGES).max(1);
                let mut e = Vec::new();
                for l in loops {
                    let pts: Vec<[f64; 2]> = l.iter().step_by(step).copied().chain(l.last().copied()).collect();
                    for w in pts.windows(2) {
                        if w[0] != w[1] {
                            e.push([w[0][0] as f32, w[0][1] as f32, w[1][0] as f32, w[1][1] as f32]);
                        }
                    }
                }
                e
            })
            .collect();
        let width = edges.iter().map(|e| e.len() + 1).max().unwrap_or(1);
        let mut t = vec![[0.0f32; 4]; width * rows.max(1)];
        for (k, e) in edges.iter().enumerate() {
            t[k * width] = [e.len() as f32, 0.0, 0.0, 0.0];
            t[k * width + 1..k * width + 1 + e.len()].copy_from_slice(e);
        }
        self.trim_width = width as u32;
        self.trims = t;
        self.trims_simplified = simplified;
        self.write_colors();
    }
}
