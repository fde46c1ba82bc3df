//! The texture sampler of the CPU programs on a block's 16 lanes: the lane
//! twin of `hitex_core::texture::sample` (nearest, bilinear, trilinear with
//! either level rule), RGBA8 texels decoded to linear light by table.
//!
//! Coordinates, level selection (a series `log2`, [`super::simd::log2`]),
//! wrapping and the blends run on whole lane vectors; only the texel reads
//! and their decoding go lane by lane (a gather), and a lane whose trilinear
//! blend weight is 0 reads one level only. Colour channels only: alpha is not
//! filtered, as no program uses it.

// lane loops index several arrays by the same lane, as the lane code reads
#![allow(clippy::needless_range_loop)]

use super::simd::{self, LANES, Lanes, lanes};
use hitex_core::texture::{Filter, LevelRule, MipPyramid, SamplerOptions, Wrap};

/// One level's texels and size.
struct Level<'a> {
    texels: &'a [[u8; 4]],
    width: u32,
    height: u32,
}

/// A pyramid bound with its sampler options.
pub struct LaneSampler<'a> {
    levels: Vec<Level<'a>>,
    opts: SamplerOptions,
    lut: &'static [f32; 256],
    /// True when the program runs at AVX-512 with fast gathers
    /// ([`simd::vector_gathers`]): the bilinear reads then go through
    /// [`wide::bilinear`]'s vector gathers.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    wide: bool,
}

/// The screen-to-texture Jacobian of a block, per lane (uv per pixel).
pub struct LaneJacobian {
    /// ∂u/∂x
    pub du_dx: Lanes,
    /// ∂v/∂x
    pub dv_dx: Lanes,
    /// ∂u/∂y
    pub du_dy: Lanes,
    /// ∂v/∂y
    pub dv_dy: Lanes,
}

/// Linear RGB per lane.
pub type Rgb = [Lanes; 3];

impl<'a> LaneSampler<'a> {
    /// Binds `pyr` with `opts`.
    pub fn new(pyr: &'a MipPyramid, opts: SamplerOptions) -> Self {
        let levels =
            pyr.levels().iter().map(|l| Level { texels: l.texels(), width: l.width(), height: l.height() }).collect();
        let wide = simd::vector_gathers(simd::level_for_gathers());
        Self { levels, opts, lut: hitex_core::texture::image::decode_table(pyr.color_space()), wide }
    }

    /// λ per lane (levels below level 0, unclamped; −∞ where the footprint is
    /// zero or not finite), as `hitex_core::texture::level_of_detail`.
    #[inline(always)]
    pub fn level_of_detail(&self, j: &LaneJacobian) -> Lanes {
        let (w, h) = (self.levels[0].width as f32, self.levels[0].height as f32);
        let mut o = [0.0; LANES];
        for i in 0..LANES {
            let (ux, vx, uy, vy) = (j.du_dx[i] * w, j.dv_dx[i] * h, j.du_dy[i] * w, j.dv_dy[i] * h);
            let rho = match self.opts.level_rule {
                LevelRule::MaxPartial => ux.abs().max(vx.abs()).max(uy.abs()).max(vy.abs()),
                LevelRule::VulkanRho => (ux * ux + vx * vx).sqrt().max((uy * uy + vy * vy).sqrt()),
            };
            let l = simd::log2(rho);
            o[i] = if rho > 0.0 && rho < f32::INFINITY { l } else { f32::NEG_INFINITY };
        }
        o
    }

