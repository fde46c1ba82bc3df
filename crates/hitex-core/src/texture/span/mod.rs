//! Span-parallel MIP mapping from one shared, interleaved texture memory
//! (seed 001, §3, eq. (8)–(10)).
//!
//! The conventional design gives each of the four pixel processors its own
//! copy of the texture memory ([`super::sample`] per pixel, eq. (1)–(4)). The
//! paper instead maps a 2×2 block of pixels, a **span**, from *one* memory
//! split into B×B interleaved **banks**: texel (x, y) of a level lives in bank
//! (x mod B, y mod B) at address (x div B, y div B). Any B×B block of texels
//! (an **mspan**) then touches every bank exactly once, so one memory cycle
//! delivers it; each pixel takes its 2×2 (bilinear) out of it.
//!
//! # Level rule (eq. (9)), derived for B×B banks
//!
//! Let `E` be the larger of the x and y extents of the span's (valid) map
//! points in level-0 texels, `E = max(x_max − x_min, y_max − y_min)`; eq. (9)
//! is `l = −log2 E` in map units, i.e. `λ₉ = log2 E` in the GPU numbering used
//! here (λ = levels below the finest, `λ = log2 N − l`). With texel centres
//! at half-integers (`p = uv·size − ½`, as in [`super::sampler`]), the bilinear
//! footprint of the four points at level k covers, per axis,
//! `⌊p_max⌋ − ⌊p_min⌋ + 2 ≤ ⌈e_k⌉ + 2` texels, `e_k ≤ E / 2^k` the extent at
//! that level. It fits a B-wide mspan for every position iff `e_k ≤ B − 2`.
//! Eq. (4) reads two levels, ⌊λ⌋ and ⌊λ⌋+1; the finer one must fit for every
//! fraction of λ, which gives
//!
//! `λ_span = log2(2E / (B − 2))`: **3×3 banks: λ = λ₉ + 1; 4×4 banks: λ = λ₉.**
//!
//! So eq. (9) read literally fits only the *coarser* of eq. (4)'s two levels
//! in 3×3 banks (the paper's `L = ⌊l⌋`, in which the span lies inside a 3×3
//! mspan, as §3 says); the finer level `L+1` of eq. (10)'s `a_ijf` spreads over
//! up to 2 texels and needs up to 4×4. Conflict-free trilinear from 3×3 banks
//! therefore costs one more level of blur, and 4×4 banks give exactly eq. (9)
//! — consistent with the paper's remark that 4×4 banks avoid the blur. (For
//! an affine footprint, `E = max(|∂x/∂xs|+|∂x/∂ys|, |∂y/∂xs|+|∂y/∂ys|)` lies
//! between 1 and 2 times eq. (2)'s largest partial, so `λ₉` is 0–1 level
//! coarser than the per-pixel level.) The blend fraction is `λ − ⌊λ⌋` as in
//! eq. (4); λ < 0 (magnification) reads level 0 only. A guard raises the level
//! when a footprint does not fit after all — only possible through rounding at
//! exact ties; [`BankModel::guard_raises`] counts it (0 in every run so far).
//! [`SpanOptions::level_shift`] moves the chosen level afterwards (−1 = one
//! level finer; on 3×3 banks that is eq. (9) literally) and is how the tests
//! show that the rule is tight: conflicts appear.
//!
//! Levels coarser than the pyramid's last (1×1) level are *virtual*: the value
//! is the last level's, and the bank access is that of the continued pyramid
//! (texel size doubling on), as the paper's mosaic of maps would provide.
//!
//! # Bank addressing (eq. (10))
//!
//! For an mspan whose first texel is `x0 = ⌊p_min⌋` (eq. (10)'s
//! `⌊2^L r_mspn⌋`), bank i reads `a_i = ⌊x0 / B⌋ + δ(i, x0)`, `δ = 1` if
//! `i < x0 mod B` else 0 (per axis; [`eq10_address`]), which is exactly the
//! address `x div B` of the one texel of the block in bank `i`. Addresses are
//! taken in the *unwrapped* texel plane (the paper addresses a global mosaic
//! of maps); the span's points are first brought to one wrap period together.
//! A single texture repeated by wrapping would, for sides not a multiple of B,
//! put both sides of a seam in one bank — a real one-tile memory would have
//! to pad its sides to a multiple of B ([`MemoryReport::span_bytes`] does).
//!
//! # Bicubic (the paper's "higher order than eq. (4)")
//!
//! [`SpanFilter::Bicubic`] is Catmull-Rom (a = −½, interpolating) per axis,
//! **restricted to the mspan**: the level rule is the bilinear one above, the
//! mspan is centred on the span's cubic footprint, and taps that fall outside
//! the B×B texels the banks delivered are replaced by the nearest delivered
//! texel (edge replication inside the mspan). A full 4-tap cubic needs
//! `⌈e⌉ + 4` texels per axis, which no B ≤ 4 provides for four distinct
//! points, so the filter is exact Catmull-Rom only where a pixel's 4×4 taps
//! happen to lie inside the mspan (sometimes with 4×4 banks, never with 3×3:
//! there it is a 3-tap cubic with one replicated tap). The result is clamped
//! per channel to the range of the taps used (no ringing outside the data).
//! Both levels of eq. (4) are filtered this way and blended.
//!
//! # Flight
//!
//! [`FlightView`] is a pinhole camera at altitude h over the flat textured
//! ground (eq. (1) for a horizontal face): ground coordinates are level-0
//! texels, the texture covers `[0, W) × [0, H)` and wraps. [`render_trilinear`]
//! renders a frame with the per-pixel sampler and the analytic Jacobian
//! (eq. (2)); [`render_spans`] renders it in 2×2 spans; [`psnr`] and [`ssim`]
//! compare them.
//!
//! # Where the parts live
//!
//! The options and the records of an access are here; `bank` holds the bank
//! model, eq. (10)'s addressing and the memory report; `level` the level rule;
//! `sample` the span sampler ([`sample_span`], [`catmull_rom`]); `flight` the
//! flight view and the two renderers with their comparison.

