//! The NURBS fragment program. Twin of `shaders/nurbs.wgsl`: same packed
//! inputs (knot and control-point textures), same steps, same order.
//!
//! Per fragment: find the knot spans (binary search), the basis functions and
//! their derivatives by the paper's triangular scheme, the homogeneous sums
//! over the (p+1)×(q+1) control points, the rational quotient rule, the exact
//! normal (with the interpolated tessellation normal as fallback where
//! `S_u × S_v` vanishes), the display mode, and the depth of the exact point.

// index loops mirror the shader's loops over spans
#![allow(clippy::needless_range_loop)]

use super::raster::{Block, BlockShader};
use super::simd::{self, LANES, Lanes, V3};
use crate::nurbs::mode_index::*;
use crate::nurbs::{ISOLINE_RGB, NurbsFrame, NurbsVertex, PackedNurbs, SECTION_RGB, flag};
use glam::{Mat4, Vec3, Vec4};
use hitex_core::nurbs::{basis_ders_fixed, basis_ders_paper, find_span};

mod block;
pub use block::{BlockPointNormal, eval_bicubic_block};

/// Varyings: tessellation normal (3), u, v, patch.
pub const VARYINGS: usize = 6;

/// The varyings of a tessellation vertex, in the order of `VsOut` in the shader.
pub fn varyings(v: &NurbsVertex) -> [f32; VARYINGS] {
    [v.normal[0], v.normal[1], v.normal[2], v.uv[0], v.uv[1], v.patch]
}

/// Exact surface values at a parameter.
#[derive(Debug, Clone, Copy, Default)]
pub struct Eval {
    /// S
    pub s: Vec3,
    /// ∂S/∂u
    pub su: Vec3,
    /// ∂S/∂v
    pub sv: Vec3,
    /// ∂²S/∂u²
    pub suu: Vec3,
    /// ∂²S/∂u∂v
    pub suv: Vec3,
    /// ∂²S/∂v²
    pub svv: Vec3,
}

/// Evaluates patch `patch` of the packed textures at (u, v) in f32, with
/// second derivatives when `second` is set. `prepared` selects the
/// straight-line kernels of the prepared degree (bicubic, the paper's design)
/// for patches of that degree; other patches take the any-degree loops.
pub fn eval_packed(t: &PackedNurbs, patch: usize, u: f32, v: f32, second: bool, prepared: bool) -> Eval {
    // patch header
    let kw = t.knot_width as usize;
    let cw = t.cp_width as usize;
    let head = t.control[patch * cw];
    let (p, q, nu, nv) = (head[0] as usize, head[1] as usize, head[2] as usize, head[3] as usize);
    let cu = t.knots_u[patch * kw] as usize;
    let cv = t.knots_v[patch * kw] as usize;
    let ku = &t.knots_u[patch * kw + 1..patch * kw + 1 + cu];
    let kv = &t.knots_v[patch * kw + 1..patch * kw + 1 + cv];
    let cp = &t.control[patch * cw + 1..patch * cw + 1 + nu * nv];
    // clamp into the domain
    let u = u.max(ku[p]).min(ku[nu]);
    let v = v.max(kv[q]).min(kv[nv]);
    // find knot span
    let su = find_span(nu - 1, p, u, ku);
    let sv = find_span(nv - 1, q, v, kv);
    // basis functions and derivatives (paper's form), then the homogeneous sums
    // the prepared degrees (3 and 5) take straight-line kernels, the others the loops
    let a = match (prepared, p, q) {
        (true, 3, 3) => fixed::<3, 4, 3, 4>(su, sv, u, v, ku, kv, cp, nu, second),
        (true, 3, 5) => fixed::<3, 4, 5, 6>(su, sv, u, v, ku, kv, cp, nu, second),
        (true, 5, 3) => fixed::<5, 6, 3, 4>(su, sv, u, v, ku, kv, cp, nu, second),
        (true, 5, 5) => fixed::<5, 6, 5, 6>(su, sv, u, v, ku, kv, cp, nu, second),
        _ => {
            let bu = basis_ders_paper(su, u, p, ku, second);
            let bv = basis_ders_paper(sv, v, q, kv, second);
            sums(&bu, &bv, p + 1, q + 1, cp, nu, su - p, sv - q, second)
        }
    };
    // rational quotient rule, with one division (1/w) for every term
    let rw = 1.0 / a[0].w;
    let s = a[0].truncate() * rw;
    let s_u = (a[1].truncate() - s * a[1].w) * rw;
    let s_v = (a[2].truncate() - s * a[2].w) * rw;
    let mut e = Eval { s, su: s_u, sv: s_v, ..Default::default() };
    if second {
        e.suu = (a[3].truncate() - s_u * (2.0 * a[1].w) - s * a[3].w) * rw;
        e.suv = (a[4].truncate() - s_u * a[2].w - s_v * a[1].w - s * a[4].w) * rw;
        e.svv = (a[5].truncate() - s_v * (2.0 * a[2].w) - s * a[5].w) * rw;
    }
    e
}

