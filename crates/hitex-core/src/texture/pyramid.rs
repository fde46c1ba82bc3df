//! MIP pyramids built in linear light.
//!
//! Level `k+1` has sides `max(1, floor(n/2))` of level `k` (the rule GPUs use),
//! so the pyramid uploads unchanged as a GPU texture's mip chain. Each texel of
//! the smaller level is the exact-area box average of the texels it covers,
//! computed in linear light with premultiplied alpha, and re-encoded in the
//! image's colour space. For power-of-two sides this is the classic 2×2 box;
//! for odd sides the footprint (1.5 texels wide, say) is weighted by overlap,
//! so no texel is dropped and the mean brightness is kept.

use super::image::{ColorSpace, Image, decode, linear_to_srgb_u8};
use glam::Vec4;
use rayon::prelude::*;
use std::sync::OnceLock;

/// A chain of images, level 0 the finest.
#[derive(Debug, Clone)]
pub struct MipPyramid {
    levels: Vec<Image>,
    /// Every level decoded to linear RGBA, built on first use (by the span
    /// samplers' emulation): the values the GPU's sRGB decode yields for each
    /// texel. The trilinear sampler reads the RGBA8 texels through a decode
    /// table instead, which measured faster (a quarter of the memory).
    linear: OnceLock<Vec<Vec<Vec4>>>,
}

impl PartialEq for MipPyramid {
    fn eq(&self, other: &Self) -> bool {
        self.levels == other.levels
    }
}

impl MipPyramid {
    /// Builds the full chain down to 1×1.
    pub fn build(base: Image) -> Self {
        let mut levels = vec![base];
        loop {
            let last = &levels[levels.len() - 1];
            if last.width() == 1 && last.height() == 1 {
                break;
            }
            let next = downsample(last);
            levels.push(next);
        }
        Self { levels, linear: OnceLock::new() }
    }

    /// A pyramid of one level (no MIP mapping).
    pub fn single(base: Image) -> Self {
        Self { levels: vec![base], linear: OnceLock::new() }
    }

    /// Level `l` decoded to linear RGBA (colour through the sRGB curve for sRGB
    /// images), row-major; decoded once, on first use.
    pub fn linear_level(&self, l: usize) -> &[Vec4] {
        let all = self.linear.get_or_init(|| {
            self.levels
                .iter()
                .map(|img| {
                    let cs = img.color_space();
                    img.texels().par_iter().map(|t| Vec4::from_array(decode(*t, cs))).collect()
                })
                .collect()
        });
        &all[l]
    }

    /// Number of levels (≥ 1).
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }
    /// Level `l` (0 = finest); `l < level_count()`.
    pub fn level(&self, l: usize) -> &Image {
        &self.levels[l]
    }
    /// All levels, finest first.
    pub fn levels(&self) -> &[Image] {
        &self.levels
    }
    /// Width of level 0.
    pub fn width(&self) -> u32 {
        self.levels[0].width()
    }
    /// Height of level 0.
    pub fn height(&self) -> u32 {
        self.levels[0].height()
    }
    /// Colour space of every level.
    pub fn color_space(&self) -> ColorSpace {
        self.levels[0].color_space()
    }
    /// Total texels over all levels.
    pub fn texel_count(&self) -> usize {
        self.levels.iter().map(|l| l.texels().len()).sum()
    }
}

/// Overlap weights of a `src`-long axis reduced to `dst` texels:
/// for each destination texel, the source range and weights summing to 1.
fn axis_weights(src: u32, dst: u32) -> Vec<(u32, Vec<f32>)> {
    let scale = src as f64 / dst as f64;
    (0..dst)
        .map(|i| {
            let a = i as f64 * scale;
            let b = (i + 1) as f64 * scale;
            let first = a.floor() as u32;
            let last = ((b.ceil() as u32).min(src)).max(first + 1);
            let w: Vec<f32> = (first..last)
                .map(|s| {
                    let lo = (s as f64).max(a);
                    let hi = ((s + 1) as f64).min(b);
                    ((hi - lo).max(0.0) / scale) as f32
                })
                .collect();
            (first, w)
        })
        .collect()
}

