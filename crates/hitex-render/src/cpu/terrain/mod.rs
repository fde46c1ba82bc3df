//! The flight fragment programs. Twin of `shaders/terrain.wgsl`: the same
//! uniforms and page table, the same steps in the same order.
//!
//! Flat ground: per pixel, the ground points under the pixel and its right
//! and lower neighbours (eq. (1)); the level from the largest partial
//! (eq. (2)); bilinear at the two levels around it and the blend (eq. (3)–(4)),
//! each texel fetched through the page table — from a coarser resident map
//! while its own loads, from a coarser level outside the active area.
//!
//! Mesh ground (the DEM, objects): the rasterizer's 2×2 quads interpolate the
//! map position; the partials are the quad's fine differences (WGSL
//! `dpdxFine`/`dpdyFine`). Objects of `kind` 1 read the generic texture
//! (repeating, trilinear, the same level rule) and multiply it by their light.
//!
//! Span samplers (eq. (8)–(10)): the quad is the span. The level comes from
//! the span's footprint `E` (the larger axis extent of its four map points,
//! finest texels): `λ = log2(2E / (B − 2))` for B×B banks (see
//! `hitex_core::texture::span` for why 3×3 banks need one level more than
//! eq. (9) read literally); each pixel filters its 2×2 (bilinear) or its
//! Catmull-Rom taps restricted to the B×B mspan (bicubic) at the two levels
//! around λ. Every access is recorded in a [`BankModel`], which counts bank
//! conflicts. Levels coarser than the pyramid's coarsest are virtual (the
//! bank access is that of the continued pyramid, the value the coarsest's).
//!
//! Files: here the program, the flat-ground trilinear and generic samplers,
//! the page table and the frame; `spans` the span samplers (lanes and per
//! pixel); `mesh` the mesh-ground shader.

// lane loops index several arrays by the same lane, as the lane code reads
#![allow(clippy::needless_range_loop)]

use super::raster::{Block, BlockShader, Target, rasterize};
use super::simd::{LANES, Lanes, ddx, ddy, whole_i32, whole_u32};
use crate::terrain::{FlyGround, FlyMesh, FlyPages, FlySampler, FlyUniform, GROUND, GenericTexture, MAP, sky};
use crate::{Frame, RenderError, check_size};
use glam::{Mat4, Vec3};
use hitex_core::residency::MapKey;
use hitex_core::texture::image::decode_table;
use hitex_core::texture::sampler::floor;
use hitex_core::texture::span::catmull_rom;
use hitex_core::texture::span::{BankModel, SpanScheme};
use hitex_core::texture::{ColorSpace, linear_to_srgb_u8};
use rayon::prelude::*;
use std::sync::Mutex;

mod mesh;
mod spans;
#[cfg(test)]
mod tests;

use mesh::*;

/// Virtual levels a span may read beyond the coarsest (as the shader).
const VIRTUAL: i32 = 24;

/// One resident map: 256 × 256 RGBA8 texels, row by row.
type Map = [[u8; 4]; (MAP * MAP) as usize];

/// The map in the first 256 × 256 × 4 bytes of `t`, None if `t` is shorter.
fn as_map(t: &[u8]) -> Option<&Map> {
    t.get(..(MAP * MAP * 4) as usize)?.as_chunks::<4>().0.try_into().ok()
}

struct Program<'a> {
    u: FlyUniform,
    pages: &'a FlyPages,
    /// The page table resolved to texels: per slot, (level of the serving map, its texels).
    slots: Vec<Option<(u32, &'a Map)>>,
    generic: Vec<&'a Map>,
    lut: &'static [f32; 256],
    /// `a / 255` for every 8-bit alpha (a load instead of a division).
    alpha: &'static [f32; 256],
    /// True when the programs run at AVX-512 with fast gathers
    /// ([`super::simd::vector_gathers`]): a block whose lanes read one map
    /// then reads it through [`wide::footprints`]' vector gathers.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    wide: bool,
}

/// Per-axis filter taps: texel indices and weights (2 or 4 used).
#[derive(Clone, Copy)]
struct Axis {
    i: [i32; 4],
    w: [f32; 4],
}