/// Basis and sums for prepared degrees `P`×`Q` (`A = P + 1`, `B = Q + 1`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn fixed<const P: usize, const A: usize, const Q: usize, const B: usize>(
    su: usize,
    sv: usize,
    u: f32,
    v: f32,
    ku: &[f32],
    kv: &[f32],
    cp: &[[f32; 4]],
    nu: usize,
    second: bool,
) -> [Vec4; 6] {
    let bu = basis_ders_fixed::<f32, P, A>(su, u, ku, second);
    let bv = basis_ders_fixed::<f32, Q, B>(sv, v, kv, second);
    sums::<A, B>(&bu, &bv, A, B, cp, nu, su - P, sv - Q, second)
}

/// Homogeneous sums A, A_u, A_v (and A_uu, A_uv, A_vv) over the `nr`×`ns`
/// control points from (i0, j0).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sums<const A: usize, const B: usize>(
    bu: &[[f32; A]; 3],
    bv: &[[f32; B]; 3],
    nr: usize,
    ns: usize,
    cp: &[[f32; 4]],
    nu: usize,
    i0: usize,
    j0: usize,
    second: bool,
) -> [Vec4; 6] {
    let mut a = [Vec4::ZERO; 6]; // A, A_u, A_v, A_uu, A_uv, A_vv (xyz = w·P, w)
    for s in 0..ns.min(B) {
        let row = (j0 + s) * nu + i0;
        let (mut t0, mut t1, mut t2) = (Vec4::ZERO, Vec4::ZERO, Vec4::ZERO);
        for r in 0..nr.min(A) {
            let c = Vec4::from_array(cp[row + r]);
            t0 += c * bu[0][r];
            t1 += c * bu[1][r];
            if second {
                t2 += c * bu[2][r];
            }
        }
        a[0] += t0 * bv[0][s];
        a[1] += t1 * bv[0][s];
        a[2] += t0 * bv[1][s];
        if second {
            a[3] += t2 * bv[0][s];
            a[4] += t1 * bv[1][s];
            a[5] += t0 * bv[2][s];
        }
    }
    a
}

/// The shaded mode's default albedo (linear RGB).
pub const DEFAULT_ALBEDO: [f32; 3] = [0.72, 0.75, 0.80];

/// A patch's albedo: its colour where the model gives one, else the default.
pub fn albedo(t: &PackedNurbs, patch: usize) -> Vec3 {
    match t.trims.get(patch * t.trim_width as usize) {
        Some(h) if h[1] >= 0.0 => Vec3::new(h[1], h[2], h[3]),
        _ => Vec3::from_array(DEFAULT_ALBEDO),
    }
}

/// Whether (u, v) is cut away by the patch's trimming loops (even–odd rule
/// over all edges; untrimmed patches keep everything).
pub fn trimmed_away(t: &PackedNurbs, patch: usize, u: f32, v: f32) -> bool {
    let w = t.trim_width as usize;
    let n = t.trims[patch * w][0] as usize;
    if n == 0 {
        return false;
    }
    let mut inside = false;
    for e in &t.trims[patch * w + 1..patch * w + 1 + n] {
        if (e[1] > v) != (e[3] > v) {
            let x = e[0] + (v - e[1]) * (e[2] - e[0]) / (e[3] - e[1]);
            if u < x {
                inside = !inside;
            }
        }
    }
    !inside
}

/// How far beyond its patch's boundary (the domain's sides or a trimming
/// loop) a fragment is still drawn, in pixels. The trimming loops of two
/// faces meeting along an edge are different polylines of one curve; drawing
/// each face a little past its loop, behind the other ([`Reach::Seam`]),
/// closes the seam without a pinhole while an open edge grows by less than a
/// pixel. (Untrimmed sides are closed by the tessellation's boundary fans
/// instead.) Past a domain side the distance is the parameter's overshoot in
/// units of its fwidth; past a trimming loop it is the distance on screen to
/// the nearest trimming edge, through the inverse of the (u, v) Jacobian, so
/// that it stays under a pixel however obliquely the surface is seen (scaling
/// u and v by their fwidths let a foreshortened face reach several pixels
/// sideways past its loop). Fragments past the domain show the boundary point
/// (their parameters are clamped); past a trimming loop, the untrimmed surface
/// just beyond it.
pub const SEAM_REACH: f32 = 0.75;

