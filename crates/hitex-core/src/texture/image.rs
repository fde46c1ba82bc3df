//! RGBA8 images and the sRGB transfer function.

use crate::CoreError;
use std::sync::LazyLock;

/// How the 8-bit channels of an [`Image`] are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColorSpace {
    /// Colour channels are sRGB-encoded (alpha is linear); filtering happens
    /// after decoding to linear light. The usual case for photographs.
    #[default]
    Srgb,
    /// Channels are linear data (masks, normal maps, index maps).
    Linear,
}

/// An RGBA image with 8 bits per channel, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    width: u32,
    height: u32,
    color_space: ColorSpace,
    data: Vec<[u8; 4]>,
}

/// Largest accepted side of an image, in texels (the limit of common GPUs).
pub const MAX_IMAGE_SIDE: u32 = 16384;

impl Image {
    /// Wraps texel data; fails if the sizes are zero, too large, or do not
    /// match the data length.
    pub fn new(width: u32, height: u32, color_space: ColorSpace, data: Vec<[u8; 4]>) -> Result<Self, CoreError> {
        check_size(width, height)?;
        let expected = width as usize * height as usize;
        if data.len() != expected {
            return Err(CoreError::InvalidImage(format!(
                "{width}x{height} image needs {expected} texels, got {}",
                data.len()
            )));
        }
        Ok(Self { width, height, color_space, data })
    }

    /// An image filled with one texel value.
    pub fn filled(width: u32, height: u32, color_space: ColorSpace, texel: [u8; 4]) -> Result<Self, CoreError> {
        check_size(width, height)?;
        Ok(Self { width, height, color_space, data: vec![texel; width as usize * height as usize] })
    }

    /// Builds an image by evaluating `f(x, y)` for every texel.
    pub fn from_fn(
        width: u32,
        height: u32,
        color_space: ColorSpace,
        mut f: impl FnMut(u32, u32) -> [u8; 4],
    ) -> Result<Self, CoreError> {
        check_size(width, height)?;
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Ok(Self { width, height, color_space, data })
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Encoding of the colour channels.
    pub fn color_space(&self) -> ColorSpace {
        self.color_space
    }
    /// Texels, row-major, top row first.
    pub fn texels(&self) -> &[[u8; 4]] {
        &self.data
    }
    /// Texels as bytes (RGBA RGBA ...).
    pub fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.data)
    }
    /// Texel at (x, y); `x < width`, `y < height`.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> [u8; 4] {
        self.data[y as usize * self.width as usize + x as usize]
    }
    /// Texel decoded to linear light (colour through the sRGB curve when the
    /// image is sRGB, alpha always linear).
    #[inline]
    pub fn texel_linear(&self, x: u32, y: u32) -> [f32; 4] {
        let t = self.texel(x, y);
        decode(t, self.color_space)
    }
    /// Consumes the image and returns its texels.
    pub fn into_texels(self) -> Vec<[u8; 4]> {
        self.data
    }
}

static LINEAR_LUT: LazyLock<[f32; 256]> = LazyLock::new(|| std::array::from_fn(|i| i as f32 / 255.0));

/// The table that decodes an 8-bit colour channel of `cs` to linear light.
#[inline]
pub fn decode_table(cs: ColorSpace) -> &'static [f32; 256] {
    match cs {
        ColorSpace::Srgb => &SRGB_LUT,
        ColorSpace::Linear => &LINEAR_LUT,
    }
}

/// Decodes one texel to linear floats.
#[inline]
pub fn decode(t: [u8; 4], cs: ColorSpace) -> [f32; 4] {
    match cs {
        ColorSpace::Srgb => {
            let lut = &*SRGB_LUT;
            [lut[t[0] as usize], lut[t[1] as usize], lut[t[2] as usize], t[3] as f32 / 255.0]
        }
        ColorSpace::Linear => [t[0] as f32 / 255.0, t[1] as f32 / 255.0, t[2] as f32 / 255.0, t[3] as f32 / 255.0],
    }
}

