//! The rendered frame every renderer returns: RGBA8, sRGB-encoded, rows top
//! to bottom (the CPU and GPU backends, the span samplers' reference
//! renderers), with the linear-light resolve of a supersampled render.

/// A rendered image: RGBA8, sRGB-encoded, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 4` bytes.
    pub rgba: Vec<u8>,
}

impl Frame {
    /// The frame reduced `k` times on each side by a box filter in linear
    /// light (the resolve of a `k`×`k` supersampled render); a side that is
    /// not a multiple of `k` drops its last partial block. Alpha is averaged.
    pub fn downsample(&self, k: u32) -> Frame {
        let k = k.max(1);
        let (w, h) = (self.width / k, self.height / k);
        let lin: Vec<f32> = (0..=255u8).map(|b| crate::texture::srgb_to_linear(b as f32 / 255.0)).collect();
        let mut rgba = vec![0u8; (w as usize) * (h as usize) * 4];
        let n = (k * k) as f32;
        for y in 0..h {
            for x in 0..w {
                let mut s = [0.0f32; 4];
                for dy in 0..k {
                    for dx in 0..k {
                        let i = (((y * k + dy) * self.width + x * k + dx) * 4) as usize;
                        for c in 0..3 {
                            s[c] += lin[self.rgba[i + c] as usize];
                        }
                        s[3] += self.rgba[i + 3] as f32;
                    }
                }
                let o = ((y * w + x) * 4) as usize;
                for c in 0..3 {
                    rgba[o + c] = crate::texture::linear_to_srgb_u8(s[c] / n);
                }
                rgba[o + 3] = (s[3] / n).round() as u8;
            }
        }
        Frame { width: w, height: h, rgba }
    }
}
