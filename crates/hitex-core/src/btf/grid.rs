//! The angular sampling grid of a BTF: polar angles θ as a list, azimuths φ
//! as a count of equal steps over 360°.
//!
//! The paper samples θ = 0…70° in 10° steps (8) and φ in 16 steps (its text
//! says 24°, but 16 samples over 360° are 22.5° apart); the grid is data, so
//! any other sampling works the same way.

use crate::CoreError;
use crate::texture::sampler::floor;

/// Largest number of polar or azimuthal samples accepted.
pub const MAX_ANGLES: usize = 256;

/// An angular grid: `theta_deg` strictly increasing in [0, 90), `phi_count`
/// azimuths at `j · 360° / phi_count`.
#[derive(Debug, Clone, PartialEq)]
pub struct AngularGrid {
    theta_deg: Vec<f32>,
    phi_count: usize,
}

/// Two neighbouring samples along one angular axis and the weight of the second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLerp {
    /// First sample index.
    pub i0: usize,
    /// Second sample index (equal to `i0` at a clamped end).
    pub i1: usize,
    /// Weight of `i1`, in [0, 1].
    pub t: f32,
    /// The continuous sample coordinate (`i0 + t` before wrapping), the
    /// texel-space coordinate a hardware filter is given.
    pub coord: f32,
}

impl AngularGrid {
    /// A grid from polar angles in degrees and an azimuth count; the angles
    /// must be finite, strictly increasing and inside [0°, 90°).
    pub fn new(theta_deg: Vec<f32>, phi_count: usize) -> Result<Self, CoreError> {
        let bad = |m: String| Err(CoreError::OutOfRange { key: "angular grid".into(), message: m });
        if theta_deg.is_empty() || theta_deg.len() > MAX_ANGLES {
            return bad(format!("{} polar angles; 1..={MAX_ANGLES} are allowed", theta_deg.len()));
        }
        if phi_count == 0 || phi_count > MAX_ANGLES {
            return bad(format!("{phi_count} azimuths; 1..={MAX_ANGLES} are allowed"));
        }
        for (i, &t) in theta_deg.iter().enumerate() {
            if !t.is_finite() || !(0.0..90.0).contains(&t) {
                return bad(format!("theta[{i}] = {t}° is outside [0°, 90°)"));
            }
            if i > 0 && t <= theta_deg[i - 1] {
                return bad(format!("theta[{i}] = {t}° does not increase (previous {}°)", theta_deg[i - 1]));
            }
        }
        Ok(Self { theta_deg, phi_count })
    }

    /// The paper's grid: θ = 0, 10, …, 70° and 16 azimuths.
    pub fn paper() -> Self {
        Self { theta_deg: (0..8).map(|i| i as f32 * 10.0).collect(), phi_count: 16 }
    }

    /// Polar angles in degrees.
    pub fn theta_deg(&self) -> &[f32] {
        &self.theta_deg
    }

    /// Number of polar angles.
    pub fn theta_count(&self) -> usize {
        self.theta_deg.len()
    }

    /// Number of azimuths.
    pub fn phi_count(&self) -> usize {
        self.phi_count
    }

    /// Number of directions (θ count × φ count).
    pub fn directions(&self) -> usize {
        self.theta_deg.len() * self.phi_count
    }

    /// Direction index of (θ index, φ index): θ-major.
    pub fn direction(&self, theta: usize, phi: usize) -> usize {
        theta * self.phi_count + phi
    }

    /// Azimuth of sample `j` in degrees.
    pub fn phi_deg(&self, j: usize) -> f32 {
        j as f32 * 360.0 / self.phi_count as f32
    }

    /// Unit vector of direction (θ index, φ index) in the tangent frame
    /// (x along U, y along V, z along the normal).
    pub fn vector(&self, theta: usize, phi: usize) -> glam::Vec3 {
        dir_vector(self.theta_deg[theta].to_radians(), self.phi_deg(phi).to_radians())
    }

