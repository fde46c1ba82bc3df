//! Image comparison with named metrics: [`hitex_core::metrics`], where
//! PSNR, SSIM and the comparison live once for every crate.

pub use hitex_core::metrics::{ImageDiff, compare_rgba};
