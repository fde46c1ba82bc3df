//! Rational B-spline surfaces: evaluation, normals, curvature.

use super::basis::{MAX_DEGREE, ders_basis_funs};
use super::knots::{find_span, validate_knots};
use super::{NurbsError, Real};

/// A (rational) B-spline surface. Control points are stored as Cartesian
/// `(x, y, z)` with weight `w`; index `j * count_u + i` (i along u).
#[derive(Debug, Clone, PartialEq)]
pub struct NurbsSurface {
    /// Degree in u.
    pub degree_u: usize,
    /// Degree in v.
    pub degree_v: usize,
    /// Control points along u.
    pub count_u: usize,
    /// Control points along v.
    pub count_v: usize,
    /// `count_u + degree_u + 1` knots.
    pub knots_u: Vec<f64>,
    /// `count_v + degree_v + 1` knots.
    pub knots_v: Vec<f64>,
    /// `(x, y, z, w)` per control point.
    pub points: Vec<[f64; 4]>,
}

/// `S_{k,l} = ∂^{k+l} S / ∂u^k ∂v^l` for `k + l ≤ 2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceDerivs<T> {
    /// `d[k][l]`; entries with `k + l > order` are zero.
    pub d: [[[T; 3]; 3]; 3],
}

/// Curvatures at a surface point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curvature {
    /// Gaussian curvature K = k1·k2.
    pub gaussian: f64,
    /// Mean curvature H = (k1 + k2)/2 (sign follows the normal).
    pub mean: f64,
    /// Principal curvatures, k1 ≥ k2.
    pub principal: [f64; 2],
}

/// Binomial coefficients for k ≤ 2.
const BIN: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 2.0, 1.0]];

/// Derivatives up to `order ≤ 2` of the rational surface given by raw data:
/// knot slices, homogeneous control points `Pw = (wx, wy, wz, w)` indexed
/// `j * nu + i`. Generic so that the f32 fragment program runs the same text.
#[allow(clippy::too_many_arguments)]
pub fn rational_derivs<T: Real>(
    p: usize,
    q: usize,
    nu: usize,
    nv: usize,
    knots_u: &[T],
    knots_v: &[T],
    pw: &[[T; 4]],
    u: T,
    v: T,
    order: usize,
) -> SurfaceDerivs<T> {
    let order = order.min(2);
    // find knot span
    let su = find_span(nu - 1, p, u, knots_u);
    let sv = find_span(nv - 1, q, v, knots_v);
    // basis functions and derivatives
    let bu = ders_basis_funs(su, u, p, order, knots_u);
    let bv = ders_basis_funs(sv, v, q, order, knots_v);
    // homogeneous derivatives A_{k,l} (x, y, z) and w_{k,l}
    let mut a = [[[T::ZERO; 4]; 3]; 3];
    for k in 0..=order {
        for l in 0..=(order - k) {
            let mut acc = [T::ZERO; 4];
            for s in 0..=q {
                let row = (sv - q + s) * nu + su - p;
                let mut tmp = [T::ZERO; 4];
                for r in 0..=p {
                    let c = pw[row + r];
                    let b = bu[k][r];
                    tmp[0] += b * c[0];
                    tmp[1] += b * c[1];
                    tmp[2] += b * c[2];
                    tmp[3] += b * c[3];
                }
                let b = bv[l][s];
                for t in 0..4 {
                    acc[t] += b * tmp[t];
                }
            }
            a[k][l] = acc;
        }
    }
    // rational quotient rule (A4.4)
    let mut d = [[[T::ZERO; 3]; 3]; 3];
    let w0 = a[0][0][3];
    for k in 0..=order {
        for l in 0..=(order - k) {
            let mut vv = [a[k][l][0], a[k][l][1], a[k][l][2]];
            for j in 1..=l {
                let c = T::from_f64(BIN[l][j]) * a[0][j][3];
                for t in 0..3 {
                    vv[t] -= c * d[k][l - j][t];
                }
            }
            for i in 1..=k {
                let c = T::from_f64(BIN[k][i]) * a[i][0][3];
                for t in 0..3 {
                    vv[t] -= c * d[k - i][l][t];
                }
                let mut v2 = [T::ZERO; 3];
                for j in 1..=l {
                    let c2 = T::from_f64(BIN[l][j]) * a[i][j][3];
                    for t in 0..3 {
                        v2[t] += c2 * d[k - i][l - j][t];
                    }
                }
                let bk = T::from_f64(BIN[k][i]);
                for t in 0..3 {
                    vv[t] -= bk * v2[t];
                }
            }
            for t in 0..3 {
                d[k][l][t] = vv[t] / w0;
            }
        }
    }
    SurfaceDerivs { d }
}

