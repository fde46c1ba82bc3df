//! hitex-render: two backends behind one render API ([`job`]).
//!
//! * [`cpu`]: a multi-threaded tiled rasterizer (top-left fill rule, 8-bit
//!   sub-pixel precision, perspective-correct attributes, depth buffer, pixels
//!   shaded in 2×2 quads) running the fragment programs of `cpu/*.rs`;
//! * [`gpu`]: wgpu 30 running `shaders/*.wgsl`, the same programs in WGSL.
//! * What both backends render, prepared once: textured scenes
//!   ([`prepare`]), NURBS models and their analysis modes ([`nurbs`]), BTF
//!   surfaces ([`btf`]), flights over tile stores ([`terrain`], with the
//!   per-frame work above the renderer in [`terrain::flight`]).
//! * [`compare`]: image metrics between frames; [`legend`]: colour legends
//!   drawn into analysis frames.
//!
//! Both consume the same [`prepare::PreparedScene`]: world-space vertices,
//! `#[repr(C)]` uniform blocks and the texture pyramids, byte for byte.
// a library prints nothing: it returns errors and warnings, or hands notices to a callback
#![cfg_attr(not(test), deny(clippy::print_stdout, clippy::print_stderr))]
#![warn(missing_docs, unreachable_pub)]

pub mod btf;
pub mod compare;
pub mod cpu;
pub mod gpu;
pub mod job;
pub mod legend;
pub mod nurbs;
pub mod prepare;
pub mod terrain;

pub use compare::{ImageDiff, compare_rgba};
pub use cpu::CpuRenderer;
pub use gpu::{GpuError, GpuRenderer, adapters_report};
pub use job::{AnyRenderer, BackendChoice, Engine, Job, OpenOptions, Rendered, Renderer};
pub use prepare::PreparedScene;

use thiserror::Error;

/// A rendered image: RGBA8, sRGB-encoded, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
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
        let lin: Vec<f32> = (0..=255u8).map(|b| hitex_core::texture::srgb_to_linear(b as f32 / 255.0)).collect();
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
                    rgba[o + c] = hitex_core::texture::linear_to_srgb_u8(s[c] / n);
                }
                rgba[o + 3] = (s[3] / n).round() as u8;
            }
        }
        Frame { width: w, height: h, rgba }
    }
}

/// Errors of a render.
#[derive(Debug, Error)]
pub enum RenderError {
    /// The GPU backend failed (no adapter, device lost, out of memory, ...).
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The request itself is invalid (size, scene).
    #[error("{0}")]
    Invalid(String),
}

/// Checks an output size.
pub fn check_size(width: u32, height: u32) -> Result<(), RenderError> {
    let max = hitex_core::scene::desc::MAX_OUTPUT_SIDE;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(RenderError::Invalid(format!("output size {width}x{height} is outside 1..={max}")));
    }
    Ok(())
}
