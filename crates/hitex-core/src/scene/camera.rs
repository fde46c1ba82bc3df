//! Perspective camera.

use crate::CoreError;
use glam::{Mat4, Vec3, Vec4};

/// A pinhole camera looking from `position` at `target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position (world).
    pub position: Vec3,
    /// Point looked at (world).
    pub target: Vec3,
    /// Approximate up direction; must not be parallel to the view direction.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f32,
    /// Near clipping distance (> 0).
    pub near: f32,
    /// Far clipping distance (> near).
    pub far: f32,
}

impl Camera {
    /// A validated camera.
    pub fn new(position: Vec3, target: Vec3, up: Vec3, fov_y_deg: f32, near: f32, far: f32) -> Result<Self, CoreError> {
        let c = Self { position, target, up, fov_y_deg, near, far };
        c.validate()?;
        Ok(c)
    }

    /// Checks that the camera forms a proper view.
    pub fn validate(&self) -> Result<(), CoreError> {
        let bad = |m: &str| Err(CoreError::DegenerateCamera(m.to_string()));
        if !(self.position.is_finite() && self.target.is_finite() && self.up.is_finite()) {
            return bad("position, target and up must be finite");
        }
        let dir = self.target - self.position;
        if dir.length() <= 1e-6 * (1.0 + self.position.length()) {
            return bad("target coincides with position");
        }
        if self.up.length() == 0.0 || dir.normalize().cross(self.up.normalize()).length() < 1e-4 {
            return bad("up is zero or parallel to the view direction");
        }
        if !(self.fov_y_deg.is_finite() && self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return bad(&format!("fov_y must be in (0, 180) degrees, got {}", self.fov_y_deg));
        }
        if !(self.near.is_finite() && self.far.is_finite() && self.near > 0.0 && self.far > self.near) {
            return bad(&format!("need 0 < near < far, got near {} far {}", self.near, self.far));
        }
        Ok(())
    }

    /// World-to-view matrix (right-handed, looking down −z).
    pub fn view(&self) -> Mat4 {
        let f = (self.target - self.position).normalize();
        let s = f.cross(self.up).normalize();
        let u = s.cross(f);
        let e = self.position;
        Mat4::from_cols(
            Vec4::new(s.x, u.x, -f.x, 0.0),
            Vec4::new(s.y, u.y, -f.y, 0.0),
            Vec4::new(s.z, u.z, -f.z, 0.0),
            Vec4::new(-s.dot(e), -u.dot(e), f.dot(e), 1.0),
        )
    }

    /// View-to-clip matrix with depth in [0, 1] (WebGPU/Vulkan convention).
    pub fn projection(&self, aspect: f32) -> Mat4 {
        let h = 1.0 / (0.5 * self.fov_y_deg.to_radians()).tan();
        let w = h / aspect;
        let r = self.far / (self.near - self.far);
        Mat4::from_cols(
            Vec4::new(w, 0.0, 0.0, 0.0),
            Vec4::new(0.0, h, 0.0, 0.0),
            Vec4::new(0.0, 0.0, r, -1.0),
            Vec4::new(0.0, 0.0, r * self.near, 0.0),
        )
    }

