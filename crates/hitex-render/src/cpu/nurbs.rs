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

use super::raster::QuadShader;
use crate::nurbs::{NurbsFrame, NurbsVertex, PackedNurbs};
use glam::{Mat4, Vec3, Vec4};
use hitex_core::nurbs::{basis_ders_fixed, basis_ders_paper, find_span};

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
    // rational quotient rule
    let w = a[0].w;
    let s = a[0].truncate() / w;
    let s_u = (a[1].truncate() - s * a[1].w) / w;
    let s_v = (a[2].truncate() - s * a[2].w) / w;
    let mut e = Eval { s, su: s_u, sv: s_v, ..Default::default() };
    if second {
        e.suu = (a[3].truncate() - s_u * (2.0 * a[1].w) - s * a[3].w) / w;
        e.suv = (a[4].truncate() - s_u * a[2].w - s_v * a[1].w - s * a[4].w) / w;
        e.svv = (a[5].truncate() - s_v * (2.0 * a[2].w) - s * a[5].w) / w;
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
        let (kw, cw) = (t.knot_width as usize, t.cp_width as usize);
        let head = t.control[patch * cw];
        let (p, q, nu, nv) = (head[0] as usize, head[1] as usize, head[2] as usize, head[3] as usize);
        let (u0, u1) = (t.knots_u[patch * kw + 1 + p], t.knots_u[patch * kw + 1 + nu]);
        let (v0, v1) = (t.knots_v[patch * kw + 1 + q], t.knots_v[patch * kw + 1 + nv]);
        let du = (v[3] - u0).min(u1 - v[3]);
        let dv = (v[4] - v0).min(v1 - v[4]);
        du < fu || dv < fv
    }

    fn lane(&self, v: &[f32; VARYINGS]) -> ([u8; 4], f32) {
        let f = self.frame;
        let patch = (v[5].round().max(0.0) as usize).min(self.packed.patches.saturating_sub(1) as usize);
        let mode = f.params[0];
        // trimmed away: no colour, no depth (discarded)
        if trimmed_away(self.packed, patch, v[3], v[4]) {
            return ([0, 0, 0, 0], f32::NAN);
        }
        let second = mode == 3 || mode == 4;
        // exact point and derivatives
        let e = eval_packed(self.packed, patch, v[3], v[4], second, f.params[3] & 1 == 1);
        let vn = Vec3::new(v[0], v[1], v[2]);
        let mut n = exact_normal(&e, vn);
        // two-sided
        let cam = Vec3::new(f.camera[0], f.camera[1], f.camera[2]);
        let view = (cam - e.s).normalize_or_zero();
        if n.dot(view) < 0.0 {
            n = -n;
        }
        // depth of the exact point
        let clip = self.view_proj * e.s.extend(1.0);
        let depth = clip.z / clip.w;
        let light = Vec3::new(f.light[0], f.light[1], f.light[2]);
        let raw = |c: Vec3| {
            let q = |x: f32| (if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } * 255.0 + 0.5) as u8;
            [q(c.x), q(c.y), q(c.z), 255]
        };
        let rgba = match mode {
            1 => raw(isophote(n, light, f.params[1])),
            2 => raw(zebra(n, view, Vec3::Z, f.params[2])),
            3 | 4 => {
                let (k, h) = curvatures(&e, n);
                let value = if mode == 3 { k } else { h };
                raw(diverging(value / f.ranges[1]))
            }
            5 => {
                let mut m = vn.normalize_or(Vec3::Z);
                if m.dot(view) < 0.0 {
                    m = -m;
                }
                raw(isophote(m, light, f.params[1]))
            }
            6 => raw(n * 0.5 + Vec3::splat(0.5)),
            7 => {
                let (c, r) = (Vec3::new(f.model[0], f.model[1], f.model[2]), f.model[3]);
                raw(highlight(e.s, n, light, c + light * (2.0 * r), 2.0 * r / f.params[2].max(1) as f32))
            }
            _ => {
                let albedo = Vec3::new(0.72, 0.75, 0.80);
                let ndl = n.dot(light).max(0.0);
                let h = (light + view).normalize_or_zero();
                let spec = if ndl > 0.0 { 0.35 * n.dot(h).max(0.0).powf(48.0) } else { 0.0 };
                let c = albedo * (f.ranges[2] + ndl) + Vec3::splat(spec);
                let e = |x: f32| hitex_core::texture::linear_to_srgb_u8(x);
                [e(c.x), e(c.y), e(c.z), 255]
            }
        };
        (rgba, depth)
    }
}

