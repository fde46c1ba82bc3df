//! Runtime SIMD dispatch of the CPU backend.
//!
//! The fragment programs and the rasterizer's block stage are written over
//! lane arrays ([`Lanes`] = `[f32; 16]`, structure of arrays) in
//! `#[inline(always)]` code; [`run`] enters that code through `pulp`, whose
//! `vectorize` compiles it once per instruction set (`#[target_feature]`) and
//! picks the set at run time. Inside, LLVM turns each lane loop into one
//! AVX-512 instruction, two AVX2, four SSE4.2 or four SSE2 (the x86-64
//! baseline, [`SimdLevel::Scalar`]), or NEON on aarch64.
//!
//! Every level computes the same IEEE operations in the same order (add,
//! multiply, divide and square root round identically at every width; no
//! fused multiply-add is used, and hitex never lets the compiler contract), so
//! the levels render bit-identical images; `tests/simd_levels.rs` checks it.
//!
//! `HITEX_SIMD=avx512|avx2|sse4|neon|scalar` forces a level (a level this
//! processor lacks is refused with a message; `auto` or unset detects).
//! No `-C target-cpu` is needed or used.

// lane loops index several arrays by the same lane, as the lane code reads
#![allow(clippy::needless_range_loop)]

use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};

/// Lanes per block: 4 quads of 2×2 pixels.
pub const LANES: usize = 16;

/// One f32 per lane.
pub type Lanes = [f32; LANES];

/// An instruction-set level of the CPU backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimdLevel {
    /// The target's baseline only (SSE2 on x86-64): no runtime-detected extension.
    Scalar,
    /// x86-64-v2: SSE4.2 and POPCNT (4 f32 lanes per instruction).
    Sse4,
    /// x86-64-v3: AVX2 and FMA (8 lanes).
    Avx2,
    /// x86-64-v4: AVX-512F/BW/CD/DQ/VL (16 lanes).
    Avx512,
    /// aarch64 NEON (4 lanes).
    Neon,
}

impl SimdLevel {
    /// Every level, widest first.
    pub const ALL: [SimdLevel; 5] =
        [SimdLevel::Avx512, SimdLevel::Avx2, SimdLevel::Sse4, SimdLevel::Neon, SimdLevel::Scalar];

    /// The name `HITEX_SIMD` and the reports use.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Sse4 => "sse4",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Neon => "neon",
        }
    }

    /// The level of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|l| l.name() == name.trim().to_ascii_lowercase())
    }

    /// f32 lanes per instruction.
    pub fn width(self) -> usize {
        match self {
            SimdLevel::Scalar => 1,
            SimdLevel::Sse4 | SimdLevel::Neon => 4,
            SimdLevel::Avx2 => 8,
            SimdLevel::Avx512 => 16,
        }
    }

    /// Whether this processor runs the level.
    pub fn available(self) -> bool {
        match self {
            SimdLevel::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Sse4 => pulp::x86::V2::try_new().is_some(),
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => pulp::x86::V3::try_new().is_some(),
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx512 => pulp::x86::V4::try_new().is_some(),
            #[cfg(target_arch = "aarch64")]
            SimdLevel::Neon => pulp::aarch64::Neon::try_new().is_some(),
            #[allow(unreachable_patterns)]
            _ => false,
        }
    }

    /// The widest level this processor runs.
    pub fn detect() -> Self {
        Self::ALL.iter().copied().find(|l| l.available()).unwrap_or(SimdLevel::Scalar)
    }

    /// Every level this processor runs, widest first.
    pub fn available_levels() -> Vec<SimdLevel> {
        Self::ALL.iter().copied().filter(|l| l.available()).collect()
    }

    fn code(self) -> u8 {
        match self {
            SimdLevel::Scalar => 1,
            SimdLevel::Sse4 => 2,
            SimdLevel::Avx2 => 3,
            SimdLevel::Avx512 => 4,
            SimdLevel::Neon => 5,
        }
    }

    fn of_code(c: u8) -> Option<Self> {
        Self::ALL.iter().copied().find(|l| l.code() == c)
    }
}

impl std::fmt::Display for SimdLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// 0: not chosen yet.
static LEVEL: AtomicU8 = AtomicU8::new(0);
/// True when the level was asked for (`HITEX_SIMD`, [`set_level`]), not detected.
static FORCED: AtomicBool = AtomicBool::new(false);

