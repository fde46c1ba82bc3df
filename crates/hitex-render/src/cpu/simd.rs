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

use std::sync::atomic::{AtomicU8, Ordering};

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

/// The level `HITEX_SIMD` asks for: `Ok(None)` when unset or `auto`, an
/// error naming the levels when it names none or one this processor lacks.
pub fn level_from_env() -> Result<Option<SimdLevel>, String> {
    let Ok(v) = std::env::var("HITEX_SIMD") else { return Ok(None) };
    if v.trim().is_empty() || v.trim().eq_ignore_ascii_case("auto") {
        return Ok(None);
    }
    let names: Vec<&str> = SimdLevel::available_levels().iter().map(|l| l.name()).collect();
    match SimdLevel::from_name(&v) {
        Some(l) if l.available() => Ok(Some(l)),
        Some(l) => Err(format!("HITEX_SIMD={v}: this processor lacks {l}; it runs {}", names.join(", "))),
        None => Err(format!("HITEX_SIMD={v} names no level; this processor runs {} (or auto)", names.join(", "))),
    }
}

/// The level the CPU backend runs at: set by [`set_level`], else
/// `HITEX_SIMD` (an unusable value falls back to detection; `hitex` checks it
/// first and refuses it), else the widest available.
pub fn level() -> SimdLevel {
    if let Some(l) = SimdLevel::of_code(LEVEL.load(Ordering::Relaxed)) {
        return l;
    }
    let l = level_from_env().ok().flatten().unwrap_or_else(SimdLevel::detect);
    LEVEL.store(l.code(), Ordering::Relaxed);
    l
}

/// Makes the CPU backend run at `l` from now on (process-wide).
pub fn set_level(l: SimdLevel) -> Result<(), String> {
    if !l.available() {
        return Err(format!("this processor lacks {l}"));
    }
    LEVEL.store(l.code(), Ordering::Relaxed);
    Ok(())
}

/// Runs `op` compiled for the current [`level`].
#[inline(always)]
pub fn run<Op: pulp::WithSimd>(op: Op) -> Op::Output {
    use pulp::Simd;
    match level() {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
