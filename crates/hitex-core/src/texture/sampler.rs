//! The texture sampler: level selection from the screen-to-texture Jacobian,
//! bilinear filtering at two levels and a linear blend between them.
//!
//! This is eq. (1)–(4) of the flight-simulator paper (seed 001):
//! the paper's level `l = −log2 max(|∂xm/∂xs|, |∂xm/∂ys|, |∂ym/∂xs|, |∂ym/∂ys|)`
//! counts levels from the coarsest map up (map units per pixel); GPUs count
//! from the finest level down (texels of level 0 per pixel). With `N` texels of
//! level 0 per map side both describe the same choice: `λ = log2 N − l`.
//! [`LevelRule::MaxPartial`] is the paper's rule expressed as λ; Vulkan's
//! `λ = log2 ρ`, `ρ = max(|∂(u,v)/∂x|, |∂(u,v)/∂y|)` is [`LevelRule::VulkanRho`]
//! (the specification allows the max-of-partials bound as an approximation).
//!
//! Texel centres sit at half-integers (GPU convention): eq. (3)'s
//! `a = ⌊2^L r_m⌋` is taken of `2^L r_m − ½`, so a texture drawn 1:1 is not
//! shifted by half a texel. `shaders/textured.wgsl` repeats these steps.

use super::pyramid::MipPyramid;
use glam::{Vec2, Vec4};

/// Which texels contribute to a lookup.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Filter {
    /// The nearest texel of level 0 (no MIP mapping, aliases under minification).
    Nearest,
    /// Bilinear at level 0 (no MIP mapping).
    Bilinear,
    /// Bilinear at levels ⌊λ⌋ and ⌊λ⌋+1, blended by the fraction of λ.
    #[default]
    Trilinear,
}

/// What happens outside [0, 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Wrap {
    /// Tile the texture.
    #[default]
    Repeat,
    /// Repeat the edge texels.
    Clamp,
    /// Tile with every other copy mirrored.
    Mirror,
}

/// How λ is computed from the Jacobian.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LevelRule {
    /// The paper's eq. (2): the largest absolute partial derivative.
    #[default]
    MaxPartial,
    /// Vulkan's ρ: the longer of the two screen-axis derivative vectors.
    VulkanRho,
}

/// The code of `v` in a choice's table: its position, the number both
/// backends' programs receive in their uniforms.
fn code_in<T: PartialEq>(all: &[(&str, T)], v: T) -> u32 {
    all.iter().position(|(_, x)| *x == v).unwrap_or(0) as u32
}