    /// World-to-clip matrix for an output of the given aspect (width / height).
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        self.projection(aspect) * self.view()
    }

    /// The nearest camera looking along `-toward` (`toward` points from the
    /// model to the eye) that shows every point inside the window
    /// `[x0, x1] × [y0, y1]` of normalised device coordinates (−1…1, y up)
    /// of a frame of the given aspect (width / height). The distance and the
    /// sideways shift are the exact solution of the linear constraints the
    /// window puts on them. `None` for no finite points, a zero or vertical
    /// direction, or an empty window.
    pub fn framing(
        points: &[Vec3],
        toward: Vec3,
        up: Vec3,
        fov_y_deg: f32,
        aspect: f32,
        window: [f32; 4],
    ) -> Option<Self> {
        let [x0, x1, y0, y1] = window;
        if !(x0 < x1 && y0 < y1 && aspect > 0.0 && fov_y_deg > 0.0 && fov_y_deg < 180.0) {
            return None;
        }
        let f = (-toward).try_normalize()?;
        let s = f.cross(up).try_normalize()?;
        let u = s.cross(f);
        let pts: Vec<Vec3> = points.iter().copied().filter(|p| p.is_finite()).collect();
        if pts.is_empty() {
            return None;
        }
        let (lo, hi) = pts.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let c = (lo + hi) * 0.5;
        let ty = (0.5 * fov_y_deg.to_radians()).tan();
        let tx = ty * aspect;
        let local: Vec<[f32; 3]> = pts.iter().map(|p| [(*p - c).dot(s), (*p - c).dot(u), (*p - c).dot(f)]).collect();
        // along one screen axis, with the eye shifted by e and set back by d:
        // a0·t·(z + d) ≤ x − e ≤ a1·t·(z + d) for every point, so
        // e + a1·t·d ≥ max(x − a1·t·z) = P and e + a0·t·d ≤ min(x − a0·t·z) = Q,
        // whence d ≥ (P − Q) / ((a1 − a0)·t)
        let axis = |k: usize, a0: f32, a1: f32, t: f32| {
            let p = local.iter().map(|q| q[k] - a1 * t * q[2]).fold(f32::NEG_INFINITY, f32::max);
            let q = local.iter().map(|q| q[k] - a0 * t * q[2]).fold(f32::INFINITY, f32::min);
            (p, q, (p - q) / ((a1 - a0) * t))
        };
        let (px, qx, dx) = axis(0, x0, x1, tx);
        let (py, qy, dy) = axis(1, y0, y1, ty);
        let zmin = local.iter().map(|q| q[2]).fold(f32::INFINITY, f32::min);
        let zmax = local.iter().map(|q| q[2]).fold(f32::NEG_INFINITY, f32::max);
        let extent = (hi - lo).length().max(1e-6);
        let d = dx.max(dy).max(-zmin + 1e-3 * extent);
        // the shift in the middle of the interval the distance leaves open
        let ex = 0.5 * ((px - x1 * tx * d) + (qx - x0 * tx * d));
        let ey = 0.5 * ((py - y1 * ty * d) + (qy - y0 * ty * d));
        let position = c + s * ex + u * ey - f * d;
        let cam = Self {
            position,
            target: position + f * d,
            up,
            fov_y_deg,
            near: ((zmin + d) * 0.5).max(d * 1e-3),
            far: (zmax + d) * 1.5 + 1e-3 * extent,
        };
        cam.validate().ok().map(|_| cam)
    }

    /// The camera turned by `angle` radians about the vertical axis through
    /// the target (for orbits and benchmarks).
    pub fn orbit(&self, angle: f32) -> Self {
        let rot = Mat4::from_axis_angle(self.up.normalize(), angle);
        Self { position: self.target + rot.transform_vector3(self.position - self.target), ..*self }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok() -> Camera {
        Camera::new(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, Vec3::Y, 45.0, 0.1, 100.0).unwrap()
    }

    #[test]
    fn degenerate_cameras_are_refused() {
        let c = ok();
        assert!(Camera { target: c.position, ..c }.validate().is_err());
        assert!(Camera { fov_y_deg: 0.0, ..c }.validate().is_err());
        assert!(Camera { fov_y_deg: 180.0, ..c }.validate().is_err());
        assert!(Camera { fov_y_deg: f32::NAN, ..c }.validate().is_err());
        assert!(Camera { up: Vec3::ZERO, ..c }.validate().is_err());
        assert!(Camera { up: c.target - c.position, ..c }.validate().is_err());
        assert!(Camera { near: 0.0, ..c }.validate().is_err());
        assert!(Camera { far: 0.05, ..c }.validate().is_err());
        assert!(Camera { position: Vec3::splat(f32::INFINITY), ..c }.validate().is_err());
    }

    #[test]
    fn target_projects_to_the_centre() {
        let c = ok();
        let p = c.view_proj(1.5) * c.target.extend(1.0);
        assert!((p.x / p.w).abs() < 1e-6 && (p.y / p.w).abs() < 1e-6);
        let z = p.z / p.w;
        assert!(z > 0.0 && z < 1.0);
    }

    #[test]
    fn near_and_far_map_to_depth_0_and_1() {
        let c = ok();
        let dir = (c.target - c.position).normalize();
        for (d, z) in [(c.near, 0.0), (c.far, 1.0)] {
            let p = c.view_proj(1.0) * (c.position + dir * d).extend(1.0);
            assert!((p.z / p.w - z).abs() < 1e-4, "{d}: {}", p.z / p.w);
        }
        // a point up and right of the view centre lands up and right in NDC
        let v = c.view();
        let right = v.row(0).truncate();
        let up = v.row(1).truncate();
        let p = c.view_proj(1.0) * (c.target + right * 0.1 + up * 0.1).extend(1.0);
        assert!(p.x > 0.0 && p.y > 0.0);
    }

    #[test]
    fn framing_fits_the_points_tightly_into_the_window() {
        // the corners of a box, seen from an oblique direction
        let mut pts = Vec::new();
        for k in 0..8 {
            pts.push(Vec3::new(
                if k & 1 == 0 { -3.0 } else { 3.5 },
                if k & 2 == 0 { -2.0 } else { 2.0 },
                if k & 4 == 0 { 0.0 } else { 3.15 },
            ));
        }
        for (toward, aspect, window) in [
            (Vec3::new(0.85, -1.5, 0.75), 1.0, [-1.0, 1.0, -1.0, 1.0]),
            (Vec3::new(-1.0, 0.2, 0.1), 16.0 / 9.0, [-0.9, 0.5, -0.8, 0.9]),
            (Vec3::new(0.0, 0.1, -1.0), 0.5, [-1.0, 1.0, -0.2, 1.0]),
        ] {
            let cam = Camera::framing(&pts, toward, Vec3::Z, 35.0, aspect, window).unwrap();
            let m = cam.view_proj(aspect);
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for p in &pts {
                let c = m * p.extend(1.0);
                let n = c.truncate() / c.w;
                assert!(c.w > 0.0 && n.z >= 0.0 && n.z <= 1.0, "{n}");
                lo = lo.min(n);
                hi = hi.max(n);
            }
            let eps = 1e-4;
            assert!(lo.x >= window[0] - eps && hi.x <= window[1] + eps, "{lo} {hi}");
            assert!(lo.y >= window[2] - eps && hi.y <= window[3] + eps, "{lo} {hi}");
            // tight along at least one axis, centred along the other
            let fx = (hi.x - lo.x) / (window[1] - window[0]);
            let fy = (hi.y - lo.y) / (window[3] - window[2]);
            assert!((fx.max(fy) - 1.0).abs() < 1e-3, "{fx} {fy}");
            let dir = (cam.position - cam.target).normalize();
            assert!(dir.dot(toward.normalize()) > 0.99999);
        }
        assert!(Camera::framing(&[], Vec3::X, Vec3::Z, 35.0, 1.0, [-1.0, 1.0, -1.0, 1.0]).is_none());
        assert!(Camera::framing(&pts, Vec3::Z, Vec3::Z, 35.0, 1.0, [-1.0, 1.0, -1.0, 1.0]).is_none());
        assert!(Camera::framing(&pts, Vec3::X, Vec3::Z, 35.0, 1.0, [1.0, -1.0, -1.0, 1.0]).is_none());
    }

    #[test]
    fn orbit_keeps_distance() {
        let c = ok();
        let o = c.orbit(1.0);
        assert!(((o.position - o.target).length() - (c.position - c.target).length()).abs() < 1e-5);
        assert!((o.position.y - c.position.y).abs() < 1e-6);
    }
}
