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

use super::image::linear_to_srgb_u8;
use super::pyramid::MipPyramid;
use super::sampler::{Filter, Jacobian, LevelRule, SamplerOptions, Wrap, sample};
use crate::frame::Frame;
use glam::{Vec2, Vec4};
use rayon::prelude::*;

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

/// Records the bank traffic of span accesses and counts conflicts.
#[derive(Debug, Clone, Default)]
pub struct BankModel {
    side: usize,
    /// Spans sampled (with at least one valid pixel).
    pub spans: u64,
    /// Span accesses: one per span and level read.
    pub accesses: u64,
    /// Distinct words (bank, address) read over all accesses.
    pub words: u64,
    /// Extra bank cycles: over accesses and banks, distinct addresses − 1.
    pub conflicts: u64,
    /// Accesses with at least one conflict.
    pub conflicted_accesses: u64,
    /// Spans whose level the rounding guard raised.
    pub guard_raises: u64,
    /// Σ (level + γ) over spans: with [`BankModel::spans`], the mean λ used.
    pub level_sum: f64,
    log: Option<Vec<SpanAccess>>,
    scratch: Vec<(u8, u8, i64, i64)>,
    texels: Vec<[i64; 2]>,
}

impl BankModel {
    /// A model for `scheme` keeping counters only.
    pub fn new(scheme: SpanScheme) -> Self {
        Self { side: scheme.side(), ..Default::default() }
    }
    /// A model that also keeps every access ([`BankModel::log`]).
    pub fn with_log(scheme: SpanScheme) -> Self {
        Self { log: Some(Vec::new()), ..Self::new(scheme) }
    }
    /// Banks per side.
    pub fn side(&self) -> usize {
        self.side
    }
    /// Every access recorded, in order (empty unless made by [`BankModel::with_log`]).
    pub fn log(&self) -> &[SpanAccess] {
        self.log.as_deref().unwrap_or(&[])
    }
    /// Mean λ (level + γ) over the spans sampled; NaN without spans.
    pub fn mean_level(&self) -> f64 {
        if self.spans == 0 { f64::NAN } else { self.level_sum / self.spans as f64 }
    }
    /// Adds another model's counters and log (same scheme) after this one's.
    pub fn merge(&mut self, other: BankModel) {
        self.spans += other.spans;
        self.accesses += other.accesses;
        self.words += other.words;
        self.conflicts += other.conflicts;
        self.conflicted_accesses += other.conflicted_accesses;
        self.guard_raises += other.guard_raises;
        self.level_sum += other.level_sum;
        if let (Some(a), Some(b)) = (self.log.as_mut(), other.log) {
            a.extend(b);
        }
    }

    /// Records one access at `level` of the mspan starting at `origin` that
    /// reads `texels` (unwrapped texel coordinates, repeats allowed: the same
    /// word read twice is one read). Returns the conflicts of this access.
    pub fn record(&mut self, level: usize, origin: [i64; 2], texels: &[[i64; 2]]) -> u64 {
        let b = self.side.max(1);
        self.scratch.clear();
        for t in texels {
            let bank = bank_of(*t, b);
            let a = address_in_bank(*t, b);
            self.scratch.push((bank[0] as u8, bank[1] as u8, a[0], a[1]));
        }
        self.scratch.sort_unstable();
        self.scratch.dedup();
        let mut conflicts = 0;
        for w in self.scratch.windows(2) {
            if w[0].0 == w[1].0 && w[0].1 == w[1].1 {
                conflicts += 1;
            }
        }
        self.accesses += 1;
        self.words += self.scratch.len() as u64;
        self.conflicts += conflicts;
        if conflicts > 0 {
            self.conflicted_accesses += 1;
        }
        if let Some(log) = self.log.as_mut() {
            log.push(SpanAccess {
                level: level.min(u32::MAX as usize) as u32,
                origin,
                served: self.scratch.iter().map(|&(i, j, x, y)| ([i, j], [x, y])).collect(),
            });
        }
        conflicts
    }
}