/// Taps on one axis at texel position `q` inside the block `o ..= o + b − 1`.
#[inline(always)]
fn axis(q: f32, bicubic: bool, o: i32, b: i32) -> Axis {
    let f = floor(q);
    let t = q - f;
    let f = f as i32;
    if bicubic {
        let c = |d: i32| (f + d).clamp(o, o + b - 1);
        Axis { i: [c(-1), c(0), c(1), c(2)], w: catmull_rom(t) }
    } else {
        Axis { i: [f, f + 1, f + 1, f + 1], w: [1.0 - t, t, 0.0, 0.0] }
    }
}

impl Program<'_> {
    /// The ground point through pixel position (px, py), or None at and above the horizon.
    #[inline(always)]
    fn ground(&self, px: f32, py: f32) -> Option<[f32; 2]> {
        let u = &self.u;
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

    /// Linear RGBA of texel `n` (row × 256 + column) of a map.
    #[inline(always)]
    fn decode(&self, t: &Map, n: i32) -> [f32; 4] {
        // the mask keeps the index in the map, so the read needs no check
        let p = t[(n & 0xFFFF) as usize];
        [self.lut[p[0] as usize], self.lut[p[1] as usize], self.lut[p[2] as usize], self.alpha[p[3] as usize]]
    }

    /// The map serving texel (tx, ty) of level z through the page table, and
    /// the shift from level z's texels to that map's: None where no data lies.
    #[inline(always)]
    fn serving(&self, z: u32, tx: i32, ty: i32) -> Option<(&Map, u32)> {
        let per = self.pages.per_side as i32;
        let (mut z, mut tx, mut ty, mut steps) = (z, tx, ty, 0u32);
        loop {
            let o = self.pages.origins[z as usize];
            let (mx, my) = ((tx >> 8) - o[0], (ty >> 8) - o[1]);
            if mx >= 0 && my >= 0 && mx < per && my < per {
                // a coarser resident map stands in: its texel containing this one
                let (found, t) = self.slots[(z as i32 * per * per + my * per + mx) as usize]?;
                return Some((t, steps + z - found));
            }
            // outside the active area: the next coarser level covers it
            if z == 0 {
                return None;
            }
            z -= 1;
            tx >>= 1;
            ty >>= 1;
            steps += 1;
        }
    }

    /// Linear RGBA of texel (tx, ty) of level z through the page table.
    #[inline(always)]
    fn texel(&self, z: u32, tx: i32, ty: i32) -> [f32; 4] {
        match self.serving(z, tx, ty) {
            Some((t, k)) => self.decode(t, ((ty >> k) & 255) << 8 | ((tx >> k) & 255)),
            None => [0.0; 4],
        }
    }

    /// Like [`Program::texel`], keeping the page-table walk of the last map
    /// read in `memo` (the walk depends on the level and the map's column
    /// and row only).
    #[inline(always)]
    fn texel_memo<'s>(&'s self, memo: &mut ([i32; 3], Option<(&'s Map, u32)>), z: u32, tx: i32, ty: i32) -> [f32; 4] {
        let key = [z as i32, tx >> 8, ty >> 8];
        if key != memo.0 {
            *memo = (key, self.serving(z, tx, ty));
        }
        match memo.1 {
            Some((t, k)) => self.decode(t, ((ty >> k) & 255) << 8 | ((tx >> k) & 255)),
            None => [0.0; 4],
        }
    }

    #[inline(always)]
    fn bilinear(&self, z: u32, p: [f32; 2]) -> [f32; 4] {
        let s = (1u32 << (self.pages.levels - 1 - z)) as f32;
        let (x, y) = (p[0] / s - 0.5, p[1] / s - 0.5);
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        lerp2(self.footprint(z, x0 as i32, y0 as i32), fx, fy)
    }

    /// The 2×2 texels (tx, ty) … (tx + 1, ty + 1) of level z, linear RGBA,
    /// in the order (0,0) (1,0) (0,1) (1,1); zero where no data lies.
    #[inline(always)]
    fn footprint(&self, z: u32, ix: i32, iy: i32) -> [[f32; 4]; 4] {
        // the four texels share one map unless they straddle a map edge: resolve it once
        if ix & 255 != 255 && iy & 255 != 255 {
            let Some((t, k)) = self.serving(z, ix, iy) else { return [[0.0; 4]; 4] };
            return self.footprint_in(t, k, ix, iy);
        }
        [self.texel(z, ix, iy), self.texel(z, ix + 1, iy), self.texel(z, ix, iy + 1), self.texel(z, ix + 1, iy + 1)]
    }

    /// The 2×2 texels from (ix, iy) of a footprint inside one map, served by
    /// `t` with shift `k` (see [`Program::serving`]).
    #[inline(always)]
    fn footprint_in(&self, t: &Map, k: u32, ix: i32, iy: i32) -> [[f32; 4]; 4] {
        let (x0, x1) = ((ix >> k) & 255, ((ix + 1) >> k) & 255);
        let (y0, y1) = (((iy >> k) & 255) << 8, (((iy + 1) >> k) & 255) << 8);
        [self.decode(t, y0 | x0), self.decode(t, y0 | x1), self.decode(t, y1 | x0), self.decode(t, y1 | x1)]
    }

    /// The ground points through 16 pixels of one row (x positions `px`,
    /// row position `py`), as [`Program::ground`] lane by lane: map x, map y
    /// and a bit per lane with ground under it.
    #[inline(always)]
    fn ground_lanes(&self, px: &Lanes, py: &Lanes) -> (Lanes, Lanes, u32) {
        let u = &self.u;
        let (w, h) = (u.sizes[0] as f32, u.sizes[1] as f32);
        let tan_h = u.eye[3];
        let (mut gx, mut gy, mut ok) = ([0.0f32; LANES], [0.0f32; LANES], 0u32);
        for i in 0..LANES {
            let sy = (1.0 - 2.0 * py[i] / h) * tan_h * h / w;
            let sx = (2.0 * px[i] / w - 1.0) * tan_h;
            let d0 = u.fwd[0] + u.right[0] * sx + u.up[0] * sy;
            let d1 = u.fwd[1] + u.right[1] * sx + u.up[1] * sy;
            let d2 = u.fwd[2] + u.right[2] * sx + u.up[2] * sy;
            let t = -u.eye[2] / d2;
            gx[i] = u.eye[0] + d0 * t;
            gy[i] = u.eye[1] + d1 * t;
            let good = d2 < -1e-6 && gx[i].is_finite() && gy[i].is_finite();
            ok |= (good as u32) << i;
        }
        (gx, gy, ok)
    }

    /// Bilinear reads of level `z[i]` at the ground points (gx, gy) of the
    /// lanes in `wanted` (the others read nothing; `ok` marks lanes with
    /// ground): positions on lanes, texels lane by lane; linear RGBA.
    #[inline(always)]
    fn bilinear_lanes(&self, z: &[u32; LANES], wanted: u32, ok: u32, gx: &Lanes, gy: &Lanes) -> [Lanes; 4] {
        let levels = self.pages.levels;
        let (mut fx, mut fy, mut ix, mut iy) = ([0.0f32; LANES], [0.0f32; LANES], [0i32; LANES], [0i32; LANES]);
        for i in 0..LANES {
            // 2^(levels − 1 − z), exactly as the integer shift converted
            let s = f32::from_bits((levels - 1 - z[i] + 127) << 23);
            let (x, y) = (
                if ok >> i & 1 == 1 { gx[i] } else { 0.5 } / s - 0.5,
                if ok >> i & 1 == 1 { gy[i] } else { 0.5 } / s - 0.5,
            );
            let (x0, y0) = (floor(x), floor(y));
            fx[i] = x - x0;
            fy[i] = y - y0;
            ix[i] = whole_i32(x0);
            iy[i] = whole_i32(y0);
        }
        #[cfg(target_arch = "x86_64")]
        if self.wide && wanted != 0 {
            // the wanted lanes' footprints all inside one map (the usual
            // case): one page-table walk and the reads as vector gathers
            let f = wanted.trailing_zeros() as usize;
            let mut one = true;
            for i in 0..LANES {
                let inside = (ix[i] & 255 != 255) & (iy[i] & 255 != 255);
                let same = (z[i] == z[f]) & (ix[i] >> 8 == ix[f] >> 8) & (iy[i] >> 8 == iy[f] >> 8);
                one &= (wanted >> i & 1 == 0) | (inside & same);
            }
            if one {
                return match self.serving(z[f], ix[f], iy[f]) {
                    // SAFETY: `wide` is set only where the processor runs AVX-512F
                    Some((t, k)) => unsafe {
                        wide::footprints(t, k, &ix, &iy, &fx, &fy, wanted as u16, self.lut, self.alpha)
                    },
                    None => [[0.0f32; LANES]; 4],
                };
            }
        }
        let mut c = [[0.0f32; LANES]; 4];
        // neighbouring lanes almost always read one map: its page-table
        // walk (which depends on the level and the map's column and row
        // only) is kept for the next lane
        let mut memo: ([i32; 3], Option<(&Map, u32)>) = ([-1; 3], None);
        for i in 0..LANES {
            if wanted >> i & 1 == 0 {
                continue;
            }
            let (x, y) = (ix[i], iy[i]);
            let q = if x & 255 != 255 && y & 255 != 255 {
                let key = [z[i] as i32, x >> 8, y >> 8];
                if key != memo.0 {
                    memo = (key, self.serving(z[i], x, y));
                }
                match memo.1 {
                    Some((t, k)) => self.footprint_in(t, k, x, y),
                    None => [[0.0; 4]; 4],
                }
            } else {
                self.footprint(z[i], x, y)
            };
            // blended at once (see Program::spans_level_lanes)
            let blended = lerp2(q, fx[i], fy[i]);
            for ch in 0..4 {
                c[ch][i] = blended[ch];
            }
        }
        c
    }

    /// Linear RGB of 16 flat-ground pixels of row `py` from column `x0`, per
    /// pixel: the same operations as [`Program::shade_flat`] in the same
    /// order, the ray, footprint, level and blends on lane vectors, the
    /// texel reads lane by lane.
    #[inline(always)]
    fn shade_flat_lanes(&self, x0: u32, py: u32) -> [Lanes; 3] {
        let px: Lanes = std::array::from_fn(|i| (x0 + i as u32) as f32 + 0.5);
        let px1: Lanes = std::array::from_fn(|i| px[i] + 1.0);
        let y = py as f32 + 0.5;
        let (gx, gy, ok0) = self.ground_lanes(&px, &[y; LANES]);
        let (gx1, gy1, ok1) = self.ground_lanes(&px1, &[y; LANES]);
        let (gx2, gy2, ok2) = self.ground_lanes(&px, &[y + 1.0; LANES]);
        let ok = ok0 & ok1 & ok2;
        let sky = sky(y, self.u.sizes[1] as f32);
        if ok == 0 {
            return sky.map(|c| [c; LANES]);
        }
        // eq. (2): the largest partial of the screen-to-map mapping; eq. (3)'s level
        let levels = self.pages.levels;
        let top = (levels - 1) as f32;
        let (mut z0, mut z1, mut t) = ([0u32; LANES], [0u32; LANES], [0.0f32; LANES]);
        for i in 0..LANES {
            let foot = (gx1[i] - gx[i])
                .abs()
                .max((gy1[i] - gy[i]).abs())
                .max((gx2[i] - gx[i]).abs())
                .max((gy2[i] - gy[i]).abs());
            let zf = (top - super::simd::log2(foot.max(1e-9))).clamp(0.0, top);
            // a lane without ground reads level 0's first texel, dropped below
            let zf = if ok >> i & 1 == 1 { zf } else { 0.0 };
            let f = floor(zf);
            z0[i] = whole_u32(f);
            z1[i] = (z0[i] + 1).min(levels - 1);
            t[i] = zf - f;
        }
        let a = self.bilinear_lanes(&z0, ok, ok, &gx, &gy);
        let mut second = 0u32;
        for i in 0..LANES {
            second |= (((z1[i] != z0[i]) & (t[i] > 0.0)) as u32) << i;
        }
        let second = second & ok;
        let b = if second != 0 { self.bilinear_lanes(&z1, second, ok, &gx, &gy) } else { a };
        std::array::from_fn(|k| {
            let mut o = [0.0f32; LANES];
            for i in 0..LANES {
                let (a4, b4) = (a[k][i], if second >> i & 1 == 1 { b[k][i] } else { a[k][i] });
                let (a3, b3) = (a[3][i], if second >> i & 1 == 1 { b[3][i] } else { a[3][i] });
                let c = a4 + (b4 - a4) * t[i];
                let alpha = a3 + (b3 - a3) * t[i];
                // over the ground colour; sky where no ground lies
                o[i] = if ok >> i & 1 == 1 { c + GROUND[k] * (1.0 - alpha) } else { sky[k] };
            }
            o
        })
    }

    /// Eq. (2)–(4) at map point `p` with largest partial `foot` (finest texels per pixel).
    #[inline(always)]
    fn trilinear(&self, p: [f32; 2], foot: f32) -> [f32; 4] {
        let levels = self.pages.levels;
        // the series log2 of the block programs (the platform's is a library call)
        let zf = ((levels - 1) as f32 - super::simd::log2(foot.max(1e-9))).clamp(0.0, (levels - 1) as f32);
        let z0 = floor(zf) as u32;
        let z1 = (z0 + 1).min(levels - 1);
        let t = zf - z0 as f32;
        let a = self.bilinear(z0, p);
        let b = if z1 != z0 && t > 0.0 { self.bilinear(z1, p) } else { a };
        std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t)
    }

    /// Texel (tx, ty) of level k of the generic texture, repeating.
    #[inline(always)]
    fn generic_texel(&self, k: u32, tx: i32, ty: i32) -> [f32; 4] {
        let n = (self.u.params[3] >> k).max(1) as i32;
        let (x, y) = (tx.rem_euclid(n) as usize, ty.rem_euclid(n) as usize);
        self.decode(self.generic[k as usize], (y * MAP as usize + x) as i32)
    }

    /// Trilinear from the generic texture at level-0 texel position `p`.
    #[inline(always)]
    fn generic(&self, p: [f32; 2], foot: f32) -> [f32; 4] {
        if self.generic.is_empty() {
            return [1.0; 4];
        }
        let last = self.u.params[2].max(1) - 1;
        let lam = foot.max(1e-9).log2().clamp(0.0, last as f32);
        let k0 = floor(lam) as u32;
        let k1 = (k0 + 1).min(last);
        let t = lam - k0 as f32;
        let one = |k: u32| {
            let s = (1u32 << k) as f32;
            let (x, y) = (p[0] / s - 0.5, p[1] / s - 0.5);
            let (x0, y0) = (floor(x), floor(y));
            let (ix, iy) = (x0 as i32, y0 as i32);
            let c = [
                self.generic_texel(k, ix, iy),
                self.generic_texel(k, ix + 1, iy),
                self.generic_texel(k, ix, iy + 1),
                self.generic_texel(k, ix + 1, iy + 1),
            ];
            lerp2(c, x - x0, y - y0)
        };
        let a = one(k0);
        let b = if k1 != k0 && t > 0.0 { one(k1) } else { a };
        std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t)
    }

    /// Linear RGB of a flat-ground pixel from its texture colour.
    #[inline(always)]
    fn over_ground(s: [f32; 4]) -> [f32; 3] {
        std::array::from_fn(|i| s[i] + GROUND[i] * (1.0 - s[3]))
    }

    /// Linear RGB of flat-ground pixel (px, py), per pixel: the reference
    /// [`Program::shade_flat_lanes`] must equal bit for bit.
    #[cfg(test)]
    fn shade_flat(&self, px: u32, py: u32) -> [f32; 3] {
        let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
        let (Some(p), Some(p1), Some(p2)) = (self.ground(x, y), self.ground(x + 1.0, y), self.ground(x, y + 1.0))
        else {
            return sky(y, self.u.sizes[1] as f32);
        };
        // eq. (2): the largest partial of the screen-to-map mapping
        let foot = (p1[0] - p[0]).abs().max((p1[1] - p[1]).abs()).max((p2[0] - p[0]).abs()).max((p2[1] - p[1]).abs());
        Self::over_ground(self.trilinear(p, foot))
    }
}

