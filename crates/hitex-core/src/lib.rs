//! hitex-core: the math and data of hitex, free of any GPU API.
//!
//! * [`texture`]: images, sRGB-correct MIP pyramids and the sampler of the
//!   flight-simulator paper (per-pixel level from the screen-to-map Jacobian,
//!   bilinear at two levels, linear blend between them).
//! * [`scene`]: cameras, lights, triangle meshes, materials and the TOML scene
//!   description with its embedded default.
//!
//! Everything here is testable with `cargo test` alone and usable as a library.

pub mod btf;
pub mod error;
pub mod nurbs;
pub mod residency;
pub mod scene;
pub mod terrain;
pub mod texture;
pub mod tolerance;

pub use error::CoreError;