/// Bank (i, j) = (x mod B, y mod B) holding texel `t` with `b` banks per side.
pub fn bank_of(t: [i64; 2], b: usize) -> [usize; 2] {
    let b = b.max(1) as i64;
    [t[0].rem_euclid(b) as usize, t[1].rem_euclid(b) as usize]
}

/// Address of texel `t` inside its bank: (x div B, y div B).
pub fn address_in_bank(t: [i64; 2], b: usize) -> [i64; 2] {
    let b = b.max(1) as i64;
    [t[0].div_euclid(b), t[1].div_euclid(b)]
}

/// Eq. (10): the address bank `bank` reads for the mspan starting at
/// `origin`: `⌊x0 / B⌋ + δ(i, x0)` per axis, `δ(i, x0) = 1` if `i < x0 mod B`.
pub fn eq10_address(origin: [i64; 2], bank: [usize; 2], b: usize) -> [i64; 2] {
    let bi = b.max(1) as i64;
    let axis = |x0: i64, i: usize| x0.div_euclid(bi) + i64::from((i as i64) < x0.rem_euclid(bi));
    [axis(origin[0], bank[0]), axis(origin[1], bank[1])]
}

/// Texture memory of the two designs (seed 001, §3–4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryReport {
    /// Pixels processed in parallel (4: one span).
    pub pixel_processors: u32,
    /// Banks of the conventional design: 2×2 per processor, 16 in all.
    pub conventional_banks: u32,
    /// Bytes of the conventional design: one full pyramid per processor.
    pub conventional_bytes: u64,
    /// Banks of the span design (9 or 16).
    pub span_banks: u32,
    /// Bytes of one pyramid copy, unpadded.
    pub copy_bytes: u64,
    /// Bytes of the span design: one copy, each level's sides padded up to a
    /// multiple of the bank side so that every bank has whole rows.
    pub span_bytes: u64,
}

impl MemoryReport {
    /// Span memory over conventional memory (padded; about 1/4).
    pub fn ratio(&self) -> f64 {
        self.span_bytes as f64 / self.conventional_bytes.max(1) as f64
    }
    /// The same without the bank padding (exactly 1/4 for 4 processors).
    pub fn unpadded_ratio(&self) -> f64 {
        self.copy_bytes as f64 / self.conventional_bytes.max(1) as f64
    }
}

/// Memory of both designs for levels of the given sizes, `bytes_per_texel` each.
pub fn memory_report(level_sizes: &[(u32, u32)], bytes_per_texel: u32, scheme: SpanScheme) -> MemoryReport {
    let b = scheme.side() as u64;
    let bpt = bytes_per_texel as u64;
    let copy: u64 = level_sizes.iter().map(|&(w, h)| w as u64 * h as u64 * bpt).sum();
    let padded: u64 =
        level_sizes.iter().map(|&(w, h)| (w as u64).div_ceil(b) * b * (h as u64).div_ceil(b) * b * bpt).sum();
    let processors = 4u32;
    MemoryReport {
        pixel_processors: processors,
        conventional_banks: processors * 4,
        conventional_bytes: copy * processors as u64,
        span_banks: scheme.banks(),
        copy_bytes: copy,
        span_bytes: padded,
    }
}

/// [`memory_report`] for an RGBA8 pyramid.
pub fn memory_for_pyramid(pyr: &MipPyramid, scheme: SpanScheme) -> MemoryReport {
    let sizes: Vec<(u32, u32)> = pyr.levels().iter().map(|l| (l.width(), l.height())).collect();
    memory_report(&sizes, 4, scheme)
}

/// The span's points brought into one wrap period together, in f64 uv.
struct SpanPoints {
    uv: [Option<[f64; 2]>; 4],
}

