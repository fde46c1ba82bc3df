//! BC1 (DXT1) block compression: 4×4 texels in 8 bytes, two RGB565 end
//! points and 2-bit indices, 8:1 against RGBA8.
//!
//! Encoding wraps well-kept crates; two are offered and compared by
//! `hitex bench btf` ([`Bc1Encoder`]): Intel's ISPC kernels (`intel_tex_2`,
//! fast, no quality knob) and `texpresso` (pure Rust; range fit, or the
//! slower cluster fit). Our own code is the decoder — the CPU twin reads
//! decoded texels where the GPU samples the blocks — and the error measure.

use crate::CoreError;
use rayon::prelude::*;

/// A BC1 encoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bc1Encoder {
    /// Intel ISPC texture compressor (`intel_tex_2`): the default.
    Ispc,
    /// `texpresso` range fit with uniform channel weights.
    TexpressoRange,
    /// `texpresso` cluster fit with uniform channel weights (slow, best).
    TexpressoCluster,
}

impl Bc1Encoder {
    /// Name for reports and the command line.
    pub fn name(self) -> &'static str {
        match self {
            Bc1Encoder::Ispc => "ispc",
            Bc1Encoder::TexpressoRange => "texpresso-range",
            Bc1Encoder::TexpressoCluster => "texpresso-cluster",
        }
    }

    /// Parses a name (see [`Bc1Encoder::name`]).
    pub fn parse(s: &str) -> Option<Self> {
        [Bc1Encoder::Ispc, Bc1Encoder::TexpressoRange, Bc1Encoder::TexpressoCluster]
            .into_iter()
            .find(|e| e.name() == s.trim())
    }
}

/// Bytes of the BC1 blocks of `slices` images of `width`×`height` texels.
pub fn compressed_size(width: u32, height: u32, slices: u32) -> usize {
    (width.div_ceil(4) * height.div_ceil(4)) as usize * 8 * slices as usize
}

/// Rows of blocks compressed per parallel job.
const BAND_BLOCK_ROWS: usize = 8;

/// Compresses `slices` RGBA8 images of `width`×`height` texels (sides
/// multiples of 4), stored one after another, into BC1 blocks in row-major
/// block order per slice — the layout GPUs upload. Alpha is ignored (opaque).
pub fn encode(rgba: &[u8], width: u32, height: u32, slices: u32, encoder: Bc1Encoder) -> Result<Vec<u8>, CoreError> {
    if !width.is_multiple_of(4) || !height.is_multiple_of(4) || width == 0 || height == 0 {
        return Err(CoreError::InvalidImage(format!("BC1 needs sides that are multiples of 4, not {width}x{height}")));
    }
    let slice_bytes = width as usize * height as usize * 4;
    if rgba.len() != slice_bytes * slices as usize {
        return Err(CoreError::InvalidImage(format!(
            "BC1 input of {} bytes; {slices} slices of {width}x{height} RGBA8 need {}",
            rgba.len(),
            slice_bytes * slices as usize
        )));
    }
    let row_blocks = width as usize / 4;
    let band_src = BAND_BLOCK_ROWS * 4 * width as usize * 4;
    let band_dst = BAND_BLOCK_ROWS * row_blocks * 8;
    let mut out = vec![0u8; compressed_size(width, height, slices)];
    let slice_dst = out.len() / slices as usize;
    // bands of block rows, in parallel over all slices
    out.par_chunks_mut(slice_dst).zip(rgba.par_chunks(slice_bytes)).for_each(|(dst, src)| {
        dst.par_chunks_mut(band_dst).zip(src.par_chunks(band_src)).for_each(|(d, s)| {
            let rows = (s.len() / (width as usize * 4)) as u32;
            match encoder {
                Bc1Encoder::Ispc => {
                    let surface = intel_tex_2::RgbaSurface { data: s, width, height: rows, stride: width * 4 };
                    intel_tex_2::bc1::compress_blocks_into(&surface, d);
                }
                Bc1Encoder::TexpressoRange | Bc1Encoder::TexpressoCluster => {
                    let algorithm = if encoder == Bc1Encoder::TexpressoRange {
                        texpresso::Algorithm::RangeFit
                    } else {
                        texpresso::Algorithm::ClusterFit
                    };
                    let params = texpresso::Params {
                        algorithm,
                        weights: texpresso::COLOUR_WEIGHTS_UNIFORM,
                        weigh_colour_by_alpha: false,
                    };
                    texpresso::Format::Bc1.compress(s, width as usize, rows as usize, params, d);
                }
            }
        });
    });
    Ok(out)
}

/// RGB565 to RGB888 by bit replication.
#[inline]
fn expand565(c: u16) -> [u32; 3] {
    let r = (c >> 11) as u32 & 31;
    let g = (c >> 5) as u32 & 63;
    let b = c as u32 & 31;
    [(r << 3) | (r >> 2), (g << 2) | (g >> 4), (b << 3) | (b >> 2)]
}

