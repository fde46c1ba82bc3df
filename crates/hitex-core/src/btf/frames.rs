//! Per-pixel view and light angles, exactly as the paper computes them.
//!
//! Inputs per pixel: position P, unit normal N, unit U and V (the directions
//! of increasing u and v on the tangent plane; not necessarily orthogonal);
//! per frame the camera or light position Pc. Then
//! C = Pc − P, C′ = C/|C|, θ = acos(C′·N), R = N × C′, R′ = R/|R|,
//! φ = acos(U·R′) − π/2. That φ covers only a half circle, [−π/2, π/2]; the
//! paper corrects it "with V" without details. Ours: V fixes the sense of
//! rotation (φ grows from U toward V, so mirrored texture coordinates mirror
//! the azimuth), and the side of C′ against U (C′·U < 0) maps φ to π − φ.
//! With an orthonormal frame this is the ordinary spherical azimuth.

use crate::texture::sampler::floor;
use glam::{Vec3, Vec4};

/// Polar angle θ ∈ [0, π] and azimuth φ ∈ [0, 2π) of direction `pc − p`
/// in the frame (N, U, V). A zero direction or one along N yields φ = 0; a
/// non-finite direction or N yields (0, 0), non-finite U or V yields φ = 0.
pub fn angles(p: Vec3, n: Vec3, u: Vec3, v: Vec3, pc: Vec3) -> (f32, f32) {
    let c = pc - p;
    let len = c.length();
    if len.is_nan() || len <= 0.0 || !len.is_finite() {
        return (0.0, 0.0);
    }
    let c1 = c / len;
    // θ = acos(C′·N)
    let s = c1.dot(n).clamp(-1.0, 1.0);
    let theta = acos(s);
    if theta.is_nan() {
        // N is not finite: no frame to measure in
        return (0.0, 0.0);
    }
    // R = N × C′, φ = acos(U·R′) − π/2
    let r = n.cross(c1);
    let rl = r.length();
    if rl.is_nan() || rl <= 1e-7 {
        return (theta, 0.0);
    }
    let t = (u.dot(r / rl)).clamp(-1.0, 1.0);
    let mut phi = acos(t) - std::f32::consts::FRAC_PI_2;
    // correction with V: sense of rotation, then the far half circle
    if n.cross(u).dot(v) < 0.0 {
        phi = -phi;
    }
    if c1.dot(u) < 0.0 {
        phi = std::f32::consts::PI - phi;
    }
    if phi.is_nan() {
        // U or V is not finite
        return (theta, 0.0);
    }
    (theta, phi - std::f32::consts::TAU * floor(phi / std::f32::consts::TAU))
}

/// acos on [−1, 1] to within 2·10⁻⁸ before rounding (Abramowitz & Stegun
/// 4.4.46): the platform's `acosf` is a library call that dominated the
/// per-pixel angle cost.
#[inline(always)]
#[allow(clippy::excessive_precision)] // the published coefficients, as printed
pub fn acos(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let p = -0.001_262_491_1;
    let p = p * a + 0.006_670_090_1;
    let p = p * a - 0.017_088_125_6;
    let p = p * a + 0.030_891_881_0;
    let p = p * a - 0.050_174_304_6;
    let p = p * a + 0.088_978_987_4;
    let p = p * a - 0.214_598_801_6;
    let p = p * a + 1.570_796_305_0;
    let r = (1.0 - a).sqrt() * p;
    if x < 0.0 { std::f32::consts::PI - r } else { r }
}

/// Four 3-vectors in structure-of-arrays form: one SIMD lane per pixel of a
/// 2×2 quad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct V3x4 {
    /// x of each lane.
    pub x: Vec4,
    /// y of each lane.
    pub y: Vec4,
    /// z of each lane.
    pub z: Vec4,
}