/// The parameter domain `[u0, u1] × [v0, v1]` of a packed patch.
fn domain(t: &PackedNurbs, patch: usize) -> (f32, f32, f32, f32) {
    let (kw, cw) = (t.knot_width as usize, t.cp_width as usize);
    let head = t.control[patch * cw];
    let (p, q, nu, nv) = (head[0] as usize, head[1] as usize, head[2] as usize, head[3] as usize);
    (
        t.knots_u[patch * kw + 1 + p],
        t.knots_u[patch * kw + 1 + nu],
        t.knots_v[patch * kw + 1 + q],
        t.knots_v[patch * kw + 1 + nv],
    )
}

/// Where a fragment lies against its patch's boundary (see [`SEAM_REACH`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reach {
    /// Within the domain and the trimming loops.
    Inside,
    /// Past the boundary, within the seam reach: drawn, behind any surface
    /// that truly covers the pixel.
    Seam,
    /// Farther past the boundary: discarded.
    Cut,
}

/// How far past its patch's boundary the fragment at (u, v) lies, whose
/// parameters have the screen derivatives `g`: beyond the domain by more
/// than [`SEAM_REACH`] fwidths, or trimmed away and farther than
/// [`SEAM_REACH`] pixels on screen from every trimming edge, is
/// [`Reach::Cut`].
pub fn reach(t: &PackedNurbs, patch: usize, u: f32, v: f32, g: &UvGrad) -> Reach {
    let (fu, fv) = (g[0].abs() + g[1].abs(), g[2].abs() + g[3].abs());
    let (u0, u1, v0, v1) = domain(t, patch);
    let (ou, ov) = ((u0 - u).max(u - u1), (v0 - v).max(v - v1));
    if ou > SEAM_REACH * fu || ov > SEAM_REACH * fv {
        return Reach::Cut;
    }
    if trimmed_away(t, patch, u, v) {
        return if near_trim(t, patch, u, v, g) { Reach::Seam } else { Reach::Cut };
    }
    if ou > 0.0 || ov > 0.0 { Reach::Seam } else { Reach::Inside }
}

/// Whether a fragment's patch varying carries the boundary-fan mark
/// ([`crate::nurbs::FAN_MARK`]): fans close seams and are drawn as seam fragments.
#[inline(always)]
fn is_fan(patch: f32) -> bool {
    (patch - patch.round()).abs() > 0.125
}

/// Seam fragments are drawn as if 0.5 % farther from the eye, so that the
/// neighbour's own fragments win where they exist.
pub const SEAM_DEPTH_SCALE: f32 = 1.005;

/// The map from a parameter offset (du, dv) to its screen offset in units of
/// `r` pixels, `[xu, xv, yu, yv]`: the inverse of the Jacobian `g` (which
/// maps (dx, dy) to (du, dv)) over `r`, to first order. `None` where `g` is
/// singular (u and v vary along one screen direction only, as on a boundary
/// fan lying on a parameter line) or not finite: |det·r| outside
/// (10⁻³⁰, 10³⁰), the test `nurbs.wgsl` makes too.
#[inline]
pub fn to_pixels(g: &UvGrad, r: f32) -> Option<[f32; 4]> {
    let dr = (g[0] * g[3] - g[1] * g[2]) * r;
    (dr.abs() > 1e-30 && dr.abs() < 1e30).then(|| {
        let s = 1.0 / dr;
        [g[3] * s, -g[1] * s, -g[2] * s, g[0] * s]
    })
}

/// Squared screen distance, in the units of `m` ([`to_pixels`]), from the
/// fragment at (u, v) to the parameter-space segment `e` (x0, y0, x1, y1).
#[inline]
fn segment_d2(m: &[f32; 4], e: &[f32; 4], u: f32, v: f32) -> f32 {
    let (pu, pv) = (e[0] - u, e[1] - v);
    let (qu, qv) = (e[2] - e[0], e[3] - e[1]);
    let (ax, ay) = (m[0] * pu + m[1] * pv, m[2] * pu + m[3] * pv);
    let (dx, dy) = (m[0] * qu + m[1] * qv, m[2] * qu + m[3] * qv);
    let dd = dx * dx + dy * dy;
    let k = if dd > 0.0 { (-(ax * dx + ay * dy) / dd).clamp(0.0, 1.0) } else { 0.0 };
    let (px, py) = (ax + k * dx, ay + k * dy);
    px * px + py * py
}

/// Whether a trimming edge of the patch passes within [`SEAM_REACH`] pixels
/// of (u, v) on screen (parameters' screen derivatives `g`).
fn near_trim(t: &PackedNurbs, patch: usize, u: f32, v: f32, g: &UvGrad) -> bool {
    let Some(m) = to_pixels(g, SEAM_REACH) else { return false };
    let w = t.trim_width as usize;
    let n = t.trims[patch * w][0] as usize;
    t.trims[patch * w + 1..patch * w + 1 + n].iter().any(|e| segment_d2(&m, e, u, v) <= 1.0)
}

