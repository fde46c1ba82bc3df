//! The textured-mesh fragment program. Twin of `shaders/textured.wgsl`:
//! same inputs, same steps, same order; change both together.

// lane loops index several arrays by the same lane, as the lane code reads
#![allow(clippy::needless_range_loop)]

use super::raster::{Block, BlockShader};
use super::sampler::{LaneJacobian, LaneSampler};
use super::simd::{self, LANES, Lanes, V3, ddx, ddy, lanes, map, splat, zip};
use crate::prepare::{FrameUniform, MaterialUniform, PreparedScene, Vertex};
use glam::{Vec3, Vec4};
use hitex_core::scene::MAX_LIGHTS;
use hitex_core::texture::{Filter, Image, Jacobian, LevelRule, MipPyramid, SamplerOptions, Wrap, level_of_detail};

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
    #[allow(clippy::type_complexity)]
    materials: Vec<(MaterialUniform, SamplerOptions, Option<&'a MipPyramid>, Option<LaneSampler<'a>>)>,
}

impl<'a> TexturedProgram<'a> {
    /// Binds the frame and the scene's materials.
    pub fn new(scene: &'a PreparedScene, frame: &'a FrameUniform) -> Self {
        let materials = scene
            .materials
            .iter()
            .zip(&scene.material_textures)
            .map(|(m, t)| {
                let opts = sampler_options(m);
                (*m, opts, t.as_deref(), t.as_deref().map(|p| LaneSampler::new(p, opts)))
            })
            .collect();
        Self { frame, materials }
    }
}

/// The sampler options a material uniform encodes.
pub fn sampler_options(m: &MaterialUniform) -> SamplerOptions {
    SamplerOptions {
        filter: Filter::from_code(m.filter).unwrap_or(Filter::Trilinear),
        wrap: Wrap::from_code(m.wrap).unwrap_or(Wrap::Repeat),
        level_rule: LevelRule::from_code(m.level_rule).unwrap_or(LevelRule::MaxPartial),
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

/// Writes an already-encoded colour in [0, 1].
#[inline]
fn raw(c: Vec3) -> [u8; 4] {
    let e = |v: f32| (if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) } * 255.0 + 0.5) as u8;
    [e(c.x), e(c.y), e(c.z), 255]
}