    /// Samples at (`u`, `v`) with the footprint `j`: linear RGB per lane.
    /// Lanes outside `live` (helpers) return a colour nobody sees.
    #[inline(always)]
    pub fn sample(&self, u: &Lanes, v: &Lanes, j: &LaneJacobian, live: u16) -> Rgb {
        let (u, v) = (self.reduce(u), self.reduce(v));
        match self.opts.filter {
            Filter::Nearest => self.nearest(&u, &v),
            Filter::Bilinear => self.trilinear(&[0; LANES], &[0; LANES], &[0.0; LANES], false, &u, &v, live),
            Filter::Trilinear => {
                let lambda = self.level_of_detail(j);
                let max_level = (self.levels.len() - 1) as f32;
                let mut l0 = [0u8; LANES];
                let mut l1 = [0u8; LANES];
                let mut gamma = [0.0; LANES];
                let mut blend = 0u16;
                for i in 0..LANES {
                    let l = lambda[i] + self.opts.lod_bias;
                    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, max_level) };
                    let f = simd::floor(l);
                    gamma[i] = l - f;
                    l0[i] = simd::whole_u32(f) as u8;
                    l1[i] = (l0[i] + 1).min(max_level as u8);
                    blend |= ((gamma[i] > 0.0) as u16) << i;
                }
                self.trilinear(&l0, &l1, &gamma, live & blend != 0, &u, &v, live)
            }
        }
    }

    /// Non-finite coordinates to the origin, the rest into one period of
    /// the wrap mode (`hitex_core::texture::sampler::reduce`).
    #[inline(always)]
    fn reduce(&self, t: &Lanes) -> Lanes {
        let mut o = [0.0; LANES];
        match self.opts.wrap {
            Wrap::Repeat => {
                for i in 0..LANES {
                    let t = if t[i].is_finite() { t[i] } else { 0.0 };
                    o[i] = t - simd::floor(t);
                }
            }
            Wrap::Mirror => {
                for i in 0..LANES {
                    let t = if t[i].is_finite() { t[i] } else { 0.0 };
                    o[i] = t - 2.0 * simd::floor(t * 0.5);
                }
            }
            Wrap::Clamp => {
                for i in 0..LANES {
                    let t = if t[i].is_finite() { t[i] } else { 0.0 };
                    o[i] = t.clamp(-1.0, 2.0);
                }
            }
        }
        o
    }

    /// Texel index per lane on an axis of `n` texels under the wrap mode,
    /// as `hitex_core::texture::wrap_index` (indices are whole floats).
    ///
    /// The sampler's own indices lie within a period of `[0, n)` (its
    /// coordinates are reduced first, and a tap steps one texel out at
    /// most): there a repeat or mirror period is added or taken once, by a
    /// compare and a select, instead of the division and floor of the
    /// general formula, whose result it is exactly (whole floats below 2²⁴,
    /// where `f / n` cannot round across an integer). A block with any lane
    /// farther out (or NaN) takes the general formula.
    #[inline(always)]
    fn wrap(&self, f: &Lanes, n: &Lanes) -> Lanes {
        let mut o = [0.0; LANES];
        // lanes within one period of [0, p) either side
        let near = |p: &Lanes| {
            let mut all = true;
            for i in 0..LANES {
                all &= (f[i] >= -p[i]) & (f[i] < 2.0 * p[i]);
            }
            all
        };
        match self.opts.wrap {
            Wrap::Repeat => {
                if near(n) {
                    for i in 0..LANES {
                        let m = if f[i] < 0.0 { f[i] + n[i] } else { f[i] };
                        o[i] = if m >= n[i] { m - n[i] } else { m };
                    }
                } else {
                    for i in 0..LANES {
                        let m = f[i] - n[i] * simd::floor(f[i] / n[i]);
                        o[i] = if (f[i] >= 0.0) & (f[i] < n[i]) { f[i] } else { m };
                    }
                }
            }
            Wrap::Clamp => {
                for i in 0..LANES {
                    o[i] = f[i].max(0.0).min(n[i] - 1.0);
                }
            }
            Wrap::Mirror => {
                let p: Lanes = lanes!(|i| 2.0 * n[i]);
                if near(&p) {
                    for i in 0..LANES {
                        let m = if f[i] < 0.0 { f[i] + p[i] } else { f[i] };
                        let m = if m >= p[i] { m - p[i] } else { m };
                        o[i] = if m >= n[i] { p[i] - 1.0 - m } else { m };
                    }
                } else {
                    for i in 0..LANES {
                        let m = f[i] - p[i] * simd::floor(f[i] / p[i]);
                        let m = if m >= n[i] { p[i] - 1.0 - m } else { m };
                        o[i] = if (f[i] >= 0.0) & (f[i] < n[i]) { f[i] } else { m };
                    }
                }
            }
        }
        o
    }

    #[inline(always)]
    fn nearest(&self, u: &Lanes, v: &Lanes) -> Rgb {
        let l = &self.levels[0];
        let (w, h) = ([l.width as f32; LANES], [l.height as f32; LANES]);
        let x = self.wrap(&lanes!(|i| simd::floor(u[i] * w[i])), &w);
        let y = self.wrap(&lanes!(|i| simd::floor(v[i] * h[i])), &h);
        let mut out = [[1.0; LANES]; 3];
        let texels: &[u32] = bytemuck::cast_slice(l.texels);
        let Some(last) = texels.len().checked_sub(1) else { return out };
        // every lane reads (helpers too, at indices as valid as any): no branch
        for i in 0..LANES {
            let at = simd::whole_u32(y[i]).wrapping_mul(l.width).wrapping_add(simd::whole_u32(x[i]));
            let p = texels[(at as usize).min(last)];
            for c in 0..3 {
                out[c][i] = self.lut[((p >> (8 * c)) & 0xff) as usize];
            }
        }
        out
    }

    /// Eq. (4)'s t_c per lane: the bilinear lookup in level `l0[lane]`,
    /// and when `blend`, the one in `l1[lane]` mixed in by `gamma[lane]`
    /// (`c0 + (c1 − c0)·γ`). Coordinates, wrapping and weights run on lane
    /// vectors; then each lane reads its texels and blends them at once
    /// (blending as vectors afterwards would load values just stored one
    /// lane at a time, which the store buffer cannot forward). Every lane
    /// reads (a helper lane's indices are as valid as any), so the reads have
    /// no branch; when the live lanes share their levels (almost always)
    /// the levels' sizes and texels are hoisted out of the lanes.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn trilinear(
        &self,
        l0: &[u8; LANES],
        l1: &[u8; LANES],
        gamma: &Lanes,
        blend: bool,
        u: &Lanes,
        v: &Lanes,
        live: u16,
    ) -> Rgb {
        let first = (live.trailing_zeros() as usize).min(LANES - 1);
        let mut same = true;
        for i in 0..LANES {
            same &= (live & (1 << i) == 0) | ((l0[i] == l0[first]) & (l1[i] == l1[first]));
        }
        let mut out = [[1.0; LANES]; 3];
        let last_level = self.levels.len() - 1;
        if same {
            let a = &self.levels[(l0[first] as usize).min(last_level)];
            let b = &self.levels[(l1[first] as usize).min(last_level)];
            let (ta, tb): (&[u32], &[u32]) = (bytemuck::cast_slice(a.texels), bytemuck::cast_slice(b.texels));
            let (Some(la), Some(lb)) = (ta.len().checked_sub(1), tb.len().checked_sub(1)) else { return out };
            let pa = self.taps(&[a.width as f32; LANES], &[a.height as f32; LANES], u, v);
            #[cfg(target_arch = "x86_64")]
            if self.wide && la <= i32::MAX as usize && lb <= i32::MAX as usize {
                // SAFETY: `wide` is set only where the processor runs
                // AVX-512F; the offsets are clamped to `la`, `lb`, which are
                // below each slice's length and within the gathers' i32 range
                let c0 = unsafe { wide::bilinear(ta, la as u32, &pa, self.lut) };
                if !blend {
                    return c0;
                }
                let pb = self.taps(&[b.width as f32; LANES], &[b.height as f32; LANES], u, v);
                // SAFETY: as above
                let c1 = unsafe { wide::bilinear(tb, lb as u32, &pb, self.lut) };
                for c in 0..3 {
                    out[c] = lanes!(|i| c0[c][i] + (c1[c][i] - c0[c][i]) * gamma[i]);
                }
                return out;
            }
            if blend {
                let pb = self.taps(&[b.width as f32; LANES], &[b.height as f32; LANES], u, v);
                for i in 0..LANES {
                    let c0 = self.read(ta, la, &pa, i);
                    let c1 = self.read(tb, lb, &pb, i);
                    for c in 0..3 {
                        out[c][i] = c0[c] + (c1[c] - c0[c]) * gamma[i];
                    }
                }
            } else {
                for i in 0..LANES {
                    let c0 = self.read(ta, la, &pa, i);
                    for c in 0..3 {
                        out[c][i] = c0[c];
                    }
                }
            }
        } else {
            // lanes on different levels: sizes and texels lane by lane
            let size = |l: &[u8; LANES]| -> (Lanes, Lanes) {
                let mut w = [1.0; LANES];
                let mut h = [1.0; LANES];
                for i in 0..LANES {
                    let lv = &self.levels[(l[i] as usize).min(last_level)];
                    (w[i], h[i]) = (lv.width as f32, lv.height as f32);
                }
                (w, h)
            };
            let (wa, ha) = size(l0);
            let pa = self.taps(&wa, &ha, u, v);
            let (wb, hb) = size(l1);
            let pb = self.taps(&wb, &hb, u, v);
            for i in 0..LANES {
                let a = &self.levels[(l0[i] as usize).min(last_level)];
                let ta: &[u32] = bytemuck::cast_slice(a.texels);
                let Some(la) = ta.len().checked_sub(1) else { continue };
                let c0 = self.read(ta, la, &pa, i);
                let c1 = if blend {
                    let b = &self.levels[(l1[i] as usize).min(last_level)];
                    let tb: &[u32] = bytemuck::cast_slice(b.texels);
                    let Some(lb) = tb.len().checked_sub(1) else { continue };
                    self.read(tb, lb, &pb, i)
                } else {
                    c0
                };
                for c in 0..3 {
                    out[c][i] = c0[c] + (c1[c] - c0[c]) * gamma[i];
                }
            }
        }
        out
    }

    /// The bilinear footprint per lane in a level of `w` × `h` texels: the
    /// four texels around `uv·size − ½` (offsets, wrapped) and the
    /// fractional position.
    #[inline(always)]
    fn taps(&self, w: &Lanes, h: &Lanes, u: &Lanes, v: &Lanes) -> Taps {
        let x: Lanes = lanes!(|i| u[i] * w[i] - 0.5);
        let y: Lanes = lanes!(|i| v[i] * h[i] - 0.5);
        let xf: Lanes = lanes!(|i| simd::floor(x[i]));
        let yf: Lanes = lanes!(|i| simd::floor(y[i]));
        let alpha: Lanes = lanes!(|i| x[i] - xf[i]);
        let beta: Lanes = lanes!(|i| y[i] - yf[i]);
        let xa = self.wrap(&xf, w);
        let xb = self.wrap(&lanes!(|i| xf[i] + 1.0), w);
        let ya = self.wrap(&yf, h);
        let yb = self.wrap(&lanes!(|i| yf[i] + 1.0), h);
        // texel offsets as integers (exact beyond 2^24 texels)
        let mut at = [[0u32; LANES]; 4];
        for i in 0..LANES {
            let stride = simd::whole_u32(w[i]);
            let (ra, rb) = (simd::whole_u32(ya[i]).wrapping_mul(stride), simd::whole_u32(yb[i]).wrapping_mul(stride));
            let (ca, cb) = (simd::whole_u32(xa[i]), simd::whole_u32(xb[i]));
            at[0][i] = ra.wrapping_add(ca);
            at[1][i] = ra.wrapping_add(cb);
            at[2][i] = rb.wrapping_add(ca);
            at[3][i] = rb.wrapping_add(cb);
        }
        Taps { at, alpha, beta }
    }

    /// Lane `i`'s four texels of `taps` in `texels` (indices clamped to
    /// `last`), decoded and blended: top row by α, bottom row by α, then
    /// the rows by β.
    #[inline(always)]
    fn read(&self, texels: &[u32], last: usize, taps: &Taps, i: usize) -> [f32; 3] {
        let p0 = texels[(taps.at[0][i] as usize).min(last)];
        let p1 = texels[(taps.at[1][i] as usize).min(last)];
        let p2 = texels[(taps.at[2][i] as usize).min(last)];
        let p3 = texels[(taps.at[3][i] as usize).min(last)];
        let (alpha, beta) = (taps.alpha[i], taps.beta[i]);
        let lut = self.lut;
        let mut o = [0.0; 3];
        for c in 0..3 {
            let s = 8 * c as u32;
            let t = |p: u32| lut[((p >> s) & 0xff) as usize];
            let top = t(p0) + (t(p1) - t(p0)) * alpha;
            let bottom = t(p2) + (t(p3) - t(p2)) * alpha;
            o[c] = top + (bottom - top) * beta;
        }
        o
    }
}