/// Half the width of drawn edges, in pixels on screen.
pub const EDGE_REACH: f32 = 1.5;

/// The colour (output-encoded) of the nearest drawn edge within
/// [`EDGE_REACH`] pixels on screen of (u, v) on `patch` (parameters' screen
/// derivatives `g`), if any (twin of `on_edge` in `nurbs.wgsl`).
pub fn on_edge(t: &PackedNurbs, patch: usize, u: f32, v: f32, g: &UvGrad) -> Option<[f32; 3]> {
    let m = to_pixels(g, EDGE_REACH)?;
    let w = t.edges_width as usize;
    let row = t.edges.get(patch * w..(patch + 1) * w)?;
    let n = (row[0][0] as usize).min((w - 1) / 2);
    let mut best = (2.0f32, None);
    for i in 0..n {
        let d2 = segment_d2(&m, &row[1 + 2 * i], u, v);
        if d2 <= 1.0 && d2 < best.0 {
            let c = row[2 + 2 * i];
            best = (d2, Some([c[0], c[1], c[2]]));
        }
    }
    best.1
}

/// Screen derivatives of (u, v) at a fragment: `[∂u/∂x, ∂u/∂y, ∂v/∂x, ∂v/∂y]`.
pub type UvGrad = [f32; 4];

/// The (u, v) derivatives of a lane of a lane-packed block (the program's
/// [`BlockShader::LANE_GRADS`] are u and v: WGSL `dpdxFine`, `dpdyFine` of its quad).
#[inline(always)]
fn lane_grad(b: &Block<VARYINGS>, lane: usize) -> UvGrad {
    [b.grad[0][0][lane], b.grad[0][1][lane], b.grad[1][0][lane], b.grad[1][1][lane]]
}

/// A packed patch's degrees, control-point counts, knots and control points.
struct PatchRef<'t> {
    p: usize,
    q: usize,
    nu: usize,
    nv: usize,
    ku: &'t [f32],
    kv: &'t [f32],
    cp: &'t [[f32; 4]],
}

/// The rows of patch `patch` of the packed textures.
#[inline(always)]
fn patch_ref(t: &PackedNurbs, patch: usize) -> PatchRef<'_> {
    let (kw, cw) = (t.knot_width as usize, t.cp_width as usize);
    let head = t.control[patch * cw];
    let (p, q, nu, nv) = (head[0] as usize, head[1] as usize, head[2] as usize, head[3] as usize);
    PatchRef {
        p,
        q,
        nu,
        nv,
        ku: &t.knots_u[patch * kw + 1..patch * kw + 1 + t.knots_u[patch * kw] as usize],
        kv: &t.knots_v[patch * kw + 1..patch * kw + 1 + t.knots_v[patch * kw] as usize],
        cp: &t.control[patch * cw + 1..patch * cw + 1 + nu * nv],
    }
}

/// Distance of `x` to the nearest whole number (`floor(x + 0.5)`, as the shader).
#[inline]
fn off_whole(x: f32) -> f32 {
    (x - (x + 0.5).floor()).abs()
}

/// Whether (u, v) lies on one of `n` isoparametric lines per direction of
/// its patch (equal steps of the domain, edges included), within half a
/// pixel (`fu`, `fv` = fwidth).
fn on_isoline(t: &PackedNurbs, patch: usize, u: f32, v: f32, fu: f32, fv: f32, n: f32) -> bool {
    let (u0, u1, v0, v1) = domain(t, patch);
    let (su, sv) = ((u1 - u0) / n, (v1 - v0) / n);
    off_whole((u - u0) / su) * su < 0.5 * fu || off_whole((v - v0) / sv) * sv < 0.5 * fv
}

/// Whether the exact point lies on a section plane `P·a = k` (a = unit
/// normal / spacing) within half a pixel: the width of `P·a` on screen
/// from the exact partials and the (u, v) derivatives.
fn on_section(e: &Eval, a: Vec3, g: &UvGrad) -> bool {
    let (s, su, sv) = (e.s.dot(a), e.su.dot(a), e.sv.dot(a));
    let width = (su * g[0] + sv * g[2]).abs() + (su * g[1] + sv * g[3]).abs();
    off_whole(s) < 0.5 * width
}

/// Unit normal `S_u × S_v`, or `fallback` where the cross product vanishes
/// against the size of the partials (collapsed rows, apexes).
pub fn exact_normal(e: &Eval, fallback: Vec3) -> Vec3 {
    let n = e.su.cross(e.sv);
    let scale = e.su.length() + e.sv.length();
    if n.length() > 1e-6 * scale * scale && n.is_finite() { n.normalize() } else { fallback.normalize_or(Vec3::Z) }
}

