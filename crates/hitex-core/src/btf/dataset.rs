//! A measured or generated BTF: one small RGB image of `width`×`height`
//! texels per (view direction, light direction) of an [`AngularGrid`].
//!
//! This is the paper's *codebook*: 8×16 view × 8×16 light directions of
//! 32×32 texels are 16,384 images, 64 MiB at 4 bytes per texel. Texels are
//! sRGB-encoded 8-bit RGB, as photographs are; filtering happens in linear
//! light after decoding, as the GPU's sRGB formats do.

use super::grid::AngularGrid;
use crate::CoreError;

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
        Ok(Self { grid, width, height, texels })
    }

    /// A black BTF of this shape.
    pub fn zeroed(grid: AngularGrid, width: u32, height: u32) -> Result<Self, CoreError> {
        let n = checked_size(&grid, width, height)?;
        Ok(Self { grid, width, height, texels: vec![0; n] })
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

    /// All texels, mutable.
    pub fn texels_mut(&mut self) -> &mut [u8] {
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

    /// The RGB8 image for (view direction, light direction), mutable.
    pub fn image_mut(&mut self, view: usize, light: usize) -> &mut [u8] {
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