impl V3x4 {
    /// Lanes from four vectors.
    pub fn from_lanes(v: [Vec3; 4]) -> Self {
        Self {
            x: Vec4::new(v[0].x, v[1].x, v[2].x, v[3].x),
            y: Vec4::new(v[0].y, v[1].y, v[2].y, v[3].y),
            z: Vec4::new(v[0].z, v[1].z, v[2].z, v[3].z),
        }
    }
    /// The same vector in every lane.
    pub fn splat(v: Vec3) -> Self {
        Self { x: Vec4::splat(v.x), y: Vec4::splat(v.y), z: Vec4::splat(v.z) }
    }
    /// Lane `i`.
    pub fn lane(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }
    /// Lane-wise dot product.
    #[inline]
    pub fn dot(self, o: Self) -> Vec4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// Lane-wise cross product.
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        Self { x: self.y * o.z - o.y * self.z, y: self.z * o.x - o.z * self.x, z: self.x * o.y - o.x * self.y }
    }
    /// Lanes where `m` holds take `a`, the others `b`.
    #[inline]
    pub fn select(m: glam::BVec4A, a: Self, b: Self) -> Self {
        Self { x: Vec4::select(m, a.x, b.x), y: Vec4::select(m, a.y, b.y), z: Vec4::select(m, a.z, b.z) }
    }
    /// Lane-wise `normalize_or(fallback)` (as glam's: zero, infinite or NaN lengths take the fallback).
    #[inline]
    pub fn normalize_or(self, fallback: Vec3) -> Self {
        let rcp = Vec4::ONE / self.dot(self).sqrt();
        let ok = rcp.is_finite_mask() & rcp.cmpne(Vec4::ZERO);
        Self::select(ok, Self { x: self.x * rcp, y: self.y * rcp, z: self.z * rcp }, Self::splat(fallback))
    }
}

impl std::ops::Sub for V3x4 {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}

impl std::ops::Div<Vec4> for V3x4 {
    type Output = Self;
    #[inline]
    fn div(self, d: Vec4) -> Self {
        Self { x: self.x / d, y: self.y / d, z: self.z / d }
    }
}

impl std::ops::Neg for V3x4 {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self { x: -self.x, y: -self.y, z: -self.z }
    }
}

/// [`acos`] on four lanes (same polynomial, same order of operations).
#[inline]
#[allow(clippy::excessive_precision)] // the published coefficients, as printed
pub fn acos4(x: Vec4) -> Vec4 {
    let x = x.clamp(Vec4::splat(-1.0), Vec4::ONE);
    let a = x.abs();
    let p = Vec4::splat(-0.001_262_491_1);
    let p = p * a + 0.006_670_090_1;
    let p = p * a - 0.017_088_125_6;
    let p = p * a + 0.030_891_881_0;
    let p = p * a - 0.050_174_304_6;
    let p = p * a + 0.088_978_987_4;
    let p = p * a - 0.214_598_801_6;
    let p = p * a + 1.570_796_305_0;
    let r = (Vec4::ONE - a).sqrt() * p;
    Vec4::select(x.cmplt(Vec4::ZERO), Vec4::splat(std::f32::consts::PI) - r, r)
}