mod bank;
mod flight;
mod level;
mod sample;

pub use bank::{BankModel, MemoryReport, address_in_bank, bank_of, eq10_address, memory_for_pyramid, memory_report};
pub use flight::{FlightView, FrameComparison, SKY, psnr, render_both, render_spans, render_trilinear, ssim};
pub use level::span_level;
pub use sample::{catmull_rom, sample_span};

use super::sampler::Wrap;

/// How the texture memory is interleaved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpanScheme {
    /// 3×3 banks: the paper's design.
    #[default]
    Banks3x3,
    /// 4×4 banks: the paper's remedy for the coarser level.
    Banks4x4,
}

impl SpanScheme {
    /// Banks per side (B).
    pub fn side(self) -> usize {
        match self {
            SpanScheme::Banks3x3 => 3,
            SpanScheme::Banks4x4 => 4,
        }
    }
    /// Number of banks (B²).
    pub fn banks(self) -> u32 {
        (self.side() * self.side()) as u32
    }
    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            SpanScheme::Banks3x3 => "3x3",
            SpanScheme::Banks4x4 => "4x4",
        }
    }
}

/// Filter applied to each pixel inside the mspan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpanFilter {
    /// Eq. (4): bilinear at two levels, linear blend.
    #[default]
    Bilinear,
    /// Catmull-Rom restricted to the mspan (see the module documentation).
    Bicubic,
}

/// Options of [`sample_span`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SpanOptions {
    /// Bank interleave.
    pub scheme: SpanScheme,
    /// Per-pixel filter.
    pub filter: SpanFilter,
    /// Addressing outside [0, 1).
    pub wrap: Wrap,
    /// Added to the level the rule chose (negative = finer). Anything below 0
    /// breaks the conflict-free guarantee; meant for experiments and tests.
    pub level_shift: i32,
}

/// Pixel order inside a span: (0,0), (1,0), (0,1), (1,1) — x right, y down.
pub const SPAN_PIXELS: [(u32, u32); 4] = [(0, 0), (1, 0), (0, 1), (1, 1)];