impl SpanPoints {
    fn new(uv: [Vec2; 4], wrap: Wrap) -> Self {
        let anchor = uv.iter().find(|p| p.is_finite()).copied();
        let offset = |a: f32| -> f64 {
            let a = a as f64;
            match wrap {
                Wrap::Repeat => a.floor(),
                Wrap::Mirror => 2.0 * (a * 0.5).floor(),
                Wrap::Clamp => 0.0,
            }
        };
        let off = anchor.map(|a| [offset(a.x), offset(a.y)]).unwrap_or([0.0; 2]);
        let uv = uv.map(|p| p.is_finite().then(|| [p.x as f64 - off[0], p.y as f64 - off[1]]));
        Self { uv }
    }
    fn any(&self) -> bool {
        self.uv.iter().any(Option::is_some)
    }
    /// Per-axis (min, max) of the valid uv.
    fn bounds(&self) -> [(f64, f64); 2] {
        let mut b = [(f64::INFINITY, f64::NEG_INFINITY); 2];
        for p in self.uv.iter().flatten() {
            for k in 0..2 {
                b[k] = (b[k].0.min(p[k]), b[k].1.max(p[k]));
            }
        }
        b
    }
}

/// Size of level `k`, continued past the last level by halving.
fn level_size(pyr: &MipPyramid, k: usize) -> [f64; 2] {
    let last = pyr.level_count() - 1;
    let img = pyr.level(k.min(last));
    let s = [img.width() as f64, img.height() as f64];
    if k <= last {
        s
    } else {
        let f = 0.5f64.powi((k - last).min(1000) as i32);
        [s[0] * f, s[1] * f]
    }
}

/// Texel-space position (centres at half-integers) of uv at a level of `size`.
#[inline]
fn texel_pos(uv: [f64; 2], size: [f64; 2]) -> [f64; 2] {
    [uv[0] * size[0] - 0.5, uv[1] * size[1] - 0.5]
}

/// Largest level the rule may pick beyond the pyramid's last.
const VIRTUAL_LEVELS: usize = 192;

fn choose_level(pyr: &MipPyramid, opts: &SpanOptions, pts: &SpanPoints) -> SpanLevel {
    let b = opts.scheme.side();
    let bounds = pts.bounds();
    let (w, h) = (pyr.width() as f64, pyr.height() as f64);
    let extent = ((bounds[0].1 - bounds[0].0) * w).max((bounds[1].1 - bounds[1].0) * h);
    let extent = if extent.is_finite() { extent.max(0.0) } else { f64::MAX };
    let lambda = (2.0 * extent / (b - 2) as f64).log2();
    let cap = pyr.level_count() - 1 + VIRTUAL_LEVELS;
    let (mut level, gamma) = if lambda.is_nan() || lambda <= 0.0 {
        (0usize, 0.0f32)
    } else {
        let f = lambda.floor();
        if f >= cap as f64 { (cap, 0.0) } else { (f as usize, (lambda - f) as f32) }
    };
    // rounding guard: the finer level's bilinear footprint must fit B texels
    let mut guard_raised = false;
    while level < cap && !footprint_fits(pts, level_size(pyr, level), b) {
        level += 1;
        guard_raised = true;
    }
    let level = (level as i64 + opts.level_shift as i64).clamp(0, cap as i64) as usize;
    SpanLevel { extent, lambda, level, gamma, guard_raised }
}

fn footprint_fits(pts: &SpanPoints, size: [f64; 2], b: usize) -> bool {
    let bounds = pts.bounds();
    (0..2).all(|k| {
        let lo = (bounds[k].0 * size[k] - 0.5).floor();
        let hi = (bounds[k].1 * size[k] - 0.5).floor();
        hi - lo + 2.0 <= b as f64
    })
}

/// The level [`sample_span`] would use for these four points (None if no
/// point is finite).
pub fn span_level(pyr: &MipPyramid, opts: &SpanOptions, uv: [Vec2; 4]) -> Option<SpanLevel> {
    let pts = SpanPoints::new(uv, opts.wrap);
    pts.any().then(|| choose_level(pyr, opts, &pts))
}

/// Filter taps on one axis: texel indices and weights.
#[derive(Clone, Copy)]
struct AxisTaps {
    idx: [i64; 4],
    w: [f32; 4],
    n: usize,
}