/// [`angles`] for the four pixels of a quad at once: the same steps on SIMD lanes.
pub fn angles4(p: V3x4, n: V3x4, u: V3x4, v: V3x4, pc: Vec3) -> (Vec4, Vec4) {
    use std::f32::consts::{FRAC_PI_2, PI, TAU};
    let c = V3x4::splat(pc) - p;
    let len = c.dot(c).sqrt();
    // NaN fails both comparisons: such lanes are degenerate too
    let good = len.cmpgt(Vec4::ZERO) & len.is_finite_mask();
    let c1 = c / len;
    // θ = acos(C′·N)
    let s = c1.dot(n).clamp(Vec4::splat(-1.0), Vec4::ONE);
    let theta = acos4(s);
    // R = N × C′, φ = acos(U·R′) − π/2
    let r = n.cross(c1);
    let rl = r.dot(r).sqrt();
    let has_r = rl.cmpgt(Vec4::splat(1e-7));
    let t = u.dot(r / rl).clamp(Vec4::splat(-1.0), Vec4::ONE);
    let mut phi = acos4(t) - Vec4::splat(FRAC_PI_2);
    // correction with V: sense of rotation, then the far half circle
    phi = Vec4::select(n.cross(u).dot(v).cmplt(Vec4::ZERO), -phi, phi);
    phi = Vec4::select(c1.dot(u).cmplt(Vec4::ZERO), Vec4::splat(PI) - phi, phi);
    let q = phi / TAU;
    let fl = Vec4::new(floor(q.x), floor(q.y), floor(q.z), floor(q.w));
    phi -= Vec4::splat(TAU) * fl;
    let phi = Vec4::select(has_r & !phi.is_nan_mask(), phi, Vec4::ZERO);
    let good = good & !theta.is_nan_mask();
    (Vec4::select(good, theta, Vec4::ZERO), Vec4::select(good, phi, Vec4::ZERO))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::grid::dir_vector;
    use std::f32::consts::{PI, TAU};

    fn ang_diff(a: f32, b: f32) -> f32 {
        let d = (a - b).rem_euclid(TAU);
        d.min(TAU - d)
    }

    #[test]
    fn four_lanes_equal_the_scalar_path() {
        let q = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0);
        let (n, u, v) = (q * Vec3::Z, q * Vec3::X, (q * Vec3::new(0.3, 1.0, 0.0)).normalize());
        let p = [Vec3::new(1.0, 2.0, -3.0), Vec3::new(0.5, 0.0, 0.0), Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0)];
        for pc in [Vec3::new(4.0, -2.0, 7.0), Vec3::ZERO, n * 5.0, -n * 3.0] {
            let (t4, p4) = angles4(V3x4::from_lanes(p), V3x4::splat(n), V3x4::splat(u), V3x4::splat(v), pc);
            for i in 0..4 {
                let (t, ph) = angles(p[i], n, u, v, pc);
                assert!((t4[i] - t).abs() < 1e-6 && (p4[i] - ph).abs() < 1e-5, "lane {i}: {t4} {p4} vs {t} {ph}");
            }
        }
    }

    #[test]
    fn fast_acos_is_accurate() {
        for i in -1000..=1000 {
            let x = i as f32 / 1000.0;
            assert!((acos(x) - x.acos()).abs() < 5e-7, "{x}");
        }
    }

    #[test]
    fn orthonormal_frame_gives_spherical_angles() {
        let (n, u, v) = (Vec3::Z, Vec3::X, Vec3::Y);
        for ti in 1..9 {
            for pi in 0..24 {
                let (th, ph) = (ti as f32 * 0.17, pi as f32 * TAU / 24.0);
                let pc = dir_vector(th, ph) * 3.0;
                let (a, b) = angles(Vec3::ZERO, n, u, v, pc);
                assert!((a - th).abs() < 1e-5, "θ {a} vs {th}");
                assert!(ang_diff(b, ph) < 1e-4, "φ {b} vs {ph} at θ {th}");
            }
        }
    }

    #[test]
    fn rotated_frame_is_invariant() {
        // the same local direction in a rotated frame gives the same angles
        let q = glam::Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0);
        let (n, u, v) = (q * Vec3::Z, q * Vec3::X, q * Vec3::Y);
        let p = Vec3::new(1.0, 2.0, -3.0);
        let local = dir_vector(1.0, 4.0);
        let (a, b) = angles(p, n, u, v, p + q * local * 5.0);
        assert!((a - 1.0).abs() < 1e-5 && ang_diff(b, 4.0) < 1e-4);
    }

    #[test]
    fn mirrored_v_mirrors_the_azimuth() {
        let pc = dir_vector(0.5, 1.0);
        let (_, b) = angles(Vec3::ZERO, Vec3::Z, Vec3::X, -Vec3::Y, pc);
        assert!(ang_diff(b, TAU - 1.0) < 1e-4);
    }

    #[test]
    fn degenerate_inputs_do_not_produce_nan() {
        let (a, b) = angles(Vec3::ZERO, Vec3::Z, Vec3::X, Vec3::Y, Vec3::ZERO);
        assert_eq!((a, b), (0.0, 0.0));
        let (a, b) = angles(Vec3::ZERO, Vec3::Z, Vec3::X, Vec3::Y, Vec3::Z);
        assert_eq!((a, b), (0.0, 0.0));
        let (a, b) = angles(Vec3::ZERO, Vec3::Z, Vec3::X, Vec3::Y, Vec3::new(f32::NAN, 0.0, 1.0));
        assert!(a.is_finite() && b.is_finite());
        let (a, _) = angles(Vec3::ZERO, Vec3::Z, Vec3::X, Vec3::Y, -Vec3::Z);
        assert!((a - PI).abs() < 1e-6);
    }

    #[test]
    fn non_orthogonal_uv_measures_from_u() {
        // V skewed 60° from U: φ is still the angle from U, growing toward V's side
        let v = Vec3::new(0.5, 0.866, 0.0);
        for k in 0..12 {
            let ph = k as f32 * TAU / 12.0 + 0.1;
            let (_, b) = angles(Vec3::ZERO, Vec3::Z, Vec3::X, v, dir_vector(0.7, ph));
            assert!(ang_diff(b, ph) < 1e-4);
        }
    }
}
