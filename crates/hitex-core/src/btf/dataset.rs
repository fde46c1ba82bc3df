//! A measured or generated BTF: one small RGB image of `width`×`height`
//! texels per (view direction, light direction) of an [`AngularGrid`].
//!
//! This is the paper's *codebook*: 8×16 view × 8×16 light directions of
//! 32×32 texels are 16,384 images, 64 MiB at 4 bytes per texel. Texels are
//! sRGB-encoded 8-bit RGB, as photographs are; filtering happens in linear
//! light after decoding, as the GPU's sRGB formats do.
//!
//! A measured high-dynamic-range BTF (OpenEXR sets) also carries its linear
//! RGB as half floats ([`Hdr`]); the 8-bit texels are then its display copy,
//! the linear values scaled by [`Hdr::ldr_scale`] and sRGB-encoded, which
//! the 8-bit tools (index synthesis, BC1, PNG export) read.

use super::grid::AngularGrid;
use crate::CoreError;
use rayon::prelude::*;

/// Largest codebook accepted, in texels × directions² (1 Gi RGB texels, 3 GiB).
pub const MAX_BTF_TEXELS: u64 = 1 << 30;

/// Largest sample side in texels.
pub const MAX_BTF_SIDE: u32 = 1024;

/// A BTF codebook.
#[derive(Debug, Clone, PartialEq)]
pub struct Btf {
    grid: AngularGrid,
    width: u32,
    height: u32,
    /// RGB8, index `((view · D + light) · height + y) · width + x`.
    texels: Vec<u8>,
    /// Linear RGB as half floats, same order, when the BTF is HDR.
    hdr: Option<Hdr>,
}

/// The high-dynamic-range payload of a BTF: linear RGB (sRGB primaries) as
/// IEEE half floats, finite and non-negative.
#[derive(Debug, Clone, PartialEq)]
pub struct Hdr {
    /// Half-float bits, three per texel, in the order of [`Btf::texels`].
    pub half: Vec<u16>,
    /// The factor the 8-bit display copy was scaled by before encoding:
    /// 1 when the values lie in [0, 1] (up to their 99.9th percentile),
    /// else 1 / that percentile.
    pub ldr_scale: f32,
}

/// The half float nearest to `v` (round to nearest even) after clamping it
/// to [0, 65504], NaN to 0: the values an [`Hdr`] payload holds.
pub fn half_bits(v: f32) -> u16 {
    // NaN, negative values and −0 all become +0
    let v = if v > 0.0 { v.min(65504.0) } else { 0.0 };
    half::f16::from_f32(v).to_bits()
}

/// The value of half-float bits.
pub fn half_value(h: u16) -> f32 {
    half::f16::from_bits(h).to_f32()
}

/// The display scale of half-float linear values: 1 when their 99.9th
/// percentile is at most 1, else its reciprocal (a histogram of the half
/// exponents and top mantissa bits, so no sort of the whole payload).
fn display_scale(half: &[u16]) -> f32 {
    // buckets: the top 10 bits of a non-negative half (exponent + 5 mantissa bits)
    let hist = half
        .par_chunks(1 << 16)
        .fold(
            || vec![0u64; 1024],
            |mut h, c| {
                c.iter().for_each(|&v| h[((v & 0x7fff) >> 5) as usize] += 1);
                h
            },
        )
        .reduce(|| vec![0u64; 1024], |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect());
    let total: u64 = hist.iter().sum();
    let want = total - total / 1000;
    let mut seen = 0;
    for (b, &n) in hist.iter().enumerate() {
        seen += n;
        if seen >= want.max(1) {
            // the bucket's lower edge: the percentile to within 1/32 of an octave
            let p = half_value(((b << 5) as u16).min(0x7bff));
            return if p > 1.0 { 1.0 / p } else { 1.0 };
        }
    }
    1.0
}

/// The number of bytes a BTF of this shape holds, refused when above
/// [`MAX_BTF_TEXELS`] or with a side outside 1..=[`MAX_BTF_SIDE`]: callers check
/// declared sizes with it before allocating.
pub fn checked_size(grid: &AngularGrid, width: u32, height: u32) -> Result<usize, CoreError> {
    if width == 0 || height == 0 || width > MAX_BTF_SIDE || height > MAX_BTF_SIDE {
        return Err(CoreError::InvalidImage(format!(
            "BTF sample of {width}x{height} texels; each side must be in 1..={MAX_BTF_SIDE}"
        )));
    }
    let d = grid.directions() as u64;
    let n = d * d * width as u64 * height as u64;
    if n > MAX_BTF_TEXELS {
        return Err(CoreError::InvalidImage(format!(
            "BTF of {d}×{d} directions × {width}x{height} texels = {n} texels exceeds the limit of {MAX_BTF_TEXELS}"
        )));
    }
    Ok(n as usize * 3)
}