/// The level `HITEX_SIMD` asks for: `Ok(None)` when unset or `auto`, an
/// error naming the levels when it names none or one this processor lacks.
pub fn level_from_env() -> Result<Option<SimdLevel>, crate::RenderError> {
    let Ok(v) = std::env::var("HITEX_SIMD") else { return Ok(None) };
    if v.trim().is_empty() || v.trim().eq_ignore_ascii_case("auto") {
        return Ok(None);
    }
    let names: Vec<&str> = SimdLevel::available_levels().iter().map(|l| l.name()).collect();
    match SimdLevel::from_name(&v) {
        Some(l) if l.available() => Ok(Some(l)),
        Some(l) => Err(crate::RenderError::Invalid(format!(
            "HITEX_SIMD={v}: this processor lacks {l}; it runs {}",
            names.join(", ")
        ))),
        None => Err(crate::RenderError::Invalid(format!(
            "HITEX_SIMD={v} names no level; this processor runs {} (or auto)",
            names.join(", ")
        ))),
    }
}

/// The level the CPU backend runs at: set by [`set_level`], else
/// `HITEX_SIMD` (an unusable value falls back to detection; `hitex` checks it
/// first and refuses it), else the widest available.
pub fn level() -> SimdLevel {
    if let Some(l) = SimdLevel::of_code(LEVEL.load(Ordering::Relaxed)) {
        return l;
    }
    let forced = level_from_env().ok().flatten();
    FORCED.store(forced.is_some(), Ordering::Relaxed);
    let l = forced.unwrap_or_else(SimdLevel::detect);
    LEVEL.store(l.code(), Ordering::Relaxed);
    l
}

/// The processor's brand string with its x86 family and model (CPUID), e.g.
/// "Intel(R) Xeon(R) Processor (family 6, model 207)": the CPU backend's
/// timings and the SIMD level that suits a program depend on it.
pub fn processor() -> String {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::__cpuid;
        let mut bytes = Vec::with_capacity(48);
        if __cpuid(0x8000_0000).eax >= 0x8000_0004 {
            for leaf in 0x8000_0002u32..=0x8000_0004 {
                let r = __cpuid(leaf);
                for w in [r.eax, r.ebx, r.ecx, r.edx] {
                    bytes.extend_from_slice(&w.to_le_bytes());
                }
            }
        }
        let brand = String::from_utf8_lossy(&bytes).trim_matches(char::from(0)).trim().to_string();
        let (family, model) = family_model(__cpuid(1).eax);
        let brand = if brand.is_empty() { "x86-64 processor".to_string() } else { brand };
        format!("{brand} (family {family}, model {model})")
    }
    #[cfg(not(target_arch = "x86_64"))]
    std::env::consts::ARCH.to_string()
}

/// The display family and model of a CPUID leaf 1 signature (`eax`): the
/// extended family is added to base family 0xf, and the extended model
/// prefixes the model for families 6 and 0xf.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn family_model(eax: u32) -> (u32, u32) {
    let base = (eax >> 8) & 0xf;
    let family = if base == 0xf { base + ((eax >> 20) & 0xff) } else { base };
    let model = if base == 0x6 || base == 0xf { ((eax >> 4) & 0xf) | ((eax >> 12) & 0xf0) } else { (eax >> 4) & 0xf };
    (family, model)
}

/// True where the processor executes a 512-bit vector operation as two
/// 256-bit halves (AMD Zen 4, family 19h). There a program whose lanes are
/// mostly gathers and per-lane reads runs faster at 8 lanes than at 16;
/// where the 512-bit units are whole (Intel's AVX-512 processors, Zen 5) it
/// runs faster at 16.
pub fn splits_512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::__cpuid;
        let v = __cpuid(0);
        let amd = (v.ebx, v.edx, v.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163); // "AuthenticAMD"
        amd && family_model(__cpuid(1).eax).0 == 0x19
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// The level a program whose lanes are mostly gathers and per-lane reads
/// runs at: [`level`] when it was asked for (`HITEX_SIMD`, [`set_level`]:
/// every level stays measurable) or when the processor runs 512-bit
/// operations whole, else at most AVX2 ([`splits_512`]).
pub fn level_for_gathers() -> SimdLevel {
    let l = level();
    if FORCED.load(Ordering::Relaxed) || l.width() <= SimdLevel::Avx2.width() || !splits_512() {
        l
    } else {
        SimdLevel::Avx2
    }
}

