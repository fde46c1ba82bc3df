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

use super::raster::{QuadShader, Target, rasterize};
use crate::terrain::{FlyGround, FlyMesh, FlyPages, FlySampler, FlyUniform, GROUND, GenericTexture, MAP, sky};
use crate::{Frame, RenderError, check_size};
use glam::{Mat4, Vec3};
use hitex_core::residency::MapKey;
use hitex_core::texture::image::decode_table;
use hitex_core::texture::sampler::floor;
use hitex_core::texture::span::{BankModel, SpanScheme};
use hitex_core::texture::{ColorSpace, linear_to_srgb_u8};
use rayon::prelude::*;
use std::sync::Mutex;

/// Virtual levels a span may read beyond the coarsest (as the shader).
const VIRTUAL: i32 = 24;

struct Program<'a> {
    u: FlyUniform,
    pages: &'a FlyPages,
    /// The page table resolved to texels: per slot, (level of the serving map, its texels).
    slots: Vec<Option<(u32, &'a [u8])>>,
    generic: Vec<&'a [u8]>,
    lut: &'static [f32; 256],
}

/// Per-axis filter taps: texel indices and weights (2 or 4 used).
#[derive(Clone, Copy)]
struct Axis {
    i: [i32; 4],
    w: [f32; 4],
}

fn catmull_rom(t: f32) -> [f32; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    [0.5 * (-t3 + 2.0 * t2 - t), 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0), 0.5 * (-3.0 * t3 + 4.0 * t2 + t), 0.5 * (t3 - t2)]
}