impl Filter {
    /// Every filter with its name; the position is the code the fragment
    /// programs receive ([`Filter::code`], WGSL `FILTER_<NAME>`).
    pub const ALL: [(&'static str, Filter); 3] =
        [("nearest", Filter::Nearest), ("bilinear", Filter::Bilinear), ("trilinear", Filter::Trilinear)];
    /// The code the fragment programs receive.
    pub fn code(self) -> u32 {
        code_in(&Self::ALL, self)
    }
    /// The filter of a code.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).map(|(_, f)| *f)
    }
}

impl Wrap {
    /// Every wrap mode with its name; the position is the code the fragment
    /// programs receive ([`Wrap::code`], WGSL `WRAP_<NAME>`).
    pub const ALL: [(&'static str, Wrap); 3] =
        [("repeat", Wrap::Repeat), ("clamp", Wrap::Clamp), ("mirror", Wrap::Mirror)];
    /// The code the fragment programs receive.
    pub fn code(self) -> u32 {
        code_in(&Self::ALL, self)
    }
    /// The wrap mode of a code.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).map(|(_, w)| *w)
    }
}

impl LevelRule {
    /// Every level rule with its name; the position is the code the
    /// fragment programs receive ([`LevelRule::code`], WGSL `LEVEL_RULE_<NAME>`).
    pub const ALL: [(&'static str, LevelRule); 2] =
        [("max-partial", LevelRule::MaxPartial), ("vulkan-rho", LevelRule::VulkanRho)];
    /// The code the fragment programs receive.
    pub fn code(self) -> u32 {
        code_in(&Self::ALL, self)
    }
    /// The level rule of a code.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).map(|(_, r)| *r)
    }
}

/// Sampler options: a small value passed to one entry point ([`sample`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SamplerOptions {
    /// Texel selection.
    pub filter: Filter,
    /// Addressing outside [0, 1).
    pub wrap: Wrap,
    /// Level selection rule.
    pub level_rule: LevelRule,
    /// Added to λ before clamping (positive blurs, negative sharpens).
    pub lod_bias: f32,
}

/// Screen-to-texture Jacobian at a pixel, in texture units (uv) per pixel.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Jacobian {
    /// ∂u/∂x
    pub du_dx: f32,
    /// ∂v/∂x
    pub dv_dx: f32,
    /// ∂u/∂y
    pub du_dy: f32,
    /// ∂v/∂y
    pub dv_dy: f32,
}

impl Jacobian {
    /// From the two screen-axis derivative vectors of (u, v).
    pub fn new(d_dx: Vec2, d_dy: Vec2) -> Self {
        Self { du_dx: d_dx.x, dv_dx: d_dx.y, du_dy: d_dy.x, dv_dy: d_dy.y }
    }
}

/// λ (levels below level 0, fractional, unclamped) for a texture whose level 0
/// is `width`×`height`. Returns −∞ for a zero or non-finite Jacobian
/// (magnification), which clamps to level 0.
pub fn level_of_detail(rule: LevelRule, jac: Jacobian, width: u32, height: u32) -> f32 {
    let (w, h) = (width as f32, height as f32);
    let (ux, vx, uy, vy) = (jac.du_dx * w, jac.dv_dx * h, jac.du_dy * w, jac.dv_dy * h);
    // level of detail
    let rho = match rule {
        LevelRule::MaxPartial => ux.abs().max(vx.abs()).max(uy.abs()).max(vy.abs()),
        LevelRule::VulkanRho => (ux * ux + vx * vx).sqrt().max((uy * uy + vy * vy).sqrt()),
    };
    if rho.is_finite() && rho > 0.0 { rho.log2() } else { f32::NEG_INFINITY }
}

/// Samples `pyr` at `uv` with the footprint `jac`; returns linear RGBA.
/// Non-finite coordinates sample the texel at the origin.
pub fn sample(pyr: &MipPyramid, opts: &SamplerOptions, uv: Vec2, jac: Jacobian) -> Vec4 {
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    let uv = Vec2::new(reduce(uv.x, opts.wrap), reduce(uv.y, opts.wrap));
    match opts.filter {
        Filter::Nearest => nearest(pyr, opts.wrap, uv),
        Filter::Bilinear => bilinear(pyr, 0, opts.wrap, uv),
        Filter::Trilinear => {
            // level selection
            let lambda = level_of_detail(opts.level_rule, jac, pyr.width(), pyr.height()) + opts.lod_bias;
            let max_level = (pyr.level_count() - 1) as f32;
            let lambda = if lambda.is_nan() { 0.0 } else { lambda.clamp(0.0, max_level) };
            let l0 = floor(lambda);
            let gamma = lambda - l0;
            let l0 = l0 as usize;
            // bilinear at L and L+1, linear blend
            let c0 = bilinear(pyr, l0, opts.wrap, uv);
            if gamma > 0.0 {
                let c1 = bilinear(pyr, l0 + 1, opts.wrap, uv);
                c0 + (c1 - c0) * gamma
            } else {
                c0
            }
        }
    }
}

/// Brings a coordinate into one period of the wrap mode so that scaling by
/// the texture size keeps its precision (1 period for repeat, 2 for mirror).
#[inline]
pub fn reduce(t: f32, wrap: Wrap) -> f32 {
    match wrap {
        Wrap::Repeat => t - floor(t),
        Wrap::Mirror => t - 2.0 * floor(t * 0.5),
        Wrap::Clamp => t.clamp(-1.0, 2.0),
    }
}

/// Texel index `i` on an axis of `n` texels under `wrap`.
#[inline]
pub fn wrap_index(i: i32, n: i32, wrap: Wrap) -> i32 {
    // inside: every mode agrees (the common case, without a division)
    if i >= 0 && i < n {
        return i;
    }
    match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m >= n { 2 * n - 1 - m } else { m }
        }
    }
}