/// Curvatures (Gaussian, mean) from the fundamental forms.
pub fn curvatures(e: &Eval, n: Vec3) -> (f32, f32) {
    let (ee, ff, gg) = (e.su.dot(e.su), e.su.dot(e.sv), e.sv.dot(e.sv));
    let (l, m, nn) = (e.suu.dot(n), e.suv.dot(n), e.svv.dot(n));
    let det = ee * gg - ff * ff;
    if det.abs() <= 1e-30 || !det.is_finite() {
        return (0.0, 0.0);
    }
    ((l * nn - m * m) / det, (ee * nn - 2.0 * ff * m + gg * l) / (2.0 * det))
}

/// Principal curvatures (κ1 ≥ κ2) from (Gaussian, mean): H ± √(H² − K).
pub fn principal((k, h): (f32, f32)) -> (f32, f32) {
    let r = (h * h - k).max(0.0).sqrt();
    (h + r, h - r)
}

/// Diverging ramp: blue (−1) → white (0) → red (+1).
pub fn diverging(t: f32) -> Vec3 {
    let t = if t.is_nan() { 0.0 } else { t.clamp(-1.0, 1.0) };
    let white = Vec3::splat(0.97);
    if t < 0.0 { white.lerp(Vec3::new(0.12, 0.28, 0.85), -t) } else { white.lerp(Vec3::new(0.85, 0.15, 0.12), t) }
}

/// Isophote band colour: alternating bands of the angle between n and l.
pub fn isophote(n: Vec3, l: Vec3, bands: u32) -> Vec3 {
    let angle = n.dot(l).clamp(-1.0, 1.0).acos();
    let band = (angle / std::f32::consts::PI * bands as f32).floor() as i32;
    if band % 2 == 0 { Vec3::new(0.95, 0.85, 0.32) } else { Vec3::new(0.10, 0.12, 0.20) }
}

/// Draft-mode colours (output-encoded): positive draft beyond the
/// tolerance, within the tolerance, negative beyond it.
pub const DRAFT_COLORS: [[f32; 3]; 3] = [[0.20, 0.72, 0.30], [0.96, 0.80, 0.16], [0.86, 0.18, 0.15]];

/// Draft: the class of the angle between the surface and the pull
/// direction `pull.xyz` (sin α = n·d with `facing` the surface's own normal;
/// `pull.w` = sin of the tolerance), shaded by `n` (two-sided) so that the
/// shape stays readable.
pub fn draft(facing: Vec3, n: Vec3, light: Vec3, pull: Vec4) -> Vec3 {
    let s = facing.dot(pull.truncate());
    let class = if s > pull.w {
        0
    } else if s < -pull.w {
        2
    } else {
        1
    };
    Vec3::from_array(DRAFT_COLORS[class]) * (0.3 + 0.7 * n.dot(light).abs())
}

/// Radius-mode colours (output-encoded): concave tighter than the tool,
/// concave with a radius from R to 100 R, convex or flat.
pub const RADIUS_COLORS: [[f32; 3]; 3] = [[0.86, 0.18, 0.15], [0.30, 0.50, 0.90], [0.72, 0.75, 0.80]];

/// Radius mode: the largest principal curvature κ1 towards `facing` (the
/// surface's own normal: positive κ bends towards the side the normal
/// points to, where a tool comes from) against `1/R` = `inv_radius`,
/// shaded by `n` (two-sided). Radii beyond 100 R count as flat, so that a
/// cylinder's straight direction does not flicker on rounding.
pub fn reach_class(e: &Eval, facing: Vec3, n: Vec3, light: Vec3, inv_radius: f32) -> Vec3 {
    let (k1, _) = principal(curvatures(e, facing));
    let class = if k1 > inv_radius {
        0
    } else if k1 > 0.01 * inv_radius {
        1
    } else {
        2
    };
    Vec3::from_array(RADIUS_COLORS[class]) * (0.3 + 0.7 * n.dot(light).abs())
}

/// Deviation-mode colours (output-encoded): within the tolerance; the
/// outside ramp from the tolerance to the range; the inside ramp likewise;
/// no reference near.
pub const DEVIATION_COLORS: [[f32; 3]; 6] = [
    [0.20, 0.72, 0.30],
    [0.96, 0.86, 0.20],
    [0.86, 0.18, 0.15],
    [0.45, 0.85, 0.90],
    [0.12, 0.28, 0.85],
    [0.42, 0.42, 0.45],
];

