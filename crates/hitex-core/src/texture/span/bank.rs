//! The interleaved banks: which bank and address a texel has (eq. (10)),
//! the traffic and conflicts of span accesses, and the memory of the two
//! designs.

use super::{SpanAccess, SpanScheme};
use crate::texture::pyramid::MipPyramid;

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
    pub(super) log: Option<Vec<SpanAccess>>,
    scratch: Vec<(u8, u8, i64, i64)>,
    pub(super) texels: Vec<[i64; 2]>,
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
