//! The textured-mesh fragment program. Twin of `shaders/textured.wgsl`:
//! same inputs, same steps, same order; change both together.

use super::raster::QuadShader;
use crate::prepare::{FrameUniform, MaterialUniform, PreparedScene, Vertex};
use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};
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

/// Four lanes of a scalar: one value per pixel of the quad (SSE on x86-64).
type Lanes = Vec4;

/// Fine derivative along x of four lanes (lanes 0 1 / 2 3).
#[inline(always)]
fn ddx(a: Lanes) -> Lanes {
    a.yyww() - a.xxzz()
}

/// Fine derivative along y of four lanes.
#[inline(always)]
fn ddy(a: Lanes) -> Lanes {
    a.zwzw() - a.xyxy()
}

/// Three lanes-vectors: a 3-vector per pixel, stored component-wise.
#[derive(Clone, Copy)]
struct V3 {
    x: Lanes,
    y: Lanes,
    z: Lanes,
}

impl V3 {
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        Self { x: Lanes::splat(v.x), y: Lanes::splat(v.y), z: Lanes::splat(v.z) }
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
    #[inline(always)]
    fn scale(self, s: Lanes) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    #[inline(always)]
    fn dot(self, o: Self) -> Lanes {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// `v / |v|`, or zero where `|v| = 0` (glam's `normalize_or_zero`).
    #[inline(always)]
    fn normalize_or_zero(self) -> Self {
        let len2 = self.dot(self);
        let rcp = Lanes::ONE / len2.sqrt();
        let ok = rcp.is_finite_mask() & len2.cmpgt(Lanes::ZERO);
        self.scale(Lanes::select(ok, rcp, Lanes::ZERO))
    }
    #[inline(always)]
    fn lane(self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }
}

impl QuadShader<VARYINGS> for TexturedProgram<'_> {
    fn shade(&self, material: usize, v: &[[f32; VARYINGS]; 4], w: [f32; 4], live: u8) -> [[u8; 4]; 4] {
        let (m, opts, tex) = &self.materials[material];
        let f = self.frame;
        // inputs, one lane per pixel
        let col = |j: usize| Lanes::new(v[0][j], v[1][j], v[2][j], v[3][j]);
        let pos = V3 { x: col(0), y: col(1), z: col(2) };
        let nrm = V3 { x: col(3), y: col(4), z: col(5) };
        let u = col(6) * m.uv_scale[0];
        let vv = col(7) * m.uv_scale[1];
        // analytic screen-to-texture Jacobian, eq. (1): uv = U / q with U = uv·q
        // and q = 1/w both linear in screen space, so their quad differences are
        // exact and ∂uv/∂x = (∂U/∂x − uv ∂q/∂x) / q
        let q = Lanes::ONE / Lanes::from_array(w);
        let (bu, bv) = (u * q, vv * q);
        let (dq_x, dq_y) = (ddx(q), ddy(q));
        let du_dx = (ddx(bu) - u * dq_x) / q;
        let dv_dx = (ddx(bv) - vv * dq_x) / q;
        let du_dy = (ddy(bu) - u * dq_y) / q;
        let dv_dy = (ddy(bv) - vv * dq_y) / q;
        let jac = |i: usize| Jacobian { du_dx: du_dx[i], dv_dx: dv_dx[i], du_dy: du_dy[i], dv_dy: dv_dy[i] };
        let uv = |i: usize| Vec2::new(u[i], vv[i]);
        // two-sided normal
        let cam = V3::splat(Vec3::new(f.camera[0], f.camera[1], f.camera[2]));
        let view = cam.sub(pos).normalize_or_zero();
        let n = nrm.normalize_or_zero();
        // (one-sided materials keep the normal as authored)
        let back = if m.one_sided == 0 { n.dot(view).cmplt(Lanes::ZERO) } else { Lanes::ZERO.cmplt(Lanes::ZERO) };
        let sign = Lanes::select(back, Lanes::splat(-1.0), Lanes::ONE);
        let n = n.scale(sign);
        let mut out = [[0u8; 4]; 4];
        match f.params[0] {
            // uv
            1 => {
                for (i, o) in out.iter_mut().enumerate() {
                    let t = uv(i);
                    *o = raw(Vec3::new(t.x - t.x.floor(), t.y - t.y.floor(), 0.0));
                }
            }
            // level
            2 => {
                for (i, o) in out.iter_mut().enumerate() {
                    let lambda = match texture_level0(*tex) {
                        Some(img) if m.has_texture == 1 => {
                            level_of_detail(opts.level_rule, jac(i), img.width(), img.height()) + opts.lod_bias
                        }
                        _ => f32::NEG_INFINITY,
                    };
                    *o = raw(level_color(lambda));
                }
            }
            // normal
            3 => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = raw(n.lane(i) * 0.5 + Vec3::splat(0.5));
                }
            }
            // shaded
            _ => {
                // albedo = base colour × texel
                let mut albedo = V3::splat(Vec4::from_array(m.base_color).truncate());
                if let Some(t) = tex.filter(|_| m.has_texture == 1) {
                    // helper lanes feed derivatives only: their texels are never seen
                    let mut c = [Vec4::ONE; 4];
                    for (i, ci) in c.iter_mut().enumerate() {
                        if live & (1 << i) != 0 {
                            *ci = sample(t, opts, uv(i), jac(i));
                        }
                    }
                    albedo.x *= Lanes::new(c[0].x, c[1].x, c[2].x, c[3].x);
                    albedo.y *= Lanes::new(c[0].y, c[1].y, c[2].y, c[3].y);
                    albedo.z *= Lanes::new(c[0].z, c[1].z, c[2].z, c[3].z);
                }
                let mut diffuse = V3::splat(Vec3::new(f.ambient[0], f.ambient[1], f.ambient[2]));
                let mut spec = V3::splat(Vec3::ZERO);
                let count = (f.params[1] as usize).min(MAX_LIGHTS);
                for l in &f.lights[..count] {
                    let lv = Vec3::new(l.vector[0], l.vector[1], l.vector[2]);
                    let rad = Vec3::new(l.radiance[0], l.radiance[1], l.radiance[2]);
                    let (to_light, atten) = if l.vector[3] == 0.0 {
                        (V3::splat(-lv), Lanes::ONE)
                    } else {
                        let d = V3::splat(lv).sub(pos);
                        (d.normalize_or_zero(), Lanes::ONE / d.dot(d).max(Lanes::splat(1e-8)))
                    };
                    let ndl = n.dot(to_light).max(Lanes::ZERO);
                    let k = ndl * atten;
                    diffuse = diffuse.add(V3 { x: k * rad.x, y: k * rad.y, z: k * rad.z });
                    let lit = ndl.cmpgt(Lanes::ZERO);
                    if m.specular > 0.0 && lit.any() {
                        let h = to_light.add(view).normalize_or_zero();
                        let nh = n.dot(h).max(Lanes::ZERO);
                        // powf per lane, as the GPU's pow (a short-series exp2·log2
                        // measured 1.10× slower over the whole textured bench)
                        let p = Lanes::from_array(std::array::from_fn(|i| nh[i].powf(m.shininess)));
                        let s = Lanes::select(lit, p * atten * m.specular, Lanes::ZERO);
                        spec = spec.add(V3 { x: s * rad.x, y: s * rad.y, z: s * rad.z });
                    }
                }
                let c = V3 {
                    x: albedo.x * diffuse.x + spec.x,
                    y: albedo.y * diffuse.y + spec.y,
                    z: albedo.z * diffuse.z + spec.z,
                };
                for (i, o) in out.iter_mut().enumerate() {
                    *o = encode(c.lane(i));
                }
            }
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