#[inline(always)]
fn lerp2(c: [[f32; 4]; 4], fx: f32, fy: f32) -> [f32; 4] {
    std::array::from_fn(|k| {
        let top = c[0][k] + (c[1][k] - c[0][k]) * fx;
        let bot = c[2][k] + (c[3][k] - c[2][k]) * fx;
        top + (bot - top) * fy
    })
}

/// The bilinear reads of 16 lanes inside one map as AVX-512 gathers: the
/// texels of each tap in one gather, each channel's decoding in one gather
/// from its table, blended on whole vectors in [`lerp2`]'s order and
/// operations (no fused multiply-add): the lane loop's bits.
#[cfg(target_arch = "x86_64")]
mod wide {
    use super::{LANES, Lanes, Map};
    use std::arch::x86_64::*;

    /// [`super::Program::footprint_in`] and [`super::lerp2`] for the lanes
    /// of `wanted` (the others 0), all served by map `t` with shift `k`.
    ///
    /// # Safety
    /// The processor runs AVX-512F.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn footprints(
        t: &Map,
        k: u32,
        ix: &[i32; LANES],
        iy: &[i32; LANES],
        fx: &Lanes,
        fy: &Lanes,
        wanted: u16,
        lut: &[f32; 256],
        alpha: &[f32; 256],
    ) -> [Lanes; 4] {
        const _: () = assert!(LANES == 16);
        // SAFETY: 16 lanes in each array
        let (x, y) =
            unsafe { (_mm512_loadu_si512(ix.as_ptr() as *const _), _mm512_loadu_si512(iy.as_ptr() as *const _)) };
        let (fx, fy) = unsafe { (_mm512_loadu_ps(fx.as_ptr()), _mm512_loadu_ps(fy.as_ptr())) };
        let (one, byte, shift) = (_mm512_set1_epi32(1), _mm512_set1_epi32(255), _mm512_set1_epi32(k as i32));
        let col = |v: __m512i| _mm512_and_si512(_mm512_srav_epi32(v, shift), byte);
        let (x0, x1) = (col(x), col(_mm512_add_epi32(x, one)));
        let (y0, y1) = (_mm512_slli_epi32::<8>(col(y)), _mm512_slli_epi32::<8>(col(_mm512_add_epi32(y, one))));
        let at = [_mm512_or_si512(y0, x0), _mm512_or_si512(y0, x1), _mm512_or_si512(y1, x0), _mm512_or_si512(y1, x1)];
        let base = t.as_ptr() as *const u8;
        let mut p = [_mm512_setzero_si512(); 4];
        for (p, at) in p.iter_mut().zip(at) {
            // SAFETY: offsets below 65,536, the map's texel count
            *p = unsafe { _mm512_i32gather_epi32::<4>(at, base as *const _) };
        }
        let mut out = [[0.0f32; LANES]; 4];
        for (c, o) in out.iter_mut().enumerate() {
            let table = if c == 3 { alpha } else { lut };
            let sh = _mm512_set1_epi32(8 * c as i32);
            let mut v = [_mm512_setzero_ps(); 4];
            for (v, p) in v.iter_mut().zip(p) {
                let i = _mm512_and_si512(_mm512_srlv_epi32(p, sh), byte);
                // SAFETY: indices masked to 0..=255, within the table
                *v = unsafe { _mm512_i32gather_ps::<4>(i, table.as_ptr() as *const _) };
            }
            let top = _mm512_add_ps(v[0], _mm512_mul_ps(_mm512_sub_ps(v[1], v[0]), fx));
            let bot = _mm512_add_ps(v[2], _mm512_mul_ps(_mm512_sub_ps(v[3], v[2]), fx));
            let mix = _mm512_maskz_mov_ps(wanted, _mm512_add_ps(top, _mm512_mul_ps(_mm512_sub_ps(bot, top), fy)));
            // SAFETY: 16 f32 in `o`
            unsafe { _mm512_storeu_ps(o.as_mut_ptr(), mix) };
        }
        out
    }
}