/// 3-vector helpers on arrays.
pub mod v3 {
    use super::Real;
    /// a × b
    pub fn cross<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    }
    /// a · b
    pub fn dot<T: Real>(a: [T; 3], b: [T; 3]) -> T {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    /// s · a
    pub fn scale<T: Real>(a: [T; 3], s: T) -> [T; 3] {
        [a[0] * s, a[1] * s, a[2] * s]
    }
    /// a − b
    pub fn sub<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    /// |a|
    pub fn len(a: [f64; 3]) -> f64 {
        dot(a, a).sqrt()
    }
}

/// Unit normal from first and second derivatives, with the limit normal where
/// `∂S/∂u × ∂S/∂v` vanishes. `toward_u`/`toward_v` are +1 when the point is at
/// (or nearer) the start of its parameter range, −1 nearer the end: the side
/// from which the limit is approached. Returns `None` only where every
/// fallback vanishes too.
pub fn normal_f64(d: &SurfaceDerivs<f64>, toward_u: f64, toward_v: f64) -> Option<[f64; 3]> {
    use v3::*;
    let (su, sv) = (d.d[1][0], d.d[0][1]);
    let (suv, suu, svv) = (d.d[1][1], d.d[2][0], d.d[0][2]);
    let norm = |a: [f64; 3]| dot(a, a).sqrt();
    let scale_len = norm(su).max(norm(sv)).max(norm(suv)).max(norm(suu)).max(norm(svv)).max(1e-300);
    let n = cross(su, sv);
    let tiny = 1e-10 * scale_len * scale_len;
    let unit = |a: [f64; 3]| {
        let l = norm(a);
        if l > tiny && l.is_finite() { Some(scale(a, 1.0 / l)) } else { None }
    };
    if let Some(n) = unit(n) {
        return Some(n);
    }
    // collapsed row: ∂S/∂u ≡ 0 along the edge, S_u ≈ S_uv·Δv
    let small_u = norm(su) <= 1e-8 * scale_len;
    let small_v = norm(sv) <= 1e-8 * scale_len;
    if small_u
        && !small_v
        && let Some(n) = unit(scale(cross(suv, sv), toward_v))
    {
        return Some(n);
    }
    if small_v
        && !small_u
        && let Some(n) = unit(scale(cross(su, suv), toward_u))
    {
        return Some(n);
    }
    // both vanish (apex): second-order terms along the diagonal
    let a = [su[0] + suu[0] * toward_u * 1e-3, su[1] + suu[1] * toward_u * 1e-3, su[2] + suu[2] * toward_u * 1e-3];
    let b = [sv[0] + svv[0] * toward_v * 1e-3, sv[1] + svv[1] * toward_v * 1e-3, sv[2] + svv[2] * toward_v * 1e-3];
    unit(cross(a, b))
}

/// Largest coordinate, weight and knot magnitude accepted (and smallest
/// weight, its inverse): products and sums of the evaluation stay finite.
pub const MAX_MAGNITUDE: f64 = 1e150;