/// Taps on one axis at texel position `q` inside the block `o ..= o + b − 1`.
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

    #[inline(always)]
    fn decode(&self, t: &[u8], i: usize) -> [f32; 4] {
        let Some(p) = t.get(i..i + 4) else { return [0.0; 4] };
        [self.lut[p[0] as usize], self.lut[p[1] as usize], self.lut[p[2] as usize], p[3] as f32 / 255.0]
    }

    /// The map serving texel (tx, ty) of level z through the page table, and
    /// the shift from level z's texels to that map's: None where no data lies.
    #[inline(always)]
    fn serving(&self, z: u32, tx: i32, ty: i32) -> Option<(&[u8], u32)> {
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
            Some((t, k)) => self.decode(t, ((((ty >> k) & 255) << 8 | ((tx >> k) & 255)) * 4) as usize),
            None => [0.0; 4],
        }
    }

    #[inline(always)]
    fn bilinear(&self, z: u32, p: [f32; 2]) -> [f32; 4] {
        let s = (1u32 << (self.pages.levels - 1 - z)) as f32;
        let (x, y) = (p[0] / s - 0.5, p[1] / s - 0.5);
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let (ix, iy) = (x0 as i32, y0 as i32);
        // the four texels share one map unless they straddle a map edge: resolve it once
        if ix & 255 != 255 && iy & 255 != 255 {
            let Some((t, k)) = self.serving(z, ix, iy) else { return [0.0; 4] };
            let (x0, x1) = ((ix >> k) & 255, ((ix + 1) >> k) & 255);
            let (y0, y1) = (((iy >> k) & 255) << 8, (((iy + 1) >> k) & 255) << 8);
            let c = [
                self.decode(t, ((y0 | x0) * 4) as usize),
                self.decode(t, ((y0 | x1) * 4) as usize),
                self.decode(t, ((y1 | x0) * 4) as usize),
                self.decode(t, ((y1 | x1) * 4) as usize),
            ];
            return lerp2(c, fx, fy);
        }
        let c = [
            self.texel(z, ix, iy),
            self.texel(z, ix + 1, iy),
            self.texel(z, ix, iy + 1),
            self.texel(z, ix + 1, iy + 1),
        ];
        lerp2(c, fx, fy)
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
        self.decode(self.generic[k as usize], (y * MAP as usize + x) * 4)
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

    /// Filters lane `me` of a span at finest-numbered level `k` (virtual above the coarsest).
    #[inline(always)]
    fn span_level(
        &self,
        pts: &[Option<[f32; 2]>; 4],
        k: i32,
        b: i32,
        bicubic: bool,
        banks: Option<&mut BankModel>,
    ) -> [[f32; 4]; 4] {
        let last = self.pages.levels as i32 - 1;
        let read = |k: i32| -> ([i32; 2], [Option<[Axis; 2]>; 4]) {
            let s = (-(k as f32)).exp2();
            let q = pts.map(|p| p.map(|p| [p[0] * s - 0.5, p[1] * s - 0.5]));
            let mut origin = [0i32; 2];
            for (a, o) in origin.iter_mut().enumerate() {
                let lo = q.iter().flatten().map(|q| floor(q[a]) as i32).min().unwrap_or(0);
                let hi = q.iter().flatten().map(|q| floor(q[a]) as i32).max().unwrap_or(0);
                *o = if bicubic { lo - 1 + (hi - lo + 4 - b).max(0) / 2 } else { lo };
            }
            let taps = q.map(|q| q.map(|q| [axis(q[0], bicubic, origin[0], b), axis(q[1], bicubic, origin[1], b)]));
            (origin, taps)
        };
        let (origin, taps) = read(k);
        if let Some(banks) = banks {
            let n = if bicubic { 4 } else { 2 };
            let mut texels = Vec::with_capacity(64);
            for [ax, ay] in taps.iter().flatten() {
                for &y in &ay.i[..n] {
                    for &x in &ax.i[..n] {
                        texels.push([x as i64, y as i64]);
                    }
                }
            }
            banks.record(k as usize, [origin[0] as i64, origin[1] as i64], &texels);
        }
        // a virtual level takes the coarsest level's values
        let (z, taps) = if k > last { (0u32, read(last).1) } else { ((last - k) as u32, taps) };
        taps.map(|t| {
            let Some([ax, ay]) = t else { return [0.0; 4] };
            if !bicubic {
                let c = [
                    self.texel(z, ax.i[0], ay.i[0]),
                    self.texel(z, ax.i[1], ay.i[0]),
                    self.texel(z, ax.i[0], ay.i[1]),
                    self.texel(z, ax.i[1], ay.i[1]),
                ];
                return lerp2(c, ax.w[1], ay.w[1]);
            }
            let mut acc = [0.0f32; 4];
            let (mut lo, mut hi) = ([f32::INFINITY; 4], [f32::NEG_INFINITY; 4]);
            for j in 0..4 {
                for i in 0..4 {
                    let c = self.texel(z, ax.i[i], ay.i[j]);
                    let w = ax.w[i] * ay.w[j];
                    for ch in 0..4 {
                        acc[ch] += c[ch] * w;
                        lo[ch] = lo[ch].min(c[ch]);
                        hi[ch] = hi[ch].max(c[ch]);
                    }
                }
            }
            std::array::from_fn(|ch| acc[ch].clamp(lo[ch], hi[ch]))
        })
    }

    /// The span sampler over the four points of a span (None: no ground there).
    #[inline(always)]
    fn span(
        &self,
        pts: [Option<[f32; 2]>; 4],
        sampler: FlySampler,
        mut banks: Option<&mut BankModel>,
    ) -> [[f32; 4]; 4] {
        let b = sampler.banks() as i32;
        let bicubic = sampler == FlySampler::Bicubic;
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for p in pts.iter().flatten() {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        if lo[0] > hi[0] {
            return [[0.0; 4]; 4];
        }
        let e = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let lam = (2.0 * e / (b - 2) as f32).log2();
        let cap = self.pages.levels as i32 - 1 + VIRTUAL;
        let (mut k, mut g) = (0i32, 0.0f32);
        if lam > 0.0 {
            let f = floor(lam);
            (k, g) = if f >= cap as f32 { (cap, 0.0) } else { (f as i32, lam - f) };
        }
        // rounding guard: the finer level's bilinear footprint must fit B texels
        let fits = |k: i32| {
            let s = (-(k as f32)).exp2();
            (0..2).all(|a| floor(hi[a] * s - 0.5) - floor(lo[a] * s - 0.5) + 2.0 <= b as f32)
        };
        let mut raised = false;
        while k < cap && !fits(k) {
            k += 1;
            raised = true;
        }
        if let Some(m) = banks.as_deref_mut() {
            m.spans += 1;
            m.guard_raises += u64::from(raised);
            m.level_sum += k as f64 + g as f64;
        }
        let c0 = self.span_level(&pts, k, b, bicubic, banks.as_deref_mut());
        if g <= 0.0 {
            return c0;
        }
        let c1 = self.span_level(&pts, k + 1, b, bicubic, banks);
        std::array::from_fn(|i| std::array::from_fn(|ch| c0[i][ch] + (c1[i][ch] - c0[i][ch]) * g))
    }

    /// Linear RGB of a flat-ground pixel from its texture colour.
    #[inline(always)]
    fn over_ground(s: [f32; 4]) -> [f32; 3] {
        std::array::from_fn(|i| s[i] + GROUND[i] * (1.0 - s[3]))
    }

    /// Linear RGB of flat-ground pixel (px, py), per pixel.
    #[inline(always)]
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

    /// Linear RGB of the flat-ground span whose top-left pixel is (px, py).
    #[inline(always)]
    fn shade_flat_span(&self, px: u32, py: u32, banks: Option<&mut BankModel>) -> [[f32; 3]; 4] {
        let pts: [Option<[f32; 2]>; 4] = std::array::from_fn(|i| {
            self.ground((px + (i as u32 & 1)) as f32 + 0.5, (py + (i as u32 >> 1)) as f32 + 0.5)
        });
        let c = self.span(pts, self.u.sampler(), banks);
        std::array::from_fn(|i| match pts[i] {
            Some(_) => Self::over_ground(c[i]),
            None => sky((py + (i as u32 >> 1)) as f32 + 0.5, self.u.sizes[1] as f32),
        })
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
        for (px, o) in self.row.chunks_exact_mut(4).enumerate() {
            let c = self.prog.shade_flat(px as u32, self.py);
            o.copy_from_slice(&[enc.encode(c[0]), enc.encode(c[1]), enc.encode(c[2]), 255]);
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

/// The mesh fragment program: lanes (0,0) (1,0) (0,1) (1,1) of a quad;
/// varyings map x, map y, kind, light.
struct MeshProgram<'a> {
    prog: &'a Program<'a>,
    /// Bank models, one per worker thread (empty: no statistics).
    banks: Vec<Mutex<BankModel>>,
}

impl QuadShader<4> for MeshProgram<'_> {
    fn shade(&self, _material: usize, v: &[[f32; 4]; 4], _w: [f32; 4], _live: u8) -> [[u8; 4]; 4] {
        let p: [[f32; 2]; 4] = std::array::from_fn(|i| [v[i][0], v[i][1]]);
        // fine differences, as dpdxFine / dpdyFine
        let dx = |row: usize| [p[2 * row + 1][0] - p[2 * row][0], p[2 * row + 1][1] - p[2 * row][1]];
        let dy = |col: usize| [p[col + 2][0] - p[col][0], p[col + 2][1] - p[col][1]];
        let foot = |i: usize| {
            let (a, b) = (dx(i >> 1), dy(i & 1));
            a[0].abs().max(a[1].abs()).max(b[0].abs()).max(b[1].abs())
        };
        let kind = v[0][2];
        let colour: [[f32; 4]; 4] = if kind > 0.5 {
            std::array::from_fn(|i| self.prog.generic(p[i], foot(i)))
        } else {
            match self.prog.u.sampler() {
                FlySampler::Trilinear => std::array::from_fn(|i| self.prog.trilinear(p[i], foot(i))),
                s if self.banks.is_empty() => self.prog.span(p.map(Some), s, None),
                s => {
                    let slot = rayon::current_thread_index().unwrap_or(0) % self.banks.len();
                    match self.banks[slot].lock() {
                        Ok(mut m) => self.prog.span(p.map(Some), s, Some(&mut m)),
                        Err(_) => self.prog.span(p.map(Some), s, None),
                    }
                }
            }
        };
        std::array::from_fn(|i| {
            let l = v[i][3];
            let c = colour[i];
            if kind > 0.5 { encode([c[0] * l, c[1] * l, c[2] * l]) } else { encode(Program::over_ground(c)) }
        })
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
        .map(|s| {
            s.and_then(|k: MapKey| {
                pages.maps.get(&k).filter(|t| t.len() >= (MAP * MAP * 4) as usize).map(|t| (k.z, t.as_slice()))
            })
        })
        .collect();
    let side = generic.map_or(1, |g| g.side);
    let generic: Vec<&[u8]> = generic.map(|g| g.levels.iter().map(|l| l.as_slice()).collect()).unwrap_or_default();
    let generic_levels = &generic;
    if generic.iter().any(|l| l.len() < (MAP * MAP * 4) as usize) {
        return Err(RenderError::Invalid("a generic texture level is not a full map".into()));
    }
    let mut u = *u;
    u.params[2] = generic_levels.len() as u32;
    u.params[3] = side;
    Ok(Program { u, pages, slots, generic, lut: decode_table(ColorSpace::Srgb) })
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
    let mut target = Target::new(w, h, [0, 0, 0, 255]);
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