/// The bilinear reads of 16 lanes as AVX-512 gathers: each tap's texels in
/// one gather, each channel's decoding in one gather from the 256-entry
/// table, the blends on whole vectors in [`LaneSampler::read`]'s order and
/// operations (no fused multiply-add), so the result is the lane loop's bit
/// for bit.
#[cfg(target_arch = "x86_64")]
mod wide {
    use super::{LANES, Rgb, Taps};
    use std::arch::x86_64::*;

    /// [`super::LaneSampler::read`] for all 16 lanes at once.
    ///
    /// # Safety
    /// The processor runs AVX-512F; `last < texels.len()` and
    /// `last <= i32::MAX`.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn bilinear(texels: &[u32], last: u32, taps: &Taps, lut: &[f32; 256]) -> Rgb {
        const _: () = assert!(LANES == 16);
        let cap = _mm512_set1_epi32(last as i32);
        let base = texels.as_ptr() as *const u8;
        let mut p = [_mm512_setzero_si512(); 4];
        for k in 0..4 {
            // SAFETY: 16 u32 in `at[k]`; offsets clamped to `last`, in bounds
            let at = unsafe { _mm512_loadu_si512(taps.at[k].as_ptr() as *const _) };
            p[k] = unsafe { _mm512_i32gather_epi32::<4>(_mm512_min_epu32(at, cap), base as *const _) };
        }
        let alpha = unsafe { _mm512_loadu_ps(taps.alpha.as_ptr()) };
        let beta = unsafe { _mm512_loadu_ps(taps.beta.as_ptr()) };
        let byte = _mm512_set1_epi32(0xff);
        let table = lut.as_ptr() as *const u8;
        let mut out: Rgb = [[0.0; LANES]; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let shift = _mm512_set1_epi32(8 * c as i32);
            let mut t = [_mm512_setzero_ps(); 4];
            for k in 0..4 {
                let i = _mm512_and_si512(_mm512_srlv_epi32(p[k], shift), byte);
                // SAFETY: indices masked to 0..=255, within the table
                t[k] = unsafe { _mm512_i32gather_ps::<4>(i, table as *const _) };
            }
            let top = _mm512_add_ps(t[0], _mm512_mul_ps(_mm512_sub_ps(t[1], t[0]), alpha));
            let bottom = _mm512_add_ps(t[2], _mm512_mul_ps(_mm512_sub_ps(t[3], t[2]), alpha));
            let mix = _mm512_add_ps(top, _mm512_mul_ps(_mm512_sub_ps(bottom, top), beta));
            // SAFETY: 16 f32 in `o`
            unsafe { _mm512_storeu_ps(o.as_mut_ptr(), mix) };
        }
        out
    }
}