#[inline]
fn floor_i64(x: f64) -> i64 {
    // saturating conversion; positions are finite here
    x.floor() as i64
}

/// The four Catmull-Rom weights (a = −½) of the taps at −1, 0, 1, 2 for a
/// position `t` ∈ [0, 1) past tap 0: the one bicubic kernel of the span
/// samplers, the CPU flight program's included.
#[inline(always)]
pub fn catmull_rom(t: f32) -> [f32; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    [0.5 * (-t3 + 2.0 * t2 - t), 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0), 0.5 * (-3.0 * t3 + 4.0 * t2 + t), 0.5 * (t3 - t2)]
}

fn axis_taps(p: f64, filter: SpanFilter, block: (i64, i64)) -> AxisTaps {
    let f = p.floor();
    let t = (p - f) as f32;
    let f = floor_i64(p);
    match filter {
        SpanFilter::Bilinear => AxisTaps { idx: [f, f.saturating_add(1), 0, 0], w: [1.0 - t, t, 0.0, 0.0], n: 2 },
        SpanFilter::Bicubic => {
            let c = |d: i64| f.saturating_add(d).clamp(block.0, block.1);
            AxisTaps { idx: [c(-1), c(0), c(1), c(2)], w: catmull_rom(t), n: 4 }
        }
    }
}

/// The mspan's first and last texel per axis, and each valid pixel's taps.
struct LevelPlan {
    origin: [i64; 2],
    taps: [Option<[AxisTaps; 2]>; 4],
}

fn plan_level(pts: &SpanPoints, size: [f64; 2], b: usize, filter: SpanFilter) -> LevelPlan {
    let pos = pts.uv.map(|p| p.map(|p| texel_pos(p, size)));
    let mut origin = [0i64; 2];
    let mut blocks = [(0i64, 0i64); 2];
    for k in 0..2 {
        let lo = pos.iter().flatten().map(|p| floor_i64(p[k])).min().unwrap_or(0);
        let hi = pos.iter().flatten().map(|p| floor_i64(p[k])).max().unwrap_or(0);
        let o = match filter {
            SpanFilter::Bilinear => lo,
            SpanFilter::Bicubic => {
                // centre the B texels on the cubic footprint ⌊min⌋−1 ..= ⌊max⌋+2
                let needed = hi.saturating_sub(lo).saturating_add(4);
                lo.saturating_sub(1).saturating_add((needed - b as i64).max(0) / 2)
            }
        };
        origin[k] = o;
        blocks[k] = (o, o.saturating_add(b as i64 - 1));
    }
    let taps = pos.map(|p| p.map(|p| [axis_taps(p[0], filter, blocks[0]), axis_taps(p[1], filter, blocks[1])]));
    LevelPlan { origin, taps }
}

fn record_plan(banks: &mut BankModel, level: usize, plan: &LevelPlan, scratch: &mut Vec<[i64; 2]>) {
    scratch.clear();
    for [tx, ty] in plan.taps.iter().flatten() {
        for &y in &ty.idx[..ty.n] {
            for &x in &tx.idx[..tx.n] {
                scratch.push([x, y]);
            }
        }
    }
    banks.record(level, plan.origin, scratch);
}

#[inline]
fn wrap_i64(i: i64, n: i64, wrap: Wrap) -> usize {
    if i >= 0 && i < n {
        return i as usize;
    }
    (match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m >= n { 2 * n - 1 - m } else { m }
        }
    }) as usize
}

/// Filters each valid pixel of `plan` from level `level` (a real level).
fn filter_plan(pyr: &MipPyramid, level: usize, wrap: Wrap, plan: &LevelPlan) -> [Vec4; 4] {
    let img = pyr.level(level);
    let (w, h) = (img.width() as i64, img.height() as i64);
    let texels = pyr.linear_level(level);
    let fetch = |x: i64, y: i64| texels[wrap_i64(y, h, wrap) * w as usize + wrap_i64(x, w, wrap)];
    plan.taps.map(|t| {
        let Some([tx, ty]) = t else { return Vec4::ZERO };
        let mut acc = Vec4::ZERO;
        let (mut lo, mut hi) = (Vec4::splat(f32::INFINITY), Vec4::splat(f32::NEG_INFINITY));
        for j in 0..ty.n {
            let mut row = Vec4::ZERO;
            for i in 0..tx.n {
                let c = fetch(tx.idx[i], ty.idx[j]);
                row += c * tx.w[i];
                lo = lo.min(c);
                hi = hi.max(c);
            }
            acc += row * ty.w[j];
        }
        if tx.n > 2 { acc.clamp(lo, hi) } else { acc }
    })
}