impl QuadShader<VARYINGS> for NurbsProgram<'_> {
    const WRITES_DEPTH: bool = true;

    fn shade(&self, material: usize, v: &[[f32; VARYINGS]; 4], w: [f32; 4], live: u8) -> [[u8; 4]; 4] {
        self.shade_depth(material, v, w, live, [0.0; 4]).0
    }

    fn shade_depth(
        &self,
        _: usize,
        v: &[[f32; VARYINGS]; 4],
        _: [f32; 4],
        live: u8,
        _z: [f32; 4],
    ) -> ([[u8; 4]; 4], [f32; 4]) {
        let mut rgba = [[0u8; 4]; 4];
        let mut depth = [f32::NAN; 4];
        // patch-boundary overlay: fwidth of u and v from the quad's lanes
        let overlay = self.frame.params[3] & 2 == 2;
        let (fu, fv) = if overlay {
            let fw = |a: [f32; 4]| -> [f32; 4] {
                let (dx, dy) = (super::textured::dpdx(a), super::textured::dpdy(a));
                std::array::from_fn(|i| dx[i].abs() + dy[i].abs())
            };
            (fw(v.map(|l| l[3])), fw(v.map(|l| l[4])))
        } else {
            ([0.0; 4], [0.0; 4])
        };
        // helper lanes only feed the derivatives above: their colour is never computed
        for lane in 0..4 {
            if live & (1 << lane) != 0 {
                let (mut c, d) = self.lane(&v[lane]);
                if overlay && self.on_boundary(&v[lane], fu[lane], fv[lane]) {
                    c = [20, 20, 24, 255];
                }
                rgba[lane] = c;
                depth[lane] = d;
            }
        }
        (rgba, depth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hitex_core::nurbs::NurbsSurface;

    #[test]
    fn packed_f32_evaluation_tracks_the_f64_reference() {
        let (nu, nv) = (6, 5);
        let mut pts = Vec::new();
        for j in 0..nv {
            for i in 0..nu {
                let (x, y) = (i as f64, j as f64);
                pts.push([x, y, (x * 0.9).sin() * (y * 0.7).cos(), 1.0 + 0.3 * ((i + j) % 3) as f64]);
            }
        }
        let s = NurbsSurface::new(
            3,
            2,
            nu,
            nv,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.55, 1.0, 1.0, 1.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.4, 0.6, 1.0, 1.0, 1.0],
            pts,
        )
        .unwrap();
        let packed = PackedNurbs::new(&[s.clone(), s.elevate(true)]);
        for k in 0..=20 {
            for l in 0..=20 {
                let (u, v) = (k as f64 / 20.0, l as f64 / 20.0);
                let r = s.derivatives(u, v, 2);
                for patch in 0..2 {
                    let e = eval_packed(&packed, patch, u as f32, v as f32, true, patch == 0);
                    let pairs = [
                        (e.s, r.d[0][0]),
                        (e.su, r.d[1][0]),
                        (e.sv, r.d[0][1]),
                        (e.suu, r.d[2][0]),
                        (e.suv, r.d[1][1]),
                        (e.svv, r.d[0][2]),
                    ];
                    for (i, (a, b)) in pairs.iter().enumerate() {
                        let scale = 1.0 + b.iter().map(|x| x.abs()).fold(0.0, f64::max);
                        for t in 0..3 {
                            assert!(
                                (a[t] as f64 - b[t]).abs() < 2e-4 * scale,
                                "patch {patch} ({u}, {v}) d{i}[{t}]: {} vs {}",
                                a[t],
                                b[t]
                            );
                        }
                    }
                }
            }
        }
    }
}