/// A level's bilinear footprint per lane: the four texel offsets (top left,
/// top right, bottom left, bottom right) and the blend weights.
struct Taps {
    at: [[u32; LANES]; 4],
    alpha: Lanes,
    beta: Lanes,
}

#[cfg(test)]
mod tests {
    use super::*;
    use hitex_core::texture::image::{ColorSpace, Image};
    use hitex_core::texture::{Jacobian, sample};

    fn pyramid(cs: ColorSpace) -> MipPyramid {
        let img = Image::from_fn(37, 20, cs, |x, y| {
            [(x * 7 + y * 3) as u8, (x * x + 5 * y) as u8, ((y * 11) ^ x) as u8, 255]
        })
        .unwrap();
        MipPyramid::build(img)
    }

    /// Every filter, wrap and level rule agrees with the scalar sampler
    /// (trilinear to the series `log2`'s error: 1e-5 of a level).
    #[test]
    fn lanes_agree_with_the_scalar_sampler() {
        for cs in [ColorSpace::Srgb, ColorSpace::Linear] {
            let pyr = pyramid(cs);
            for filter in [Filter::Nearest, Filter::Bilinear, Filter::Trilinear] {
                for wrap in [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror] {
                    for level_rule in [LevelRule::MaxPartial, LevelRule::VulkanRho] {
                        let opts = SamplerOptions { filter, wrap, level_rule, lod_bias: 0.25 };
                        let s = LaneSampler::new(&pyr, opts);
                        let mut worst = 0.0f32;
                        for k in 0..200 {
                            let f = |i: usize, a: f32| ((k * 16 + i) as f32 * a).sin() * 3.0;
                            let u: Lanes = std::array::from_fn(|i| f(i, 0.731));
                            let v: Lanes = std::array::from_fn(|i| f(i, 1.377));
                            let d = |a: f32| -> Lanes { std::array::from_fn(|i| f(i, a) * 0.05) };
                            let j = LaneJacobian { du_dx: d(0.31), dv_dx: d(0.17), du_dy: d(0.53), dv_dy: d(0.29) };
                            let live = if k % 3 == 0 { 0xffff } else { 0x5a5a };
                            let got = s.sample(&u, &v, &j, live);
                            for i in 0..LANES {
                                if live & (1 << i) == 0 {
                                    continue;
                                }
                                let jac = Jacobian {
                                    du_dx: j.du_dx[i],
                                    dv_dx: j.dv_dx[i],
                                    du_dy: j.du_dy[i],
                                    dv_dy: j.dv_dy[i],
                                };
                                let want = sample(&pyr, &opts, glam::Vec2::new(u[i], v[i]), jac);
                                for c in 0..3 {
                                    worst = worst.max((got[c][i] - want[c]).abs());
                                }
                            }
                        }
                        let tol = if filter == Filter::Trilinear { 2e-5 } else { 1e-6 };
                        assert!(worst <= tol, "{cs:?} {filter:?} {wrap:?} {level_rule:?}: {worst}");
                    }
                }
            }
        }
    }