impl Btf {
    /// A BTF from its texels (RGB8, view-major, then light, rows, columns).
    pub fn new(grid: AngularGrid, width: u32, height: u32, texels: Vec<u8>) -> Result<Self, CoreError> {
        let want = checked_size(&grid, width, height)?;
        if texels.len() != want {
            return Err(CoreError::InvalidImage(format!(
                "BTF texel data of {} bytes; {width}x{height} texels × {}² directions need {want}",
                texels.len(),
                grid.directions()
            )));
        }
        Ok(Self { grid, width, height, texels, hdr: None })
    }

    /// An HDR BTF from linear RGB values (three per texel, in the order of
    /// [`Btf::texels`]): kept as half floats (values clamped to [0, 65504],
    /// NaN to 0), with the 8-bit display copy scaled into range by
    /// [`Hdr::ldr_scale`].
    pub fn from_linear(grid: AngularGrid, width: u32, height: u32, linear: &[f32]) -> Result<Self, CoreError> {
        let want = checked_size(&grid, width, height)?;
        if linear.len() != want {
            return Err(CoreError::InvalidImage(format!(
                "BTF linear data of {} values; {width}x{height} texels × {}² directions need {want}",
                linear.len(),
                grid.directions()
            )));
        }
        let half: Vec<u16> = linear.par_iter().map(|&v| half_bits(v)).collect();
        Self::from_half(grid, width, height, half)
    }

    /// An HDR BTF from half-float bits (three per texel): the display copy
    /// is derived as in [`Btf::from_linear`]. Infinite or NaN halves are
    /// clamped as there.
    pub fn from_half(grid: AngularGrid, width: u32, height: u32, mut half: Vec<u16>) -> Result<Self, CoreError> {
        let want = checked_size(&grid, width, height)?;
        if half.len() != want {
            return Err(CoreError::InvalidImage(format!(
                "BTF half-float data of {} values; {width}x{height} texels × {}² directions need {want}",
                half.len(),
                grid.directions()
            )));
        }
        half.par_iter_mut().for_each(|h| *h = half_bits(half_value(*h)));
        let ldr_scale = display_scale(&half);
        let texels = half.par_iter().map(|&h| crate::texture::linear_to_srgb_u8(half_value(h) * ldr_scale)).collect();
        Ok(Self { grid, width, height, texels, hdr: Some(Hdr { half, ldr_scale }) })
    }

    /// A BTF from stored parts: the 8-bit texels and, for an HDR BTF, its
    /// half floats (three per texel, finite and non-negative) and display
    /// scale, as a file holds them.
    pub fn from_parts(
        grid: AngularGrid,
        width: u32,
        height: u32,
        texels: Vec<u8>,
        hdr: Option<Hdr>,
    ) -> Result<Self, CoreError> {
        let mut btf = Self::new(grid, width, height, texels)?;
        if let Some(h) = &hdr {
            if h.half.len() != btf.texels.len() {
                return Err(CoreError::InvalidImage(format!(
                    "BTF half-float data of {} values; the 8-bit texels hold {}",
                    h.half.len(),
                    btf.texels.len()
                )));
            }
            if let Some(i) = h.half.iter().position(|&v| v & 0x8000 != 0 || v & 0x7c00 == 0x7c00) {
                return Err(CoreError::InvalidImage(format!(
                    "BTF half-float value {i} is {:#06x}: negative, infinite or NaN",
                    h.half[i]
                )));
            }
            if !(h.ldr_scale.is_finite() && h.ldr_scale > 0.0 && h.ldr_scale <= 1.0) {
                return Err(CoreError::InvalidImage(format!("HDR display scale {} is outside (0, 1]", h.ldr_scale)));
            }
        }
        btf.hdr = hdr;
        Ok(btf)
    }

    /// The HDR payload, when the BTF has one.
    pub fn hdr(&self) -> Option<&Hdr> {
        self.hdr.as_ref()
    }

    /// Whether the BTF carries linear half-float RGB.
    pub fn is_hdr(&self) -> bool {
        self.hdr.is_some()
    }