fn encode(c: [f32; 3]) -> [u8; 4] {
    [linear_to_srgb_u8(c[0]), linear_to_srgb_u8(c[1]), linear_to_srgb_u8(c[2]), 255]
}

/// One row of flat ground, per pixel (trilinear).
struct FlatRow<'a, 'b> {
    prog: &'a Program<'a>,
    py: u32,
    row: &'b mut [u8],
}

impl pulp::WithSimd for FlatRow<'_, '_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let enc = hitex_core::texture::srgb_encoder();
        for (b, out) in self.row.chunks_mut(4 * LANES).enumerate() {
            let c = self.prog.shade_flat_lanes((b * LANES) as u32, self.py);
            let rgba = super::simd::encode_rgb(enc, &c);
            for (o, p) in out.chunks_exact_mut(4).zip(&rgba) {
                o.copy_from_slice(p);
            }
        }
    }
}

/// Two rows of flat ground, span by span (2×2 pixels).
struct FlatSpanRows<'a, 'b> {
    prog: &'a Program<'a>,
    py: u32,
    pair: &'b mut [u8],
    banks: Option<&'b mut BankModel>,
}

impl pulp::WithSimd for FlatSpanRows<'_, '_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let FlatSpanRows { prog, py, pair, mut banks } = self;
        let enc = hitex_core::texture::srgb_encoder();
        let w = prog.u.sizes[0];
        let two = pair.len() > (w * 4) as usize;
        if banks.is_none() {
            // four spans a block, on lanes
            for bx in 0..w.div_ceil(8) {
                let c = prog.shade_spans_lanes(bx * 8, py);
                let rgba = super::simd::encode_rgb(enc, &c);
                for i in 0..LANES {
                    let (x, y) = (bx * 8 + 2 * (i as u32 / 4) + (i as u32 & 1), (i as u32 >> 1) & 1);
                    if x < w && (y == 0 || two) {
                        let o = ((y * w + x) * 4) as usize;
                        pair[o..o + 4].copy_from_slice(&rgba[i]);
                    }
                }
            }
            return;
        }
        for sx in 0..w.div_ceil(2) {
            let c = prog.shade_flat_span(sx * 2, py, banks.as_deref_mut());
            for (i, c) in c.iter().enumerate() {
                let (x, y) = (sx * 2 + (i as u32 & 1), i as u32 >> 1);
                if x < w && (y == 0 || two) {
                    let o = ((y * w + x) * 4) as usize;
                    pair[o..o + 4].copy_from_slice(&[enc.encode(c[0]), enc.encode(c[1]), enc.encode(c[2]), 255]);
                }
            }
        }
    }
}