/// Whether a sampler's reads at `l` go through vector gathers: at AVX-512
/// where the processor runs it and its gathers are fast
/// ([`gathers_are_fast`]). AVX2 gathers were measured on an AMD Zen 3 against
/// the lane loops and ran no faster, so AVX2 and the narrower levels read
/// lane by lane.
pub fn vector_gathers(l: SimdLevel) -> bool {
    l == SimdLevel::Avx512 && l.available() && gathers_are_fast()
}

/// False where the kernel reports the Gather Data Sampling microcode
/// mitigation (`/sys/devices/system/cpu/vulnerabilities/gather_data_sampling`:
/// "Mitigation: Microcode"), under which a vector gather takes several times
/// its lane loop's time (Intel Skylake to Tiger Lake); true elsewhere
/// ("Not affected", AMD processors, no such file).
pub fn gathers_are_fast() -> bool {
    static FAST: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *FAST.get_or_init(|| {
        std::fs::read_to_string("/sys/devices/system/cpu/vulnerabilities/gather_data_sampling")
            .map(|s| !s.trim_start().starts_with("Mitigation: Microcode"))
            .unwrap_or(true)
    })
}

/// Makes the CPU backend run at `l` from now on (process-wide).
pub fn set_level(l: SimdLevel) -> Result<(), crate::RenderError> {
    if !l.available() {
        return Err(crate::RenderError::Invalid(format!("this processor lacks {l}")));
    }
    LEVEL.store(l.code(), Ordering::Relaxed);
    FORCED.store(true, Ordering::Relaxed);
    Ok(())
}

/// Runs `op` compiled for the current [`level`].
#[inline(always)]
pub fn run<Op: pulp::WithSimd>(op: Op) -> Op::Output {
    run_at(level(), op)
}

/// Runs `op` compiled for `l` (a level this processor lacks runs the baseline).
#[inline(always)]
pub fn run_at<Op: pulp::WithSimd>(l: SimdLevel, op: Op) -> Op::Output {
    use pulp::Simd;
    match l {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 => match pulp::x86::V4::try_new() {
            Some(s) => Simd::vectorize(s, op),
            None => Simd::vectorize(pulp::Scalar::new(), op),
        },
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 => match pulp::x86::V3::try_new() {
            Some(s) => Simd::vectorize(s, op),
            None => Simd::vectorize(pulp::Scalar::new(), op),
        },
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Sse4 => match pulp::x86::V2::try_new() {
            Some(s) => Simd::vectorize(s, op),
            None => Simd::vectorize(pulp::Scalar::new(), op),
        },
        #[cfg(target_arch = "aarch64")]
        SimdLevel::Neon => match pulp::aarch64::Neon::try_new() {
            Some(s) => Simd::vectorize(s, op),
            None => Simd::vectorize(pulp::Scalar::new(), op),
        },
        _ => Simd::vectorize(pulp::Scalar::new(), op),
    }
}

// ---- lane arithmetic: plain loops the level's code generation vectorises ----

/// `[e(i) for each lane i]` as a plain loop. Lane code avoids closures and
/// `std::array::from_fn`: a helper the compiler leaves out of line is
/// compiled for the baseline instruction set, outside the level's code.
macro_rules! lanes {
    (|$i:ident| $e:expr) => {{
        let mut o = [0.0f32; $crate::cpu::simd::LANES];
        for $i in 0..$crate::cpu::simd::LANES {
            o[$i] = $e;
        }
        o
    }};
}
pub(crate) use lanes;

/// The sRGB codes of 16 lanes of linear RGB (alpha 255), channel by channel
/// over the lanes, so that each channel's table reads run as one lane loop
/// rather than three scalar lookups per pixel, and the four bytes of a pixel
/// are put together as one 32-bit word per lane (shifts and ors on whole
/// registers, not byte inserts).
#[inline(always)]
pub fn encode_rgb(enc: &hitex_core::texture::SrgbEncoder, c: &[Lanes; 3]) -> [[u8; 4]; LANES] {
    let mut word = [0xff00_0000u32; LANES];
    for ch in 0..3 {
        for i in 0..LANES {
            word[i] |= enc.code(c[ch][i]) << (8 * ch);
        }
    }
    // little-endian byte order of the word: R, G, B, A
    let mut out = [[0u8; 4]; LANES];
    for i in 0..LANES {
        out[i] = word[i].to_le_bytes();
    }
    out
}

/// `[x; 16]`
#[inline(always)]
pub fn splat(x: f32) -> Lanes {
    [x; LANES]
}

