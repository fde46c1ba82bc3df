//! Tone maps: linear radiance (after exposure) to the displayable [0, 1]
//! range, per channel, before the sRGB encoding. The same formulas run in
//! the WGSL programs (`tone_map` in `shaders/btf.wgsl`).
//!
//! * [`ToneMap::None`]: the value itself; the encoder clamps at 1 (what an
//!   8-bit BTF has always been rendered with);
//! * [`ToneMap::Reinhard`]: `x / (1 + x)` (Reinhard et al. 2002, eq. 3),
//!   which never clips and maps 1 to ½;
//! * [`ToneMap::Aces`]: Narkowicz's 2015 fit of the ACES reference rendering
//!   transform, `x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)` clamped to
//!   [0, 1]: a film-like shoulder that reaches 1 at x ≈ 7.24.
//!
//! Inputs are clamped to [0, 10⁴] first (the maps are flat there), so that
//! no product overflows at extreme exposures.

/// A tone map, per channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToneMap {
    /// No mapping: clamp at 1.
    #[default]
    None,
    /// `x / (1 + x)`.
    Reinhard,
    /// Narkowicz's ACES fit.
    Aces,
}

impl ToneMap {
    /// Every tone map.
    pub const ALL: [ToneMap; 3] = [ToneMap::None, ToneMap::Reinhard, ToneMap::Aces];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ToneMap::None => "none",
            ToneMap::Reinhard => "reinhard",
            ToneMap::Aces => "aces",
        }
    }

    /// The code the shaders receive (0, 1, 2).
    pub fn code(self) -> u32 {
        match self {
            ToneMap::None => 0,
            ToneMap::Reinhard => 1,
            ToneMap::Aces => 2,
        }
    }

    /// The map of one channel value (NaN and negative values give 0).
    #[inline(always)]
    pub fn apply(self, x: f32) -> f32 {
        let x = if x > 0.0 { x.min(1.0e4) } else { 0.0 };
        match self {
            ToneMap::None => x,
            ToneMap::Reinhard => x / (1.0 + x),
            ToneMap::Aces => ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_maps_by_hand() {
        assert_eq!(ToneMap::None.apply(2.5), 2.5);
        assert_eq!(ToneMap::Reinhard.apply(1.0), 0.5);
        assert_eq!(ToneMap::Reinhard.apply(3.0), 0.75);
        // ACES fit at 1: 2.54 / 3.16
        assert!((ToneMap::Aces.apply(1.0) - 2.54 / 3.16).abs() < 1e-6);
        assert_eq!(ToneMap::Aces.apply(100.0), 1.0);
        // no overflow to NaN at extreme exposures
        for t in ToneMap::ALL {
            assert!(t.apply(1.0e30).is_finite() && t.apply(f32::INFINITY).is_finite());
        }
        for t in ToneMap::ALL {
            assert_eq!(t.apply(0.0), 0.0);
            assert_eq!(t.apply(-1.0), 0.0);
            assert_eq!(t.apply(f32::NAN), 0.0);
            // monotonic
            let mut last = 0.0;
            for i in 0..2000 {
                let y = t.apply(i as f32 * 0.01);
                assert!(y >= last, "{t:?} at {i}");
                last = y;
            }
        }
    }
}
