//! The BTF fragment program. Twin of `shaders/btf.wgsl`: same inputs (the
//! frame uniforms, the index map, the codebook in its layout), same steps in
//! the same order.
//!
//! Per fragment: renormalise N, U, V (N faces the viewer); the view and light
//! angles of the paper; their neighbouring samples on the angular grid; the
//! index map's four texels around T (4 index reads) with bilinear weights;
//! per index texel the hexa-linear interpolation over the angles through the
//! layout's reads ([`Codebook::corner`]); exposure, sRGB encoding.

use super::raster::QuadShader;
use crate::btf::{BtfFrame, BtfVertex, PreparedBtf};
use glam::{Vec3, Vec4};
use hitex_core::btf::frames::{V3x4, angles4};
use hitex_core::btf::layout::{FetchSink, ReadCounter};
use hitex_core::btf::{AngleLerps, Codebook, angles};
use hitex_core::texture::linear_to_srgb_u8;
use hitex_core::texture::sampler::floor;

/// Varyings: world position (3), N (3), U (3), V (3), T (2).
pub const VARYINGS: usize = 14;

/// The varyings of a vertex, in the order of `VsOut` in the shader.
pub fn varyings(v: &BtfVertex) -> [f32; VARYINGS] {
    let (p, n, u, w, t) = (v.position, v.normal, v.tangent_u, v.tangent_v, v.uv);
    [p[0], p[1], p[2], n[0], n[1], n[2], u[0], u[1], u[2], w[0], w[1], w[2], t[0], t[1]]
}

/// The program: borrowed prepared data and one frame's uniforms.
pub struct BtfProgram<'a> {
    scene: &'a PreparedBtf,
    camera: Vec3,
    light: Vec3,
    exposure: f32,
}

impl<'a> BtfProgram<'a> {
    /// The program for `scene` with uniforms `frame`.
    pub fn new(scene: &'a PreparedBtf, frame: &BtfFrame) -> Self {
        Self {
            scene,
            camera: Vec3::new(frame.camera[0], frame.camera[1], frame.camera[2]),
            light: Vec3::new(frame.light[0], frame.light[1], frame.light[2]),
            exposure: frame.light[3],
        }
    }

    /// Shades one fragment in linear RGB, reporting its reads to `sink`.
    pub fn shade_linear<S: FetchSink>(&self, v: &[f32; VARYINGS], sink: &mut S) -> Vec3 {
        let at = |i: usize| Vec3::new(v[i], v[i + 1], v[i + 2]);
        let p = at(0);
        // per-pixel frame; the normal faces the viewer
        let mut n = at(3).normalize_or(Vec3::Z);
        let u = at(6).normalize_or(Vec3::X);
        let w = at(9).normalize_or(Vec3::Y);
        if n.dot(self.camera - p) < 0.0 {
            n = -n;
        }
        // light below the surface: no light
        if n.dot(self.light - p) <= 0.0 {
            return Vec3::ZERO;
        }
        // view and light angles, their neighbouring samples
        let (tc, pc) = angles(p, n, u, w, self.camera);
        let (tl, pl) = angles(p, n, u, w, self.light);
        let g = &self.scene.grid;
        let l = AngleLerps { tc: g.lerp_theta(tc), pc: g.lerp_phi(pc), tl: g.lerp_theta(tl), pl: g.lerp_phi(pl) };
        // index map: four texels around T, bilinear weights (4 index reads)
        let idx = &self.scene.index;
        let (x0, x1, fx) = index_taps(v[12], idx.width);
        let (y0, y1, fy) = index_taps(v[13], idx.height);
        let cb: &Codebook = &self.scene.codebook;
        let corners = [
            (x0, y0, (1.0 - fx) * (1.0 - fy)),
            (x1, y0, fx * (1.0 - fy)),
            (x0, y1, (1.0 - fx) * fy),
            (x1, y1, fx * fy),
        ];
        let mut acc = Vec3::ZERO;
        if S::COUNTS {
            for (x, y, wgt) in corners {
                let e = idx.get(x, y);
                // hexa-linear over the angles through the layout's reads
                acc += cb.corner(e[0] as u32, e[1] as u32, &l, sink) * wgt;
            }
        } else {
            // the same reads with the per-pixel invariants hoisted
            let plan = cb.plan(&l);
            let mut a4 = glam::Vec4::ZERO;
            for (x, y, wgt) in corners {
                let e = idx.get(x, y);
                a4 += cb.corner_planned_linear(&plan, e[0] as u32, e[1] as u32, &self.scene.linear) * wgt;
            }
            acc = a4.truncate();
        }
        acc * self.exposure
    }