/// Lane-wise `f(a)`.
#[inline(always)]
pub fn map(a: &Lanes, f: impl Fn(f32) -> f32) -> Lanes {
    let mut o = [0.0; LANES];
    for i in 0..LANES {
        o[i] = f(a[i]);
    }
    o
}

/// Lane-wise `f(a, b)`.
#[inline(always)]
pub fn zip(a: &Lanes, b: &Lanes, f: impl Fn(f32, f32) -> f32) -> Lanes {
    let mut o = [0.0; LANES];
    for i in 0..LANES {
        o[i] = f(a[i], b[i]);
    }
    o
}

/// Lane-wise `f(a, b, c)`.
#[inline(always)]
pub fn zip3(a: &Lanes, b: &Lanes, c: &Lanes, f: impl Fn(f32, f32, f32) -> f32) -> Lanes {
    let mut o = [0.0; LANES];
    for i in 0..LANES {
        o[i] = f(a[i], b[i], c[i]);
    }
    o
}

/// A 3-vector of lanes.
#[derive(Clone, Copy, Debug)]
pub struct V3 {
    /// x per lane
    pub x: Lanes,
    /// y per lane
    pub y: Lanes,
    /// z per lane
    pub z: Lanes,
}

impl V3 {
    /// The same vector in every lane.
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Self { x: splat(v.x), y: splat(v.y), z: splat(v.z) }
    }
    /// `a·b` per lane.
    #[inline(always)]
    pub fn dot(&self, b: &V3) -> Lanes {
        let mut o = [0.0; LANES];
        for i in 0..LANES {
            o[i] = self.x[i] * b.x[i] + self.y[i] * b.y[i] + self.z[i] * b.z[i];
        }
        o
    }
    /// `a×b` per lane.
    #[inline(always)]
    pub fn cross(&self, b: &V3) -> V3 {
        V3 {
            x: zip3(&zip(&self.y, &b.z, |p, q| p * q), &self.z, &b.y, |l, p, q| l - p * q),
            y: zip3(&zip(&self.z, &b.x, |p, q| p * q), &self.x, &b.z, |l, p, q| l - p * q),
            z: zip3(&zip(&self.x, &b.y, |p, q| p * q), &self.y, &b.x, |l, p, q| l - p * q),
        }
    }
    /// Lane `i` as a `Vec3`.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::new(self.x[i], self.y[i], self.z[i])
    }
}

/// `log2(x)` of a positive finite `x` from its exponent and a series in the
/// mantissa (max relative error ≈ 2e-7; the same bits at every level).
/// `x = 0` gives −∞; NaN, negative or infinite `x` give NaN or +∞ as `log2`;
/// subnormals are read as 2⁻¹²⁶·m (the results only feed level selection and
/// `pow` of values in [0, 1], where such inputs round to 0 anyway).
#[inline(always)]
pub fn log2(x: f32) -> f32 {
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    // m in [√½, √2) so that the series argument stays small
    let big = m > std::f32::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    e += big as i32;
    // ln m = 2 artanh s, s = (m − 1)/(m + 1), |s| ≤ 0.172
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = 1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0))));
    let l = e as f32 + s * series * (2.0 * std::f32::consts::LOG2_E);
    if x > 0.0 && x < f32::INFINITY {
        l
    } else if x == 0.0 {
        f32::NEG_INFINITY
    } else if x == f32::INFINITY {
        x
    } else {
        f32::NAN
    }
}

/// `2^y` from an integer power and a Taylor series of the fraction
/// (max relative error ≈ 1e-8 plus rounding). `y < −126` gives 0,
/// `y ≥ 128` +∞, NaN gives NaN.
#[inline(always)]
pub fn exp2(y: f32) -> f32 {
    let yc = y.clamp(-126.0, 127.0);
    // y = i + f with f in [−½, ½]
    let i = crate::cpu::simd::floor(yc + 0.5);
    let f = (yc - i) * std::f32::consts::LN_2;
    let p = 1.0
        + f * (1.0
            + f * (1.0 / 2.0
                + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0 + f * (1.0 / 5040.0)))))));
    // 2^i from its exponent bits (i + 127 is a whole float in [1, 254]: the
    // clamped conversion is exact and vectorises, `as i32` would not)
    let r = p * f32::from_bits(whole_u32(i + 127.0) << 23);
    if y < -126.0 {
        0.0
    } else if y >= 128.0 {
        f32::INFINITY
    } else if y.is_nan() {
        y
    } else {
        r
    }
}

