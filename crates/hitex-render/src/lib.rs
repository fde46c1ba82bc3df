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
//!   drawn into analysis frames; [`codes`]: the codes of the uniforms'
//!   choices (filter, wrap, modes, tone map, sampler), which the shaders
//!   receive as generated constants.
//!
//! Both consume the same [`prepare::PreparedScene`]: world-space vertices,
//! `#[repr(C)]` uniform blocks and the texture pyramids, byte for byte.
// a library prints nothing: it returns errors and warnings, or hands notices to a callback
#![cfg_attr(not(test), deny(clippy::print_stdout, clippy::print_stderr))]
#![warn(missing_docs, unreachable_pub)]

pub mod btf;
pub mod codes;
pub mod compare;
pub mod cpu;
pub mod gpu;
pub mod job;
pub mod legend;
pub mod nurbs;
mod nurbs_model;
pub mod prepare;
pub mod terrain;

pub use compare::{ImageDiff, compare_rgba};
pub use cpu::CpuRenderer;
pub use gpu::{GpuError, GpuRenderer, adapters_report};
/// A rendered image: RGBA8, sRGB-encoded, rows top to bottom ([`hitex_core::frame::Frame`]).
pub use hitex_core::frame::Frame;
pub use job::{AnyRenderer, BackendChoice, Engine, Job, OpenOptions, Rendered, Renderer};
pub use prepare::PreparedScene;

use thiserror::Error;

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