    /// The four lanes of a quad in linear RGB: the same steps as
    /// [`BtfProgram::shade_linear`], the per-pixel frame and both angle pairs
    /// computed on SIMD lanes, the reads lane by lane. Lanes not in `live`
    /// are left black.
    pub fn shade_quad(&self, v: &[[f32; VARYINGS]; 4], live: u8) -> [Vec3; 4] {
        let at = |i: usize| V3x4 {
            x: Vec4::new(v[0][i], v[1][i], v[2][i], v[3][i]),
            y: Vec4::new(v[0][i + 1], v[1][i + 1], v[2][i + 1], v[3][i + 1]),
            z: Vec4::new(v[0][i + 2], v[1][i + 2], v[2][i + 2], v[3][i + 2]),
        };
        let p = at(0);
        // per-pixel frame; the normal faces the viewer
        let mut n = at(3).normalize_or(Vec3::Z);
        let u = at(6).normalize_or(Vec3::X);
        let w = at(9).normalize_or(Vec3::Y);
        let back = n.dot(V3x4::splat(self.camera) - p).cmplt(Vec4::ZERO);
        n = V3x4::select(back, -n, n);
        // light below the surface: no light
        let lit = n.dot(V3x4::splat(self.light) - p).cmpgt(Vec4::ZERO).bitmask() as u8 & live;
        // view and light angles
        let (tc, pc) = angles4(p, n, u, w, self.camera);
        let (tl, pl) = angles4(p, n, u, w, self.light);
        let g = &self.scene.grid;
        let idx = &self.scene.index;
        let cb: &Codebook = &self.scene.codebook;
        let mut out = [Vec3::ZERO; 4];
        for (lane, o) in out.iter_mut().enumerate() {
            if lit & (1 << lane) == 0 {
                continue;
            }
            let l = AngleLerps {
                tc: g.lerp_theta(tc[lane]),
                pc: g.lerp_phi(pc[lane]),
                tl: g.lerp_theta(tl[lane]),
                pl: g.lerp_phi(pl[lane]),
            };
            // index map: four texels around T, bilinear weights (4 index reads)
            let (x0, x1, fx) = index_taps(v[lane][12], idx.width);
            let (y0, y1, fy) = index_taps(v[lane][13], idx.height);
            let plan = cb.plan(&l);
            let mut a4 = Vec4::ZERO;
            for (x, y, wgt) in [
                (x0, y0, (1.0 - fx) * (1.0 - fy)),
                (x1, y0, fx * (1.0 - fy)),
                (x0, y1, (1.0 - fx) * fy),
                (x1, y1, fx * fy),
            ] {
                let e = idx.get(x, y);
                // hexa-linear over the angles through the layout's reads
                a4 += cb.corner_planned_linear(&plan, e[0] as u32, e[1] as u32, &self.scene.linear) * wgt;
            }
            *o = a4.truncate() * self.exposure;
        }
        out
    }

    /// Reads per fragment at these varyings (texture instructions, texels).
    pub fn count_reads(&self, v: &[f32; VARYINGS]) -> ReadCounter {
        let mut c = ReadCounter::default();
        self.shade_linear(v, &mut c);
        c
    }
}