/// `x^y` for `x` in [0, ∞) and finite `y > 0`, as a GPU's `pow`: `exp2(y·log2 x)`.
#[inline(always)]
pub fn pow(x: f32, y: f32) -> f32 {
    exp2(y * log2(x))
}

/// `x^y` per lane for `x` in [0, ∞): by squarings and products when `y` is
/// a whole number from 1 to 1024 (the usual specular exponents: 32 is five
/// squarings, where [`pow`] takes a logarithm with a division and an
/// exponential, a tenth of a textured frame), else [`pow`] lane by lane.
/// Either rounds differently from a GPU's `pow` (as [`pow`] does), and
/// gives the same bits at every level.
#[inline(always)]
pub fn pow_lanes(x: &Lanes, y: f32) -> Lanes {
    if !((1.0..=1024.0).contains(&y) && y == floor(y)) {
        return lanes!(|i| pow(x[i], y));
    }
    let mut e = whole_u32(y);
    let mut base = *x;
    let mut r: Option<Lanes> = None;
    loop {
        if e & 1 == 1 {
            r = Some(match r {
                None => base,
                Some(r) => lanes!(|i| r[i] * base[i]),
            });
        }
        e >>= 1;
        if e == 0 {
            // e ≥ 1 at the start: a bit was set on the way
            return r.unwrap_or(base);
        }
        base = lanes!(|i| base[i] * base[i]);
    }
}

/// `t as u32` that vectorises: `hitex_core::texture::sampler::to_u32_clamped`
/// (NaN and negatives 0, fractions cut).
#[inline(always)]
pub fn whole_u32(t: f32) -> u32 {
    hitex_core::texture::sampler::to_u32_clamped(t)
}

/// `t as i32` that vectorises: `hitex_core::texture::sampler::to_i32_clamped`
/// (NaN 0, fractions cut toward zero, the same as `as` inside ±2³¹).
#[inline(always)]
pub fn whole_i32(t: f32) -> i32 {
    hitex_core::texture::sampler::to_i32_clamped(t)
}

/// `floor`, branch-free, for lane loops (no library call at any level).
#[inline(always)]
pub fn floor(t: f32) -> f32 {
    hitex_core::texture::sampler::floor(t)
}

/// Lane indices of the fine x derivative within each quad: `a[HI] − a[LO]`.
const DX_HI: [usize; LANES] = [1, 1, 3, 3, 5, 5, 7, 7, 9, 9, 11, 11, 13, 13, 15, 15];
const DX_LO: [usize; LANES] = [0, 0, 2, 2, 4, 4, 6, 6, 8, 8, 10, 10, 12, 12, 14, 14];
const DY_HI: [usize; LANES] = [2, 3, 2, 3, 6, 7, 6, 7, 10, 11, 10, 11, 14, 15, 14, 15];
const DY_LO: [usize; LANES] = [0, 1, 0, 1, 4, 5, 4, 5, 8, 9, 8, 9, 12, 13, 12, 13];

/// Fine derivative along x of a block's lanes, per quad (WGSL `dpdxFine`).
#[inline(always)]
pub fn ddx(a: &Lanes) -> Lanes {
    lanes!(|i| a[DX_HI[i]] - a[DX_LO[i]])
}