/// Samples the four pixels of a span (order [`SPAN_PIXELS`]) at `uv` in one
/// access per level from the shared banked memory; records the accesses in
/// `banks`. Returns linear RGBA; pixels with a non-finite uv are skipped
/// (zero) and do not take part in the level choice.
pub fn sample_span(pyr: &MipPyramid, opts: &SpanOptions, uv: [Vec2; 4], banks: &mut BankModel) -> [Vec4; 4] {
    let pts = SpanPoints::new(uv, opts.wrap);
    if !pts.any() {
        return [Vec4::ZERO; 4];
    }
    let b = opts.scheme.side();
    let lv = choose_level(pyr, opts, &pts);
    banks.spans += 1;
    banks.guard_raises += u64::from(lv.guard_raised);
    banks.level_sum += lv.level as f64 + lv.gamma as f64;
    let last = pyr.level_count() - 1;
    let mut scratch = std::mem::take(&mut banks.texels);
    let mut level_values = |k: usize| -> [Vec4; 4] {
        let plan = plan_level(&pts, level_size(pyr, k), b, opts.filter);
        record_plan(banks, k, &plan, &mut scratch);
        if k <= last {
            filter_plan(pyr, k, opts.wrap, &plan)
        } else {
            // virtual level: the value of the last level
            let p = plan_level(&pts, level_size(pyr, last), b, opts.filter);
            filter_plan(pyr, last, opts.wrap, &p)
        }
    };
    let c0 = level_values(lv.level);
    let out = if lv.gamma > 0.0 {
        let c1 = level_values(lv.level + 1);
        std::array::from_fn(|i| c0[i] + (c1[i] - c0[i]) * lv.gamma)
    } else {
        c0
    };
    banks.texels = scratch;
    out
}

