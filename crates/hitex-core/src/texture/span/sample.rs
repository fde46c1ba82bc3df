//! Sampling a span from the banks: the bilinear or mspan-restricted
//! Catmull-Rom taps of each pixel at the chosen levels, the bank traffic
//! recorded, both levels blended (eq. (4)).

use super::level::{SpanPoints, choose_level, level_size, texel_pos};
use super::{BankModel, SpanFilter, SpanOptions};
use crate::texture::pyramid::MipPyramid;
use crate::texture::sampler::Wrap;
use glam::{Vec2, Vec4};

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

/// Samples the four pixels of a span (order [`SPAN_PIXELS`](super::SPAN_PIXELS)) at `uv` in one
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
