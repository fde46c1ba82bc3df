//! The level rule of a span (eq. (9) for B×B banks, see the module above):
//! the span's points in one wrap period, and the level at which their
//! footprint fits one mspan.

use super::{SpanLevel, SpanOptions};
use crate::texture::pyramid::MipPyramid;
use crate::texture::sampler::Wrap;
use glam::Vec2;

/// The span's points brought into one wrap period together, in f64 uv.
pub(super) struct SpanPoints {
    pub(super) uv: [Option<[f64; 2]>; 4],
}

impl SpanPoints {
    pub(super) fn new(uv: [Vec2; 4], wrap: Wrap) -> Self {
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
    pub(super) fn any(&self) -> bool {
        self.uv.iter().any(Option::is_some)
    }
    /// Per-axis (min, max) of the valid uv.
    pub(super) fn bounds(&self) -> [(f64, f64); 2] {
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
pub(super) fn level_size(pyr: &MipPyramid, k: usize) -> [f64; 2] {
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
pub(super) fn texel_pos(uv: [f64; 2], size: [f64; 2]) -> [f64; 2] {
    [uv[0] * size[0] - 0.5, uv[1] * size[1] - 0.5]
}

/// Largest level the rule may pick beyond the pyramid's last.
const VIRTUAL_LEVELS: usize = 192;

pub(super) fn choose_level(pyr: &MipPyramid, opts: &SpanOptions, pts: &SpanPoints) -> SpanLevel {
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

/// The level [`sample_span`](super::sample_span) would use for these four points (None if no
/// point is finite).
pub fn span_level(pyr: &MipPyramid, opts: &SpanOptions, uv: [Vec2; 4]) -> Option<SpanLevel> {
    let pts = SpanPoints::new(uv, opts.wrap);
    pts.any().then(|| choose_level(pyr, opts, &pts))
}