/// `t as u32` for lane loops: NaN and negative values give 0, values from
/// 2³¹ on 2³¹ − 128, whole values in between themselves (fractions are cut).
/// Rust's saturating `as` conversions compile lane by lane on x86 vector
/// levels (scalar conversions and fix-ups); this one clamps first so that
/// the plain conversion (one vector instruction) is always in range.
#[inline(always)]
pub fn to_u32_clamped(t: f32) -> u32 {
    #[allow(clippy::manual_clamp)] // clamp would keep NaN
    let c = t.max(0.0).min(2_147_483_520.0);
    // SAFETY: c is finite and in [0, 2³¹ − 128], inside i32's range
    unsafe { c.to_int_unchecked::<i32>() as u32 }
}

/// `t as i32` for lane loops, as [`to_u32_clamped`]: NaN gives 0, values
/// below −2³¹ give −2³¹, values from 2³¹ on 2³¹ − 128 (where `as` gives
/// 2³¹ − 1), whole values in between themselves (fractions cut toward zero).
#[inline(always)]
pub fn to_i32_clamped(t: f32) -> i32 {
    #[allow(clippy::manual_clamp)] // clamp would keep NaN
    let c = t.max(-2_147_483_648.0).min(2_147_483_520.0);
    let c = if t.is_nan() { 0.0 } else { c };
    // SAFETY: c is finite and in [−2³¹, 2³¹ − 128], inside i32's range
    unsafe { c.to_int_unchecked::<i32>() }
}

/// `floor`, inlined where the platform's `floorf` is a library call, in
/// float operations only (no conversion to an integer, which vector code
/// pays for in range fixups): adding and subtracting 2²³ rounds |t| to an
/// integer, one step down corrects it. Floats of magnitude ≥ 2²³ are
/// integers already; NaN stays NaN; the sign of zero is kept as `t as i32`
/// would give it (+0 for −0).
#[inline(always)]
pub fn floor(t: f32) -> f32 {
    const BIG: f32 = 8_388_608.0;
    let a = t.abs();
    let r = (a + BIG) - BIG;
    let r = if t < 0.0 { -r } else { r };
    let f = if r > t { r - 1.0 } else { r };
    // NaN fails the comparison and is returned as it came
    if a < BIG { f } else { t }
}

fn nearest(pyr: &MipPyramid, wrap: Wrap, uv: Vec2) -> Vec4 {
    let (w, h) = (pyr.width() as i32, pyr.height() as i32);
    let x = wrap_index(floor(uv.x * w as f32) as i32, w, wrap);
    let y = wrap_index(floor(uv.y * h as f32) as i32, h, wrap);
    let img = pyr.level(0);
    Vec4::from_array(crate::texture::image::decode(
        img.texels()[y as usize * w as usize + x as usize],
        img.color_space(),
    ))
}