/// Fine derivative along y of a block's lanes, per quad (WGSL `dpdyFine`).
#[inline(always)]
pub fn ddy(a: &Lanes) -> Lanes {
    lanes!(|i| a[DY_HI[i]] - a[DY_LO[i]])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whole exponents by squaring agree with `powf` within their rounding
    /// (a squaring doubles the relative error: about 2y half-ulps in all)
    /// and with [`pow`] within its; zero stays zero; other exponents are
    /// [`pow`]'s bits. (Results below f32's normal range lose their relative
    /// precision: an absolute 1e-37 covers them.)
    #[test]
    fn whole_powers_by_squaring() {
        let x: Lanes = std::array::from_fn(|i| i as f32 / 15.0);
        for y in [1.0f32, 2.0, 3.0, 5.0, 8.0, 32.0, 48.0, 100.0, 1024.0] {
            let got = pow_lanes(&x, y);
            for i in 0..LANES {
                let want = (x[i] as f64).powf(y as f64) as f32;
                let l = if x[i] > 0.0 { (x[i] as f64).log2().abs() as f32 } else { 0.0 };
                assert!((got[i] - want).abs() <= 1.2e-7 * y * want + 1e-37, "{}^{y}: {} {want}", x[i], got[i]);
                let p = pow(x[i], y);
                assert!(
                    (got[i] - p).abs() <= 4e-7 * y * (1.0 + l) * want + 1e-37,
                    "{}^{y} vs pow: {} {p}",
                    x[i],
                    got[i]
                );
            }
            assert_eq!(got[0], 0.0);
        }
        for y in [0.5f32, 31.5, 2000.0] {
            let got = pow_lanes(&x, y);
            for i in 0..LANES {
                assert_eq!(got[i].to_bits(), pow(x[i], y).to_bits());
            }
        }
    }

    #[test]
    fn names_round_trip_and_detection_is_available() {
        for l in SimdLevel::ALL {
            assert_eq!(SimdLevel::from_name(l.name()), Some(l));
        }
        assert!(SimdLevel::detect().available());
        assert!(SimdLevel::Scalar.available());
        assert_eq!(SimdLevel::from_name("AVX2"), Some(SimdLevel::Avx2));
        assert_eq!(SimdLevel::from_name("mmx"), None);
    }

    struct Sum<'a>(&'a [f32]);
    impl pulp::WithSimd for Sum<'_> {
        type Output = Lanes;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) -> Lanes {
            let mut acc = splat(0.0);
            for c in self.0.chunks_exact(LANES) {
                for i in 0..LANES {
                    acc[i] += c[i] * 0.5;
                }
            }
            acc
        }
    }

    #[test]
    fn run_computes_the_same_at_the_current_level() {
        let data: Vec<f32> = (0..LANES * 8).map(|i| (i as f32 * 0.37).sin()).collect();
        let got = run(Sum(&data));
        let mut want = [0.0f32; LANES];
        for c in data.chunks_exact(LANES) {
            for i in 0..LANES {
                want[i] += c[i] * 0.5;
            }
        }
        assert_eq!(got, want);
    }

    #[test]
    fn log2_exp2_and_pow_match_the_library() {
        let mut worst: f32 = 0.0;
        for k in 0..200_000 {
            let x = 1e-30f32 * 1.0007f32.powi(k);
            if !x.is_finite() {
                break;
            }
            let (got, want) = (log2(x), x.log2());
            worst = worst.max((got - want).abs() / want.abs().max(1.0));
        }
        assert!(worst < 4e-7, "log2 error {worst}");
        assert_eq!(log2(0.0), f32::NEG_INFINITY);
        assert_eq!(log2(f32::INFINITY), f32::INFINITY);
        assert!(log2(-1.0).is_nan() && log2(f32::NAN).is_nan());
        let mut worst: f32 = 0.0;
        for k in 0..100_000 {
            let y = -126.0 + k as f32 * 0.00253;
            let (got, want) = (exp2(y), y.exp2());
            worst = worst.max((got - want).abs() / want);
        }
        assert!(worst < 4e-7, "exp2 error {worst}");
        assert_eq!(exp2(-200.0), 0.0);
        assert_eq!(exp2(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp2(300.0), f32::INFINITY);
        // specular powers of cosines, as the lighting uses them
        for s in [1.0f32, 8.0, 32.0, 64.0, 200.0] {
            for k in 0..=1000 {
                let x = k as f32 / 1000.0;
                let (got, want) = (pow(x, s), x.powf(s));
                assert!((got - want).abs() <= 1e-5 * want + 1e-12, "{x}^{s}: {got} vs {want}");
            }
        }
    }

    /// CPUID signatures of known processors: Intel Emerald Rapids (family
    /// 6, model 0xCF = 207), AMD Zen 4 (base family 0xf + extended 0xA =
    /// 0x19, model 0x11), and a family-5 part whose extended model bits
    /// are not part of its model.
    #[test]
    fn family_and_model_decode_known_signatures() {
        assert_eq!(family_model(0x000C_06F2), (6, 207));
        assert_eq!(family_model(0x00A1_0F11), (0x19, 0x11));
        assert_eq!(family_model(0x0001_0543), (5, 4));
    }

    #[test]
    fn block_derivatives_stay_within_each_quad() {
        // f = 3x + 5y + 100q over four quads
        let a: Lanes = std::array::from_fn(|i| {
            let (q, l) = (i / 4, i % 4);
            3.0 * (l % 2) as f32 + 5.0 * (l / 2) as f32 + 100.0 * q as f32
        });
        assert_eq!(ddx(&a), [3.0; LANES]);
        assert_eq!(ddy(&a), [5.0; LANES]);
    }
}