impl NurbsSurface {
    /// A validated surface.
    pub fn new(
        degree_u: usize,
        degree_v: usize,
        count_u: usize,
        count_v: usize,
        knots_u: Vec<f64>,
        knots_v: Vec<f64>,
        points: Vec<[f64; 4]>,
    ) -> Result<Self, NurbsError> {
        for (dir, deg) in [("u", degree_u), ("v", degree_v)] {
            if deg == 0 || deg > MAX_DEGREE {
                return Err(NurbsError::Degree { dir, degree: deg });
            }
        }
        validate_knots("u", &knots_u, count_u, degree_u)?;
        validate_knots("v", &knots_v, count_v, degree_v)?;
        if points.len() != count_u * count_v {
            return Err(NurbsError::Counts {
                dir: "u×v",
                message: format!("{} control points for a {count_u}×{count_v} net", points.len()),
            });
        }
        for (k, c) in points.iter().enumerate() {
            let (i, j) = (k % count_u, k / count_u);
            if !c.iter().all(|x| x.is_finite()) {
                return Err(NurbsError::ControlPoint { i, j, message: format!("non-finite value {c:?}") });
            }
            if c[3] <= 0.0 {
                return Err(NurbsError::ControlPoint { i, j, message: format!("weight {} is not positive", c[3]) });
            }
            // weighted sums of such values stay finite in f64
            if c[..3].iter().any(|x| x.abs() > MAX_MAGNITUDE) || !(1.0 / MAX_MAGNITUDE..=MAX_MAGNITUDE).contains(&c[3])
            {
                return Err(NurbsError::ControlPoint {
                    i,
                    j,
                    message: format!("{c:?}: coordinates beyond ±1e150 or a weight outside [1e-150, 1e150]"),
                });
            }
        }
        Ok(Self { degree_u, degree_v, count_u, count_v, knots_u, knots_v, points })
    }

    /// A rational Bézier patch (`(p+1)×(q+1)` points `(x, y, z, w)`, u fastest)
    /// as the B-spline it is: clamped knots `0^(p+1) 1^(p+1)` in each direction.
    pub fn from_bezier(p: usize, q: usize, points: Vec<[f64; 4]>) -> Result<Self, NurbsError> {
        let clamp = |d: usize| [vec![0.0; d + 1], vec![1.0; d + 1]].concat();
        Self::new(p, q, p + 1, q + 1, clamp(p), clamp(q), points)
    }

    /// A sequence of Bézier patches joined along u (each `(p+1)×(q+1)`,
    /// neighbours sharing their boundary row) as one B-spline surface with
    /// interior knots of multiplicity p at 1, 2, … (C0 joins, exactly the patches).
    pub fn from_bezier_strip(p: usize, q: usize, patches: &[Vec<[f64; 4]>]) -> Result<Self, NurbsError> {
        let n = patches.len();
        if n == 0 {
            return Err(NurbsError::Counts { dir: "u", message: "no Bézier patches".into() });
        }
        let count_u = n * p + 1;
        let mut points = vec![[0.0; 4]; count_u * (q + 1)];
        for (k, b) in patches.iter().enumerate() {
            if b.len() != (p + 1) * (q + 1) {
                return Err(NurbsError::Counts {
                    dir: "u×v",
                    message: format!("Bézier patch {k} has {} points, needs {}", b.len(), (p + 1) * (q + 1)),
                });
            }
            for j in 0..=q {
                for i in 0..=p {
                    points[j * count_u + k * p + i] = b[j * (p + 1) + i];
                }
            }
        }
        let mut ku = vec![0.0; p + 1];
        for k in 1..n {
            ku.extend(std::iter::repeat_n(k as f64, p));
        }
        ku.extend(vec![n as f64; p + 1]);
        let kv = [vec![0.0; q + 1], vec![1.0; q + 1]].concat();
        Self::new(p, q, count_u, q + 1, ku, kv, points)
    }

    /// Parameter range `((u0, u1), (v0, v1))`.
    pub fn domain(&self) -> ((f64, f64), (f64, f64)) {
        (
            (self.knots_u[self.degree_u], self.knots_u[self.count_u]),
            (self.knots_v[self.degree_v], self.knots_v[self.count_v]),
        )
    }

    /// Whether every weight is 1 (a polynomial B-spline).
    pub fn is_polynomial(&self) -> bool {
        self.points.iter().all(|p| p[3] == 1.0)
    }

    /// Homogeneous control points `(wx, wy, wz, w)`.
    pub fn homogeneous(&self) -> Vec<[f64; 4]> {
        self.points.iter().map(|p| [p[0] * p[3], p[1] * p[3], p[2] * p[3], p[3]]).collect()
    }

