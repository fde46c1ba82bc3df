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
    fn orbit_keeps_distance() {
        let c = ok();
        let o = c.orbit(1.0);
        assert!(((o.position - o.target).length() - (c.position - c.target).length()).abs() < 1e-5);
        assert!((o.position.y - c.position.y).abs() < 1e-6);
    }
}