/// A pinhole camera flying over flat textured ground (eq. (1) for a
/// horizontal face). Ground coordinates are level-0 texels (x east = u,
/// y south = v); the camera looks `pitch_deg` below the horizon towards
/// `heading_deg` (clockwise from north, i.e. from −y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlightView {
    /// Eye position over the ground, level-0 texels.
    pub position: [f64; 2],
    /// Height of the eye above the ground, level-0 texels.
    pub altitude: f64,
    /// Pitch below the horizon, degrees.
    pub pitch_deg: f64,
    /// Heading, degrees clockwise from north.
    pub heading_deg: f64,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl FlightView {
    /// The paper's `k = n_pxl / (2 tan(ψ_FOV/2))`: pixels per unit of tan(angle).
    pub fn k(&self) -> f64 {
        self.width as f64 / (2.0 * (self.fov_deg.to_radians() / 2.0).tan())
    }

    fn usable(&self) -> bool {
        [self.position[0], self.position[1], self.altitude, self.pitch_deg, self.heading_deg, self.fov_deg]
            .iter()
            .all(|v| v.is_finite())
            && self.altitude > 0.0
            && self.fov_deg > 0.0
            && self.fov_deg < 180.0
    }

    /// Forward, right and up unit vectors (z up).
    fn basis(&self) -> [[f64; 3]; 3] {
        let (p, h) = (self.pitch_deg.to_radians(), self.heading_deg.to_radians());
        let d = [h.sin(), -h.cos()];
        let f = [d[0] * p.cos(), d[1] * p.cos(), -p.sin()];
        let r = [h.cos(), h.sin(), 0.0];
        // u = f × r
        let u = [f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2], f[0] * r[1] - f[1] * r[0]];
        [f, r, u]
    }

    /// Ground point seen through pixel `(x, y)`'s centre and its derivatives
    /// with respect to the screen x and y (texels per pixel); None above the
    /// horizon or for an unusable camera.
    pub fn map_point_and_jacobian(&self, x: f64, y: f64) -> Option<([f64; 2], [[f64; 2]; 2])> {
        if !self.usable() {
            return None;
        }
        let [f, r, u] = self.basis();
        let k = self.k();
        let xs = x + 0.5 - self.width as f64 / 2.0;
        let ys = y + 0.5 - self.height as f64 / 2.0;
        let d: [f64; 3] = std::array::from_fn(|i| k * f[i] + xs * r[i] - ys * u[i]);
        if d[2].is_nan() || d[2] >= -1e-12 {
            return None;
        }
        let h = self.altitude;
        let t = -h / d[2];
        let p = [self.position[0] + t * d[0], self.position[1] + t * d[1]];
        // ∂P/∂xs = t r + (h r_z / d_z²) d;  ∂P/∂ys = −t u − (h u_z / d_z²) d
        let dz2 = d[2] * d[2];
        let (ax, ay) = (h * r[2] / dz2, -h * u[2] / dz2);
        let jx = [t * r[0] + ax * d[0], t * r[1] + ax * d[1]];
        let jy = [-t * u[0] + ay * d[0], -t * u[1] + ay * d[1]];
        (p[0].is_finite() && p[1].is_finite()).then_some((p, [jx, jy]))
    }

    /// Ground point through pixel `(x, y)`'s centre (eq. (1)); None above the horizon.
    pub fn map_point(&self, x: u32, y: u32) -> Option<[f64; 2]> {
        self.map_point_and_jacobian(x as f64, y as f64).map(|(p, _)| p)
    }

    /// Texture coordinates and the analytic Jacobian (uv per pixel) at pixel
    /// `(x, y)` for a texture whose level 0 is `tex_w`×`tex_h`.
    pub fn uv(&self, tex_w: u32, tex_h: u32, x: u32, y: u32) -> Option<(Vec2, Jacobian)> {
        let (p, [jx, jy]) = self.map_point_and_jacobian(x as f64, y as f64)?;
        let (w, h) = (tex_w.max(1) as f64, tex_h.max(1) as f64);
        let uv = Vec2::new((p[0] / w) as f32, (p[1] / h) as f32);
        let jac = Jacobian::new(
            Vec2::new((jx[0] / w) as f32, (jx[1] / h) as f32),
            Vec2::new((jy[0] / w) as f32, (jy[1] / h) as f32),
        );
        Some((uv, jac))
    }
}

/// Colour of pixels above the horizon (sRGB).
pub const SKY: [u8; 4] = [178, 203, 237, 255];

#[inline]
fn encode(c: Vec4) -> [u8; 4] {
    [linear_to_srgb_u8(c.x), linear_to_srgb_u8(c.y), linear_to_srgb_u8(c.z), 255]
}

/// Renders `view` with the per-pixel trilinear sampler (eq. (1)–(4), level
/// from the analytic Jacobian by eq. (2)): the conventional design.
pub fn render_trilinear(pyr: &MipPyramid, view: &FlightView, wrap: Wrap) -> Frame {
    let (w, h) = (view.width, view.height);
    let opts = SamplerOptions { filter: Filter::Trilinear, wrap, level_rule: LevelRule::MaxPartial, lod_bias: 0.0 };
    let (tw, th) = (pyr.width(), pyr.height());
    let mut rgba = vec![0u8; w as usize * h as usize * 4];
    rgba.par_chunks_mut((w as usize * 4).max(1)).enumerate().for_each(|(y, row)| {
        for (x, px) in row.chunks_exact_mut(4).enumerate() {
            let c = match view.uv(tw, th, x as u32, y as u32) {
                Some((uv, jac)) => encode(sample(pyr, &opts, uv, jac)),
                None => SKY,
            };
            px.copy_from_slice(&c);
        }
    });
    Frame { width: w, height: h, rgba }
}