/// A flight frame rendered on the CPU, with the span sampler's bank traffic.
pub struct FlyFrame {
    /// The image.
    pub frame: Frame,
    /// Span accesses and conflicts (None for the per-pixel sampler).
    pub banks: Option<BankModel>,
}

fn bind<'a>(
    u: &FlyUniform,
    pages: &'a FlyPages,
    generic: Option<&'a GenericTexture>,
) -> Result<Program<'a>, RenderError> {
    let (w, h) = (u.sizes[0], u.sizes[1]);
    check_size(w, h)?;
    if pages.levels == 0 || pages.origins.len() != pages.levels as usize {
        return Err(RenderError::Invalid("the page table has no levels".into()));
    }
    if pages.levels > 31 {
        // a level's shift to a coarser map's texels stays below 32 bits
        return Err(RenderError::Invalid(format!("the page table has {} levels; at most 31", pages.levels)));
    }
    let per = pages.per_side as usize;
    if pages.slots.len() != pages.levels as usize * per * per
        || u.sizes[2] != pages.levels
        || u.sizes[3] != pages.per_side
    {
        return Err(RenderError::Invalid("the page table does not match the uniforms".into()));
    }
    let slots = pages
        .slots
        .iter()
        .map(|s| s.and_then(|k: MapKey| pages.maps.get(&k).and_then(|t| as_map(t)).map(|t| (k.z, t))))
        .collect();
    let side = generic.map_or(1, |g| g.side);
    let generic: Vec<&Map> = generic
        .map(|g| g.levels.iter().map(|l| as_map(l)).collect::<Option<_>>())
        .unwrap_or(Some(Vec::new()))
        .ok_or_else(|| RenderError::Invalid("a generic texture level is not a full map".into()))?;
    let generic_levels = &generic;
    let mut u = *u;
    u.params[2] = generic_levels.len() as u32;
    u.params[3] = side;
    Ok(Program {
        u,
        pages,
        slots,
        generic,
        lut: decode_table(ColorSpace::Srgb),
        alpha: decode_table(ColorSpace::Linear),
        wide: super::simd::vector_gathers(super::simd::level()),
    })
}