    /// Both ways of wrapping (a period added or taken once, near the
    /// texture; the general formula, farther out) give the integer wrap of
    /// `hitex_core::texture::wrap_index`, on blocks wholly near, wholly far
    /// and mixed.
    #[test]
    fn wrap_matches_the_integer_wrap_near_and_far() {
        let pyr = pyramid(ColorSpace::Linear);
        for wrap in [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp] {
            let s = LaneSampler::new(&pyr, SamplerOptions { wrap, ..Default::default() });
            for n in [1i32, 2, 3, 7, 64, 1000, 16384] {
                let span = 5 * n + 6;
                let all: Vec<i32> = (-2 * n - 3..=3 * n + 3).collect();
                let far: Vec<i32> = (0..LANES as i32).map(|k| k * span / 3 - 2 * span).collect();
                for (k, chunk) in all.chunks(LANES).chain(std::iter::once(&far[..])).enumerate() {
                    let mut f: Lanes = std::array::from_fn(|i| chunk[i % chunk.len()] as f32);
                    if k % 5 == 4 {
                        f[7] = (40 * n + 11) as f32; // one lane far out: the general formula
                    }
                    let got = s.wrap(&f, &[n as f32; LANES]);
                    for i in 0..LANES {
                        let want = hitex_core::texture::sampler::wrap_index(f[i] as i32, n, wrap) as f32;
                        assert_eq!(got[i].to_bits(), want.to_bits(), "{wrap:?} n {n} f {}", f[i]);
                    }
                }
            }
        }
    }