/// The level chosen for one span.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpanLevel {
    /// `E`: the larger axis extent of the valid map points, level-0 texels.
    pub extent: f64,
    /// The rule's continuous λ (`log2(2E/(B−2))`, −∞ for E = 0), unclamped.
    pub lambda: f64,
    /// The finer level read (after guard and shift); may exceed the
    /// pyramid's last level (a virtual level, see the module documentation).
    pub level: usize,
    /// Weight of `level + 1` in the blend (0: one level only).
    pub gamma: f32,
    /// Whether the rounding guard raised the level.
    pub guard_raised: bool,
}

/// One span access as the banks see it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SpanAccess {
    /// Level read (may be virtual).
    pub level: u32,
    /// First texel of the mspan (eq. (10)'s `⌊2^L r_mspn⌋`).
    pub origin: [i64; 2],
    /// Every distinct (bank (i, j), address) pair served, sorted; a bank
    /// listed twice is a conflict.
    pub served: Vec<([u8; 2], [i64; 2])>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Frame;
    use crate::texture::image::{ColorSpace, Image};
    use crate::texture::procedural::Pattern;
    use crate::texture::pyramid::MipPyramid;
    use crate::texture::sampler::{Jacobian, LevelRule};
    use crate::texture::sampler::{bilinear, level_of_detail};
    use glam::{Vec2, Vec4};

    fn bricks(size: u32) -> MipPyramid {
        MipPyramid::build(Pattern::Bricks.render(size).unwrap())
    }

    fn view(alt: f64, pitch: f64, heading: f64, w: u32, h: u32) -> FlightView {
        FlightView {
            position: [37.25, 81.5],
            altitude: alt,
            pitch_deg: pitch,
            heading_deg: heading,
            fov_deg: 45.0,
            width: w,
            height: h,
        }
    }

    fn flight() -> Vec<FlightView> {
        let mut v = Vec::new();
        for (i, alt) in [12.0, 60.0, 400.0].into_iter().enumerate() {
            for (j, pitch) in [8.0, 35.0, 89.0].into_iter().enumerate() {
                let heading = [0.0, 33.0, 90.0, 217.0][(i + j) % 4];
                let mut f = view(alt, pitch, heading, 64, 48);
                f.position = [f.position[0] + 17.0 * i as f64, f.position[1] - 9.0 * j as f64];
                v.push(f);
            }
        }
        v
    }

    fn all_opts(wrap: Wrap) -> Vec<SpanOptions> {
        let mut v = Vec::new();
        for scheme in [SpanScheme::Banks3x3, SpanScheme::Banks4x4] {
            for filter in [SpanFilter::Bilinear, SpanFilter::Bicubic] {
                v.push(SpanOptions { scheme, filter, wrap, level_shift: 0 });
            }
        }
        v
    }

    #[test]
    fn eq10_addresses_every_bank_once_per_mspan() {
        for b in [3usize, 4] {
            for x0 in -8i64..9 {
                for y0 in -8i64..9 {
                    let mut seen = vec![false; b * b];
                    for dy in 0..b as i64 {
                        for dx in 0..b as i64 {
                            let t = [x0 + dx, y0 + dy];
                            let bank = bank_of(t, b);
                            assert!(!seen[bank[1] * b + bank[0]], "bank {bank:?} twice at {x0},{y0}");
                            seen[bank[1] * b + bank[0]] = true;
                            assert_eq!(address_in_bank(t, b), eq10_address([x0, y0], bank, b));
                        }
                    }
                    assert!(seen.iter().all(|&s| s));
                }
            }
        }
        // the paper's δ by hand: x0 = 7 → 7 div 3 = 2, 7 mod 3 = 1: bank 0 reads 3, banks 1, 2 read 2
        assert_eq!(eq10_address([7, 0], [0, 0], 3)[0], 3);
        assert_eq!(eq10_address([7, 0], [1, 0], 3)[0], 2);
        assert_eq!(eq10_address([7, 0], [2, 0], 3)[0], 2);
    }

    #[test]
    fn no_bank_conflicts_over_a_flight() {
        let pyr = bricks(128);
        for wrap in [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp] {
            for opts in all_opts(wrap) {
                let mut m = BankModel::new(opts.scheme);
                for v in flight() {
                    let _ = render_spans(&pyr, &v, &opts, &mut m);
                }
                assert!(m.accesses > 1000, "{opts:?}: {} accesses", m.accesses);
                assert_eq!(m.conflicts, 0, "{opts:?}: {} conflicts in {} accesses", m.conflicts, m.accesses);
                assert_eq!(m.guard_raises, 0, "{opts:?}");
            }
        }
    }

    #[test]
    fn one_level_finer_conflicts() {
        // the rule is tight: one level finer than it, the banks conflict
        // (on 3×3 this is eq. (9) applied literally to both levels of eq. (4))
        let pyr = bricks(128);
        for scheme in [SpanScheme::Banks3x3, SpanScheme::Banks4x4] {
            let opts = SpanOptions { scheme, level_shift: -1, ..Default::default() };
            let mut m = BankModel::new(scheme);
            for v in flight() {
                let _ = render_spans(&pyr, &v, &opts, &mut m);
            }
            assert!(m.conflicts > 0, "{scheme:?}: no conflict one level finer");
            assert!(m.conflicted_accesses * 20 > m.accesses, "{scheme:?}: {} of {}", m.conflicted_accesses, m.accesses);
        }
    }

    #[test]
    fn the_log_shows_one_address_per_bank_and_eq10() {
        let pyr = bricks(64);
        let opts = SpanOptions::default();
        let mut m = BankModel::with_log(opts.scheme);
        let _ = render_spans(&pyr, &view(30.0, 40.0, 20.0, 16, 12), &opts, &mut m);
        assert_eq!(m.log().len() as u64, m.accesses);
        assert!(m.accesses >= 48);
        for a in m.log() {
            for w in a.served.windows(2) {
                assert_ne!(w[0].0, w[1].0, "bank served twice: {a:?}");
            }
            for (bank, addr) in &a.served {
                assert_eq!(*addr, eq10_address(a.origin, [bank[0] as usize, bank[1] as usize], 3), "{a:?}");
            }
        }
    }

    #[test]
    fn span_level_is_never_finer_than_per_pixel() {
        // The per-pixel level (eq. (2), analytic Jacobian) at the span centre
        // (eq. (8)'s r_spn) is never coarser than the span's: the 4×4 rule is
        // eq. (9) itself, the 3×3 rule one level coarser still. Against each of
        // the four pixels, 3×3 is coarser wherever perspective changes the
        // per-pixel level by less than half a level across the span (at grazing
        // angles the far pixel's derivative exceeds any finite difference).
        let pyr = bricks(128);
        let (tw, th) = (pyr.width(), pyr.height());
        let (mut spans, mut grazing) = (0, 0);
        for v in flight() {
            for sy in 0..v.height / 2 {
                for sx in 0..v.width / 2 {
                    let px: Vec<(Vec2, Jacobian)> =
                        SPAN_PIXELS.iter().filter_map(|&(dx, dy)| v.uv(tw, th, 2 * sx + dx, 2 * sy + dy)).collect();
                    let Some((_, [jx, jy])) = v.map_point_and_jacobian(2.0 * sx as f64 + 0.5, 2.0 * sy as f64 + 0.5)
                    else {
                        continue;
                    };
                    if px.len() < 4 {
                        continue;
                    }
                    let jc = Jacobian {
                        du_dx: (jx[0] / tw as f64) as f32,
                        dv_dx: (jx[1] / th as f64) as f32,
                        du_dy: (jy[0] / tw as f64) as f32,
                        dv_dy: (jy[1] / th as f64) as f32,
                    };
                    let centre = level_of_detail(LevelRule::MaxPartial, jc, tw, th) as f64;
                    let uv = [px[0].0, px[1].0, px[2].0, px[3].0];
                    let pp: Vec<f64> =
                        px.iter().map(|(_, j)| level_of_detail(LevelRule::MaxPartial, *j, tw, th) as f64).collect();
                    let pp_max = pp.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    let pp_min = pp.iter().copied().fold(f64::INFINITY, f64::min);
                    let o3 = SpanOptions { scheme: SpanScheme::Banks3x3, ..Default::default() };
                    let o4 = SpanOptions { scheme: SpanScheme::Banks4x4, ..Default::default() };
                    let (Some(l3), Some(l4)) = (span_level(&pyr, &o3, uv), span_level(&pyr, &o4, uv)) else {
                        panic!("valid span")
                    };
                    spans += 1;
                    assert!(l4.lambda >= centre - 1e-3, "{v:?} {l4:?} centre {centre}");
                    assert!((l3.lambda - l4.lambda - 1.0).abs() < 1e-9);
                    assert!(l3.level >= l4.level);
                    // the level read is never finer than the per-pixel ⌊λ⌋ at the centre
                    assert!(l4.level as f64 >= centre.floor().min(7.0), "{l4:?} {centre}");
                    if pp_max - pp_min < 0.5 {
                        assert!(l3.lambda >= pp_max - 1e-3, "{v:?} {l3:?} {pp:?}");
                    } else {
                        grazing += 1;
                    }
                }
            }
        }
        assert!(spans > 3000 && grazing * 20 < spans, "{spans} spans, {grazing} grazing");
    }

    #[test]
    fn four_by_four_is_closer_to_trilinear_than_three_by_three() {
        for pattern in [Pattern::Bricks, Pattern::Checker] {
            let pyr = MipPyramid::build(pattern.render(256).unwrap());
            let v = view(90.0, 30.0, 23.0, 128, 96);
            let c3 = render_both(&pyr, &v, &SpanOptions { scheme: SpanScheme::Banks3x3, ..Default::default() });
            let c4 = render_both(&pyr, &v, &SpanOptions { scheme: SpanScheme::Banks4x4, ..Default::default() });
            assert!(c4.psnr >= c3.psnr, "{pattern:?}: 4x4 {} dB < 3x3 {} dB", c4.psnr, c3.psnr);
            assert!(c4.ssim >= c3.ssim, "{pattern:?}: 4x4 {} < 3x3 {}", c4.ssim, c3.ssim);
            assert!(c3.psnr > 15.0 && c3.psnr.is_finite(), "{pattern:?}: {}", c3.psnr);
            assert_eq!(c3.banks.conflicts + c4.banks.conflicts, 0);
            // the span levels are coarser on average
            assert!(c3.banks.mean_level() > c4.banks.mean_level());
        }
    }

    #[test]
    fn bicubic_is_finite_and_in_range() {
        let pyr = bricks(128);
        for scheme in [SpanScheme::Banks3x3, SpanScheme::Banks4x4] {
            let opts = SpanOptions { scheme, filter: SpanFilter::Bicubic, ..Default::default() };
            let mut m = BankModel::new(scheme);
            for sy in 0..40 {
                for sx in 0..40 {
                    let base = Vec2::new(sx as f32 * 0.0137 - 0.2, sy as f32 * 0.0091 + 0.3);
                    let d = 0.002 + 0.0005 * ((sx + sy) % 7) as f32;
                    let uv = [base, base + Vec2::new(d, 0.0003), base + Vec2::new(-0.0002, d), base + Vec2::splat(d)];
                    for c in sample_span(&pyr, &opts, uv, &mut m) {
                        assert!(c.is_finite(), "{c:?}");
                        assert!(c.min_element() >= 0.0 && c.max_element() <= 1.0, "{c:?}");
                    }
                }
            }
            assert_eq!(m.conflicts, 0);
        }
        // on a constant texture every filter returns the constant
        let flat = MipPyramid::build(Image::filled(16, 16, ColorSpace::Linear, [51, 102, 204, 255]).unwrap());
        for opts in all_opts(Wrap::Repeat) {
            let mut m = BankModel::new(opts.scheme);
            let uv = [Vec2::new(0.1, 0.2), Vec2::new(0.13, 0.2), Vec2::new(0.1, 0.24), Vec2::new(0.13, 0.24)];
            for c in sample_span(&flat, &opts, uv, &mut m) {
                assert!((c - Vec4::new(0.2, 0.4, 0.8, 1.0)).abs().max_element() < 1e-5, "{opts:?} {c:?}");
            }
        }
    }

    #[test]
    fn single_point_span_equals_the_bilinear_sampler() {
        // four equal points: E = 0, level 0, eq. (4)'s t_c
        let pyr = bricks(64);
        let mut m = BankModel::new(SpanScheme::Banks3x3);
        for (u, v) in [(0.3f32, 0.7f32), (0.01, 0.99), (-1.37, 2.2)] {
            let p = Vec2::new(u, v);
            let c = sample_span(&pyr, &SpanOptions::default(), [p; 4], &mut m);
            let reference = bilinear(&pyr, 0, Wrap::Repeat, Vec2::new(u - u.floor(), v - v.floor()));
            for x in c {
                assert!((x - reference).abs().max_element() < 1e-4, "{x:?} {reference:?}");
            }
        }
    }

    #[test]
    fn memory_is_a_quarter() {
        let pyr = bricks(256);
        let m3 = memory_for_pyramid(&pyr, SpanScheme::Banks3x3);
        let m4 = memory_for_pyramid(&pyr, SpanScheme::Banks4x4);
        assert_eq!((m3.conventional_banks, m3.span_banks, m4.span_banks), (16, 9, 16));
        assert_eq!(m3.conventional_bytes, 4 * pyr.texel_count() as u64 * 4);
        assert!((m3.unpadded_ratio() - 0.25).abs() < 1e-12);
        // per-level padding of the sides to multiples of 3 (258² for 256², …) costs ~2 %
        assert!(m3.ratio() >= 0.25 && m3.ratio() < 0.26, "{}", m3.ratio());
        assert!((m4.ratio() - 0.25).abs() < 1e-3, "{}", m4.ratio());
        // independently of the formula: lay every texel of every level out
        // by the banks' addressing (bank_of, address_in_bank); banks work in
        // lockstep, so each holds the largest extent any bank needs
        for (scheme, m) in [(SpanScheme::Banks3x3, m3), (SpanScheme::Banks4x4, m4)] {
            let b = scheme.side();
            let mut bytes = 0u64;
            for l in pyr.levels() {
                let mut extent = [[0i64; 2]; 16];
                for y in 0..l.height() as i64 {
                    for x in 0..l.width() as i64 {
                        let [i, j] = bank_of([x, y], b);
                        let a = address_in_bank([x, y], b);
                        let e = &mut extent[j * b + i];
                        *e = [e[0].max(a[0] + 1), e[1].max(a[1] + 1)];
                    }
                }
                let (ex, ey) = (extent.iter().map(|e| e[0]).max().unwrap(), extent.iter().map(|e| e[1]).max().unwrap());
                bytes += (b * b) as u64 * (ex * ey) as u64 * 4;
            }
            assert_eq!(bytes, m.span_bytes, "{scheme:?}: the addressing needs {bytes} bytes");
            assert_eq!(m.conventional_bytes, 4 * m.copy_bytes);
        }
        // sides that are multiples of 3 need no padding
        let m = memory_report(&[(9, 6), (3, 3)], 4, SpanScheme::Banks3x3);
        assert_eq!(m.span_bytes, m.copy_bytes);
        assert_eq!(m.conventional_bytes, 4 * m.copy_bytes);
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let pyr = bricks(32);
        for opts in all_opts(Wrap::Repeat).into_iter().chain(all_opts(Wrap::Clamp)).chain(all_opts(Wrap::Mirror)) {
            let mut m = BankModel::new(opts.scheme);
            let n = Vec2::NAN;
            let inf = Vec2::new(f32::INFINITY, 0.5);
            let cases = [
                [n; 4],
                [n, n, n, Vec2::new(0.5, 0.5)],
                [inf, Vec2::new(0.5, 0.5), n, Vec2::new(0.51, 0.5)],
                [Vec2::new(1e30, -1e30), Vec2::ZERO, Vec2::new(-1e30, 1e30), Vec2::splat(f32::MAX)],
                [Vec2::new(1e6, 1e6), Vec2::new(1e6 + 0.5, 1e6), Vec2::new(1e6, 1e6 + 0.5), Vec2::new(-3.0, 7.0)],
            ];
            for uv in cases {
                let c = sample_span(&pyr, &opts, uv, &mut m);
                for (i, x) in c.iter().enumerate() {
                    assert!(x.is_finite(), "{opts:?} {uv:?} {c:?}");
                    if !uv[i].is_finite() {
                        assert_eq!(*x, Vec4::ZERO);
                    }
                }
            }
            assert_eq!(m.conflicts, 0, "{opts:?}");
            assert_eq!(span_level(&pyr, &opts, [n; 4]), None);
        }
        // a 1×1 and a single-level pyramid, odd frame sizes, the horizon, bad cameras
        let one = MipPyramid::build(Image::filled(1, 1, ColorSpace::Srgb, [9, 9, 9, 255]).unwrap());
        let single = MipPyramid::single(Pattern::Checker.render(16).unwrap());
        for p in [&one, &single, &pyr] {
            for v in [view(5.0, 3.0, 10.0, 17, 13), view(5.0, 1.0, 0.0, 9, 7)] {
                let c = render_both(p, &v, &SpanOptions::default());
                assert_eq!(c.span.rgba.len(), 4 * v.width as usize * v.height as usize);
                // the top rows look above the horizon: sky in both
                assert_eq!(&c.span.rgba[..4], &SKY);
                assert_eq!(&c.trilinear.rgba[..4], &SKY);
                assert!(c.psnr > 10.0, "{}", c.psnr);
            }
        }
        for bad in [view(-1.0, 30.0, 0.0, 4, 4), view(f64::NAN, 30.0, 0.0, 4, 4), view(10.0, 30.0, f64::INFINITY, 4, 4)]
        {
            assert_eq!(bad.map_point(1, 1), None);
            let c = render_both(&pyr, &bad, &SpanOptions::default());
            assert!(c.span.rgba.chunks_exact(4).all(|p| p == SKY));
        }
        let empty = Frame { width: 0, height: 0, rgba: vec![] };
        assert!(psnr(&empty, &empty).is_nan() && ssim(&empty, &empty).is_nan());
    }

    #[test]
    fn flight_geometry_and_jacobian() {
        // looking straight down (pitch 90) from h: the centre pixel sees the
        // ground under the eye, one pixel is h/k texels
        let v = view(100.0, 90.0, 0.0, 64, 64);
        let Some((p, [jx, jy])) = v.map_point_and_jacobian(31.5, 31.5) else { panic!("ground") };
        assert!((p[0] - v.position[0]).abs() < 1e-9 && (p[1] - v.position[1]).abs() < 1e-9, "{p:?}");
        let s = v.altitude / v.k();
        assert!((jx[0] - s).abs() < 1e-9 && jx[1].abs() < 1e-9, "{jx:?}");
        // heading north, looking down: screen up (−y) is north (−v), so ∂v/∂y = +s
        assert!((jy[1] - s).abs() < 1e-9 && jy[0].abs() < 1e-9, "{jy:?}");
        // the analytic Jacobian matches finite differences in an oblique view
        let v = view(50.0, 25.0, 37.0, 64, 48);
        let e = 1e-4;
        for (x, y) in [(3.0, 40.0), (60.0, 20.0), (32.0, 47.0)] {
            let Some((_, [jx, jy])) = v.map_point_and_jacobian(x, y) else { panic!("ground") };
            let f = |x, y| v.map_point_and_jacobian(x, y).map(|(p, _)| p).unwrap_or([f64::NAN; 2]);
            let (px0, px1, py0, py1) = (f(x - e, y), f(x + e, y), f(x, y - e), f(x, y + e));
            for k in 0..2 {
                assert!((jx[k] - (px1[k] - px0[k]) / (2.0 * e)).abs() < 1e-4 * (1.0 + jx[k].abs()));
                assert!((jy[k] - (py1[k] - py0[k]) / (2.0 * e)).abs() < 1e-4 * (1.0 + jy[k].abs()));
            }
        }
        // pitch 10°, vertical FOV ~34°: the top rows are sky, the bottom rows ground
        let v = view(50.0, 10.0, 0.0, 64, 48);
        assert_eq!(v.map_point(10, 0), None);
        assert!(v.map_point(10, 47).is_some());
    }

    #[test]
    fn identical_frames_compare_perfectly() {
        let pyr = bricks(64);
        let f = render_trilinear(&pyr, &view(30.0, 40.0, 0.0, 20, 10), Wrap::Repeat);
        assert_eq!(psnr(&f, &f), f64::INFINITY);
        assert!((ssim(&f, &f) - 1.0).abs() < 1e-12);
        let mut g = f.clone();
        g.rgba[0] = g.rgba[0].wrapping_add(40);
        assert!(psnr(&f, &g).is_finite() && ssim(&f, &g) < 1.0);
    }
}
