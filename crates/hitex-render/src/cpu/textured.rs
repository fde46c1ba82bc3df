//! The textured-mesh fragment program. Twin of `shaders/textured.wgsl`:
//! same inputs, same steps, same order; change both together.

use super::raster::QuadShader;
use crate::prepare::{FrameUniform, MaterialUniform, PreparedScene, Vertex};
use glam::{Vec2, Vec3, Vec4};
use hitex_core::scene::MAX_LIGHTS;
use hitex_core::texture::{
    Filter, Image, Jacobian, LevelRule, MipPyramid, SamplerOptions, Wrap, level_of_detail, sample,
};

/// Varyings per vertex: world position (3), world normal (3), uv (2).
pub const VARYINGS: usize = 8;

/// The varyings of a vertex, in the order of `VsOut` in the shader.
pub fn varyings(v: &Vertex) -> [f32; VARYINGS] {
    let (p, n, t) = (v.position, v.normal, v.uv);
    [p[0], p[1], p[2], n[0], n[1], n[2], t[0], t[1]]
}

/// The program with its bindings.
pub struct TexturedProgram<'a> {
    frame: &'a FrameUniform,
    materials: Vec<(MaterialUniform, SamplerOptions, Option<&'a MipPyramid>)>,
}

impl<'a> TexturedProgram<'a> {
    /// Binds the frame and the scene's materials.
    pub fn new(scene: &'a PreparedScene, frame: &'a FrameUniform) -> Self {
        let materials = scene
            .materials
            .iter()
            .zip(&scene.material_textures)
            .map(|(m, t)| (*m, sampler_options(m), t.as_deref()))
            .collect();
        Self { frame, materials }
    }
}

/// The sampler options a material uniform encodes.
pub fn sampler_options(m: &MaterialUniform) -> SamplerOptions {
    SamplerOptions {
        filter: match m.filter {
            0 => Filter::Nearest,
            1 => Filter::Bilinear,
            _ => Filter::Trilinear,
        },
        wrap: match m.wrap {
            1 => Wrap::Clamp,
            2 => Wrap::Mirror,
            _ => Wrap::Repeat,
        },
        level_rule: if m.level_rule == 1 { LevelRule::VulkanRho } else { LevelRule::MaxPartial },
        lod_bias: m.lod_bias,
    }
}

/// Fine derivative along x within a quad (lanes 0 1 / 2 3), as WGSL `dpdxFine`.
#[inline]
pub fn dpdx<T: Copy + std::ops::Sub<Output = T>>(v: [T; 4]) -> [T; 4] {
    let top = v[1] - v[0];
    let bottom = v[3] - v[2];
    [top, top, bottom, bottom]
}

/// Fine derivative along y within a quad, as WGSL `dpdyFine`.
#[inline]
pub fn dpdy<T: Copy + std::ops::Sub<Output = T>>(v: [T; 4]) -> [T; 4] {
    let left = v[2] - v[0];
    let right = v[3] - v[1];
    [left, right, left, right]
}

/// Colour ramp for MIP levels 0..=11 (blue → cyan → green → yellow → red → magenta).
const LEVEL_COLORS: [[f32; 3]; 12] = [
    [0.10, 0.10, 0.60],
    [0.10, 0.30, 0.90],
    [0.10, 0.60, 0.90],
    [0.10, 0.80, 0.70],
    [0.20, 0.80, 0.30],
    [0.55, 0.85, 0.15],
    [0.90, 0.85, 0.10],
    [0.95, 0.60, 0.10],
    [0.90, 0.30, 0.10],
    [0.80, 0.10, 0.20],
    [0.70, 0.10, 0.60],
    [0.95, 0.95, 0.95],
];

/// The MIP-level ramp at λ (output-encoded colour).
pub fn level_color(lambda: f32) -> Vec3 {
    if !lambda.is_finite() || lambda < 0.0 {
        return Vec3::from_array(LEVEL_COLORS[0]) * 0.6;
    }
    let l = lambda.min(10.999);
    let i = l.floor() as usize;
    let f = l - i as f32;
    let a = Vec3::from_array(LEVEL_COLORS[i]);
    let b = Vec3::from_array(LEVEL_COLORS[i + 1]);
    a + (b - a) * f
}

fn texture_level0(t: Option<&MipPyramid>) -> Option<&Image> {
    t.map(|p| p.level(0))
}

/// Encodes a linear colour for the 8-bit target (round to nearest).
#[inline]
fn encode(c: Vec3) -> [u8; 4] {
    let e = |v: f32| hitex_core::texture::linear_to_srgb_u8(v);
    [e(c.x), e(c.y), e(c.z), 255]
}

/// Writes an already-encoded colour in [0, 1].
#[inline]
fn raw(c: Vec3) -> [u8; 4] {
    let e = |v: f32| (if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) } * 255.0 + 0.5) as u8;
    [e(c.x), e(c.y), e(c.z), 255]
}

