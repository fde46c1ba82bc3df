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
use glam::Vec3;

/// Polar angle θ ∈ [0, π] and azimuth φ ∈ [0, 2π) of direction `pc − p`
/// in the frame (N, U, V). A zero direction or one along N yields φ = 0.
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
    (theta, phi - std::f32::consts::TAU * floor(phi / std::f32::consts::TAU))
}

/// acos on [−1, 1] to within 2·10⁻⁸ before rounding (Abramowitz & Stegun
/// 4.4.46): the platform's `acosf` is a library call that dominated the
/// per-pixel angle cost.
#[inline]
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