fn check_size(width: u32, height: u32) -> Result<(), CoreError> {
    if width == 0 || height == 0 {
        return Err(CoreError::InvalidImage(format!("image size {width}x{height} has a zero side")));
    }
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(CoreError::InvalidImage(format!(
            "image size {width}x{height} exceeds the limit of {MAX_IMAGE_SIDE} texels per side"
        )));
    }
    Ok(())
}

/// sRGB electro-optical transfer: encoded value in [0, 1] to linear light.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Inverse of [`srgb_to_linear`]; input clamped to [0, 1].
#[inline]
pub fn linear_to_srgb(l: f32) -> f32 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    if l <= 0.0031308 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

/// Linear light to an 8-bit sRGB code: `round(255 · linear_to_srgb(l))`,
/// computed without `powf`: the value's cell among 4096 equal cells of
/// [0, 1] holds the code at the cell's low edge and the one decision
/// threshold inside the cell (if any), so the code is the cell's plus one
/// comparison: the correctly rounded code. One threshold per cell at most:
/// the curve rises at most 0.8 codes across a cell (its steepest part,
/// 12.92·255/4095); a test checks every threshold and cell edge. Two
/// independent table reads, no loop and no branch, so lane code vectorises it.
#[inline]
pub fn linear_to_srgb_u8(l: f32) -> u8 {
    SRGB_ENCODE.encode(l)
}

/// The tables of [`linear_to_srgb_u8`], for lane loops: fetch them once
/// ([`srgb_encoder`]) and call [`SrgbEncoder::encode`] per lane, so that the
/// loop holds no lazy-initialisation check and no bounds check.
pub struct SrgbEncoder {
    /// `threshold[c]`: smallest linear value that encodes to code `c` or
    /// more (the tables' source, kept for the tests).
    #[cfg(test)]
    threshold: [f32; 256],
    /// `base[i]`: the code of the smallest value in cell `i`, as a 32-bit
    /// word so that lane loops read the table with vector gathers (bytes
    /// were read lane by lane, a load and an insert each).
    base: [u32; ENCODE_CELLS],
    /// `step[i]`: the threshold of code `base[i] + 1` where it lies in cell
    /// `i`, else +∞.
    step: [f32; ENCODE_CELLS],
}

impl SrgbEncoder {
    /// The cell of a value in [0, 1].
    #[inline(always)]
    fn cell(l: f32) -> usize {
        // (a saturating `as usize` would run lane by lane in lane loops)
        (super::sampler::to_u32_clamped(l * (ENCODE_CELLS - 1) as f32) as usize).min(ENCODE_CELLS - 1)
    }

    /// [`linear_to_srgb_u8`].
    #[inline(always)]
    pub fn encode(&self, l: f32) -> u8 {
        self.code(l) as u8
    }

    /// [`linear_to_srgb_u8`] as a 32-bit word (0..=255), for lane loops
    /// that put the codes of a pixel together in one word.
    #[inline(always)]
    pub fn code(&self, l: f32) -> u32 {
        // NaN → 0 (max returns the other operand), then [0, 1]
        #[allow(clippy::manual_clamp)] // clamp would keep NaN
        let l = l.max(0.0).min(1.0);
        let i = Self::cell(l);
        self.base[i] + (l >= self.step[i]) as u32
    }
}

/// The encoder's tables (built on first use).
pub fn srgb_encoder() -> &'static SrgbEncoder {
    &SRGB_ENCODE
}

/// Reference encoder with `powf`, for tests and tables.
pub fn linear_to_srgb_u8_exact(l: f32) -> u8 {
    (linear_to_srgb(l) * 255.0 + 0.5) as u8
}

const ENCODE_CELLS: usize = 4096;