/// The deviation mode's colour of a signed deviation `d` (unshaded): green
/// within ± `tol`, yellow → red from `tol` to `range` outside the surface,
/// cyan → blue inside, saturated beyond; grey for no data.
pub fn deviation_base(d: f32, tol: f32, range: f32) -> Vec3 {
    let k = DEVIATION_COLORS.map(Vec3::from_array);
    if hitex_core::nurbs::deviation::is_no_data(d) {
        return k[5];
    }
    let a = d.abs();
    if a <= tol {
        return k[0];
    }
    let span = range - tol;
    let t = if span > 0.0 { ((a - tol) / span).clamp(0.0, 1.0) } else { 1.0 };
    if d > 0.0 { k[1] + (k[2] - k[1]) * t } else { k[3] + (k[4] - k[3]) * t }
}

/// The patch's deviation grid at (u, v): bilinear between its four nodes
/// over the patch's domain, `NO_DATA` where one has none or the patch has
/// no grid (twin of `deviation_at` in `nurbs.wgsl`).
pub fn deviation_at(t: &PackedNurbs, patch: usize, u: f32, v: f32) -> f32 {
    use hitex_core::nurbs::deviation::{NO_DATA, is_no_data};
    let w = t.deviation_width as usize;
    let Some(row) = t.deviation.get(patch * w..(patch + 1) * w) else { return NO_DATA };
    let g = row[0] as usize;
    if g < 2 || g * g + 1 > w {
        return NO_DATA;
    }
    let (u0, u1, v0, v1) = domain(t, patch);
    let s = if u1 > u0 { ((u - u0) / (u1 - u0)).clamp(0.0, 1.0) * (g - 1) as f32 } else { 0.0 };
    let r = if v1 > v0 { ((v - v0) / (v1 - v0)).clamp(0.0, 1.0) * (g - 1) as f32 } else { 0.0 };
    let (i, j) = ((s.floor() as usize).min(g - 2), (r.floor() as usize).min(g - 2));
    let (a, b) = (s - i as f32, r - j as f32);
    let c = [row[1 + j * g + i], row[2 + j * g + i], row[1 + (j + 1) * g + i], row[2 + (j + 1) * g + i]];
    if c.iter().any(|&x| is_no_data(x)) {
        return NO_DATA;
    }
    let top = c[0] + (c[1] - c[0]) * a;
    let bottom = c[2] + (c[3] - c[2]) * a;
    top + (bottom - top) * b
}

/// The studio's soft boxes: elevation of the centre, half height, half
/// width in azimuth (degrees, azimuth 0 straight behind the viewer), and
/// brightness: three overhead, two dimmer ones low on the floor's cove
/// (which vertical walls seen from above reflect).
const SOFT_BOXES: [[f32; 4]; 5] = [
    [15.0, 6.0, 70.0, 1.0],
    [40.0, 6.0, 55.0, 1.0],
    [65.0, 6.0, 40.0, 1.0],
    [-20.0, 5.0, 80.0, 0.6],
    [-45.0, 5.0, 60.0, 0.45],
];

/// How much of a light whose extent along one angle is `c ± half` covers
/// `x`: 1 inside, 0 outside, a linear ramp 1.5° wide across its edge.
fn coverage(x: f32, c: f32, half: f32) -> f32 {
    ((half - (x - c).abs()) / 1.5 + 0.5).clamp(0.0, 1.0)
}

/// Reflection mode: the radiance (linear) a mirror at normal `n` shows the
/// eye at `view` (unit, towards the eye) of a procedural studio: three
/// horizontal soft boxes behind and above the viewer, two dimmer ones
/// below the horizon, a vertical one at its side, a sky graded towards the
/// zenith and a dark floor; `forward`
/// is the viewer's horizontal looking direction (azimuths are measured from
/// its opposite), `up` the model's up axis.
pub fn studio(n: Vec3, view: Vec3, forward: Vec3, up: Vec3) -> f32 {
    let r = n * (2.0 * n.dot(view)) - view;
    let elevation = r.dot(up).clamp(-1.0, 1.0).asin().to_degrees();
    // azimuth in the horizontal plane, 0 straight behind the viewer
    let back = -(forward - up * forward.dot(up)).normalize_or(Vec3::X);
    let side = up.cross(back);
    let azimuth = r.dot(side).atan2(r.dot(back)).to_degrees();
    let mut light = if elevation < 0.0 { 0.03 } else { 0.08 + 0.17 * elevation / 90.0 };
    for b in SOFT_BOXES {
        light = light.max(b[3] * coverage(elevation, b[0], b[1]) * coverage(azimuth, 0.0, b[2]));
    }
    // the side light: a tall strip at azimuth 100°
    light.max(0.8 * coverage(elevation, 25.0, 35.0) * coverage(azimuth, 100.0, 5.0))
}