    /// Derivatives up to `order ≤ 2` at (u, v) (clamped into the domain).
    pub fn derivatives(&self, u: f64, v: f64, order: usize) -> SurfaceDerivs<f64> {
        let ((u0, u1), (v0, v1)) = self.domain();
        let (u, v) = (clamp_nan(u, u0, u1), clamp_nan(v, v0, v1));
        let pw = self.homogeneous();
        rational_derivs(
            self.degree_u,
            self.degree_v,
            self.count_u,
            self.count_v,
            &self.knots_u,
            &self.knots_v,
            &pw,
            u,
            v,
            order,
        )
    }

    /// The surface point.
    pub fn point(&self, u: f64, v: f64) -> [f64; 3] {
        self.derivatives(u, v, 0).d[0][0]
    }

    /// The unit normal `(S_u × S_v)/|S_u × S_v|`, or its limit at degenerate
    /// points (collapsed rows, apexes). Never NaN: falls back to +z only where
    /// the surface has no tangent plane at all.
    pub fn normal(&self, u: f64, v: f64) -> [f64; 3] {
        let d = self.derivatives(u, v, 2);
        let ((u0, u1), (v0, v1)) = self.domain();
        let tu = if (u - u0) <= (u1 - u) { 1.0 } else { -1.0 };
        let tv = if (v - v0) <= (v1 - v) { 1.0 } else { -1.0 };
        normal_f64(&d, tu, tv).unwrap_or([0.0, 0.0, 1.0])
    }

    /// Gaussian, mean and principal curvatures from the fundamental forms.
    pub fn curvature(&self, u: f64, v: f64) -> Curvature {
        use v3::*;
        let d = self.derivatives(u, v, 2);
        let n = self.normal(u, v);
        let (su, sv) = (d.d[1][0], d.d[0][1]);
        let (e, f, g) = (dot(su, su), dot(su, sv), dot(sv, sv));
        let (l, m, nn) = (dot(d.d[2][0], n), dot(d.d[1][1], n), dot(d.d[0][2], n));
        let det = e * g - f * f;
        if det.abs() <= 1e-300 || !det.is_finite() {
            return Curvature { gaussian: 0.0, mean: 0.0, principal: [0.0, 0.0] };
        }
        let k = (l * nn - m * m) / det;
        let h = (e * nn - 2.0 * f * m + g * l) / (2.0 * det);
        let disc = (h * h - k).max(0.0).sqrt();
        Curvature { gaussian: k, mean: h, principal: [h + disc, h - disc] }
    }

    /// Axis-aligned bounds of the control net (which contains the surface).
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.points {
            for t in 0..3 {
                lo[t] = lo[t].min(p[t]);
                hi[t] = hi[t].max(p[t]);
            }
        }
        (lo, hi)
    }
}