fn downsample(src: &Image) -> Image {
    let (sw, sh) = (src.width(), src.height());
    let (dw, dh) = ((sw / 2).max(1), (sh / 2).max(1));
    let cs = src.color_space();
    let wx = axis_weights(sw, dw);
    let wy = axis_weights(sh, dh);
    let data: Vec<[u8; 4]> = (0..dh)
        .into_par_iter()
        .flat_map_iter(|y| {
            let (y0, wys) = &wy[y as usize];
            let wx = &wx;
            (0..dw).map(move |x| {
                let (x0, wxs) = &wx[x as usize];
                // premultiplied linear accumulation
                let mut acc = [0.0f32; 4];
                for (j, wyj) in wys.iter().enumerate() {
                    for (i, wxi) in wxs.iter().enumerate() {
                        let t = decode(src.texel(x0 + i as u32, y0 + j as u32), cs);
                        let w = wxi * wyj;
                        acc[0] += t[0] * t[3] * w;
                        acc[1] += t[1] * t[3] * w;
                        acc[2] += t[2] * t[3] * w;
                        acc[3] += t[3] * w;
                    }
                }
                encode_premultiplied(acc, cs)
            })
        })
        .collect();
    match Image::new(dw, dh, cs, data) {
        Ok(img) => img,
        // sizes are derived from a valid image: dw*dh texels were produced
        Err(_) => unreachable!("downsample produced a consistent image"),
    }
}

fn encode_premultiplied(acc: [f32; 4], cs: ColorSpace) -> [u8; 4] {
    let a = acc[3];
    let c = if a > 0.0 { [acc[0] / a, acc[1] / a, acc[2] / a] } else { [0.0; 3] };
    let enc = |v: f32| match cs {
        ColorSpace::Srgb => linear_to_srgb_u8(v),
        ColorSpace::Linear => (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
    };
    [enc(c[0]), enc(c[1]), enc(c[2]), (a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn chain_sizes_follow_gpu_rule() {
        let p = MipPyramid::build(Image::filled(10, 3, ColorSpace::Srgb, [1, 2, 3, 255]).unwrap());
        let sizes: Vec<(u32, u32)> = p.levels().iter().map(|l| (l.width(), l.height())).collect();
        assert_eq!(sizes, vec![(10, 3), (5, 1), (2, 1), (1, 1)]);
    }

    #[test]
    fn two_by_two_box_in_linear_light() {
        // black and white average to linear 0.5, which is sRGB code 188, not 128
        let img = Image::new(2, 1, ColorSpace::Srgb, vec![[0, 0, 0, 255], [255, 255, 255, 255]]).unwrap();
        let p = MipPyramid::build(img);
        assert_eq!(p.level(1).texel(0, 0), [188, 188, 188, 255]);
        // in a linear image it is the arithmetic mean
        let img = Image::new(2, 1, ColorSpace::Linear, vec![[0, 0, 0, 255], [255, 255, 255, 255]]).unwrap();
        assert_eq!(MipPyramid::build(img).level(1).texel(0, 0), [128, 128, 128, 255]);
    }

    #[test]
    fn odd_side_uses_area_weights() {
        // 3 texels -> 1: each contributes 1/3
        let img = Image::new(3, 1, ColorSpace::Linear, vec![[0, 0, 0, 255], [255, 0, 0, 255], [0, 0, 0, 255]]).unwrap();
        let p = MipPyramid::build(img);
        assert_eq!(p.level(1).texel(0, 0), [85, 0, 0, 255]);
    }

    #[test]
    fn transparent_texels_do_not_darken() {
        let img = Image::new(2, 1, ColorSpace::Srgb, vec![[255, 0, 0, 255], [0, 0, 0, 0]]).unwrap();
        let p = MipPyramid::build(img);
        assert_eq!(p.level(1).texel(0, 0), [255, 0, 0, 128]);
    }

    #[test]
    fn axis_weights_sum_to_one() {
        for (s, d) in [(7u32, 3u32), (5, 2), (16, 8), (1, 1), (3, 1)] {
            for (_, w) in axis_weights(s, d) {
                let sum: f32 = w.iter().sum();
                assert!((sum - 1.0).abs() < 1e-6, "{s}->{d}: {sum}");
            }
        }
    }

    proptest! {
        #[test]
        fn constant_image_stays_constant_at_every_level(
            w in 1u32..40, h in 1u32..40, r: u8, g: u8, b: u8, srgb: bool,
        ) {
            let cs = if srgb { ColorSpace::Srgb } else { ColorSpace::Linear };
            let p = MipPyramid::build(Image::filled(w, h, cs, [r, g, b, 255]).unwrap());
            for l in p.levels() {
                for t in l.texels() {
                    prop_assert_eq!(*t, [r, g, b, 255]);
                }
            }
        }
    }
}
