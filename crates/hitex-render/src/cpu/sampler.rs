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
        Self { levels, opts, lut: hitex_core::texture::image::decode_table(pyr.color_space()) }
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
            Filter::Nearest => self.nearest(&u, &v, live),
            Filter::Bilinear => {
                let mut out = [[1.0; LANES]; 3];
                self.bilinear(&[0; LANES], &u, &v, live, &mut out);
                out
            }
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
                    l0[i] = f as u8;
                    l1[i] = (f as u8 + 1).min(max_level as u8);
                    blend |= ((gamma[i] > 0.0) as u16) << i;
                }
                let mut c0 = [[1.0; LANES]; 3];
                self.bilinear(&l0, &u, &v, live, &mut c0);
                let mut c1 = c0;
                if live & blend != 0 {
                    self.bilinear(&l1, &u, &v, live, &mut c1);
                }
                let mut out = c0;
                for c in 0..3 {
                    for i in 0..LANES {
                        out[c][i] = c0[c][i] + (c1[c][i] - c0[c][i]) * gamma[i];
                    }
                }
                out
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
    #[inline(always)]
    fn wrap(&self, f: &Lanes, n: &Lanes) -> Lanes {
        let mut o = [0.0; LANES];
        match self.opts.wrap {
            Wrap::Repeat => {
                for i in 0..LANES {
                    let m = f[i] - n[i] * simd::floor(f[i] / n[i]);
                    o[i] = if f[i] >= 0.0 && f[i] < n[i] { f[i] } else { m };
                }
            }
            Wrap::Clamp => {
                for i in 0..LANES {
                    o[i] = f[i].max(0.0).min(n[i] - 1.0);
                }
            }
            Wrap::Mirror => {
                for i in 0..LANES {
                    let p = 2.0 * n[i];
                    let m = f[i] - p * simd::floor(f[i] / p);
                    let m = if m >= n[i] { p - 1.0 - m } else { m };
                    o[i] = if f[i] >= 0.0 && f[i] < n[i] { f[i] } else { m };
                }
            }
        }
        o
    }

    #[inline(always)]
    fn nearest(&self, u: &Lanes, v: &Lanes, live: u16) -> Rgb {
        let l = &self.levels[0];
        let (w, h) = ([l.width as f32; LANES], [l.height as f32; LANES]);
        let x = self.wrap(&lanes!(|i| simd::floor(u[i] * w[i])), &w);
        let y = self.wrap(&lanes!(|i| simd::floor(v[i] * h[i])), &h);
        let mut out = [[1.0; LANES]; 3];
        let last = l.texels.len() - 1;
        for i in 0..LANES {
            if live & (1 << i) != 0 {
                let t = l.texels[(y[i] as usize * l.width as usize + x[i] as usize).min(last)];
                for c in 0..3 {
                    out[c][i] = self.lut[t[c] as usize];
                }
            }
        }
        out
    }

    /// Bilinear lookup per lane in level `lvl[lane]` (eq. (4)'s t_c): the four
    /// texels around `uv·size − ½` weighted by the fractional position.
    /// Every lane reads (a helper lane's indices are as valid as any), so the
    /// gather has no branch; when the live lanes share one level (almost
    /// always) its size and texels are hoisted out of the lanes.
    #[inline(always)]
    fn bilinear(&self, lvl: &[u8; LANES], u: &Lanes, v: &Lanes, live: u16, out: &mut Rgb) {
        let first = lvl[(live.trailing_zeros() as usize).min(LANES - 1)];
        let mut same = true;
        for i in 0..LANES {
            same &= live & (1 << i) == 0 || lvl[i] == first;
        }
        if same {
            self.bilinear_in::<true>(&[first; LANES], u, v, out);
        } else {
            self.bilinear_in::<false>(lvl, u, v, out);
        }
    }

    #[inline(always)]
    fn bilinear_in<const UNIFORM: bool>(&self, lvl: &[u8; LANES], u: &Lanes, v: &Lanes, out: &mut Rgb) {
        let mut w = [0.0; LANES];
        let mut h = [0.0; LANES];
        let one = &self.levels[(lvl[0] as usize).min(self.levels.len() - 1)];
        if UNIFORM {
            w = [one.width as f32; LANES];
            h = [one.height as f32; LANES];
        } else {
            for i in 0..LANES {
                let l = &self.levels[lvl[i] as usize];
                w[i] = l.width as f32;
                h[i] = l.height as f32;
            }
        }
        let x: Lanes = lanes!(|i| u[i] * w[i] - 0.5);
        let y: Lanes = lanes!(|i| v[i] * h[i] - 0.5);
        let xf: Lanes = lanes!(|i| simd::floor(x[i]));
        let yf: Lanes = lanes!(|i| simd::floor(y[i]));
        let alpha: Lanes = lanes!(|i| x[i] - xf[i]);
        let beta: Lanes = lanes!(|i| y[i] - yf[i]);
        let xa = self.wrap(&xf, &w);
        let xb = self.wrap(&lanes!(|i| xf[i] + 1.0), &w);
        let ya = self.wrap(&yf, &h);
        let yb = self.wrap(&lanes!(|i| yf[i] + 1.0), &h);
        // texel offsets as integers (exact beyond 2^24 texels)
        let mut ra = [0u32; LANES];
        let mut rb = [0u32; LANES];
        let mut ca = [0u32; LANES];
        let mut cb = [0u32; LANES];
        for i in 0..LANES {
            let stride = w[i] as u32;
            ra[i] = (ya[i] as u32).wrapping_mul(stride);
            rb[i] = (yb[i] as u32).wrapping_mul(stride);
            ca[i] = xa[i] as u32;
            cb[i] = xb[i] as u32;
        }
        // the gather: four texels a lane, decoded
        let mut t = [[[0.0f32; LANES]; 3]; 4];
        let lut = self.lut;
        if UNIFORM {
            // one texel position for all lanes at a time: a vector gather of
            // the RGBA8 words, then one of the table per channel
            let texels: &[u32] = bytemuck::cast_slice(one.texels);
            let last = texels.len().saturating_sub(1);
            for k in 0..4 {
                let (r, c) = match k {
                    0 => (&ra, &ca),
                    1 => (&ra, &cb),
                    2 => (&rb, &ca),
                    _ => (&rb, &cb),
                };
                let mut px = [0u32; LANES];
                for i in 0..LANES {
                    px[i] = texels[((r[i] + c[i]) as usize).min(last)];
                }
                for i in 0..LANES {
                    t[k][0][i] = lut[(px[i] & 0xff) as usize];
                    t[k][1][i] = lut[((px[i] >> 8) & 0xff) as usize];
                    t[k][2][i] = lut[((px[i] >> 16) & 0xff) as usize];
                }
            }
        } else {
            for i in 0..LANES {
                let l = &self.levels[lvl[i] as usize];
                let last = l.texels.len() - 1;
                let at = [ra[i] + ca[i], ra[i] + cb[i], rb[i] + ca[i], rb[i] + cb[i]];
                for k in 0..4 {
                    let texel = l.texels[(at[k] as usize).min(last)];
                    for c in 0..3 {
                        t[k][c][i] = lut[texel[c] as usize];
                    }
                }
            }
        }
        for c in 0..3 {
            for i in 0..LANES {
                let top = t[0][c][i] + (t[1][c][i] - t[0][c][i]) * alpha[i];
                let bottom = t[2][c][i] + (t[3][c][i] - t[2][c][i]) * alpha[i];
                out[c][i] = top + (bottom - top) * beta[i];
            }
        }
    }
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
