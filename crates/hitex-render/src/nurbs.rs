//! NURBS scenes → data both backends consume: the paper's knot and
//! control-point textures, and a coarse tessellation that only generates
//! fragments carrying (u, v, patch).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use hitex_core::nurbs::NurbsSurface;
use hitex_core::scene::Camera;

pub use crate::nurbs_model::{Density, MeshCut, model_size};

/// The degrees with straight-line kernels in both fragment programs (the
/// paper's prepared degrees); others run the any-degree loops, or are raised
/// to the nearest prepared degree above them by [`PreparedNurbs::elevate_to_prepared`].
pub const PREPARED_DEGREES: [usize; 2] = [3, 5];

/// The nearest prepared degree at or above `d` (None above the largest).
pub fn prepared_degree_for(d: usize) -> Option<usize> {
    PREPARED_DEGREES.iter().copied().find(|&p| p >= d)
}

/// A patch's parameter range `((u0, u1), (v0, v1))`.
pub type ParamRange = ((f64, f64), (f64, f64));

/// What the NURBS fragment program shows. Its names ([`NurbsMode::name`])
/// are those of the command line (with the `clap` feature, `clap::ValueEnum`
/// derives the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum NurbsMode {
    /// Lit surface (Blinn–Phong) with the exact normal.
    #[default]
    #[cfg_attr(feature = "clap", value(help = "Lit surface."))]
    Shaded,
    /// Isophotes: bands of equal angle between normal and light.
    #[cfg_attr(feature = "clap", value(help = "Isophote bands."))]
    Isophote,
    /// Reflection lines of a striped environment.
    #[cfg_attr(feature = "clap", value(help = "Reflection lines."))]
    Zebra,
    /// Highlight lines: where the normal line meets a plane of parallel
    /// light lines (view-independent, Beier & Chen).
    #[cfg_attr(feature = "clap", value(help = "Highlight lines."))]
    Highlight,
    /// Gaussian curvature on a diverging colour ramp.
    #[cfg_attr(feature = "clap", value(help = "Gaussian curvature."))]
    Gauss,
    /// Mean curvature on a diverging colour ramp.
    #[cfg_attr(feature = "clap", value(help = "Mean curvature."))]
    Mean,
    /// Isophotes of normals interpolated from the tessellation's vertices
    /// (per-vertex evaluation, the paper's Fig. 4 comparison).
    #[cfg_attr(
        feature = "clap",
        value(help = "Isophotes of interpolated vertex normals (the paper's Fig. 4 comparison).")
    )]
    VertexNormals,
    /// The exact normal as RGB.
    #[cfg_attr(feature = "clap", value(help = "Normals as RGB."))]
    Normal,
    /// Draft angle against a pull direction in three classes: positive
    /// beyond the tolerance, within it, negative beyond it.
    #[cfg_attr(
        feature = "clap",
        value(help = "Draft angle against the pull direction: positive, within tolerance, negative.")
    )]
    Draft,
    /// Where a ball tool of a given radius cannot reach: concave with a
    /// radius of curvature below it, concave above it, convex or flat.
    #[cfg_attr(
        feature = "clap",
        value(help = "Where a ball tool of radius --min-radius cannot reach (concave, tighter than it).")
    )]
    Radius,
    /// The larger principal curvature κ1 on a diverging colour ramp (signed
    /// towards the normal that faces the viewer, as the mean curvature).
    #[cfg_attr(feature = "clap", value(help = "The larger principal curvature κ1."))]
    K1,
    /// The smaller principal curvature κ2, same ramp and sign.
    #[cfg_attr(feature = "clap", value(help = "The smaller principal curvature κ2."))]
    K2,
    /// A mirror reflecting a procedural photo studio (soft boxes behind
    /// and above the viewer, one at the side, a dark floor): the
    /// highlights a class-A surface is judged by, from the exact normal.
    #[cfg_attr(
        feature = "clap",
        value(
            help = "A mirror in a procedural photo studio (soft boxes behind and above the viewer): highlights as a class-A surfacer judges them."
        )
    )]
    Reflection,
    /// Signed deviation from a reference mesh or point cloud
    /// ([`PreparedNurbs::set_deviation`]): green within the tolerance,
    /// yellow to red outside the surface, cyan to blue inside, grey where
    /// the reference has nothing near.
    #[cfg_attr(
        feature = "clap",
        value(
            help = "Signed deviation from --reference (a scan's mesh or points): green within --tolerance, yellow to red outside the surface, cyan to blue inside."
        )
    )]
    Deviation,
}

impl NurbsMode {
    /// The mode of a CLI or scene-file name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, m)| *m)
    }

    /// Every mode with its CLI name.
    pub const ALL: [(&'static str, NurbsMode); 14] = [
        ("shaded", NurbsMode::Shaded),
        ("isophote", NurbsMode::Isophote),
        ("zebra", NurbsMode::Zebra),
        ("highlight", NurbsMode::Highlight),
        ("gauss", NurbsMode::Gauss),
        ("mean", NurbsMode::Mean),
        ("vertex-normals", NurbsMode::VertexNormals),
        ("normal", NurbsMode::Normal),
        ("draft", NurbsMode::Draft),
        ("radius", NurbsMode::Radius),
        ("k1", NurbsMode::K1),
        ("k2", NurbsMode::K2),
        ("deviation", NurbsMode::Deviation),
        ("reflection", NurbsMode::Reflection),
    ];
    /// The CLI and scene-file name of the mode.
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(_, m)| *m == self).map_or("shaded", |(n, _)| n)
    }

    /// Index used by both fragment programs ([`mode_index`]).
    pub const fn index(self) -> u32 {
        use mode_index::*;
        match self {
            NurbsMode::Shaded => SHADED,
            NurbsMode::Isophote => ISOPHOTE,
            NurbsMode::Zebra => ZEBRA,
            NurbsMode::Gauss => GAUSS,
            NurbsMode::Mean => MEAN,
            NurbsMode::VertexNormals => VERTEX_NORMALS,
            NurbsMode::Normal => NORMAL,
            NurbsMode::Highlight => HIGHLIGHT,
            NurbsMode::Draft => DRAFT,
            NurbsMode::Radius => RADIUS,
            NurbsMode::K1 => K1,
            NurbsMode::K2 => K2,
            NurbsMode::Deviation => DEVIATION,
            NurbsMode::Reflection => REFLECTION,
        }
    }
}