impl BlockShader<VARYINGS> for TexturedProgram<'_> {
    // texel and decode-table gathers, per-lane reads: on AMD Zen 4 the
    // frame took 0.67-0.90x the time at 8 lanes (trilinear 0.82-0.84x, 3
    // pairs); on Intel Xeon (Emerald Rapids) 0.86-0.92x at 16
    const GATHER_BOUND: bool = true;
    #[inline(always)]
    fn shade_block(&self, b: &Block<VARYINGS>, rgba: &mut [[u8; 4]; LANES], _depth: &mut Lanes) {
        let (m, opts, tex, sampler) = &self.materials[b.material];
        let f = self.frame;
        let live = b.live;
        // inputs, one lane per pixel
        let pos = V3 { x: b.v[0], y: b.v[1], z: b.v[2] };
        let nrm = V3 { x: b.v[3], y: b.v[4], z: b.v[5] };
        let u = map(&b.v[6], |t| t * m.uv_scale[0]);
        let vv = map(&b.v[7], |t| t * m.uv_scale[1]);
        // analytic screen-to-texture Jacobian, eq. (1): uv = U / q with U = uv·q
        // and q = 1/w both linear in screen space, so their quad differences are
        // exact and ∂uv/∂x = (∂U/∂x − uv ∂q/∂x) / q
        let q = map(&b.w, |w| 1.0 / w);
        let bu = zip(&u, &q, |a, q| a * q);
        let bv = zip(&vv, &q, |a, q| a * q);
        let (dq_x, dq_y) = (ddx(&q), ddy(&q));
        let (dbu_x, dbu_y, dbv_x, dbv_y) = (ddx(&bu), ddy(&bu), ddx(&bv), ddy(&bv));
        let jac = LaneJacobian {
            du_dx: lanes!(|i| (dbu_x[i] - u[i] * dq_x[i]) / q[i]),
            dv_dx: lanes!(|i| (dbv_x[i] - vv[i] * dq_x[i]) / q[i]),
            du_dy: lanes!(|i| (dbu_y[i] - u[i] * dq_y[i]) / q[i]),
            dv_dy: lanes!(|i| (dbv_y[i] - vv[i] * dq_y[i]) / q[i]),
        };
        // two-sided normal
        let cam = Vec3::new(f.camera[0], f.camera[1], f.camera[2]);
        let view = normalize_or_zero(&V3 {
            x: map(&pos.x, |p| cam.x - p),
            y: map(&pos.y, |p| cam.y - p),
            z: map(&pos.z, |p| cam.z - p),
        });
        let n = normalize_or_zero(&nrm);
        // (one-sided materials keep the normal as authored)
        let ndv = n.dot(&view);
        let sign: Lanes = lanes!(|i| if m.one_sided == 0 && ndv[i] < 0.0 { -1.0 } else { 1.0 });
        let n = V3 {
            x: zip(&n.x, &sign, |a, s| a * s),
            y: zip(&n.y, &sign, |a, s| a * s),
            z: zip(&n.z, &sign, |a, s| a * s),
        };
        match f.params[0] {
            // uv
            1 => {
                for i in 0..LANES {
                    rgba[i] = raw(Vec3::new(u[i] - u[i].floor(), vv[i] - vv[i].floor(), 0.0));
                }
            }
            // level
            2 => {
                for i in 0..LANES {
                    let lambda = match texture_level0(*tex) {
                        Some(img) if m.has_texture == 1 => {
                            let j = Jacobian {
                                du_dx: jac.du_dx[i],
                                dv_dx: jac.dv_dx[i],
                                du_dy: jac.du_dy[i],
                                dv_dy: jac.dv_dy[i],
                            };
                            level_of_detail(opts.level_rule, j, img.width(), img.height()) + opts.lod_bias
                        }
                        _ => f32::NEG_INFINITY,
                    };
                    rgba[i] = raw(level_color(lambda));
                }
            }
            // normal
            3 => {
                for i in 0..LANES {
                    rgba[i] = raw(n.lane(i) * 0.5 + Vec3::splat(0.5));
                }
            }
            // shaded
            _ => {
                // albedo = base colour × texel
                let base = Vec4::from_array(m.base_color).truncate();
                let mut albedo = [splat(base.x), splat(base.y), splat(base.z)];
                if let Some(s) = sampler.as_ref().filter(|_| m.has_texture == 1) {
                    // helper lanes feed derivatives only: their texels are never read
                    let t = s.sample(&u, &vv, &jac, live);
                    for c in 0..3 {
                        albedo[c] = zip(&albedo[c], &t[c], |a, t| a * t);
                    }
                }
                let mut diffuse = [splat(f.ambient[0]), splat(f.ambient[1]), splat(f.ambient[2])];
                let mut spec = [splat(0.0); 3];
                let count = (f.params[1] as usize).min(MAX_LIGHTS);
                for l in &f.lights[..count] {
                    let lv = Vec3::new(l.vector[0], l.vector[1], l.vector[2]);
                    let rad = [l.radiance[0], l.radiance[1], l.radiance[2]];
                    let (to_light, atten) = if l.vector[3] == 0.0 {
                        (V3::splat(-lv), splat(1.0))
                    } else {
                        let d = V3 {
                            x: map(&pos.x, |p| lv.x - p),
                            y: map(&pos.y, |p| lv.y - p),
                            z: map(&pos.z, |p| lv.z - p),
                        };
                        let d2 = d.dot(&d);
                        (normalize_or_zero(&d), map(&d2, |d2| 1.0 / d2.max(1e-8)))
                    };
                    let ndl = map(&n.dot(&to_light), |x| x.max(0.0));
                    for c in 0..3 {
                        for i in 0..LANES {
                            diffuse[c][i] += ndl[i] * atten[i] * rad[c];
                        }
                    }
                    let lit = ndl.iter().any(|&x| x > 0.0);
                    if m.specular > 0.0 && lit {
                        let h = normalize_or_zero(&V3 {
                            x: zip(&to_light.x, &view.x, |a, b| a + b),
                            y: zip(&to_light.y, &view.y, |a, b| a + b),
                            z: zip(&to_light.z, &view.z, |a, b| a + b),
                        });
                        let nh = n.dot(&h);
                        // (n·h)^shininess: whole exponents by squaring, others
                        // as exp2(shininess·log2 n·h), a GPU's pow
                        let p = simd::pow_lanes(&map(&nh, |x| x.max(0.0)), m.shininess);
                        let mut s = [0.0; LANES];
                        for i in 0..LANES {
                            s[i] = if ndl[i] > 0.0 { p[i] * atten[i] * m.specular } else { 0.0 };
                        }
                        for c in 0..3 {
                            for i in 0..LANES {
                                spec[c][i] += s[i] * rad[c];
                            }
                        }
                    }
                }
                let mut c = [[0.0; LANES]; 3];
                for k in 0..3 {
                    for i in 0..LANES {
                        c[k][i] = albedo[k][i] * diffuse[k][i] + spec[k][i];
                    }
                }
                let codes = simd::encode_rgb(hitex_core::texture::srgb_encoder(), &c);
                for i in 0..LANES {
                    if live & (1 << i) != 0 {
                        rgba[i] = codes[i];
                    }
                }
            }
        }
    }
}

/// `v / |v|` per lane, or zero where `|v| = 0` (glam's `normalize_or_zero`).
#[inline(always)]
fn normalize_or_zero(v: &V3) -> V3 {
    let len2 = v.dot(v);
    let mut s = [0.0; LANES];
    for i in 0..LANES {
        let rcp = 1.0 / len2[i].sqrt();
        s[i] = if rcp.is_finite() & (len2[i] > 0.0) { rcp } else { 0.0 };
    }
    V3 { x: zip(&v.x, &s, |a, s| a * s), y: zip(&v.y, &s, |a, s| a * s), z: zip(&v.z, &s, |a, s| a * s) }
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