    /// The AVX-512 gathers return the lane loop's bits, on every filter,
    /// wrap and colour space, with lanes on one level or blending two.
    #[test]
    fn gathers_read_the_lane_loops_bits() {
        if !simd::SimdLevel::Avx512.available() {
            // past the harness's capture, so that the skip shows in every log
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                b"SKIPPED: gathers_read_the_lane_loops_bits: this processor lacks AVX-512\n",
            );
            assert!(!std::env::var("HITEX_REQUIRE_AVX512").is_ok_and(|v| v == "1"), "HITEX_REQUIRE_AVX512=1");
            return;
        }
        let mut blended = 0;
        for cs in [ColorSpace::Srgb, ColorSpace::Linear] {
            let pyr = pyramid(cs);
            for filter in [Filter::Bilinear, Filter::Trilinear] {
                for wrap in [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror] {
                    let opts = SamplerOptions { filter, wrap, level_rule: LevelRule::MaxPartial, lod_bias: 0.0 };
                    let mut wide = LaneSampler::new(&pyr, opts);
                    wide.wide = true;
                    let mut lanes = LaneSampler::new(&pyr, opts);
                    lanes.wide = false;
                    for k in 0..300 {
                        let f = |i: usize, a: f32| ((k * 16 + i) as f32 * a).sin() * 2.5;
                        let u: Lanes = std::array::from_fn(|i| f(i, 0.731));
                        let v: Lanes = std::array::from_fn(|i| f(i, 1.377));
                        // one footprint for the block (its lanes share their levels)
                        let s = 0.01 * (1.0 + (k % 40) as f32);
                        let j = LaneJacobian {
                            du_dx: [s; LANES],
                            dv_dx: [0.0; LANES],
                            du_dy: [0.0; LANES],
                            dv_dy: [s; LANES],
                        };
                        let g = lanes.level_of_detail(&j)[0];
                        blended += (g.fract() != 0.0 && g > 0.0) as usize;
                        let (a, b) = (wide.sample(&u, &v, &j, 0xffff), lanes.sample(&u, &v, &j, 0xffff));
                        for c in 0..3 {
                            for i in 0..LANES {
                                assert_eq!(a[c][i].to_bits(), b[c][i].to_bits(), "{cs:?} {filter:?} {wrap:?} lane {i}");
                            }
                        }
                    }
                }
            }
        }
        assert!(blended > 100, "the footprints blend two levels ({blended})");
    }

    #[test]
    fn non_finite_coordinates_read_the_origin() {
        let pyr = pyramid(ColorSpace::Linear);
        let opts = SamplerOptions { filter: Filter::Trilinear, ..Default::default() };
        let s = LaneSampler::new(&pyr, opts);
        let mut u = [0.25; LANES];
        u[3] = f32::NAN;
        u[5] = f32::INFINITY;
        u[7] = -1e30;
        let j =
            LaneJacobian { du_dx: [f32::NAN; LANES], dv_dx: [0.0; LANES], du_dy: [0.0; LANES], dv_dy: [0.0; LANES] };
        let got = s.sample(&u, &[0.5; LANES], &j, 0xffff);
        for c in 0..3 {
            for i in 0..LANES {
                assert!(got[c][i].is_finite() && (0.0..=1.0).contains(&got[c][i]));
            }
        }
    }
}
