//! Textures: images, MIP pyramids, samplers and procedural patterns.
//!
//! Data (the [`MipPyramid`]) is kept apart from options ([`SamplerOptions`])
//! and from the lookup ([`sample`]), as in pbrt's `MIPMap`.

pub mod bc1;
pub mod image;
pub mod procedural;
pub mod pyramid;
pub mod sampler;
pub mod span;
pub mod tone;

pub use image::{
    ColorSpace, Image, SrgbEncoder, linear_to_srgb, linear_to_srgb_u8, srgb_encoder, srgb_to_linear, srgb_u8_to_linear,
};
pub use pyramid::MipPyramid;
pub use sampler::{Filter, Jacobian, LevelRule, SamplerOptions, Wrap, level_of_detail, sample};
pub use tone::ToneMap;