/// The display modes' indices in the uniform (`params.x`), one table for
/// both programs: `cpu/nurbs.rs` matches on these, `nurbs.wgsl` on the
/// `MODE_*` constants generated from them ([`wgsl_mode_constants`]).
pub mod mode_index {
    #![allow(missing_docs)]
    pub const SHADED: u32 = 0;
    pub const ISOPHOTE: u32 = 1;
    pub const ZEBRA: u32 = 2;
    pub const GAUSS: u32 = 3;
    pub const MEAN: u32 = 4;
    pub const VERTEX_NORMALS: u32 = 5;
    pub const NORMAL: u32 = 6;
    pub const HIGHLIGHT: u32 = 7;
    pub const DRAFT: u32 = 8;
    pub const RADIUS: u32 = 9;
    pub const K1: u32 = 10;
    pub const K2: u32 = 11;
    pub const DEVIATION: u32 = 12;
    pub const REFLECTION: u32 = 13;
}

/// Bits of the flags word (`params.w`) of [`NurbsFrame`].
pub mod flag {
    /// Prepared-degree kernels.
    pub const PREPARED: u32 = 1;
    /// Patch-boundary overlay.
    pub const BOUNDARIES: u32 = 2;
    /// Isoparametric lines overlay (`lines.w` per patch and direction).
    pub const ISOLINES: u32 = 4;
    /// Section curves of a plane family (`lines.xyz` = normal / spacing).
    pub const SECTIONS: u32 = 8;
    /// Classified edges ([`super::PackedNurbs::edges`]).
    pub const EDGES: u32 = 16;
}

/// Overlay colours (sRGB bytes): isoparametric lines and section curves.
pub const ISOLINE_RGB: [u8; 3] = [64, 70, 82];
/// See [`ISOLINE_RGB`].
pub const SECTION_RGB: [u8; 3] = [200, 40, 200];

/// WGSL constants `MODE_<NAME>` for every display mode (the CLI name in
/// capitals, `-` as `_`) and the overlay colours `ISOLINE_RGB`,
/// `SECTION_RGB`, prepended to `nurbs.wgsl`.
pub fn wgsl_mode_constants() -> String {
    let rgb = |c: [u8; 3]| format!("vec3<f32>({}.0 / 255.0, {}.0 / 255.0, {}.0 / 255.0)", c[0], c[1], c[2]);
    let mut s: String = NurbsMode::ALL
        .iter()
        .map(|(name, m)| format!("const MODE_{}: u32 = {}u;\n", name.to_ascii_uppercase().replace('-', "_"), m.index()))
        .collect();
    s += &format!("const ISOLINE_RGB: vec3<f32> = {};\n", rgb(ISOLINE_RGB));
    s += &format!("const SECTION_RGB: vec3<f32> = {};\n", rgb(SECTION_RGB));
    s
}

/// A tessellation vertex: coarse position, exact normal there, (u, v), patch.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct NurbsVertex {
    /// Surface point at the vertex (only places the fragments).
    pub position: [f32; 3],
    /// Exact (limit) unit normal at the vertex, for the vertex-normal mode.
    pub normal: [f32; 3],
    /// Surface parameters.
    pub uv: [f32; 2],
    /// Patch index (a whole number).
    pub patch: f32,
    /// Padding.
    pub _pad: f32,
}

/// Default tolerance of the draft mode, degrees.
pub const DEFAULT_DRAFT_TOLERANCE_DEG: f32 = 1.0;

/// Per-frame uniforms of `nurbs.wgsl` (group 0, binding 0).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct NurbsFrame {
    /// World-to-clip matrix.
    pub view_proj: [[f32; 4]; 4],
    /// Camera position.
    pub camera: [f32; 4],
    /// Unit direction towards the light.
    pub light: [f32; 4],
    /// x: mode, y: isophote bands, z: zebra / highlight stripes, w: flags
    /// ([`flag`]: prepared-degree kernels, patch boundaries, isoparametric
    /// lines, sections).
    pub params: [u32; 4],
    /// x, y: curvature range for the colour ramp (deviation mode: the
    /// tolerance and the range); z: ambient; w: 1 / the tool radius of the
    /// radius mode.
    pub ranges: [f32; 4],
    /// Linear background RGB.
    pub background: [f32; 4],
    /// Model bounding sphere: centre xyz, radius w (places the highlight-line plane).
    pub model: [f32; 4],
    /// Draft: unit pull direction xyz, w: sine of the draft tolerance.
    pub pull: [f32; 4],
    /// Overlays: xyz the section planes' unit normal divided by their
    /// spacing (a section wherever `P·xyz` is a whole number), w the
    /// isoparametric lines per patch and direction.
    pub lines: [f32; 4],
    /// The view's up axis (unit; the model's up): the zebra's light bars
    /// and the studio's horizon lie across it.
    pub up: [f32; 4],
}

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

