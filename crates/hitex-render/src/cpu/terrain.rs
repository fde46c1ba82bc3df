//! The flight fragment program. Twin of `shaders/terrain.wgsl`: the same
//! uniforms and page table, the same steps in the same order.
//!
//! Per pixel: the ground points under the pixel and its right and lower
//! neighbours (eq. (1), flat ground); the level from the largest partial
//! (eq. (2)); bilinear at the two levels around it and the blend (eq. (3)–(4)),
//! each texel fetched through the page table — from a coarser resident map
//! while its own loads, from a coarser level outside the active area.

use crate::terrain::{FlyPages, FlyUniform, GROUND, MAP, sky};
use crate::{Frame, RenderError, check_size};
use hitex_core::residency::MapKey;
use hitex_core::texture::image::decode_table;
use hitex_core::texture::sampler::floor;
use hitex_core::texture::{ColorSpace, linear_to_srgb_u8};
use rayon::prelude::*;

struct Program<'a> {
    u: &'a FlyUniform,
    pages: &'a FlyPages,
    /// The page table resolved to texels: per slot, (level of the serving map, its texels).
    slots: Vec<Option<(u32, &'a [u8])>>,
    lut: &'static [f32; 256],
}

impl Program<'_> {
    /// The ground point through pixel position (px, py), or None at and above the horizon.
    fn ground(&self, px: f32, py: f32) -> Option<[f32; 2]> {
        let u = self.u;
        let (w, h) = (u.sizes[0] as f32, u.sizes[1] as f32);
        let tan_h = u.eye[3];
        let sx = (2.0 * px / w - 1.0) * tan_h;
        let sy = (1.0 - 2.0 * py / h) * tan_h * h / w;
        let d: [f32; 3] = std::array::from_fn(|i| u.fwd[i] + u.right[i] * sx + u.up[i] * sy);
        if d[2] >= -1e-6 {
            return None;
        }
        let t = -u.eye[2] / d[2];
        let g = [u.eye[0] + d[0] * t, u.eye[1] + d[1] * t];
        (g[0].is_finite() && g[1].is_finite()).then_some(g)
    }

    /// Linear RGBA of texel (tx, ty) of level z through the page table.
    fn texel(&self, z: u32, tx: i32, ty: i32) -> [f32; 4] {
        let per = self.pages.per_side as i32;
        let (mut z, mut tx, mut ty) = (z, tx, ty);
        loop {
            let o = self.pages.origins[z as usize];
            let (mx, my) = (tx.div_euclid(MAP as i32) - o[0], ty.div_euclid(MAP as i32) - o[1]);
            if mx >= 0 && my >= 0 && mx < per && my < per {
                let Some((found, t)) = self.slots[(z as i32 * per * per + my * per + mx) as usize] else {
                    return [0.0; 4];
                };
                // a coarser resident map stands in: its texel containing this one
                let k = z - found;
                let (lx, ly) = ((tx >> k).rem_euclid(MAP as i32) as usize, (ty >> k).rem_euclid(MAP as i32) as usize);
                let i = (ly * MAP as usize + lx) * 4;
                return [
                    self.lut[t[i] as usize],
                    self.lut[t[i + 1] as usize],
                    self.lut[t[i + 2] as usize],
                    t[i + 3] as f32 / 255.0,
                ];
            }
            // outside the active area: the next coarser level covers it
            if z == 0 {
                return [0.0; 4];
            }
            z -= 1;
            tx >>= 1;
            ty >>= 1;
        }
    }

    fn bilinear(&self, z: u32, p: [f32; 2]) -> [f32; 4] {
        let s = (1u32 << (self.pages.levels - 1 - z)) as f32;
        let (x, y) = (p[0] / s - 0.5, p[1] / s - 0.5);
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let (ix, iy) = (x0 as i32, y0 as i32);
        let c = [
            self.texel(z, ix, iy),
            self.texel(z, ix + 1, iy),
            self.texel(z, ix, iy + 1),
            self.texel(z, ix + 1, iy + 1),
        ];
        std::array::from_fn(|k| {
            let top = c[0][k] + (c[1][k] - c[0][k]) * fx;
            let bot = c[2][k] + (c[3][k] - c[2][k]) * fx;
            top + (bot - top) * fy
        })
    }

    /// Linear RGB of pixel (px, py).
    fn shade(&self, px: u32, py: u32) -> [f32; 3] {
        let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
        let (Some(p), Some(p1), Some(p2)) = (self.ground(x, y), self.ground(x + 1.0, y), self.ground(x, y + 1.0))
        else {
            return sky(y, self.u.sizes[1] as f32);
        };
        // eq. (2): the largest partial of the screen-to-map mapping
        let foot = (p1[0] - p[0]).abs().max((p1[1] - p[1]).abs()).max((p2[0] - p[0]).abs()).max((p2[1] - p[1]).abs());
        let levels = self.pages.levels;
        let zf = ((levels - 1) as f32 - foot.max(1e-9).log2()).clamp(0.0, (levels - 1) as f32);
        let z0 = floor(zf) as u32;
        let z1 = (z0 + 1).min(levels - 1);
        let t = zf - z0 as f32;
        let a = self.bilinear(z0, p);
        let b = if z1 != z0 && t > 0.0 { self.bilinear(z1, p) } else { a };
        let s: [f32; 4] = std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t);
        std::array::from_fn(|i| s[i] + GROUND[i] * (1.0 - s[3]))
    }
}

/// Renders one flight frame on the CPU.
pub fn render_fly(u: &FlyUniform, pages: &FlyPages) -> Result<Frame, RenderError> {
    let (w, h) = (u.sizes[0], u.sizes[1]);
    check_size(w, h)?;
    if pages.levels == 0 || pages.origins.len() != pages.levels as usize {
        return Err(RenderError::Invalid("the page table has no levels".into()));
    }
    let slots = pages
        .slots
        .iter()
        .map(|s| {
            s.and_then(|k: MapKey| {
                pages.maps.get(&k).filter(|t| t.len() >= (MAP * MAP * 4) as usize).map(|t| (k.z, t.as_slice()))
            })
        })
        .collect();
    let prog = Program { u, pages, slots, lut: decode_table(ColorSpace::Srgb) };
    let mut rgba = vec![0u8; (w * h * 4) as usize];
    rgba.par_chunks_mut((w * 4) as usize).enumerate().for_each(|(py, row)| {
        for px in 0..w {
            let c = prog.shade(px, py as u32);
            let o = (px * 4) as usize;
            row[o..o + 4].copy_from_slice(&[
                linear_to_srgb_u8(c[0]),
                linear_to_srgb_u8(c[1]),
                linear_to_srgb_u8(c[2]),
                255,
            ]);
        }
    });
    Ok(Frame { width: w, height: h, rgba })
}