/// Decodes one 8-byte BC1 block to 16 RGBA8 texels (row-major 4×4).
pub fn decode_block(block: &[u8]) -> [[u8; 4]; 16] {
    let mut out = [[0u8; 4]; 16];
    if block.len() < 8 {
        return out;
    }
    let c0 = u16::from_le_bytes([block[0], block[1]]);
    let c1 = u16::from_le_bytes([block[2], block[3]]);
    let (a, b) = (expand565(c0), expand565(c1));
    let mut palette = [[0u8; 4]; 4];
    for k in 0..3 {
        palette[0][k] = a[k] as u8;
        palette[1][k] = b[k] as u8;
        if c0 > c1 {
            palette[2][k] = ((2 * a[k] + b[k] + 1) / 3) as u8;
            palette[3][k] = ((a[k] + 2 * b[k] + 1) / 3) as u8;
        } else {
            palette[2][k] = (a[k] + b[k]).div_ceil(2) as u8;
            palette[3][k] = 0;
        }
    }
    palette[0][3] = 255;
    palette[1][3] = 255;
    palette[2][3] = 255;
    palette[3][3] = if c0 > c1 { 255 } else { 0 };
    let bits = u32::from_le_bytes([block[4], block[5], block[6], block[7]]);
    for (i, t) in out.iter_mut().enumerate() {
        *t = palette[((bits >> (2 * i)) & 3) as usize];
    }
    out
}

/// Decodes BC1 blocks (as [`encode`] lays them out) back to RGBA8.
pub fn decode(blocks: &[u8], width: u32, height: u32, slices: u32) -> Result<Vec<u8>, CoreError> {
    if blocks.len() != compressed_size(width, height, slices) || !width.is_multiple_of(4) || !height.is_multiple_of(4) {
        return Err(CoreError::InvalidImage(format!(
            "{} bytes of BC1 blocks do not match {slices} slices of {width}x{height}",
            blocks.len()
        )));
    }
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![0u8; w * h * 4 * slices as usize];
    let row_blocks = w / 4;
    // one block row (4 texel rows) per job
    out.par_chunks_mut(w * 4 * 4).zip(blocks.par_chunks(row_blocks * 8)).for_each(|(dst, src)| {
        for (bx, block) in src.chunks_exact(8).enumerate() {
            let texels = decode_block(block);
            for (i, t) in texels.iter().enumerate() {
                let (x, y) = (bx * 4 + i % 4, i / 4);
                dst[(y * w + x) * 4..(y * w + x) * 4 + 4].copy_from_slice(t);
            }
        }
    });
    Ok(out)
}

/// Peak signal-to-noise ratio of `decoded` against `original` (RGBA8; the
/// three colour channels weighed equally, alpha ignored), in dB:
/// [`crate::metrics::psnr_rgb`].
pub use crate::metrics::psnr_rgb;

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> Vec<u8> {
        let mut v = Vec::new();
        for y in 0..h {
            for x in 0..w {
                v.extend_from_slice(&[(x * 255 / w) as u8, (y * 255 / h) as u8, ((x + y) * 7 % 256) as u8, 255]);
            }
        }
        v
    }

    #[test]
    fn decode_follows_the_format() {
        // c0 = pure red (0xF800) > c1 = pure blue (0x001F): 4-colour mode
        let block = [0x00, 0xF8, 0x1F, 0x00, 0b1110_0100, 0, 0, 0];
        let t = decode_block(&block);
        assert_eq!(t[0], [255, 0, 0, 255]);
        assert_eq!(t[1], [0, 0, 255, 255]);
        assert_eq!(t[2], [170, 0, 85, 255]);
        assert_eq!(t[3], [85, 0, 170, 255]);
        // c0 ≤ c1: 3 colours + transparent black
        let block = [0x1F, 0x00, 0x00, 0xF8, 0b1110_0100, 0, 0, 0];
        let t = decode_block(&block);
        assert_eq!(t[2], [128, 0, 128, 255]);
        assert_eq!(t[3], [0, 0, 0, 0]);
    }

    #[test]
    fn every_encoder_round_trips_with_good_quality() {
        let (w, h) = (64, 48);
        let src = gradient(w, h);
        for e in [Bc1Encoder::Ispc, Bc1Encoder::TexpressoRange, Bc1Encoder::TexpressoCluster] {
            assert!(encode(&src, w, h, 2, e).is_err(), "one slice given, two declared");
            let two: Vec<u8> = src.iter().chain(src.iter()).copied().collect();
            let blocks = encode(&two, w, h, 2, e).unwrap();
            assert_eq!(blocks.len(), compressed_size(w, h, 2));
            let back = decode(&blocks, w, h, 2).unwrap();
            let p = psnr_rgb(&two, &back);
            assert!(p > 30.0, "{}: {p} dB", e.name());
        }
    }

    #[test]
    fn bad_sizes_are_errors() {
        assert!(encode(&[0; 36], 3, 3, 1, Bc1Encoder::Ispc).is_err());
        assert!(encode(&[0; 60], 4, 4, 1, Bc1Encoder::Ispc).is_err());
        assert!(decode(&[0; 7], 4, 4, 1).is_err());
        assert_eq!(psnr_rgb(&[1, 2, 3, 4], &[1, 2, 3, 9]), f64::INFINITY);
    }
}