/// Renders one flight frame on the CPU, recording the span sampler's bank
/// traffic (see [`render_fly_with`]).
pub fn render_fly(u: &FlyUniform, pages: &FlyPages, ground: FlyGround<'_>) -> Result<FlyFrame, RenderError> {
    render_fly_with(u, pages, ground, true)
}

/// Renders one flight frame on the CPU; with `stats`, every span access is
/// recorded in a bank model (the frame's [`FlyFrame::banks`]), which costs
/// time a renderer without that question need not spend.
pub fn render_fly_with(
    u: &FlyUniform,
    pages: &FlyPages,
    ground: FlyGround<'_>,
    stats: bool,
) -> Result<FlyFrame, RenderError> {
    let (w, h) = (u.sizes[0], u.sizes[1]);
    let sampler = u.sampler();
    match ground {
        FlyGround::Flat => {
            let prog = bind(u, pages, None)?;
            let mut rgba = vec![0u8; (w * h * 4) as usize];
            let banks = if sampler == FlySampler::Trilinear {
                // each row compiled for the SIMD level in use
                rgba.par_chunks_mut((w * 4) as usize).enumerate().for_each(|(py, row)| {
                    super::simd::run(FlatRow { prog: &prog, py: py as u32, row });
                });
                None
            } else {
                let scheme = if sampler.banks() == 3 { SpanScheme::Banks3x3 } else { SpanScheme::Banks4x4 };
                let rows = (w * 4 * 2) as usize;
                let banks = rgba
                    .par_chunks_mut(rows)
                    .enumerate()
                    .map(|(sy, pair)| {
                        let mut m = BankModel::new(scheme);
                        // each row pair compiled for the SIMD level in use
                        super::simd::run(FlatSpanRows {
                            prog: &prog,
                            py: sy as u32 * 2,
                            pair,
                            banks: stats.then_some(&mut m),
                        });
                        m
                    })
                    .reduce(
                        || BankModel::new(scheme),
                        |mut a, b| {
                            a.merge(b);
                            a
                        },
                    );
                stats.then_some(banks)
            };
            Ok(FlyFrame { frame: Frame { width: w, height: h, rgba }, banks })
        }
        FlyGround::Mesh { mesh, generic } => {
            let prog = bind(u, pages, Some(generic))?;
            render_mesh(&prog, mesh, sampler, stats)
        }
    }
}