static SRGB_ENCODE: LazyLock<SrgbEncoder> = LazyLock::new(|| {
    let mut threshold = [0.0f32; 256];
    for (c, th) in threshold.iter_mut().enumerate().skip(1) {
        // bisect the exact encoder's decision point between c − 1 and c
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..64 {
            let mid = 0.5 * (lo + hi);
            if linear_to_srgb_u8_exact(mid) as usize >= c { hi = mid } else { lo = mid }
        }
        *th = hi;
    }
    // the smallest value of each cell: a bisection over the bit patterns of
    // [0, 1], on which the cell index is monotone
    let low_edge = |i: usize| -> f32 {
        let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if SrgbEncoder::cell(f32::from_bits(mid)) >= i { hi = mid } else { lo = mid + 1 }
        }
        f32::from_bits(lo)
    };
    let code = |l: f32| threshold[1..].iter().filter(|&&t| l >= t).count();
    let mut base = [0u32; ENCODE_CELLS];
    let mut step = [f32::INFINITY; ENCODE_CELLS];
    let mut next = low_edge(0);
    for i in 0..ENCODE_CELLS {
        let (lo, hi) = (next, if i + 1 < ENCODE_CELLS { low_edge(i + 1) } else { f32::INFINITY });
        let c = code(lo);
        base[i] = c as u32;
        if c < 255 && threshold[c + 1] < hi {
            step[i] = threshold[c + 1];
        }
        next = hi;
    }
    SrgbEncoder {
        #[cfg(test)]
        threshold,
        base,
        step,
    }
});

static SRGB_LUT: LazyLock<[f32; 256]> = LazyLock::new(|| {
    let mut t = [0.0f32; 256];
    for (i, v) in t.iter_mut().enumerate() {
        *v = srgb_to_linear(i as f32 / 255.0);
    }
    t
});

/// 8-bit sRGB code to linear light (table lookup).
#[inline]
pub fn srgb_u8_to_linear(c: u8) -> f32 {
    SRGB_LUT[c as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_is_exact_for_every_code() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb_u8(srgb_u8_to_linear(c)), c);
        }
    }

    #[test]
    fn size_mismatch_is_an_error() {
        assert!(Image::new(2, 2, ColorSpace::Srgb, vec![[0; 4]; 3]).is_err());
        assert!(Image::new(0, 2, ColorSpace::Srgb, vec![]).is_err());
        assert!(Image::filled(MAX_IMAGE_SIDE + 1, 1, ColorSpace::Srgb, [0; 4]).is_err());
    }

    #[test]
    fn fast_encoder_equals_the_powf_encoder() {
        let mut l = 0.0f32;
        while l <= 1.0 {
            assert_eq!(linear_to_srgb_u8(l), linear_to_srgb_u8_exact(l), "at {l}");
            l += 1.0 / 65536.0;
        }
        for c in 0..=255u8 {
            let x = srgb_u8_to_linear(c);
            for v in [x, f32::from_bits(x.to_bits().wrapping_sub(1)), f32::from_bits(x.to_bits() + 1)] {
                assert_eq!(linear_to_srgb_u8(v), linear_to_srgb_u8_exact(v), "at {v}");
            }
        }
    }

    #[test]
    fn nan_encodes_to_black() {
        assert_eq!(linear_to_srgb_u8(f32::NAN), 0);
        assert_eq!(linear_to_srgb_u8(7.0), 255);
    }

    /// The cell encoder equals a full count of the thresholds at every
    /// decision threshold and cell edge (±4 ulps) and on a dense sweep, and
    /// no cell holds two thresholds.
    #[test]
    fn one_threshold_per_cell_is_enough() {
        let t = &*SRGB_ENCODE;
        let count = |l: f32| -> u8 {
            let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
            t.threshold[1..].iter().filter(|&&th| l >= th).count() as u8
        };
        for c in 1..255 {
            assert_ne!(SrgbEncoder::cell(t.threshold[c]), SrgbEncoder::cell(t.threshold[c + 1]), "code {c}");
        }
        let near = |x: f32| (-4i32..=4).map(move |k| f32::from_bits((x.to_bits() as i32 + k).max(0) as u32));
        let mut points: Vec<f32> = Vec::new();
        for th in t.threshold {
            points.extend(near(th));
        }
        for i in 0..ENCODE_CELLS {
            points.extend(near(i as f32 / (ENCODE_CELLS - 1) as f32));
        }
        points.extend((0..=2_000_000).map(|i| i as f32 / 2_000_000.0));
        points.extend([f32::NAN, -1.0, 2.0, f32::INFINITY, f32::NEG_INFINITY, 1.0]);
        for l in points {
            assert_eq!(linear_to_srgb_u8(l), count(l), "at {l:e}");
        }
    }
}