/// Which model axis points up in a view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpAxis {
    /// The axis of a flat model's smallest extent (a sheet lies on its
    /// largest face), else Z (the usual CAD convention).
    Auto,
    /// A signed model axis: 0 = X, 1 = Y, 2 = Z; `true` for negative.
    Axis(usize, bool),
}

impl UpAxis {
    /// Parses `auto`, `x`, `y`, `z`, `+z`, `-y`, …
    pub fn parse(s: &str) -> Result<Self, crate::RenderError> {
        let t = s.trim().to_ascii_lowercase();
        if t == "auto" {
            return Ok(Self::Auto);
        }
        let (neg, name) = match t.strip_prefix('-') {
            Some(r) => (true, r),
            None => (false, t.strip_prefix('+').unwrap_or(&t)),
        };
        let k = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => {
                return Err(crate::RenderError::Invalid(format!(
                    "'{s}' is not an axis: give auto, x, y, z, -x, -y or -z"
                )));
            }
        };
        Ok(Self::Axis(k, neg))
    }

    /// The axis as a unit vector (`Auto`: +Z).
    pub fn direction(self) -> Vec3 {
        match self {
            Self::Auto => Vec3::Z,
            Self::Axis(k, neg) => {
                let mut v = Vec3::ZERO;
                v[k.min(2)] = if neg { -1.0 } else { 1.0 };
                v
            }
        }
    }

    /// `+X`, `-Z`, … (`auto` before it is resolved).
    pub fn name(self) -> String {
        match self {
            Self::Auto => "auto".into(),
            Self::Axis(k, neg) => format!("{}{}", if neg { '-' } else { '+' }, ["X", "Y", "Z"][k.min(2)]),
        }
    }
}

/// How a model is looked at: which way is up, the turn about it and the
/// elevation above the horizontal, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelView {
    /// The model's up axis.
    pub up: UpAxis,
    /// Turn about the up axis, degrees.
    pub turn_deg: f32,
    /// Elevation of the eye above the horizontal plane, degrees in [−89, 89].
    pub elevation_deg: f32,
}

impl ModelView {
    /// Default elevation: the eye about 23.5° above the horizontal.
    pub const ELEVATION_DEG: f32 = 23.5;
    /// Default azimuth of the eye from the −(second axis) side, degrees.
    const AZIMUTH_DEG: f32 = 29.54;
}

impl Default for ModelView {
    fn default() -> Self {
        Self { up: UpAxis::Auto, turn_deg: 0.0, elevation_deg: Self::ELEVATION_DEG }
    }
}

/// Most triangles [`fitted_grids`] gives a model (about 200 MB of
/// vertices and indices at the largest).
pub const MAX_FITTED_TRIANGLES: u64 = 1 << 22;

/// Each patch's tessellation grid (cells along u, along v) such that the
/// mesh that places fragments lies within `tol` model units of the exact
/// surface along its grid lines: at least `min` cells a side and one a
/// knot span, refined per direction until the largest sag of a cell's edge
/// (the distance between the surface at the edge's middle and the chord's
/// middle, over lines across the patch) is at most `tol`, up to 256 cells a
/// side. Where the mesh falls short of the surface (a convex silhouette
/// seen between grid lines), the exact fragments beyond it are not drawn:
/// a whole-turn cylinder on an 8×8 grid loses a polygon's sag (7.6 % of
/// its radius) at its silhouette, one fitted to a quarter pixel draws the
/// circle. A model whose grids would exceed [`MAX_FITTED_TRIANGLES`] has
/// every side scaled down evenly to fit (the sag then exceeds `tol`).
pub fn fitted_grids(surfaces: &[NurbsSurface], ranges: &[ParamRange], min: u32, tol: f64) -> Vec<(u32, u32)> {
    use rayon::prelude::*;
    let min = min.clamp(1, 256);
    let tol = if tol.is_finite() && tol > 0.0 { tol } else { f64::MAX };
    let grids: Vec<(u32, u32)> = surfaces
        .par_iter()
        .enumerate()
        .map(|(k, s)| {
            let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
            // knot spans inside the range: a grid line on every knot would
            // need more, one cell a span at least
            let spans = |knots: &[f64], a: f64, b: f64| -> u32 {
                let mut inner: Vec<f64> = knots.iter().copied().filter(|&t| t > a && t < b).collect();
                inner.dedup();
                (inner.len() as u32 + 1).min(256)
            };
            let mut nu = min.max(spans(&s.knots_u, u0, u1));
            let mut nv = min.max(spans(&s.knots_v, v0, v1));
            // refine each direction over lines across the other one's grid
            for _ in 0..4 {
                let su = grid_sag(s, (u0, u1), (v0, v1), nu, nv.min(32), false);
                let sv = grid_sag(s, (v0, v1), (u0, u1), nv, nu.min(32), true);
                let grow = |n: u32, sag: f64| -> u32 {
                    if sag <= tol || n >= 256 {
                        n
                    } else {
                        // a sag falls with the square of the cells a side
                        let want = (n as f64 * (sag / tol).sqrt() * 1.05).ceil();
                        (want.min(256.0) as u32).max(n + 1)
                    }
                };
                let (gu, gv) = (grow(nu, su), grow(nv, sv));
                if (gu, gv) == (nu, nv) {
                    break;
                }
                (nu, nv) = (gu, gv);
            }
            (nu, nv)
        })
        .collect();
    let total: u64 = grids.iter().map(|&(a, b)| 2 * a as u64 * b as u64).sum();
    if total <= MAX_FITTED_TRIANGLES {
        return grids;
    }
    let f = (MAX_FITTED_TRIANGLES as f64 / total as f64).sqrt();
    grids.iter().map(|&(a, b)| (((a as f64 * f) as u32).max(1), ((b as f64 * f) as u32).max(1))).collect()
}