impl QuadShader<VARYINGS> for TexturedProgram<'_> {
    fn shade(&self, material: usize, v: &[[f32; VARYINGS]; 4], w: [f32; 4]) -> [[u8; 4]; 4] {
        let (m, opts, tex) = &self.materials[material];
        let f = self.frame;
        // inputs
        let pos = v.map(|a| Vec3::new(a[0], a[1], a[2]));
        let nrm = v.map(|a| Vec3::new(a[3], a[4], a[5]));
        let scale = Vec2::from_array(m.uv_scale);
        let uv = v.map(|a| Vec2::new(a[6], a[7]) * scale);
        // analytic screen-to-texture Jacobian, eq. (1): uv = U / q with U = uv·q
        // and q = 1/w both linear in screen space, so their quad differences are
        // exact and ∂uv/∂x = (∂U/∂x − uv ∂q/∂x) / q
        let q = w.map(|w| 1.0 / w);
        let big_u = [uv[0] * q[0], uv[1] * q[1], uv[2] * q[2], uv[3] * q[3]];
        let (du_x, du_y, dq_x, dq_y) = (dpdx(big_u), dpdy(big_u), dpdx(q), dpdy(q));
        let mut out = [[0u8; 4]; 4];
        for lane in 0..4 {
            let jac = Jacobian::new(
                (du_x[lane] - uv[lane] * dq_x[lane]) / q[lane],
                (du_y[lane] - uv[lane] * dq_y[lane]) / q[lane],
            );
            // two-sided normal
            let cam = Vec3::new(f.camera[0], f.camera[1], f.camera[2]);
            let view = (cam - pos[lane]).normalize_or_zero();
            let mut n = nrm[lane].normalize_or_zero();
            if n.dot(view) < 0.0 {
                n = -n;
            }
            out[lane] = match f.params[0] {
                // uv
                1 => raw(Vec3::new(uv[lane].x - uv[lane].x.floor(), uv[lane].y - uv[lane].y.floor(), 0.0)),
                // level
                2 => {
                    let lambda = match texture_level0(*tex) {
                        Some(img) if m.has_texture == 1 => {
                            level_of_detail(opts.level_rule, jac, img.width(), img.height()) + opts.lod_bias
                        }
                        _ => f32::NEG_INFINITY,
                    };
                    raw(level_color(lambda))
                }
                // normal
                3 => raw(n * 0.5 + Vec3::splat(0.5)),
                // shaded
                _ => {
                    let texel = match tex {
                        Some(t) if m.has_texture == 1 => sample(t, opts, uv[lane], jac),
                        _ => Vec4::ONE,
                    };
                    let albedo = Vec4::from_array(m.base_color) * texel;
                    let mut diffuse = Vec3::new(f.ambient[0], f.ambient[1], f.ambient[2]);
                    let mut spec = Vec3::ZERO;
                    let count = (f.params[1] as usize).min(MAX_LIGHTS);
                    for l in &f.lights[..count] {
                        let lv = Vec3::new(l.vector[0], l.vector[1], l.vector[2]);
                        let mut radiance = Vec3::new(l.radiance[0], l.radiance[1], l.radiance[2]);
                        let to_light = if l.vector[3] == 0.0 {
                            -lv
                        } else {
                            let d = lv - pos[lane];
                            radiance /= d.dot(d).max(1e-8);
                            d.normalize_or_zero()
                        };
                        let ndl = n.dot(to_light).max(0.0);
                        diffuse += radiance * ndl;
                        if ndl > 0.0 && m.specular > 0.0 {
                            let h = (to_light + view).normalize_or_zero();
                            spec += radiance * (m.specular * n.dot(h).max(0.0).powf(m.shininess));
                        }
                    }
                    encode(albedo.truncate() * diffuse + spec)
                }
            };
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quad_derivatives_follow_fine_semantics() {
        // f(x, y) = 3x + 5y sampled at the quad lanes (0,0) (1,0) (0,1) (1,1)
        let v = [0.0f32, 3.0, 5.0, 8.0];
        assert_eq!(dpdx(v), [3.0; 4]);
        assert_eq!(dpdy(v), [5.0; 4]);
        // fine: each row/column uses its own pair
        let g = [0.0f32, 1.0, 0.0, 4.0];
        assert_eq!(dpdx(g), [1.0, 1.0, 4.0, 4.0]);
        assert_eq!(dpdy(g), [0.0, 3.0, 0.0, 3.0]);
    }

    #[test]
    fn level_ramp_is_finite_everywhere() {
        for l in [f32::NEG_INFINITY, -1.0, 0.0, 0.5, 10.999, 11.0, 1e9, f32::NAN] {
            assert!(level_color(l).is_finite());
        }
    }
}