fn clamp_nan(x: f64, lo: f64, hi: f64) -> f64 {
    if x.is_nan() { lo } else { x.clamp(lo, hi) }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A quarter cylinder of radius 1 as a rational quadratic in u, linear in v.
    pub(crate) fn quarter_cylinder() -> NurbsSurface {
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let mut pts = Vec::new();
        for z in [0.0, 2.0] {
            pts.push([1.0, 0.0, z, 1.0]);
            pts.push([1.0, 1.0, z, w]);
            pts.push([0.0, 1.0, z, 1.0]);
        }
        NurbsSurface::new(2, 1, 3, 2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0], vec![0.0, 0.0, 1.0, 1.0], pts).unwrap()
    }

    /// A bicubic patch with non-uniform knots and a wavy net.
    pub(crate) fn wavy() -> NurbsSurface {
        let (nu, nv) = (6, 5);
        let mut pts = Vec::new();
        for j in 0..nv {
            for i in 0..nu {
                let (x, y) = (i as f64, j as f64);
                pts.push([x, y, (x * 0.9).sin() * (y * 0.7).cos(), 1.0 + 0.3 * ((i + j) % 3) as f64]);
            }
        }
        NurbsSurface::new(
            3,
            2,
            nu,
            nv,
            vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.55, 1.0, 1.0, 1.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.4, 0.6, 1.0, 1.0, 1.0],
            pts,
        )
        .unwrap()
    }

    #[test]
    fn rational_cylinder_points_lie_on_the_circle() {
        let s = quarter_cylinder();
        for i in 0..=20 {
            let u = i as f64 / 20.0;
            let p = s.point(u, 0.37);
            assert!(((p[0] * p[0] + p[1] * p[1]).sqrt() - 1.0).abs() < 1e-14, "{p:?}");
            assert!((p[2] - 0.74).abs() < 1e-14);
            // outward or inward normal, but radial
            let n = s.normal(u, 0.37);
            assert!((n[0] * p[1] - n[1] * p[0]).abs() < 1e-12 && n[2].abs() < 1e-12);
            // curvature of a cylinder: K = 0, |H| = 1/2
            let c = s.curvature(u, 0.37);
            assert!(c.gaussian.abs() < 1e-10 && (c.mean.abs() - 0.5).abs() < 1e-10, "{c:?}");
        }
    }

    #[test]
    fn rational_sphere_points_lie_on_the_sphere() {
        // a full sphere of radius 2: rational quadratic circle (9 points) swept by a
        // rational quadratic half-circle meridian (5 points)
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let circle = [
            (1.0, 0.0, 1.0),
            (1.0, 1.0, w),
            (0.0, 1.0, 1.0),
            (-1.0, 1.0, w),
            (-1.0, 0.0, 1.0),
            (-1.0, -1.0, w),
            (0.0, -1.0, 1.0),
            (1.0, -1.0, w),
            (1.0, 0.0, 1.0),
        ];
        let meridian = [(0.0, -1.0, 1.0), (1.0, -1.0, w), (1.0, 0.0, 1.0), (1.0, 1.0, w), (0.0, 1.0, 1.0)];
        let mut pts = Vec::new();
        for &(r, z, wv) in &meridian {
            for &(x, y, wu) in &circle {
                pts.push([2.0 * r * x, 2.0 * r * y, 2.0 * z, wu * wv]);
            }
        }
        let ku = vec![0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0];
        let kv = vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0];
        let s = NurbsSurface::new(2, 2, 9, 5, ku, kv, pts).unwrap();
        for i in 0..=24 {
            for j in 0..=24 {
                let (u, v) = (i as f64 / 24.0, j as f64 / 24.0);
                let p = s.point(u, v);
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                assert!((r - 2.0).abs() < 1e-14, "({u}, {v}): r = {r}");
                // a sphere: K = 1/4 and |H| = 1/2 away from the poles
                if (0.05..0.95).contains(&v) {
                    let c = s.curvature(u, v);
                    assert!((c.gaussian - 0.25).abs() < 1e-9 && (c.mean.abs() - 0.5).abs() < 1e-9, "{c:?}");
                }
                // the normal is radial everywhere, poles included (limit normal)
                let n = s.normal(u, v);
                let d = (n[0] * p[0] + n[1] * p[1] + n[2] * p[2]).abs() / r;
                assert!((d - 1.0).abs() < 1e-6, "({u}, {v}): n·p/r = {d}");
            }
        }
    }

    #[test]
    fn bezier_patches_convert_exactly() {
        let bez: Vec<[f64; 4]> = (0..16)
            .map(|k| [(k % 4) as f64, (k / 4) as f64, ((k * 7) % 5) as f64 * 0.3, 1.0 + (k % 3) as f64 * 0.2])
            .collect();
        let s = NurbsSurface::from_bezier(3, 3, bez.clone()).unwrap();
        // de Casteljau in homogeneous space along u then v at (0.3, 0.6)
        let lerp = |a: [f64; 4], b: [f64; 4], t: f64| [0, 1, 2, 3].map(|i| a[i] + (b[i] - a[i]) * t);
        let hom: Vec<[f64; 4]> = bez.iter().map(|c| [c[0] * c[3], c[1] * c[3], c[2] * c[3], c[3]]).collect();
        let casteljau = |pts: &[[f64; 4]], t: f64| {
            let mut v = pts.to_vec();
            while v.len() > 1 {
                v = v.windows(2).map(|w| lerp(w[0], w[1], t)).collect();
            }
            v[0]
        };
        let rows: Vec<[f64; 4]> = (0..4).map(|j| casteljau(&hom[j * 4..j * 4 + 4], 0.3)).collect();
        let h = casteljau(&rows, 0.6);
        let p = s.point(0.3, 0.6);
        for t in 0..3 {
            assert!((p[t] - h[t] / h[3]).abs() < 1e-13);
        }
        // a strip of two patches sharing a row evaluates each patch on its half
        let mut b2 = bez.clone();
        for j in 0..4 {
            b2[j * 4] = bez[j * 4 + 3];
        }
        let strip = NurbsSurface::from_bezier_strip(3, 3, &[bez.clone(), b2.clone()]).unwrap();
        let second = NurbsSurface::from_bezier(3, 3, b2).unwrap();
        let (a, b) = (strip.point(1.4, 0.6), second.point(0.4, 0.6));
        for t in 0..3 {
            assert!((a[t] - b[t]).abs() < 1e-13);
        }
    }

    #[test]
    fn collapsed_row_has_a_limit_normal() {
        // a cone: the v = 0 row collapses to the apex (0, 0, 1)
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let mut pts = Vec::new();
        for (r, z) in [(0.0, 1.0), (1.0, 0.0)] {
            pts.push([r, 0.0, z, 1.0]);
            pts.push([r, r, z, w]);
            pts.push([0.0, r, z, 1.0]);
        }
        let s =
            NurbsSurface::new(2, 1, 3, 2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0], vec![0.0, 0.0, 1.0, 1.0], pts).unwrap();
        for i in 0..=10 {
            let u = i as f64 / 10.0;
            let n = s.normal(u, 0.0);
            assert!(n.iter().all(|x| x.is_finite()));
            // limit normal = normal just off the apex
            let m = s.normal(u, 1e-6);
            let dot = n[0] * m[0] + n[1] * m[1] + n[2] * m[2];
            assert!(dot > 0.999_999, "u {u}: {n:?} vs {m:?}");
        }
    }

    proptest! {
        #[test]
        fn derivatives_match_central_differences(u in 0.05f64..0.95, v in 0.05f64..0.95) {
            let s = wavy();
            let h = 1e-5;
            let near = |k: &[f64], x: f64| k.iter().any(|&t| (t - x).abs() < 3.0 * h);
            prop_assume!(!near(&s.knots_u, u) && !near(&s.knots_v, v));
            let d = s.derivatives(u, v, 2);
            let fd = |f: &dyn Fn(f64, f64) -> [f64; 3], du: f64, dv: f64| {
                let a = f(u + du, v + dv);
                let b = f(u - du, v - dv);
                [(a[0] - b[0]) / (2.0 * h), (a[1] - b[1]) / (2.0 * h), (a[2] - b[2]) / (2.0 * h)]
            };
            let pt = |a: f64, b: f64| s.point(a, b);
            let su = |a: f64, b: f64| s.derivatives(a, b, 1).d[1][0];
            let sv = |a: f64, b: f64| s.derivatives(a, b, 1).d[0][1];
            let checks = [
                (fd(&pt, h, 0.0), d.d[1][0]),
                (fd(&pt, 0.0, h), d.d[0][1]),
                (fd(&su, h, 0.0), d.d[2][0]),
                (fd(&sv, 0.0, h), d.d[0][2]),
                (fd(&su, 0.0, h), d.d[1][1]),
            ];
            for (i, (num, ana)) in checks.iter().enumerate() {
                for t in 0..3 {
                    prop_assert!((num[t] - ana[t]).abs() < 1e-4 * (1.0 + ana[t].abs()), "check {i}[{t}]: {} vs {}", num[t], ana[t]);
                }
            }
        }

        #[test]
        fn f32_path_tracks_f64(u in 0.0f64..=1.0, v in 0.0f64..=1.0) {
            let s = wavy();
            let pw = s.homogeneous();
            let pw32: Vec<[f32; 4]> = pw.iter().map(|c| c.map(|x| x as f32)).collect();
            let ku: Vec<f32> = s.knots_u.iter().map(|&x| x as f32).collect();
            let kv: Vec<f32> = s.knots_v.iter().map(|&x| x as f32).collect();
            let a = rational_derivs(3, 2, s.count_u, s.count_v, &ku, &kv, &pw32, u as f32, v as f32, 1);
            let b = s.derivatives(u, v, 1);
            for t in 0..3 {
                prop_assert!((a.d[0][0][t] as f64 - b.d[0][0][t]).abs() < 1e-5 * 6.0);
            }
        }
    }
}