/// The largest sag of the `n` cells along one direction of a patch (its
/// range `along`), over `lines` + 1 lines at equal steps of the other
/// (`across`); `v_first`: the direction is v. Non-finite points are passed over.
fn grid_sag(s: &NurbsSurface, along: (f64, f64), across: (f64, f64), n: u32, lines: u32, v_first: bool) -> f64 {
    let at = |t: f64, c: f64| if v_first { s.point(c, t) } else { s.point(t, c) };
    let step = |r: (f64, f64), i: f64, m: u32| r.0 + (r.1 - r.0) * i / m as f64;
    let mut worst = 0.0f64;
    for j in 0..=lines {
        let c = step(across, j as f64, lines);
        let mut a = at(along.0, c);
        for i in 0..n {
            let b = at(step(along, (i + 1) as f64, n), c);
            let m = at(step(along, i as f64 + 0.5, n), c);
            let d = (0..3).map(|t| (m[t] - 0.5 * (a[t] + b[t])).powi(2)).sum::<f64>().sqrt();
            if d.is_finite() {
                worst = worst.max(d);
            }
            a = b;
        }
    }
    worst
}

/// For each boundary polyline (patch, side, density, points), whether
/// another side's polyline has every one of its points within `tol`
/// (neighbours sampled alike, whose tessellations already meet).
fn matched_sides(sides: &[(usize, usize, u32, Vec<[f64; 3]>)], tol: f64) -> Vec<bool> {
    use std::collections::HashMap;
    let key = |p: &[f64; 3]| -> Option<[i64; 3]> {
        let k = p.map(|x| (x / tol).floor());
        k.iter().all(|x| x.is_finite() && x.abs() < 1e15).then(|| k.map(|x| x as i64))
    };
    // every side under the cells of its points
    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, side) in sides.iter().enumerate() {
        for p in &side.3 {
            if let Some(c) = key(p) {
                let list = cells.entry(c).or_default();
                if list.last() != Some(&i) {
                    list.push(i);
                }
            }
        }
    }
    let near = |p: &[f64; 3], q: &[f64; 3]| (0..3).all(|t| (p[t] - q[t]).abs() <= tol);
    sides
        .iter()
        .enumerate()
        .map(|(i, side)| {
            let pts = &side.3;
            // a collapsed side (a pole) has no seam to close
            if pts.iter().all(|p| near(p, &pts[0])) {
                return true;
            }
            let Some(c) = key(&pts[0]) else { return false };
            let mut candidates = Vec::new();
            for d in 0..27i64 {
                let cell = [c[0] + d % 3 - 1, c[1] + (d / 3) % 3 - 1, c[2] + d / 9 - 1];
                if let Some(list) = cells.get(&cell) {
                    candidates.extend(list.iter().copied().filter(|&j| j != i));
                }
            }
            candidates.sort_unstable();
            candidates.dedup();
            candidates.iter().any(|&j| pts.iter().all(|p| sides[j].3.iter().any(|q| near(p, q))))
        })
        .collect()
}

/// Added to the patch index of boundary-fan vertices: the programs round the
/// index, and draw fan fragments behind any surface truly there.
pub const FAN_MARK: f32 = 0.25;

/// Largest number of halvings of a boundary segment in its fan.
const FAN_LEVELS: u32 = 3;

/// Triangles closing the lens between one boundary segment's chord and its
/// curve: the curve's midpoint joined to the chord, then each half again,
/// until the sag left is below 1/4^[`FAN_LEVELS`] of the chord's (or
/// vanishes). `at(t)` gives the boundary parameter pair at `t`, `push` takes
/// one vertex (parameters, point, normal).
fn boundary_fan(
    s: &NurbsSurface,
    at: &dyn Fn(f64) -> (f64, f64),
    ta: f64,
    tb: f64,
    level: u32,
    floor: f64,
    push: &mut dyn FnMut((f64, f64), [f64; 3], [f64; 3]),
) {
    let tm = 0.5 * (ta + tb);
    let (a, b, m) = (at(ta), at(tb), at(tm));
    let (pa, pb, pm) = (s.point(a.0, a.1), s.point(b.0, b.1), s.point(m.0, m.1));
    let sag = (0..3).map(|t| pm[t] - 0.5 * (pa[t] + pb[t])).map(|x| x * x).sum::<f64>().sqrt();
    if !(sag.is_finite() && sag > floor && pa.iter().chain(&pb).chain(&pm).all(|x| x.is_finite())) {
        return;
    }
    for (uv, p) in [(a, pa), (b, pb), (m, pm)] {
        push(uv, p, s.normal(uv.0, uv.1));
    }
    if level + 1 < FAN_LEVELS {
        let floor = if level == 0 { sag / 4f64.powi(FAN_LEVELS as i32) } else { floor };
        boundary_fan(s, at, ta, tm, level + 1, floor, push);
        boundary_fan(s, at, tm, tb, level + 1, floor, push);
    }
}