    /// Neighbouring polar samples of θ (radians): clamps at the first and the
    /// last ring.
    pub fn lerp_theta(&self, theta: f32) -> AxisLerp {
        let deg = if theta.is_finite() { theta.to_degrees() } else { 0.0 };
        let th = &self.theta_deg;
        let n = th.len();
        if n == 1 || deg <= th[0] {
            return AxisLerp { i0: 0, i1: 0, t: 0.0, coord: 0.0 };
        }
        if deg >= th[n - 1] {
            return AxisLerp { i0: n - 1, i1: n - 1, t: 0.0, coord: (n - 1) as f32 };
        }
        // first ring above deg (binary search; the list is strictly increasing)
        let i1 = th.partition_point(|&x| x <= deg).clamp(1, n - 1);
        let i0 = i1 - 1;
        let t = ((deg - th[i0]) / (th[i1] - th[i0])).clamp(0.0, 1.0);
        AxisLerp { i0, i1, t, coord: i0 as f32 + t }
    }

    /// Neighbouring azimuth samples of φ (radians): wraps around the circle.
    pub fn lerp_phi(&self, phi: f32) -> AxisLerp {
        let n = self.phi_count as f32;
        let mut x = if phi.is_finite() { phi / std::f32::consts::TAU * n } else { 0.0 };
        x -= n * floor(x / n);
        if x >= n {
            x = 0.0;
        }
        let i0 = (floor(x) as usize).min(self.phi_count - 1);
        let t = (x - i0 as f32).clamp(0.0, 1.0);
        AxisLerp { i0, i1: (i0 + 1) % self.phi_count, t, coord: x }
    }
}

/// Unit vector of polar angle `theta` and azimuth `phi` (radians) in a frame
/// with z up.
pub fn dir_vector(theta: f32, phi: f32) -> glam::Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    glam::Vec3::new(st * cp, st * sp, ct)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_grid_has_128_directions() {
        let g = AngularGrid::paper();
        assert_eq!(g.directions(), 128);
        assert_eq!(g.phi_deg(1), 22.5);
    }

    #[test]
    fn theta_clamps_and_interpolates() {
        let g = AngularGrid::paper();
        let l = g.lerp_theta(35f32.to_radians());
        assert_eq!((l.i0, l.i1), (3, 4));
        assert!((l.t - 0.5).abs() < 1e-5);
        let top = g.lerp_theta(85f32.to_radians());
        assert_eq!((top.i0, top.i1, top.t), (7, 7, 0.0));
        assert_eq!(g.lerp_theta(-0.1).i0, 0);
        assert_eq!(g.lerp_theta(f32::NAN).i0, 0);
    }

    #[test]
    fn phi_wraps() {
        let g = AngularGrid::paper();
        let l = g.lerp_phi(350f32.to_radians());
        assert_eq!((l.i0, l.i1), (15, 0));
        assert!((l.t - (350.0 - 337.5) / 22.5).abs() < 1e-4);
        let neg = g.lerp_phi(-10f32.to_radians());
        assert_eq!((neg.i0, neg.i1), (15, 0));
        let big = g.lerp_phi(10.0 * std::f32::consts::TAU + 0.1);
        assert_eq!(big.i0, 0);
        assert_eq!(g.lerp_phi(f32::INFINITY).i0, 0);
    }

    #[test]
    fn bad_grids_are_refused() {
        assert!(AngularGrid::new(vec![], 16).is_err());
        assert!(AngularGrid::new(vec![0.0, 10.0], 0).is_err());
        assert!(AngularGrid::new(vec![10.0, 10.0], 4).is_err());
        assert!(AngularGrid::new(vec![0.0, 95.0], 4).is_err());
        assert!(AngularGrid::new(vec![0.0, f32::NAN], 4).is_err());
        assert!(AngularGrid::new(vec![20.0, 10.0], 4).is_err());
        assert!(AngularGrid::new(vec![0.0, 15.0, 30.0, 45.0, 60.0, 75.0], 12).is_ok());
    }
}