/// The two index texels around texture coordinate `t` (index-map repeats)
/// on a wrapping axis of `size` texels, and the weight of the second.
#[inline]
pub fn index_taps(t: f32, size: u32) -> (u32, u32, f32) {
    let t = if t.is_finite() { t.clamp(-1.0e6, 1.0e6) } else { 0.0 };
    let x = t * size as f32 - 0.5;
    let f0 = floor(x);
    let n = size as i64;
    let i0 = f0 as i64;
    (i0.rem_euclid(n) as u32, (i0 + 1).rem_euclid(n) as u32, x - f0)
}

impl QuadShader<VARYINGS> for BtfProgram<'_> {
    fn shade(&self, _material: usize, v: &[[f32; VARYINGS]; 4], _w: [f32; 4], live: u8) -> [[u8; 4]; 4] {
        let c = self.shade_quad(v, live);
        std::array::from_fn(|i| [linear_to_srgb_u8(c[i].x), linear_to_srgb_u8(c[i].y), linear_to_srgb_u8(c[i].z), 255])
    }
}

/// The fragments of `scene` seen by `camera` at `width`×`height`, in the
/// order a GPU shades them — 2×2 quads, quads row by row — each with its
/// perspective-correct varyings. Found by casting a ray through every pixel
/// centre (for the texture-cache model, which needs one ordered stream;
/// rendering itself goes through the rasterizer).
pub fn fragments_in_quad_order(scene: &PreparedBtf, frame: &BtfFrame, width: u32, height: u32) -> Vec<[f32; VARYINGS]> {
    let vp = glam::Mat4::from_cols_array_2d(&frame.view_proj);
    let inv = vp.inverse();
    let tris: Vec<[usize; 3]> = scene
        .indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| (i as usize) < scene.vertices.len()))
        .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
        .collect();
    let pos = |i: usize| Vec3::from_array(scene.vertices[i].position);
    let vary: Vec<[f32; VARYINGS]> = scene.vertices.iter().map(varyings).collect();
    let mut out = Vec::new();
    let hit = |px: u32, py: u32| -> Option<[f32; VARYINGS]> {
        let ndc_x = (px as f32 + 0.5) / width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (py as f32 + 0.5) / height as f32 * 2.0;
        let a = inv.project_point3(Vec3::new(ndc_x, ndc_y, 0.0));
        let b = inv.project_point3(Vec3::new(ndc_x, ndc_y, 1.0));
        let dir = b - a;
        let mut best: Option<(f32, usize, f32, f32)> = None;
        for (k, t) in tris.iter().enumerate() {
            // Möller–Trumbore
            let (p0, p1, p2) = (pos(t[0]), pos(t[1]), pos(t[2]));
            let (e1, e2) = (p1 - p0, p2 - p0);
            let h = dir.cross(e2);
            let det = e1.dot(h);
            if det.abs() < 1e-12 {
                continue;
            }
            let s = a - p0;
            let u = s.dot(h) / det;
            let q = s.cross(e1);
            let v = dir.dot(q) / det;
            let d = e2.dot(q) / det;
            if u < 0.0 || v < 0.0 || u + v > 1.0 || !(0.0..=1.0).contains(&d) {
                continue;
            }
            if best.is_none_or(|b| d < b.0) {
                best = Some((d, k, u, v));
            }
        }
        best.map(|(_, k, u, v)| {
            let t = tris[k];
            std::array::from_fn(|i| vary[t[0]][i] * (1.0 - u - v) + vary[t[1]][i] * u + vary[t[2]][i] * v)
        })
    };
    for qy in (0..height).step_by(2) {
        for qx in (0..width).step_by(2) {
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (px, py) = (qx + dx, qy + dy);
                if px < width
                    && py < height
                    && let Some(v) = hit(px, py)
                {
                    out.push(v);
                }
            }
        }
    }
    out
}