/// A NURBS model ready for either backend.
#[derive(Debug, Clone)]
pub struct PreparedNurbs {
    /// The surfaces (f64 reference).
    pub surfaces: Vec<NurbsSurface>,
    /// Tessellation vertices.
    pub vertices: Vec<NurbsVertex>,
    /// Triangles.
    pub indices: Vec<u32>,
    /// Knot and control-point textures.
    pub packed: PackedNurbs,
    /// Camera framing the model.
    pub camera: Camera,
    /// Display mode.
    pub mode: NurbsMode,
    /// Isophote bands over 180°.
    pub bands: u32,
    /// Zebra stripes over 180°.
    pub stripes: u32,
    /// Pull (demoulding) direction of the draft mode.
    pub pull: Vec3,
    /// Draft angles within ± this many degrees count as "no draft".
    pub draft_tolerance_deg: f32,
    /// Tool radius of the radius mode (model units; 0: 1/50 of the model's
    /// bounding diameter).
    pub tool_radius: f32,
    /// Deviation mode: `(tolerance, range)` in model units — within ±
    /// tolerance green, the colour ramps saturate at ± range.
    pub deviation_range: (f32, f32),
    /// Curvature mapped to full colour on the ramp: [Gaussian, mean,
    /// principal]; by default twice the area-weighted 75th percentile of |K|
    /// and |H| over the surface (over its curved part where flat faces hold
    /// more than a quarter of the area), and of max(|κ1|, |κ2|) over its curved part
    /// (radius of curvature below 10⁴ × the model's bounding radius; none:
    /// 1 / that radius).
    pub curvature_range: [f32; 3],
    /// Whether each default of [`PreparedNurbs::curvature_range`] was
    /// taken over the curved part alone (always for the principal ramp; for
    /// |K| and |H| where flat faces hold more than a quarter of the area).
    pub curvature_over_curved_part: [bool; 3],
    /// Linear background.
    pub background: Vec3,
    /// Use the straight-line kernels of the prepared degree (bicubic) for
    /// patches of that degree, as the paper does; otherwise the any-degree loops.
    pub prepared_kernels: bool,
    /// Draw patch boundaries (one pixel wide) over the display mode.
    pub boundaries: bool,
    /// Draw this many isoparametric lines per patch and direction (at
    /// equal steps of each patch's parameter range, its edges included; 0:
    /// none), one pixel wide, over the display mode.
    pub isolines: u32,
    /// Draw section curves of the planes `P·normal = k·spacing` (a unit
    /// normal and a spacing in model units), one pixel wide.
    pub sections: Option<(Vec3, f32)>,
    /// Draw the edges set by [`PreparedNurbs::set_edges`] (three pixels wide).
    pub edges: bool,
    /// Direction towards the light; `None`: over the viewer's shoulder.
    pub light: Option<Vec3>,
    /// Bounding sphere of the tessellation: centre, radius.
    pub bounds: (Vec3, f32),
    /// Largest distance between the exact surface and its tessellation,
    /// estimated at every cell's centre (model units).
    pub tess_deviation: f32,
    /// Let the CPU backend skip fragments that lie behind the depth already
    /// drawn by more than the tessellation's deviation allows (a conservative
    /// early depth test; the image is the same).
    pub early_depth: bool,
    id: u64,
}

static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1 << 40);