/// Renders `view` in 2×2 spans with [`sample_span`]; adds the bank traffic to
/// `banks`. Spans on the right or bottom edge of odd sizes have fewer pixels.
pub fn render_spans(pyr: &MipPyramid, view: &FlightView, opts: &SpanOptions, banks: &mut BankModel) -> Frame {
    let (w, h) = (view.width, view.height);
    let (tw, th) = (pyr.width(), pyr.height());
    let mut rgba = vec![0u8; w as usize * h as usize * 4];
    let logging = banks.log.is_some();
    let scheme = opts.scheme;
    let models: Vec<BankModel> = rgba
        .par_chunks_mut((w as usize * 8).max(1))
        .enumerate()
        .map(|(sy, rows)| {
            let mut m = if logging { BankModel::with_log(scheme) } else { BankModel::new(scheme) };
            let rows_here = rows.len() / (w as usize * 4).max(1);
            for sx in 0..w.div_ceil(2) {
                let mut uv = [Vec2::NAN; 4];
                for (i, &(dx, dy)) in SPAN_PIXELS.iter().enumerate() {
                    let (x, y) = (2 * sx + dx, 2 * sy as u32 + dy);
                    if let Some((p, _)) = (x < w && y < h).then(|| view.uv(tw, th, x, y)).flatten() {
                        uv[i] = p;
                    }
                }
                let c = sample_span(pyr, opts, uv, &mut m);
                for (i, &(dx, dy)) in SPAN_PIXELS.iter().enumerate() {
                    let x = (2 * sx + dx) as usize;
                    if x >= w as usize || dy as usize >= rows_here {
                        continue;
                    }
                    let o = (dy as usize * w as usize + x) * 4;
                    let px = if uv[i].is_finite() { encode(c[i]) } else { SKY };
                    rows[o..o + 4].copy_from_slice(&px);
                }
            }
            m
        })
        .collect();
    for m in models {
        banks.merge(m);
    }
    Frame { width: w, height: h, rgba }
}

/// Peak signal-to-noise ratio over RGB, dB (∞ for identical frames, NaN for
/// frames of different sizes): [`crate::metrics::psnr_rgb`].
pub fn psnr(a: &Frame, b: &Frame) -> f64 {
    if a.width != b.width || a.height != b.height {
        return f64::NAN;
    }
    crate::metrics::psnr_rgb(&a.rgba, &b.rgba)
}

/// Mean SSIM of the luma (1 for identical frames, NaN for frames of
/// different sizes): [`crate::metrics::ssim_luma`].
pub fn ssim(a: &Frame, b: &Frame) -> f64 {
    if a.width != b.width || a.height != b.height {
        return f64::NAN;
    }
    crate::metrics::ssim_luma(&a.rgba, &b.rgba, a.width, a.height)
}

/// A frame rendered both ways and compared.
#[derive(Debug, Clone)]
pub struct FrameComparison {
    /// Per-pixel trilinear (the conventional design).
    pub trilinear: Frame,
    /// Span-parallel mapping.
    pub span: Frame,
    /// Bank traffic of the span frame.
    pub banks: BankModel,
    /// [`psnr`] of the span frame against the trilinear one.
    pub psnr: f64,
    /// [`ssim`] of the span frame against the trilinear one.
    pub ssim: f64,
}

/// Renders `view` per pixel (trilinear) and in spans and compares them.
pub fn render_both(pyr: &MipPyramid, view: &FlightView, opts: &SpanOptions) -> FrameComparison {
    let trilinear = render_trilinear(pyr, view, opts.wrap);
    let mut banks = BankModel::new(opts.scheme);
    let span = render_spans(pyr, view, opts, &mut banks);
    let (p, s) = (psnr(&trilinear, &span), ssim(&trilinear, &span));
    FrameComparison { trilinear, span, banks, psnr: p, ssim: s }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::image::{ColorSpace, Image};
    use crate::texture::procedural::Pattern;
    use crate::texture::sampler::{bilinear, level_of_detail};

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