/// Zebra: the reflected view ray against horizontal light bars.
pub fn zebra(n: Vec3, view: Vec3, up: Vec3, stripes: u32) -> Vec3 {
    let r = n * (2.0 * n.dot(view)) - view;
    let elevation = r.dot(up).clamp(-1.0, 1.0).asin();
    let k = ((elevation / std::f32::consts::PI + 0.5) * stripes as f32).floor() as i32;
    if k % 2 == 0 { Vec3::splat(0.96) } else { Vec3::splat(0.05) }
}

/// Highlight lines: the normal line through `p` meets the plane of light
/// lines (normal `e`, through `origin`), and the stripe is read across the lines.
pub fn highlight(p: Vec3, n: Vec3, e: Vec3, origin: Vec3, spacing: f32) -> Vec3 {
    let en = e.dot(n);
    if en.abs() < 1e-4 {
        return Vec3::splat(0.05);
    }
    let t = (e.dot(origin) - e.dot(p)) / en;
    let x = p + n * t;
    // lines run along d, stripes are counted along c
    let d = if e.cross(Vec3::Z).length() > 1e-3 { e.cross(Vec3::Z).normalize() } else { Vec3::X };
    let c = e.cross(d);
    let k = (c.dot(x - origin) / spacing).floor() as i32;
    if k.rem_euclid(2) == 0 { Vec3::new(0.95, 0.95, 0.9) } else { Vec3::new(0.08, 0.1, 0.16) }
}

/// `x⁴⁸` by five squarings and a product: the specular exponent of the
/// shaded mode (`pow(x, 48.0)` in `nurbs.wgsl`; the two differ by rounding).
#[inline(always)]
pub fn pow48(x: f32) -> f32 {
    let x2 = x * x;
    let x3 = x2 * x;
    let x6 = x3 * x3;
    let x12 = x6 * x6;
    let x24 = x12 * x12;
    x24 * x24
}

/// The program with its bindings.
pub struct NurbsProgram<'a> {
    frame: &'a NurbsFrame,
    packed: &'a PackedNurbs,
    view_proj: Mat4,
}

impl<'a> NurbsProgram<'a> {
    /// Binds the frame and the textures.
    pub fn new(frame: &'a NurbsFrame, packed: &'a PackedNurbs) -> Self {
        Self { frame, packed, view_proj: Mat4::from_cols_array_2d(&frame.view_proj) }
    }

    /// Whether (u, v) lies within one pixel (`fu`, `fv` = fwidth) of its
    /// patch's domain boundary.
    fn on_boundary(&self, v: &[f32; VARYINGS], fu: f32, fv: f32) -> bool {
        let t = self.packed;
        let patch = (v[5].round().max(0.0) as usize).min(t.patches.saturating_sub(1) as usize);
        let (u0, u1, v0, v1) = domain(t, patch);
        let du = (v[3] - u0).min(u1 - v[3]);
        let dv = (v[4] - v0).min(v1 - v[4]);
        du < fu || dv < fv
    }