impl PreparedNurbs {
    /// Tessellates every patch over its parameter range into a
    /// `density`×`density` grid and frames the model with a camera.
    pub fn new(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], density: u32) -> Self {
        let densities = vec![density; surfaces.len()];
        Self::with_densities(surfaces, ranges, &densities)
    }

    /// Like [`PreparedNurbs::new`] for a model whose patches carry trim
    /// loops (`trims[k]` for patch k; empty: untrimmed). Models read from
    /// files (IGES 144/142, free-form OBJ) go through this one, so that no
    /// caller can drop their trims by forgetting a step.
    pub fn trimmed(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], trims: &[TrimLoops], density: u32) -> Self {
        let mut p = Self::new(surfaces, ranges, density);
        if trims.iter().any(|t| !t.is_empty()) {
            p.set_trims(trims);
        }
        p
    }

    /// Like [`PreparedNurbs::new`] with a tessellation density per patch.
    pub fn with_densities(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], densities: &[u32]) -> Self {
        let grids: Vec<(u32, u32)> = densities.iter().map(|&d| (d, d)).collect();
        Self::with_grids(surfaces, ranges, &grids)
    }

    /// Like [`PreparedNurbs::trimmed`] with each patch's own grid, cells
    /// along u and along v (e.g. from [`fitted_grids`]); a patch beyond
    /// `grids` takes 8×8, sides are clamped to 1…256.
    pub fn trimmed_grids(
        surfaces: Vec<NurbsSurface>,
        ranges: &[ParamRange],
        trims: &[TrimLoops],
        grids: &[(u32, u32)],
    ) -> Self {
        let mut p = Self::with_grids(surfaces, ranges, grids);
        if trims.iter().any(|t| !t.is_empty()) {
            p.set_trims(trims);
        }
        p
    }

    /// Like [`PreparedNurbs::new`] with a grid per patch: `grids[k]` cells
    /// along u and along v (8×8 beyond the slice; each side clamped to 1…256).
    pub fn with_grids(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], grids: &[(u32, u32)]) -> Self {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut sides: Vec<(usize, usize, u32, Vec<[f64; 3]>)> = Vec::new();
        let mut deviation = 0.0f32;
        for (k, s) in surfaces.iter().enumerate() {
            let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
            let (nu, nv) = grids.get(k).copied().unwrap_or((8, 8));
            let (nu, nv) = (nu.clamp(1, 256), nv.clamp(1, 256));
            let base = vertices.len() as u32;
            let grid =
                |a: f64, b: f64, n: u32| (0..=n).map(|i| a + (b - a) * i as f64 / n as f64).collect::<Vec<f64>>();
            let (us, vs) = (grid(u0, u1, nu), grid(v0, v1, nv));
            for &v in &vs {
                for &u in &us {
                    let p = s.point(u, v);
                    let n = s.normal(u, v);
                    if p.iter().all(|x| x.is_finite()) {
                        for t in 0..3 {
                            lo[t] = lo[t].min(p[t]);
                            hi[t] = hi[t].max(p[t]);
                        }
                    }
                    vertices.push(NurbsVertex {
                        position: p.map(|x| x as f32),
                        normal: n.map(|x| x as f32),
                        uv: [u as f32, v as f32],
                        patch: k as f32,
                        _pad: 0.0,
                    });
                }
            }
            let row = nu + 1;
            for j in 0..nv {
                for i in 0..nu {
                    let a = base + j * row + i;
                    indices.extend_from_slice(&[a, a + 1, a + row, a + 1, a + row + 1, a + row]);
                    // the deviation at the cell's centre from its corners' mean
                    let (uc, vc) =
                        (0.5 * (us[i as usize] + us[i as usize + 1]), 0.5 * (vs[j as usize] + vs[j as usize + 1]));
                    let exact = s.point(uc, vc);
                    let corners = [a, a + 1, a + row, a + row + 1].map(|c| vertices[c as usize].position);
                    let d = (0..3)
                        .map(|t| exact[t] as f32 - corners.iter().map(|c| c[t]).sum::<f32>() / 4.0)
                        .map(|x| x * x)
                        .sum::<f32>()
                        .sqrt();
                    if d.is_finite() {
                        deviation = deviation.max(d);
                    }
                }
            }
            // the boundary polylines, for the fans below
            for side in 0..4 {
                // sides 0 and 1 run along v, 2 and 3 along u
                let density = if side < 2 { nv } else { nu };
                let pts = (0..=density as usize)
                    .map(|i| {
                        let (u, v) = (
                            if side == 0 {
                                u0
                            } else if side == 1 {
                                u1
                            } else {
                                us[i]
                            },
                            if side == 2 {
                                v0
                            } else if side == 3 {
                                v1
                            } else {
                                vs[i]
                            },
                        );
                        s.point(u, v)
                    })
                    .collect();
                sides.push((k, side, density, pts));
            }
        }
        // boundary fans: each side's chords are joined to the curve they cut
        // across. Neighbours tessellated independently cut a shared curve into
        // different chords; each fills up to the curve (within 1/64 of its
        // chords' sag), so no background shows between them, and nothing
        // reaches past the true surface. A side whose polyline another side
        // repeats point for point needs none (the teapot's seams).
        let extent = (0..3).map(|t| (hi[t] - lo[t]).powi(2)).sum::<f64>().sqrt();
        let matched = matched_sides(&sides, 1e-9 * extent.max(1e-300));
        for ((k, side, density, _), matched) in sides.iter().zip(matched) {
            if matched {
                continue;
            }
            let (k, density) = (*k, *density);
            let s = &surfaces[k];
            let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
            let at: Box<dyn Fn(f64) -> (f64, f64)> = match side {
                0 => Box::new(|t| (u0, t)),
                1 => Box::new(|t| (u1, t)),
                2 => Box::new(|t| (t, v0)),
                _ => Box::new(|t| (t, v1)),
            };
            let (a, b) = if *side < 2 { (v0, v1) } else { (u0, u1) };
            let mut push = |uv: (f64, f64), p: [f64; 3], n: [f64; 3]| {
                indices.push(vertices.len() as u32);
                vertices.push(NurbsVertex {
                    position: p.map(|x| x as f32),
                    normal: n.map(|x| x as f32),
                    uv: [uv.0 as f32, uv.1 as f32],
                    patch: k as f32 + FAN_MARK,
                    _pad: 0.0,
                });
            };
            for i in 0..density {
                let (ta, tb) = (a + (b - a) * i as f64 / density as f64, a + (b - a) * (i + 1) as f64 / density as f64);
                boundary_fan(s, at.as_ref(), ta, tb, 0, 0.0, &mut push);
            }
        }
        let center =
            Vec3::new(((lo[0] + hi[0]) / 2.0) as f32, ((lo[1] + hi[1]) / 2.0) as f32, ((lo[2] + hi[2]) / 2.0) as f32);
        let radius = (0..3).map(|t| (hi[t] - lo[t]) / 2.0).map(|x| x * x).sum::<f64>().sqrt().max(1e-6) as f32;
        let fov = 35.0f32;
        let dist = radius / (fov.to_radians() / 2.0).sin() * 0.95;
        let dir = Vec3::new(0.85, -1.5, 0.75).normalize();
        let camera = Camera {
            position: center + dir * dist,
            target: center,
            up: Vec3::Z,
            fov_y_deg: fov,
            near: (dist - radius * 1.5).max(dist * 0.01),
            far: dist + radius * 1.5,
        };
        let packed = PackedNurbs::new(&surfaces);
        // curvature ranges: twice the area-weighted 75th percentile of |K| and
        // |H| over a 6×6 sample grid per patch, each sample weighted by the
        // surface area it stands for (|S_u × S_v| du dv), so that many small,
        // sharply curved patches (fillets, rims) do not set the scale of the
        // large ones
        let mut ks = Vec::new();
        let mut hs = Vec::new();
        let mut ps = Vec::new();
        let (mut ks_curved, mut hs_curved) = (Vec::new(), Vec::new());
        for s in &surfaces {
            let ((u0, u1), (v0, v1)) = s.domain();
            let cell = (u1 - u0) * (v1 - v0) / 36.0;
            for k in 0..36 {
                let u = u0 + (u1 - u0) * ((k % 6) as f64 + 0.5) / 6.0;
                let v = v0 + (v1 - v0) * ((k / 6) as f64 + 0.5) / 6.0;
                let c = s.curvature(u, v);
                let d = s.derivatives(u, v, 1);
                let (a, b) = (d.d[1][0], d.d[0][1]);
                let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                let area = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() * cell;
                if c.gaussian.is_finite() && c.mean.is_finite() && area.is_finite() {
                    ks.push((c.gaussian.abs(), area));
                    hs.push((c.mean.abs(), area));
                    if c.gaussian.abs() * (radius as f64).powi(2) > 1e-8 {
                        ks_curved.push((c.gaussian.abs(), area));
                    }
                    if c.mean.abs() * radius as f64 > 1e-4 {
                        hs_curved.push((c.mean.abs(), area));
                    }
                    // the principal ramp is scaled by the curved part alone:
                    // on a machined part most of the area is planes, whose
                    // zero would set a scale of nothing
                    let k = c.principal[0].abs().max(c.principal[1].abs());
                    if k.is_finite() && k * radius as f64 > 1e-4 {
                        ps.push((k, area));
                    }
                }
            }
        }
        let pick = |mut v: Vec<(f64, f64)>| -> f32 {
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            let total: f64 = v.iter().map(|x| x.1).sum();
            let mut acc = 0.0;
            let mut at = v.last().map_or(0.5, |x| x.0);
            for (value, w) in &v {
                acc += w;
                if acc >= 0.75 * total {
                    at = *value;
                    break;
                }
            }
            2.0 * at as f32
        };
        let r = radius.max(f32::MIN_POSITIVE);
        let principal_range = if ps.is_empty() { 1.0 / r } else { pick(ps).max(1e-12) };
        // |K| and |H| over the whole surface, unless flat faces hold more
        // than a quarter of the area (a machined part): their zeros would
        // set a scale of nothing, and the curved part alone sets it
        let over = |all: Vec<(f64, f64)>, curved: Vec<(f64, f64)>, floor: f32, none: f32| -> (f32, bool) {
            let whole = pick(all);
            if whole / 2.0 > floor {
                (whole.max(1e-12), false)
            } else if curved.is_empty() {
                (none, true)
            } else {
                (pick(curved).max(1e-12), true)
            }
        };
        let (k_range, k_curved) = over(ks, ks_curved, 1e-8 / (r * r), 1.0 / (r * r));
        let (h_range, h_curved) = over(hs, hs_curved, 1e-4 / r, 1.0 / r);
        let curvature_range = [k_range, h_range, principal_range];
        let curvature_over_curved_part = [k_curved, h_curved, true];
        Self {
            surfaces,
            vertices,
            indices,
            packed,
            camera,
            mode: NurbsMode::Shaded,
            bands: 12,
            stripes: 10,
            pull: Vec3::Z,
            draft_tolerance_deg: DEFAULT_DRAFT_TOLERANCE_DEG,
            tool_radius: 0.0,
            deviation_range: (0.0, 1.0),
            curvature_range,
            curvature_over_curved_part,
            background: Vec3::new(0.06, 0.07, 0.09),
            prepared_kernels: true,
            boundaries: false,
            isolines: 0,
            sections: None,
            edges: false,
            light: None,
            bounds: (center, radius),
            tess_deviation: deviation,
            early_depth: true,
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// The paper's design for shaders without loops: raises every patch whose
    /// degree lies below a prepared degree (3 or 5) to the nearest one above
    /// it by exact degree elevation, so that the prepared kernels evaluate it.
    /// The surfaces, their parameterisation and so the tessellation stay the
    /// same. Returns how many patches were elevated.
    pub fn elevate_to_prepared(&mut self) -> usize {
        let mut count = 0;
        for s in &mut self.surfaces {
            let (Some(pu), Some(pv)) = (prepared_degree_for(s.degree_u), prepared_degree_for(s.degree_v)) else {
                continue;
            };
            if (pu, pv) == (s.degree_u, s.degree_v) {
                continue;
            }
            while s.degree_u < pu {
                *s = s.elevate(true);
            }
            while s.degree_v < pv {
                *s = s.elevate(false);
            }
            count += 1;
        }
        if count > 0 {
            // trims stay: elevation keeps the parameterisation
            let (width, trims) = (self.packed.trim_width, std::mem::take(&mut self.packed.trims));
            let colors = std::mem::take(&mut self.packed.colors);
            let simplified = std::mem::take(&mut self.packed.trims_simplified);
            let deviation = (self.packed.deviation_width, std::mem::take(&mut self.packed.deviation));
            let edges = (self.packed.edges_width, std::mem::take(&mut self.packed.edges));
            self.packed = PackedNurbs::new(&self.surfaces);
            self.packed.trim_width = width;
            self.packed.trims = trims;
            self.packed.colors = colors;
            self.packed.trims_simplified = simplified;
            (self.packed.deviation_width, self.packed.deviation) = deviation;
            (self.packed.edges_width, self.packed.edges) = edges;
            self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        count
    }

    /// The up axis `Auto` resolves to: for a flat model (its thinnest extent
    /// under half the middle one) the axis of that extent, else +Z.
    pub fn detect_up(&self) -> UpAxis {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for v in &self.vertices {
            for t in 0..3 {
                lo[t] = lo[t].min(v.position[t]);
                hi[t] = hi[t].max(v.position[t]);
            }
        }
        let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        if !ext.iter().all(|e| e.is_finite()) {
            return UpAxis::Axis(2, false);
        }
        // a flat part (its thinnest extent under half the middle one) lies on
        // its largest face; anything else stands on Z, the usual CAD convention
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| ext[a].total_cmp(&ext[b]));
        let k = if ext[order[0]] < 0.5 * ext[order[1]] { order[0] } else { 2 };
        UpAxis::Axis(k, false)
    }

    /// A camera showing the whole model from `view`, fitted into the window
    /// `[x0, x1] × [y0, y1]` of normalised device coordinates of a frame of
    /// `aspect` (width / height), with the same field of view as
    /// [`PreparedNurbs::camera`]. Falls back to that camera if the model has
    /// no finite vertex.
    pub fn view_camera(&self, view: &ModelView, aspect: f32, window: [f32; 4]) -> Camera {
        let up = match view.up {
            UpAxis::Auto => self.detect_up(),
            a => a,
        };
        let UpAxis::Axis(k, neg) = up else { return self.camera };
        let k = k.min(2);
        let unit = |i: usize| Vec3::from_array(std::array::from_fn(|t| if t == i % 3 { 1.0 } else { 0.0 }));
        // (a, b, up) right-handed: Z-up gives (X, Y, Z)
        let sign = if neg { -1.0 } else { 1.0 };
        let (a, b, u) = (unit(k + 1) * sign, unit(k + 2), unit(k) * sign);
        let az = (ModelView::AZIMUTH_DEG + view.turn_deg).to_radians();
        let el = view.elevation_deg.clamp(-89.0, 89.0).to_radians();
        let toward = (a * az.sin() - b * az.cos()) * el.cos() + u * el.sin();
        let points: Vec<Vec3> = self.vertices.iter().map(|v| Vec3::from_array(v.position)).collect();
        Camera::framing(&points, toward, u, self.camera.fov_y_deg, aspect, window).unwrap_or(self.camera)
    }

    /// The margin of the conservative early depth test: how much nearer
    /// than its triangle a fragment's exact point may lie — the
    /// tessellation's deviation, with half as much again for the estimate
    /// (taken at cell centres) and a hair of the model's size.
    pub fn early_depth_margin(&self) -> f32 {
        1.5 * self.tess_deviation + 1e-5 * self.bounds.1
    }

    /// Gives patches their albedo for the shaded mode (see [`PackedNurbs::set_colors`]).
    pub fn set_colors(&mut self, colors: &[Option<[f32; 3]>]) {
        self.packed.set_colors(colors);
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Gives patches polylines to draw over the display mode (see
    /// [`PackedNurbs::set_edges`]) and turns the overlay on.
    pub fn set_edges(&mut self, runs: &[Vec<EdgeRun>]) {
        self.packed.set_edges(runs);
        self.edges = true;
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Gives patches a deviation grid for the deviation mode (see
    /// [`PackedNurbs::set_deviation`]; [`hitex_core::nurbs::deviation::deviation_grid`]
    /// computes one).
    pub fn set_deviation(&mut self, grid: usize, values: &[Vec<f32>]) {
        self.packed.set_deviation(grid, values);
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Trims patches by loops in their parameter space (see [`PackedNurbs::set_trims`]).
    pub fn set_trims(&mut self, trims: &[TrimLoops]) {
        self.packed.set_trims(trims);
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Identity of the uploaded content (geometry and packed textures).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Frame uniforms for `camera` at `width`×`height`.
    pub fn frame(&self, camera: &Camera, width: u32, height: u32) -> NurbsFrame {
        let vp: Mat4 = camera.view_proj(width as f32 / height as f32);
        // light over the viewer's shoulder
        let view_dir = (camera.target - camera.position).normalize();
        let right = view_dir.cross(camera.up).normalize_or_zero();
        let light = self
            .light
            .and_then(|l| l.try_normalize())
            .unwrap_or_else(|| (-view_dir + right * 0.4 + camera.up.normalize() * 0.6).normalize());
        let range = self.curvature_range[self.curvature_slot()];
        let sections = self
            .sections
            .and_then(|(n, spacing)| (spacing > 0.0 && spacing.is_finite()).then(|| n.normalize_or_zero() / spacing))
            .filter(|a| a.is_finite() && *a != Vec3::ZERO);
        let flags = if self.prepared_kernels { flag::PREPARED } else { 0 }
            | if self.boundaries { flag::BOUNDARIES } else { 0 }
            | if self.isolines > 0 { flag::ISOLINES } else { 0 }
            | if sections.is_some() { flag::SECTIONS } else { 0 }
            | if self.edges { flag::EDGES } else { 0 };
        NurbsFrame {
            view_proj: vp.to_cols_array_2d(),
            camera: camera.position.extend(1.0).to_array(),
            light: light.extend(0.0).to_array(),
            params: [self.mode.index(), self.bands, self.stripes, flags],
            ranges: if self.mode == NurbsMode::Deviation {
                [self.deviation_range.0, self.deviation_range.1, 0.12, 1.0 / self.effective_tool_radius()]
            } else {
                [-range, range, 0.12, 1.0 / self.effective_tool_radius()]
            },
            background: self.background.extend(1.0).to_array(),
            model: self.bounds.0.extend(self.bounds.1).to_array(),
            pull: self.pull.normalize_or(Vec3::Z).extend(self.draft_tolerance_deg.to_radians().sin()).to_array(),
            lines: sections.unwrap_or(Vec3::ZERO).extend(self.isolines as f32).to_array(),
            up: camera.up.normalize_or(Vec3::Z).extend(0.0).to_array(),
        }
    }

    /// Which [`PreparedNurbs::curvature_range`] the display mode's ramp
    /// uses: 0 Gaussian, 2 principal, 1 mean (and every other mode).
    pub fn curvature_slot(&self) -> usize {
        match self.mode {
            NurbsMode::Gauss => 0,
            NurbsMode::K1 | NurbsMode::K2 => 2,
            _ => 1,
        }
    }

    /// The radius mode's tool radius: as set, else 1/50 of the model's
    /// bounding diameter.
    pub fn effective_tool_radius(&self) -> f32 {
        if self.tool_radius > 0.0 && self.tool_radius.is_finite() {
            self.tool_radius
        } else {
            (self.bounds.1 / 25.0).max(f32::MIN_POSITIVE)
        }
    }

    /// Number of patches.
    pub fn patch_count(&self) -> usize {
        self.surfaces.len()
    }
}
