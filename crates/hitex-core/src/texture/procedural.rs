//! Procedural images: the embedded textures of the default scene, so that
//! hitex renders its showcase without any file.

use super::image::{ColorSpace, Image};
use crate::CoreError;

/// The procedural patterns available by name in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Two-colour checkerboard of 8×8 squares: the classic aliasing test.
    Checker,
    /// A colour ramp in u and v with grid lines every 1/16: shows orientation,
    /// stretching and the MIP level (the lines fade as levels coarsen).
    UvGrid,
    /// Running-bond bricks with mortar joints and per-brick tint.
    Bricks,
}

impl Pattern {
    /// Every pattern, for listings.
    pub const ALL: [Pattern; 3] = [Pattern::Checker, Pattern::UvGrid, Pattern::Bricks];

    /// Name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Pattern::Checker => "checker",
            Pattern::UvGrid => "uv-grid",
            Pattern::Bricks => "bricks",
        }
    }

    /// Looks a pattern up by its scene-file name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Renders the pattern into a `size`×`size` sRGB image.
    pub fn render(self, size: u32) -> Result<Image, CoreError> {
        let s = size as f32;
        match self {
            Pattern::Checker => Image::from_fn(size, size, ColorSpace::Srgb, |x, y| {
                let cell = (size / 8).max(1);
                if ((x / cell) + (y / cell)).is_multiple_of(2) { [235, 235, 225, 255] } else { [40, 45, 60, 255] }
            }),
            Pattern::UvGrid => Image::from_fn(size, size, ColorSpace::Srgb, |x, y| {
                let (u, v) = ((x as f32 + 0.5) / s, (y as f32 + 0.5) / s);
                let line = (size / 16).max(1);
                let width = (size / 128).max(1);
                if x % line < width || y % line < width {
                    return [20, 20, 20, 255];
                }
                let r = (60.0 + 190.0 * u) as u8;
                let g = (60.0 + 190.0 * v) as u8;
                let b = (220.0 - 160.0 * (u * v)) as u8;
                [r, g, b, 255]
            }),
            Pattern::Bricks => Image::from_fn(size, size, ColorSpace::Srgb, |x, y| {
                let rows = 8u32;
                let bh = (size / rows).max(1);
                let bw = (2 * bh).max(1);
                let row = y / bh;
                let shift = if row % 2 == 1 { bw / 2 } else { 0 };
                let col = (x + shift) / bw;
                let (bx, by) = ((x + shift) % bw, y % bh);
                let mortar = (bh / 8).max(1);
                if bx < mortar || by < mortar {
                    return [200, 196, 186, 255];
                }
                // per-brick tint from a small integer hash
                let h = (row.wrapping_mul(73_856_093) ^ col.wrapping_mul(19_349_663)) % 64;
                let n = ((x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)) >> 7) % 16;
                let t = h as i32 - 32 + n as i32 - 8;
                let c = |base: i32| (base + t).clamp(0, 255) as u8;
                [c(160), c(70), c(52), 255]
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_patterns_tile() {
        for p in Pattern::ALL {
            assert_eq!(Pattern::from_name(p.name()), Some(p));
            let img = p.render(64).unwrap();
            assert_eq!((img.width(), img.height()), (64, 64));
        }
        assert_eq!(Pattern::from_name("nope"), None);
        // the checker has 8 cells per side
        let c = Pattern::Checker.render(64).unwrap();
        assert_ne!(c.texel(7, 0), c.texel(8, 0));
        assert_eq!(c.texel(0, 0), c.texel(16, 0));
    }
}