/// Bilinear lookup in level `level` (eq. (4)'s t_c): the four texels around
/// `uv·size − ½` weighted by the fractional position.
pub fn bilinear(pyr: &MipPyramid, level: usize, wrap: Wrap, uv: Vec2) -> Vec4 {
    let img = pyr.level(level);
    let (w, h) = (img.width() as i32, img.height() as i32);
    let x = uv.x * w as f32 - 0.5;
    let y = uv.y * h as f32 - 0.5;
    let (xf, yf) = (floor(x), floor(y));
    let (alpha, beta) = (x - xf, y - yf);
    let (x0, y0) = (xf as i32, yf as i32);
    let xa = wrap_index(x0, w, wrap) as usize;
    let xb = wrap_index(x0 + 1, w, wrap) as usize;
    let ya = wrap_index(y0, h, wrap) as usize;
    let yb = wrap_index(y0 + 1, h, wrap) as usize;
    // RGBA8 texels decoded by table: measured 0.94× the time of fetching
    // texels decoded to linear f32 in advance (a quarter of the memory)
    let texels = img.texels();
    let lut = crate::texture::image::decode_table(img.color_space());
    let d =
        |t: [u8; 4]| Vec4::new(lut[t[0] as usize], lut[t[1] as usize], lut[t[2] as usize], t[3] as f32 * (1.0 / 255.0));
    let (ra, rb) = (ya * w as usize, yb * w as usize);
    let t00 = d(texels[ra + xa]);
    let t10 = d(texels[ra + xb]);
    let t01 = d(texels[rb + xa]);
    let t11 = d(texels[rb + xb]);
    let top = t00 + (t10 - t00) * alpha;
    let bottom = t01 + (t11 - t01) * alpha;
    top + (bottom - top) * beta
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every value's code leads back to it, and the programs' defaults for
    /// a material are the codes the enums' defaults have.
    #[test]
    fn codes_lead_back_to_their_values() {
        for (_, f) in Filter::ALL {
            assert_eq!(Filter::from_code(f.code()), Some(f));
        }
        for (_, w) in Wrap::ALL {
            assert_eq!(Wrap::from_code(w.code()), Some(w));
        }
        for (_, r) in LevelRule::ALL {
            assert_eq!(LevelRule::from_code(r.code()), Some(r));
        }
        assert_eq!((Filter::Nearest.code(), Filter::Trilinear.code(), Wrap::Mirror.code()), (0, 2, 2));
        assert_eq!((LevelRule::VulkanRho.code(), Filter::from_code(3), Wrap::from_code(3)), (1, None, None));
    }
    use crate::assert_near;
    use crate::texture::image::{ColorSpace, Image};
    use proptest::prelude::*;

    #[test]
    fn clamped_conversion_matches_as_in_range_and_clamps_outside() {
        for t in [0.0f32, 0.3, 1.0, 1.99, 255.0, 4095.5, 16_777_216.0, 2_147_483_520.0] {
            assert_eq!(to_u32_clamped(t), t as u32, "{t}");
        }
        for (t, want) in [
            (-0.5f32, 0),
            (-1e30, 0),
            (f32::NAN, 0),
            (f32::NEG_INFINITY, 0),
            (f32::INFINITY, 2_147_483_520),
            (4e9, 2_147_483_520),
        ] {
            assert_eq!(to_u32_clamped(t), want, "{t}");
        }
    }

    #[test]
    fn signed_clamped_conversion_matches_as_in_range_and_clamps_outside() {
        for t in
            [0.0f32, -0.0, 0.3, -0.3, 1.99, -1.99, -255.0, 4095.5, -16_777_216.0, 2_147_483_520.0, -2_147_483_648.0]
        {
            assert_eq!(to_i32_clamped(t), t as i32, "{t}");
        }
        for (t, want) in [
            (f32::NAN, 0),
            (-1e30f32, i32::MIN),
            (f32::NEG_INFINITY, i32::MIN),
            (f32::INFINITY, 2_147_483_520),
            (4e9, 2_147_483_520),
        ] {
            assert_eq!(to_i32_clamped(t), want, "{t}");
        }
        let mut x = 0x2545_f491_u32;
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let t = f32::from_bits(x);
            if t.is_finite() && t.abs() < 2_147_483_520.0 {
                assert_eq!(to_i32_clamped(t), t as i32, "{t}");
            }
        }
    }

    fn lin(data: Vec<[u8; 4]>, w: u32, h: u32) -> MipPyramid {
        MipPyramid::build(Image::new(w, h, ColorSpace::Linear, data).unwrap())
    }

    fn tri() -> SamplerOptions {
        SamplerOptions { filter: Filter::Trilinear, ..Default::default() }
    }

    #[test]
    fn level_rules_by_hand() {
        // 256-texel texture, 1/128 uv per pixel along x: 2 texels per pixel → λ = 1
        let j = Jacobian { du_dx: 1.0 / 128.0, ..Default::default() };
        assert_near!(level_of_detail(LevelRule::MaxPartial, j, 256, 256), 1.0, 1e-6);
        // diagonal footprint (3, 4) texels: paper's rule takes 4, Vulkan's 5
        let j = Jacobian { du_dx: 3.0 / 256.0, dv_dx: 4.0 / 256.0, ..Default::default() };
        assert_near!(level_of_detail(LevelRule::MaxPartial, j, 256, 256), 2.0, 1e-6);
        assert_near!(level_of_detail(LevelRule::VulkanRho, j, 256, 256), 5.0f32.log2(), 1e-6);
        // magnification and degenerate footprints clamp to level 0
        assert_eq!(level_of_detail(LevelRule::MaxPartial, Jacobian::default(), 4, 4), f32::NEG_INFINITY);
        let nan = Jacobian { du_dx: f32::NAN, ..Default::default() };
        assert_eq!(level_of_detail(LevelRule::MaxPartial, nan, 4, 4), f32::NEG_INFINITY);
    }

    #[test]
    fn bilinear_by_hand() {
        // 2x2 linear texture: 0, 255 / 0, 255 on red → at the centre 0.5
        let p = lin(vec![[0, 0, 0, 255], [255, 0, 0, 255], [0, 0, 0, 255], [255, 0, 0, 255]], 2, 2);
        let o = SamplerOptions { filter: Filter::Bilinear, wrap: Wrap::Clamp, ..Default::default() };
        // texel centres at 0.25 and 0.75: exact values there
        assert_near!(sample(&p, &o, Vec2::new(0.25, 0.25), Jacobian::default()).x, 0.0, 1e-7);
        assert_near!(sample(&p, &o, Vec2::new(0.75, 0.25), Jacobian::default()).x, 1.0, 1e-7);
        assert_near!(sample(&p, &o, Vec2::new(0.5, 0.5), Jacobian::default()).x, 0.5, 1e-7);
        // a quarter of the way from centre 0 to centre 1
        assert_near!(sample(&p, &o, Vec2::new(0.375, 0.6), Jacobian::default()).x, 0.25, 1e-6);
        // repeat wraps: at u = 0 we sit between texel 1 (left, wrapped) and texel 0
        let r = SamplerOptions { wrap: Wrap::Repeat, ..o };
        assert_near!(sample(&p, &r, Vec2::new(0.0, 0.25), Jacobian::default()).x, 0.5, 1e-6);
        // clamp does not
        assert_near!(sample(&p, &o, Vec2::new(0.0, 0.25), Jacobian::default()).x, 0.0, 1e-7);
    }

    #[test]
    fn trilinear_blends_levels_by_fraction() {
        // 2x1 linear texture: level 0 = [0, 255], level 1 = [128]
        let p = lin(vec![[0, 0, 0, 255], [255, 0, 0, 255]], 2, 1);
        let o = SamplerOptions { wrap: Wrap::Clamp, ..tri() };
        let at = |lambda: f32| {
            let j = Jacobian { du_dx: lambda.exp2() / 2.0, ..Default::default() };
            sample(&p, &o, Vec2::new(0.25, 0.5), j).x
        };
        assert_near!(at(0.0), 0.0, 1e-6);
        assert_near!(at(1.0), 128.0 / 255.0, 1e-6);
        assert_near!(at(0.25), 0.25 * 128.0 / 255.0, 1e-6);
        // beyond the last level it clamps
        assert_near!(at(7.0), 128.0 / 255.0, 1e-6);
        // lod bias shifts the level
        let b = SamplerOptions { lod_bias: 1.0, ..o };
        let j0 = Jacobian { du_dx: 0.5, ..Default::default() };
        assert_near!(sample(&p, &b, Vec2::new(0.25, 0.5), j0).x, 128.0 / 255.0, 1e-6);
    }

    #[test]
    fn nearest_picks_the_covering_texel() {
        let p = lin(vec![[10, 0, 0, 255], [200, 0, 0, 255]], 2, 1);
        let o = SamplerOptions { filter: Filter::Nearest, ..Default::default() };
        assert_near!(sample(&p, &o, Vec2::new(0.49, 0.5), Jacobian::default()).x, 10.0 / 255.0, 1e-7);
        assert_near!(sample(&p, &o, Vec2::new(0.51, 0.5), Jacobian::default()).x, 200.0 / 255.0, 1e-7);
        assert_near!(sample(&p, &o, Vec2::new(-0.49, 0.5), Jacobian::default()).x, 200.0 / 255.0, 1e-7);
    }

    #[test]
    fn fast_floor_equals_floor() {
        for t in
            [0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999, -2.999, 1e7, -1e7, 8388607.5, -8388607.5, 3e9, -3e9, f32::MAX]
        {
            assert_eq!(floor(t), t.floor(), "{t}");
        }
        assert!(floor(f32::NAN).is_nan());
        assert_eq!(floor(f32::NEG_INFINITY), f32::NEG_INFINITY);
        // halves (rounding to even must not leak through), neighbours of
        // integers and of 2²³, and a sweep, all equal to the library floor
        let mut ts =
            vec![0.49999997f32, -0.49999997, 1.5, 2.5, -1.5, -2.5, 8388606.5, -8388606.5, 8388608.0, 16777215.0];
        for k in -2000..2000 {
            ts.push(k as f32 * 0.37 + 0.001 * (k % 7) as f32);
            let i = k as f32 * 4099.0;
            ts.extend([i, f32::from_bits(i.to_bits() + 1), f32::from_bits(i.to_bits().saturating_sub(1))]);
        }
        for t in ts {
            assert_eq!(floor(t), t.floor(), "{t}");
        }
        // −0 gives +0 (as the integer round trip did); the lane code relies on no sign
        assert_eq!(floor(-0.0).to_bits(), 0.0f32.to_bits());
    }

    #[test]
    fn wrap_indices() {
        assert_eq!((-3..7).map(|i| wrap_index(i, 3, Wrap::Repeat)).collect::<Vec<_>>(), [0, 1, 2, 0, 1, 2, 0, 1, 2, 0]);
        assert_eq!((-3..7).map(|i| wrap_index(i, 3, Wrap::Clamp)).collect::<Vec<_>>(), [0, 0, 0, 0, 1, 2, 2, 2, 2, 2]);
        assert_eq!((-3..7).map(|i| wrap_index(i, 3, Wrap::Mirror)).collect::<Vec<_>>(), [2, 1, 0, 0, 1, 2, 2, 1, 0, 0]);
    }

    #[test]
    fn non_finite_uv_does_not_panic() {
        let p = lin(vec![[1, 2, 3, 255]; 4], 2, 2);
        for f in [Filter::Nearest, Filter::Bilinear, Filter::Trilinear] {
            let o = SamplerOptions { filter: f, ..Default::default() };
            let c =
                sample(&p, &o, Vec2::new(f32::NAN, f32::INFINITY), Jacobian { du_dx: f32::NAN, ..Default::default() });
            assert!(c.is_finite());
        }
    }

    proptest! {
        #[test]
        fn constant_texture_is_constant_everywhere(
            u in -100.0f32..100.0, v in -100.0f32..100.0,
            jx in -10.0f32..10.0, jy in -10.0f32..10.0,
            w in 1u32..20, h in 1u32..20, c: u8, wrap in 0usize..3, rule: bool,
        ) {
            let p = MipPyramid::build(Image::filled(w, h, ColorSpace::Srgb, [c, c, c, 255]).unwrap());
            let wrap = [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror][wrap];
            let rule = if rule { LevelRule::MaxPartial } else { LevelRule::VulkanRho };
            let expect = crate::texture::srgb_u8_to_linear(c);
            for filter in [Filter::Nearest, Filter::Bilinear, Filter::Trilinear] {
                let o = SamplerOptions { filter, wrap, level_rule: rule, lod_bias: 0.0 };
                let s = sample(&p, &o, Vec2::new(u, v), Jacobian { du_dx: jx, dv_dx: jy, du_dy: -jy, dv_dy: jx });
                prop_assert!((s.x - expect).abs() < 1e-5 && (s.w - 1.0).abs() < 1e-6, "{s:?} vs {expect}");
            }
        }

        #[test]
        fn bilinear_stays_within_texel_range(u in -5.0f32..5.0, v in -5.0f32..5.0, a: u8, b: u8) {
            let p = lin(vec![[a, 0, 0, 255], [b, 0, 0, 255], [b, 0, 0, 255], [a, 0, 0, 255]], 2, 2);
            let o = SamplerOptions { filter: Filter::Bilinear, ..Default::default() };
            let s = sample(&p, &o, Vec2::new(u, v), Jacobian::default()).x * 255.0;
            let (lo, hi) = (a.min(b) as f32, a.max(b) as f32);
            prop_assert!(s >= lo - 1e-3 && s <= hi + 1e-3);
        }
    }
}