    /// The linear RGB of one texel: the half floats of an HDR BTF, else the
    /// 8-bit texel decoded from sRGB.
    pub fn texel_linear(&self, view: usize, light: usize, x: u32, y: u32) -> [f32; 3] {
        let i = self.texel_offset(view, light, x, y);
        match &self.hdr {
            Some(h) => [half_value(h.half[i]), half_value(h.half[i + 1]), half_value(h.half[i + 2])],
            None => {
                let d = |c: u8| crate::texture::srgb_to_linear(c as f32 / 255.0);
                [d(self.texels[i]), d(self.texels[i + 1]), d(self.texels[i + 2])]
            }
        }
    }

    /// The half-float bits of one texel of an HDR BTF.
    pub fn texel_half(&self, view: usize, light: usize, x: u32, y: u32) -> Option<[u16; 3]> {
        let i = self.texel_offset(view, light, x, y);
        self.hdr.as_ref().map(|h| [h.half[i], h.half[i + 1], h.half[i + 2]])
    }

    /// The half-float image for (view, light) of an HDR BTF (three per texel).
    pub fn image_half(&self, view: usize, light: usize) -> Option<&[u16]> {
        let n = self.image_bytes();
        let i = self.image_index(view, light) * n;
        self.hdr.as_ref().map(|h| &h.half[i..i + n])
    }

    fn texel_offset(&self, view: usize, light: usize, x: u32, y: u32) -> usize {
        self.image_index(view, light) * self.image_bytes() + (y as usize * self.width as usize + x as usize) * 3
    }

    /// A black BTF of this shape.
    pub fn zeroed(grid: AngularGrid, width: u32, height: u32) -> Result<Self, CoreError> {
        let n = checked_size(&grid, width, height)?;
        Ok(Self { grid, width, height, texels: vec![0; n], hdr: None })
    }

    /// The angular grid.
    pub fn grid(&self) -> &AngularGrid {
        &self.grid
    }

    /// Sample width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Sample height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Number of images (directions²).
    pub fn images(&self) -> usize {
        self.grid.directions() * self.grid.directions()
    }

    /// Bytes of one image (RGB8).
    pub fn image_bytes(&self) -> usize {
        self.width as usize * self.height as usize * 3
    }

    /// All texels, RGB8.
    pub fn texels(&self) -> &[u8] {
        &self.texels
    }

    /// All texels, mutable. Writing the 8-bit texels of an HDR BTF makes
    /// it an 8-bit BTF: the half floats are dropped.
    pub fn texels_mut(&mut self) -> &mut [u8] {
        self.hdr = None;
        &mut self.texels
    }

    /// Index of the image for (view direction, light direction).
    pub fn image_index(&self, view: usize, light: usize) -> usize {
        view * self.grid.directions() + light
    }

    /// The RGB8 image for (view direction, light direction).
    pub fn image(&self, view: usize, light: usize) -> &[u8] {
        let n = self.image_bytes();
        let i = self.image_index(view, light) * n;
        &self.texels[i..i + n]
    }

    /// The RGB8 image for (view direction, light direction), mutable. As
    /// with [`Btf::texels_mut`], an HDR BTF becomes an 8-bit one.
    pub fn image_mut(&mut self, view: usize, light: usize) -> &mut [u8] {
        self.hdr = None;
        let n = self.image_bytes();
        let i = self.image_index(view, light) * n;
        &mut self.texels[i..i + n]
    }

    /// One texel: (view, light) directions, (x, y) in the sample.
    pub fn texel(&self, view: usize, light: usize, x: u32, y: u32) -> [u8; 3] {
        let i =
            self.image_index(view, light) * self.image_bytes() + (y as usize * self.width as usize + x as usize) * 3;
        [self.texels[i], self.texels[i + 1], self.texels[i + 2]]
    }

    /// Size of the codebook on a GPU at 4 bytes per texel.
    pub fn gpu_bytes(&self) -> u64 {
        self.images() as u64 * self.width as u64 * self.height as u64 * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_codebook_is_64_mib() {
        let b = Btf::zeroed(AngularGrid::paper(), 32, 32).unwrap();
        assert_eq!(b.images(), 16_384);
        assert_eq!(b.gpu_bytes(), 64 << 20);
    }

    #[test]
    fn sizes_are_checked_before_allocating() {
        let g = AngularGrid::paper();
        assert!(checked_size(&g, 0, 32).is_err());
        assert!(checked_size(&g, 1024, 1024).is_err());
        assert!(Btf::new(g, 2, 2, vec![0; 7]).is_err());
    }
}
