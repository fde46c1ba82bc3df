//! hitex-core: the math and data of hitex, free of any GPU API.
//!
//! * [`texture`]: images, sRGB-correct MIP pyramids and the sampler of the
//!   flight-simulator paper (per-pixel level from the screen-to-map Jacobian,
//!   bilinear at two levels, linear blend between them), spans on banks, BC1.
//! * [`btf`]: bidirectional texture functions (seed 000): index map and
//!   codebook, the per-pixel angles, hexa-linear reads, layouts (a)–(f).
//! * [`terrain`]: the active area (seed 001, eq. (5)–(7)), meshes from
//!   elevation grids, flight paths ([`terrain::path`]).
//! * [`residency`]: the resident-map cache loading a pyramid's maps in the
//!   background.
//! * [`nurbs`]: NURBS surfaces (seed 004): evaluation, derivatives,
//!   curvature, trims, knot insertion and degree elevation.
//! * [`scene`]: cameras, lights, triangle meshes, materials and the TOML scene
//!   description with its embedded default.
//! * [`frame`]: the RGBA8 frame every renderer returns.
//! * [`metrics`]: image metrics, once for every crate: PSNR, SSIM, and the
//!   comparison the parity tests and benches report.
//! * [`tolerance`]: the named tolerances tests and comparisons state;
//!   [`error`]: the crate's error type.
//!
//! Everything here is testable with `cargo test` alone and usable as a library.
// a library prints nothing: it returns errors and warnings, or hands notices to a callback
#![cfg_attr(not(test), deny(clippy::print_stdout, clippy::print_stderr))]
#![warn(missing_docs, unreachable_pub)]

pub mod btf;
pub mod error;
pub mod frame;
pub mod metrics;
pub mod nurbs;
pub mod residency;
pub mod scene;
pub mod terrain;
pub mod texture;
pub mod tolerance;

pub use error::CoreError;

/// The splitmix64 finaliser: a fast, well-mixed hash of a 64-bit value, the
/// deterministic noise of the procedural generators.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Three values hashed into one ([`splitmix64`] chained).
#[inline]
pub(crate) fn hash3(a: u64, b: u64, c: u64) -> u64 {
    splitmix64(splitmix64(a ^ splitmix64(b)) ^ c)
}

/// A hash as a float in [0, 1) (its top 53 bits).
#[inline]
pub(crate) fn unit_interval(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}