fn render_mesh(prog: &Program<'_>, mesh: &FlyMesh, sampler: FlySampler, stats: bool) -> Result<FlyFrame, RenderError> {
    let u = &prog.u;
    let (w, h) = (u.sizes[0], u.sizes[1]);
    if mesh.indices.iter().any(|&i| i as usize >= mesh.vertices.len()) {
        return Err(RenderError::Invalid("a flight mesh index is out of range".into()));
    }
    let positions: Vec<Vec3> = mesh.vertices.iter().map(|v| Vec3::from_array(v.pos)).collect();
    let varyings: Vec<[f32; 4]> = mesh.vertices.iter().map(|v| [v.tex[0], v.tex[1], v.kind, v.shade]).collect();
    let draws =
        [crate::prepare::Draw { first_index: 0, index_count: (mesh.indices.len() / 3 * 3) as u32, material: 0 }];
    let scheme = if sampler.banks() == 3 { SpanScheme::Banks3x3 } else { SpanScheme::Banks4x4 };
    let threads = if stats { rayon::current_num_threads().max(1) } else { 0 };
    let shader = MeshProgram { prog, banks: (0..threads).map(|_| Mutex::new(BankModel::new(scheme))).collect() };
    let mut target = Target::deferred(w, h, [0, 0, 0, 255]);
    let vp = Mat4::from_cols_array_2d(&u.view_proj);
    rasterize(&mut target, vp, &positions, &varyings, &mesh.indices, &draws, &shader);
    // the sky where nothing was drawn
    for (i, (c, d)) in target.color.iter_mut().zip(&target.depth).enumerate() {
        if *d >= 1.0 {
            *c = encode(sky((i / w as usize) as f32 + 0.5, h as f32));
        }
    }
    let banks = (stats && sampler != FlySampler::Trilinear).then(|| {
        let mut all = BankModel::new(scheme);
        for m in shader.banks {
            if let Ok(m) = m.into_inner() {
                all.merge(m);
            }
        }
        all
    });
    Ok(FlyFrame { frame: Frame { width: w, height: h, rgba: target.into_rgba() }, banks })
}