    /// One fragment; `g`: the screen derivatives of u and v.
    fn lane(&self, v: &[f32; VARYINGS], g: &UvGrad) -> ([u8; 4], f32) {
        let f = self.frame;
        let (fu, fv) = (g[0].abs() + g[1].abs(), g[2].abs() + g[3].abs());
        let patch = (v[5].round().max(0.0) as usize).min(self.packed.patches.saturating_sub(1) as usize);
        let mode = f.params[0];
        // past the domain or trimmed away, beyond the seam reach: no colour, no depth (discarded)
        let mut at = reach(self.packed, patch, v[3], v[4], g);
        if at == Reach::Inside && is_fan(v[5]) {
            at = Reach::Seam;
        }
        if at == Reach::Cut {
            return ([0, 0, 0, 0], f32::NAN);
        }
        let second = matches!(mode, GAUSS | MEAN | RADIUS | K1 | K2);
        // exact point and derivatives
        let e = eval_packed(self.packed, patch, v[3], v[4], second, f.params[3] & 1 == 1);
        let vn = Vec3::new(v[0], v[1], v[2]);
        let mut n = exact_normal(&e, vn);
        // the surface's own orientation (Su × Sv), for the draft's sign
        let facing = n;
        // two-sided
        let cam = Vec3::new(f.camera[0], f.camera[1], f.camera[2]);
        let view = (cam - e.s).normalize_or_zero();
        if n.dot(view) < 0.0 {
            n = -n;
        }
        // depth of the exact point (of a seam fragment: pushed back)
        let at_depth = if at == Reach::Seam { cam + (e.s - cam) * SEAM_DEPTH_SCALE } else { e.s };
        let clip = self.view_proj * at_depth.extend(1.0);
        let depth = clip.z / clip.w;
        let light = Vec3::new(f.light[0], f.light[1], f.light[2]);
        let raw = |c: Vec3| {
            let q = |x: f32| (if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } * 255.0 + 0.5) as u8;
            [q(c.x), q(c.y), q(c.z), 255]
        };
        let rgba = match mode {
            ISOPHOTE => raw(isophote(n, light, f.params[1])),
            ZEBRA => raw(zebra(n, view, Vec3::new(f.up[0], f.up[1], f.up[2]), f.params[2])),
            REFLECTION => {
                let forward = Vec3::new(f.model[0] - cam.x, f.model[1] - cam.y, f.model[2] - cam.z);
                let l = 0.9 * studio(n, view, forward, Vec3::new(f.up[0], f.up[1], f.up[2]));
                let e = hitex_core::texture::linear_to_srgb_u8(l);
                [e, e, e, 255]
            }
            GAUSS | MEAN => {
                let (k, h) = curvatures(&e, n);
                let value = if mode == GAUSS { k } else { h };
                raw(diverging(value / f.ranges[1]))
            }
            VERTEX_NORMALS => {
                let mut m = vn.normalize_or(Vec3::Z);
                if m.dot(view) < 0.0 {
                    m = -m;
                }
                raw(isophote(m, light, f.params[1]))
            }
            NORMAL => raw(n * 0.5 + Vec3::splat(0.5)),
            K1 | K2 => {
                let (k1, k2) = principal(curvatures(&e, n));
                raw(diverging(if mode == K1 { k1 } else { k2 } / f.ranges[1]))
            }
            DRAFT => raw(draft(facing, n, light, Vec4::from_array(f.pull))),
            RADIUS => raw(reach_class(&e, facing, n, light, f.ranges[3])),
            DEVIATION => {
                let d = deviation_at(self.packed, patch, v[3], v[4]);
                raw(deviation_base(d, f.ranges[0], f.ranges[1]) * (0.3 + 0.7 * n.dot(light).abs()))
            }
            HIGHLIGHT => {
                let (c, r) = (Vec3::new(f.model[0], f.model[1], f.model[2]), f.model[3]);
                raw(highlight(e.s, n, light, c + light * (2.0 * r), 2.0 * r / f.params[2].max(1) as f32))
            }
            _ => {
                let albedo = albedo(self.packed, patch);
                let ndl = n.dot(light).max(0.0);
                let h = (light + view).normalize_or_zero();
                let spec = if ndl > 0.0 { 0.35 * pow48(n.dot(h).max(0.0)) } else { 0.0 };
                let c = albedo * (f.ranges[2] + ndl) + Vec3::splat(spec);
                let e = |x: f32| hitex_core::texture::linear_to_srgb_u8(x);
                [e(c.x), e(c.y), e(c.z), 255]
            }
        };
        let flags = f.params[3];
        let mut rgba = rgba;
        if flags & flag::ISOLINES != 0 && on_isoline(self.packed, patch, v[3], v[4], fu, fv, f.lines[3]) {
            rgba = [ISOLINE_RGB[0], ISOLINE_RGB[1], ISOLINE_RGB[2], 255];
        }
        if flags & flag::SECTIONS != 0 && on_section(&e, Vec3::new(f.lines[0], f.lines[1], f.lines[2]), g) {
            rgba = [SECTION_RGB[0], SECTION_RGB[1], SECTION_RGB[2], 255];
        }
        if flags & flag::EDGES != 0
            && let Some(c) = on_edge(self.packed, patch, v[3], v[4], g)
        {
            rgba = raw(Vec3::from_array(c));
        }
        (rgba, depth)
    }
}

impl BlockShader<VARYINGS> for NurbsProgram<'_> {
    const WRITES_DEPTH: bool = true;
    /// The program reads only the screen derivatives of u and v of a quad
    /// (seam reach, overlays): its lanes are packed one by one, whatever
    /// patch they lie on, and grouped by patch and knot spans when shaded.
    const LANE_GRADS: Option<[usize; 2]> = Some([3, 4]);

    #[inline(always)]
    fn shade_block(&self, b: &Block<VARYINGS>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes) {
        *depth = [f32::NAN; LANES];
        if self.block_bicubic(b, rgba, depth).is_some() {
            return;
        }

        // any degree, any mode: lane by lane
        let overlay = self.frame.params[3] & flag::BOUNDARIES != 0;
        let mut live = b.live;
        while live != 0 {
            let lane = live.trailing_zeros() as usize;
            live &= live - 1;
            let g = lane_grad(b, lane);
            let v: [f32; VARYINGS] = std::array::from_fn(|j| b.v[j][lane]);
            let (mut c, d) = self.lane(&v, &g);
            // fwidth of u and v (the boundary overlay)
            if overlay && self.on_boundary(&v, g[0].abs() + g[1].abs(), g[2].abs() + g[3].abs()) {
                c = [20, 20, 24, 255];
            }
            rgba[lane] = c;
            depth[lane] = d;
        }
    }
}

#[cfg(test)]
mod tests;
